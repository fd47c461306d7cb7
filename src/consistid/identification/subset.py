r"""Identification from a subset of the torque channels: joints excluded by the user, and dead
channels excluded automatically.

The dynamics ``τ = Y(q, q̇, q̈) π`` hold row by row: each joint's row involves the bodies it
carries, so dropping joint ``k``'s torque rows leaves the others' rows valid, with ``q_k, q̇_k,
q̈_k`` still entering their kinematics. What only row ``k`` informs is lost: the per-joint terms
of joint ``k`` (its friction, offset and armature columns are dropped), and the rigid-body
combinations that act on no other row (e.g. a last link's inertia about its own axis when ``k`` is
the last joint). The base parameters are recomputed on the kept rows (Gautier 1991's random-state
QR restricted to them, :func:`rows_base`); :func:`lost_parameters` names what could be
identified with every row and no longer is.

A torque channel that reads exactly one value throughout (0, or a frozen constant) while the arm
moves (:func:`consistid.data.checks.check_motion` passed) is *dead*: no joint of a moving arm
carries a constant torque to :data:`DEAD_SPREAD`. It is excluded with a
:class:`~consistid.errors.DataQualityWarning` rather than refused.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from .base import BaseParameters, base_parameters_from_regressor, random_states
from .compression import CompressedProblem
from .regressor import RegressorSpec, parameter_names, regressor
from ..data.dataset import Dataset
from ..errors import OptionError
from ..robot.model import RobotModel

__all__ = ["DEAD_SPREAD", "resolve_excluded", "dead_channels", "without_joints", "rows_base",
           "restricted", "lost_parameters", "expand"]

#: A torque channel whose peak-to-peak spread is at most this (N·m) over the whole log is dead.
DEAD_SPREAD = 1e-9


def resolve_excluded(model: RobotModel, exclude_joints: Sequence[int | str] | None
                     ) -> tuple[int, ...]:
    """``exclude_joints`` (names or indices) as sorted indices; :class:`OptionError` naming the
    keyword for an unknown joint, or when every joint would be excluded."""
    if exclude_joints is None:
        return ()
    if isinstance(exclude_joints, (str, int, np.integer)):
        exclude_joints = (exclude_joints,)
    out = set()
    for j in exclude_joints:
        if isinstance(j, str) and j in model.joint_names:
            j = model.joint_names.index(j)
        if isinstance(j, bool) or not isinstance(j, (int, np.integer)) \
                or not 0 <= int(j) < model.nv:
            raise OptionError(f"exclude_joints: {j!r} is not a joint of {model.name} (names "
                              f"{list(model.joint_names)} or indices 0..{model.nv - 1})")
        out.add(int(j))
    if len(out) == model.nv:
        raise OptionError(f"exclude_joints excludes every joint of {model.name}: no torque row "
                          "is left to identify from")
    return tuple(sorted(out))


def dead_channels(dataset: Dataset) -> np.ndarray:
    """Indices of the torque channels whose spread ``max − min`` is at most :data:`DEAD_SPREAD`
    (module docstring)."""
    tau = dataset.require_torque()
    return np.flatnonzero(np.ptp(tau, axis=0) <= DEAD_SPREAD)


def without_joints(spec: RegressorSpec, excluded: Sequence[int]) -> RegressorSpec:
    """``spec`` without the per-joint columns of the ``excluded`` joints (only their own rows
    carry them)."""
    drop = set(excluded)
    return RegressorSpec(spec.nv, tuple(
        (term, tuple(m and j not in drop for j, m in enumerate(mask)))
        for term, mask in spec.masks))


def rows_base(model: RobotModel, spec: RegressorSpec, kept: Sequence[int], seed: int = 0
              ) -> BaseParameters:
    """Base parameters of the kept joints' rows: the random-state regressor of
    :func:`~consistid.identification.base.compute_base_parameters` (same seed and tolerance)
    restricted to those rows."""
    names = parameter_names(model, spec)
    n = max(200, 4 * len(names) // len(kept))
    q, dq, ddq = random_states(model, n, np.random.default_rng(seed))
    y = regressor(model, q, dq, ddq, spec).reshape(n, model.nv, -1)[:, list(kept)]
    return base_parameters_from_regressor(y.reshape(n * len(kept), -1), names)


def restricted(problem: CompressedProblem, kept: Sequence[int]) -> CompressedProblem:
    """The compressed problem of the kept joints' rows only (their per-joint factors)."""
    kept = list(kept)
    return CompressedProblem(problem.factors[kept], problem.n_samples,
                             problem.tau_sum_squares[kept], problem.filtered)


def lost_parameters(full: BaseParameters, reduced: BaseParameters) -> list[str]:
    """Standard parameters that act on the torques with every row (not in
    ``full.unidentifiable``) but on none of the kept rows, or whose columns were dropped."""
    gone = set(full.unidentifiable)
    kept_names = set(reduced.standard_names)
    dropped = [n for n in full.standard_names if n not in kept_names]
    return dropped + [n for n in reduced.unidentifiable if n not in gone]


def expand(values: np.ndarray, kept: Sequence[int], nv: int) -> np.ndarray:
    """Per-kept-joint ``values`` as ``(nv,)``, NaN at the excluded joints (no rows: no value)."""
    out = np.full(nv, np.nan)
    out[list(kept)] = values
    return out

r"""The joint-torque regressor with named column blocks.

The torque model is linear in the parameters (Atkeson, An, Hollerbach 1986; Khalil & Dombre,
*Modeling, Identification and Control of Robots*, ch. 12):

.. math::

    \tau_k = Y_\text{rb}(q_k, \dot q_k, \ddot q_k)\,\pi
           + \operatorname{diag}(\operatorname{sign}\dot q_k)\, f_c
           + \operatorname{diag}(\dot q_k)\, f_v + f_o
           + \operatorname{diag}(\ddot q_k)\, I_a

Columns, in this order:

``rigid``
    10 per body, Pinocchio order (``pinocchio.computeJointTorqueRegressor``), names
    ``"<body>.<m|mx|my|mz|Ixx|Ixy|Iyy|Ixz|Iyz|Izz>"``.
``coulomb``, ``viscous``, ``offset``, ``armature``
    one column per enabled joint, names ``"<joint>.fc"``, ``".fv"``, ``".fo"``, ``".Ia"``.

Rows are **sample-major**: row ``k·nv + j`` is joint ``j`` of sample ``k``, i.e.
``Y.reshape(N, nv, p)[k, j]``.

``pinocchio.rnea`` adds ``model.armature · q̈`` whereas the rigid-body regressor does not; the
armature block is how rotor inertia enters here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator, Mapping, Sequence

import numpy as np
import pinocchio as pin

from .dataset import Dataset
from .errors import JointCountError, check_option
from .model import RobotModel

JOINT_TERMS: tuple[str, ...] = ("coulomb", "viscous", "offset", "armature")
TERM_SUFFIX = {"coulomb": "fc", "viscous": "fv", "offset": "fo", "armature": "Ia"}

FrictionArg = Sequence[str] | Mapping[str, Sequence[int | str] | bool] | None


@dataclass(frozen=True)
class RegressorSpec:
    """Which per-joint columns the regressor carries, beside the rigid-body block.

    ``masks[term]`` is a boolean tuple of length ``nv``. Build one with :meth:`make`.
    """

    nv: int
    masks: tuple[tuple[str, tuple[bool, ...]], ...]

    @classmethod
    def make(cls, model: RobotModel, friction: FrictionArg = ("coulomb", "viscous", "offset"),
             armature: bool | Sequence[int | str] = False) -> "RegressorSpec":
        """Build a spec.

        Parameters
        ----------
        friction : names among ``"coulomb", "viscous", "offset"`` (all joints), or a mapping
            ``{term: joints}`` where joints are indices or names (or ``True`` for all), or ``None``.
        armature : ``True`` for a rotor-inertia column per joint, or the joints that get one.
        """
        nv = model.nv

        def mask(selection: Sequence[int | str] | bool) -> tuple[bool, ...]:
            if selection is True:
                return (True,) * nv
            if selection is False or selection is None:
                return (False,) * nv
            out = [False] * nv
            for j in selection:
                if isinstance(j, str):
                    check_option("joint", j, model.joint_names)
                    j = model.joint_names.index(j)
                if not 0 <= int(j) < nv:
                    raise ValueError(f"joint index {j} out of range 0..{nv - 1}")
                out[int(j)] = True
            return tuple(out)

        if friction is None:
            friction = {}
        if isinstance(friction, str):
            friction = (friction,)
        if not isinstance(friction, Mapping):
            friction = {term: True for term in friction}
        for term in friction:
            check_option("friction term", term, JOINT_TERMS[:3])
        masks = {term: mask(friction.get(term, False)) for term in JOINT_TERMS[:3]}
        masks["armature"] = mask(armature)
        return cls(nv, tuple((t, masks[t]) for t in JOINT_TERMS))

    def mask(self, term: str) -> np.ndarray:
        return np.array(dict(self.masks)[term], dtype=bool)

    @property
    def n_joint_columns(self) -> int:
        return int(sum(sum(m) for _, m in self.masks))

    def joint_column_names(self, joint_names: Sequence[str]) -> list[str]:
        return [f"{joint_names[j]}.{TERM_SUFFIX[term]}"
                for term, m in self.masks for j in range(self.nv) if m[j]]

    def describe(self) -> str:
        parts = [f"{term} on {sum(m)}/{self.nv}" for term, m in self.masks if any(m)]
        return ", ".join(parts) if parts else "rigid body only"


def parameter_names(model: RobotModel, spec: RegressorSpec) -> list[str]:
    """Names of all regressor columns: rigid-body block, then per-joint blocks."""
    return [*model.parameter_names, *spec.joint_column_names(model.joint_names)]


def prior_vector(model: RobotModel, spec: RegressorSpec) -> np.ndarray:
    """The CAD prior extended by zeros for friction/offset/armature columns."""
    return np.concatenate([model.prior_parameters, np.zeros(spec.n_joint_columns)])


def joint_columns(dq: np.ndarray, ddq: np.ndarray, spec: RegressorSpec) -> np.ndarray:
    """The per-joint blocks for samples ``(N, nv)`` as an array ``(N, nv, n_joint_columns)``."""
    n, nv = dq.shape
    signals = {"coulomb": np.sign(dq), "viscous": dq, "offset": np.ones_like(dq), "armature": ddq}
    out = np.zeros((n, nv, spec.n_joint_columns))
    c = 0
    for term, m in spec.masks:
        for j in range(nv):
            if m[j]:
                out[:, j, c] = signals[term][:, j]
                c += 1
    return out


def rigid_body_regressor(model: RobotModel, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray,
                         out: np.ndarray | None = None) -> np.ndarray:
    """Pinocchio's joint-torque regressor for each sample, shape ``(N, nv, 10·nbodies)``.

    Satisfies ``Y[k] @ π = rnea(q_k, dq_k, ddq_k)`` for a model without armature. ``out`` may be
    a preallocated array (or a view) of that shape to write into.
    """
    m, data = model.pin_model, model.pin_model.createData()
    n = q.shape[0]
    out = np.empty((n, model.nv, model.n_inertial)) if out is None else out
    same = m.nq == m.nv
    for k in range(n):
        qk = q[k] if same else model.configuration(q[k])
        out[k] = pin.computeJointTorqueRegressor(m, data, qk, dq[k], ddq[k])
    return out


def regressor(model: RobotModel, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray,
              spec: RegressorSpec | None = None, out: np.ndarray | None = None) -> np.ndarray:
    """The stacked regressor ``Y``, shape ``(N·nv, p)``, rows sample-major.

    Parameters
    ----------
    q, dq, ddq : (N, nv) joint angles, velocities, accelerations (one sample may be 1-D).
    spec : which friction/armature columns to append; default rigid body only.
    out : optional preallocated ``(N, nv, p)`` array to fill (avoids a copy for large N).
    """
    q, dq, ddq = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (q, dq, ddq))
    if q.shape[1] != model.nv:
        raise JointCountError(f"q has {q.shape[1]} joints but {model.name} has {model.nv}")
    spec = spec or RegressorSpec.make(model, friction=None)
    n, p = q.shape[0], model.n_inertial + spec.n_joint_columns
    y = np.empty((n, model.nv, p)) if out is None else out
    rigid_body_regressor(model, q, dq, ddq, out=y[:, :, :model.n_inertial])
    if spec.n_joint_columns:
        y[:, :, model.n_inertial:] = joint_columns(dq, ddq, spec)
    return y.reshape(n * model.nv, p)


def dataset_regressor(model: RobotModel, dataset: Dataset,
                      spec: RegressorSpec | None = None) -> np.ndarray:
    """:func:`regressor` of a dataset's samples (checks the joint count)."""
    dataset.check_joints(model.nv, model.joint_names)
    return regressor(model, dataset.q, dataset.dq, dataset.ddq, spec)


def iter_regressor(model: RobotModel, dataset: Dataset, spec: RegressorSpec,
                   chunk: int = 4096) -> Iterator[tuple[slice, np.ndarray]]:
    """Yield ``(sample slice, Y_chunk)`` with ``Y_chunk`` of shape ``(n, nv, p)``: O(chunk) memory.

    The chunks share one buffer: each yielded array is overwritten by the next one.
    """
    dataset.check_joints(model.nv, model.joint_names)
    buffer = np.empty((min(chunk, dataset.n_samples), model.nv,
                       model.n_inertial + spec.n_joint_columns))
    for start in range(0, dataset.n_samples, chunk):
        s = slice(start, min(start + chunk, dataset.n_samples))
        y = buffer[: s.stop - s.start]
        regressor(model, dataset.q[s], dataset.dq[s], dataset.ddq[s], spec, out=y)
        yield s, y

"""Exceptions raised by consistid.

Every error names what is wrong (field, index, joint, body, solver status) so that a user can fix
the input without reading the source. Bad *values* are ``ValueError`` subclasses; failures of a
numerical method are :class:`IdentificationError` subclasses.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np


class ConsistidError(Exception):
    """Base class of every consistid exception."""


class DatasetError(ConsistidError, ValueError):
    """A dataset field has the wrong shape, a non-finite value or non-increasing time."""


class JointCountError(DatasetError):
    """A dataset (or array) has a different joint count than the robot model."""


class MissingColumnsError(DatasetError):
    """A CSV/NPZ file lacks columns that a :class:`~consistid.Dataset` needs."""


class JointNameError(DatasetError):
    """A log's joint names do not match the model's (lists the names missing on each side)."""


class MissingDependencyError(ConsistidError, ImportError):
    """An optional dependency is not installed (pyarrow for Parquet, rosbags for ROS bags and
    MCAP …); the message names the package and the ``consistid[extra]`` that installs it."""


class ConfigError(ConsistidError, ValueError):
    """A run configuration (TOML) is missing a table or key, or has an unknown one."""


class OptionError(ConsistidError, ValueError):
    """An option takes a value outside its allowed set; the message lists the allowed values."""


class OutputPathError(ConfigError):
    """An output path is unsafe: the file exists (pass ``--force`` / ``force=True`` to replace
    it), it is one of the run's inputs (never overwritten, even with ``--force``), or its folder
    does not exist or is not writable. Raised before any long work starts."""


class ModelError(ConsistidError, ValueError):
    """A robot model cannot be built or does not fit the request (unknown joint, robot, file)."""


class ResultFileError(ConsistidError, ValueError):
    """A saved result file cannot be read back: missing, not JSON, another format or version,
    a field missing or of the wrong shape (names the file and the field)."""


class IdentificationError(ConsistidError, RuntimeError):
    """A numerical identification step failed (solver status, rank deficiency)."""


class InfeasibleError(IdentificationError):
    """The constraints admit no solution (the solver proved infeasibility)."""


class SolverError(IdentificationError):
    """The conic solver crashed or refused the problem (a Rust panic in Clarabel, a solver
    exception); the message names the solver and what to try. Never a ``BaseException``."""


class PoorExcitationError(IdentificationError):
    """The data do not excite the base parameters: the base regressor is rank deficient."""


class UninformedGainError(PoorExcitationError):
    """The runs of :func:`consistid.identify_drive_gains` do not determine a drive gain: the
    load does not change that joint's torque enough (the message names the joint and what
    experiment would)."""


class UnrealizableCoefficientsError(InfeasibleError):
    """No physically consistent standard parameters reproduce the given base coefficients.

    ``moves`` holds the smallest (weighted L1) changes of the named coefficients that would make
    them realisable (:class:`consistid.estimation.recover.CoefficientMove`).
    """

    def __init__(self, message: str, moves: tuple = ()) -> None:
        super().__init__(message)
        self.moves = tuple(moves)


class ExcitationError(ConsistidError, ValueError):
    """An excitation trajectory cannot be built or evaluated as requested (boundary conditions,
    via-point times, sampling outside a non-periodic trajectory)."""


class InfeasibleExcitationError(ExcitationError):
    """The excitation limits admit no trajectory (e.g. a zero velocity limit, a rest pose outside
    the workspace), or no optimisation start ended feasible; names the joint/constraint."""


class ParameterShapeError(ConsistidError, ValueError):
    """A parameter vector or matrix has the wrong shape (not 10 per body, not 4×4 …)."""


class InconsistentParametersError(ConsistidError, ValueError):
    """Parameters that must be physically consistent are not (names the body and the violation)."""


def check_option(name: str, value: object, allowed: tuple | list | set) -> None:
    """Raise :class:`OptionError` unless ``value`` is one of ``allowed``."""
    if value not in allowed:
        listed = ", ".join(repr(a) for a in allowed)
        raise OptionError(f"{name}={value!r} is not supported; allowed: {listed}")


def check_number(name: str, value: object, minimum: float | None = None, *,
                 strict: bool = False, integer: bool = False) -> float:
    """``value`` as a finite number (``≥ minimum``, or ``> minimum`` when ``strict``; an integer
    when ``integer``), else :class:`OptionError` naming ``name``. Booleans are not numbers."""
    ok = isinstance(value, (int, float, np.integer, np.floating)) \
        and not isinstance(value, (bool, np.bool_))
    try:
        ok = ok and bool(np.isfinite(float(value))) and (not integer or float(value).is_integer())
    except OverflowError:                       # an int beyond float's range
        ok = False
    if ok and minimum is not None:
        ok = value > minimum if strict else value >= minimum
    if not ok:
        kind = "an integer" if integer else "a finite number"
        bound = "" if minimum is None else f" {'>' if strict else '≥'} {minimum:g}"
        raise OptionError(f"{name} must be {kind}{bound}, got {value!r}")
    return int(value) if integer else float(value)


def check_seed(name: str, seed: object) -> object:
    """A random seed numpy accepts: an integer ≥ 0 (or ``None``, or a ``numpy`` Generator),
    else :class:`OptionError` naming ``name`` (numpy's own message names no option)."""
    if seed is None or isinstance(seed, np.random.Generator):
        return seed
    return check_number(name, seed, 0, integer=True)


def check_bounds(name: str, value: object) -> tuple[float | None, float | None]:
    """A ``(lower, upper)`` pair of numbers or ``None`` (no bound), else :class:`OptionError`."""
    if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)) \
            or np.shape(value) != (2,):
        raise OptionError(f"{name} must be a pair (lower, upper) of numbers or None, got "
                          f"{value!r}")
    lo, hi = (None if v is None else check_number(f"{name} bound", v) for v in value)
    return lo, hi


def check_box(name: str, value: object) -> tuple[np.ndarray, np.ndarray]:
    """A box ``(lower, upper)``, each 3 finite numbers with ``lower ≤ upper``, else
    :class:`OptionError` naming ``name``."""
    try:
        lo, hi = (np.asarray(v, dtype=float) for v in value)  # type: ignore[union-attr]
    except (TypeError, ValueError):
        lo = hi = np.array([np.nan])
    if lo.shape != (3,) or hi.shape != (3,) or not np.all(np.isfinite([lo, hi])) \
            or np.any(lo > hi):
        raise OptionError(f"{name} must be (lower, upper), each 3 finite numbers (m), lower ≤ "
                          f"upper, got {value!r}")
    return lo, hi


class PoorExcitationWarning(UserWarning):
    """The data excite the base parameters poorly (large condition number)."""


class ExtrapolationWarning(UserWarning):
    """New data go where the training data never went (a velocity sign a joint never moved
    with, a position, speed or acceleration range exceeded): the prediction there extrapolates,
    and directions the training data barely informed may decide it. Names the joint and what."""


class DataQualityWarning(UserWarning):
    """The data look suspicious but usable (e.g. a lone glitch in a torque channel): names the
    field, sample and joint, and what to do."""


class ModelMisfitWarning(UserWarning):
    """The fitted model leaves a residual that its noise model does not explain (e.g. larger
    where a joint stands still, held by static friction that ``f_c sign(q̇)`` cannot describe):
    names the joint, where and how much, and what to do."""


class NothingFoundWarning(UserWarning):
    """An estimate found nothing (e.g. a payload on data that carry none): the answer is zero
    within its uncertainty, and what derives from it (a centre of mass) is undefined."""


class InaccurateSolutionWarning(UserWarning):
    """The solver stopped at reduced accuracy (status ``optimal_inaccurate``)."""


class GeometryWarning(UserWarning):
    """A body has no collision geometry, so no bounding shape (:mod:`consistid.robot.shapes`)."""


class ExportWarning(UserWarning):
    """Some identified values have no place in the target format (named in the message)."""


class TrackingWarning(UserWarning):
    """A simulated robot did not follow its reference: the tracking error exceeds the bound of
    :func:`consistid.simulate.record` (``max_tracking_error``)."""


class ModelWarning(UserWarning):
    """A robot model loads but is suspicious: a URDF body whose inertia no physical body has
    (negative principal moment, triangle inequality violated); names the bodies and what will
    refuse them (MuJoCo, the log-det prior)."""


class BoundActiveWarning(UserWarning):
    """A bound the user gave (a payload's ``mass_range`` or ``com_bounds``, an ellipsoid)
    decides the estimate: the data alone would put it outside, beyond their uncertainty. Names
    the bound, the unbounded estimate and the χ² it costs. Also: consistency constraints that
    move drive gains beyond their σ (:func:`consistid.identify_drive_gains`)."""

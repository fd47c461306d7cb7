r"""The joint-torque regressor with named column blocks.

The torque model is linear in the parameters (Atkeson, An, Hollerbach 1986; Khalil & Dombre,
*Modeling, Identification and Control of Robots*, ch. 12):

.. math::

    \tau_k = Y_\text{rb}(q_k, \dot q_k, \ddot q_k)\,\pi
           + \operatorname{diag}(\operatorname{sign}\dot q_k)\, f_c
           + \operatorname{diag}(\dot q_k)\, f_v + f_o
           + \operatorname{diag}(\sin q_k)\, p_s + \operatorname{diag}(\cos q_k)\, p_c
           + \operatorname{diag}(\ddot q_k)\, I_a

Columns, in this order:

``rigid``
    10 per body, Pinocchio order (``pinocchio.computeJointTorqueRegressor``), names
    ``"<body>.<m|mx|my|mz|Ixx|Ixy|Iyy|Ixz|Iyz|Izz>"``.
``coulomb``, ``viscous``, ``offset``
    one column per enabled joint, names ``"<joint>.fc"``, ``".fv"``, ``".fo"``.
``position``
    two columns per enabled joint, ``sin q_j`` and ``cos q_j``, names ``"<joint>.ps1"``,
    ``".pc1"``: the first harmonic of a torque that is periodic in the joint's own angle, one
    cycle per revolution. Physically, what a joint torque sensor reads besides the joint torque
    and that turns with the joint: cross-talk of the bending moments it carries (their direction
    in the sensor frame turns with ``q_j``; S.-H. Lee, Y.-L. Kim, J.-B. Song, "Torque sensor
    calibration using virtual load for a manipulator", Int. J. Precision Engineering and
    Manufacturing 11(2), 219–225, 2010, doi:10.1007/s12541-010-0025-0), a mounting
    eccentricity or misalignment of sensor or bearing, and the once-per-revolution component of
    position-dependent transmission torque. It is not a rigid-body effect, so it is free of sign
    and (like an offset) of any prior. On a joint whose axis keeps a fixed direction relative to
    gravity while the joints before it move (a horizontal first joint; the second joint of an
    arm whose vertical first axis meets it), the link's own gravity torque is already
    ``a sin q_j + b cos q_j`` (D. Ma, J. M. Hollerbach, Y. Xu, "Gravity based autonomous
    calibration for robot manipulators", IEEE ICRA 1994): there the two columns are dependent on
    that link's first mass moments, and the base parameters (:mod:`consistid.identification.base`)
    regroup
    them; torques cannot tell the two apart.
``armature``
    one column per enabled joint, names ``"<joint>.Ia"``.

Rows are **sample-major**: row ``k·nv + j`` is joint ``j`` of sample ``k``, i.e.
``Y.reshape(N, nv, p)[k, j]``.

``pinocchio.rnea`` adds ``model.armature · q̈`` whereas the rigid-body regressor does not; the
armature block is how rotor inertia enters here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterator, Mapping, Sequence

import numpy as np
import pinocchio as pin

from ..data.checks import MAX_ABS
from ..data.dataset import Dataset
from ..data.parallel import lowpass_runs, plan
from ..errors import DatasetError, JointCountError, OptionError, check_option
from ..robot.joint_terms import (DEFAULT_FRICTION, FRICTION_TERMS, JOINT_TERMS,
                                 NONNEGATIVE_TERMS, TERM_COLUMNS)
from ..robot.model import RobotModel

FrictionArg = Sequence[str] | Mapping[str, Sequence[int | str] | bool] | None


@dataclass(frozen=True)
class RegressorSpec:
    """Which per-joint columns the regressor carries, beside the rigid-body block.

    ``masks[term]`` is a boolean tuple of length ``nv``. Build one with :meth:`make`. Columns
    come term by term (order of :data:`JOINT_TERMS`), joint by joint within a term, and within a
    joint in the order of :data:`TERM_COLUMNS` (:attr:`columns`).
    """

    nv: int
    masks: tuple[tuple[str, tuple[bool, ...]], ...]

    @classmethod
    def make(cls, model: RobotModel, friction: FrictionArg = DEFAULT_FRICTION,
             armature: bool | Sequence[int | str] = False) -> "RegressorSpec":
        """Build a spec.

        Parameters
        ----------
        friction : names among ``"coulomb", "viscous", "offset", "position"`` (all joints), or
            a mapping ``{term: joints}`` where joints are indices or names (or ``True`` for
            all), or ``None``. ``"position"`` is the per-joint ``sin q_j, cos q_j`` pair (module
            docstring); it is not friction, but like the offset it is a per-joint torque term.
        armature : ``True`` for a rotor-inertia column per joint, or the joints that get one.
        """
        nv = model.nv

        def mask(selection: Sequence[int | str] | bool) -> tuple[bool, ...]:
            if isinstance(selection, (bool, np.bool_)):
                return (bool(selection),) * nv
            if selection is None:
                return (False,) * nv
            if isinstance(selection, (str, int, np.integer)):
                selection = (selection,)
            if not isinstance(selection, (Sequence, np.ndarray)):
                raise OptionError(f"joints must be True/False, a joint, or a list of joint names "
                                  f"or indices, got {selection!r}")
            out = [False] * nv
            for j in selection:
                if isinstance(j, str):
                    check_option("joint", j, model.joint_names)
                    j = model.joint_names.index(j)
                if isinstance(j, bool) or not isinstance(j, (int, np.integer)):
                    raise OptionError(f"a joint is a name or an index, got {j!r}")
                if not 0 <= int(j) < nv:
                    raise OptionError(f"joint index {j} out of range 0..{nv - 1}")
                out[int(j)] = True
            return tuple(out)

        if friction is None:
            friction = {}
        if isinstance(friction, str):
            friction = (friction,)
        if not isinstance(friction, (Mapping, Sequence, np.ndarray)):
            raise OptionError(f"friction must be term names, {{term: joints}} or None, got "
                              f"{friction!r}")
        if not isinstance(friction, Mapping):
            friction = {term: True for term in friction}
        for term in friction:
            check_option("friction term", term, FRICTION_TERMS)
        masks = {term: mask(friction.get(term, False)) for term in FRICTION_TERMS}
        masks["armature"] = mask(armature)
        return cls(nv, tuple((t, masks[t]) for t in JOINT_TERMS))

    def mask(self, term: str) -> np.ndarray:
        return np.array(dict(self.masks)[term], dtype=bool)

    @property
    def columns(self) -> tuple[tuple[str, int, str], ...]:
        """``(term, joint index, suffix)`` of each per-joint column, in column order."""
        return tuple((term, j, suffix) for term, m in self.masks for j in range(self.nv) if m[j]
                     for suffix in TERM_COLUMNS[term])

    @property
    def n_joint_columns(self) -> int:
        return len(self.columns)

    @property
    def nonnegative_columns(self) -> np.ndarray:
        """Indices, among the per-joint columns, of the terms that are ≥ 0 physically
        (:data:`NONNEGATIVE_TERMS`: Coulomb, viscous, armature)."""
        return np.array([c for c, (term, _, _) in enumerate(self.columns)
                         if term in NONNEGATIVE_TERMS], dtype=int)

    def joint_column_names(self, joint_names: Sequence[str]) -> list[str]:
        return [f"{joint_names[j]}.{suffix}" for _, j, suffix in self.columns]

    def describe(self) -> str:
        parts = [f"{term} on {sum(m)}/{self.nv}" for term, m in self.masks if any(m)]
        return ", ".join(parts) if parts else "rigid body only"


def matching_settings(model: RobotModel, accept: Callable[[RegressorSpec], bool]) -> list[str]:
    """The ``friction``/``armature`` settings (each term on every joint or on none) whose spec
    ``accept`` takes, as ``"friction=(…), armature=…"``: for errors that suggest what a user
    meant when a coefficient count does not fit."""
    found = []
    for k in range(2 ** len(FRICTION_TERMS)):
        terms = tuple(t for i, t in enumerate(FRICTION_TERMS) if k >> i & 1)
        for armature in (False, True):
            if accept(RegressorSpec.make(model, terms, armature)):
                found.append(f"friction={terms or None}, armature={armature}")
    return found


def _is_auto(value: object) -> bool:
    return isinstance(value, str) and value == "auto"


def resolve_spec(model: RobotModel, friction: FrictionArg | str,
                 armature: bool | Sequence[int | str] | str,
                 given: RegressorSpec | None = None) -> RegressorSpec:
    """The spec of ``friction``/``armature`` arguments whose default is ``"auto"``.

    Without ``given`` (a bare parameter vector), ``"auto"`` means :data:`DEFAULT_FRICTION` and
    no armature, the defaults of ``identify``. With ``given`` (the spec of an identification
    result), ``"auto"`` takes its columns, and an explicit value must describe the same columns
    for its terms: otherwise :class:`~consistid.errors.OptionError`, never a silent choice.
    """
    if given is None:
        return RegressorSpec.make(model, DEFAULT_FRICTION if _is_auto(friction) else friction,
                                  False if _is_auto(armature) else armature)
    probe = RegressorSpec.make(model, None if _is_auto(friction) else friction,
                               False if _is_auto(armature) else armature)
    own = dict(given.masks)
    stated = [t for t, _ in probe.masks
              if not _is_auto(armature if t == "armature" else friction)]
    differs = [t for t, m in probe.masks if t in stated and m != own[t]]
    if differs:
        raise OptionError(f"friction/armature describe other per-joint columns ({differs}: "
                          f"{probe.describe()}) than the identification result's "
                          f"({given.describe()}); leave them out: they are taken from the result")
    return given


def parameter_names(model: RobotModel, spec: RegressorSpec) -> list[str]:
    """Names of all regressor columns: rigid-body block, then per-joint blocks."""
    return [*model.parameter_names, *spec.joint_column_names(model.joint_names)]


def prior_vector(model: RobotModel, spec: RegressorSpec) -> np.ndarray:
    """The CAD prior extended by zeros for the per-joint (friction, offset, position, armature)
    columns."""
    return np.concatenate([model.prior_parameters, np.zeros(spec.n_joint_columns)])


def joint_signal(suffix: str, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray,
                 sign: np.ndarray | None = None) -> np.ndarray:
    """The per-joint signal multiplying the coefficient ``suffix``, for samples ``(n,)``.

    ``sign``: the Coulomb signal ``sign(q̇)`` as the torque channel sees it, when the signal
    chain low-pass filtered the torques (:attr:`consistid.data.dataset.Dataset.dq_sign`, the
    same filter applied to ``sign(q̇)``: parallel filtering, Gautier 1997); ``None``:
    ``sign(dq)``."""
    if suffix == "fc":
        return np.sign(dq) if sign is None else sign
    if suffix == "fv":
        return dq
    if suffix == "fo":
        return np.ones_like(dq)
    if suffix == "ps1":
        return np.sin(q)
    if suffix == "pc1":
        return np.cos(q)
    return ddq                                                     # "Ia"


def _sign_of(dq_sign: np.ndarray | None, j: int) -> np.ndarray | None:
    return None if dq_sign is None else dq_sign[:, j]


def joint_columns(q: np.ndarray, dq: np.ndarray, ddq: np.ndarray,
                  spec: RegressorSpec, out: np.ndarray | None = None,
                  dq_sign: np.ndarray | None = None) -> np.ndarray:
    """The per-joint blocks for samples ``(N, nv)`` as an array ``(N, nv, n_joint_columns)``
    (``out``: a preallocated one to fill; ``dq_sign``: the Coulomb signal, see
    :func:`joint_signal`). Each signal is computed for its joint's column only:
    ``(N, nv, c)`` zeros plus one strided copy per column, no per-term ``(N, nv)`` arrays."""
    n, nv = dq.shape
    if out is None:
        out = np.zeros((n, nv, spec.n_joint_columns))
    else:
        out[...] = 0.0
    for c, (_, j, suffix) in enumerate(spec.columns):
        out[:, j, c] = joint_signal(suffix, q[:, j], dq[:, j], ddq[:, j], _sign_of(dq_sign, j))
    return out


def joint_torque(q: np.ndarray, dq: np.ndarray, ddq: np.ndarray, spec: RegressorSpec,
                 coefficients: np.ndarray, dq_sign: np.ndarray | None = None) -> np.ndarray:
    """``Σ_c coefficient_c · signal_c`` of the per-joint columns, shape ``(N, nv)``: their part
    of ``Y θ`` without building the ``(N, nv, n_joint_columns)`` block (``dq_sign``: the
    Coulomb signal, see :func:`joint_signal`)."""
    out = np.zeros(dq.shape)
    for c, (_, j, suffix) in enumerate(spec.columns):
        if coefficients[c] != 0.0:
            out[:, j] += coefficients[c] * joint_signal(suffix, q[:, j], dq[:, j], ddq[:, j],
                                                        _sign_of(dq_sign, j))
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
    if m.nq != m.nv:
        q = np.array([model.configuration(row) for row in q])
    # one Pinocchio call and one copy per sample: rows of q, dq, ddq and out iterated together
    # (no per-sample indexing), the function looked up once
    fill = pin.computeJointTorqueRegressor
    for qk, dqk, ddqk, row in zip(q, dq, ddq, out):
        row[...] = fill(m, data, qk, dqk, ddqk)
    return out


def check_states(model: RobotModel, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(q, dq, ddq)`` as float arrays ``(N, nv)`` (one sample may be 1-D), checked: joint
    count, equal shapes, finite values within ``±MAX_ABS``. Raises :class:`JointCountError` or
    :class:`DatasetError` naming the array, sample and joint."""
    q, dq, ddq = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (q, dq, ddq))
    if q.shape[1] != model.nv:
        raise JointCountError(f"q has {q.shape[1]} joints but {model.name} has {model.nv}")
    for name, a in (("dq", dq), ("ddq", ddq)):
        if a.shape != q.shape:
            raise JointCountError(f"{name} has shape {a.shape} but q has {q.shape}")
    for name, a in (("q", q), ("dq", dq), ("ddq", ddq)):
        if np.all(np.abs(a) <= MAX_ABS):       # the common case: one reduction, no index list
            continue
        bad = np.argwhere(~(np.abs(a) <= MAX_ABS))     # NaN, ±inf, or beyond MAX_ABS
        k, j = (int(i) for i in bad[0])
        raise DatasetError(f"{name}[{k}, {model.joint_names[j]!r}] = {a[k, j]:.3g}: not a "
                           f"finite joint value within ±{MAX_ABS:.0e} (SI units); "
                           f"{len(bad)} such value(s) in {name}")
    return q, dq, ddq


def fill_regressor(model: RobotModel, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray,
                   spec: RegressorSpec, out: np.ndarray, joint_zeroed: bool = False,
                   dq_sign: np.ndarray | None = None) -> None:
    """Write the regressor of checked samples (:func:`check_states`) into ``out[:, :, :p]``
    (``out`` of shape ``(N, nv, ≥ p)``, e.g. a reused buffer with room for the torques).
    ``joint_zeroed``: the per-joint block's structurally zero entries are already 0 (a buffer
    this function filled before), so only the ``(joint, column)`` entries that carry a signal
    are written. ``dq_sign``: the Coulomb signal (:func:`joint_signal`)."""
    n_in = model.n_inertial
    rigid_body_regressor(model, q, dq, ddq, out=out[:, :, :n_in])
    if not spec.n_joint_columns:
        return
    if not joint_zeroed:
        out[:, :, n_in:n_in + spec.n_joint_columns] = 0.0
    for c, (_, j, suffix) in enumerate(spec.columns):
        out[:, j, n_in + c] = joint_signal(suffix, q[:, j], dq[:, j], ddq[:, j],
                                           _sign_of(dq_sign, j))


def regressor(model: RobotModel, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray,
              spec: RegressorSpec | None = None, out: np.ndarray | None = None,
              dq_sign: np.ndarray | None = None) -> np.ndarray:
    """The stacked regressor ``Y``, shape ``(N·nv, p)``, rows sample-major.

    Parameters
    ----------
    q, dq, ddq : (N, nv) joint angles, velocities, accelerations (one sample may be 1-D).
    spec : which per-joint columns to append; default rigid body only.
    out : optional preallocated ``(N, nv, p)`` array to fill (avoids a copy for large N).
    dq_sign : (N, nv) the Coulomb signal as the torques see it (:func:`joint_signal`); default
        ``sign(dq)``.
    """
    q, dq, ddq = check_states(model, q, dq, ddq)
    spec = spec or RegressorSpec.make(model, friction=None)
    n, p = q.shape[0], model.n_inertial + spec.n_joint_columns
    y = np.empty((n, model.nv, p)) if out is None else out
    fill_regressor(model, q, dq, ddq, spec, y, dq_sign=dq_sign)
    return y.reshape(n * model.nv, p)


def dataset_regressor(model: RobotModel, dataset: Dataset,
                      spec: RegressorSpec | None = None) -> np.ndarray:
    """:func:`regressor` of a dataset's samples (checks the joint count)."""
    dataset.check_joints(model.nv, model.joint_names)
    return regressor(model, dataset.q, dataset.dq, dataset.ddq, spec, dq_sign=dataset.dq_sign)


#: Byte budget of a regressor buffer (:func:`default_chunk`).
CHUNK_BYTES = 64 * 2 ** 20


def default_chunk(model: RobotModel, spec: RegressorSpec) -> int:
    """Samples per regressor buffer: 4096, fewer (≥ 1024) when ``(chunk, nv, p)`` doubles would
    exceed :data:`CHUNK_BYTES` (a 32-body robot's 4096 samples are 436 MB, whose first touch
    costs more than a smaller buffer's extra chunks)."""
    row_bytes = 8 * model.nv * (model.n_inertial + spec.n_joint_columns)
    return int(min(4096, max(1024, CHUNK_BYTES // max(row_bytes, 1))))


def iter_regressor(model: RobotModel, dataset: Dataset, spec: RegressorSpec,
                   chunk: int | None = None) -> Iterator[tuple[slice, np.ndarray]]:
    """Yield ``(sample slice, Y_chunk)`` with ``Y_chunk`` of shape ``(n, nv, p)``: O(chunk) memory
    (default :func:`default_chunk`).

    The chunks share one buffer: each yielded array is overwritten by the next one (read it,
    do not write into it: the structurally zero entries of its per-joint block are written
    once, for the first chunk).
    """
    dataset.check_joints(model.nv, model.joint_names)
    chunk = default_chunk(model, spec) if chunk is None else chunk
    buffer = np.empty((min(chunk, dataset.n_samples), model.nv,
                       model.n_inertial + spec.n_joint_columns))
    for start in range(0, dataset.n_samples, chunk):
        s = slice(start, min(start + chunk, dataset.n_samples))
        y = buffer[: s.stop - s.start]
        q, dq, ddq = check_states(model, dataset.q[s], dataset.dq[s], dataset.ddq[s])
        fill_regressor(model, q, dq, ddq, spec, y, joint_zeroed=start > 0,
                       dq_sign=None if dataset.dq_sign is None else dataset.dq_sign[s])
        yield s, y


def iter_filtered(model: RobotModel, dataset: Dataset, spec: RegressorSpec,
                  chunk: int | None = None
                  ) -> Iterator[tuple[slice, np.ndarray, np.ndarray]]:
    """Yield ``(samples, Y, τ)`` as least squares sees them: ``Y`` ``(n, nv, p)`` and ``τ``
    ``(n, nv)`` of consecutive samples through the dataset's identification low-pass
    (``Dataset.identification_filter``, parallel filtering: :mod:`consistid.data.parallel`,
    windows padded within each run; memory ``O(chunk + rate/f_p)``), or as they are
    (:func:`iter_regressor`'s chunks) when it records none. Fresh arrays each time."""
    dataset.check_joints(model.nv, model.joint_names)
    tau = dataset.require_torque()
    chunk = default_chunk(model, spec) if chunk is None else chunk
    cutoff, order = dataset.identification_filter or (None, 4)
    p = model.n_inertial + spec.n_joint_columns
    for w in plan(dataset.t, dataset.segment, cutoff, chunk):
        s = w.rows
        y = np.empty((s.stop - s.start, model.nv, p))
        q, dq, ddq = check_states(model, dataset.q[s], dataset.dq[s], dataset.ddq[s])
        fill_regressor(model, q, dq, ddq, spec, y,
                       dq_sign=None if dataset.dq_sign is None else dataset.dq_sign[s])
        yield w.kept, w.apply(y, cutoff, order), w.apply(tau[s], cutoff, order)


def residual_torque(model: RobotModel, dataset: Dataset, spec: RegressorSpec,
                    theta: np.ndarray) -> np.ndarray:
    """``τ − Y θ`` (N, nv) as least squares sees it: through the dataset's identification
    low-pass ``H`` per run when it records one (``Dataset.identification_filter``), which is
    ``Hτ − (HY) θ`` since ``H`` is linear (:mod:`consistid.data.parallel`); else as it is."""
    residual = dataset.require_torque() - predict_torque(model, dataset, spec, theta)
    flt = dataset.identification_filter
    return residual if flt is None else lowpass_runs(dataset.t, dataset.segment, residual, *flt)


def column_support(model: RobotModel, spec: RegressorSpec) -> np.ndarray:
    """Which columns of joint ``j``'s rows can be non-zero, for any motion: shape ``(nv, p)``.

    The torque of joint ``j`` is its axis applied to the spatial forces of the bodies it carries
    (RNEA's backward pass, Featherstone 2008, §5.3), so body ``k``'s ten columns can be non-zero
    in joint ``j``'s rows only when body ``k`` lies in joint ``j``'s subtree; a per-joint column
    (friction, offset, armature) only in its own joint's rows. On a serial 7-DoF arm with three
    friction columns per joint this leaves 13–73 of 91 columns per joint (41 % of the flops of a
    dense QR).
    """
    m = model.pin_model
    support = np.zeros((model.nv, model.n_inertial + spec.n_joint_columns), dtype=bool)
    for joint in range(1, m.njoints):
        carried = [k - 1 for k in m.subtrees[joint]]              # body k ↔ pinocchio joint k+1
        cols = np.concatenate([np.arange(10 * k, 10 * k + 10) for k in carried])
        for v in range(m.joints[joint].idx_v, m.joints[joint].idx_v + m.joints[joint].nv):
            support[v, cols] = True
    for c, (_, j, _) in enumerate(spec.columns):
        support[j, model.n_inertial + c] = True
    return support


def batch_rnea(model: RobotModel, carrier: pin.Model, q: np.ndarray, dq: np.ndarray,
               ddq: np.ndarray, chunk: int = 65536) -> np.ndarray:
    """``pinocchio.rnea(carrier, q_k, dq_k, ddq_k)`` for every sample, shape ``(N, nv)``.

    ``pinocchio.rneaInParallel`` on one thread (the samples as columns, Fortran order), in
    chunks of ``chunk`` samples; ``model`` maps angles to Pinocchio configurations for
    continuous joints (``nq ≠ nv``). The same numbers as a loop of ``pinocchio.rnea`` calls,
    without the Python call per sample."""
    n = q.shape[0]
    out = np.empty((n, carrier.nv))
    if not hasattr(pin, "rneaInParallel"):   # a Pinocchio built without it: the same loop
        data = carrier.createData()
        for k in range(n):
            qk = q[k] if carrier.nq == carrier.nv else model.configuration(q[k])
            out[k] = pin.rnea(carrier, data, qk, dq[k], ddq[k])
        return out
    pool = pin.ModelPool(carrier, 1)
    for start in range(0, n, chunk):
        s = slice(start, min(start + chunk, n))
        qs = q[s] if carrier.nq == carrier.nv else np.array(
            [model.configuration(row) for row in q[s]])
        tau = np.empty((carrier.nv, s.stop - s.start), order="F")
        pin.rneaInParallel(1, pool, np.asfortranarray(qs.T), np.asfortranarray(dq[s].T),
                           np.asfortranarray(ddq[s].T), tau)
        out[s] = tau.T
    return out


def predict_torque(model: RobotModel, dataset: Dataset, spec: RegressorSpec, theta: np.ndarray,
                   chunk: int | None = None) -> np.ndarray:
    """``Y(q, q̇, q̈) θ`` for a dataset's samples, shape (N, nv).

    The rigid-body part is ``pinocchio.rnea`` of the model carrying ``θ``'s inertias (armature
    zeroed: the regressor has none), about a third of the cost of building the regressor, over
    all samples in one call (``pinocchio.rneaInParallel`` on one thread: no Python loop); the
    per-joint columns are added directly (:func:`joint_torque`). ``rnea`` is linear in each body's
    ``(m, h, I)`` whatever their physical consistency, but Pinocchio stores a body as mass, CoM
    and inertia about the CoM, so a body whose mass is ~0 (its CoM undefined) falls back to the
    regressor, built chunk by chunk (:func:`iter_regressor`; memory O(chunk·nv·p)).
    """
    theta = np.asarray(theta, dtype=float)
    masses = theta[:model.n_inertial:10]
    scale = max(float(np.max(np.abs(masses), initial=0.0)), 1e-300)
    if np.all(np.abs(masses) > 1e-9 * scale):
        dataset.check_joints(model.nv, model.joint_names)
        carrier = model.with_parameters(theta[:model.n_inertial]).pin_model
        carrier.armature[:] = 0.0
        out = batch_rnea(model, carrier, dataset.q, dataset.dq, dataset.ddq)
        if spec.n_joint_columns:
            out += joint_torque(dataset.q, dataset.dq, dataset.ddq, spec,
                                theta[model.n_inertial:], dataset.dq_sign)
        return out
    out = np.empty((dataset.n_samples, model.nv))
    for s, y in iter_regressor(model, dataset, spec, chunk):
        out[s] = y @ theta
    return out

r"""Limits an excitation trajectory must respect, evaluated on sampled states with margins.

Following Rackl, Lampariello, Hirzinger 2012 (ICRA, doi:10.1109/ICRA.2012.6225279):

* joint limits, eq. 18: ``h_min ≤ h_i(t) ≤ h_max`` for ``h ∈ {q, q̇, q̈, τ}``; the torque is the
  prior model's inverse dynamics ``τ = RNEA(q, q̇, q̈)`` (Pinocchio, armature included);
* a Cartesian workspace box, eq. 16: ``x_min ≤ x_f(q) ≤ x_max`` for chosen frames ``f``
  (default the end effector);
* a self-collision keep-out sphere around the base, eq. 17: ``‖x_f(q) − c‖ ≥ r``;
* a floor plane ``z_f(q) ≥ z_min`` for chosen frames (the Maestro write-up's ground constraint).

Every constraint is written as a *margin* that is ≥ 0 when satisfied, in physical units (rad,
rad/s, rad/s², N·m, m), with a scale that makes it dimensionless for the optimiser (joint range,
velocity/acceleration/torque limit, 1 m); a joint bounded on one side only has the scale 2π.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
import pinocchio as pin

from ..errors import ExcitationError, InfeasibleExcitationError, ModelError
from ..robot.model import RobotModel
from .trajectory import DEFAULT_ACCELERATION_LIMIT, joint_vector, position_range


def end_effector_frame(model: RobotModel) -> str:
    """The default end-effector frame: the outermost frame carried by the last joint.

    Among the ``BODY`` and ``OP_FRAME`` frames whose parent joint is the model's last joint,
    the one furthest from that joint's origin (a tie, within 1 nm, goes to the frame defined
    last). So fingers, which sit nearer the wrist than the tool point, are not picked: Panda
    ``panda_hand_tcp``, UR ``tool0``, Kinova ``j2s6s200_end_effector`` (not a finger tip, the
    last body frame in the URDF).

    Raises
    ------
    ModelError : no body or operational frame is attached to the last joint.
    """
    pm = model.pin_model
    last = pm.njoints - 1
    kinds = (pin.FrameType.BODY, pin.FrameType.OP_FRAME)
    candidates = [(round(float(np.linalg.norm(f.placement.translation)), 9), k)
                  for k, f in enumerate(pm.frames) if f.parentJoint == last and f.type in kinds]
    if not candidates:
        raise ModelError(f"{model.name}: no body or operational frame is attached to the last "
                         f"joint {pm.names[last]!r}; name the end-effector frame (frames=...)")
    return pm.frames[max(candidates)[1]].name


def _point(name: str, value: Sequence[float]) -> tuple[float, ...]:
    """3 finite numbers as a tuple (so that shapes compare with ``==``), else ExcitationError."""
    try:
        out = tuple(float(v) for v in np.asarray(value, dtype=float).reshape(-1))
    except (TypeError, ValueError):
        out = ()
    if len(out) != 3 or not np.all(np.isfinite(out)):
        raise ExcitationError(f"{name} must be 3 finite numbers (m, base frame), got {value!r}")
    return out


def _frames(value: Sequence[str] | str | None) -> tuple[str, ...] | None:
    return None if value is None else (value,) if isinstance(value, str) else tuple(value)


@dataclass(frozen=True)
class CartesianBox:
    """Workspace box ``lower ≤ x_f ≤ upper`` (m, base frame) for ``frames`` (default: end
    effector), Rackl et al. 2012 eq. 16. Corners are stored as tuples (shapes compare with
    ``==``, whatever sequence or array they were given as)."""

    lower: Sequence[float]
    upper: Sequence[float]
    frames: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        lower, upper = _point("CartesianBox.lower", self.lower), _point("CartesianBox.upper",
                                                                        self.upper)
        if any(lo > hi for lo, hi in zip(lower, upper)):
            raise ExcitationError(f"CartesianBox needs lower ≤ upper, got {lower} and {upper}")
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)
        object.__setattr__(self, "frames", _frames(self.frames))


@dataclass(frozen=True)
class FloorPlane:
    """Floor ``z_f ≥ z_min`` (m, base frame) for ``frames`` (default: end effector)."""

    z_min: float
    frames: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.z_min, (int, float, np.integer, np.floating)) \
                or not np.isfinite(self.z_min):
            raise ExcitationError(f"FloorPlane.z_min must be a finite number (m), got "
                                  f"{self.z_min!r}")
        object.__setattr__(self, "z_min", float(self.z_min))
        object.__setattr__(self, "frames", _frames(self.frames))


@dataclass(frozen=True)
class KeepOutSphere:
    """Self-collision sphere ``‖x_f − centre‖ ≥ radius`` (m) for ``frames`` (default: end
    effector), Rackl et al. 2012 eq. 17; the centre defaults to the base origin."""

    radius: float
    centre: Sequence[float] = (0.0, 0.0, 0.0)
    frames: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.radius, (int, float, np.integer, np.floating)) \
                or not np.isfinite(self.radius) or self.radius <= 0:
            raise ExcitationError(f"KeepOutSphere.radius must be a finite number > 0 (m), got "
                                  f"{self.radius!r}")
        object.__setattr__(self, "radius", float(self.radius))
        object.__setattr__(self, "centre", _point("KeepOutSphere.centre", self.centre))
        object.__setattr__(self, "frames", _frames(self.frames))


@dataclass(frozen=True, eq=False)
class ExcitationLimits:
    """All limits of an excitation design, per joint in SI units.

    Attributes
    ----------
    lower, upper : (nv,) joint position limits (rad or m); ``±inf`` for unbounded joints.
    velocity, acceleration : (nv,) symmetric limits on ``|q̇|``, ``|q̈|``; ``inf`` for none.
    torque : (nv,) symmetric limit on ``|τ|`` of the prior model (``inf``: that joint's torque
        is not checked), or ``None`` (no torque is checked).
    workspace, floor, sphere : optional Cartesian constraints.
    """

    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    torque: np.ndarray | None = None
    workspace: CartesianBox | None = None
    floor: FloorPlane | None = None
    sphere: KeepOutSphere | None = None

    @classmethod
    def from_model(cls, model: RobotModel,
                   acceleration: float | Sequence[float] = DEFAULT_ACCELERATION_LIMIT,
                   velocity: float | Sequence[float] | None = None,
                   torque: bool | float | Sequence[float] = True,
                   lower: float | Sequence[float] | None = None,
                   upper: float | Sequence[float] | None = None,
                   workspace: CartesianBox | None = None, floor: FloorPlane | None = None,
                   sphere: KeepOutSphere | None = None) -> "ExcitationLimits":
        """Limits from the URDF (position, velocity, effort), overridden where given.

        Parameters
        ----------
        acceleration : rad/s² (URDFs have none; default :data:`DEFAULT_ACCELERATION_LIMIT`).
        velocity, lower, upper : override the URDF's values (scalar or per joint).
        torque : ``True`` for the URDF effort limits, ``False`` for no torque check, or values
            (``inf`` for a joint without one). ``torque`` is ``None`` when no limit is finite
            (e.g. a URDF without efforts, which :attr:`RobotModel.limits` reads as ``inf``).
        """
        lim, nv = model.limits, model.nv
        if torque is True:
            tau = lim.effort.copy()
        elif torque is False or torque is None:
            tau = None
        else:
            tau = joint_vector("torque limit", torque, nv, allow_infinite=True)
        if tau is not None and not np.isfinite(tau).any():
            tau = None
        lower_v = lim.lower.copy() if lower is None else joint_vector("lower", lower, nv, True)
        upper_v = lim.upper.copy() if upper is None else joint_vector("upper", upper, nv, True)
        for label, given, side in (("lower", lower_v, -1.0), ("upper", upper_v, 1.0)):
            urdf = lim.lower if side < 0 else lim.upper
            # widening is allowed (inf: no limit), but a finite bound past the URDF's and past
            # one turn is what degrees given for radians look like
            turn = np.isfinite(given) & (np.abs(given) > 2 * np.pi)   # no inf − inf below
            beyond = np.flatnonzero(turn & (side * (np.where(turn, given, 0.0) - urdf) > 1e-9))
            if beyond.size:
                j = int(beyond[0])
                raise ExcitationError(
                    f"{label} = {given[j]:.4g} rad for joint {model.joint_names[j]!r} lies beyond "
                    f"the URDF's {label} limit {urdf[j]:.4g} rad and beyond one turn: limits "
                    "are in radians (np.radians(...) if these are degrees); for a joint "
                    "without that limit give inf")
        return cls(
            lower=lower_v,
            upper=upper_v,
            velocity=lim.velocity.copy() if velocity is None else joint_vector(
                "velocity limit", velocity, nv, allow_infinite=True),
            acceleration=joint_vector("acceleration limit", acceleration, nv),
            torque=tau, workspace=workspace, floor=floor, sphere=sphere)

    @property
    def checks_torque(self) -> bool:
        """Whether some joint has a finite torque limit (the torque block is evaluated)."""
        return self.torque is not None and bool(np.isfinite(self.torque).any())

    def validate(self, model: RobotModel) -> None:
        """Raise :class:`InfeasibleExcitationError` naming the joint when a limit leaves no room
        to move (non-positive velocity/acceleration/torque limit, ``lower ≥ upper``), and
        :class:`ModelError` for an unknown frame."""
        names = model.joint_names
        for label, values in (("lower", self.lower), ("upper", self.upper),
                              ("velocity", self.velocity), ("acceleration", self.acceleration),
                              ("torque", self.torque)):
            if values is not None and np.shape(values) != (model.nv,):
                raise InfeasibleExcitationError(f"{label} limits have shape {np.shape(values)};"
                                                f" {model.name} has {model.nv} joints")
        for what, values in (("velocity", self.velocity), ("acceleration", self.acceleration),
                             ("torque", self.torque)):
            if values is None:
                continue
            bad = np.flatnonzero(~(np.asarray(values) > 0))
            if bad.size:
                j = int(bad[0])
                raise InfeasibleExcitationError(
                    f"{what} limit of joint {names[j]!r} is {values[j]!r}: the joint cannot move "
                    f"({bad.size} joint(s) with a non-positive {what} limit)")
        bad = np.flatnonzero(~(self.lower < self.upper))
        if bad.size:
            j = int(bad[0])
            raise InfeasibleExcitationError(
                f"position limits of joint {names[j]!r} leave no range: lower "
                f"{self.lower[j]!r} ≥ upper {self.upper[j]!r}")
        for c in (self.workspace, self.floor, self.sphere):
            for frame in (c.frames or ()) if c is not None else ():
                if not model.pin_model.existFrame(frame):
                    raise ModelError(f"unknown frame {frame!r} in excitation limits")
        if self.workspace is not None and not np.all(
                np.asarray(self.workspace.lower) < np.asarray(self.workspace.upper)):
            raise InfeasibleExcitationError(f"workspace box lower {list(self.workspace.lower)} "
                                            f"is not below upper {list(self.workspace.upper)}")
        if self.sphere is not None and not self.sphere.radius >= 0:
            raise InfeasibleExcitationError(f"keep-out sphere radius {self.sphere.radius} < 0")


@dataclass(frozen=True, eq=False)
class ConstraintBlock:
    """Margins of one kind of constraint at N samples.

    Attributes
    ----------
    kind : ``"position" | "velocity" | "acceleration" | "torque" | "workspace" | "floor" |
        "self-collision"``.
    labels : (k,) what each column constrains, e.g. ``"panda_joint3 upper"``.
    values : (N, k) margins in physical units, ≥ 0 when satisfied.
    scale : (k,) normalisation (joint range, limit, or 1 m).
    derivative : (N, k, 3, nv) derivative of each margin w.r.t. the sample's ``(q, q̇, q̈)``, or
        ``None`` when not requested.
    linear : the margins are affine in ``(q, q̇, q̈)`` (joint limits).
    """

    kind: str
    labels: tuple[str, ...]
    values: np.ndarray
    scale: np.ndarray
    derivative: np.ndarray | None = field(default=None, repr=False)
    linear: bool = False


@dataclass(frozen=True)
class Margin:
    """The worst margin of one kind of constraint over a trajectory."""

    kind: str
    value: float          # physical units
    relative: float       # value / scale
    label: str
    time: float

    @property
    def satisfied(self) -> bool:
        return self.relative >= -1e-9


@dataclass(frozen=True)
class ConstraintReport:
    """Worst margins per constraint kind on a (dense) time grid."""

    margins: tuple[Margin, ...]
    n_samples: int

    def __post_init__(self) -> None:
        for m in self.margins:
            if np.isnan(m.value) or np.isnan(m.relative):
                raise ExcitationError(f"{m.kind} margin of {m.label!r} at t = {m.time:g} s is "
                                      f"NaN (value {m.value}, relative {m.relative}): a limit "
                                      "or the trajectory is not a number")

    @property
    def feasible(self) -> bool:
        return all(m.satisfied for m in self.margins)

    @property
    def min_relative_margin(self) -> float:
        return min((m.relative for m in self.margins), default=np.inf)

    def __getitem__(self, kind: str) -> Margin:
        for m in self.margins:
            if m.kind == kind:
                return m
        raise KeyError(f"no {kind!r} constraint; kinds are {[m.kind for m in self.margins]}")

    def __str__(self) -> str:
        units = {"position": "rad", "velocity": "rad/s", "acceleration": "rad/s²",
                 "torque": "N·m", "workspace": "m", "floor": "m", "self-collision": "m"}
        lines = [f"constraints on {self.n_samples} samples: "
                 f"{'all satisfied' if self.feasible else 'VIOLATED'}",
                 f"  {'kind':<15}{'worst margin':>16}{'relative':>10}  {'where':<28}{'t (s)':>8}"]
        for m in self.margins:
            lines.append(f"  {m.kind:<15}{m.value:>10.4g} {units.get(m.kind, ''):<6}"
                         f"{m.relative * 100:>9.2f}%  {m.label:<28}{m.time:>8.3f}")
        return "\n".join(lines)


class ConstraintSet:
    """Evaluates the margins of :class:`ExcitationLimits` for a model on sampled states."""

    def __init__(self, model: RobotModel, limits: ExcitationLimits) -> None:
        limits.validate(model)
        self.model, self.limits = model, limits
        ee = end_effector_frame(model)
        self._frames: dict[str, int] = {}
        self.cartesian = []
        for kind, c in (("workspace", limits.workspace), ("floor", limits.floor),
                        ("self-collision", limits.sphere)):
            if c is None:
                continue
            frames = tuple(c.frames) if c.frames else (ee,)
            for f in frames:
                self._frames.setdefault(f, model.pin_model.getFrameId(f))
            self.cartesian.append((kind, c, frames))

    # ----------------------------------------------------------------------------- joint limits
    def _joint_blocks(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray,
                      derivatives: bool) -> list[ConstraintBlock]:
        lim, names, nv = self.limits, self.model.joint_names, self.model.nv
        n = q.shape[0]
        out = []
        lo_range, hi_range = position_range(lim.lower, lim.upper)
        span = hi_range - lo_range            # 2π for a joint bounded on one side only
        specs = [("position", 0, q, lim.lower, lim.upper, span),
                 ("velocity", 1, dq, -lim.velocity, lim.velocity, lim.velocity),
                 ("acceleration", 2, ddq, -lim.acceleration, lim.acceleration, lim.acceleration)]
        for kind, order, x, lo, hi, scale in specs:
            labels, values, sc, sign_joint = [], [], [], []
            for j in range(nv):
                if np.isfinite(lo[j]):
                    labels.append(f"{names[j]} lower")
                    values.append(x[:, j] - lo[j])
                    sign_joint.append((1.0, j))
                    sc.append(scale[j])
                if np.isfinite(hi[j]):
                    labels.append(f"{names[j]} upper")
                    values.append(hi[j] - x[:, j])
                    sign_joint.append((-1.0, j))
                    sc.append(scale[j])
            if not labels:
                continue
            deriv = None
            if derivatives:
                deriv = np.zeros((n, len(labels), 3, nv))
                for r, (s, j) in enumerate(sign_joint):
                    deriv[:, r, order, j] = s
            out.append(ConstraintBlock(kind, tuple(labels), np.column_stack(values),
                                       np.asarray(sc, dtype=float), deriv, linear=True))
        return out

    # ----------------------------------------------------------------------------- torque
    def _torque_block(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray,
                      derivatives: bool) -> ConstraintBlock:
        n, nv = q.shape
        deriv = None
        if derivatives:
            m = self.model.pin_model
            data = m.createData()
            tau = np.empty((n, nv))
            deriv = np.empty((n, 2 * nv, 3, nv))
            for k in range(n):
                qk = self.model.configuration(q[k])
                dtau_dq, dtau_dv, mass = pin.computeRNEADerivatives(m, data, qk, dq[k], ddq[k])
                tau[k] = data.tau
                d = np.stack([dtau_dq, dtau_dv, mass], axis=1)        # (nv, 3, nv)
                deriv[k, :nv], deriv[k, nv:] = d, -d
        else:
            tau = self.model.rnea(q, dq, ddq)
        # joints without a limit (inf) get no column: their margins would be inf/inf = NaN
        checked = np.flatnonzero(np.isfinite(self.limits.torque))
        limit = self.limits.torque[checked]
        names = [self.model.joint_names[j] for j in checked]
        labels = [f"{j} lower" for j in names] + [f"{j} upper" for j in names]
        values = np.hstack([tau[:, checked] + limit, limit - tau[:, checked]])
        if deriv is not None:
            deriv = deriv[:, np.concatenate([checked, nv + checked])]
        return ConstraintBlock("torque", tuple(labels), values, np.concatenate([limit, limit]),
                               deriv)

    # ----------------------------------------------------------------------------- Cartesian
    def _cartesian_blocks(self, q: np.ndarray, derivatives: bool) -> list[ConstraintBlock]:
        m = self.model.pin_model
        data = m.createData()
        n, nv = q.shape
        ids = list(self._frames.values())
        pos = np.empty((n, len(ids), 3))
        jac = np.empty((n, len(ids), 3, nv)) if derivatives else None
        for k in range(n):
            qk = self.model.configuration(q[k])
            if derivatives:
                pin.computeJointJacobians(m, data, qk)
            else:
                pin.forwardKinematics(m, data, qk)
            for i, fid in enumerate(ids):
                pos[k, i] = pin.updateFramePlacement(m, data, fid).translation
                if derivatives:
                    jac[k, i] = pin.getFrameJacobian(m, data, fid,
                                                     pin.LOCAL_WORLD_ALIGNED)[:3]
        index = {f: i for i, f in enumerate(self._frames)}
        out = []
        for kind, c, frames in self.cartesian:
            labels, values, derivs = [], [], []
            for f in frames:
                p = pos[:, index[f]]
                jf = jac[:, index[f]] if derivatives else None     # (N, 3, nv)
                if kind == "workspace":
                    lo, hi = np.asarray(c.lower, float), np.asarray(c.upper, float)
                    for a, axis in enumerate("xyz"):
                        labels += [f"{f} {axis} ≥ {lo[a]:g}", f"{f} {axis} ≤ {hi[a]:g}"]
                        values += [p[:, a] - lo[a], hi[a] - p[:, a]]
                        if derivatives:
                            derivs += [jf[:, a], -jf[:, a]]
                elif kind == "floor":
                    labels.append(f"{f} z ≥ {c.z_min:g}")
                    values.append(p[:, 2] - c.z_min)
                    if derivatives:
                        derivs.append(jf[:, 2])
                else:
                    d = p - np.asarray(c.centre, float)
                    dist = np.linalg.norm(d, axis=1)
                    labels.append(f"{f} outside r={c.radius:g}")
                    values.append(dist - c.radius)
                    if derivatives:
                        derivs.append(np.einsum("na,nav->nv", d / np.maximum(dist, 1e-12)[:, None],
                                                jf))
            deriv = None
            if derivatives:
                deriv = np.zeros((n, len(labels), 3, nv))
                deriv[:, :, 0, :] = np.stack(derivs, axis=1)
            out.append(ConstraintBlock(kind, tuple(labels), np.column_stack(values),
                                       np.ones(len(labels)), deriv))
        return out

    # ----------------------------------------------------------------------------- all
    def blocks(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray, derivatives: bool = False,
               linear: bool | None = None) -> list[ConstraintBlock]:
        """Margins of every constraint at the samples ``(q, dq, ddq)`` (each (N, nv)).

        ``linear=True`` returns only the joint-limit blocks, ``False`` only the others, ``None``
        all of them.
        """
        out: list[ConstraintBlock] = []
        if linear in (None, True):
            out += self._joint_blocks(q, dq, ddq, derivatives)
        if linear in (None, False):
            if self.limits.checks_torque:
                out.append(self._torque_block(q, dq, ddq, derivatives))
            if self.cartesian:
                out += self._cartesian_blocks(q, derivatives)
        return out

    def report(self, t: np.ndarray, q: np.ndarray, dq: np.ndarray,
               ddq: np.ndarray) -> ConstraintReport:
        """Worst margin of each kind over the samples, with where and when it occurs."""
        margins = []
        for b in self.blocks(q, dq, ddq):
            rel = b.values / b.scale
            i, c = np.unravel_index(int(np.argmin(rel)), rel.shape)
            margins.append(Margin(b.kind, float(b.values[i, c]), float(rel[i, c]), b.labels[c],
                                  float(t[i])))
        return ConstraintReport(tuple(margins), int(np.asarray(t).size))

r"""Physical and sensor effects that a nominal rigid-body model lacks, as switches with magnitudes.

An :class:`Effects` value describes what the simulated "real robot"
(:func:`consistid.simulate.record`) adds to the rigid-body dynamics and to its sensors. Every
per-joint field is a magnitude per joint; **zero means off**. A field accepts a scalar (all
joints), a sequence of ``nv`` values, or a mapping ``{joint name or index: value}`` (other joints
off). :meth:`Effects.for_model` resolves every field to an ``(nv,)`` array and validates it;
:meth:`Effects.with_effect` switches one named effect on, which is how a caller injects effects
one at a time (e.g. to test a diagnosis blindly).

Dynamics (simulated inside MuJoCo). Signs are those of the torque the drive must *supply*, so on
a rigid joint each adds to the measured torque:

==============  ============================  ==================================================
name            field(s)                      added drive torque
==============  ============================  ==================================================
``viscous``     ``viscous`` (N·m·s/rad)       :math:`f_v\,\dot q` (MuJoCo ``dof_damping``)
``coulomb``     ``coulomb`` (N·m),            :math:`f_c\operatorname{sign}\dot q` through
                ``coulomb_model``             MuJoCo's ``frictionloss`` (a soft constraint,
                                              tuned to be exact once :math:`|\dot q|` exceeds
                                              ~0.01 rad/s at 1 kHz),
                                              or :math:`f_c\tanh(\dot q/v_s)` as an external
                                              torque (``coulomb_model="tanh"``, ``v_s`` =
                                              ``coulomb_speed``)
``stribeck``    ``static_friction`` f_s       the Stribeck curve
                (N·m, ≥ f_c),                 :math:`(f_c + (f_s - f_c)e^{-|\dot q/v_s|^δ})`
                ``stribeck_speed`` v_s        :math:`\cdot\operatorname{sign}\dot q`: MuJoCo's
                (rad/s),                      ``frictionloss`` set to :math:`f_s` (it holds the
                ``stribeck_exponent`` δ ≥ 1   joint up to f_s at rest) and, as an external
                                              torque computed per step, the relief
                                              :math:`(f_s-f_c)(1-e^{-|\dot q/v_s|^δ})`
                                              :math:`\cdot\operatorname{sign}\dot q` (zero at
                                              rest, continuous); needs
                                              ``coulomb_model="frictionloss"``
``sigmoid``     ``sigmoid_amplitude`` φ1      Gaz et al. 2019 (RA-L 4(4), eq. 8),
                (N·m), ``sigmoid_steepness``  :math:`φ_1σ(φ_2(\dot q+φ_3)) - φ_1σ(φ_2φ_3)`,
                φ2 (s/rad),                   σ the logistic function, as an external
                ``sigmoid_shift`` φ3 (rad/s)  torque computed per step
``armature``    ``armature`` (kg·m²)          :math:`I_a\,\ddot q` (MuJoCo ``dof_armature``)
``payload``     ``payload``                   a rigid body on the flange (:class:`MountedPayload`)
``elasticity``  ``stiffness`` K (N·m/rad),    a motor inertia B coupled to the link by a spring
                ``motor_inertia`` B (kg·m²),  (Spong 1987, "Modeling and control of elastic
                ``spring_damping`` D          joint robots", J. Dyn. Sys. Meas. Control 109(4),
                (N·m·s/rad)                   pp. 310–318):
                                              :math:`M(q)\ddot q + h = \tau_J`,
                                              :math:`B\ddot\theta + \tau_J = u`,
                                              :math:`\tau_J = K(\theta-q) + D(\dot\theta-\dot q)`
==============  ============================  ==================================================

On an elastic joint the drive-side effects (``viscous``, ``coulomb``, ``armature``) act on the
motor coordinate θ; the torque sensor sits at the spring and reads τ_J, so it does not see them.
On a rigid joint the measured torque is the drive torque ``u``.

Sensors (applied to the logged signals by :func:`measure_torque` and :func:`measure_position`):

==================  =========================  ==================================================
name                field                      measured signal
==================  =========================  ==================================================
``offset``          ``torque_offset`` o (N·m)  :math:`\tau_m(t) = (1+g)\,\tau(t-d) + o + \epsilon`
``gain``            ``torque_gain`` g          ``g`` the relative gain *error*,
``delay``           ``delay`` d (s)            the torque channel lagging the positions by d,
``torque_noise``    ``torque_noise`` (N·m)     :math:`\epsilon \sim \mathcal N(0, \sigma_\tau^2)`
``position_noise``  ``position_noise`` (rad)   :math:`\nu \sim \mathcal N(0, \sigma_q^2)` added
                                               to ``q_s``, then
``quantisation``    ``quantisation`` Δ (rad)   :math:`q_m = \Delta\,\mathrm{round}(q/\Delta)`
                                               (Δ one count; no rounding where Δ = 0)
==================  =========================  ==================================================

``q_s`` is the link angle, or on an elastic joint the motor angle θ when
``position_sensor="motor"`` (the default: a motor-side encoder, as on most geared arms).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Mapping, Sequence

import numpy as np
import pinocchio as pin

from ..errors import ModelError, OptionError, check_option
from ..robot.model import RobotModel

JointValues = float | Sequence[float] | Mapping[str | int, float] | np.ndarray

#: Per-joint magnitude fields of :class:`Effects`.
JOINT_FIELDS: tuple[str, ...] = (
    "viscous", "coulomb", "armature", "stiffness", "motor_inertia", "spring_damping",
    "torque_offset", "torque_gain", "delay", "torque_noise", "position_noise", "quantisation",
    "static_friction", "stribeck_speed", "stribeck_exponent", "sigmoid_amplitude",
    "sigmoid_steepness", "sigmoid_shift")
#: Per-joint fields that may be negative.
SIGNED_FIELDS: tuple[str, ...] = ("torque_offset", "sigmoid_shift")

#: Effect names (those of :mod:`consistid.diagnose` where they overlap) → field of the magnitude.
EFFECT_FIELDS: dict[str, str] = {
    "viscous": "viscous", "coulomb": "coulomb", "armature": "armature",
    "stribeck": "static_friction", "sigmoid": "sigmoid_amplitude",
    "elasticity": "stiffness", "offset": "torque_offset", "gain": "torque_gain",
    "delay": "delay", "torque_noise": "torque_noise", "position_noise": "position_noise",
    "quantisation": "quantisation",
}
#: Every effect name, including ``payload`` (set with :meth:`Effects.with_payload`).
EFFECT_NAMES: tuple[str, ...] = (*EFFECT_FIELDS, "payload")

COULOMB_MODELS = ("frictionloss", "tanh")
POSITION_SENSORS = ("motor", "link")
#: Motor inertia (kg·m², reflected to the link side) of an elastic joint when none is given.
DEFAULT_MOTOR_INERTIA = 0.5
#: Round-off (kg·m²) forgiven in the triangle inequalities of a :class:`MountedPayload`'s inertia.
PAYLOAD_INERTIA_TOL = 1e-12


@dataclass(frozen=True, eq=False)
class MountedPayload:
    """A rigid body fixed to the flange.

    Parameters
    ----------
    mass : kg, > 0.
    com : (3,) centre of mass in ``frame`` (m).
    inertia : (3, 3) symmetric rotational inertia about the CoM in the axes of ``frame``
        (kg·m²); default zero (a point mass). Its principal moments must satisfy the triangle
        inequalities ``I_1 + I_2 ≥ I_3`` (to :data:`PAYLOAD_INERTIA_TOL`), which make it
        positive *semi*-definite: a thin rod (one zero moment) and a point mass are accepted,
        and MuJoCo simulates both.
    frame : a frame of the Pinocchio model (e.g. ``"panda_hand"``); default the frame of the
        last joint. The payload moves with that frame's parent joint.

    Raises :class:`ModelError` naming the field for a bad mass, CoM or inertia.
    """

    mass: float
    com: Sequence[float] = (0.0, 0.0, 0.0)
    inertia: np.ndarray | Sequence[Sequence[float]] | None = None
    frame: str | None = None

    def __post_init__(self) -> None:
        if not (np.isfinite(self.mass) and self.mass > 0):
            raise ModelError(f"payload.mass = {self.mass!r}; it must be a positive number (kg)")
        com = np.asarray(self.com, dtype=float)
        if com.shape != (3,) or not np.isfinite(com).all():
            raise ModelError(f"payload.com = {self.com!r}; expected 3 finite coordinates (m)")
        inertia = (np.zeros((3, 3)) if self.inertia is None
                   else np.asarray(self.inertia, dtype=float))
        if inertia.shape != (3, 3) or not np.allclose(inertia, inertia.T, atol=1e-12):
            raise ModelError(f"payload.inertia must be a symmetric 3×3 matrix, got {inertia}")
        if not np.isfinite(inertia).all():
            raise ModelError(f"payload.inertia has non-finite entries: {inertia.tolist()}")
        moments = np.linalg.eigvalsh(inertia)                         # ascending
        slack = moments[0] + moments[1] - moments[2]
        if slack < -PAYLOAD_INERTIA_TOL:
            raise ModelError(f"payload.inertia violates the triangle inequality: principal "
                             f"moments {moments.tolist()} kg·m² have I1 + I2 − I3 = {slack:.3g} "
                             "< 0 (no rigid body has them)")
        object.__setattr__(self, "com", com)
        object.__setattr__(self, "inertia", inertia)

    def placement(self, model: RobotModel) -> tuple[int, pin.SE3]:
        """``(joint index, placement of the payload frame in that joint's frame)``."""
        pm = model.pin_model
        if self.frame is None:
            return model.nv - 1, pin.SE3.Identity()
        if not pm.existFrame(self.frame):
            raise ModelError(f"payload.frame {self.frame!r} is not a frame of {model.name}; "
                             f"frames are {[f.name for f in pm.frames]}")
        frame = pm.frames[pm.getFrameId(self.frame)]
        if frame.parentJoint == 0:
            raise ModelError(f"payload.frame {self.frame!r} is fixed to the base: a payload "
                             "there loads no joint")
        return frame.parentJoint - 1, frame.placement

    def parameters(self, model: RobotModel) -> tuple[int, np.ndarray]:
        """``(joint index, 10-vector)``: the payload's standard parameters in the frame of the
        joint that carries it (Pinocchio order), i.e. what it adds to that body's parameters.

        Raises :class:`ModelError` for a ``frame`` that is not in ``model`` or is fixed to the
        base (the inertia is checked when the payload is made).
        """
        joint, placement = self.placement(model)
        local = pin.Inertia(float(self.mass), np.asarray(self.com), np.asarray(self.inertia))
        return joint, np.array(placement.act(local).toDynamicParameters())


def _joint_array(name: str, value: JointValues, model: RobotModel) -> np.ndarray:
    """Resolve one per-joint field to an ``(nv,)`` float array, naming the field on error."""
    nv = model.nv
    if isinstance(value, Mapping):
        out = np.zeros(nv)
        for key, v in value.items():
            if isinstance(key, str):
                check_option(f"effects.{name} joint", key, model.joint_names)
                j = model.joint_names.index(key)
            else:
                j = int(key)
                if not 0 <= j < nv:
                    raise OptionError(f"effects.{name}: joint index {j} out of range 0..{nv - 1}")
            out[j] = float(v)
    else:
        a = np.asarray(value, dtype=float)
        if a.ndim == 0:
            out = np.full(nv, float(a))
        elif a.shape == (nv,):
            out = a.copy()
        else:
            raise ModelError(f"effects.{name} has shape {a.shape}; expected a scalar, ({nv},) "
                             f"for {model.name}'s joints, or a mapping joint → value")
    bad = np.flatnonzero(~np.isfinite(out))
    if bad.size:
        raise ModelError(f"effects.{name}[{model.joint_names[bad[0]]!r}] = {out[bad[0]]} "
                         "is not finite")
    return out


def _check_nonlinear_friction(effects: "Effects", values: dict[str, np.ndarray],
                              model: RobotModel) -> None:
    """Stribeck and sigmoid fields of resolved ``values``: raise :class:`ModelError` naming
    the field and the joint of a value the simulator cannot apply."""
    names = model.joint_names
    stribeck = values["static_friction"] > 0
    checks = [
        (stribeck & (values["static_friction"] < values["coulomb"]), "static_friction",
         "must be ≥ effects.coulomb (f_s ≥ f_c) where the Stribeck effect is on"),
        (stribeck & ~(values["stribeck_speed"] > 0), "stribeck_speed",
         "must be > 0 rad/s where static_friction > 0"),
        (stribeck & ~(values["stribeck_exponent"] >= 1), "stribeck_exponent",
         "must be ≥ 1 where static_friction > 0 (the relief torque is applied per step; "
         "below 1 its slope at rest is unbounded)"),
        ((values["sigmoid_amplitude"] > 0) & ~(values["sigmoid_steepness"] > 0),
         "sigmoid_steepness", "must be > 0 s/rad where sigmoid_amplitude > 0")]
    for bad, name, what in checks:
        if bad.any():
            j = int(np.flatnonzero(bad)[0])
            raise ModelError(f"effects.{name}[{names[j]!r}] = {values[name][j]:.6g}: it {what}")
    if stribeck.any() and effects.coulomb_model != "frictionloss":
        raise ModelError("effects.static_friction (Stribeck) needs coulomb_model="
                         f"'frictionloss' (MuJoCo holds the joint at rest), not "
                         f"{effects.coulomb_model!r}")


@dataclass(frozen=True, eq=False)
class Effects:
    """What the simulated robot adds to the nominal rigid-body model; all zero = nothing.

    Per-joint fields take a scalar, ``nv`` values, or ``{joint name or index: value}`` (the
    equations are in the module docstring). Build variants with :meth:`with_effect` and
    :meth:`with_payload`; :meth:`for_model` resolves the fields to ``(nv,)`` arrays.

    Parameters
    ----------
    viscous : N·m·s/rad, ≥ 0.
    coulomb : N·m, ≥ 0.
    coulomb_model : ``"frictionloss"`` (MuJoCo's dry friction) or ``"tanh"``.
    coulomb_speed : rad/s, > 0, the smoothing speed ``v_s`` of the ``"tanh"`` model.
    armature : kg·m², ≥ 0, rotor inertia reflected to the joint.
    payload : a :class:`MountedPayload` or ``None``.
    stiffness : N·m/rad, ≥ 0; > 0 makes the joint elastic.
    motor_inertia : kg·m², motor inertia of elastic joints (link side); 0 on an elastic joint
        means :data:`DEFAULT_MOTOR_INERTIA`.
    spring_damping : N·m·s/rad, ≥ 0, damping in parallel with the spring.
    position_sensor : ``"motor"`` or ``"link"``, the angle an elastic joint's encoder reads.
    torque_offset : N·m, either sign.
    torque_gain : relative gain error, > −1.
    delay : s, ≥ 0, lag of the torque channel behind the position channel.
    torque_noise, position_noise : standard deviations (N·m, rad), ≥ 0.
    quantisation : rad per encoder count, ≥ 0.
    static_friction : N·m, ``f_s`` of the Stribeck curve (0: no Stribeck effect on that joint;
        else ``≥ coulomb``, with ``coulomb_model="frictionloss"``).
    stribeck_speed : rad/s, > 0, ``v_s``.
    stribeck_exponent : ``δ ≥ 1`` (the relief torque is applied explicitly; below 1 its slope at
        rest is unbounded).
    sigmoid_amplitude : N·m, ``φ1 ≥ 0`` of Gaz et al.'s sigmoid (0: off).
    sigmoid_steepness : s/rad, ``φ2 > 0``.
    sigmoid_shift : rad/s, ``φ3``, either sign.

    Examples
    --------
    >>> Effects(viscous=0.3, coulomb={"panda_joint2": 1.5}, torque_noise=0.05)
    >>> Effects().with_effect("elasticity", 3000.0, joints=[1, 3])
    """

    viscous: JointValues = 0.0
    coulomb: JointValues = 0.0
    coulomb_model: str = "frictionloss"
    coulomb_speed: float = 0.05
    armature: JointValues = 0.0
    payload: MountedPayload | None = None
    stiffness: JointValues = 0.0
    motor_inertia: JointValues = 0.0
    spring_damping: JointValues = 0.0
    position_sensor: str = "motor"
    torque_offset: JointValues = 0.0
    torque_gain: JointValues = 0.0
    delay: JointValues = 0.0
    torque_noise: JointValues = 0.0
    position_noise: JointValues = 0.0
    quantisation: JointValues = 0.0
    static_friction: JointValues = 0.0
    stribeck_speed: JointValues = 0.1
    stribeck_exponent: JointValues = 2.0
    sigmoid_amplitude: JointValues = 0.0
    sigmoid_steepness: JointValues = 10.0
    sigmoid_shift: JointValues = 0.0

    def __post_init__(self) -> None:
        check_option("effects.coulomb_model", self.coulomb_model, COULOMB_MODELS)
        check_option("effects.position_sensor", self.position_sensor, POSITION_SENSORS)
        if not (np.isfinite(self.coulomb_speed) and self.coulomb_speed > 0):
            raise ModelError(f"effects.coulomb_speed = {self.coulomb_speed!r}; it must be > 0 "
                             "rad/s")
        if self.payload is not None and not isinstance(self.payload, MountedPayload):
            raise ModelError("effects.payload must be a consistid.simulate.MountedPayload (the "
                             "simulator's payload: mass, com, inertia, frame), got "
                             f"{type(self.payload).__module__}.{type(self.payload).__name__}")

    # ----------------------------------------------------------------------------- building
    def with_effect(self, name: str, magnitude: JointValues,
                    joints: Sequence[int | str] | None = None) -> "Effects":
        """A copy with effect ``name`` set to ``magnitude`` on ``joints`` (default all).

        ``name`` is a key of :data:`EFFECT_FIELDS` (``"elasticity"`` sets the stiffness); a
        payload is set with :meth:`with_payload`. With ``joints``, ``magnitude`` is a scalar,
        and the other joints keep their value for this effect only if it was given as a mapping
        (otherwise they are switched off for it).
        """
        if name == "payload":
            raise OptionError("use Effects.with_payload(MountedPayload(...)) for the payload "
                              "effect")
        check_option("effect", name, tuple(EFFECT_FIELDS))
        attr = EFFECT_FIELDS[name]
        if joints is None:
            return replace(self, **{attr: magnitude})
        if np.ndim(magnitude) != 0:
            raise OptionError(f"with_effect({name!r}, ..., joints=...) needs a scalar magnitude")
        previous = getattr(self, attr)
        value = dict(previous) if isinstance(previous, Mapping) else {}
        value.update({j: float(magnitude) for j in joints})
        return replace(self, **{attr: value})

    def with_payload(self, payload: MountedPayload | None) -> "Effects":
        """A copy with ``payload`` on the flange (``None`` removes it)."""
        return replace(self, payload=payload)

    # ----------------------------------------------------------------------------- resolving
    def for_model(self, model: RobotModel) -> "Effects":
        """A copy whose per-joint fields are ``(nv,)`` arrays for ``model``, validated.

        Raises :class:`ModelError` naming the field and the joint of a negative or non-finite
        magnitude (``torque_offset`` may be negative, ``torque_gain`` must exceed −1), of a
        motor inertia or spring damping on a joint without stiffness, or of a bad payload.
        """
        values = {name: _joint_array(name, getattr(self, name), model) for name in JOINT_FIELDS}
        for name, v in values.items():
            if name in SIGNED_FIELDS:
                continue
            bad = np.flatnonzero(v <= -1.0) if name == "torque_gain" else np.flatnonzero(v < 0)
            if bad.size:
                j = bad[0]
                raise ModelError(f"effects.{name}[{model.joint_names[j]!r}] = {v[j]:.6g}; it must "
                                 f"be {'> -1' if name == 'torque_gain' else '≥ 0'}")
        elastic = values["stiffness"] > 0
        loose = np.flatnonzero(~elastic & ((values["motor_inertia"] > 0)
                                           | (values["spring_damping"] > 0)))
        if loose.size:
            raise ModelError(f"effects: joint {model.joint_names[loose[0]]!r} has a motor inertia "
                             "or spring damping but no stiffness (it is not elastic)")
        _check_nonlinear_friction(self, values, model)
        values["motor_inertia"] = np.where(elastic & (values["motor_inertia"] == 0),
                                           DEFAULT_MOTOR_INERTIA, values["motor_inertia"])
        if self.payload is not None:
            self.payload.placement(model)  # validates the frame
        return replace(self, **values)

    @property
    def resolved(self) -> bool:
        """Whether every per-joint field is an array (the output of :meth:`for_model`)."""
        return all(isinstance(getattr(self, name), np.ndarray) for name in JOINT_FIELDS)

    def _require_resolved(self) -> None:
        if not self.resolved:
            raise ModelError("this Effects value is not resolved; call effects.for_model(model)")

    @property
    def elastic(self) -> np.ndarray:
        """(nv,) bool, the joints with a spring (needs :meth:`for_model` first)."""
        self._require_resolved()
        return np.asarray(self.stiffness) > 0

    def active(self) -> list[str]:
        """Names of the effects switched on (non-zero on some joint, or a payload)."""
        out = []
        for name, attr in EFFECT_FIELDS.items():
            v = getattr(self, attr)
            values = v.values() if isinstance(v, Mapping) else np.ravel(v)
            if any(float(x) != 0.0 for x in values):
                out.append(name)
        if self.payload is not None:
            out.append("payload")
        return out

    def describe(self) -> str:
        """One line per active effect with its magnitudes."""
        lines = []
        for name in self.active():
            if name == "payload":
                p = self.payload
                lines.append(f"payload: {p.mass:g} kg at {np.round(p.com, 4).tolist()} m in "
                             f"{p.frame or 'the last joint frame'}")
                continue
            v = getattr(self, EFFECT_FIELDS[name])
            shown = (dict(v) if isinstance(v, Mapping)
                     else np.array2string(np.asarray(v, dtype=float), precision=4))
            lines.append(f"{name}: {shown}")
        return "\n".join(lines) if lines else "no effects (the nominal rigid-body robot)"


# --------------------------------------------------------------------------------- sensor models
def measure_torque(t: np.ndarray, t_fine: np.ndarray, tau_fine: np.ndarray, effects: Effects,
                   rng: np.random.Generator) -> np.ndarray:
    r"""The torque log at times ``t`` from the true sensor torque sampled finely at ``t_fine``.

    .. math:: \tau_m(t) = (1 + g)\,\tau(t - d) + o + \epsilon

    ``τ(t − d)`` is interpolated linearly in ``(t_fine, tau_fine)``, which must reach back to
    ``t[0] − d``. ``effects`` must be resolved (:meth:`Effects.for_model`).
    """
    effects._require_resolved()
    out = np.empty((t.shape[0], tau_fine.shape[1]))
    delay = np.asarray(effects.delay)
    for j in range(out.shape[1]):
        shifted = t - delay[j]
        if shifted[0] < t_fine[0] - 1e-12:
            raise ModelError(f"effects.delay[{j}] = {delay[j]} s reaches before the start of the "
                             "simulation; simulate a longer settling time")
        out[:, j] = np.interp(shifted, t_fine, tau_fine[:, j])
    out = sensor_torque(effects, out)
    return out + np.asarray(effects.torque_noise) * rng.standard_normal(out.shape)


def measure_position(q_sensor: np.ndarray, effects: Effects,
                     rng: np.random.Generator) -> np.ndarray:
    """The position log from the sensed angle: Gaussian noise, then rounding to encoder counts."""
    effects._require_resolved()
    q = q_sensor + np.asarray(effects.position_noise) * rng.standard_normal(q_sensor.shape)
    step = np.asarray(effects.quantisation)
    return np.where(step > 0, np.round(q / np.where(step > 0, step, 1.0)) * step, q)


# --------------------------------------------------------------------------------- friction laws
def _stribeck_decay(eff: Effects, dq: np.ndarray) -> np.ndarray:
    """``e^{-|q̇/v_s|^δ}`` per joint (1 where the Stribeck effect is off, unused there)."""
    vs = np.where(np.asarray(eff.static_friction) > 0, np.asarray(eff.stribeck_speed), 1.0)
    return np.exp(-(np.abs(dq) / vs) ** np.asarray(eff.stribeck_exponent))


def _sigmoid(eff: Effects, dq: np.ndarray) -> np.ndarray:
    """Gaz et al.'s sigmoid friction per joint (module docstring), 0 where it is off."""
    a, b, c = (np.asarray(getattr(eff, f)) for f in ("sigmoid_amplitude", "sigmoid_steepness",
                                                     "sigmoid_shift"))
    return a * (_logistic(b * (dq + c)) - _logistic(b * c))


def _logistic(x: np.ndarray) -> np.ndarray:
    return 0.5 * (1.0 + np.tanh(0.5 * x))          # 1/(1 + e^{-x}) without overflow


def has_explicit_friction(effects: Effects) -> bool:
    """Whether the simulator must add a friction torque per step (:func:`explicit_friction`):
    a ``tanh`` Coulomb, a Stribeck relief or a sigmoid on some joint. ``effects`` resolved."""
    return bool((effects.coulomb_model == "tanh" and np.any(effects.coulomb))
                or np.any(effects.static_friction) or np.any(effects.sigmoid_amplitude))


def explicit_friction(effects: Effects, dq: np.ndarray) -> np.ndarray:
    r"""The friction torque the simulator applies per step outside MuJoCo's ``frictionloss``
    (the torque the drive must supply, so the simulator applies its negative), shape of ``dq``:

    .. math:: f_c	anh(\dot q/v_s)\;[	ext{tanh model}]
              \;-\;(f_s - f_c)(1 - e^{-|\dot q/v_s|^δ})\operatorname{sign}\dot q
              \;+\;φ_1ig(σ(φ_2(\dot q+φ_3)) - σ(φ_2φ_3)ig)

    With ``frictionloss = f_s`` on a Stribeck joint, the total is the Stribeck curve in motion
    and MuJoCo's dry friction (up to ``f_s``) at rest. ``effects`` must be resolved.
    """
    effects._require_resolved()
    dq = np.asarray(dq, dtype=float)
    out = _sigmoid(effects, dq)
    if effects.coulomb_model == "tanh":
        out = out + np.asarray(effects.coulomb) * np.tanh(dq / effects.coulomb_speed)
    excess = np.asarray(effects.static_friction) - np.asarray(effects.coulomb)
    relief = np.where(np.asarray(effects.static_friction) > 0, excess, 0.0)
    return out - relief * (1.0 - _stribeck_decay(effects, dq)) * np.sign(dq)


def explicit_friction_slope(effects: Effects) -> np.ndarray:
    """(nv,) bound on ``|∂/∂q̇|`` of :func:`explicit_friction` per joint (for the stability of
    applying it once per step): ``f_c/v_s`` (tanh), ``φ1 φ2 / 4`` (sigmoid) and
    ``(f_s − f_c) max_x δ x^{δ−1} e^{−x^δ} / v_s`` (Stribeck relief, ``x = |q̇|/v_s``)."""
    effects._require_resolved()
    slope = 0.25 * np.asarray(effects.sigmoid_amplitude) * np.asarray(effects.sigmoid_steepness)
    if effects.coulomb_model == "tanh":
        slope = slope + np.asarray(effects.coulomb) / effects.coulomb_speed
    on = np.asarray(effects.static_friction) > 0
    delta = np.where(on, np.asarray(effects.stribeck_exponent), 1.0)
    x = ((delta - 1.0) / delta) ** (1.0 / delta)               # maximiser of δ x^{δ−1} e^{−x^δ}
    peak = delta * x ** (delta - 1.0) * np.exp(-x ** delta)
    vs = np.where(on, np.asarray(effects.stribeck_speed), 1.0)
    excess = np.asarray(effects.static_friction) - np.asarray(effects.coulomb)
    return slope + np.where(on, excess * peak / vs, 0.0)


def friction_torque(effects: Effects, dq: np.ndarray) -> np.ndarray:
    """The dry and nonlinear friction the drive supplies in motion (viscous excluded), shape of
    ``dq``: ``f_c sign q̇`` (frictionloss, or the Stribeck curve where ``f_s > 0``), or
    ``f_c tanh(q̇/v_s)``, plus the sigmoid. ``effects`` must be resolved."""
    dq = np.asarray(dq, dtype=float)
    dry = (np.asarray(effects.coulomb) * np.sign(dq) if effects.coulomb_model == "frictionloss"
           else np.zeros_like(dq))
    static = np.asarray(effects.static_friction)
    stribeck = np.where(static > 0, (static - np.asarray(effects.coulomb))
                        * _stribeck_decay(effects, dq) * np.sign(dq), 0.0)
    tanh = (np.asarray(effects.coulomb) * np.tanh(dq / effects.coulomb_speed)
            if effects.coulomb_model == "tanh" else 0.0)
    return dry + stribeck + tanh + _sigmoid(effects, dq)


# --------------------------------------------------------------------------------- closed forms
def effect_torque(model: RobotModel, effects: Effects, q: np.ndarray, dq: np.ndarray,
                  ddq: np.ndarray) -> np.ndarray:
    r"""The drive torque the dynamic effects add to the rigid-body model, (N, nv).

    .. math:: \Delta\tau = f_v \dot q + f_c s(\dot q) + I_a \ddot q + Y_p(q,\dot q,\ddot q)\,\pi_p

    with ``s = sign`` for ``"frictionloss"`` (what MuJoCo applies once ``|q̇|`` ≳ 0.01 rad/s)
    or ``tanh(·/v_s)``, the Stribeck and sigmoid terms added (:func:`friction_torque`), and
    ``Y_p π_p`` the payload through the regressor of the body that carries it. On an elastic
    joint the drive-side terms ``f_v q̇ + f_c s + I_a q̈`` are zero: they act on the motor, and
    the torque sensor at the spring reads the link-side torque (rigid body and payload) only.
    Sensor effects are not included (see :func:`sensor_torque`).

    ``Y_p π_p`` is computed as the inverse dynamics (``pinocchio.rnea``) of a copy of the
    robot that carries the payload and nothing else (every body massless, no armature): the
    regressor is linear in the parameters, ``Y(q, q̇, q̈) π = rnea_π(q, q̇, q̈)``.
    """
    eff = effects if effects.resolved else effects.for_model(model)
    q, dq, ddq = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (q, dq, ddq))
    drive = (np.asarray(eff.viscous) * dq + friction_torque(eff, dq)
             + np.asarray(eff.armature) * ddq)
    out = np.where(eff.elastic, 0.0, drive)
    if eff.payload is not None:
        joint, p = eff.payload.parameters(model)
        carrier = model.pin_model.copy()
        # not model.with_parameters: a massless body from dynamic parameters is 0/0 (its CoM)
        for j in range(1, carrier.njoints):
            carrier.inertias[j] = pin.Inertia.Zero()
        carrier.inertias[joint + 1] = pin.Inertia.FromDynamicParameters(p)
        carrier.armature = np.zeros(model.nv)
        out += RobotModel(carrier, name=f"{model.name} payload").rnea(q, dq, ddq)
    return out


def sensor_torque(effects: Effects, tau: np.ndarray) -> np.ndarray:
    """What the torque sensor reports for the torque ``tau`` without delay and noise:
    ``(1 + g) τ + o``. ``effects`` must be resolved."""
    effects._require_resolved()
    return (1.0 + np.asarray(effects.torque_gain)) * tau + np.asarray(effects.torque_offset)

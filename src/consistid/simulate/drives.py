r"""A simulated robot that logs what a current-controlled industrial arm logs.

Motor currents through per-motor torque constants, motor-side encoders through gear ratios,
and a coupled transmission (:class:`~consistid.drives.transmission.Transmission`). Each motor is
a MuJoCo fixed tendon over the joints with coefficients ``r_m g_m`` (its length is the motor
angle ``q_m = r_m g_m^\top q``), carrying the rotor inertia as tendon ``armature``, the motor's
viscous friction as tendon ``damping`` and its Coulomb friction as tendon ``frictionloss``:
MuJoCo maps them to the joints through the tendon's moment arms, ``G^\top\operatorname{diag}(r)``,
the truth that :mod:`consistid.drives.motor_terms` models (MuJoCo documentation, "Tendon";
Todorov et al. 2012).

The controller's joint torque ``u`` is what the motors deliver; the logger turns it into motor
torques ``τ_m = G^{-\top} u / r`` and currents ``i = τ_m / k_t`` (plus the current sensor's
offset and noise, rounded to its resolution: ``i_log = step · round((i + b + ε) / step)``), and
the joint angles into motor angles ``q_m = r ⊙ (G q)`` (plus encoder rounding).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence
from xml.sax.saxutils import quoteattr

import numpy as np

from ..drives.transmission import Transmission
from ..errors import ModelError, OptionError, check_number
from ..robot.model import RobotModel
from .effects import Effects
from .experiments import DesiredMotion, SimulatedRecording, record
from .mujoco_robot import FRICTION_SOLIMP


def _per_motor(name: str, value: float | Sequence[float], n: int) -> np.ndarray:
    a = np.broadcast_to(np.asarray(value, dtype=float), (n,)).copy() if np.ndim(value) == 0 \
        else np.asarray(value, dtype=float)
    if a.shape != (n,) or not np.isfinite(a).all() or (a < 0).any():
        raise OptionError(f"{name} must be one non-negative number or one per motor ({n}), "
                          f"got {value!r}")
    return a


@dataclass(frozen=True, eq=False)
class SimulatedDrives:
    """The true drives of a simulated robot.

    Parameters
    ----------
    transmission : ratios, coupling and the true torque constants (required here).
    rotor_inertia, viscous, coulomb : per motor, motor side (kg·m², N·m·s/rad, N·m); a scalar
        for all.
    current_noise : standard deviation of the current measurement (A).
    current_offset : the current sensor's constant bias per motor (A, signed); a scalar for all.
    current_step : the current sensor's resolution (A; the logged current is rounded to it), 0
        for none.
    encoder_counts : counts per motor revolution (the motor angle is rounded to them); 0 for
        exact angles.
    """

    transmission: Transmission
    rotor_inertia: float | Sequence[float] = 0.0
    viscous: float | Sequence[float] = 0.0
    coulomb: float | Sequence[float] = 0.0
    current_noise: float = 0.0
    encoder_counts: int = 0
    current_offset: float | Sequence[float] = 0.0
    current_step: float = 0.0

    def __post_init__(self) -> None:
        if self.transmission.torque_constants is None:
            raise OptionError("SimulatedDrives needs transmission.torque_constants: the truth "
                              "the currents are logged through")
        n = self.transmission.n
        for name in ("rotor_inertia", "viscous", "coulomb"):
            object.__setattr__(self, name, _per_motor(name, getattr(self, name), n))
        check_number("current_noise", self.current_noise, 0)
        check_number("encoder_counts", self.encoder_counts, 0)
        check_number("current_step", self.current_step, 0)
        offset = np.asarray(self.current_offset, dtype=float)
        offset = np.broadcast_to(offset, (n,)).copy() if offset.ndim == 0 else offset
        if offset.shape != (n,) or not np.isfinite(offset).all():
            raise OptionError(f"current_offset must be one number or one per motor ({n}), got "
                              f"{self.current_offset!r}")
        object.__setattr__(self, "current_offset", offset)

    def tendons(self, model: RobotModel, timestep: float) -> list[str]:
        """One MJCF ``<fixed>`` tendon per motor with a motor-side term (module docstring)."""
        tr = self.transmission
        out = []
        for m in range(tr.n):
            if not (self.rotor_inertia[m] or self.viscous[m] or self.coulomb[m]):
                continue
            joints = "".join(
                f"<joint joint={quoteattr(model.joint_names[j])} "
                f'coef="{tr.ratios[m] * tr.coupling[m, j]:.17g}"/>'
                for j in np.flatnonzero(tr.coupling[m]))
            out.append(
                f'<fixed name="motor{m + 1}" armature="{self.rotor_inertia[m]:.17g}" '
                f'damping="{self.viscous[m]:.17g}" frictionloss="{self.coulomb[m]:.17g}" '
                f'solreffriction="{2 * timestep:.17g} 1" '
                f'solimpfriction="{" ".join(f"{v:g}" for v in FRICTION_SOLIMP)}">'
                f"{joints}</fixed>")
        return out


@dataclass(frozen=True, eq=False)
class DriveRecording:
    """What the simulated robot logs, and the truth behind it.

    Attributes
    ----------
    t : (N,) s.
    motor_q : (N, n) motor angles (rad at the motor), rounded to the encoder counts.
    currents : (N, n) motor currents (A), with noise.
    drives : the :class:`SimulatedDrives` (the true torque constants and motor terms).
    truth : the :class:`~consistid.simulate.SimulatedRecording` (joint-side truth; its ``tau``
        is the drive torque without noise).
    """

    t: np.ndarray
    motor_q: np.ndarray
    currents: np.ndarray
    drives: SimulatedDrives
    truth: SimulatedRecording

    @property
    def true_gains(self) -> np.ndarray:
        """``κ = r ⊙ k_t`` of the simulated motors (N·m per A)."""
        return self.drives.transmission.gains


def record_drives(model: RobotModel, trajectory: DesiredMotion, drives: SimulatedDrives,
                  effects: Effects | None = None, seed: int = 0, **options) -> DriveRecording:
    """Run :func:`~consistid.simulate.record` with the motors of ``drives`` and log currents
    and motor angles (module docstring).

    ``effects`` may add joint-side effects and a payload; it must not add torque-sensor
    effects (this robot has no torque sensor: its noise is ``drives.current_noise``).
    ``options`` go to :func:`~consistid.simulate.record` (duration, rate, physics_rate, …).
    """
    drives.transmission.check_joints(model.nv, model.joint_names)
    effects = effects or Effects()
    if np.any(effects.torque_noise) or np.any(effects.torque_gain) or np.any(effects.torque_offset):
        raise ModelError("record_drives logs currents, not a torque sensor: leave the torque "
                         "sensor effects of Effects at their defaults and give "
                         "SimulatedDrives(current_noise=...)")
    physics_rate = float(options.get("physics_rate", 1000.0))
    rec = record(model, trajectory, effects, seed=seed,
                 tendons=drives.tendons(model, 1.0 / physics_rate), **options)
    tr = drives.transmission
    rng = np.random.default_rng([seed, 28])
    currents = tr.motor_torque(rec.tau) / tr.torque_constants
    currents = currents + drives.current_offset \
        + drives.current_noise * rng.standard_normal(currents.shape)
    if drives.current_step:
        currents = np.round(currents / drives.current_step) * drives.current_step
    motor_q = tr.motor_positions(rec.true_q)
    if drives.encoder_counts:
        step = 2 * np.pi / drives.encoder_counts
        motor_q = np.round(motor_q / step) * step
    return DriveRecording(rec.t, motor_q, currents, drives, rec)

"""The sim-to-real gap made visible: what a nominal model leaves unexplained on a MuJoCo log.

:func:`run` (behind ``consistid simulate``) records an example-robot-data arm with effects the
nominal Pinocchio model lacks (:func:`consistid.simulate.record`), turns the log into a dataset
with the default signal chain (:meth:`Dataset.from_recording`), and compares the nominal
model's residual ``τ − RNEA(q, q̇, q̈)`` per joint with

* the residual of the *same* run without the dynamic effects: the floor set by sensor noise and
  signal processing;
* the residual left after subtracting the injected effects' closed forms
  (:func:`consistid.simulate.effects.effect_torque`,
  :func:`~consistid.simulate.effects.sensor_torque`):
  it falls back to that floor when the closed forms are right. Delay and elasticity have no
  closed form in the link states, so they stay in this column.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..data.dataset import Dataset
from ..errors import OptionError
from ..excitation import FourierTrajectory
from ..robot.mjcf import joint_axes
from ..robot.model import RobotModel
from ..identification.summary import table
from ..simulate.effects import (EFFECT_FIELDS, EFFECT_NAMES, Effects, MountedPayload, effect_torque,
                            sensor_torque)
from ..simulate.experiments import SimulatedRecording, nominal_residual, record

#: Default of ``consistid simulate``: two effects, 1 N·m dry friction on every joint and a 1 kg
#: payload 10 cm out along the last joint's axis.
DEFAULT_EFFECTS: tuple[str, ...] = ("coulomb=1.0", "payload=1.0")
#: Sensor effects are not part of the "two effects"; they come with ``torque_noise``.
SENSOR_ONLY = ("offset", "gain", "delay", "torque_noise", "position_noise", "quantisation")


def parse_effects(specs: Sequence[str], model: RobotModel) -> Effects:
    """Effects from ``NAME=VALUE`` strings (the value applies to every joint).

    ``payload=MASS`` puts a point mass of MASS kg 0.1 m along the last joint's axis from its
    origin (where a tool flange usually is); other names are those of
    :data:`consistid.simulate.effects.EFFECT_FIELDS`.
    """
    effects = Effects()
    for spec in specs:
        name, sep, value = spec.partition("=")
        name = name.strip()
        try:
            magnitude = float(value)
        except ValueError:
            magnitude = None
        if not sep or magnitude is None:
            raise OptionError(f"effect {spec!r} is not NAME=NUMBER (e.g. coulomb=1.0)")
        if name == "payload":
            axis = joint_axes(model)[1][-1]
            effects = effects.with_payload(MountedPayload(magnitude, com=0.1 * axis))
        elif name in EFFECT_FIELDS:
            effects = effects.with_effect(name, magnitude)
        else:
            raise OptionError(f"unknown effect {name!r}; known: "
                              f"{', '.join(EFFECT_NAMES)}")
    return effects


@dataclass(frozen=True, eq=False)
class ResidualDemo:
    """A recording with effects and what the nominal model makes of it.

    Attributes
    ----------
    model : the nominal robot.
    recording : the MuJoCo log with the effects.
    dataset : that log through the default signal chain.
    residual : (N, nv) ``τ − RNEA_nominal`` on ``dataset``.
    baseline : (M, nv) the same for the run without the dynamic effects (same sensors).
    explained : (N, nv) the measured torque minus the rigid-body model plus the injected
        effects' closed forms, evaluated at the true states and filtered like the measurement.
    """

    model: RobotModel
    recording: SimulatedRecording
    dataset: Dataset
    residual: np.ndarray
    baseline: np.ndarray
    explained: np.ndarray

    @staticmethod
    def _rms(x: np.ndarray) -> np.ndarray:
        return np.sqrt(np.mean(x ** 2, axis=0))

    def table(self) -> str:
        """Per joint: torque RMS, the nominal residual RMS with and without the effects, and
        after removing the effects' closed forms (N·m)."""
        tau = self._rms(self.dataset.require_torque())
        residual, baseline = self._rms(self.residual), self._rms(self.baseline)
        explained = self._rms(self.explained)
        rows = [(name, tau[j], residual[j], baseline[j], explained[j])
                for j, name in enumerate(self.model.joint_names)]
        header = ["joint", "τ RMS", "residual", "no-effect floor", "after closed forms"]
        return table(header, rows, ".3g")

    def __str__(self) -> str:
        rec = self.recording
        return "\n".join([
            f"{self.model.name}: {rec.t[-1] - rec.t[0] + 1 / rec.rate:g} s logged at "
            f"{rec.rate:g} Hz under computed-torque control on the nominal model",
            "effects: " + rec.effects.describe().replace("\n", "; "),
            "nominal-model residual τ − RNEA(q, q̇, q̈), RMS per joint (N·m):",
            self.table()])

    def plot(self, path: str | Path) -> Path:
        """Residual against time and against velocity, one column per joint, to a PNG."""
        from matplotlib.figure import Figure     # no pyplot, no backend switch: no global state

        path = Path(path)
        nv = self.model.nv
        fig = Figure(figsize=(2.4 * nv, 5.0))
        axes = fig.subplots(2, nv, squeeze=False)
        d = self.dataset
        for j in range(nv):
            top, bottom = axes[0, j], axes[1, j]
            top.plot(d.t, self.residual[:, j], lw=0.6, label="with effects")
            top.plot(d.t, self.explained[:, j], lw=0.6, label="minus closed forms")
            top.set_title(self.model.joint_names[j], fontsize=8)
            bottom.plot(d.dq[:, j], self.residual[:, j], ".", ms=0.5)
            top.set_xlabel("t (s)", fontsize=7)
            bottom.set_xlabel("q̇ (rad/s)", fontsize=7)
            for ax in (top, bottom):
                ax.tick_params(labelsize=6)
        axes[0, 0].set_ylabel("residual (N·m)", fontsize=7)
        axes[1, 0].set_ylabel("residual (N·m)", fontsize=7)
        axes[0, 0].legend(fontsize=6)
        fig.suptitle(f"{self.model.name}: nominal-model residual; "
                     f"{', '.join(self.recording.effects.active())}", fontsize=9)
        fig.tight_layout()
        fig.savefig(path, dpi=120)
        return path


def run(robot: str | RobotModel = "panda", effects: Effects | Sequence[str] = DEFAULT_EFFECTS,
        duration: float = 20.0, torque_noise: float | None = None, seed: int = 0,
        progress: Callable[[str], None] | None = None) -> ResidualDemo:
    """Record ``robot`` with ``effects``, and without them, along one random Fourier
    excitation (5 harmonics, period 10 s), at 1 kHz; see the module notes.

    ``torque_noise`` (N·m), when given, replaces the torque noise of ``effects`` (which is
    otherwise kept: an :class:`Effects` value's own, or a ``torque_noise=VALUE`` string's).
    """
    model = robot if isinstance(robot, RobotModel) else RobotModel.example(robot)
    if not isinstance(effects, Effects):
        effects = parse_effects(effects, model)
    if torque_noise is not None:
        effects = replace(effects, torque_noise=torque_noise)
    sensors = Effects(**{EFFECT_FIELDS[n]: getattr(effects, EFFECT_FIELDS[n])
                         for n in SENSOR_ONLY})
    trajectory = FourierTrajectory.random(model, 5, 10.0, seed=seed)
    say = progress or (lambda _: None)
    say(f"simulating {duration:g} s of {model.name} with {', '.join(effects.active())}")
    rec = record(model, trajectory, effects, duration=duration, seed=seed)
    say("simulating the same run without the dynamic effects")
    plain = record(model, trajectory, sensors, duration=duration, seed=seed)
    options = dict(bandwidth=0.5)
    data = Dataset.from_recording(rec.t, rec.q, rec.tau, joint_names=model.joint_names,
                                  **options)
    base = Dataset.from_recording(plain.t, plain.q, plain.tau, **options)
    # the closed forms at the true states, through the same chain as the measured torque (the
    # low-pass rounds the friction's sign changes off in both alike)
    truth = (rec.true_q, rec.true_dq, rec.true_ddq)
    predicted = sensor_torque(rec.effects, model.rnea(*truth) + effect_torque(model, rec.effects,
                                                                           *truth))
    filtered = Dataset.from_recording(rec.t, rec.q, predicted, **options)
    residual = nominal_residual(model, data)
    return ResidualDemo(model, rec, data, residual, nominal_residual(model, base),
                        data.require_torque() - filtered.require_torque())

r"""A simulated run in which the robot changes: the ground truth for online estimators.

:func:`payload_change_run` samples a random Fourier excitation and evaluates the model's own
equations, ``τ = Y(q, q̇, q̈) π(t) + ε`` with ``ε ~ N(0, σ²)`` (as
:func:`consistid.simulate.excitation_run` does), where ``π(t)`` gains a payload
(:class:`~consistid.simulate.MountedPayload`, the rule of change of
:mod:`consistid.estimation.payload`) at ``change_time``. The estimator under test then sees
exactly the model it assumes, so every figure measures the estimator, not a model mismatch (the
MuJoCo run of :mod:`consistid.online.adaptive_run` is the test with a simulator in the loop).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..data.dataset import Dataset
from ..errors import OptionError, check_number
from ..excitation import FourierTrajectory
from ..identification.regressor import DEFAULT_FRICTION, FrictionArg, RegressorSpec, regressor
from ..robot.model import RobotModel, require_model
from ..simulate.effects import MountedPayload

#: Default payload: 1.5 kg, its CoM 5 cm along the flange axis.
DEFAULT_PAYLOAD = MountedPayload(1.5, (0.0, 0.0, 0.05))


@dataclass(frozen=True, eq=False)
class ChangeRun:
    """A simulated log with a change, and its truth.

    Attributes
    ----------
    dataset : the samples (exact ``q, q̇, q̈``; torques with noise).
    change_time : s; ``change_index`` : the first sample with the payload.
    before, after : (p,) the true standard parameters (then friction) before and after.
    payload : the payload; ``spec`` : the regressor columns of ``before``/``after``.
    torque_noise : σ (N·m).
    """

    dataset: Dataset
    change_time: float
    change_index: int
    before: np.ndarray
    after: np.ndarray
    payload: MountedPayload
    spec: RegressorSpec
    torque_noise: float

    def truth(self, index: int | np.ndarray) -> np.ndarray:
        """The true parameters at sample(s) ``index``."""
        index = np.asarray(index)
        return np.where((index >= self.change_index)[..., None], self.after, self.before)


def payload_change_run(model: RobotModel, duration: float = 60.0, change_time: float = 20.0,
                       payload: MountedPayload = DEFAULT_PAYLOAD, rate: float = 1000.0,
                       torque_noise: float = 0.1, friction: FrictionArg = DEFAULT_FRICTION,
                       harmonics: int = 5, period: float = 10.0, seed: int = 0,
                       parameters: np.ndarray | None = None) -> ChangeRun:
    """A run with a payload attached at ``change_time`` (module docstring).

    Parameters
    ----------
    duration, rate : seconds and Hz of the log.
    change_time : when the payload is attached (s); ``≥ duration``: never.
    friction : per-joint columns of the truth; their values (without ``parameters``) are drawn
        per joint: Coulomb 0.2–1 N·m, viscous 0.1–0.5 N·m·s/rad, offset ±0.5 N·m.
    parameters : (p,) the true parameters before the change (default the URDF's and the drawn
        friction).
    seed : seeds the trajectory, the friction and the noise.
    """
    require_model(model)
    duration = check_number("duration", duration, 0, strict=True)
    rate = check_number("rate", rate, 0, strict=True)
    change_time = check_number("change_time", change_time, 0)
    torque_noise = check_number("torque_noise", torque_noise, 0)
    rng = np.random.default_rng(seed)
    spec = RegressorSpec.make(model, friction)
    draws = {"fc": (0.2, 1.0), "fv": (0.1, 0.5), "fo": (-0.5, 0.5), "ps1": (-0.2, 0.2),
             "pc1": (-0.2, 0.2), "Ia": (0.0, 0.1)}
    joint = np.array([rng.uniform(*draws[suffix]) for _, _, suffix in spec.columns])
    before = (np.concatenate([model.prior_parameters, joint]) if parameters is None
              else np.asarray(parameters, dtype=float))
    if before.shape != (model.n_inertial + spec.n_joint_columns,):
        raise OptionError(f"parameters must have {model.n_inertial + spec.n_joint_columns} "
                          f"entries ({spec.describe()}), got {before.shape}")
    j, values = payload.parameters(model)
    after = before.copy()
    after[10 * j:10 * j + 10] += values
    trajectory = FourierTrajectory.random(model, harmonics, period, rng)
    data = trajectory.sample(rate, duration)
    y = regressor(model, data.q, data.dq, data.ddq, spec).reshape(data.n_samples, model.nv, -1)
    change = int(np.searchsorted(data.t, change_time - 1e-12))
    tau = np.empty((data.n_samples, model.nv))
    tau[:change] = y[:change] @ before
    tau[change:] = y[change:] @ after
    tau += torque_noise * rng.standard_normal(tau.shape)
    dataset = replace(data, tau=tau, joint_names=tuple(model.joint_names))
    return ChangeRun(dataset, float(change_time), change, before, after, payload, spec,
                     float(torque_noise))

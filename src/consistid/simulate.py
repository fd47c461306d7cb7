"""Simulated experiments with known ground truth.

:func:`excitation_run` evaluates the *model's own* equations (regressor × true parameters) along a
Fourier excitation and adds Gaussian noise: the ideal experiment, for checking estimators against
their assumptions. The MuJoCo "real robot", whose data do not come from our equations, lives in
:mod:`consistid.mujoco_robot`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .dataset import Dataset
from .excitation import FourierTrajectory
from .model import RobotModel
from .regressor import FrictionArg, RegressorSpec, regressor


@dataclass(frozen=True)
class SimulatedRun:
    """A simulated recording and the truth it was made from."""

    dataset: Dataset
    true_parameters: np.ndarray
    spec: RegressorSpec
    trajectory: FourierTrajectory
    torque_noise: float
    position_noise: float


def excitation_run(model: RobotModel, parameters: np.ndarray | None = None,
                   duration: float = 30.0, rate: float = 500.0, harmonics: int = 5,
                   period: float = 10.0, torque_noise: float = 0.1,
                   position_noise: float = 0.0, friction: FrictionArg = None,
                   armature: bool = False, seed: int = 0,
                   trajectory: FourierTrajectory | None = None) -> SimulatedRun:
    """Torques ``τ = Y(q, q̇, q̈) π_true + ε`` along a random Fourier excitation.

    Parameters
    ----------
    parameters : true parameters matching ``RegressorSpec.make(model, friction, armature)``;
        default the model's prior with zero friction.
    duration, rate : seconds and Hz of the recording.
    torque_noise, position_noise : standard deviations of Gaussian noise added to the recorded
        torque (N·m) and position (rad); velocities and accelerations stay exact.
    seed : seeds the trajectory (unless given) and the noise.
    """
    spec = RegressorSpec.make(model, friction, armature)
    p = model.n_inertial + spec.n_joint_columns
    truth = (np.concatenate([model.prior_parameters, np.zeros(spec.n_joint_columns)])
             if parameters is None else np.asarray(parameters, dtype=float))
    if truth.shape != (p,):
        raise ValueError(f"true parameters have shape {truth.shape}; the regressor "
                         f"({spec.describe()}) has {p} columns")
    rng = np.random.default_rng(seed)
    trajectory = trajectory or FourierTrajectory.random(model, harmonics, period, rng)
    data = trajectory.sample(rate, duration)
    tau = (regressor(model, data.q, data.dq, data.ddq, spec) @ truth).reshape(-1, model.nv)
    tau = tau + torque_noise * rng.standard_normal(tau.shape)
    q = data.q + position_noise * rng.standard_normal(data.q.shape)
    dataset = replace(data, q=q, tau=tau, joint_names=tuple(model.joint_names))
    return SimulatedRun(dataset, truth, spec, trajectory, torque_noise, position_noise)

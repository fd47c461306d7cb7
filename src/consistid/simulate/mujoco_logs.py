"""MuJoCo logs with a known truth, shared by the tests and the benchmarks that check coverage.

:func:`pd_log`
    MuJoCo itself on the robot's MJCF (:func:`consistid.robot.mjcf.mjcf_spec`) at a fixed step,
    ``implicitfast``, a PD plus gravity compensation tracking a random Fourier trajectory; the
    joints receive ``gain · u`` of ``lag`` steps before (a drive), ``u`` is logged. The truth of
    the simulator terms (armature, damping, gain, delay) is what it was given
    (``benchmarks/simulator_coverage.py``, ``tests/test_simulator.py``).
:func:`friction_run`
    the arm of :func:`consistid.simulate.record` with dry (MuJoCo's ``frictionloss``) and
    viscous friction on every joint and bodies perturbed off the URDF; :meth:`FrictionRun.truth`
    reads the inertias back from the compiled MuJoCo model, so that the truth is the
    simulation's (``benchmarks/coverage_friction.py``, ``tests/test_model_error.py``).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ..data.dataset import Dataset
from ..errors import TrackingWarning
from ..excitation import FourierTrajectory
from ..excitation.trajectory import sample_count
from ..robot.inertia import perturb
from ..robot.model import RobotModel
from .effects import Effects
from .experiments import record

#: Step (s) of :func:`pd_log`'s simulation, and its log's sample time.
PD_STEP = 0.002


def pd_log(model: RobotModel, parameters: np.ndarray, names: list[str], duration: float,
           seed: int, noise: float = 0.0, gain: np.ndarray | None = None, lag: int = 0,
           gains: tuple[float, float] = (400.0, 40.0)) -> Dataset:
    """A log of MuJoCo at step :data:`PD_STEP`, ``implicitfast``, on ``mjcf_spec(model,
    parameters, names)``: ``u = qfrc_bias + k_p (q_d − q) + k_d (q̇_d − q̇)`` tracks a random
    Fourier trajectory (4 harmonics, 4 s, seeded), the joints receive ``gain · u`` of ``lag``
    steps before, and the log is ``(t, q, q̇, q̈ = Δq̇/h, u + noise)`` (white noise of standard
    deviation ``noise``, N·m). ``gains = (k_p, k_d)``."""
    import mujoco

    from ..robot.mjcf import mjcf_spec

    h = PD_STEP
    sample_count(1.0 / h, duration, model.nv)       # refused before allocating
    spec = mjcf_spec(model, parameters, names)
    spec.option.timestep = h
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    mj = spec.compile()
    data = mujoco.MjData(mj)
    rng = np.random.default_rng(seed)
    des = FourierTrajectory.random(model, 4, 4.0, rng).sample(1.0 / h, duration + 2 * h)
    steps = int(round(duration / h))
    data.qpos[:], data.qvel[:] = des.q[0], des.dq[0]
    q, dq, u = (np.empty((steps + 1, model.nv)) for _ in range(3))
    kp, kd = gains
    g = np.ones(model.nv) if gain is None else np.asarray(gain, dtype=float)
    for k in range(steps + 1):
        mujoco.mj_forward(mj, data)
        u[k] = data.qfrc_bias + kp * (des.q[k] - data.qpos) + kd * (des.dq[k] - data.qvel)
        q[k], dq[k] = data.qpos, data.qvel
        data.qfrc_applied[:] = g * u[max(k - lag, 0)]
        mujoco.mj_step(mj, data)
    tau = u + noise * rng.standard_normal(u.shape)
    return Dataset(t=h * np.arange(steps), q=q[:-1], dq=dq[:-1], ddq=np.diff(dq, axis=0) / h,
                   tau=tau[:-1], joint_names=tuple(model.joint_names))


@dataclass(frozen=True)
class FrictionRun:
    """A :func:`friction_run`: its log (exact states, measured torques) and what was simulated:
    the bodies' standard parameters given to MuJoCo, Coulomb levels and viscous coefficients
    per joint (N·m, N·m·s/rad)."""

    dataset: Dataset
    effects: Effects
    inertias: np.ndarray
    coulomb: np.ndarray
    viscous: np.ndarray

    def truth(self, model: RobotModel, names: list[str]) -> np.ndarray:
        """The simulated robot as a vector of the parameters ``names`` (``"<joint>.fc"``,
        ``"<joint>.fv"`` and the inertial block first, as ``identify`` names them): its bodies
        read back from the compiled MuJoCo model (mass, ``body_ipos``, ``body_iquat``,
        ``body_inertia``; the body frame is the joint frame), its friction as simulated,
        every other term 0."""
        theta = np.zeros(len(names))
        theta[:model.n_inertial] = mujoco_inertias(model, self.effects, self.inertias)
        for j, joint in enumerate(model.joint_names):
            theta[names.index(f"{joint}.fc")] = self.coulomb[j]
            theta[names.index(f"{joint}.fv")] = self.viscous[j]
        return theta


def friction_run(model: RobotModel, seed: int, duration: float = 10.0, rate: float = 200.0,
                 spread: float = 0.12, noise: float = 0.1) -> FrictionRun:
    """The URDF's bodies perturbed by ``±spread`` (:func:`consistid.robot.inertia.perturb`),
    Coulomb friction ``U(0.5, 2)`` N·m (``frictionloss``) and viscous ``U(0.2, 1)`` N·m·s/rad
    on every joint, torque noise ``noise`` N·m, a random Fourier trajectory (5 harmonics,
    10 s, 80 % amplitude) recorded by :func:`consistid.simulate.record` for ``duration`` s at
    ``rate`` Hz; all seeded by ``seed`` (its tracking warnings silenced: the states are
    exact whatever the tracking)."""
    rng = np.random.default_rng(seed)
    inertias = perturb(model.prior_parameters, spread, rng)
    fc, fv = rng.uniform(0.5, 2.0, model.nv), rng.uniform(0.2, 1.0, model.nv)
    effects = Effects(viscous=fv, coulomb=fc, torque_noise=noise)
    traj = FourierTrajectory.random(model, 5, 10.0, rng, amplitude=0.8)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TrackingWarning)
        rec = record(model, traj, effects, inertias, duration=duration, rate=rate,
                     seed=int(rng.integers(2**31)))
    return FrictionRun(rec.true_dataset(), effects, inertias, fc, fv)


def mujoco_inertias(model: RobotModel, effects: Effects, inertias: np.ndarray) -> np.ndarray:
    """Stacked 10-vectors (Pinocchio's order) of the link bodies of the MuJoCo model
    :class:`~consistid.simulate.mujoco_robot.MujocoRobot` compiles for ``(model, effects,
    inertias)`` (bodies without a joint — rotors, payloads — skipped)."""
    import mujoco
    import pinocchio as pin

    from .mujoco_robot import MujocoRobot

    mj = MujocoRobot(model, effects, inertias, timestep=1e-3).mj_model
    out = []
    for body in range(1, mj.nbody):
        if mj.body_jntnum[body] == 0:
            continue
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, mj.body_iquat[body])
        rot = rot.reshape(3, 3)
        out.append(pin.Inertia(float(mj.body_mass[body]), mj.body_ipos[body].copy(),
                               rot @ np.diag(mj.body_inertia[body]) @ rot.T
                               ).toDynamicParameters())
    return np.concatenate(out)

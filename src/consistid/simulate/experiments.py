"""Simulated experiments with known ground truth.

:func:`excitation_run` evaluates the *model's own* equations (regressor × true parameters) along a
Fourier excitation and adds Gaussian noise: the ideal experiment, for checking estimators against
their assumptions.

:func:`record` runs the MuJoCo "real robot" (:mod:`consistid.simulate.mujoco_robot`), whose data do
not
come from our equations, through a trajectory under a tracking controller, with the physical and
sensor effects of :class:`~consistid.simulate.effects.Effects` switched on or off, and returns a
:class:`SimulatedRecording`: the log ``(t, q, tau)`` a real robot would give, plus the truth for
scoring.

>>> rec = record(model, trajectory, Effects(viscous=0.5, torque_noise=0.05), duration=20.0)
>>> data = Dataset.from_recording(rec.t, rec.q, rec.tau)       # filter + differentiate
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace
from typing import Callable, Protocol, Sequence

import numpy as np

from ..data.dataset import Dataset
from .effects import Effects, MountedPayload, measure_position, measure_torque
from ..errors import ModelError, TrackingWarning, check_number, check_seed
from ..excitation import FourierTrajectory
from ..excitation.trajectory import sample_count
from ..robot.model import RobotModel
from ..identification.regressor import FrictionArg, RegressorSpec, regressor

__all__ = ["DesiredMotion", "Effects", "MountedPayload", "SimulatedRecording", "SimulatedRun",
           "TrackingController", "excitation_run", "nominal_residual", "record"]


@dataclass(frozen=True, eq=False)
class SimulatedRun:
    """A simulated recording and the truth it was made from."""

    dataset: Dataset
    true_parameters: np.ndarray
    spec: RegressorSpec
    trajectory: FourierTrajectory
    torque_noise: float
    position_noise: float


def ar1_noise(shape: tuple[int, ...], phi: float, std: float,
              rng: np.random.Generator) -> np.ndarray:
    """Stationary AR(1) noise along axis 0, ``e_k = φ e_{k−1} + √(1 − φ²)·std·ξ_k``, ``ξ``
    standard normal: standard deviation ``std`` and autocorrelation time ``(1 + φ)/(1 − φ)``
    samples, the correlated residual of low-pass filtered torques (tests of honest ±)."""
    if not 0.0 <= phi < 1.0:
        raise ModelError(f"AR(1) coefficient must lie in [0, 1), got {phi}")
    e = rng.standard_normal(shape) * std * np.sqrt(1.0 - phi ** 2)
    e[0] /= np.sqrt(1.0 - phi ** 2)
    for k in range(1, e.shape[0]):
        e[k] += phi * e[k - 1]
    return e


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
    torque_noise = check_number("torque_noise", torque_noise, 0)
    position_noise = check_number("position_noise", position_noise, 0)
    check_seed("seed", seed)
    spec = RegressorSpec.make(model, friction, armature)
    p = model.n_inertial + spec.n_joint_columns
    truth = (np.concatenate([model.prior_parameters, np.zeros(spec.n_joint_columns)])
             if parameters is None else np.asarray(parameters, dtype=float))
    if truth.shape != (p,):
        raise ModelError(f"true parameters have shape {truth.shape}; the regressor "
                         f"({spec.describe()}) has {p} columns")
    rng = np.random.default_rng(seed)
    trajectory = trajectory or FourierTrajectory.random(model, harmonics, period, rng)
    data = trajectory.sample(rate, duration)
    tau = (regressor(model, data.q, data.dq, data.ddq, spec) @ truth).reshape(-1, model.nv)
    tau = tau + torque_noise * rng.standard_normal(tau.shape)
    q = data.q + position_noise * rng.standard_normal(data.q.shape)
    dataset = replace(data, q=q, tau=tau, joint_names=tuple(model.joint_names))
    return SimulatedRun(dataset, truth, spec, trajectory, torque_noise, position_noise)


class DesiredMotion(Protocol):
    """Anything that gives the desired ``(q, dq, ddq)``, each (len(t), nv), at times ``t``.

    :func:`record` also reads two optional attributes: ``period`` (the default duration) and
    ``periodic``; a trajectory with ``periodic = False`` is evaluated on ``t ≥ 0`` only.
    """

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...


@dataclass(frozen=True)
class TrackingController:
    r"""PD + computed torque on the *nominal* model, the inverse-dynamics controller:

    .. math:: u = \hat M(q)\,(\ddot q_d + K_p e + K_d \dot e) + \hat h(q, \dot q),
              \quad e = q_d - q,\; K_p = \omega^2,\; K_d = 2\zeta\omega

    (Craig, *Introduction to Robotics*, ch. 10; the seeds' simulated experiment), one
    ``pinocchio.rnea`` call of the nominal model per physics step. ``q`` is the drive-side
    angle, noise free: the joint angle, or the motor angle on an elastic joint (collocated
    feedback, as elastic-joint arms do; through the spring the loop would be unstable), whatever
    the logged position sensor is. ``u`` is held over the step (a 1 kHz torque loop by default).
    Model errors and unmodelled effects show up as tracking error and in ``u``.

    Parameters
    ----------
    bandwidth : ω (rad/s), the closed-loop natural frequency. The gains are scaled by the
        nominal mass matrix, so a light wrist joint gets a small stiffness ``M̂_jj ω²``: the
        default 50 rad/s keeps the Panda's tracking error under ~0.2 rad with 0.5–2 N·m of
        unmodelled dry friction (the most on the wrist, ``panda_joint7``).
    damping_ratio : ζ.
    """

    bandwidth: float = 50.0
    damping_ratio: float = 1.0

    def __post_init__(self) -> None:
        if not (self.bandwidth > 0 and self.damping_ratio > 0):
            raise ModelError(f"controller bandwidth = {self.bandwidth} and damping_ratio = "
                             f"{self.damping_ratio} must both be positive")

    @property
    def gains(self) -> tuple[float, float]:
        """``(K_p, K_d)`` in 1/s² and 1/s."""
        return self.bandwidth ** 2, 2.0 * self.damping_ratio * self.bandwidth


@dataclass(frozen=True, eq=False)
class SimulatedRecording:
    """A simulated robot log and the truth behind it.

    The log, as a real robot would give it:

    Attributes
    ----------
    t : (N,) s, uniform at ``rate``.
    q : (N, nv) measured positions (rad / m): the sensed angle (link, or motor on an elastic
        joint with a motor-side encoder) with noise and encoder rounding.
    tau : (N, nv) measured torques (N·m / N): drive torque on a rigid joint, spring torque on an
        elastic one, through the torque sensor's gain, offset, delay and noise.

    The truth, for scoring:

    true_q, true_dq, true_ddq : (N, nv) link coordinates, velocities and MuJoCo's
        accelerations at ``t``.
    true_tau : (N, nv) the torque at the torque sensor, before any sensor effect.
    motor_q, motor_dq : (N, nv) drive-side coordinates (equal to the link's on rigid joints).
    control : (N, nv) the controller's torque ``u`` (the motor torque; on a rigid joint it is
        ``true_tau``).
    desired_q : (N, nv) the controller's reference.
    tracking_error : (nv,) ``max |true_q − desired_q|`` per joint over the log (rad / m); on an
        elastic joint it includes the spring's deflection (the controller tracks the motor).
    effects : the :class:`Effects`, resolved per joint (``(nv,)`` arrays).
    true_parameters : (10·nbodies,) inertial parameters of the simulated robot, payload excluded.
    payload_parameters : (10,) the payload in the frame of the joint that carries it (what it
        adds to that body's 10-vector), or ``None``; ``payload_joint`` is that joint's index.
    joint_names, rate, physics_rate, controller, trajectory : the set-up.
    """

    t: np.ndarray
    q: np.ndarray
    tau: np.ndarray
    true_q: np.ndarray
    true_dq: np.ndarray
    true_ddq: np.ndarray
    true_tau: np.ndarray
    motor_q: np.ndarray
    motor_dq: np.ndarray
    control: np.ndarray
    desired_q: np.ndarray
    tracking_error: np.ndarray
    effects: Effects
    true_parameters: np.ndarray
    payload_parameters: np.ndarray | None
    payload_joint: int | None
    joint_names: tuple[str, ...]
    rate: float
    physics_rate: float
    controller: TrackingController
    trajectory: DesiredMotion

    @property
    def n_samples(self) -> int:
        return int(self.t.shape[0])

    def true_dataset(self) -> Dataset:
        """The exact states with the *measured* torques: a dataset with perfect signal
        processing (what :meth:`Dataset.from_recording` tries to approach)."""
        return Dataset(t=self.t, q=self.true_q, dq=self.true_dq, ddq=self.true_ddq,
                       tau=self.tau, joint_names=self.joint_names)


#: Default bound (rad, or m on a prismatic joint) on the tracking error of :func:`record`, above
#: which it warns that the robot did not follow its reference. The default controller leaves
#: up to ~0.2 rad on the Panda's light wrist with 2 N·m of unmodelled dry friction, and 0.55
#: rad on the UR3's last joint with 1 N·m (which warns).
MAX_TRACKING_ERROR = 0.5


def _desired(trajectory: DesiredMotion, t: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The reference at the physics steps ``t``. A trajectory that says it is not periodic
    (``periodic = False``) is held at its start state before ``t = 0``, which needs it to
    start at rest."""
    if getattr(trajectory, "periodic", True) or t[0] >= 0:
        return trajectory.evaluate(t)
    before = t < 0
    q, dq, ddq = trajectory.evaluate(np.where(before, 0.0, t))
    start = np.max(np.abs(np.concatenate([dq[0], ddq[0]])))
    if start > 1e-9:
        raise ModelError(f"the trajectory is not periodic and does not start at rest (|q̇(0)|, "
                         f"|q̈(0)| up to {start:.3g}): it cannot be held during settle = "
                         f"{-t[0]:g} s before t = 0; give settle=0, or a trajectory that starts "
                         "at rest")
    dq[before], ddq[before] = 0.0, 0.0
    return q, dq, ddq


def record(model: RobotModel, trajectory: DesiredMotion, effects: Effects | None = None,
           true_parameters: np.ndarray | None = None, duration: float | None = None,
           rate: float = 1000.0, physics_rate: float = 1000.0, settle: float = 1.0,
           controller: TrackingController | None = None, seed: int = 0,
           integrator: str = "Euler", max_tracking_error: float = MAX_TRACKING_ERROR,
           progress: Callable[[float], None] | None = None,
           step_hook: Callable | None = None, tendons: Sequence[str] = ()) -> SimulatedRecording:
    """Run the MuJoCo robot through ``trajectory`` and log ``(t, q, tau)`` like a real robot.

    Parameters
    ----------
    model : the *nominal* robot; the controller uses it, and the simulated robot has its
        kinematics and gravity.
    trajectory : desired motion, e.g. :class:`consistid.excitation.FourierTrajectory`.
    effects : what the simulated robot adds (default none).
    true_parameters : inertial parameters (10 per body) of the simulated robot; default the
        nominal ones (``model.prior_parameters``).
    duration : seconds logged, from ``t = 0``; default one period of ``trajectory`` (needs a
        ``period`` attribute).
    rate : log rate (Hz); ``physics_rate / rate`` must be an integer.
    physics_rate : physics and control rate (Hz).
    settle : seconds simulated before ``t = 0`` (the controller settles, and a delayed torque
        channel has history); must cover the largest ``effects.delay``. A periodic trajectory
        is followed backwards in time over it; one with ``periodic = False`` (e.g. an
        :class:`~consistid.excitation.Trajectory` whose end state differs from its start)
        is held at its start state, which must be at rest.
    controller : default :class:`TrackingController()` (ω = 50 rad/s, ζ = 1).
    seed : seeds the sensor noise.
    integrator : MuJoCo integrator (see :class:`~consistid.simulate.mujoco_robot.MujocoRobot`).
    max_tracking_error : warn (:class:`~consistid.errors.TrackingWarning`) when some joint's
        ``max |true_q − desired_q|`` over the log exceeds this (rad / m; default
        :data:`MAX_TRACKING_ERROR`); ``inf`` never warns.
    progress : called with the fraction of physics steps done.
    step_hook : called as ``step_hook(mj_model, mj_data)`` before every physics step
        (:meth:`~consistid.simulate.mujoco_robot.MujocoRobot.run`), e.g. the per-step torques of
        :mod:`consistid.simulate.disturbances`.
    tendons : extra MJCF ``<fixed>`` tendon elements (:class:`MujocoRobot`), e.g. the motors
        of :mod:`consistid.simulate.drives`.

    Returns
    -------
    SimulatedRecording

    Raises
    ------
    ModelError : bad rates, a delay longer than ``settle``, effects that do not fit the model,
        a ``tanh`` friction too stiff for the physics step, a diverging simulation, or a
        non-periodic trajectory that does not start at rest with ``settle > 0``.
    """
    from .mujoco_robot import MujocoRobot  # MuJoCo is imported only when simulating

    controller = controller or TrackingController()
    if duration is None:
        if not hasattr(trajectory, "period"):
            raise ModelError("record(duration=None) needs a trajectory with a period")
        duration = float(trajectory.period)
    if not (rate > 0 and physics_rate > 0 and duration > 0 and settle >= 0):
        raise ModelError(f"rate = {rate}, physics_rate = {physics_rate}, duration = {duration} "
                         f"and settle = {settle} must be positive (settle ≥ 0)")
    if not max_tracking_error > 0:
        raise ModelError(f"max_tracking_error = {max_tracking_error}; it must be positive")
    ratio = physics_rate / rate
    if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
        raise ModelError(f"physics_rate / rate = {physics_rate} / {rate} must be a positive "
                         "integer: the log takes every k-th physics step")
    robot = MujocoRobot(model, effects, true_parameters, timestep=1.0 / physics_rate,
                        integrator=integrator, tendons=tendons)
    eff = robot.effects
    if np.max(eff.delay) > settle:
        raise ModelError(f"effects.delay up to {np.max(eff.delay)} s needs settle ≥ that; "
                         f"settle = {settle} s")
    check_seed("seed", seed)
    sample_count(physics_rate, duration + settle, model.nv)   # refused before allocating
    every = int(round(ratio))
    n_settle = int(np.ceil(settle * physics_rate - 1e-9))
    n_log = int(round(duration * rate))
    steps = n_settle + (n_log - 1) * every + 1
    t_fine = (np.arange(steps) - n_settle) / physics_rate        # t = 0 at the first log
    desired = _desired(trajectory, t_fine)
    trace = robot.run(controller.gains, model, t_fine, desired, every, n_settle, progress,
                      step_hook)
    _check_effort(model, trace.tau_fine, physics_rate)
    rng = np.random.default_rng(seed)
    desired_q = desired[0][n_settle::every]
    tracking = np.max(np.abs(trace.q - desired_q), axis=0)
    worst = int(np.argmax(tracking))
    if not tracking[worst] <= max_tracking_error:
        warnings.warn(f"{model.name} did not follow the trajectory: tracking error "
                      f"{tracking[worst]:.3g} on {model.joint_names[worst]!r} exceeds "
                      f"max_tracking_error = {max_tracking_error:g} (a controller too soft "
                      "for the effects, or an unstable simulation); the log is not the "
                      "intended motion. To stiffen the controller, raise its bandwidth: "
                      f"controller=TrackingController(bandwidth={2 * controller.bandwidth:g}) "
                      f"(now {controller.bandwidth:g} rad/s; the gains scale with its square)",
                      TrackingWarning, stacklevel=2)
    payload = robot.payload or (None, None)
    return SimulatedRecording(
        t=trace.t, q=measure_position(trace.sensed_q, eff, rng),
        tau=measure_torque(trace.t, trace.t_fine, trace.tau_fine, eff, rng),
        true_q=trace.q, true_dq=trace.dq, true_ddq=trace.ddq,
        true_tau=trace.tau_fine[n_settle::every], motor_q=trace.motor_q,
        motor_dq=trace.motor_dq, control=trace.control, desired_q=desired_q,
        tracking_error=tracking, effects=eff, true_parameters=robot.model.prior_parameters,
        payload_parameters=payload[1], payload_joint=payload[0],
        joint_names=tuple(model.joint_names), rate=float(rate),
        physics_rate=float(physics_rate), controller=controller, trajectory=trajectory)


#: A simulated joint torque beyond this multiple of the URDF's effort limit is a diverging
#: (oscillating) simulation, not a motion the arm makes.
EFFORT_DIVERGENCE = 10.0


def _check_effort(model: RobotModel, tau: np.ndarray, physics_rate: float) -> None:
    """Raise :class:`ModelError` when the applied torque exceeds :data:`EFFORT_DIVERGENCE` ×
    a joint's effort limit (finite ones): the simulation oscillates at the physics step without
    MuJoCo flagging a bad state (a light joint with damping or a stiff controller), and its log
    would be garbage that a softer controller cannot fix."""
    effort = np.asarray(model.limits.effort, dtype=float)
    peak = np.max(np.abs(tau), axis=0)
    ratio = np.where(np.isfinite(effort) & (effort > 0), peak / np.where(effort > 0, effort, 1.0),
                     0.0)
    j = int(np.argmax(ratio))
    if ratio[j] > EFFORT_DIVERGENCE:
        raise ModelError(
            f"the MuJoCo simulation of {model.name} diverged: the torque on "
            f"{model.joint_names[j]!r} reaches {peak[j]:.3g} N·m, {ratio[j]:.0f} × its effort "
            f"limit {effort[j]:g} N·m: the physics step 1/{physics_rate:g} s is too long for a "
            "light link with damping, stiffness or a stiff controller; raise physics_rate (e.g. "
            f"physics_rate={4 * physics_rate:g}) or soften the effect")


def nominal_residual(model: RobotModel, dataset: Dataset) -> np.ndarray:
    """``τ − RNEA_nominal(q, q̇, q̈)`` per sample and joint, (N, nv): what the nominal
    rigid-body model leaves unexplained in a dataset."""
    return dataset.require_torque() - model.rnea(dataset.q, dataset.dq, dataset.ddq)

r"""The Slotine–Li controller on the MuJoCo robot: a periodic trajectory, a wrong nominal model,
and a payload grasped in the middle of the run.

:func:`adaptive_run` simulates the "real robot" (:class:`consistid.simulate.mujoco_robot.
MujocoRobot`, the true inertias, optionally its effects) under
:class:`~consistid.online.slotine_li.SlotineLiController`, which starts from a nominal model
whose bodies are off by ``±nominal_error`` (each body's mass, CoM coordinates and inertia about
the CoM scaled by ``1 ± nominal_error``, signs drawn at random: consistent, and wrong).
The controller torque is applied as ``qfrc_applied`` and held over each physics step (a 1 kHz
torque loop by default); the payload (a :class:`~consistid.simulate.MountedPayload`) is attached
at ``payload_time`` with :meth:`MujocoRobot.set_payload`.

Figures (:class:`AdaptiveRun`): the RMS tracking error per period, and the estimate's error as
the RMS, along one period of the desired motion, of the inverse-dynamics torque it mispredicts,
``‖Y_rnea(q_d, q̇_d, q̈_d)(π̂ − π_true)‖`` (N·m): a unit-consistent figure that, unlike the
standard parameters themselves (which the motion need not determine), a controller feels.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pinocchio as pin

from ..errors import ModelError, OptionError, check_number, check_seed
from ..excitation.trajectory import sample_count
from ..excitation import FourierTrajectory
from ..identification.regressor import FrictionArg, RegressorSpec, prior_vector, regressor
from ..robot.inertia import from_mass_com_inertia, to_mass_com_inertia
from ..robot.model import RobotModel, require_model
from ..simulate.effects import (Effects, MountedPayload, explicit_friction,
                                has_explicit_friction)
from . import report
from .scenario import DEFAULT_PAYLOAD
from .slotine_li import SlotineLiController

#: Radius (m) of the sphere that stands for the payload capacity in the reference body.
CAPACITY_RADIUS = 0.1
#: Points per period at which the estimate's torque error is evaluated.
ERROR_POINTS = 200


def misestimate(parameters: np.ndarray, relative: float, rng: np.random.Generator) -> np.ndarray:
    """Each body's mass, CoM coordinates and inertia about the CoM scaled by ``1 ± relative``
    (independent random signs): a consistent model that is off by exactly ``relative``."""
    if not 0.0 <= relative < 1.0:
        raise OptionError(f"nominal_error = {relative} must lie in [0, 1)")
    out = np.array(parameters, dtype=float)
    for i in range(out.size // 10):
        m, c, inertia = to_mass_com_inertia(out[10 * i:10 * i + 10])
        f = 1.0 + relative * rng.choice([-1.0, 1.0], size=5)
        out[10 * i:10 * i + 10] = from_mass_com_inertia(m * f[0], c * f[1:4], inertia * f[4])
    return out


def capacity_body(mass: float, radius: float = CAPACITY_RADIUS) -> np.ndarray:
    """The 10-vector of a solid sphere of ``mass`` kg and ``radius`` m centred at the joint
    origin (``I = 2/5 m r²``)."""
    mass = check_number("payload_capacity", mass, 0, strict=True)
    return from_mass_com_inertia(mass, np.zeros(3), 0.4 * mass * radius ** 2 * np.eye(3))


@dataclass(frozen=True, eq=False)
class AdaptiveRun:
    """A logged run of the adaptive controller.

    Attributes
    ----------
    t : (N,) s; ``q``, ``q_desired``, ``tau`` : (N, nv) the joint angles, the reference and the
        applied torques at every physics step.
    period : s; ``periods`` : how many were run.
    payload_time : when the payload was attached (``None``: never).
    estimate_t : (M,) times of the estimate snapshots (one per ``snapshot`` s);
        ``estimate_error`` : (M,) its torque error (module docstring, N·m RMS).
    initial_parameters, final_parameters : the controller's estimate at the start and end.
    true_parameters, true_parameters_loaded : the truth before and after the payload.
    projected_minimum : (steps/project_every,) the smallest prior-normalised pseudo-inertia
        eigenvalue over the bodies after each projection (``≥ margin`` means consistent).
    clips : projections that moved the estimate.
    controller : the controller, after the run.
    """

    t: np.ndarray
    q: np.ndarray
    q_desired: np.ndarray
    tau: np.ndarray
    period: float
    periods: int
    payload_time: float | None
    estimate_t: np.ndarray
    estimate_error: np.ndarray
    initial_parameters: np.ndarray
    final_parameters: np.ndarray
    true_parameters: np.ndarray
    true_parameters_loaded: np.ndarray
    projected_minimum: np.ndarray
    clips: int
    controller: SlotineLiController

    def period_rms(self) -> np.ndarray:
        """(periods,) RMS tracking error (rad) over every joint and sample of each period."""
        index = np.minimum((self.t / self.period + 1e-9).astype(int), self.periods - 1)
        err = self.q - self.q_desired
        return np.array([np.sqrt(np.mean(err[index == k] ** 2)) for k in range(self.periods)])

    @property
    def payload_period(self) -> int | None:
        """The period in which the payload was attached."""
        return None if self.payload_time is None else int(self.payload_time / self.period + 1e-9)

    def summary(self) -> str:
        rms = self.period_rms()
        lines = [f"Slotine–Li adaptive control of {self.controller.model.name!r}: {self.periods} "
                 f"periods of {self.period:g} s, {self.controller}",
                 "period  RMS tracking error [mrad]  estimate torque error before its end [N·m]"]
        for k, r in enumerate(rms):
            at = np.searchsorted(self.estimate_t, (k + 1) * self.period - 1e-9) - 1
            err = self.estimate_error[max(at, 0)]
            mark = "  ← payload attached" if k == self.payload_period else ""
            lines.append(f"{k + 1:>6d}  {1e3 * r:>26.3f}  {err:>38.3f}{mark}")
        lines.append(f"last/first period RMS {rms[-1] / rms[0]:.3g}; projections "
                     f"{self.projected_minimum.size}, {self.clips} of them clipped, smallest "
                     f"normalised eigenvalue after any {np.min(self.projected_minimum):.3g}"
                     if self.projected_minimum.size else
                     f"last/first period RMS {rms[-1] / rms[0]:.3g}; no projection")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def figure(self):
        """A matplotlib ``Figure``: tracking error and estimate error versus time, RMS per
        period (the grasp as a dashed line)."""
        return report.adaptive_figure(self)

    def report(self, path: str | Path) -> Path:
        """Write an HTML page (the figure embedded, the summary) to ``path`` (a ``.html`` file,
        or a folder that gets ``adaptive_run.html``); returns the file."""
        title = f"consistid Slotine–Li adaptive control of {self.controller.model.name!r}"
        return report.write(path, report.page(title, self.summary(), self.figure()),
                            "adaptive_run.html")

    def _repr_html_(self) -> str:
        return report.fragment(self.summary())


def adaptive_run(model: RobotModel, *, periods: int = 8, period: float = 4.0,
                 trajectory: FourierTrajectory | None = None, harmonics: int = 5,
                 amplitude: float = 0.8, nominal_error: float = 0.3,
                 true_parameters: np.ndarray | None = None,
                 payload: MountedPayload | None = DEFAULT_PAYLOAD,
                 payload_time: float | None = None, effects: Effects | None = None,
                 lam: float | np.ndarray = 5.0, bandwidth: float = 50.0,
                 gamma: float | np.ndarray = 10.0, rate: float = 1000.0,
                 project_every: int = 1, composite: float = 0.0,
                 payload_capacity: float = 3.0, friction: FrictionArg = None,
                 snapshot: float = 0.1, seed: int = 0,
                 controller: SlotineLiController | None = None,
                 progress: Callable[[float], None] | None = None) -> AdaptiveRun:
    """Run the Slotine–Li controller on the MuJoCo robot (module docstring).

    Parameters
    ----------
    model : the robot (its URDF inertias are the truth unless ``true_parameters`` is given).
    periods, period : how many periods of the trajectory, and its period (s).
    trajectory : a periodic desired motion; default
        ``FourierTrajectory.random(model, harmonics, period, seed, amplitude)``.
    nominal_error : relative error of every body of the controller's initial model.
    payload : attached at ``payload_time`` (default: the start of the middle period,
        ``(periods // 2)·period``); ``None`` for no payload.
    effects : further effects of the simulated robot: friction (MuJoCo's ``damping`` and
        ``frictionloss``, and the explicit tanh, Stribeck and sigmoid torques of
        :func:`consistid.simulate.effects.explicit_friction`, applied every step) and armature;
        its ``payload`` must be unset and elasticity is refused. Sensor effects (noise, delay,
        quantisation) are not applied: the controller reads the true state.
    lam : ``Λ`` (1/s). ``bandwidth`` : ``K = bandwidth · M̂(q_d(0))`` (N·m·s/rad, the nominal
        mass matrix at the start), the poles of the ``s`` dynamics at about ``bandwidth`` rad/s.
    payload_capacity : kg the last body may carry: the controller's reference body there is the
        URDF's plus a solid sphere of this mass and radius :data:`CAPACITY_RADIUS` at the joint
        origin (:class:`SlotineLiController` ``reference``), so that a grasped payload heavier
        than the link is re-learnt at the link-plus-payload scale; 0: the URDF's bodies.
    composite : ``μ`` of the controller's prediction-error term (:meth:`SlotineLiController.
        observe`), fed every step with the previous step's state, applied torque and the
        acceleration ``(q̇_{k+1} − q̇_k)/h`` (a backward difference of measured velocities, exact
        for MuJoCo's semi-implicit Euler step); 0: the pure Slotine–Li law.
    gamma : the controller's ``Γ`` (a number: the natural gain).
    rate : physics and control rate (Hz).
    project_every : the controller's projection period (steps).
    friction : per-joint columns the controller adapts (:meth:`RegressorSpec.make`; start at
        0); default none. Their truth (for the estimate's error) is taken as 0.
    snapshot : seconds between estimate snapshots.
    controller : a ready controller (then ``lam``, ``bandwidth``, ``gamma``, ``nominal_error``,
        ``project_every`` are not used).

    Raises
    ------
    OptionError, ModelError : bad options; a diverging simulation.
    """
    import mujoco  # noqa: PLC0415 (heavy)

    from ..simulate.mujoco_robot import MujocoRobot  # noqa: PLC0415 (MuJoCo)

    require_model(model)
    periods = check_number("periods", periods, 1, integer=True)
    period = check_number("period", period, 0, strict=True)
    rate = check_number("rate", rate, 0, strict=True)
    snapshot = check_number("snapshot", snapshot, 0, strict=True)
    sample_count(rate, periods * period, model.nv)   # refused before allocating
    rng = np.random.default_rng(check_seed("seed", seed))
    truth = (model.prior_parameters.copy() if true_parameters is None
             else np.asarray(true_parameters, dtype=float))
    if trajectory is None:
        trajectory = FourierTrajectory.random(model, harmonics, period, rng, amplitude=amplitude)
    elif abs(trajectory.period - period) > 1e-12:
        raise OptionError(f"period = {period} differs from the trajectory's {trajectory.period}")
    effects = effects or Effects()
    if effects.payload is not None:
        raise OptionError("pass the payload as payload=, not in effects (it is grasped mid-run)")
    if payload is not None:
        payload_time = (periods // 2) * period if payload_time is None else float(payload_time)
        effects = effects.with_payload(payload)
    robot = MujocoRobot(model, effects, truth, timestep=1.0 / rate)
    if robot.effects.elastic.any():
        raise OptionError("adaptive_run drives the link joints directly: elastic joints "
                          "(effects.stiffness) are not supported here")
    explicit = has_explicit_friction(robot.effects)
    loaded = truth.copy()
    if payload is not None:
        joint, values = robot.payload
        loaded[10 * joint:10 * joint + 10] += values
        robot.set_payload(False)
    steps = int(round(periods * period * rate))
    t = np.arange(steps) / rate
    qd, dqd, ddqd = trajectory.evaluate(t)
    if controller is None:
        nominal = misestimate(truth, nominal_error, rng)
        m_hat = model.with_parameters(nominal).pin_model
        m0 = pin.crba(m_hat, m_hat.createData(), model.configuration(qd[0]))
        m0 = np.triu(m0) + np.triu(m0, 1).T
        reference = model.prior_parameters.copy()
        if payload_capacity > 0:
            joint = robot.payload[0] if robot.payload is not None else model.nv - 1
            reference[10 * joint:10 * joint + 10] += capacity_body(payload_capacity)
        spec = RegressorSpec.make(model, friction)
        controller = SlotineLiController(
            model, lam, bandwidth * m0, gamma,
            initial=np.concatenate([nominal, np.zeros(spec.n_joint_columns)]),
            friction=friction, project_every=project_every, composite=composite,
            reference=reference)
    initial = controller.parameters.copy()
    spec = controller.spec
    n_truth = prior_vector(model, spec).size
    truth_full = np.concatenate([truth, np.zeros(n_truth - truth.size)])
    loaded_full = np.concatenate([loaded, np.zeros(n_truth - loaded.size)])
    t_err = np.linspace(0.0, period, ERROR_POINTS, endpoint=False)
    y_err = regressor(model, *trajectory.evaluate(t_err), spec)

    def torque_error(estimate: np.ndarray, true: np.ndarray) -> float:
        return float(np.sqrt(np.mean((y_err @ (estimate - true)) ** 2)))

    mj = robot.mj_model
    data = mujoco.MjData(mj)
    link = robot.link_dof
    data.qpos[link], data.qvel[link] = qd[0], dqd[0]
    q_log, tau_log = np.empty((steps, model.nv)), np.empty((steps, model.nv))
    every = max(int(round(snapshot * rate)), 1)
    snap_t, snap_err = [], []
    attached = False
    h = 1.0 / rate
    dq_prev = dqd[0]
    for k in range(steps):
        if payload is not None and not attached and t[k] >= payload_time - 1e-12:
            robot.set_payload(True)
            attached = True
        q, dq = data.qpos[link].copy(), data.qvel[link].copy()
        if controller.composite > 0 and k > 0:
            controller.observe(q_log[k - 1], dq_prev, (dq - dq_prev) / h, tau_log[k - 1])
        dq_prev = dq
        tau = controller.step(q, dq, qd[k], dqd[k], ddqd[k], h)
        data.qfrc_applied[link] = (tau - explicit_friction(robot.effects, dq) if explicit
                                   else tau)
        mujoco.mj_step(mj, data)
        if data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number:
            raise ModelError(f"the MuJoCo simulation diverged at t = {t[k]:.3f} s (bad "
                             "accelerations): lower gamma, bandwidth or composite, or raise rate")
        q_log[k], tau_log[k] = q, tau
        if k % every == 0 or k == steps - 1:
            snap_t.append(t[k])
            snap_err.append(torque_error(controller.parameters,
                                         loaded_full if attached else truth_full))
        if k % 1000 == 999:
            if not np.all(np.isfinite(data.qpos)) or np.max(np.abs(q - qd[k])) > np.pi:
                raise ModelError(f"the adaptive run diverged before t = {t[k]:.3f} s (tracking "
                                 f"error {np.max(np.abs(q - qd[k])):.3g} rad): lower gamma or "
                                 "bandwidth, or raise rate")
            if progress is not None:
                progress((k + 1) / steps)
    return AdaptiveRun(
        t=t, q=q_log, q_desired=qd, tau=tau_log, period=period, periods=periods,
        payload_time=payload_time if payload is not None else None,
        estimate_t=np.array(snap_t), estimate_error=np.array(snap_err),
        initial_parameters=initial, final_parameters=controller.parameters.copy(),
        true_parameters=truth_full, true_parameters_loaded=loaded_full,
        projected_minimum=np.array(controller.projected_minimum),
        clips=len(controller.clips), controller=controller)



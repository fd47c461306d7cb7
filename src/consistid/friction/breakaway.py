r"""Break-away (static) friction per joint: the torque at which a joint at rest starts to move.

An *event* is the first sample ``k`` at which joint ``j``'s speed reaches the threshold
``v_th`` after at least ``min_still`` seconds below it (the youBot report's criterion, seeds
Section 3.6: "the point at which the applied torque is greater than the frictional force, the
velocity of the body increases"). Its friction torque is what the model does not explain,

.. math::  f_k = τ_{kj} - \mathrm{RNEA}_j(q_k, \dot q_k, \ddot q_k)

— the gravity torque of the pose with the identified (or nominal) model, and, with
``inertial=True`` (default), the inertial and Coriolis torque of the starting motion, which a
threshold crossing always has (without it a ramp of slope ``ṙ`` reads high by about
``√(2 M_jj v_th ṙ)``). The event's value is the largest ``s·f_k`` from the crossing until the
speed reaches :data:`PEAK_FACTOR` ``· v_th``: a stiction that creeps before it lets go (a soft
one, e.g. MuJoCo's friction loss on a joint of small inertia, whose creep speed grows as
``τ/M_jj``) is still rising at the crossing, and the peak is where it breaks away. The peak is
that of a moving mean over :data:`PEAK_SMOOTHING` samples, so torque noise ``σ`` biases it by
about ``σ/√5`` to ``σ`` (fewer samples: more). A stiction so soft
that the joint creeps beyond ``PEAK_FACTOR · v_th`` before it lets go reads low (raise
``threshold`` and the plan's ``abort_speed`` together). The break-away torque of the joint is
the median of ``s_k f_k`` over its events (``s_k`` the direction of motion), as in the report
(Section 4.2, box plots of 25 experiments), and its spread ``1.4826·MAD``; the medians per
direction are kept too (a gravity-model error ``Δg`` moves them by ``∓Δg``: their mean
``(f⁺ + f⁻)/2`` is free of it).

Sources of events: any log (``estimate_breakaway(model, data)``: the first motion after each
standstill), or, with ``data=None``, the torque ramps of a
:class:`~consistid.friction.ramp.RampPlan` run on the MuJoCo robot (:func:`simulate_ramps`)
carrying the given :class:`~consistid.simulate.Effects` — MuJoCo's ``frictionloss`` holds a
joint up to its value, so a set value is a truth to check against.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

import numpy as np
import pinocchio as pin

from ..data.dataset import Dataset
from ..errors import (DatasetError, IdentificationError, ModelError, ModelMisfitWarning,
                      OptionError, check_number)
from ..identification.result import StandardParameterSet
from ..identification.summary import table
from ..report.html import Page
from ..report.result import Reported
from ..robot.joint_terms import STANDSTILL_SPEED
from ..robot.model import RobotModel
from ..simulate.effects import (Effects, explicit_friction, explicit_friction_slope,
                                has_explicit_friction)
from .ramp import RampPlan, ramp_plan

if TYPE_CHECKING:
    from ..simulate.mujoco_robot import MujocoRobot

#: Default detection threshold ``v_th`` (rad/s) and standstill before an event (s).
THRESHOLD, MIN_STILL = STANDSTILL_SPEED, 0.1
#: The friction of an event is read up to ``PEAK_FACTOR · v_th`` (module docstring).
PEAK_FACTOR = 2.5
#: ... as the peak of its moving mean over this many samples (when the window has them).
PEAK_SMOOTHING = 5
#: Bandwidth (rad/s) of the computed-torque hold of the other joints during simulated ramps.
HOLD_BANDWIDTH = 30.0
MISSING = ("raise", "warn")


@dataclass(frozen=True)
class BreakawayEvent:
    """One first motion after standstill: joint index, time (s), direction ±1, friction torque
    magnitude ``s·f`` (N·m) and the speed at the detecting sample (rad/s)."""

    joint: int
    time: float
    direction: int
    torque: float
    speed: float


@dataclass(frozen=True, eq=False)
class BreakawayEstimate(Reported):
    """Break-away torque per joint (module docstring).

    Attributes
    ----------
    joint_names : (nv,) names.
    torque : (nv,) median break-away torque (N·m); NaN only for joints not asked for
        (``measured`` False) or, with ``missing="warn"``, without events (the warning names them).
    spread : (nv,) ``1.4826·MAD`` of the events (N·m; NaN below 3 events, noted).
    positive, negative : (nv,) medians of the events in each direction (NaN if none).
    n_events : (nv,) number of events.
    events : every event.
    measured : (nv,) bool, joints analysed.
    threshold, min_still : the detection settings.
    inertial : whether the inertial torque of the starting motion was subtracted.
    source : ``"log"`` or a description of the simulated ramp experiment.
    duration : seconds of data read (the experiment's length for simulated ramps).
    notes : what was not found, and why.
    """

    joint_names: tuple[str, ...]
    torque: np.ndarray
    spread: np.ndarray
    positive: np.ndarray
    negative: np.ndarray
    n_events: np.ndarray
    events: tuple[BreakawayEvent, ...]
    measured: np.ndarray
    threshold: float
    min_still: float
    inertial: bool
    source: str
    duration: float
    notes: tuple[str, ...] = ()

    @property
    def estimate(self) -> np.ndarray:
        """The estimated vector: ``torque`` (N·m per joint)."""
        return self.torque

    @property
    def std(self) -> np.ndarray:
        """Standard error of each median, ``1.2533·spread/√n`` (the large-sample standard error
        of a median of normal events); ``conf_int`` gives the normal intervals from it."""
        return 1.2533 * self.spread / np.sqrt(np.maximum(self.n_events, 1))

    def summary(self) -> str:
        rows = []
        for j, name in enumerate(self.joint_names):
            if not self.measured[j]:
                rows.append([name, "not measured", "", "", "", ""])
                continue
            rows.append([name, self.torque[j], self.spread[j], self.positive[j],
                         self.negative[j], int(self.n_events[j])])
        head = (f"break-away friction from {self.source} ({self.duration:.1f} s): first motion "
                f"after ≥ {self.min_still:g} s below {self.threshold:g} rad/s; torque minus "
                f"{'inverse dynamics' if self.inertial else 'gravity'} of the model")
        text = head + "\n" + table(["joint", "median [N·m]", "spread [N·m]", "median +",
                                    "median −", "events"], rows)
        if self.notes:
            text += "\nNotes:\n" + "\n".join(f"  - {n}" for n in self.notes)
        return text

    def __str__(self) -> str:
        return self.summary()

    def page(self) -> Page:
        """The HTML report: per joint the median, spread, directions, events and interval."""
        page = Page("consistid break-away friction",
                    f"from {self.source} ({self.duration:.1f} s): first motion after "
                    f"≥ {self.min_still:g} s below {self.threshold:g} rad/s")
        ci = self.conf_int()
        page.table(["joint", "median [N·m]", "spread [N·m]", "median +", "median −", "events",
                    "95 % interval"],
                   [(n, t, s, p, m, int(k), f"{lo:.4g} … {hi:.4g}") if ok
                    else (n, "not measured", "", "", "", "", "")
                    for n, t, s, p, m, k, (lo, hi), ok in zip(
                        self.joint_names, self.torque, self.spread, self.positive,
                        self.negative, self.n_events, ci, self.measured)])
        page.bullets(self.notes)
        return page


@dataclass(frozen=True, eq=False)
class RampRun:
    """A simulated ramp experiment: the log (exact MuJoCo states, measured torques), the plan,
    and each ramp's sample window ``(ramp, first, last, moved)``."""

    dataset: Dataset
    plan: RampPlan
    windows: tuple[tuple[object, int, int, bool], ...]


def _robot_model(model: RobotModel | StandardParameterSet) -> RobotModel:
    if isinstance(model, StandardParameterSet):
        return model.identified_model()
    if isinstance(model, RobotModel):
        return model
    raise ModelError(f"model must be a RobotModel or an identification result, got "
                     f"{type(model).__name__}")


def simulate_ramps(model: RobotModel, plan: RampPlan, effects: Effects | None = None,
                   parameters: np.ndarray | None = None, timestep: float = 1e-3,
                   seed: int = 0) -> RampRun:
    """Run ``plan`` on the MuJoCo robot (:class:`~consistid.simulate.mujoco_robot.MujocoRobot`)
    carrying ``effects`` and true inertial ``parameters`` (default the model's).

    Before each ramp every joint is held at the pose by computed torque on ``model`` (bandwidth
    :data:`HOLD_BANDWIDTH`); during a ramp the other joints stay held and the ramped joint's
    torque ramps from the torque that held it (``g(q₀)`` plus what holding needed), until it
    reaches ``plan.abort_speed``, leaves ``plan.max_excursion`` or the ramp reaches
    ``max_torque``. Every physics step is logged:
    MuJoCo's exact ``q, q̇, q̈`` and the commanded torque with ``effects.torque_noise``.
    Raises :class:`ModelError` for elastic joints (the ramp acts on the link).
    """
    from ..simulate.mujoco_robot import MujocoRobot

    robot = MujocoRobot(model, effects, parameters, timestep=timestep)
    if robot.effects.elastic.any():
        raise ModelError("ramp experiments act on rigid joints; switch elasticity off")
    _check_friction_step(model, robot.effects, plan, timestep)
    rec = _RampRecorder(model, robot, plan)
    n_settle = int(round(plan.settle / rec.h))
    windows = tuple(_run_ramp(rec, plan, ramp, n_settle) for ramp in plan.ramps)
    n = len(rec.log_u)
    if not (np.all(np.isfinite(rec.data.qpos)) and np.all(np.isfinite(rec.log_dq[-1]))):
        raise ModelError("the simulated ramp experiment diverged (non-finite state): a friction "
                         "law too steep for the physics step; shorten timestep")
    rng = np.random.default_rng(seed)
    tau = np.asarray(rec.log_u) + np.asarray(rec.eff.torque_noise) * rng.standard_normal(
        (n, model.nv))
    dataset = Dataset(t=np.arange(n) * rec.h, q=np.asarray(rec.log_q),
                      dq=np.asarray(rec.log_dq), ddq=np.asarray(rec.log_ddq), tau=tau,
                      joint_names=tuple(model.joint_names))
    return RampRun(dataset, plan, windows)


def _check_friction_step(model: RobotModel, eff: Effects, plan: RampPlan,
                         timestep: float) -> None:
    """An explicit friction law is applied once per physics step: refuse one whose slope makes
    ``h·slope/M_jj ≥ 1`` at the pose (the step would overshoot)."""
    if not has_explicit_friction(eff):
        return
    pm = model.pin_model
    inertia = np.diag(pin.crba(pm, pm.createData(), model.configuration(plan.pose))) \
        + np.asarray(eff.armature)
    ratio = timestep * explicit_friction_slope(eff) / inertia
    if np.any(ratio >= 1.0):
        j = int(np.argmax(ratio))
        raise ModelError(f"the explicit friction on {model.joint_names[j]!r} is too steep "
                         f"for the physics step at the pose: h·slope/M_jj = {ratio[j]:.3g} "
                         "≥ 1; shorten timestep or soften the friction law")


class _RampRecorder:
    """The MuJoCo robot of a ramp experiment at the plan's pose, at rest: one physics
    :meth:`step` under a torque (logged), and the computed-torque :meth:`hold` of the pose."""

    def __init__(self, model: RobotModel, robot: "MujocoRobot", plan: RampPlan) -> None:
        import mujoco

        self.model, self.plan, self.eff = model, plan, robot.effects
        self.mj, self.data = robot.mj_model, mujoco.MjData(robot.mj_model)
        self.link, self.h = robot.link_dof, robot.timestep
        self.pm = model.pin_model
        self.pdata = self.pm.createData()
        self.explicit = has_explicit_friction(self.eff)
        self.data.qpos[self.link] = plan.pose
        self.data.qvel[:] = 0.0
        self.log_q, self.log_dq, self.log_ddq, self.log_u = [], [], [], []

    def step(self, u: np.ndarray) -> None:
        import mujoco

        data, link = self.data, self.link
        self.log_q.append(data.qpos[link].copy())
        self.log_dq.append(data.qvel[link].copy())
        applied = u - explicit_friction(self.eff, data.qvel[link]) if self.explicit else u
        data.qfrc_applied[link] = applied
        mujoco.mj_step(self.mj, data)
        self.log_ddq.append(data.qacc[link].copy())
        self.log_u.append(u.copy())

    def hold(self) -> np.ndarray:
        kp, kd = HOLD_BANDWIDTH ** 2, 2.0 * HOLD_BANDWIDTH
        q, v = self.data.qpos[self.link].copy(), self.data.qvel[self.link].copy()
        a = kp * (self.plan.pose - q) - kd * v
        return pin.rnea(self.pm, self.pdata, self.model.configuration(q), v, a)


def _run_ramp(rec: _RampRecorder, plan: RampPlan, ramp: object, n_settle: int
              ) -> tuple[object, int, int, bool]:
    """Hold the pose ``n_settle`` steps, then ramp ``ramp.joint``'s torque (module docstring of
    :func:`simulate_ramps`); returns the window ``(ramp, first, last, moved)``."""
    j = ramp.joint
    u_start = plan.gravity[j]
    for _ in range(n_settle):
        u = rec.hold()
        rec.step(u)
        u_start = u[j]
    first, moved = len(rec.log_u), False
    top = float(plan.max_torque[j])
    k = 0
    while True:
        # from the holding torque (a step to g(q0) would jolt the stuck joint)
        commanded = u_start + ramp.direction * plan.rate * k * rec.h
        if abs(commanded - plan.gravity[j]) > top:
            break
        u = rec.hold()       # the ramped joint's own torque is replaced; its hold term stays
        u[j] = commanded     # in the others' (a jump there would jolt it too)
        rec.step(u)
        k += 1
        if abs(rec.data.qvel[rec.link[j]]) >= plan.abort_speed or \
                abs(rec.data.qpos[rec.link[j]] - plan.pose[j]) > plan.max_excursion:
            moved = True
            break
    return ramp, first, len(rec.log_u) - 1, moved


def _reading_window(dq: np.ndarray, segment: np.ndarray, k: int, speed: float) -> np.ndarray:
    """Samples from the crossing ``k`` while ``|q̇| < speed`` (the crossing always), the joint
    moving the same way in the same segment (a ramp's torque is replaced by the holding
    controller's once the joint reaches its abort speed: that sample is not read)."""
    s, n, stop = np.sign(dq[k]), dq.size, k
    while stop + 1 < n and segment[stop + 1] == segment[k] and np.sign(dq[stop + 1]) == s \
            and abs(dq[stop + 1]) < speed:
        stop += 1
    return np.arange(k, stop + 1)


def _events(dq: np.ndarray, t: np.ndarray, segment: np.ndarray, threshold: float,
            min_still: float, start: int = 0) -> tuple[list[int], bool]:
    """Indices of the first samples at or above ``threshold`` after ``≥ min_still`` s below it
    (within one segment), and whether any standstill was found at all."""
    moving = np.abs(dq) >= threshold
    out, still_found = [], False
    k, n = 0, dq.size
    while k < n:
        if moving[k]:
            k += 1
            continue
        stop = k
        while stop < n and not moving[stop] and segment[stop] == segment[k]:
            stop += 1
        long_enough = t[stop - 1] - t[k] >= min_still
        still_found |= bool(long_enough)
        if long_enough and stop < n and segment[stop] == segment[k]:
            out.append(start + stop)
        k = stop if stop > k else k + 1
    return out, still_found


def _still_rising(f: np.ndarray) -> bool:
    """Whether the friction read over an event's window peaks at its last sample and has risen
    by more than 2 % of its value over the window's last quarter: the joint crept past the
    reading speed before breaking free, so the peak was not reached."""
    if f.size < 8 or int(np.argmax(f)) != f.size - 1:
        return False
    quarter = max(f.size // 4, 1)
    return bool(f[-1] - f[-1 - quarter] > 0.02 * abs(f[-1]))


def estimate_breakaway(model: RobotModel | StandardParameterSet, data: Dataset | None = None, *,
                       effects: Effects | None = None, plan: RampPlan | None = None,
                       parameters: np.ndarray | None = None,
                       joints: Sequence[int | str] | None = None,
                       threshold: float = THRESHOLD, min_still: float = MIN_STILL,
                       inertial: bool = True, missing: str = "raise", seed: int = 0,
                       **plan_options: object) -> BreakawayEstimate:
    """Break-away torque per joint (module docstring).

    Parameters
    ----------
    model : the robot whose inverse dynamics is subtracted: a :class:`RobotModel` (nominal) or an
        identification result (its identified inertias).
    data : a log with torques; ``None`` runs the ramp experiment on the MuJoCo robot
        (:func:`simulate_ramps`) with ``effects``, ``parameters`` (true inertias, default the
        model's) and ``plan`` (default :func:`~consistid.friction.ramp.ramp_plan` of the model
        with ``plan_options``, e.g. ``rate``, ``repeats``, ``pose``, ``max_torque``).
    joints : joints to analyse (names or indices); default all (those of the plan when given).
    threshold : ``v_th`` (rad/s); must lie below the plan's ``abort_speed`` for simulated ramps.
    min_still : seconds below ``v_th`` before an event counts.
    inertial : subtract the full inverse dynamics (default) or the gravity torque of the pose
        only (``RNEA(q, 0, 0)``, for logs whose accelerations are too noisy).
    missing : ``"raise"`` (default) or ``"warn"`` for a joint without events.

    Raises
    ------
    DatasetError : in a log, a joint that never stands still for ``min_still`` ("a joint that
        never stops"), or stands still but never starts to move again.
    IdentificationError : in the ramp experiment, a joint that moved in none of its ramps up to
        ``max_torque`` (its break-away torque is larger: raise ``max_torque`` within the effort
        limit).
    """
    robot = _robot_model(model)
    threshold = check_number("threshold", threshold, 0, strict=True)
    min_still = check_number("min_still", min_still, 0)
    if missing not in MISSING:
        raise OptionError(f"missing={missing!r} is not supported; allowed: {MISSING}")
    nv, names = robot.nv, robot.joint_names
    if data is None:
        run, source = _simulated(robot, effects, plan, parameters, threshold, seed,
                                 plan_options)
        data, default_joints = run.dataset, sorted({r.joint for r in run.plan.ramps})
    else:
        _check_log(robot, data, effects, plan, parameters, plan_options)
        run, source, default_joints = None, "log", list(range(nv))
    tau = data.require_torque()
    chosen = _chosen_joints(robot, joints, default_joints)
    segment = data.segment if data.segment is not None else np.zeros(data.n_samples, int)
    notes: list[str] = []
    problems: list[tuple[type, str]] = []
    found = {}
    for j in chosen:
        idx = (_log_events(names, data, segment, j, threshold, min_still, problems)
               if run is None else
               _ramp_events(names, data, segment, j, run, threshold, notes, problems))
        if idx is not None:
            found[j] = idx
    events, rising = _read_events(robot, data, tau, segment, found, threshold, inertial)
    for kind, message in problems:
        if missing == "raise":
            raise kind(message)
        warnings.warn(message, UserWarning, stacklevel=2)
        notes.append(message)
    torque, spread, pos, neg, count = _statistics(names, chosen, events, rising, notes)
    measured = np.zeros(nv, dtype=bool)
    measured[list(chosen)] = True
    return BreakawayEstimate(tuple(names), torque, spread, pos, neg, count, tuple(events),
                             measured, threshold, min_still, bool(inertial), source,
                             float(data.t[-1] - data.t[0]), tuple(notes))


def _simulated(robot: RobotModel, effects: Effects | None, plan: RampPlan | None,
               parameters: np.ndarray | None, threshold: float, seed: int,
               plan_options: dict) -> tuple[RampRun, str]:
    """The ramp experiment of :func:`estimate_breakaway` with ``data=None``, and its
    description."""
    start_time = time.perf_counter()
    plan = plan or ramp_plan(robot, **plan_options)  # type: ignore[arg-type]
    if threshold >= plan.abort_speed:
        raise OptionError(f"threshold = {threshold:g} rad/s must lie below the plan's "
                          f"abort_speed = {plan.abort_speed:g} rad/s (a ramp stops there)")
    run = simulate_ramps(robot, plan, effects, parameters, seed=seed)
    return run, (f"{len(plan.ramps)} simulated torque ramps at {plan.rate:g} N·m/s "
                 f"(MuJoCo, {time.perf_counter() - start_time:.1f} s wall)")


def _check_log(robot: RobotModel, data: object, effects: Effects | None,
               plan: RampPlan | None, parameters: np.ndarray | None, plan_options: dict
               ) -> None:
    """A given log: a :class:`Dataset` of the robot's joints, and no option of the simulated
    experiment."""
    if plan_options or plan is not None or effects is not None or parameters is not None:
        raise OptionError("effects, parameters, plan and ramp options apply to the simulated "
                          "experiment (data=None), not to a given log")
    if not isinstance(data, Dataset):
        raise DatasetError(f"data must be a Dataset (or None to simulate ramps), got "
                           f"{type(data).__name__}")
    data.check_joints(robot.nv, robot.joint_names)


def _chosen_joints(robot: RobotModel, joints: Sequence[int | str] | None,
                   default: list[int]) -> list[int]:
    """The indices of ``joints`` (names or indices; ``None``: ``default``), checked."""
    names = robot.joint_names
    chosen = default if joints is None else [
        names.index(j) if isinstance(j, str) and j in names else j for j in joints]
    for j in chosen:
        if isinstance(j, bool) or not isinstance(j, (int, np.integer)) or not 0 <= j < robot.nv:
            raise OptionError(f"joints: {j!r} is not a joint of {robot.name} ({names})")
    return chosen


def _ramp_events(names: Sequence[str], data: Dataset, segment: np.ndarray, j: int,
                 run: RampRun, threshold: float, notes: list[str],
                 problems: list[tuple[type, str]]) -> list[int] | None:
    """The event of each of joint ``j``'s simulated ramps that moved (``None`` and a problem
    when none did); a warning and a note for the ramps that did not."""
    idx, tried, still = [], 0, {1: 0, -1: 0}
    for ramp, first, last, moved in run.windows:
        if ramp.joint != j:
            continue
        tried += 1
        found, _ = _events(data.dq[first:last + 1, j], data.t[first:last + 1],
                           segment[first:last + 1], threshold, 0.0, first)
        idx += found[:1]
        still[ramp.direction] += not found
    top = float(run.plan.max_torque[j])
    if not idx:
        problems.append((IdentificationError,
                         f"joint {names[j]!r} did not move in any of its {tried} ramps "
                         f"up to ±{top:.4g} N·m beyond g(q0): its break-away torque is "
                         f"above {top:.4g} N·m, not a number (raise max_torque within "
                         "the effort limit) or the joint is blocked"))
        return None
    for sign, count in still.items():
        if count:
            message = (f"{names[j]}: {count} ramp(s) towards {'+' if sign > 0 else '−'} "
                       f"ended without motion at ±{top:.4g} N·m beyond g(q0): the "
                       f"break-away that way is above {top:.4g} N·m in those; the "
                       "estimate comes from the ramps that moved (raise max_torque)")
            warnings.warn(message, UserWarning, stacklevel=3)
            notes.append(message)
    return idx


def _log_events(names: Sequence[str], data: Dataset, segment: np.ndarray, j: int,
                threshold: float, min_still: float,
                problems: list[tuple[type, str]]) -> list[int] | None:
    """Joint ``j``'s events in a log (``None`` and a problem when it never stands still or
    never starts again)."""
    idx, still = _events(data.dq[:, j], data.t, segment, threshold, min_still)
    if not still:
        problems.append((DatasetError,
                         f"joint {names[j]!r} never stands still (|q̇| < {threshold:g} "
                         f"rad/s for ≥ {min_still:g} s) in the log: no break-away event; "
                         "record a ramp from rest (consistid.friction.ramp) or lower "
                         "min_still"))
        return None
    if not idx:
        problems.append((DatasetError,
                         f"joint {names[j]!r} stands still in the log but never starts "
                         f"to move again (|q̇| ≥ {threshold:g} rad/s): no break-away "
                         "event"))
        return None
    return idx


def _read_events(robot: RobotModel, data: Dataset, tau: np.ndarray, segment: np.ndarray,
                 found: dict[int, list[int]], threshold: float, inertial: bool
                 ) -> tuple[list[BreakawayEvent], dict[int, int]]:
    """Each found event's friction (module docstring: the peak of the moving mean of
    ``s·(τ − RNEA)`` over the reading window), and per joint the number of events whose
    friction still rose at the window's end."""
    dq, ddq = (data.dq, data.ddq) if inertial else (np.zeros_like(data.dq),) * 2
    events: list[BreakawayEvent] = []
    rising: dict[int, int] = {}
    for j, idx in found.items():
        for k in idx:
            window = _reading_window(data.dq[:, j], segment, k, PEAK_FACTOR * threshold)
            s = int(np.sign(data.dq[k, j]))
            f = s * (tau[window, j] - robot.rnea(data.q[window], dq[window], ddq[window])[:, j])
            if f.size >= PEAK_SMOOTHING:    # the peak of a moving mean: less noise bias
                f = np.convolve(f, np.full(PEAK_SMOOTHING, 1.0 / PEAK_SMOOTHING), "valid")
            events.append(BreakawayEvent(j, float(data.t[k]), s, float(np.max(f)),
                                         float(abs(data.dq[k, j]))))
            rising[j] = rising.get(j, 0) + int(_still_rising(f))
    return events, rising


def _statistics(names: Sequence[str], chosen: list[int], events: list[BreakawayEvent],
                rising: dict[int, int], notes: list[str]) -> tuple[np.ndarray, ...]:
    """Per joint the median break-away torque, its spread ``1.4826·MAD``, the medians per
    direction and the number of events; notes (and warnings) on what makes them doubtful."""
    nv = len(names)
    torque, spread, pos, neg = (np.full(nv, np.nan) for _ in range(4))
    count = np.zeros(nv, dtype=int)
    for j in chosen:
        own = [e for e in events if e.joint == j]
        values = np.array([e.torque for e in own])
        if values.size == 0:
            continue
        dirs = np.array([e.direction for e in own])
        torque[j] = float(np.median(values))
        spread[j] = (float(1.4826 * np.median(np.abs(values - torque[j])))
                     if values.size >= 3 else np.nan)
        if values.size < 3:
            notes.append(f"{names[j]}: {values.size} event(s) only: no spread (NaN); repeat the "
                         "ramp (repeats=) for one")
        if 2 * rising.get(j, 0) > values.size:
            message = (f"{names[j]}: the friction was still rising at the end of the reading "
                       f"window in {rising[j]} of {values.size} events (the joint crept past "
                       f"{PEAK_FACTOR:g}·threshold before it broke free): the break-away torque "
                       "may read low; raise threshold (and abort_speed for a ramp)")
            warnings.warn(message, UserWarning, stacklevel=3)
            notes.append(message)
        pos[j] = float(np.median(values[dirs > 0])) if np.any(dirs > 0) else np.nan
        neg[j] = float(np.median(values[dirs < 0])) if np.any(dirs < 0) else np.nan
        count[j] = values.size
        if torque[j] <= 0:          # a friction that pushes along the motion: non-physical
            message = (f"{names[j]}: break-away torque {torque[j]:.4g} N·m ≤ 0 (median of "
                       f"{values.size} event(s)) is not physical: static friction opposes "
                       "the motion; the model's gravity (or a torque offset) is off by about "
                       "the break-away torque: identify the rigid body and offsets first")
            warnings.warn(message, ModelMisfitWarning, stacklevel=3)
            notes.append(message)
        elif np.any(values <= 0):
            notes.append(f"{names[j]}: {int(np.sum(values <= 0))} event(s) with friction "
                         "against the motion ≤ 0: the model's gravity (or a torque offset) "
                         "is off by about the break-away torque")
    return torque, spread, pos, neg, count

r"""Replays of a log in the simulator, batched through ``mujoco.rollout``.

The log is put on the simulator's time grid ``t_k = t_0 + k h`` (positions and velocities
interpolated linearly, the torque held from the last logged sample: a zero-order hold, as a
torque loop applies it). Two replays:

* **closed loop** (:func:`closed_loop`): from the logged start state, the PD of
  :mod:`.options` around the logged motion with the logged torque as feed-forward; reported are
  the tracking error ``e_k = q_k − q_{log,k}`` and the correction torque
  ``c_k = K_p(q_{log,k} − q_k) + K_d(q̇_{log,k+a} − q̇_{k+a})`` (the torque the simulated robot
  needs beyond the logged one to follow the log). ``a = 1`` under an implicit integrator, which
  applies the damping at the end of the step, ``(M + A + h K_d) Δv = h (f + K_d (q̇_{ref} −
  q̇_k))``: with the reference one step ahead, a robot that follows the log needs no correction,
  and the PD adds no inertia ``h K_d`` of its own (with ``a = 0`` it would, the bias that
  ``mujoco.sysid``'s armature absorbs); ``a = 0`` under ``Euler`` and ``RK4``;
* **computed torque** (:func:`computed_torque`): at each step the torque
  ``u_k = ID(q_k, q̇_k, a_k)`` of the simulated model itself with
  ``a_k = a_{log,k} + K_d(q̇_{log,k} − q̇_k) + K_p(q_{log,k} − q_k)`` and
  ``a_{log,k} = (q̇_{log,k+1} − q̇_{log,k}) / h`` the log's acceleration over the step (so that a
  log that is a MuJoCo run at this step is followed exactly, whatever its filter's ``q̈``);
  reported are ``e_k`` and ``c_k = u_k − τ_{log,k}``, the torque the model commands beyond the
  logged one. The model's inverse includes its drive gain (``u = ID / g``, so that the joint
  receives ``ID``), not its delay (the command is applied late, as a real one would be). One
  ``mj_inverse`` and one ``mj_step`` per step and model (no batch: the control depends on the
  state);
* **open loop** (:func:`open_loop`): the logged torque alone, the state reset to the logged
  one every ``W`` seconds (windows run as one batch); reported is the drift ``q − q_log`` per
  window. Open-loop replays of an arm under gravity diverge without feedback; the window keeps
  the measure finite and comparable.

Every replay applies the simulator's actuation to a commanded torque ``τ`` (the logged one,
or the computed torque): the joint receives ``g ⊙ τ(t − δ)`` (:func:`actuated`; gain ``g`` and
delay ``δ`` of :mod:`.terms`, 1 and 0 unless calibrated), ``τ`` interpolated linearly between
grid points and held at its first value before the log starts.

A rollout that diverges (a non-finite state, MuJoCo's ``BADQACC`` reset, or a tracking error
beyond :data:`DIVERGED` rad) is flagged rather than raised, so that one bad candidate does not
abort a calibration (unlike ``mujoco.sysid`` 4.0.0).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import mujoco
import mujoco.rollout
import numpy as np

from ..data.dataset import Dataset
from ..errors import DatasetError
from .engine import CONTROLS, Simulator
from .options import ComputedTorque, Controller

#: A tracking error beyond this (rad) marks a closed-loop rollout as diverged.
DIVERGED = 1.0
#: The most simulator steps a replayed log may span (10⁷: 5.5 h at 2 ms; each step holds
#: the state of every model compared), checked before any array is allocated.
MAX_STEPS = 10_000_000


@dataclass(frozen=True, eq=False)
class LogGrid:
    """A log on the simulator's grid: ``t`` (S,), ``q``, ``dq``, ``tau`` (S, nv)."""

    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray

    @classmethod
    def from_dataset(cls, data: Dataset, timestep: float) -> "LogGrid":
        """The one-segment dataset ``data`` on the grid of step ``timestep`` (module notes)."""
        if data.tau is None:
            raise DatasetError("a replay needs logged torques; the dataset has tau=None")
        if data.segment is not None and np.unique(data.segment).size > 1:
            raise DatasetError("a replay runs one continuous recording; select one segment "
                               "(Dataset.select(data.segment == k))")
        span = float(data.t[-1] - data.t[0])
        if not span / timestep <= MAX_STEPS:
            raise DatasetError(f"the log lasts {span:.6g} s: {span / timestep:.3g} simulator "
                               f"steps of timestep={timestep:g} s, more than {MAX_STEPS:.0e}; "
                               "give a larger timestep or replay a shorter part of the log "
                               "(Dataset.select)")
        t = data.t[0] + timestep * np.arange(int(np.floor(span / timestep + 1e-9)) + 1)
        if t.size < 3:
            raise DatasetError(f"the log lasts {data.t[-1] - data.t[0]:.3g} s, less than three "
                               f"simulator steps of {timestep:g} s")
        q = np.column_stack([np.interp(t, data.t, c) for c in data.q.T])
        dq = np.column_stack([np.interp(t, data.t, c) for c in data.dq.T])
        held = np.clip(np.searchsorted(data.t, t + 1e-9 * timestep, side="right") - 1, 0, None)
        return cls(t, q, dq, np.asarray(data.tau, dtype=float)[held])


def actuated(tau: np.ndarray, timestep: float, gain: np.ndarray | None,
             delay: float) -> np.ndarray:
    """``g ⊙ τ(t − δ)`` of a torque ``tau`` (S, nv) on a grid of step ``timestep`` (module
    docstring)."""
    out = tau
    if delay > 0.0:
        s = np.arange(tau.shape[0]) - delay / timestep
        out = np.column_stack([np.interp(s, np.arange(tau.shape[0]), c) for c in tau.T])
    return out if gain is None else out * gain


def _rollout(models: Sequence[Any], sim: Simulator, states: np.ndarray, controls: np.ndarray,
             threads: int) -> np.ndarray:
    """``mujoco.rollout`` of ``models`` (one per batch row) from ``states`` under ``controls``
    (batch, steps, nu + nv); returns the states after each step (batch, steps, nstate)."""
    datas = [mujoco.MjData(sim.mj_model) for _ in range(threads)]
    out, _ = mujoco.rollout.rollout(list(models), datas, states, controls,
                                    control_spec=int(CONTROLS))
    return out


def was_reset(start: np.ndarray, states: np.ndarray, timestep: float) -> np.ndarray:
    """(batch,) whether MuJoCo reset a rollout on the way (a ``BADQACC`` warning: an
    unstable step, e.g. gains too stiff for the step or torques beyond any physics): its
    time, the first coordinate of each state, stops following ``t_0 + (k + 1) h``."""
    expected = start[:, None, 0] + timestep * np.arange(1, states.shape[1] + 1)
    with np.errstate(invalid="ignore"):
        return np.any(~(np.abs(states[..., 0] - expected) <= 0.5 * timestep), axis=1)


def _positions(sim: Simulator, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Joint positions and velocities out of full-physics states (…, nstate)."""
    nq = sim.mj_model.nq
    return states[..., 1 + sim.qpos], states[..., 1 + nq + sim.dofs]


def _controls(sim: Simulator, q_ref: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Per-step controls (steps, nu + nv): PD set points, the torque as applied force."""
    m = sim.mj_model
    out = np.zeros((tau.shape[0], m.nu + m.nv))
    out[:, :sim.nv] = q_ref
    out[:, m.nu + sim.dofs] = tau
    return out


@dataclass(frozen=True, eq=False)
class ClosedLoop:
    """Closed-loop replays of a batch of models: ``error`` (B, S, nv) rad, ``correction``
    (B, S − 1, nv) N·m (one per step), ``diverged`` (B,)."""

    error: np.ndarray
    correction: np.ndarray
    diverged: np.ndarray


def closed_loop(sim: Simulator, models: Sequence[Any], log: LogGrid, kp: np.ndarray,
                kd: np.ndarray, threads: int = 1,
                actuation: Sequence[tuple[np.ndarray | None, float]] | None = None
                ) -> ClosedLoop:
    """Closed-loop replay (module docstring) of each of ``models`` (variants of ``sim``'s,
    copied with the gains, :meth:`Simulator.with_gains`), one ``mujoco.rollout`` call;
    ``actuation``: ``(gain, delay)`` per model (default ``sim``'s)."""
    models = [sim.with_gains(m, kp, kd) for m in models]
    actuation = actuation or [(sim.gain, sim.delay)] * len(models)
    a = int(sim.implicit)
    steps = log.t.size - 1
    h = float(sim.mj_model.opt.timestep)
    ref = log.q[:-1] + (kd / kp) * log.dq[a:steps + a]
    controls = np.stack([_controls(sim, ref, actuated(log.tau, h, g, d)[:-1])
                         for g, d in actuation])
    start = sim.initial_state(log.q[0], log.dq[0])
    starts = np.tile(start, (len(models), 1))
    states = _rollout(models, sim, starts, controls, threads)
    q, dq = _positions(sim, states)
    q0 = np.broadcast_to(log.q[0], (len(models), 1, sim.nv))
    dq0 = np.broadcast_to(log.dq[0], (len(models), 1, sim.nv))
    q, dq = np.concatenate([q0, q], axis=1), np.concatenate([dq0, dq], axis=1)
    error = q - log.q
    with np.errstate(invalid="ignore", over="ignore"):
        correction = kp * (log.q[:-1] - q[:, :-1]) + kd * (log.dq[a:steps + a]
                                                            - dq[:, a:steps + a])
        diverged = ~np.all(np.isfinite(error), axis=(1, 2)) | (
            np.nanmax(np.abs(error), axis=(1, 2)) > DIVERGED) | was_reset(starts, states, h)
    return ClosedLoop(error, correction, diverged)


def closed_loop_under(controller: Controller, sim: Simulator, models: Sequence[Any],
                      log: LogGrid, kp: np.ndarray, kd: np.ndarray, threads: int = 1,
                      actuation: Sequence[tuple[np.ndarray | None, float]] | None = None
                      ) -> ClosedLoop:
    """The closed-loop replay of ``controller``'s kind: :func:`computed_torque` (with
    ``sim``'s actuation) or the PD's :func:`closed_loop` (with ``actuation`` per model)."""
    if isinstance(controller, ComputedTorque):
        return computed_torque(sim, models, log, kp, kd)
    return closed_loop(sim, models, log, kp, kd, threads, actuation)


def computed_torque(sim: Simulator, models: Sequence[Any], log: LogGrid, kp: np.ndarray,
                    kd: np.ndarray) -> ClosedLoop:
    """Closed-loop replay under computed torque (module docstring) of each of ``models``
    (variants of ``sim``'s; the added PD actuators are switched off)."""
    steps, nv = log.t.size - 1, sim.nv
    h = float(sim.mj_model.opt.timestep)
    accel = np.diff(log.dq, axis=0) / h
    q = np.empty((len(models), steps + 1, nv))
    correction = np.empty((len(models), steps, nv))
    for b, model in enumerate(models):
        model = sim.with_gains(model, np.zeros(nv), np.zeros(nv))
        if not sim.discrete_inverse:
            model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_INVDISCRETE)
        else:
            model.opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_INVDISCRETE)
        q[b], correction[b] = _track(sim, model, log, accel, kp, kd)
    error = q - log.q
    with np.errstate(invalid="ignore"):
        diverged = ~np.all(np.isfinite(error), axis=(1, 2)) | (
            np.nanmax(np.abs(error), axis=(1, 2)) > DIVERGED)
    return ClosedLoop(error, correction, diverged)


def _track(sim: Simulator, model: Any, log: LogGrid, accel: np.ndarray, kp: np.ndarray,
           kd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One model's computed-torque run: positions (S, nv) and ``u − τ_log`` (S − 1, nv); NaN
    from the step where the state left the finite numbers or MuJoCo reset it."""
    data = mujoco.MjData(model)
    data.qpos[sim.qpos], data.qvel[sim.dofs] = log.q[0], log.dq[0]
    q = np.full((log.t.size, sim.nv), np.nan)
    c = np.full((log.t.size - 1, sim.nv), np.nan)
    u_all = np.zeros_like(c)
    lag = sim.delay / float(model.opt.timestep)
    gain = np.ones(sim.nv) if sim.gain is None else sim.gain
    q[0] = log.q[0]
    for k in range(log.t.size - 1):
        qk, vk = data.qpos[sim.qpos], data.qvel[sim.dofs]
        data.qacc[:] = 0.0
        data.qacc[sim.dofs] = accel[k] + kd * (log.dq[k] - vk) + kp * (log.q[k] - qk)
        mujoco.mj_inverse(model, data)
        u = u_all[k] = data.qfrc_inverse[sim.dofs] / gain
        data.qfrc_applied[:] = 0.0
        data.qfrc_applied[sim.dofs] = gain * _lagged(u_all, k, lag)
        mujoco.mj_step(model, data)
        if not np.all(np.isfinite(data.qpos)) or data.warning[
                mujoco.mjtWarning.mjWARN_BADQACC].number > 0:
            break
        q[k + 1], c[k] = data.qpos[sim.qpos], u - log.tau[k]
    return q, c


def _lagged(u: np.ndarray, k: int, lag: float) -> np.ndarray:
    """``u`` at step ``k − lag`` (linear between steps, ``u[0]`` before the start)."""
    if lag <= 0.0:
        return u[k]
    s = max(k - lag, 0.0)
    m = int(np.floor(s))
    f = s - m
    return (1.0 - f) * u[m] + f * u[min(m + 1, k)]


def open_loop(sim: Simulator, log: LogGrid, window: float, threads: int = 1) -> np.ndarray:
    """Open-loop replay under the logged torque, reset every ``window`` s: the drift
    ``q − q_log``, (windows, steps per window, nv); NaN where a window diverged."""
    steps = max(1, int(round(window / float(sim.mj_model.opt.timestep))))
    starts = np.arange(0, log.t.size - steps, steps)
    if starts.size == 0:
        starts, steps = np.array([0]), log.t.size - 1
    m = sim.with_gains(sim.mj_model, np.zeros(sim.nv), np.zeros(sim.nv))   # no feedback
    tau = actuated(log.tau, float(sim.mj_model.opt.timestep), sim.gain, sim.delay)
    controls = np.stack([_controls(sim, np.zeros((steps, sim.nv)), tau[k:k + steps])
                         for k in starts])
    states = np.stack([sim.initial_state(log.q[k], log.dq[k]) for k in starts])
    out = _rollout([m] * starts.size, sim, states, controls, threads)
    q, _ = _positions(sim, out)
    idx = starts[:, None] + np.arange(1, steps + 1)[None, :]
    drift = q - log.q[idx]
    with np.errstate(invalid="ignore"):
        bad = ~np.all(np.isfinite(drift), axis=(1, 2)) | (np.nanmax(np.abs(drift), axis=(1, 2))
                                                          > 10 * DIVERGED) | was_reset(
            states, out, float(sim.mj_model.opt.timestep))
    drift[bad] = np.nan
    return drift

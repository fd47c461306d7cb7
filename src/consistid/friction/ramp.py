r"""Torque-ramp experiments for the break-away (static) friction of each joint.

The youBot report in the seeds (Section 3.6, Fig. 3.8; Section 4.2) measures static friction by
raising a joint's torque step by step from rest until its velocity leaves a threshold
(0.13 rad/s there), repeating the experiment and taking the median; gravity is kept out of the
measurement by the pose. Here the pose can be any: the feed-forward holds the robot against
the gravity torque ``g(q₀)`` of the model, and the ramp adds

.. math::  u_j(t) = g_j(q_0) + s\,\dot r\,(t - t_0), \qquad s = \pm 1,

on one joint at a time, both directions, ``repeats`` times, until the joint moves
(``|q̇_j| ≥`` the abort speed), leaves ``max_excursion`` or the ramp reaches ``max_torque``. A
:class:`RampPlan` is the ordered list of ramps with their limits; :meth:`RampPlan.to_csv` writes
the feed-forward torques of every ramp slot (worst case: up to ``max_torque``) for a robot
controller, whose own loop must hold the other joints at ``q₀``, start each ramp from the torque
that holds the joint at that moment (a step would jolt it) and abort a ramp at the abort
speed; :func:`consistid.friction.breakaway.simulate_ramps` runs the same plan on the MuJoCo
robot, and :func:`consistid.friction.breakaway.estimate_breakaway` reads either log.

Safety: ``max_torque`` defaults to :data:`EFFORT_FRACTION` of each joint's URDF effort limit,
capped so that the feed-forward ``|g_j(q₀)| + max_torque`` stays within :data:`EFFORT_HEADROOM`
of it; the ramp is aborted at the first motion, and ``max_excursion`` bounds the motion a ramp
can cause. The fraction is a half because break-away torques are a large share of the effort
limit on small joints: a Panda whose joint 6 breaks away at 2.45 N·m (20 % of its 12 N·m) never
moved under the former default of 20 %. The ramp stops at the first motion, so the wider range
costs time only on a joint that does not move; a joint that moved in none of its ramps (or in
none of one direction's) is reported with its break-away *above* the range, never as a number
(:func:`consistid.friction.breakaway.estimate_breakaway`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from ..errors import ModelError, OptionError, check_number
from ..robot.model import RobotModel
from ..textsafety import check_writable_name

#: Default ``max_torque``: this fraction of the URDF effort limit (10 N·m where none is set) …
EFFORT_FRACTION = 0.5
#: … capped so that ``|g(q₀)| + max_torque`` stays within this fraction of the effort limit.
EFFORT_HEADROOM = 0.9
#: Default ``max_torque`` of a joint without an effort limit (N·m).
UNLIMITED_MAX_TORQUE = 10.0


@dataclass(frozen=True)
class Ramp:
    """One ramp: ``joint`` (index), ``direction`` ±1, ``repeat`` (0-based)."""

    joint: int
    direction: int
    repeat: int


@dataclass(frozen=True, eq=False)
class RampPlan:
    """An ordered set of torque ramps from a pose (module docstring).

    Attributes
    ----------
    joint_names : (nv,) names.
    pose : (nv,) ``q₀`` (rad / m).
    gravity : (nv,) ``g(q₀)`` of the model the plan was made with (N·m), the feed-forward.
    rate : ramp slope ``ṙ`` (N·m/s).
    max_torque : (nv,) the most a ramp adds to ``g(q₀)`` on each joint (N·m).
    abort_speed : a ramp stops once ``|q̇_j|`` reaches this (rad/s).
    max_excursion : a ramp stops once ``|q_j − q₀_j|`` exceeds this (rad / m).
    settle : seconds of holding ``q₀`` before each ramp.
    ramps : the ramps in order.
    """

    joint_names: tuple[str, ...]
    pose: np.ndarray
    gravity: np.ndarray
    rate: float
    max_torque: np.ndarray
    abort_speed: float
    max_excursion: float
    settle: float
    ramps: tuple[Ramp, ...]

    def slot(self, ramp: Ramp) -> float:
        """Worst-case length of a ramp's slot (s): settle, then the ramp up to ``max_torque``."""
        return self.settle + float(self.max_torque[ramp.joint]) / self.rate

    @property
    def worst_case_duration(self) -> float:
        """Seconds if no ramp is aborted early (no joint ever moves)."""
        return float(sum(self.slot(r) for r in self.ramps))

    def sample(self, rate_hz: float = 1000.0) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                      np.ndarray]:
        """The feed-forward of every slot at ``rate_hz``: ``(t, tau, joint, direction)``, with
        ``tau`` (S, nv) = ``g(q₀)`` plus the ramp on the ramped joint, and ``joint`` (S,) the
        ramped joint (−1 while settling) and ``direction`` (S,) its sign (0 while settling)."""
        rate_hz = check_number("rate_hz", rate_hz, 0, strict=True)
        ts, taus, joints, dirs, t0 = [], [], [], [], 0.0
        for ramp in self.ramps:
            n = int(np.ceil(self.slot(ramp) * rate_hz))
            t = np.arange(n) / rate_hz
            tau = np.tile(self.gravity, (n, 1))
            on = t >= self.settle
            tau[on, ramp.joint] += ramp.direction * self.rate * (t[on] - self.settle)
            ts.append(t0 + t)
            taus.append(tau)
            joints.append(np.where(on, ramp.joint, -1))
            dirs.append(np.where(on, ramp.direction, 0))
            t0 += n / rate_hz
        return (np.concatenate(ts), np.vstack(taus), np.concatenate(joints),
                np.concatenate(dirs))

    def to_csv(self, path: str | Path, rate_hz: float = 1000.0) -> Path:
        """Write the feed-forward torques (:meth:`sample`) as CSV: columns ``t``,
        ``ramped_joint`` (1-based, 0 while settling), ``direction``, ``tau1..taun`` (N·m),
        preceded by ``#`` lines that state the pose, the abort speed and the excursion limit that
        the robot's controller must enforce (a CSV cannot stop a ramp at the first motion)."""
        path = Path(path)
        for name in self.joint_names:               # a newline would add a line above the header
            check_writable_name(name, "RampPlan joint name")
        t, tau, joint, direction = self.sample(rate_hz)
        header = ["t", "ramped_joint", "direction", *(f"tau{j + 1}" for j in range(tau.shape[1]))]
        notes = [
            "# consistid break-away ramp plan (consistid.friction.ramp)",
            f"# joints: {', '.join(self.joint_names)}",
            f"# pose q0 (hold every joint here; the ramped joint is torque-controlled): "
            f"{' '.join(f'{v:.6g}' for v in self.pose)}",
            f"# ABORT a ramp (hold q0 again, skip to the next slot) once |dq| >= "
            f"{self.abort_speed:g} rad/s or |q - q0| > {self.max_excursion:g} on the ramped joint",
            f"# ramp rate {self.rate:g} N*m/s; max added torque per joint: "
            f"{' '.join(f'{v:.4g}' for v in self.max_torque)}; log t, q, tau at >= 200 Hz and "
            "read it with consistid.friction.estimate_breakaway(model, data)"]
        rows = np.column_stack([t, joint + 1, direction, tau])
        with path.open("w", encoding="utf-8") as f:
            f.write("\n".join(notes) + "\n" + ",".join(header) + "\n")
            np.savetxt(f, rows, delimiter=",", fmt="%.9g")
        return path

    def summary(self) -> str:
        lines = [f"break-away ramp plan: {len(self.ramps)} ramps at {self.rate:g} N·m/s, abort at "
                 f"|q̇| ≥ {self.abort_speed:g} rad/s or {self.max_excursion:g} rad from the pose; "
                 f"worst case {self.worst_case_duration:.1f} s"]
        for j, name in enumerate(self.joint_names):
            n = sum(r.joint == j for r in self.ramps)
            if n:
                lines.append(f"  {name}: {n} ramps, g(q0) = {self.gravity[j]:+.3f} N·m, up to "
                             f"±{self.max_torque[j]:.3g} N·m")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()


def ramp_plan(model: RobotModel, pose: Sequence[float] | None = None,
              joints: Sequence[int | str] | None = None, rate: float = 3.0,
              max_torque: float | Sequence[float] | None = None, repeats: int = 3,
              abort_speed: float = 0.05, max_excursion: float = 0.05,
              settle: float = 0.4) -> RampPlan:
    """A :class:`RampPlan` (module docstring).

    Parameters
    ----------
    model : the robot; its gravity torque at ``pose`` is the feed-forward.
    pose : ``q₀``; default the middle of each joint's limits (0 where unlimited).
    joints : joints to ramp (names or indices); default all.
    rate : ramp slope (N·m/s), > 0.
    max_torque : most a ramp adds on a joint (N·m), scalar or per joint; default
        :data:`EFFORT_FRACTION` of the effort limit, at most :data:`EFFORT_HEADROOM` of it
        minus ``|g(q₀)|``. Must stay within the effort limit.
    repeats : ramps per joint and direction (≥ 1); both directions are ramped, alternately.
    abort_speed : rad/s at which a ramp stops (above the break-away detection threshold).
    max_excursion : rad a ramp may move the joint before it stops.
    settle : seconds of holding the pose before each ramp.
    """
    nv, names = model.nv, model.joint_names
    lim = model.limits
    if pose is None:
        q0 = np.where(np.isfinite(lim.lower) & np.isfinite(lim.upper),
                      0.5 * (np.nan_to_num(lim.lower) + np.nan_to_num(lim.upper)), 0.0)
    else:
        q0 = np.asarray(pose, dtype=float)
        if q0.shape != (nv,) or not np.all(np.isfinite(q0)):
            raise OptionError(f"pose must be {nv} finite joint positions, got {pose!r}")
        outside = np.flatnonzero((q0 < lim.lower) | (q0 > lim.upper))
        if outside.size:
            j = int(outside[0])
            raise OptionError(f"pose[{names[j]!r}] = {q0[j]:.4g} is outside the joint's limits "
                              f"[{lim.lower[j]:.4g}, {lim.upper[j]:.4g}]")
    rate = check_number("rate", rate, 0, strict=True)
    repeats = check_number("repeats", repeats, 1, integer=True)
    abort_speed = check_number("abort_speed", abort_speed, 0, strict=True)
    max_excursion = check_number("max_excursion", max_excursion, 0, strict=True)
    settle = check_number("settle", settle, 0)
    effort = lim.effort
    gravity = model.rnea(q0[None], np.zeros((1, nv)), np.zeros((1, nv)))[0]
    if max_torque is None:
        top = np.where(np.isfinite(effort), np.minimum(
            EFFORT_FRACTION * effort, EFFORT_HEADROOM * effort - np.abs(gravity)),
            UNLIMITED_MAX_TORQUE)
        held = np.flatnonzero(top <= 0)
        if held.size:
            j = int(held[0])
            raise ModelError(f"holding {names[j]!r} against gravity at the pose takes "
                             f"|g(q0)| = {abs(gravity[j]):.4g} N·m, beyond {EFFORT_HEADROOM:.0%} "
                             f"of its effort limit {effort[j]:.4g} N·m: no room for a ramp; "
                             "choose another pose")
    else:
        top = np.broadcast_to(np.asarray(max_torque, dtype=float), (nv,)).copy() \
            if np.ndim(max_torque) == 0 or np.shape(max_torque) == (nv,) else None
        if top is None or not np.all(np.isfinite(top)) or np.any(top <= 0):
            raise OptionError(f"max_torque must be a positive number or {nv} of them (N·m), got "
                              f"{max_torque!r}")
    over = np.flatnonzero(np.abs(gravity) + top > effort)
    if over.size:
        j = int(over[0])
        raise ModelError(f"a ramp on {names[j]!r} would command |g(q0)| + max_torque = "
                         f"{abs(gravity[j]) + top[j]:.4g} N·m, beyond its effort limit "
                         f"{effort[j]:.4g} N·m: lower max_torque or choose another pose")
    if joints is None:
        chosen = list(range(nv))
    else:
        chosen = []
        for j in joints:
            if isinstance(j, str):
                if j not in names:
                    raise OptionError(f"joints: {j!r} is not a joint of {model.name} ({names})")
                j = names.index(j)
            if isinstance(j, bool) or not isinstance(j, (int, np.integer)) or not 0 <= j < nv:
                raise OptionError(f"joints: {j!r} is not a joint name or an index 0..{nv - 1}")
            chosen.append(int(j))
        if not chosen:
            raise OptionError("joints is empty: name at least one joint to ramp")
    ramps = tuple(Ramp(j, d, k) for j in chosen for k in range(repeats) for d in (1, -1))
    return RampPlan(tuple(names), q0, gravity, rate, top, abort_speed, max_excursion, settle,
                    ramps)

r"""Effects *outside* the diagnosis' candidate list, for testing that it says so.

:func:`consistid.diagnose` explains a torque gap with a list of candidate effects
(:mod:`consistid.diagnosis.effects`). A robot can hold others; these are some, each simulated
the way it arises:

Physical (on the simulated robot, set at every physics step through ``record``'s ``step_hook``,
so the controller feels them and the logged torque carries them):

``position_friction``
    dry friction whose level turns with the angle, ``f(q) = f₀ (1 + 0.8 sin(k q_j + φ))`` (a
    bearing preload or gear mesh that varies around the turn; MuJoCo ``frictionloss``).
``drifting_friction``
    dry friction that warms in over the log, ``f(t) = f₀ (0.1 + 1.9 t / T)`` (lubricant
    temperature; mean ``f₀`` over ``T``).
``load_friction``
    dry friction proportional to the joint's bias load (gravity and velocity terms),
    ``f = μ |c_j(q, q̇)|`` (gear-mesh friction of harmonic drives grows with the load).
``quadratic_drag``
    a drag ``c q̇ |q̇|`` (churning, seals), not the linear ``viscous`` candidate (MuJoCo
    ``damping`` set to ``c |q̇_j|`` at each step, integrated implicitly).

Sensor-side (on the logged signals, sample by sample):

``dead_zone``
    the torque sensor reads nothing below ``δ``: ``τ_m = sign(τ) max(|τ| − δ, 0)``.
``crosstalk``
    channel ``j`` picks up a fraction of another joint's torque, ``τ_m,j = τ_j + c τ_k``.
``backlash``
    a gear with backlash ``b`` between the motor-side encoder and the link: the encoder leads
    the link by ``b/2`` in the direction of the last motion, ``q_m = q + (b/2) s(t)``,
    ``s`` the sign of the last velocity beyond 1 % of its peak (a hysteresis in position).

:func:`record_with` runs :func:`consistid.simulate.record` with them.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..errors import ModelError, check_option
from ..robot.model import RobotModel
from .experiments import SimulatedRecording, record

PHYSICAL = ("position_friction", "drifting_friction", "load_friction", "quadratic_drag")
SENSOR = ("dead_zone", "crosstalk", "backlash")
KINDS = PHYSICAL + SENSOR


@dataclass(frozen=True)
class Disturbance:
    """One effect outside the candidate list (see the module notes).

    Parameters
    ----------
    kind : one of :data:`KINDS`.
    joint : the joint index it acts on (crosstalk: the channel that picks it up).
    magnitude : ``f₀`` (N·m), ``μ`` (–), ``c`` (N·m·s²/rad²), ``δ`` (N·m), ``c`` (–) or
        ``b`` (rad), by kind.
    source : crosstalk: the joint whose torque leaks in.
    order, phase : ``position_friction``: ``k`` cycles per radian and ``φ`` (rad).
    """

    kind: str
    joint: int
    magnitude: float
    source: int | None = None
    order: float = 3.0
    phase: float = 0.0

    def __post_init__(self) -> None:
        check_option("kind", self.kind, KINDS)
        if not self.magnitude >= 0:
            raise ModelError(f"Disturbance {self.kind!r}: magnitude {self.magnitude} must be ≥ 0")
        if self.kind == "crosstalk" and (self.source is None or self.source == self.joint):
            raise ModelError("a crosstalk Disturbance needs a source joint other than its joint")

    def describe(self, names: list[str]) -> str:
        extra = f" from {names[self.source]}" if self.source is not None else ""
        return f"{self.kind}@{names[self.joint]}{extra} {self.magnitude:.3g}"


def _step_hook(model: RobotModel, physical: list[Disturbance], duration: float):
    import mujoco  # imported where the simulation runs

    cache: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def addresses(m) -> tuple[np.ndarray, np.ndarray]:
        key = id(m)
        if key not in cache:
            ids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n) for n in model.joint_names]
            if min(ids) < 0 or m.nv != model.nv:
                raise ModelError("record_with: disturbances need a MuJoCo robot whose joints are "
                                 "the model's (no elastic joints)")
            cache[key] = (np.array([m.jnt_dofadr[i] for i in ids]),
                          np.array([m.jnt_qposadr[i] for i in ids]))
        return cache[key]

    def callback(m, d) -> None:
        dof, qadr = addresses(m)
        for dist in physical:
            k = dof[dist.joint]
            v = d.qvel[k]
            if dist.kind == "position_friction":
                m.dof_frictionloss[k] = dist.magnitude * (
                    1 + 0.8 * np.sin(dist.order * d.qpos[qadr[dist.joint]] + dist.phase))
            elif dist.kind == "drifting_friction":
                m.dof_frictionloss[k] = dist.magnitude * (0.1 + 1.9 * max(d.time, 0.0)
                                                          / duration)
            elif dist.kind == "load_friction":
                m.dof_frictionloss[k] = dist.magnitude * abs(d.qfrc_bias[k])
            elif dist.kind == "quadratic_drag":
                m.dof_damping[k] = dist.magnitude * abs(v)

    return callback


def _backlash(q: np.ndarray, dq: np.ndarray, b: float) -> np.ndarray:
    s = np.zeros(q.shape[0])
    thresh = 0.01 * np.max(np.abs(dq))
    state = 1.0 if dq[0] >= 0 else -1.0
    for i, v in enumerate(dq):
        if abs(v) > thresh:
            state = 1.0 if v > 0 else -1.0
        s[i] = state
    return q + 0.5 * b * s


def record_with(model: RobotModel, trajectory, effects, disturbances: list[Disturbance],
                duration: float, **options) -> SimulatedRecording:
    """:func:`consistid.simulate.record` with ``disturbances`` added (module notes): physical
    ones at every physics step, sensor ones on the log. ``options`` go to ``record``
    (``rate``, ``seed``, ``true_parameters`` …). The recording's ``tau`` and ``q`` are the
    disturbed log; its truth fields are those of the simulation."""
    for d in disturbances:
        for j in (d.joint, d.source):
            if j is not None and not 0 <= j < model.nv:
                raise ModelError(f"Disturbance {d.kind!r}: joint index {j} outside 0…"
                                 f"{model.nv - 1}")
    physical = [d for d in disturbances if d.kind in PHYSICAL]
    hook = _step_hook(model, physical, duration) if physical else None
    rec = record(model, trajectory, effects, duration=duration, step_hook=hook, **options)
    tau, q = rec.tau.copy(), rec.q.copy()
    for d in disturbances:
        j = d.joint
        if d.kind == "dead_zone":
            tau[:, j] = np.sign(rec.tau[:, j]) * np.maximum(np.abs(rec.tau[:, j]) - d.magnitude,
                                                            0.0)
        elif d.kind == "crosstalk":
            tau[:, j] += d.magnitude * rec.tau[:, d.source]
        elif d.kind == "backlash":
            q[:, j] = _backlash(rec.q[:, j], rec.true_dq[:, j], d.magnitude)
    return replace(rec, tau=tau, q=q)

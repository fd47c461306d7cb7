r"""Angle units of joint logs: ``angle_unit="rad"`` or ``"deg"``; degrees read as radians.

A log whose header names no unit is read in SI units (rad, rad/s, rad/s²). A controller that
logs degrees then gives positions 57.3 × too large, and identification fits those: the answer
(status, σ, "consistent") describes data that are not the robot's. Two routes:

* **Said**: ``angle_unit="deg"`` (``[data] angle_unit = "deg"`` in a configuration) converts
  ``q``, ``dq``, ``ddq`` of the revolute joints by ``π/180`` (:func:`convert_angles`;
  prismatic joints of a model stay in metres).
* **Detected** (:func:`degree_suspects`, run at load time and by
  :func:`consistid.identify`): per revolute joint,

  - its positions span more than :data:`MAX_SPAN` (two full turns) — a joint with finite limits,
    or any joint when no model is given (a continuous joint that really turns that far is the
    one false alarm, and the message says so);
  - its speed (99th percentile of ``|q̇|``) exceeds :data:`MAX_SPEED` (720 °/s, beyond any
    manipulator joint's rating) and :data:`SPEED_FACTOR` × its URDF velocity limit;
  - its positions leave the URDF limits by more than a tenth of their range while the same
    numbers read as degrees lie within them.

  A log in degrees of small motions (a joint moving ±5°) passes all three.
* **Torque** (:func:`degree_torque_evidence`, with a model and torques, whatever the motion):
  the URDF's RNEA torque ``τ̂(q, q̇, q̈)`` is compared with the logged ``τ`` twice, the angles
  read as radians and as degrees (``q, q̇, q̈`` of the revolute joints × π/180). Gravity alone
  makes the two readings differ by the pose: a log whose torque the degrees reading explains
  with less than :data:`DEGREE_FIT` of the residual RMS of the radians reading, and of the
  torque's own RMS, is in degrees (the second: a gravity-compensated or commanded torque is no
  RNEA torque, and the collapsed pose of the degrees reading, with less gravity, fits it
  better than the radians reading does).
  A radians log is not flagged: read as degrees its pose collapses to about zero, whose gravity
  torque differs from the logged one unless the arm stays near zero — and there the two
  readings give about the same residual (ratio ≈ 1). Tested both ways on the example arms,
  with inertias ±20 % off the URDF and friction the URDF lacks.

Naming the unit is still the one sure way.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ..errors import check_option
from ..robot.model import RobotModel

#: The accepted ``angle_unit`` values and their factor to radians.
ANGLE_UNITS = {"rad": 1.0, "deg": float(np.pi / 180.0)}
#: A revolute joint spanning more than this (rad: two full turns) reads as degrees.
MAX_SPAN = 4.0 * np.pi
#: No manipulator joint turns faster than this (rad/s: 720 °/s).
MAX_SPEED = 4.0 * np.pi
#: … nor faster than this multiple of its URDF velocity limit.
SPEED_FACTOR = 2.0
#: Slack beyond the limits, as a fraction of their range (at least :data:`LIMIT_FLOOR` rad).
LIMIT_SLACK = 0.1
LIMIT_FLOOR = 0.1
#: Read as degrees, the URDF's torque leaves less than this fraction of the residual RMS it
#: leaves read as radians: the log is in degrees (:func:`degree_torque_evidence`).
DEGREE_FIT = 0.5
#: Samples at most (evenly spaced) for that comparison.
DEGREE_SAMPLES = 2000


def check_angle_unit(angle_unit: str | None) -> float | None:
    """The factor to radians of ``angle_unit`` (``None``: not said); :class:`OptionError`
    for anything but ``None``, ``"rad"``, ``"deg"``."""
    check_option("angle_unit", angle_unit, (None, *ANGLE_UNITS))
    return None if angle_unit is None else ANGLE_UNITS[angle_unit]


def revolute_joints(model: RobotModel) -> np.ndarray:
    """(nv,) ``True`` for the model's angular joints (revolute, continuous), ``False`` for the
    prismatic ones, in the model's joint order."""
    m = model.pin_model
    out = np.ones(model.nv, bool)
    for joint in m.joints[1:]:
        name = joint.shortname()       # JointModelPX/PY/PZ, JointModelPrismaticUnaligned
        if joint.nv == 1 and (name.startswith("JointModelP") or "Prismatic" in name):
            out[joint.idx_v] = False
    return out


def model_limits(model: RobotModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(lower, upper, velocity)`` per joint, as :func:`degree_suspects` takes them."""
    lim = model.limits
    return lim.lower, lim.upper, lim.velocity


def convert_angles(arrays: dict[str, np.ndarray], factor: float,
                   revolute: np.ndarray) -> dict[str, np.ndarray]:
    """``arrays`` with the ``q``, ``dq``, ``ddq`` columns of the ``revolute`` joints times
    ``factor`` (``tau`` and prismatic columns as they are)."""
    out = dict(arrays)
    for f in ("q", "dq", "ddq"):
        if f in out:
            a = np.array(out[f], dtype=float)
            a[:, revolute] *= factor
            out[f] = a
    return out


def _within(lo: float, hi: float, lower: float, upper: float) -> bool:
    slack = max(LIMIT_SLACK * (upper - lower), LIMIT_FLOOR)
    return lower - slack <= lo and hi <= upper + slack


def degree_suspects(q: np.ndarray, dq: np.ndarray, names: Sequence[str] | None = None,
                    revolute: np.ndarray | None = None,
                    limits: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
                    ) -> list[str]:
    """One sentence per revolute joint whose positions ``q`` and velocities ``dq`` (N, n) look
    like degrees read as radians (module docstring), naming the joint and the evidence.

    ``revolute`` (n,) marks the angular joints (default all); ``limits`` are the model's
    ``(lower, upper, velocity)`` per joint (``±inf``/``inf`` where unset)."""
    q, dq = np.asarray(q, dtype=float), np.asarray(dq, dtype=float)
    n = q.shape[1]
    revolute = np.ones(n, bool) if revolute is None else np.asarray(revolute, bool)
    lower, upper, speed_limit = (limits if limits is not None
                                 else (np.full(n, -np.inf), np.full(n, np.inf),
                                       np.full(n, np.inf)))
    lo, hi = q.min(axis=0), q.max(axis=0)
    speed = np.percentile(np.abs(dq), 99, axis=0) if dq.shape[0] else np.zeros(n)
    found = []
    for j in np.flatnonzero(revolute):
        name = repr(str(names[j])) if names is not None else f"column {j}"
        bounded = bool(np.isfinite(lower[j]) and np.isfinite(upper[j]))
        why = []
        span = float(hi[j] - lo[j])
        if span > MAX_SPAN and (bounded or limits is None):
            why.append(f"spans {span:.4g} rad ({span / (2 * np.pi):.1f} turns; "
                       f"{np.radians(span):.3g} rad if degrees)")
        if speed[j] > max(MAX_SPEED, SPEED_FACTOR * speed_limit[j]):
            why.append(f"turns at {speed[j]:.4g} rad/s (99th percentile; "
                       f"{np.radians(speed[j]):.3g} rad/s if degrees)")
        if bounded and not _within(lo[j], hi[j], lower[j], upper[j]) \
                and _within(*np.radians([lo[j], hi[j]]), lower[j], upper[j]):
            why.append(f"spans [{lo[j]:.4g}, {hi[j]:.4g}] against its limits "
                       f"[{lower[j]:.4g}, {upper[j]:.4g}], within them if degrees")
        if why:
            found.append(f"{name} {' and '.join(why)}")
    return found


def degree_torque_evidence(model: RobotModel, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray,
                           tau: np.ndarray) -> str | None:
    """A sentence when the logged torque ``tau`` (N, nv) is the model's RNEA torque of the
    angles read as degrees rather than as radians (module docstring: the residual RMS over all
    joints ``‖τ − τ̂(q·π/180, …)‖ < DEGREE_FIT · min(‖τ − τ̂(q, …)‖, ‖τ‖)``: the degrees reading
    must also explain the torque itself, else a log whose torque is no RNEA torque — gravity
    compensated, commanded, currents — would read as degrees); ``None`` otherwise."""
    n = q.shape[0]
    if n < 10 or q.shape[1] != model.nv or tau.shape != q.shape:
        return None
    pick = np.unique(np.linspace(0, n - 1, min(n, DEGREE_SAMPLES)).astype(int))
    arrays = {"q": q[pick], "dq": dq[pick], "ddq": ddq[pick]}
    factor = ANGLE_UNITS["deg"]
    as_deg = convert_angles(arrays, factor, revolute_joints(model))
    y = np.asarray(tau, dtype=float)[pick]
    rad = float(np.sqrt(np.mean((y - model.rnea(arrays["q"], arrays["dq"], arrays["ddq"])) ** 2)))
    deg = float(np.sqrt(np.mean((y - model.rnea(as_deg["q"], as_deg["dq"], as_deg["ddq"])) ** 2)))
    size = float(np.sqrt(np.mean(y ** 2)))
    if not (np.isfinite(rad) and np.isfinite(deg)) or deg >= DEGREE_FIT * min(rad, size):
        return None
    return (f"the logged torque is {model.name}'s RNEA torque of these angles read as degrees "
            f"(residual RMS {deg:.3g} N·m, against {rad:.3g} N·m read as radians)")


def degree_message(found: Sequence[str], source: str) -> str:
    """The warning text for :func:`degree_suspects`' findings: what, where, and the fix."""
    listed = "; ".join(found[:6]) + (" …" if len(found) > 6 else "")
    return (f"{source}: joint positions that look like degrees read as radians: {listed}. If "
            "the log is in degrees, say so: angle_unit=\"deg\" (load_recording, from_arrays; "
            "[data] angle_unit = \"deg\" in a configuration) or a unit in the header "
            "('q_<joint> [deg]'); if it is in radians (a continuous joint that turns that far), "
            "angle_unit=\"rad\" silences this")

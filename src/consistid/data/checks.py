r"""Checks of a dataset before any numerics: magnitudes, motion, dead torque channels, glitches.

:class:`~consistid.data.dataset.Dataset` already refuses NaN/inf, wrong shapes and
non-increasing time. What it accepts can still break or fool the linear algebra downstream:

* **Magnitudes** beyond :data:`MAX_ABS` (``|x| > 10⁸`` in SI units: rad, rad/s, rad/s², N·m) are
  no physical joint value; their squares overflow a QR factorisation ("SVD did not converge")
  long before they mean anything. :func:`check_magnitudes` names the first one
  (:class:`~consistid.errors.DatasetError`): a glitch, or wrong units.
* **No motion at all** (every ``q`` constant, ``q̇ = q̈ = 0``): one static pose informs at most
  the gravity torques there; :func:`check_motion` raises
  :class:`~consistid.errors.PoorExcitationError`.
* **A dead torque channel** (``τ_j = 0`` in every sample): no joint of a real arm carries no
  torque at all, and per-joint noise weights ``1/σ_j`` would be infinite (σ is floored at a
  multiple of the channel's RMS, here 0): :func:`check_torque` raises :class:`DatasetError`.
* **A single glitch** (in ``q``, ``dq``, ``ddq`` or ``tau``; none found in the real KUKA LWR4+
  logs of ``../shared``): a sample further than :data:`GLITCH_FACTOR` robust standard deviations
  (``1.4826 · MAD``) from its channel's median, in a channel whose other samples stay within
  ``GLITCH_FACTOR / 10`` of them. Least squares follows such a sample; the warning
  (:class:`~consistid.errors.DataQualityWarning`) names it and suggests ``loss="huber"``.
  Robust scale: Hampel 1974, doi:10.1080/01621459.1974.10482962.
"""

from __future__ import annotations

import warnings
from typing import Sequence

import numpy as np

from ..errors import DataQualityWarning, DatasetError, PoorExcitationError
from .dataset import FIELDS, Dataset

#: Largest magnitude accepted in ``q, dq, ddq, tau`` (SI units) before identification.
MAX_ABS = 1e8
#: A torque channel whose RMS is at most this (N·m) is dead (:func:`check_torque`).
MIN_TORQUE_RMS = 1e-9
#: Robust z-score above which a lone sample is called a glitch (see the module docstring).
GLITCH_FACTOR = 1e3
#: Rows of the strided subsample that screens channels for glitches (:func:`check_glitches`).
SCREEN_ROWS = 2048

__all__ = ["MAX_ABS", "GLITCH_FACTOR", "check_magnitudes", "check_motion", "check_torque",
           "check_glitches", "check_for_identification"]


def _joint(dataset: Dataset, j: int, joint_names: Sequence[str] | None = None) -> str | int:
    names = dataset.joint_names or joint_names
    return str(names[j]) if names and len(names) == dataset.nv else int(j)


def _where(dataset: Dataset, name: str, k: int, j: int,
           joint_names: Sequence[str] | None = None) -> str:
    return f"dataset.{name}[{int(k)}, {_joint(dataset, j, joint_names)!r}]"


def check_magnitudes(dataset: Dataset, fields: Sequence[str] = FIELDS,
                     joint_names: Sequence[str] | None = None) -> None:
    """:class:`DatasetError` naming the first sample (field, index, joint) with
    ``|value| > MAX_ABS``."""
    for name in fields:
        a = getattr(dataset, name)
        if a is None or (a.max(initial=0.0) <= MAX_ABS and a.min(initial=0.0) >= -MAX_ABS):
            continue                    # the common case: two reductions, no |a| array
        big = np.argwhere(np.abs(a) > MAX_ABS)
        if big.size:
            k, j = (int(i) for i in big[0])
            raise DatasetError(
                f"{_where(dataset, name, k, j, joint_names)} = {a[k, j]:.3g}: beyond "
                f"±{MAX_ABS:.0e}, no physical joint value in SI units ({len(big)} such "
                f"value(s) in {name}); a "
                "glitch or wrong units (degrees? mN·m?). Remove or rescale those samples")


def check_motion(dataset: Dataset) -> None:
    """:class:`PoorExcitationError` when nothing moves: every ``q`` constant, ``q̇ = q̈ = 0``."""
    still = (not np.any(dataset.dq) and not np.any(dataset.ddq)       # cheap tests first
             and bool(np.all(dataset.q == dataset.q[0])))
    if still:
        raise PoorExcitationError(
            f"the dataset has no motion at all ({dataset.n_samples} sample(s) of one static "
            "pose, dq = ddq = 0): it cannot inform the dynamic parameters; record an "
            "excitation trajectory (consistid.design_excitation)")


def check_torque(dataset: Dataset, joint_names: Sequence[str] | None = None,
                 exclude: Sequence[int] = ()) -> None:
    """:class:`DatasetError` naming a torque channel that is zero in every sample, or whose RMS
    is below :data:`MIN_TORQUE_RMS` (no sensor resolves that: zero in disguise, or wrong
    units; its noise weight ``1/σ`` would overflow). Channels in ``exclude`` (joints left out
    of the identification) are not checked."""
    tau = dataset.require_torque()
    scaled = np.ascontiguousarray(tau.T) / MAX_ABS       # per column, contiguous; no overflow
    rms = np.sqrt(np.einsum("ij,ij->i", scaled, scaled) / tau.shape[0]) * MAX_ABS
    dead = np.setdiff1d(np.flatnonzero(rms <= MIN_TORQUE_RMS), exclude)
    if dead.size:
        names = [_joint(dataset, j, joint_names) for j in dead]
        what = ("is 0" if not np.any(tau[:, dead[0]])
                else f"has RMS {rms[dead[0]]:.3g} N·m, below {MIN_TORQUE_RMS:g},")
        raise DatasetError(
            f"dataset.tau[:, {names[0]!r}] {what} in all {dataset.n_samples} samples (dead "
            f"torque channel(s): {names}); no joint of a moving or loaded arm carries no "
            "torque, and its noise weight would be infinite. Check the log's torque columns "
            "(keys=) and units, or drop that joint")


def check_glitches(dataset: Dataset, fields: Sequence[str] = ("tau",),
                   joint_names: Sequence[str] | None = None, stacklevel: int = 3) -> list[str]:
    """Warn (:class:`DataQualityWarning`) about lone samples far from their channel (module
    docstring); returns their descriptions (``[]`` when none)."""
    found = []
    for name in fields:
        a = getattr(dataset, name)
        if a is None or a.shape[0] < 10:
            continue
        # A sample GLITCH_FACTOR robust σ off needs the channel's range to be that wide; screen
        # with the scale of an evenly strided subsample (within a few % of the full one), and
        # compute the exact median and MAD only for channels that could hold a glitch.
        step = max(1, a.shape[0] // SCREEN_ROWS)
        sub = a[::step]
        sub_scale = 1.4826 * np.median(np.abs(sub - np.median(sub, axis=0)), axis=0)
        columns = np.ascontiguousarray(a.T)        # column reductions 3× faster than axis=0
        span = columns.max(axis=1) - columns.min(axis=1)
        maybe = np.flatnonzero(~(span <= 0.1 * GLITCH_FACTOR * sub_scale))
        if maybe.size == 0:
            continue
        a = a[:, maybe]
        med = np.median(a, axis=0)
        dev = np.abs(a - med)
        scale = 1.4826 * np.median(dev, axis=0)
        for i in np.flatnonzero(scale > 0):
            j = int(maybe[i])
            z = dev[:, i] / scale[i]
            far = np.flatnonzero(z > GLITCH_FACTOR)
            if far.size and far.size <= max(1, a.shape[0] // 1000) \
                    and np.max(np.delete(z, far)) < GLITCH_FACTOR / 10:
                k = int(far[np.argmax(z[far])])
                found.append(f"{_where(dataset, name, k, j, joint_names)} = {a[k, i]:.4g} "
                             f"({z[k]:.3g} robust "
                             f"σ from the channel's median {med[i]:.4g})")
    if found:
        warnings.warn(f"lone outlying sample(s), likely glitches: {'; '.join(found[:5])}. Least "
                      "squares follows them: remove those samples, or use method='sdp' with "
                      "loss='huber'", DataQualityWarning, stacklevel=stacklevel)
    return found


def check_limits(dataset: Dataset, lower: np.ndarray, upper: np.ndarray,
                 joint_names: Sequence[str] | None = None, stacklevel: int = 4) -> None:
    """Warn (:class:`DataQualityWarning`) when a joint's positions leave its limits by more than
    a tenth of its range (at least 0.1 rad or m): a log in degrees (or millimetres) read as SI,
    an encoder offset, or a log of another robot. Joints without limits are not checked."""
    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    if lower.shape != (dataset.q.shape[1],) or upper.shape != lower.shape:
        return      # a joint-count mismatch: named by the joint check that follows
    found = []
    columns = np.ascontiguousarray(dataset.q.T)      # column reductions 3× faster than axis=0
    q_lo, q_hi = columns.min(axis=1), columns.max(axis=1)
    for j in range(dataset.q.shape[1]):
        if not (np.isfinite(lower[j]) and np.isfinite(upper[j])):
            continue
        slack = max(0.1 * (upper[j] - lower[j]), 0.1)
        lo, hi = float(q_lo[j]), float(q_hi[j])
        if lo < lower[j] - slack or hi > upper[j] + slack:
            found.append(f"{_joint(dataset, j, joint_names)!r} spans [{lo:.4g}, {hi:.4g}] "
                         f"against its limits [{lower[j]:.4g}, {upper[j]:.4g}]")
    if found:
        warnings.warn(f"positions beyond the joint limits: {'; '.join(found[:5])}. Are they in "
                      "degrees (name the unit in the log's header, e.g. 'q_<joint> [deg]'), "
                      "offset, or from another robot? Identification goes on with them as "
                      "given", DataQualityWarning, stacklevel=stacklevel)


#: A joint whose torque's 99th percentile exceeds this multiple of its URDF effort limit is
#: warned about: an actuator does not exceed its rating that often (mN·m logged as N·m do).
EFFORT_FACTOR = 2.0


def check_effort(dataset: Dataset, effort: np.ndarray,
                 joint_names: Sequence[str] | None = None, stacklevel: int = 4) -> None:
    """Warn (:class:`DataQualityWarning`) when a joint's torque exceeds :data:`EFFORT_FACTOR` ×
    its effort limit in more than 1 % of the samples: torques in mN·m (or another unit), another
    robot's log, or a URDF whose limits are wrong. Joints without a positive finite limit are not
    checked."""
    effort = np.asarray(effort, dtype=float)
    tau = dataset.tau
    if tau is None or effort.shape != (tau.shape[1],):
        return
    limit = np.where(np.isfinite(effort) & (effort > 0), EFFORT_FACTOR * effort, np.inf)
    over = np.count_nonzero(np.abs(tau) > limit, axis=0) > 0.01 * tau.shape[0]  # one pass
    found = [f"{_joint(dataset, j, joint_names)!r} reaches "
             f"{np.percentile(np.abs(tau[:, j]), 99):.4g} against its {effort[j]:.4g}"
             for j in np.flatnonzero(over)]
    if found:
        warnings.warn(f"torques beyond the URDF's effort limits (99th percentile of |τ|): "
                      f"{'; '.join(found[:5])}. Are they in mN·m or another unit (name it in "
                      "the log's header, e.g. 'tau_<joint> [mNm]'), from another robot, or are "
                      "the URDF's limits wrong? Identification goes on with them as given",
                      DataQualityWarning, stacklevel=stacklevel)


def check_for_identification(dataset: Dataset, joint_names: Sequence[str] | None = None,
                             limits: tuple[np.ndarray, ...] | None = None,
                             exclude: Sequence[int] = ()) -> None:
    """All of the above, in order, for data about to be identified (needs torques);
    ``joint_names`` (the model's) name the joints when the dataset does not; ``limits``
    ``(lower, upper[, effort])`` per joint (the model's) are checked when given; the torque
    channels in ``exclude`` are not checked for being dead."""
    dataset.require_torque()
    check_magnitudes(dataset, joint_names=joint_names)
    check_motion(dataset)
    check_torque(dataset, joint_names, exclude)
    check_glitches(dataset, FIELDS, joint_names=joint_names, stacklevel=5)
    if limits is not None:
        check_limits(dataset, *limits[:2], joint_names=joint_names, stacklevel=5)
        if len(limits) > 2:
            check_effort(dataset, limits[2], joint_names, stacklevel=5)

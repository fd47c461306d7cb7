r"""Time stamps of a robot log: units, duplicates, gaps, and what instant a sample stands for.

Loggers are careless with time. This module checks and repairs the stamps before any signal is
touched, and each function says what it did, so that a loader's record can quote it:

:func:`convert_units`
    stamps in milliseconds, microseconds or nanoseconds taken as seconds give a "1 Hz" log of
    eight hours. A log is *plausible* in seconds when its median step lies in
    :data:`PLAUSIBLE_STEP` (a sampling rate of 2 Hz … 100 kHz, which covers every robot
    controller); otherwise the units under which it would be plausible are named in a
    :class:`~consistid.errors.DatasetError`. Stamps are converted only when the unit is given
    (``time_unit="ms"``), or with ``time_unit="auto"``, which converts to the one plausible unit
    and says so.
:func:`merge_duplicates`
    samples sharing a stamp are merged (``"average"``: the mean of the group, which is the same
    as dropping exact repeats), kept first (``"first"``), refused (``"error"``) or spread evenly
    over the step to the next stamp (``"spread"``). *Collapsed* stamps — a clock coarser than
    the sampling, so that many samples (more than :data:`COLLAPSED_FRACTION` of them) share a
    stamp — are refused by default: averaging them would silently throw most of the log away.
:func:`long_steps`, :func:`median_step`
    the steps longer than a limit (gaps) and the typical step, ignoring repeated stamps.
:func:`interval_centres`
    a logger that *averages* a signal over each sample interval and stamps the average at the
    interval's start or end puts it half a step away from the instant it represents (the
    average of a signal over ``[t_{k-1}, t_k]`` equals its value at the centre to second order:
    ``(1/h)∫ x dt = x(t_c) + h² ẍ(t_c)/24``). ``timestamp="end"`` moves stamp ``t_k`` to
    ``(t_{k-1} + t_k)/2``, ``"start"`` to ``(t_k + t_{k+1})/2``, ``"centre"`` keeps it; the
    first (last) interval, whose other end is not logged, takes the median step.
"""

from __future__ import annotations

import numpy as np

from ..errors import DatasetError, OptionError, check_option

#: Seconds per unit for ``time_unit=``.
TIME_UNITS: dict[str, float] = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
#: A median step (s) in this range is a plausible robot log (2 Hz … 100 kHz).
PLAUSIBLE_STEP = (1e-5, 0.5)
#: More than this fraction of samples sharing their stamp with the previous one: collapsed stamps.
COLLAPSED_FRACTION = 0.1
DUPLICATES = ("average", "first", "error", "spread")
TIMESTAMPS = ("centre", "start", "end")
#: Stamps of a narrow float type whose spacing exceeds this fraction of the median step are
#: refused (:func:`check_resolution`).
MAX_QUANTUM = 0.05


def median_step(t: np.ndarray) -> float:
    """The median of the positive steps of non-decreasing stamps ``t`` (s); repeated stamps are
    not steps. Raises :class:`DatasetError` when all stamps are equal."""
    dt = np.diff(np.asarray(t, dtype=float))
    positive = dt[dt > 0]
    if positive.size == 0:
        raise DatasetError(f"all {np.size(t)} time stamps are equal ({float(t[0])!r}): the log "
                           "has no time axis")
    return float(np.median(positive))


def check_resolution(t: np.ndarray, source: str = "t") -> None:
    """:class:`DatasetError` when stamps stored as a narrow float (``float32``, ``float16``)
    cannot resolve their own steps: the spacing of that type at the largest stamp exceeds
    :data:`MAX_QUANTUM` of the median step (``float32`` Unix seconds are 128 s apart; five hours
    into a session, 2 ms apart — a 500 Hz log then reads as 512 Hz with steps of 2 or 4 ms)."""
    a = np.asarray(t)
    if a.dtype.kind != "f" or a.dtype.itemsize >= 8 or a.size < 2:
        return
    finite = a[np.isfinite(a)]
    if finite.size < 2:
        return
    quantum = float(np.spacing(np.max(np.abs(finite))))
    dt = np.diff(np.sort(finite.astype(float)))
    positive = dt[dt > 0]
    step = float(np.median(positive)) if positive.size else 0.0
    if step == 0.0 or quantum > MAX_QUANTUM * step:
        what = (f"{quantum / step:.3g} of the median step {step:.4g}" if step
                else "every stamp collapses onto one value")
        raise DatasetError(f"{source}: the time stamps are {a.dtype}, whose resolution at "
                           f"{float(np.max(np.abs(finite))):.6g} is {quantum:.3g}: {what}, so "
                           "the stamps are quantised. Store time as float64 (or integer "
                           "nanoseconds) where the log is written or converted")


def seconds_of(t: np.ndarray) -> np.ndarray:
    """Stamps typed as times — ``datetime64`` (seconds from the first) or ``timedelta64``
    (seconds) — in float seconds; other arrays unchanged (their unit is the caller's)."""
    a = np.asarray(t)
    if a.dtype.kind == "M" and a.size:
        return (a - a[0]) / np.timedelta64(1, "ns") * 1e-9
    if a.dtype.kind == "m":
        return a / np.timedelta64(1, "ns") * 1e-9
    return a


def check_stamps(t: np.ndarray, source: str = "t") -> np.ndarray:
    """``t`` as a 1-D float array of finite stamps; names the first bad index otherwise (and
    refuses stamps a narrow float type cannot resolve, :func:`check_resolution`)."""
    a = np.asarray(t)
    if a.ndim != 1 or a.size == 0:
        raise DatasetError(f"{source}: time stamps must be a non-empty 1-D array, got shape "
                           f"{a.shape}")
    check_resolution(a, source)
    a = seconds_of(a)
    try:
        a = a.astype(float)
    except (TypeError, ValueError):
        raise DatasetError(f"{source}: time stamps are not numbers (dtype {a.dtype})") from None
    bad = np.flatnonzero(~np.isfinite(a))
    if bad.size:
        raise DatasetError(f"{source}: time stamp t[{bad[0]}] is {a[bad[0]]} ({bad.size} "
                           "non-finite stamp(s)); drop those rows or repair the log's clock")
    return a


def plausible_units(step: float) -> list[str]:
    """The units of :data:`TIME_UNITS` under which a median step of ``step`` (in those units)
    is a plausible robot log."""
    lo, hi = PLAUSIBLE_STEP
    return [u for u, s in TIME_UNITS.items() if lo <= step * s <= hi]


def convert_units(t: np.ndarray, time_unit: str | None, source: str = "t"
                  ) -> tuple[np.ndarray, str | None, float]:
    """Stamps in seconds, a sentence saying what was converted or assumed (``None`` when the
    stamps were already seconds and plausible), and the seconds per stamp unit.

    ``time_unit``: ``None`` (seconds; implausible stamps raise :class:`DatasetError` naming the
    plausible units), ``"auto"`` (seconds if plausible, else the one plausible unit, said in the
    sentence) or one of :data:`TIME_UNITS`.
    """
    check_option("time_unit", time_unit, (None, "auto", *TIME_UNITS))
    if t.size < 2:
        return t, None, 1.0
    step = median_step(t)
    if time_unit in TIME_UNITS:
        if time_unit == "s":
            return t, None, 1.0
        scale = TIME_UNITS[time_unit]
        return t * scale, (f"time stamps converted from {time_unit} to s (time_unit="
                           f"{time_unit!r}); median step {step * scale * 1e3:.4g} ms"), scale
    units = plausible_units(step)
    if "s" in units:
        return t, None, 1.0
    rate = 1.0 / step
    if time_unit == "auto" and len(units) == 1:
        scale = TIME_UNITS[units[0]]
        return t * scale, (f"time stamps read as {units[0]} (time_unit='auto'): their median step "
                           f"{step:.6g} would be {rate:.4g} Hz in seconds, {1 / (step * scale):.4g}"
                           f" Hz in {units[0]}"), scale
    if units:
        hint = " or ".join(f"time_unit={u!r} ({1 / (step * TIME_UNITS[u]):.4g} Hz)" for u in units)
    else:
        hint = "time_unit= with the log's unit"
    raise DatasetError(f"{source}: the median time step {step:.6g} is {rate:.4g} Hz in seconds, "
                       f"not a plausible robot log (steps of {PLAUSIBLE_STEP[0]:g}–"
                       f"{PLAUSIBLE_STEP[1]:g} s); if the stamps are in another unit pass {hint}")


def duplicate_groups(t: np.ndarray, tol: float = 0.0) -> np.ndarray:
    """Group index of each sample of non-decreasing stamps ``t``: a step ``t_k − t_{k−1} ≤ tol``
    keeps sample ``k`` in the group of ``k − 1`` (``tol = 0``: exactly repeated stamps).

    Returns ``(N,)`` integers ``0, …, n_groups − 1``, non-decreasing.
    """
    return np.concatenate([[0], np.cumsum(np.diff(t) > tol)])


def group_mean(x: np.ndarray, group: np.ndarray) -> np.ndarray:
    """Mean of the rows of ``x`` (``(N,)`` or ``(N, m)``) over each group of
    :func:`duplicate_groups`; ``(n_groups,)`` or ``(n_groups, m)``."""
    counts = np.bincount(group)
    if x.ndim == 1:
        return np.bincount(group, weights=x) / counts
    return np.stack([np.bincount(group, weights=col) / counts for col in x.T], axis=1)


def merge_duplicates(t: np.ndarray, arrays: dict[str, np.ndarray], policy: str | None,
                     tol: float = 0.0, source: str = "t"
                     ) -> tuple[np.ndarray, dict[str, np.ndarray], str]:
    """Resolve samples whose stamp is within ``tol`` s of the previous one (module docstring).

    ``policy``: ``None`` (``"average"``, but collapsed stamps raise), ``"average"``,
    ``"first"``, ``"error"`` or ``"spread"``. Returns the stamps, the arrays (rows along axis 0)
    and the sentence for the record.
    """
    check_option("duplicates", policy, (None, *DUPLICATES))
    group = duplicate_groups(t, tol)
    n_dup = t.size - 1 - int(group[-1])
    if n_dup == 0:
        return t, arrays, "no duplicated time stamps"
    first_dup = int(np.flatnonzero(np.diff(group) == 0)[0]) + 1
    within = "" if tol == 0 else f" (within {tol:.3g} s)"
    if policy == "error":
        raise DatasetError(f"{source}: t[{first_dup}] = {float(t[first_dup])!r} repeats "
                           f"t[{first_dup - 1}]{within} ({n_dup} duplicated stamp(s)); pass "
                           "duplicates='average', "
                           "'first' or 'spread'")
    counts = np.bincount(group)
    collapsed = n_dup > COLLAPSED_FRACTION * t.size
    if collapsed and policy is None:
        res = median_step(t)
        raise DatasetError(
            f"{source}: collapsed time stamps: {n_dup} of {t.size} samples share their stamp with "
            f"the previous one (first at t[{first_dup}] = {float(t[first_dup])!r}; up to "
            f"{counts.max()} samples per stamp, stamps {res:.4g} apart): the clock is coarser "
            "than the sampling. Pass duplicates='spread' to place the samples of each stamp evenly "
            "until the next stamp (assumes uniform sampling), 'average' to merge each group "
            "into one sample, or give the real stamps")
    n_groups = int(group[-1]) + 1
    starts = np.flatnonzero(np.concatenate([[True], np.diff(group) != 0]))
    if policy == "spread":
        tg = t[starts]
        nxt = np.append(tg[1:], np.nan)
        if n_groups > 1:
            nxt[-1] = tg[-1] + median_step(tg)
        else:
            raise DatasetError(f"{source}: all {t.size} stamps are equal; nothing to spread over")
        rank = np.arange(t.size) - starts[group]
        spread_t = tg[group] + rank / counts[group] * (nxt - tg)[group]
        return spread_t, arrays, (f"{n_dup} of {t.size} samples shared a stamp{within} (up to "
                                  f"{counts.max()} per stamp): spread evenly over the step to "
                                  "the next stamp (duplicates='spread', assumes uniform sampling)")
    same = np.flatnonzero(np.diff(group) == 0)
    identical = all(np.array_equal(a[same], a[same + 1]) for a in arrays.values())
    if policy == "first":
        merged = {k: a[starts] for k, a in arrays.items()}
        how = "kept the first sample of each"
    else:
        merged = {k: group_mean(a, group) for k, a in arrays.items()}
        how = "replaced each group by its mean"
    kind = "identical repeats" if identical else "samples that differ"
    note = " — collapsed stamps, merged as asked" if collapsed else ""
    return t[starts], merged, (f"{n_dup} duplicated time stamp(s){within} ({kind}): {how}; "
                               f"{t.size} → {n_groups} samples{note}")


def long_steps(t: np.ndarray, factor: float) -> tuple[np.ndarray, float]:
    """Gaps: the indices ``k`` of the steps ``t_{k+1} − t_k`` longer than ``factor`` × the
    median step, and that limit (s)."""
    dt = np.diff(t)
    limit = factor * float(np.median(dt))
    return np.flatnonzero(dt > limit), limit


def interval_centres(t: np.ndarray, timestamp: str, step: float | None = None) -> np.ndarray:
    """The centres of the averaging intervals of samples stamped at their ``timestamp``
    (``"start"``, ``"centre"`` or ``"end"``; module docstring). ``step``: the length of the
    interval whose far end is not logged (default the median step)."""
    check_option("timestamp", timestamp, TIMESTAMPS)
    t = np.asarray(t, dtype=float)
    if timestamp == "centre" or t.size < 2:
        return t
    dt = np.diff(t)
    h = float(np.median(dt)) if step is None else float(step)
    if timestamp == "end":
        return t - 0.5 * np.concatenate([[h], dt])
    return t + 0.5 * np.concatenate([dt, [h]])


def check_timestamp(timestamp: object, fields: tuple[str, ...] = ("tau",)
                    ) -> dict[str, str]:
    """``timestamp=`` as a mapping field → convention: a string applies to ``fields`` (the
    averaged signals; by default the torques, positions being sampled at their stamp), a
    mapping names them (``{"tau": "end", "q": "centre"}``)."""
    if isinstance(timestamp, str):
        check_option("timestamp", timestamp, TIMESTAMPS)
        return {f: timestamp for f in fields}
    if isinstance(timestamp, dict):
        for k, v in timestamp.items():
            check_option("timestamp field", k, ("q", "tau", "dq", "ddq"))
            check_option(f"timestamp[{k!r}]", v, TIMESTAMPS)
        return dict(timestamp)
    raise OptionError(f"timestamp={timestamp!r}: give 'start', 'centre' or 'end' (how the logger "
                      "stamps the torques it averaged over each interval), or a mapping such as "
                      "{'tau': 'end'}")

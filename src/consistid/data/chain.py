r"""The signal chain: a robot log ``(t, q, τ)`` to uniformly sampled, filtered ``(t, q, q̇, q̈, τ)``
arrays and the record of every step (:func:`run_chain`).

It returns arrays, not a :class:`~consistid.data.dataset.Dataset`, so that the dataset module can
build itself from it (:meth:`Dataset.from_recording`) without an import cycle;
:func:`consistid.data.signals.preprocess` is the same chain returning a dataset. The default
chain, in order (each step appears in the record when it did something):

1. **time stamps** (:mod:`consistid.data.timestamps`): units (``time_unit``; implausible stamps
   are refused, never silently rescaled, and judged after sorting); sort if needed (stamps
   going back by more than ``CLOCK_STEP_BACK`` median steps warn: a stepped clock, whose
   stretches sorting interleaves); samples whose stamps are within
   ``duplicate_tol`` median steps merged (``duplicates``; collapsed stamps refused unless a
   policy is given); positions that jump by ±2π between two samples (a logger that wraps angles)
   unwrapped, with a warning;
2. **outliers**: a Hampel filter (window 11, 6 robust σ) on ``q`` and ``τ`` replaces spikes by
   the running median, on the raw samples, per *stretch* (the parts between outages: steps
   longer than both ``gap`` median steps and :data:`OUTAGE` s); a sample between the levels
   before and after it is a step (Coulomb friction reversing), kept
   (:func:`~consistid.data.filters.hampel`); torque samples a logger repeated while the joint
   moved are bridged (:func:`~consistid.data.filters.stuck_samples`);
3. **cut-offs**: two. The *derivative* cut-off ``f_d``, at which ``q`` is low-passed before it
   is differentiated and ``τ`` filtered alike: given (``cutoff``), or
   ``min(10 × bandwidth, 0.4 × rate)`` with the bandwidth given or
   estimated from the positions of the longest stretch (on the uniform grid, linearly
   interpolated), from the part of their spectrum that stands above its noise
   (:func:`~consistid.data.filters.estimate_bandwidth`: the error of jittered stamps, sensor
   noise and encoder counts are not motion). The *identification* cut-off ``f_p``
   (``Dataset.identification_filter``), at which identification low-passes ``τ`` and every
   column of ``Y`` alike (parallel filtering, :mod:`consistid.data.parallel`):
   ``min(3 × bandwidth, f_d)`` when ``f_d`` is chosen from the bandwidth, ``parallel_cutoff``
   when given; none with a given ``cutoff`` alone (which keeps its meaning), with
   ``parallel=False``, ``filter_torque=False`` or ``derivative="fourier"``. The chain's
   "cut-off" (``Preprocessed.cutoff``) is ``f_p`` when there is one, else ``f_d``; the rules
   below that depend on a cut-off (gaps, trim, Fourier harmonics, the filters) use ``f_d``;
4. **gaps**: a step longer than the gap limit splits the log into *segments*, which the filters
   never cross. By default the limit is the larger of ``5`` median steps and half a period of
   the cut-off (:data:`GAP_CUTOFF_PERIODS`): a shorter step is bridged by the cubic spline,
   whose second-derivative error across a step ``h`` at the excitation bandwidth
   ``f_b = f_c/10`` is about ``(2π f_b h)²/12 ≤ 0.8 %`` there (de Boor 2001, ch. V), and the
   filter then averages it with its neighbours. ``gap=`` (median steps) sets the limit alone;
5. **timestamp**: signals a logger averaged over each interval and stamped at its ``"start"`` or
   ``"end"`` (``timestamp=``; by default the torques) are moved to the interval centres and
   interpolated back to the positions' stamps (:func:`~consistid.data.timestamps.interval_centres`);
6. **resample**: a segment whose steps vary by more than ``jitter`` (relative), or whose rate is
   not ``rate``, goes onto a uniform grid by cubic spline (:mod:`consistid.data.resample`, the
   one resampler). ``rate`` defaults to the rate the log supports
   (:func:`~consistid.data.resample.supported_rate`: one over the median step); a given
   ``rate`` below 0.9 × a segment's own is refused (use ``decimate``);
7. **filter and differentiate** (``derivative``):

   * ``"central"`` (default): the same zero-phase Butterworth (order 4) on ``q`` and ``τ``,
     then central differences of the filtered ``q``. It does not distort both sides of
     ``τ = Y π`` alike: ``Y`` is nonlinear in the motion, and ``f_d`` must pass the torque's
     harmonics (:mod:`consistid.data.filters`); ``sign(q̇)`` is filtered like ``τ``
     (``dq_sign``); the identification's low-pass at ``f_p`` then acts on both sides alike;
   * ``"savgol"``: Savitzky–Golay smoothing of ``q`` (value, first, second derivative) and of
     ``τ`` (value), window from the cut-off;
   * ``"fourier"``: ``q`` and ``τ`` averaged over whole periods of ``period`` and truncated to
     the harmonics below the cut-off; the result is the one averaged period;
8. **edges**: ``trim`` seconds cut at both ends of each segment (default ``3 / f_c``; none for
   ``"fourier"``, which refuses a ``trim``), where the filters' transients sit;
9. optional **decimation** (``decimate``, after the low-pass, so it does not alias) and
   **low-speed removal** (``min_speed``).
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import asdict, dataclass, fields
from typing import Any, Mapping, Sequence

import numpy as np

from ..errors import DataQualityWarning, DatasetError, OptionError, check_number, check_option
from .filters import (
    CUTOFF_FACTOR,
    MAX_CUTOFF_FRACTION,
    as_2d,
    central_difference,
    default_cutoff,
    estimate_bandwidth,
    fourier_derivatives,
    bridge,
    hampel,
    held_still,
    low_speed_mask,
    lowpass,
    period_average,
    savgol_derivatives,
    savgol_window,
    stuck_samples,
    transposed_hint,
)
from .parallel import PARALLEL_FACTOR, parallel_cutoff
from .resample import check_rate, nominal_rate, resample, supported_rate, uniform_grid
from .timestamps import (
    DUPLICATES,
    PLAUSIBLE_STEP,
    TIME_UNITS,
    check_resolution,
    check_timestamp,
    convert_units,
    interval_centres,
    median_step,
    merge_duplicates,
    seconds_of,
)

LOG = logging.getLogger(__name__)

DERIVATIVES = ("central", "savgol", "fourier")
#: Default edge trim, in periods of the cut-off: the transient of the reflected ends (the
#: padding flips the curvature) leaves ~1e-4 relative error in q̈ after it (Panda excitation).
TRIM_PERIODS = 3.0
#: Default gap limit in median steps (also the least one of the automatic rule).
GAP_FACTOR = 5.0
#: With the automatic rule, steps up to this many periods of the cut-off are bridged.
GAP_CUTOFF_PERIODS = 0.5
#: Steps longer than this (s) and than the gap limit are outages: they end a stretch.
OUTAGE = 0.1
#: Fewer samples than this in a segment: dropped.
MIN_SEGMENT = 16
#: Stamps going back by more than this many median steps warn (:func:`_warn_clock_steps`).
CLOCK_STEP_BACK = 2.0
#: Peak joint speed (rad/s or m/s) below which a moving log warns as quasi-static
#: (:func:`_warn_quasi_static`); a robot being identified moves 10–100 × faster.
QUASI_STATIC_SPEED = 0.01
#: A position step within this (rad) of ±2π, where every other step is below π, is a wrap
#: (:func:`_unwrap`).
WRAP_TOL = 0.5


@dataclass(frozen=True)
class Step:
    """One processing step applied by the chain: its name and what it did."""

    name: str
    detail: str

    def __str__(self) -> str:
        return f"{self.name}: {self.detail}"


@dataclass(frozen=True)
class PreprocessOptions:
    """The options of the signal chain (module docstring), validated on construction.

    Attributes
    ----------
    derivative : ``"central"``, ``"savgol"`` or ``"fourier"``.
    cutoff : low-pass cut-off (Hz); default from ``bandwidth``.
    bandwidth : excitation bandwidth (Hz), e.g. ``harmonics / period``; default estimated.
    order : Butterworth order (one direction).
    period : excitation period (s), needed by ``derivative="fourier"``.
    rate : resampling rate (Hz); default the rate the log supports.
    outliers : Hampel threshold (robust σ), ``None`` to skip.
    outlier_window : Hampel window (odd, samples).
    trim : seconds cut at both ends of each segment; default ``3 / cutoff``.
    min_speed : drop samples where some ``|q̇|`` is below this (rad/s; scalar or per joint).
    decimate : keep every ``decimate``-th sample after the low-pass.
    gap : gap limit in median steps; ``None``: the automatic rule (module docstring, step 4).
    jitter : relative spread of steps above which a segment is resampled.
    duplicate_tol : steps shorter than this × the median step are duplicate stamps.
    duplicates : ``None`` (average; collapsed stamps refused), ``"average"``, ``"first"``,
        ``"error"``, ``"spread"`` (:func:`consistid.data.timestamps.merge_duplicates`).
    filter_torque : low-pass the torques with the same filter as the positions.
    parallel : choose an identification cut-off (parallel filtering,
        :mod:`consistid.data.parallel`): ``PARALLEL_FACTOR × bandwidth`` when the cut-off is
        chosen from the bandwidth (given or estimated), ``parallel_cutoff`` when given; never
        with ``derivative="fourier"`` (one averaged period) nor with ``filter_torque=False``.
    parallel_cutoff : the identification cut-off (Hz), at most ``cutoff``; default as above.
        With ``cutoff`` given and not this, there is none: ``cutoff`` keeps its meaning (the one
        low-pass of ``q`` and ``τ``, and least squares on those samples as they are).
    polyorder : Savitzky–Golay polynomial order.
    timestamp : how the logger stamps the torques it averaged over each interval:
        ``"centre"`` (default: no shift), ``"start"`` or ``"end"``; or a mapping per field
        (``{"tau": "end", "q": "end"}``).
    time_unit : ``None`` (seconds, implausible stamps refused), ``"auto"``, ``"s"``, ``"ms"``,
        ``"us"``, ``"ns"``.
    """

    derivative: str = "central"
    cutoff: float | None = None
    bandwidth: float | None = None
    order: int = 4
    period: float | None = None
    rate: float | None = None
    outliers: float | None = 6.0
    outlier_window: int = 11
    trim: float | None = None
    min_speed: float | Sequence[float] | None = None
    decimate: int = 1
    gap: float | None = None
    jitter: float = 1e-3
    duplicate_tol: float = 1e-6
    duplicates: str | None = None
    filter_torque: bool = True
    parallel: bool = True
    parallel_cutoff: float | None = None
    polyorder: int = 5
    timestamp: str | Mapping[str, str] = "centre"
    time_unit: str | None = None

    def __post_init__(self) -> None:
        check_option("derivative", self.derivative, DERIVATIVES)
        check_option("duplicates", self.duplicates, (None, *DUPLICATES))
        check_option("time_unit", self.time_unit, (None, "auto", *TIME_UNITS))
        for name in ("cutoff", "bandwidth", "period", "rate", "outliers", "gap",
                     "parallel_cutoff"):
            if getattr(self, name) is not None:
                check_number(name, getattr(self, name), 0.0, strict=True)
        for name in ("order", "outlier_window", "polyorder"):
            check_number(name, getattr(self, name), 0, strict=True, integer=True)
        if isinstance(self.decimate, bool) or not isinstance(self.decimate, (int, np.integer)) \
                or self.decimate < 1:
            raise OptionError(f"decimate = {self.decimate!r}; it must be a positive integer")
        check_number("jitter", self.jitter, 0.0)
        check_number("duplicate_tol", self.duplicate_tol, 0.0)
        if self.trim is not None:
            check_number("trim", self.trim, 0.0)
        if self.derivative == "fourier" and self.trim:
            raise OptionError(f"trim = {self.trim} s does not apply to derivative='fourier': its "
                              "dataset is one averaged period, which has no filter edges")
        check_timestamp(self.timestamp)
        if not isinstance(self.parallel, (bool, np.bool_)):
            raise OptionError(f"parallel must be True or False, got {self.parallel!r}")
        if self.parallel_cutoff is not None:
            why = ("parallel=False" if not self.parallel else
                   "derivative='fourier' (one averaged period)" if self.derivative == "fourier"
                   else "filter_torque=False" if not self.filter_torque else "")
            if why:
                raise OptionError(f"parallel_cutoff = {self.parallel_cutoff} Hz: no "
                                  f"identification cut-off with {why}")
            if self.cutoff is not None and self.parallel_cutoff > self.cutoff:
                raise OptionError(f"parallel_cutoff = {self.parallel_cutoff} Hz is above "
                                  f"cutoff = {self.cutoff} Hz, where q and τ were already "
                                  "filtered: it would remove nothing; give one at most cutoff")

    @classmethod
    def from_kwargs(cls, options: Mapping[str, Any]) -> "PreprocessOptions":
        """The options from keyword arguments; an unknown name raises :class:`OptionError`
        listing the known ones."""
        known = [f.name for f in fields(cls)]
        unknown = sorted(set(options) - set(known))
        if unknown:
            raise OptionError(f"unknown signal-chain option(s) {unknown}; known: {known}")
        return cls(**options)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True, eq=False)
class ChainResult:
    """Arrays out of :func:`run_chain` and the record of how.

    Attributes
    ----------
    t : (N,) s; q, dq, ddq, tau : (N, nv); segment : (N,) gap-free stretch index.
    dq_sign : (N, nv) ``sign(q̇)`` through the torque's filter (the regressor's Coulomb column
        for these torques, :attr:`consistid.data.dataset.Dataset.dq_sign`), or ``None`` when
        the torques were not filtered.
    steps : the :class:`Step` s applied, in order.
    rate : sampling rate of the result (Hz), after resampling/decimation.
    derivative_cutoff : cut-off (Hz) of the low-pass on ``q`` (differentiated after it) and
        ``τ``.
    parallel_cutoff : the identification cut-off (Hz): ``τ`` and every column of ``Y`` are
        low-passed alike there at identification (:mod:`consistid.data.parallel`); ``None``:
        none.
    bandwidth : excitation bandwidth used to choose them (Hz), or ``None`` when given.
    options : the :class:`PreprocessOptions` used.
    """

    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray
    tau: np.ndarray
    segment: np.ndarray
    dq_sign: np.ndarray | None
    steps: tuple[Step, ...]
    rate: float
    derivative_cutoff: float
    parallel_cutoff: float | None
    bandwidth: float | None
    options: PreprocessOptions

    @property
    def cutoff(self) -> float:
        """The cut-off the identification sees (Hz): :attr:`parallel_cutoff`, or
        :attr:`derivative_cutoff` when there is none."""
        return self.derivative_cutoff if self.parallel_cutoff is None else self.parallel_cutoff

    @property
    def identification_filter(self) -> tuple[float, int] | None:
        """``(parallel cut-off Hz, order)`` for
        :attr:`consistid.data.dataset.Dataset.identification_filter`, or ``None``."""
        if self.parallel_cutoff is None:
            return None
        return float(self.parallel_cutoff), int(self.options.order)

    @property
    def torque_filter(self) -> tuple[float, int] | None:
        """``(cut-off Hz, order)`` of the zero-phase Butterworth low-pass applied to the torques
        (:attr:`consistid.data.dataset.Dataset.torque_filter`), or ``None``: torques unfiltered,
        smoothed another way (Savitzky–Golay, Fourier harmonics), or decimated after the filter
        (its response is then not that of the same filter at the result's rate)."""
        if (self.options.filter_torque and self.options.derivative == "central"
                and self.options.decimate == 1):
            return float(self.derivative_cutoff), int(self.options.order)
        return None

    def __str__(self) -> str:
        lines = [f"{len(self.steps)} steps → {self.t.size} samples, "
                 f"{len(np.unique(self.segment))} segment(s) at {self.rate:.6g} Hz"]
        lines += [f"  {i + 1}. {s}" for i, s in enumerate(self.steps)]
        return "\n".join(lines)


# ------------------------------------------------------------------------------- helpers
def _jittered(ts: np.ndarray, rate: float, jitter: float) -> bool:
    """Whether some step of ``ts`` is more than ``jitter`` (relative) off ``1 / rate``."""
    return ts.size > 1 and float(np.max(np.abs(np.diff(ts) * rate - 1.0))) > jitter


def _split(t: np.ndarray, limit: float) -> list[slice]:
    cuts = np.flatnonzero(np.diff(t) > limit) + 1
    edges = [0, *cuts.tolist(), t.size]
    return [slice(a, b) for a, b in zip(edges[:-1], edges[1:])]


def _check_inputs(t: np.ndarray, q: np.ndarray, tau: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    check_resolution(t)
    t = np.asarray(seconds_of(t), dtype=float)
    if t.ndim != 1:
        raise DatasetError(f"t must be 1-D (N,), got shape {t.shape}")
    q, tau = as_2d("q", q), as_2d("tau", tau)
    for name, a in (("t", t[:, None]), ("q", q), ("tau", tau)):
        if a.shape[0] != t.shape[0]:
            raise DatasetError(f"{name} has {a.shape[0]} samples; t has {t.shape[0]}"
                               + transposed_hint(a.shape, t.shape[0]))
        bad = np.argwhere(~np.isfinite(a))
        if bad.size:
            raise DatasetError(f"{name}[{bad[0][0]}{'' if name == 't' else f', {bad[0][1]}'}] "
                               f"is {a[tuple(bad[0])]} ({len(bad)} non-finite value(s))")
    if q.shape[1] != tau.shape[1]:
        raise DatasetError(f"q has {q.shape[1]} joints, tau has {tau.shape[1]}")
    if t.size < MIN_SEGMENT:
        raise DatasetError(f"the log has {t.size} samples; the signal chain needs at least "
                           f"{MIN_SEGMENT}")
    return t, q, tau


def _fix_time(t: np.ndarray, x: np.ndarray, o: PreprocessOptions, steps: list[Step]
              ) -> tuple[np.ndarray, np.ndarray]:
    back = np.flatnonzero(np.diff(t) < 0)
    raw = t
    if back.size:                       # sorted first: units are judged on the sorted steps
        order = np.argsort(t, kind="stable")
        moved = int(np.sum(order != np.arange(t.size)))
        t, x = t[order], x[order]
    t, note, scale = convert_units(t, o.time_unit)
    if note:
        steps.append(Step("time unit", note))
    if back.size:
        steps.append(Step("sort", f"{moved} samples were out of time order; sorted by time"))
        _warn_clock_steps(raw, back, scale, median_step(t))
    tol = o.duplicate_tol * median_step(t)
    t, merged, note = merge_duplicates(t, {"x": x}, o.duplicates, tol)
    if not note.startswith("no "):
        steps.append(Step("duplicates", note))
    return t, merged["x"]


def _warn_clock_steps(t: np.ndarray, back: np.ndarray, scale: float, step: float) -> None:
    """Warn (:class:`DataQualityWarning`) when the raw stamps ``t`` go back by more than
    :data:`CLOCK_STEP_BACK` median steps ``step`` (s) anywhere (``back``: the indices ``k``
    with ``t[k+1] < t[k]``). Rows logged out of order go back by about one step and are sorted
    silently (the record says so); a larger step back is what a stepped clock (NTP, a
    controller reboot) leaves, and sorting then interleaves two stretches of the log."""
    drops = (t[back] - t[back + 1]) * scale
    big = back[drops > CLOCK_STEP_BACK * step]
    if not big.size:
        return
    k = int(big[0]) + 1
    first = (f"time goes back {back.size} time(s), by up to {drops.max() * 1e3:.4g} ms "
             f"({drops.max() / step:.3g} median steps); first by "
             f"{drops[back == big[0]][0] * 1e3:.4g} ms at t[{k}] = {float(t[k])!r} after "
             f"t[{k - 1}] = {float(t[k - 1])!r}. The samples were sorted by time")
    if big.size == 1:
        advice = (", which interleaves two stretches of the log if the logger's clock was "
                  f"stepped back (NTP, a reboot): then cut the log at index {k} and load the "
                  "two parts as separate recordings")
    else:
        advice = (f"; {big.size} such steps back: rows written out of order, or several logs "
                  "(or clocks) mixed in one file? Check that it is one recording")
    warnings.warn(first + advice, DataQualityWarning, stacklevel=5)


def _unwrap(t: np.ndarray, x: np.ndarray, nv: int, steps: list[Step]) -> np.ndarray:
    """Positions that jump by ±2π (within :data:`WRAP_TOL`) between two samples, and by less
    than π everywhere else, come from a logger that wraps angles into a 2π interval (ROS drivers
    do, for continuous joints): no joint turns half a revolution in one sample. Those columns
    are unwrapped (``numpy.unwrap``: multiples of 2π added after each jump), which changes no
    sine or cosine of them; said in the record and warned (:class:`DataQualityWarning`)."""
    d = np.diff(x[:, :nv], axis=0)
    big = np.abs(d) > np.pi
    cols = [j for j in range(nv) if big[:, j].any() and np.all(
        np.abs(np.abs(d[big[:, j], j]) - 2 * np.pi) < WRAP_TOL)]
    if not cols:
        return x
    x = x.copy()
    x[:, cols] = np.unwrap(x[:, cols], axis=0)
    what = "; ".join(f"q[:, {j}] {int(big[:, j].sum())} time(s), first at t = "
                     f"{t[int(np.flatnonzero(big[:, j])[0]) + 1]:.4g} s" for j in cols)
    steps.append(Step("unwrap", f"angles wrapped into a 2π interval unwrapped ({what})"))
    warnings.warn(f"positions jump by ±2π between two samples ({what}): the logger wraps the "
                  "angles into a 2π interval. They were unwrapped (multiples of 2π added after "
                  "each jump), which the dynamics do not see; joint limits, if checked, see the "
                  "unwrapped angles", DataQualityWarning, stacklevel=4)
    return x


def _warn_quasi_static(t: np.ndarray, dq: np.ndarray, step: float,
                       time_unit: str | None) -> None:
    """Warn (:class:`DataQualityWarning`) when no joint ever moves faster than
    :data:`QUASI_STATIC_SPEED` while the positions do change: a quasi-static log informs the
    gravity terms only — or its stamps are not seconds (a 10 kHz log stamped in milliseconds
    reads as a plausible 10 Hz log whose motion is a thousand times too slow)."""
    peak = float(np.max(np.abs(dq))) if dq.size else 0.0
    if peak == 0.0 or peak >= QUASI_STATIC_SPEED:
        return                      # no motion at all is refused where it matters (identify)
    hint = ""
    if time_unit in (None, "s", "auto"):
        lo, hi = PLAUSIBLE_STEP
        other = [f"time_unit={u!r} ({1 / (step * TIME_UNITS[u]):.4g} Hz, peak speed "
                 f"{peak / TIME_UNITS[u]:.3g} rad/s)" for u in ("ms", "us")
                 if lo <= step * TIME_UNITS[u] <= hi]
        if other:
            hint = (f". If the time stamps are not seconds (a log at {1 / step:.4g} Hz and "
                    f"{t[-1] - t[0]:.4g} s long?), pass " + " or ".join(other))
    warnings.warn(f"no joint moves faster than {peak:.3g} rad/s (or m/s) in this log: it is "
                  "quasi-static and informs the gravity terms only (inertia and friction barely)"
                  f"{hint}", DataQualityWarning, stacklevel=4)


def _outliers(t: np.ndarray, x: np.ndarray, stretches: list[slice], nv: int,
              o: PreprocessOptions, steps: list[Step]) -> np.ndarray:
    spikes = np.zeros(x.shape[1], dtype=int)
    stale = np.zeros(nv, dtype=int)
    x = x.copy()
    for s in stretches:
        if s.stop - s.start >= o.outlier_window:
            x[s], mask = hampel(x[s], o.outlier_window, o.outliers, t[s])
            spikes += mask.sum(axis=0)
        stuck = stuck_samples(x[s, nv:], x[s, :nv])
        if stuck.any():
            x[s, nv:] = bridge(x[s, nv:], stuck)
            stale += stuck.sum(axis=0)
    if spikes.any():
        where = ", ".join(f"{'q' if c < nv else 'tau'}[{c % nv}]: {n}"
                          for c, n in enumerate(spikes) if n)
        steps.append(Step("outliers", f"Hampel ({o.outlier_window} samples, {o.outliers:g} σ; "
                                      "steps between two levels kept) replaced "
                                      f"{int(spikes.sum())} sample(s) by the running median "
                                      f"({where})"))
    else:
        steps.append(Step("outliers", f"Hampel ({o.outlier_window} samples, {o.outliers:g} σ): "
                                      "none found"))
    if stale.any():
        where = ", ".join(f"tau[{j}]: {n}" for j, n in enumerate(stale) if n)
        steps.append(Step("stuck samples", f"{int(stale.sum())} torque sample(s) repeated the "
                                           "one before them (runs of 3 or more while the joint "
                                           "moved) replaced by linear interpolation "
                                           f"({where})"))
    return x


def _cutoff(t: np.ndarray, q: np.ndarray, stretches: list[slice], rate: float,
            o: PreprocessOptions, steps: list[Step]
            ) -> tuple[float, float | None, float | None]:
    """``(derivative cut-off, bandwidth or None when the cut-off is given, identification
    cut-off or None)``, and the step that says them."""
    parallel = o.parallel and o.filter_torque and o.derivative != "fourier"
    if o.cutoff is not None:
        if o.parallel_cutoff is None:
            steps.append(Step("cut-off", f"{o.cutoff:.4g} Hz (given)"))
            return float(o.cutoff), None, None
        steps.append(Step("cut-off", f"{o.parallel_cutoff:.4g} Hz (given; τ and Y filtered "
                                     "alike at identification); positions differentiated and "
                                     f"torques filtered at {o.cutoff:.4g} Hz (given)"))
        return float(o.cutoff), None, float(o.parallel_cutoff)
    if o.bandwidth is None:
        longest = max(stretches, key=lambda s: s.stop - s.start)
        ts, qs = t[longest], q[longest]
        if _jittered(ts, rate, o.jitter):
            grid = uniform_grid(ts[0], ts[-1], rate)
            qs = resample(ts, qs, grid, "linear")
        bandwidth = estimate_bandwidth(qs, rate)
        origin = "estimated from the position spectrum (99.99 % of the power above its noise)"
        still = np.flatnonzero(held_still(qs))
        if 0 < still.size < qs.shape[1]:
            origin += (f"; q[:, {still.tolist()}] held still (constant or flickering between "
                       "counts): left out")
    else:
        bandwidth, origin = float(o.bandwidth), "given"
    cutoff = default_cutoff(bandwidth, rate)
    rule = (f"min({CUTOFF_FACTOR:g} × bandwidth, {MAX_CUTOFF_FRACTION:g} × {rate:.6g} Hz)")
    if not parallel:
        steps.append(Step("cut-off", f"{cutoff:.4g} Hz = min({CUTOFF_FACTOR:g} × bandwidth "
                                     f"{bandwidth:.4g} Hz ({origin}), {MAX_CUTOFF_FRACTION:g} × "
                                     f"{rate:.6g} Hz)"))
        return cutoff, bandwidth, None
    chosen = (float(o.parallel_cutoff) if o.parallel_cutoff is not None
              else parallel_cutoff(bandwidth, cutoff))
    if chosen > cutoff:
        raise OptionError(f"parallel_cutoff = {chosen} Hz is above the cut-off {cutoff:.4g} Hz "
                          "chosen for q and τ, where they were already filtered: it would "
                          "remove nothing; give one at most that, or cutoff= too")
    how = ("given" if o.parallel_cutoff is not None else
           f"{PARALLEL_FACTOR:g} × bandwidth {bandwidth:.4g} Hz ({origin})")
    steps.append(Step("cut-off", f"{chosen:.4g} Hz = {how} (τ and Y filtered alike at "
                                 f"identification); positions differentiated and torques "
                                 f"filtered at {cutoff:.4g} Hz = {rule}"))
    return cutoff, bandwidth, chosen


def _segments(t: np.ndarray, h: float, cutoff: float, o: PreprocessOptions,
              steps: list[Step]) -> list[slice]:
    dt = np.diff(t)
    if o.gap is not None:
        limit, rule = o.gap * h, f"{o.gap:g} median steps (gap=)"
    else:
        limit = max(GAP_FACTOR * h, GAP_CUTOFF_PERIODS / cutoff)
        rule = (f"max({GAP_FACTOR:g} median steps, {GAP_CUTOFF_PERIODS:g} / cut-off) = "
                f"{limit * 1e3:.4g} ms")
    segments = _split(t, limit)
    cuts = [s.start for s in segments[1:]]
    if cuts:
        steps.append(Step("gaps", f"{len(cuts)} gap(s) longer than {rule} (at t = "
                                  f"{', '.join(f'{t[c - 1]:.4g}' for c in cuts[:5])}"
                                  f"{', …' if len(cuts) > 5 else ''}); split into "
                                  f"{len(cuts) + 1} segments"))
    bridged = (dt > GAP_FACTOR * h) & (dt <= limit)
    if bridged.any():
        steps.append(Step("long steps", f"{int(bridged.sum())} step(s) longer than "
                                        f"{GAP_FACTOR:g} median steps (up to "
                                        f"{dt[bridged].max() * 1e3:.4g} ms) bridged by the "
                                        f"cubic spline: shorter than the gap limit {rule}"))
    return segments


def _regrid(ts: np.ndarray, xs: np.ndarray, nv: int, rate: float, rate_given: bool,
            shifts: Mapping[str, str], o: PreprocessOptions, h: float
            ) -> tuple[np.ndarray, np.ndarray, bool, int]:
    """One segment: averaged fields moved to their interval centres, then onto the uniform
    grid at ``rate`` if its steps jitter or its rate differs. Returns the stamps, values,
    whether it was resampled and how many edge samples the shift dropped."""
    own = nominal_rate(ts)
    if rate_given:
        check_rate(rate, own, "the log")
    cols = {"q": slice(0, nv), "tau": slice(nv, 2 * nv)}
    centres = {f: interval_centres(ts, conv, step=h) for f, conv in shifts.items()
               if conv != "centre" and f in cols}
    lo = max([ts[0], *(c[0] for c in centres.values())])
    hi = min([ts[-1], *(c[-1] for c in centres.values())])
    needs_grid = _jittered(ts, rate, o.jitter)
    if needs_grid:
        at = uniform_grid(lo, hi, rate)
    else:
        at = ts[(ts >= lo - 1e-12) & (ts <= hi + 1e-12)]
    out = np.empty((at.size, xs.shape[1]))
    for f, c in cols.items():
        src = centres.get(f, ts)
        if needs_grid or f in centres:
            out[:, c] = resample(src, xs[:, c], np.clip(at, src[0], src[-1]))
        else:
            out[:, c] = xs[(ts >= lo - 1e-12) & (ts <= hi + 1e-12), c]
    dropped = 0 if needs_grid else ts.size - at.size
    return at, out, needs_grid, dropped


# ------------------------------------------------------------------------------- the chain
def run_chain(t: np.ndarray, q: np.ndarray, tau: np.ndarray,
              options: PreprocessOptions | None = None) -> ChainResult:
    """Turn a log ``(t, q, τ)`` into filtered, differentiated arrays by the documented chain
    (module docstring), with the record of each step (also logged at INFO level on the
    ``consistid.data.chain`` logger).

    Parameters
    ----------
    t : (N,) time stamps (s unless ``options.time_unit``), any order, possibly duplicated,
        jittered or with gaps.
    q, tau : (N, nv) measured positions (rad / m) and torques (N·m / N).
    options : :class:`PreprocessOptions` (default: all defaults).

    Raises
    ------
    DatasetError : bad shapes, non-finite values (named by index), implausible or collapsed
        stamps, too few samples, a period that is not a whole number of samples.
    OptionError : bad options.
    """
    o = PreprocessOptions() if options is None else options
    t, q, tau = _check_inputs(t, q, tau)
    nv = q.shape[1]
    steps: list[Step] = []
    t, x = _fix_time(t, np.hstack([q, tau]), o, steps)
    x = _unwrap(t, x, nv, steps)
    h = median_step(t)
    stretches = _split(t, max(GAP_FACTOR * h, OUTAGE) if o.gap is None else o.gap * h)
    if o.rate is not None:
        rate, rate_given = float(o.rate), True
    else:
        rate, how = supported_rate([t[s] for s in _split(t, GAP_FACTOR * h)])
        rate_given = False
        if _jittered(t, rate, o.jitter):
            steps.append(Step("rate", f"{how}: steps {np.diff(t).min() * 1e3:.4g}–"
                                      f"{np.diff(t).max() * 1e3:.4g} ms, median {h * 1e3:.4g} ms"))
    if o.outliers is not None:
        x = _outliers(t, x, stretches, nv, o, steps)
    cutoff, bandwidth, chosen = _cutoff(t, x[:, :nv], stretches, rate, o, steps)
    if o.derivative == "fourier" and o.period is None:
        raise OptionError("derivative='fourier' needs the excitation period (s)")
    if o.decimate > 1 and cutoff >= 0.5 * rate / o.decimate:
        raise OptionError(f"decimate = {o.decimate} brings the Nyquist frequency to "
                          f"{0.5 * rate / o.decimate:.4g} Hz, below the {cutoff:.4g} Hz cut-off: "
                          "the decimated signal would alias")
    segments = _segments(t, h, cutoff, o, steps)
    if o.derivative == "fourier" and len(segments) > 1:
        raise DatasetError("derivative='fourier' needs one gap-free log; this one has "
                           f"{len(segments)} segments")

    shifts = check_timestamp(o.timestamp)
    moved = {f: c for f, c in shifts.items() if c != "centre"}
    if any(f not in ("q", "tau") for f in moved):
        raise OptionError(f"timestamp={o.timestamp!r}: a raw log has only q and tau")
    pieces, n_resampled, n_in, n_out, n_dropped, short = [], 0, 0, 0, 0, 0
    for s in segments:
        ts, xs = t[s], x[s]
        if ts.size < MIN_SEGMENT:
            short += 1
            continue
        at, xr, resampled, dropped = _regrid(ts, xs, nv, rate, rate_given, moved, o, h)
        n_resampled += resampled
        n_in += ts.size if resampled else 0
        n_out += at.size if resampled else 0
        n_dropped += dropped
        pieces.append((at, xr))
    if short:
        steps.append(Step("short segment", f"{short} segment(s) of fewer than {MIN_SEGMENT} "
                                           "samples dropped"))
    if not pieces:
        raise DatasetError(f"no segment of the log has {MIN_SEGMENT} samples or more")
    if moved:
        what = ", ".join(f"{'τ' if f == 'tau' else f} stamped at the interval {c}"
                         for f, c in moved.items())
        steps.append(Step("timestamp", f"{what}: moved to the interval centres (half a step, "
                                       f"{0.5 * h * 1e3:.4g} ms at the median) and interpolated "
                                       "at the positions' stamps by cubic spline"
                                       + (f"; {n_dropped} edge sample(s) outside dropped"
                                          if n_dropped else "")))
    if n_resampled:
        dt = np.diff(t)
        worst = float(np.max(np.abs(dt * rate - 1.0)))
        steps.append(Step("resample", f"{n_resampled} of {len(pieces)} segment(s): time steps "
                                      f"{dt.min() * 1e3:.4g}–{dt.max() * 1e3:.4g} ms (up to "
                                      f"{worst:.1%} off {1e3 / rate:.4g} ms); resampled {n_in} → "
                                      f"{n_out} samples at {rate:.6g} Hz by cubic spline"))

    out_t, out_q, out_dq, out_ddq, out_tau, out_seg, out_sign = [], [], [], [], [], [], []
    if o.derivative == "fourier":
        ts, xs = pieces[0]
        mean, n_periods = period_average(xs, o.period, rate)
        harmonics = int(np.floor(cutoff * o.period + 1e-9))
        qf, dqf, ddqf = fourier_derivatives(mean[:, :nv], rate, o.period, harmonics)
        tauf = (fourier_derivatives(mean[:, nv:], rate, o.period, harmonics)[0]
                if o.filter_torque else mean[:, nv:])
        # the Coulomb column through the torque's filter (Dataset.dq_sign)
        signf = (fourier_derivatives(np.sign(dqf), rate, o.period, harmonics)[0]
                 if o.filter_torque else np.sign(dqf))
        p = mean.shape[0]
        steps.append(Step("fourier", f"averaged {n_periods} period(s) of {o.period:g} s "
                                     f"({p} samples; {xs.shape[0] - n_periods * p} trailing "
                                     f"samples unused), kept harmonics 1–{harmonics} "
                                     f"(≤ {cutoff:.4g} Hz) of q"
                                     f"{' and τ' if o.filter_torque else ''}, differentiated in "
                                     "the frequency domain"))
        out_t.append(ts[:p]), out_q.append(qf), out_dq.append(dqf), out_ddq.append(ddqf)
        out_tau.append(tauf), out_seg.append(np.zeros(p, dtype=int)), out_sign.append(signf)
    else:
        trim = TRIM_PERIODS / cutoff if o.trim is None else float(o.trim)
        both = " and τ" if o.filter_torque else ""
        if o.derivative == "central":
            steps.append(Step("low-pass", f"zero-phase Butterworth, order {o.order}, "
                                          f"{cutoff:.4g} Hz on q{both}; central differences of "
                                          "the filtered q"))
        else:
            window = savgol_window(cutoff, rate, o.polyorder)
            steps.append(Step("savitzky-golay", f"window {window} samples "
                                                f"({window / rate * 1e3:.4g} ms), order "
                                                f"{o.polyorder}, on q{both}"))
        too_short = 0
        for seg_id, (ts, xs) in enumerate(pieces):
            qs, taus = xs[:, :nv], xs[:, nv:]
            if o.derivative == "central":
                qf = lowpass(qs, cutoff, rate, o.order)
                dqf, ddqf = central_difference(qf, rate)
                tauf = lowpass(taus, cutoff, rate, o.order) if o.filter_torque else taus
                signf = (lowpass(np.sign(dqf), cutoff, rate, o.order) if o.filter_torque
                         else np.sign(dqf))
            else:
                qf, dqf, ddqf = savgol_derivatives(qs, rate, window, o.polyorder)
                tauf = (savgol_derivatives(taus, rate, window, o.polyorder)[0]
                        if o.filter_torque else taus)
                signf = (savgol_derivatives(np.sign(dqf), rate, window, o.polyorder)[0]
                         if o.filter_torque else np.sign(dqf))
            tol = 1e-3 / rate                   # float stamps (Unix seconds) are not exact
            keep = (ts >= ts[0] + trim - tol) & (ts <= ts[-1] - trim + tol)
            if not keep.any():
                too_short += 1
                continue
            out_t.append(ts[keep]), out_q.append(qf[keep]), out_dq.append(dqf[keep])
            out_ddq.append(ddqf[keep]), out_tau.append(tauf[keep])
            out_seg.append(np.full(int(keep.sum()), seg_id)), out_sign.append(signf[keep])
        if too_short:
            steps.append(Step("short segment", f"{too_short} segment(s) shorter than twice the "
                                               f"{trim:.3g} s trim dropped"))
        if trim > 0:
            steps.append(Step("trim", f"{trim:.4g} s cut at both ends of each segment (filter "
                                      "transients)"))
        if not out_t:
            raise DatasetError("every segment is shorter than twice the edge trim")

    arrays = [np.concatenate(a) for a in (out_t, out_q, out_dq, out_ddq, out_tau, out_seg,
                                          out_sign)]
    _warn_quasi_static(arrays[0], arrays[2], h, o.time_unit)
    if o.decimate > 1:
        keep = np.zeros(arrays[0].size, dtype=bool)
        for s in np.unique(arrays[5]):
            keep[np.flatnonzero(arrays[5] == s)[::o.decimate]] = True
        arrays = [a[keep] for a in arrays]
        rate = rate / o.decimate
        steps.append(Step("decimate", f"kept every {o.decimate}-th sample → {rate:.6g} Hz"))
    if o.min_speed is not None:
        keep = low_speed_mask(arrays[2], o.min_speed)
        if not keep.any():
            raise DatasetError(f"no sample has every joint faster than min_speed = "
                               f"{o.min_speed}")
        arrays = [a[keep] for a in arrays]
        steps.append(Step("low speed", f"dropped {int((~keep).sum())} of {keep.size} samples "
                                       f"where some |q̇| < {o.min_speed} rad/s"))
    for step in steps:
        LOG.info("%s", step)
    if not o.filter_torque:
        arrays[-1] = None          # unfiltered torques: the Coulomb column is sign(dq)
    return ChainResult(*arrays, tuple(steps), float(rate), float(cutoff), chosen, bandwidth, o)

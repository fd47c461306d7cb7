r"""From a robot log ``(t, q, τ)`` to a :class:`~consistid.data.dataset.Dataset`: time stamps, outliers,
zero-phase filtering, differentiation, sample selection.

Identification needs ``q̇`` and ``q̈``, which robots rarely log; they are estimated off line from
the measured positions with non-causal filters (Gautier 1997, "Dynamic identification of robots
with power model", ICRA, doi:10.1109/ROBOT.1997.614364; Swevers, Ganseman, Tükel, De Schutter,
Van Brussel 1997, "Optimal robot excitation and identification", IEEE T-RA 13(5),
doi:10.1109/70.631234). The building blocks, each usable alone:

:func:`lowpass`
    zero-phase Butterworth (``scipy.signal.sosfiltfilt``): the forward-backward filter's power
    (squared magnitude) is ``|H(f)|² = 1/(1 + (f/f_c)^{2n})²``, −6 dB in magnitude at ``f_c``;
    no phase lag.
:func:`central_difference`
    ``q̇_k = (q_{k+1} − q_{k−1}) / 2h``, ``q̈_k = (q_{k+1} − 2q_k + q_{k−1}) / h²``.
:func:`savgol_derivatives`
    Savitzky–Golay local polynomial fits (Savitzky & Golay 1964, Anal. Chem. 36(8),
    doi:10.1021/ac60214a047); the window whose −3 dB point is nearest the cut-off, found from
    the filter's frequency response starting at Schafer's rule
    ``f_c ≈ (p + 1) / (3.2 w − 4.6) · f_s`` (Schafer 2011, IEEE Signal Proc. Mag. 28(4),
    doi:10.1109/MSP.2011.941097), which alone puts it at 0.8–0.9 × the cut-off.
:func:`fourier_derivatives`
    for periodic excitations: average the whole periods, keep the harmonics below the cut-off,
    differentiate by multiplying harmonic ``k`` by ``(i k ω_f)`` (Swevers et al. 1997).
:func:`hampel`
    outlier rejection against a running median (Hampel 1974, JASA 69(346),
    doi:10.1080/01621459.1974.10482962).
:func:`low_speed_mask`
    drop samples where some joint moves slower than a threshold: around velocity reversals the
    Coulomb term switches sign and is badly described (De Luca's lecture notes, the seeds), which
    matters when friction is not modelled.
:func:`estimate_bandwidth`, :func:`default_cutoff`
    the excitation bandwidth from the position spectrum and the cut-off ``f_c = 10 ×
    bandwidth`` (Gautier's rule of thumb; with the few-Hz excitations of the seeds it gives their
    30 Hz at 1 kHz), at most 0.4 × the sampling rate.

:func:`preprocess` chains them and returns the :class:`Dataset` with the list of
:class:`Step` s it applied; :meth:`Dataset.from_recording` is its short form. The default chain:

1. **time stamps**: sort if needed; merge samples with duplicate time stamps (averaged); split at
   gaps longer than ``gap`` × the median step into segments; resample a segment whose steps
   vary by more than ``jitter`` (relative) onto a uniform grid at ``rate`` (default
   ``1 / median step``) with a cubic spline (C², so its derivatives are continuous);
2. **outliers**: a Hampel filter (window 11, 6 robust σ) on ``q`` and ``τ`` replaces spikes by
   the running median;
3. **filter and differentiate** (``derivative``):

   * ``"central"`` (default): the same zero-phase Butterworth (order 4) on ``q`` and ``τ``
     (parallel filtering, so the filter distorts both sides of ``τ = Y π`` alike), then central
     differences of the filtered ``q``;
   * ``"savgol"``: Savitzky–Golay smoothing of ``q`` (value, first, second derivative) and of
     ``τ`` (value), window from the cut-off;
   * ``"fourier"``: ``q`` and ``τ`` averaged over whole periods of ``period`` and truncated to
     the harmonics below the cut-off; the dataset is the one averaged period;
4. **edges**: ``trim`` seconds cut at both ends of each segment (default ``3 / f_c``; none for
   ``"fourier"``, which refuses a ``trim``), where the filters' transients sit;
5. optional **decimation** (``decimate``, after the low-pass, so it does not alias) and
   **low-speed removal** (``min_speed``).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import scipy.interpolate
import scipy.signal

from .dataset import Dataset
from ..errors import DatasetError, OptionError, check_option

LOG = logging.getLogger(__name__)

DERIVATIVES = ("central", "savgol", "fourier")
#: Cut-off = this × the excitation bandwidth (Gautier's rule of thumb).
CUTOFF_FACTOR = 10.0
#: The cut-off never exceeds this fraction of the sampling rate (0.8 × Nyquist).
MAX_CUTOFF_FRACTION = 0.4
#: Odd-reflection padding of :func:`lowpass`, in periods of the cut-off.
PAD_PERIODS = 6.0
#: Default edge trim, in periods of the cut-off: the transient of the reflected ends (the
#: padding flips the curvature) leaves ~1e-4 relative error in q̈ after it (Panda excitation).
TRIM_PERIODS = 3.0


@dataclass(frozen=True)
class Step:
    """One processing step applied by :func:`preprocess`: its name and what it did."""

    name: str
    detail: str

    def __str__(self) -> str:
        return f"{self.name}: {self.detail}"


@dataclass(frozen=True)
class Preprocessed:
    """The dataset made from a recording, and the record of how.

    Attributes
    ----------
    dataset : the :class:`Dataset` (one segment per gap-free stretch of the log).
    steps : the :class:`Step` s applied, in order.
    rate : sampling rate of the dataset (Hz), after resampling/decimation.
    cutoff : low-pass cut-off used (Hz).
    bandwidth : excitation bandwidth used to choose it (Hz; given or estimated), or ``None``
        when the cut-off was given.
    """

    dataset: Dataset
    steps: tuple[Step, ...]
    rate: float
    cutoff: float
    bandwidth: float | None

    def __str__(self) -> str:
        lines = [f"{len(self.steps)} steps → {self.dataset.n_samples} samples, "
                 f"{len(np.unique(self.dataset.segment))} segment(s) at {self.rate:.6g} Hz"]
        lines += [f"  {i + 1}. {s}" for i, s in enumerate(self.steps)]
        return "\n".join(lines)


# ------------------------------------------------------------------------------- building blocks
def _as_2d(name: str, x: np.ndarray) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2:
        raise DatasetError(f"{name} must be (N,) or (N, nv), got shape {a.shape}")
    return a


def lowpass(x: np.ndarray, cutoff: float, rate: float, order: int = 4) -> np.ndarray:
    """Zero-phase Butterworth low-pass along axis 0 (``scipy.signal.sosfiltfilt``).

    ``order`` is that of the one-way filter; run forward and backward, the magnitude is squared
    (``|H|² = 1/(1 + (f/f_c)^{2n})²``, −6 dB at ``f_c``) and the phase is zero. The ends are
    padded by odd reflection over ``6 / f_c`` seconds (scipy's default, 15 samples, leaves the
    initial-state transient in the data: 20× larger edge errors in ``q̈``).
    """
    if not 0 < cutoff < 0.5 * rate:
        raise OptionError(f"cutoff = {cutoff} Hz must lie in (0, {0.5 * rate:g}) Hz, below the "
                          f"Nyquist frequency of {rate:g} Hz sampling")
    sos = scipy.signal.butter(order, cutoff, fs=rate, output="sos")
    x = np.asarray(x, dtype=float)
    pad = min(int(np.ceil(PAD_PERIODS * rate / cutoff)), x.shape[0] - 1)
    return scipy.signal.sosfiltfilt(sos, x, axis=0, padlen=pad)


def central_difference(x: np.ndarray, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """First and second derivatives of uniformly sampled ``x`` by central differences.

    Interior: ``(x_{k+1} − x_{k−1})/2h`` and ``(x_{k+1} − 2x_k + x_{k−1})/h²`` (errors
    ``h² x'''/6`` and ``h² x''''/12``); second-order one-sided formulas at the two ends.
    """
    x = np.asarray(x, dtype=float)
    if x.shape[0] < 4:
        raise DatasetError(f"central differences need at least 4 samples, got {x.shape[0]}")
    h = 1.0 / rate
    dx = np.gradient(x, h, axis=0, edge_order=2)
    ddx = np.empty_like(x)
    ddx[1:-1] = (x[2:] - 2.0 * x[1:-1] + x[:-2]) / h ** 2
    ddx[0] = (2 * x[0] - 5 * x[1] + 4 * x[2] - x[3]) / h ** 2
    ddx[-1] = (2 * x[-1] - 5 * x[-2] + 4 * x[-3] - x[-4]) / h ** 2
    return dx, ddx


def savgol_cutoff(window: int, rate: float, polyorder: int = 3) -> float:
    """The −3 dB frequency (Hz) of the Savitzky–Golay smoother of ``window`` samples.

    Its weights are the centre value of the least-squares polynomial fit, ``e_0ᵀ V⁺`` with
    ``V`` the Vandermonde matrix of the window's sample offsets scaled to ``[−1, 1]`` (exact in
    floating point for any window length); the cut-off is the first frequency where the
    magnitude response falls to ``1/√2``, interpolated linearly on a grid of 2048 steps up to
    3 × Schafer's estimate, then up to Nyquist (Nyquist if it never falls that low).
    """
    x = np.linspace(-1.0, 1.0, window)
    weights = np.linalg.pinv(np.vander(x, polyorder + 1, increasing=True))[0]
    estimate = (polyorder + 1) * rate / max(3.2 * window - 4.6, 1e-9)
    for top in (min(3.0 * estimate, 0.5 * rate), 0.5 * rate):
        f = np.linspace(0.0, top, 2049)
        mag = np.abs(scipy.signal.freqz(weights, worN=f, fs=rate)[1])
        below = np.flatnonzero(mag < 1.0 / np.sqrt(2.0))
        if below.size:
            i = below[0]
            return float(f[i - 1] + (mag[i - 1] - 1.0 / np.sqrt(2.0)) / (mag[i - 1] - mag[i])
                         * (f[i] - f[i - 1]))
    return 0.5 * rate


def savgol_window(cutoff: float, rate: float, polyorder: int = 3) -> int:
    """The odd window length whose Savitzky–Golay smoother has its −3 dB point
    (:func:`savgol_cutoff`) closest to ``cutoff``.

    Schafer's rule ``w = ((p + 1) f_s / f_c + 4.6) / 3.2`` (Schafer 2011) alone puts the −3 dB
    point at 0.8–0.9 × ``cutoff`` (0.6–0.8 × below 25 samples); the window is rescaled by that
    ratio (the cut-off is nearly ∝ 1/w) and then moved by 2 while that brings it closer.
    """
    if not 0 < cutoff < 0.5 * rate:
        raise OptionError(f"cutoff = {cutoff} Hz must lie in (0, {0.5 * rate:g}) Hz")
    smallest = polyorder + 2 if polyorder % 2 else polyorder + 1      # odd, > polyorder

    def odd(n: float) -> int:
        k = max(int(round(n)), smallest)
        return k + 1 if k % 2 == 0 else k

    w = odd(((polyorder + 1) * rate / cutoff + 4.6) / 3.2)
    w = odd(w * savgol_cutoff(w, rate, polyorder) / cutoff)
    error = {}

    def miss(n: int) -> float:
        if n not in error:
            error[n] = abs(savgol_cutoff(n, rate, polyorder) - cutoff)
        return error[n]

    for step in (2, -2):
        while w + step >= smallest and miss(w + step) < miss(w):
            w += step
    return w


def savgol_derivatives(x: np.ndarray, rate: float, window: int, polyorder: int = 3
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Smoothed value, first and second derivative by Savitzky–Golay fits along axis 0."""
    x = np.asarray(x, dtype=float)
    if window > x.shape[0]:
        raise DatasetError(f"Savitzky–Golay window {window} is longer than the {x.shape[0]} "
                           "samples")
    total = scipy.signal.savgol_coeffs(window, polyorder).sum()
    if not abs(total - 1.0) < 1e-6:        # scipy's weights break for long windows, high orders
        raise OptionError(f"scipy's Savitzky–Golay weights for {window} samples at order "
                          f"{polyorder} are numerically broken (they sum to {total:.3g}, not 1; "
                          "order 5 breaks beyond ~700 samples): use a lower polyorder, a higher "
                          "cut-off, or derivative='central'")
    kw = dict(window_length=window, polyorder=polyorder, axis=0, mode="interp")
    return (scipy.signal.savgol_filter(x, **kw),
            scipy.signal.savgol_filter(x, deriv=1, delta=1.0 / rate, **kw),
            scipy.signal.savgol_filter(x, deriv=2, delta=1.0 / rate, **kw))


def samples_per_period(period: float, rate: float) -> int:
    """``period × rate`` as an integer; raises :class:`DatasetError` unless it is one."""
    p = period * rate
    if abs(p - round(p)) > 1e-6 * max(p, 1.0) or round(p) < 4:
        raise DatasetError(f"period × rate = {period} s × {rate} Hz = {p:.9g} samples: "
                           "frequency-domain processing needs a whole number (≥ 4) of samples "
                           "per period")
    return int(round(p))


def period_average(x: np.ndarray, period: float, rate: float) -> tuple[np.ndarray, int]:
    """The mean over the whole periods of ``x`` (from its first sample), ``(P, ...)``, and the
    number of periods averaged. Trailing samples of an incomplete period are left out."""
    p = samples_per_period(period, rate)
    n = x.shape[0] // p
    if n < 1:
        raise DatasetError(f"the log has {x.shape[0]} samples, less than one period ({p})")
    return x[:n * p].reshape(n, p, *x.shape[1:]).mean(axis=0), n


def fourier_derivatives(x: np.ndarray, rate: float, period: float, harmonics: int
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r"""Band-limited value, first and second derivative of one period of a periodic signal.

    ``x`` is one period (e.g. from :func:`period_average`), ``P`` samples. With its DFT
    ``X_k``, harmonics ``k > harmonics`` are zeroed and

    .. math:: \dot x = \mathcal F^{-1}[(i k \omega_f) X_k], \quad
              \ddot x = \mathcal F^{-1}[-(k \omega_f)^2 X_k], \quad \omega_f = 2\pi/T

    (the Nyquist bin, if kept, is dropped from the derivatives: its sign is ambiguous).
    """
    x = np.asarray(x, dtype=float)
    p = x.shape[0]
    if harmonics < 1:
        raise OptionError(f"harmonics = {harmonics}; keep at least the fundamental")
    spec = np.fft.rfft(x, axis=0)
    k = np.arange(spec.shape[0])
    keep = k <= harmonics
    shape = (-1,) + (1,) * (x.ndim - 1)
    spec = spec * keep.reshape(shape)
    iw = (1j * 2 * np.pi / period * k).reshape(shape)
    if p % 2 == 0 and keep[-1]:
        dspec = spec.copy()
        dspec[-1] = 0
    else:
        dspec = spec
    return (np.fft.irfft(spec, n=p, axis=0), np.fft.irfft(iw * dspec, n=p, axis=0),
            np.fft.irfft(iw ** 2 * dspec, n=p, axis=0))


def hampel(x: np.ndarray, window: int = 11, n_sigma: float = 6.0
           ) -> tuple[np.ndarray, np.ndarray]:
    r"""Replace outliers by the running median; returns ``(cleaned, outlier mask)``.

    Sample ``k`` of a channel is an outlier when ``|x_k − m_k| > n_σ · s_k``, with ``m_k`` the
    median of the ``window`` samples centred on ``k`` and ``s_k = max(1.4826 · median_j |x_j −
    m_k|, s_min)`` over the same samples (the local MAD); ``s_min`` is the smallest non-zero
    step between consecutive samples of the channel, so that on a flat stretch of an encoder
    signal one count is not an outlier. A smooth signal is never flagged (at an extremum the
    ratio is about 1).
    """
    x = _as_2d("x", x)
    if window < 3 or window % 2 == 0:
        raise OptionError(f"hampel window = {window}; it must be odd and ≥ 3")
    if x.shape[0] < window:
        raise DatasetError(f"hampel needs at least window = {window} samples, got {x.shape[0]}")
    half = window // 2
    padded = np.pad(x, ((half, half), (0, 0)), mode="reflect")
    win = np.lib.stride_tricks.sliding_window_view(padded, window, axis=0)  # (N, nv, window)
    med = np.median(win, axis=2)
    scale = 1.4826 * np.median(np.abs(win - med[:, :, None]), axis=2)
    steps = np.abs(np.diff(x, axis=0))
    floor = np.array([np.min(s[s > 0]) if np.any(s > 0) else 0.0 for s in steps.T])
    mask = np.abs(x - med) > n_sigma * np.maximum(scale, floor)
    return np.where(mask, med, x), mask


def low_speed_mask(dq: np.ndarray, threshold: float | Sequence[float]) -> np.ndarray:
    """``True`` for the samples to keep: every joint's ``|q̇|`` at least ``threshold`` (rad/s,
    scalar or per joint)."""
    dq = _as_2d("dq", dq)
    thr = np.broadcast_to(np.asarray(threshold, dtype=float), (dq.shape[1],))
    return np.all(np.abs(dq) >= thr, axis=1)


def estimate_bandwidth(q: np.ndarray, rate: float, fraction: float = 0.9999) -> float:
    """The excitation bandwidth (Hz): the frequency below which ``fraction`` of the power of
    every joint's detrended, Hann-windowed position lies (the largest over joints).

    Positions are used, not velocities: their noise is tiny compared with the motion.
    """
    q = _as_2d("q", q)
    if q.shape[0] < 16:
        raise DatasetError(f"{q.shape[0]} samples are too few to estimate a bandwidth")
    x = scipy.signal.detrend(q, axis=0) * np.hanning(q.shape[0])[:, None]
    power = np.abs(np.fft.rfft(x, axis=0)) ** 2
    freqs = np.fft.rfftfreq(q.shape[0], 1.0 / rate)
    total = power.sum(axis=0)
    moving = total > 0
    if not moving.any():
        raise DatasetError("the positions do not move: no excitation bandwidth")
    cum = np.cumsum(power[:, moving], axis=0) / total[moving]
    idx = np.argmax(cum >= fraction, axis=0)
    return float(max(freqs[idx].max(), freqs[1]))


def default_cutoff(bandwidth: float, rate: float) -> float:
    """``min(10 × bandwidth, 0.4 × rate)`` (Hz)."""
    if not bandwidth > 0:
        raise OptionError(f"bandwidth = {bandwidth} Hz must be positive")
    return float(min(CUTOFF_FACTOR * bandwidth, MAX_CUTOFF_FRACTION * rate))


# ------------------------------------------------------------------------------- time stamps
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


def long_steps(t: np.ndarray, factor: float) -> tuple[np.ndarray, float]:
    """Gaps: the indices ``k`` of the steps ``t_{k+1} − t_k`` longer than ``factor`` × the
    median step, and that limit (s)."""
    dt = np.diff(t)
    limit = factor * np.median(dt)
    return np.flatnonzero(dt > limit), limit


def _fix_time(t: np.ndarray, x: np.ndarray, duplicate_tol: float, steps: list[Step]
              ) -> tuple[np.ndarray, np.ndarray]:
    """Sort and merge duplicate time stamps (rows averaged)."""
    if np.any(np.diff(t) < 0):
        order = np.argsort(t, kind="stable")
        moved = int(np.sum(order != np.arange(t.size)))
        t, x = t[order], x[order]
        steps.append(Step("sort", f"{moved} samples were out of time order; sorted by time"))
    dt = np.diff(t)
    positive = dt[dt > 0]
    if positive.size == 0:
        raise DatasetError("all time stamps are equal")
    tol = duplicate_tol * np.median(positive)
    group = duplicate_groups(t, tol)
    n_dup = t.size - 1 - int(group[-1])
    if n_dup:
        t, x = group_mean(t, group), group_mean(x, group)
        steps.append(Step("duplicates", f"{n_dup} samples shared a time stamp (within "
                                        f"{tol:.3g} s) with the previous one; merged by averaging"))
    return t, x


def _segments(t: np.ndarray, gap: float, steps: list[Step]) -> list[slice]:
    cuts, limit = long_steps(t, gap)
    cuts = cuts + 1
    if cuts.size:
        steps.append(Step("gaps", f"{cuts.size} gap(s) longer than {limit:.4g} s (at t = "
                                  f"{', '.join(f'{t[c - 1]:.4g}' for c in cuts[:5])}"
                                  f"{', …' if cuts.size > 5 else ''}); split into "
                                  f"{cuts.size + 1} segments"))
    edges = [0, *cuts.tolist(), t.size]
    return [slice(a, b) for a, b in zip(edges[:-1], edges[1:])]


def _uniform(t: np.ndarray, x: np.ndarray, rate: float, jitter: float, label: str,
             steps: list[Step]) -> tuple[np.ndarray, np.ndarray]:
    """The segment on a uniform grid at ``rate`` (cubic spline) if its steps vary by more than
    ``jitter``; refuses to go more than 1 % below the segment's own rate (a spline does not
    low-pass first, so that would alias)."""
    dt = np.diff(t)
    own = 1.0 / float(np.median(dt))
    if rate < 0.99 * own:
        raise OptionError(f"{label}: resampling from its {own:.6g} Hz to rate = {rate:.6g} Hz by "
                          "spline would alias (nothing low-passes before it); resample at the "
                          "log's rate and reduce it with decimate=, which comes after the "
                          "low-pass")
    h = 1.0 / rate
    worst = float(np.max(np.abs(dt / h - 1.0)))
    if worst <= jitter:
        return t, x
    n = int(np.floor((t[-1] - t[0]) * rate + 1e-9)) + 1
    grid = t[0] + np.arange(n) * h
    x_new = scipy.interpolate.CubicSpline(t, x, axis=0)(grid)
    steps.append(Step("resample", f"{label}: time steps {dt.min() * 1e3:.4g}–{dt.max() * 1e3:.4g}"
                                  f" ms (up to {worst:.1%} off {h * 1e3:.4g} ms); resampled "
                                  f"{t.size} → {n} samples at {rate:.6g} Hz by cubic spline"))
    return grid, x_new


# ------------------------------------------------------------------------------- the chain
def preprocess(t: np.ndarray, q: np.ndarray, tau: np.ndarray, *,
               derivative: str = "central", cutoff: float | None = None,
               bandwidth: float | None = None, order: int = 4, period: float | None = None,
               rate: float | None = None, outliers: float | None = 6.0,
               outlier_window: int = 11, trim: float | None = None,
               min_speed: float | Sequence[float] | None = None, decimate: int = 1,
               gap: float = 5.0, jitter: float = 1e-3, duplicate_tol: float = 1e-6,
               filter_torque: bool = True, polyorder: int = 5,
               joint_names: Sequence[str] | None = None) -> Preprocessed:
    """Turn a log ``(t, q, τ)`` into a :class:`Dataset` by the documented chain (module notes).

    Parameters
    ----------
    t : (N,) time stamps (s), any order, possibly duplicated, jittered or with gaps.
    q, tau : (N, nv) measured positions (rad / m) and torques (N·m / N).
    derivative : ``"central"`` (Butterworth + central differences), ``"savgol"`` or
        ``"fourier"`` (periodic excitation of ``period`` s; averages whole periods).
    cutoff : low-pass cut-off (Hz). Default :func:`default_cutoff` of ``bandwidth``.
    bandwidth : excitation bandwidth (Hz), e.g. ``harmonics / period`` of a Fourier excitation;
        default :func:`estimate_bandwidth` of the positions.
    order : Butterworth order (one direction).
    period : the excitation period (s), needed by ``derivative="fourier"``.
    rate : sampling rate to resample jittered time stamps to; default ``1 / median Δt`` (to 9
        significant digits). Not below a segment's own rate (that would alias): use
        ``decimate`` to lower the rate.
    outliers : Hampel threshold in robust σ, or ``None`` to skip outlier rejection.
    outlier_window : Hampel window (odd, samples).
    trim : seconds dropped at both ends of each segment; default ``3 / cutoff``. Not with
        ``"fourier"``, whose result is one averaged period (no edges).
    min_speed : drop samples where some joint's ``|q̇|`` is below this (rad/s, scalar or per
        joint); default keep all.
    decimate : keep every ``decimate``-th sample after filtering; the cut-off must stay below
        the new Nyquist frequency.
    gap : a time step longer than ``gap`` × the median step splits the log into segments.
    jitter : relative spread of time steps above which a segment is resampled.
    duplicate_tol : steps shorter than this × the median step count as duplicate stamps.
    filter_torque : low-pass the torques with the same filter as the positions.
    polyorder : Savitzky–Golay polynomial order.
    joint_names : carried into the dataset.

    Returns
    -------
    Preprocessed
        ``.dataset``, and ``.steps``: what was done (also logged at INFO level on the
        ``consistid.data.signals`` logger).

    Raises
    ------
    DatasetError : bad shapes, non-finite values (named by index), too few samples, a period
        that is not a whole number of samples. OptionError : bad options.
    """
    check_option("derivative", derivative, DERIVATIVES)
    t = np.asarray(t, dtype=float)
    if t.ndim != 1:
        raise DatasetError(f"t must be 1-D (N,), got shape {t.shape}")
    q, tau = _as_2d("q", q), _as_2d("tau", tau)
    for name, a in (("t", t[:, None]), ("q", q), ("tau", tau)):
        if a.shape[0] != t.shape[0]:
            raise DatasetError(f"{name} has {a.shape[0]} samples; t has {t.shape[0]}")
        bad = np.argwhere(~np.isfinite(a))
        if bad.size:
            raise DatasetError(f"{name}[{bad[0][0]}{'' if name == 't' else f', {bad[0][1]}'}] "
                               f"is {a[tuple(bad[0])]} ({len(bad)} non-finite value(s))")
    if q.shape[1] != tau.shape[1]:
        raise DatasetError(f"q has {q.shape[1]} joints, tau has {tau.shape[1]}")
    if decimate < 1 or int(decimate) != decimate:
        raise OptionError(f"decimate = {decimate}; it must be a positive integer")
    if derivative == "fourier" and trim:
        raise OptionError(f"trim = {trim} s does not apply to derivative='fourier': its dataset "
                          "is one averaged period, which has no filter edges")
    nv = q.shape[1]
    steps: list[Step] = []
    t, x = _fix_time(t, np.hstack([q, tau]), duplicate_tol, steps)
    segments = _segments(t, gap, steps)
    h_med = float(np.median(np.diff(t)))
    # 9 significant digits: 1/median(Δt) of np.arange(n)/1000 is 999.9999999999991
    rate = float(rate) if rate is not None else float(f"{1.0 / h_med:.9g}")
    if derivative == "fourier" and len(segments) > 1:
        raise DatasetError("derivative='fourier' needs one gap-free log; this one has "
                           f"{len(segments)} segments")

    pieces = []
    for i, seg in enumerate(segments):
        ts, xs = t[seg], x[seg]
        if ts.size < 16:
            steps.append(Step("short segment", f"segment {i} ({ts.size} samples) dropped"))
            continue
        pieces.append(_uniform(ts, xs, rate, jitter, f"segment {i}", steps))
    if not pieces:
        raise DatasetError("no segment of the log has 16 samples or more")

    if outliers is not None:
        total = np.zeros(2 * nv, dtype=int)
        cleaned = []
        for ts, xs in pieces:
            xs, mask = hampel(xs, outlier_window, outliers)
            total += mask.sum(axis=0)
            cleaned.append((ts, xs))
        pieces = cleaned
        if total.any():
            where = ", ".join(f"{'q' if c < nv else 'tau'}[{c % nv}]: {n}"
                              for c, n in enumerate(total) if n)
            steps.append(Step("outliers", f"Hampel ({outlier_window} samples, {outliers:g} σ) "
                                          f"replaced {int(total.sum())} sample(s) by the running"
                                          f" median ({where})"))
        else:
            steps.append(Step("outliers", f"Hampel ({outlier_window} samples, {outliers:g} σ): "
                                          "none found"))

    if cutoff is None:
        if bandwidth is None:
            longest = max(pieces, key=lambda p: p[0].size)
            bandwidth = estimate_bandwidth(longest[1][:, :nv], rate)
            origin = "estimated from the position spectrum (99.99 % of the power)"
        else:
            origin = "given"
        cutoff = default_cutoff(bandwidth, rate)
        steps.append(Step("cut-off", f"{cutoff:.4g} Hz = min({CUTOFF_FACTOR:g} × bandwidth "
                                     f"{bandwidth:.4g} Hz ({origin}), {MAX_CUTOFF_FRACTION:g} × "
                                     f"{rate:.6g} Hz)"))
    else:
        bandwidth = None
        steps.append(Step("cut-off", f"{cutoff:.4g} Hz (given)"))
    if decimate > 1 and cutoff >= 0.5 * rate / decimate:
        raise OptionError(f"decimate = {decimate} brings the Nyquist frequency to "
                          f"{0.5 * rate / decimate:.4g} Hz, below the {cutoff:.4g} Hz cut-off: "
                          "the decimated signal would alias")

    out_t, out_q, out_dq, out_ddq, out_tau, out_seg = [], [], [], [], [], []
    if derivative == "fourier":
        if period is None:
            raise OptionError("derivative='fourier' needs the excitation period (s)")
        ts, xs = pieces[0]
        mean, n_periods = period_average(xs, period, rate)
        harmonics = int(np.floor(cutoff * period + 1e-9))
        qf, dqf, ddqf = fourier_derivatives(mean[:, :nv], rate, period, harmonics)
        tauf = fourier_derivatives(mean[:, nv:], rate, period, harmonics)[0] if filter_torque \
            else mean[:, nv:]
        p = mean.shape[0]
        steps.append(Step("fourier", f"averaged {n_periods} period(s) of {period:g} s "
                                     f"({p} samples; {xs.shape[0] - n_periods * p} trailing "
                                     f"samples unused), kept harmonics 1–{harmonics} "
                                     f"(≤ {cutoff:.4g} Hz) of q{' and τ' if filter_torque else ''}"
                                     ", differentiated in the frequency domain"))
        out_t.append(ts[:p]), out_q.append(qf), out_dq.append(dqf), out_ddq.append(ddqf)
        out_tau.append(tauf), out_seg.append(np.zeros(p, dtype=int))
    else:
        trim = TRIM_PERIODS / cutoff if trim is None else trim
        if derivative == "central":
            steps.append(Step("low-pass", f"zero-phase Butterworth, order {order}, {cutoff:.4g} Hz"
                                          f" on q{' and τ' if filter_torque else ''}; central "
                                          "differences of the filtered q"))
        else:
            window = savgol_window(cutoff, rate, polyorder)
            steps.append(Step("savitzky-golay", f"window {window} samples "
                                                f"({window / rate * 1e3:.4g} ms), order "
                                                f"{polyorder}, on q{' and τ' if filter_torque else ''}"))
        for seg_id, (ts, xs) in enumerate(pieces):
            qs, taus = xs[:, :nv], xs[:, nv:]
            if derivative == "central":
                qf = lowpass(qs, cutoff, rate, order)
                dqf, ddqf = central_difference(qf, rate)
                tauf = lowpass(taus, cutoff, rate, order) if filter_torque else taus
            else:
                qf, dqf, ddqf = savgol_derivatives(qs, rate, window, polyorder)
                tauf = (savgol_derivatives(taus, rate, window, polyorder)[0] if filter_torque
                        else taus)
            keep = (ts >= ts[0] + trim - 1e-12) & (ts <= ts[-1] - trim + 1e-12)
            if not keep.any():
                steps.append(Step("short segment", f"segment {seg_id} ({ts[-1] - ts[0]:.3g} s) "
                                                   f"is shorter than twice the {trim:.3g} s trim;"
                                                   " dropped"))
                continue
            out_t.append(ts[keep]), out_q.append(qf[keep]), out_dq.append(dqf[keep])
            out_ddq.append(ddqf[keep]), out_tau.append(tauf[keep])
            out_seg.append(np.full(int(keep.sum()), seg_id))
        if trim > 0:
            steps.append(Step("trim", f"{trim:.4g} s cut at both ends of each segment (filter "
                                      "transients)"))
        if not out_t:
            raise DatasetError("every segment is shorter than twice the edge trim")

    data = Dataset(t=np.concatenate(out_t), q=np.concatenate(out_q),
                   dq=np.concatenate(out_dq), ddq=np.concatenate(out_ddq),
                   tau=np.concatenate(out_tau), segment=np.concatenate(out_seg),
                   joint_names=tuple(joint_names) if joint_names is not None else None)
    if decimate > 1:
        keep = np.zeros(data.n_samples, dtype=bool)
        for s in np.unique(data.segment):
            keep[np.flatnonzero(data.segment == s)[::decimate]] = True
        data = data.select(keep)
        rate = rate / decimate
        steps.append(Step("decimate", f"kept every {decimate}-th sample → {rate:.6g} Hz"))
    if min_speed is not None:
        keep = low_speed_mask(data.dq, min_speed)
        if not keep.any():
            raise DatasetError(f"no sample has every joint faster than min_speed = {min_speed}")
        data = data.select(keep)
        steps.append(Step("low speed", f"dropped {int((~keep).sum())} of {keep.size} samples "
                                       f"where some |q̇| < {min_speed} rad/s"))
    for step in steps:
        LOG.info("%s", step)
    return Preprocessed(data, tuple(steps), rate, float(cutoff), bandwidth)

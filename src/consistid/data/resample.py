r"""The one resampler: signals at irregular stamps onto a uniform grid (and back), and the rate a
log supports.

Every part of consistid that needs a uniform time grid — the signal chain before its filters,
the diagnosis's spectra and derivatives, the shift of interval-averaged torques to their
centres — goes through :func:`resample` (or :func:`on_uniform_grid`), so that there is one
interpolation rule and one place that decides what rate a log can carry.

Interpolation (``method``)
    ``"spline"``: the not-a-knot cubic spline through the samples (``scipy.interpolate.
    CubicSpline``), C² so that derivatives taken afterwards are continuous; its error for a
    sinusoid of frequency ``f`` across a step ``h`` is ``O((2πfh)⁴)`` in value and
    ``O((2πfh)²)`` in the second derivative (de Boor 2001, *A Practical Guide to Splines*,
    ch. V). ``"linear"``: ``numpy.interp``, for quick looks and for signals that are not smooth.

Rate (:func:`supported_rate`)
    interpolation is not filtering: evaluating the spline on a grid *coarser* than the samples
    folds content above the new Nyquist frequency ``r/2`` down to ``r − f``. Sampled at
    ``ρ`` (one over the median step) and resampled at ``r ≥`` :data:`MIN_RATE_FRACTION` ``× ρ
    = 0.9 ρ``, whatever folds lands above ``r − ρ/2 ≥ 0.44 r``, beyond the signal chain's
    largest cut-off ``0.4 r`` (:data:`consistid.data.filters.MAX_CUTOFF_FRACTION`), where the
    low-pass removes it. Jitter (steps of 0.7–8.8 ms around a 1 ms median) does not raise the
    rate a log supports: the median step is the logger's clock, the scatter its timing noise.
"""

from __future__ import annotations

import numpy as np
import scipy.interpolate

from ..errors import DatasetError, OptionError, check_option

METHODS = ("spline", "linear")
#: A log sampled at ρ may be resampled down to this fraction of ρ (module docstring).
MIN_RATE_FRACTION = 0.9
#: Steps within this fraction of the median step set the nominal rate.
NEAR_MEDIAN = 0.1
#: A stretch shorter than this (samples) does not set the rate of a log whose rate changed.
MIN_STRETCH = 256


def uniform_grid(start: float, stop: float, rate: float) -> np.ndarray:
    """``start + k / rate`` for ``k = 0, 1, …`` up to ``stop`` (inclusive within 1e-9 step)."""
    if not rate > 0 or not np.isfinite(rate):
        raise OptionError(f"rate = {rate} Hz must be a positive finite number")
    n = int(np.floor((stop - start) * rate + 1e-9)) + 1
    return start + np.arange(max(n, 1)) / rate


def nominal_rate(t: np.ndarray) -> float:
    """The sampling rate of stamps ``t`` (Hz): one over the mean of the steps within
    :data:`NEAR_MEDIAN` of the median step (gaps, long steps and repeated stamps left out),
    to 7 significant digits.

    Not one over the median: stamps stored as float Unix seconds are quantised to 0.24 µs, and
    the median of such steps is off by up to that much (a 500 Hz log read as 499.977 Hz, its
    velocities 5e-5 too small); the mean of the near-median steps averages the quantisation out.
    """
    dt = np.diff(np.asarray(t, dtype=float))
    dt = dt[dt > 0]
    if dt.size == 0:
        raise DatasetError("fewer than two distinct time stamps: no sampling rate")
    k = (dt.size - 1) // 2
    med = float(np.partition(dt, k)[k])        # the lower median: a step of the log itself
    near = dt[np.abs(dt - med) <= NEAR_MEDIAN * med]
    return float(f"{1.0 / float(np.mean(near)):.7g}")


def supported_rate(pieces: list[np.ndarray]) -> tuple[float, str]:
    """The rate (Hz) a log made of the stamp arrays ``pieces`` (gap-free stretches) supports,
    and how it was chosen.

    The nominal rate of all steps together (:func:`nominal_rate`); if some long stretch (at least
    :data:`MIN_STRETCH` samples and a tenth of the log; short ones scatter by chance) is
    sampled faster than that by more than 1 / :data:`MIN_RATE_FRACTION` (a log whose rate
    changed), the fastest such stretch's rate, so that none is resampled below what it
    carries.
    """
    steps = np.concatenate([np.diff(p) for p in pieces if p.size > 1] or [np.zeros(0)])
    rate = nominal_rate(np.concatenate([[0.0], np.cumsum(steps)]))
    total = sum(p.size for p in pieces)
    own = [nominal_rate(p) for p in pieces if p.size >= max(MIN_STRETCH, 0.1 * total)]
    fastest = max(own, default=rate)
    if fastest * MIN_RATE_FRACTION > rate:
        return fastest, (f"{fastest:.7g} Hz, the fastest stretch's rate (the log's typical step "
                         f"gives {rate:.7g} Hz; a lower rate would fold that stretch's content)")
    return rate, f"{rate:.7g} Hz = 1 / mean of the steps within 10 % of the median"


def check_rate(rate: float, own: float, label: str) -> None:
    """Refuse resampling a stretch sampled at ``own`` Hz to ``rate`` below
    :data:`MIN_RATE_FRACTION` × ``own`` (it would alias; module docstring)."""
    if rate < MIN_RATE_FRACTION * own:
        raise OptionError(f"{label}: resampling from its {own:.6g} Hz to rate = {rate:.6g} Hz by "
                          f"interpolation would alias (below {MIN_RATE_FRACTION:g} × its rate; "
                          "nothing low-passes before it); resample at the log's rate and reduce "
                          "it with decimate=, which comes after the low-pass")


def resample(t: np.ndarray, x: np.ndarray, at: np.ndarray, method: str = "spline"
             ) -> np.ndarray:
    """``x`` sampled at stamps ``t`` (``(N,)``, strictly increasing), interpolated at ``at``
    (within ``[t[0], t[-1]]``: no extrapolation), along axis 0. ``x`` is ``(N,)`` or
    ``(N, ...)``."""
    check_option("method", method, METHODS)
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    at = np.asarray(at, dtype=float)
    if x.shape[0] != t.size:
        raise DatasetError(f"resample: x has {x.shape[0]} samples but t has {t.size}")
    if t.size < 2 or np.any(np.diff(t) <= 0):
        raise DatasetError("resample: stamps must be at least two and strictly increasing")
    span = 1e-9 * max(abs(t[-1] - t[0]), 1.0)
    if at.size and (at.min() < t[0] - span or at.max() > t[-1] + span):
        raise DatasetError(f"resample: asked for [{at.min():.6g}, {at.max():.6g}] s outside the "
                           f"samples' [{t[0]:.6g}, {t[-1]:.6g}] s (no extrapolation)")
    if method == "linear" or t.size < 4:
        flat = x.reshape(t.size, -1)
        out = np.column_stack([np.interp(at, t, c) for c in flat.T]) if flat.shape[1] else \
            np.zeros((at.size, 0))
        return out.reshape((at.size,) + x.shape[1:])
    return scipy.interpolate.CubicSpline(t, x, axis=0)(at)


def to_uniform(t: np.ndarray, x: np.ndarray, rate: float | None = None,
               method: str = "spline") -> tuple[np.ndarray, np.ndarray]:
    """``(grid, x on the grid)``: ``x`` resampled onto the uniform grid at ``rate`` (default
    :func:`nominal_rate`) from ``t[0]`` to ``t[-1]``."""
    rate = nominal_rate(t) if rate is None else float(rate)
    grid = uniform_grid(float(t[0]), float(t[-1]), rate)
    return grid, resample(t, x, grid, method)


def is_uniform(t: np.ndarray, tol: float = 1e-6) -> bool:
    """Whether the steps of ``t`` differ from each other by at most ``tol`` × the median."""
    dt = np.diff(np.asarray(t, dtype=float))
    return dt.size == 0 or float(np.ptp(dt)) <= tol * float(np.median(dt))


def on_uniform_grid(t: np.ndarray, x: np.ndarray, func, method: str = "linear") -> np.ndarray:
    """``func(x_grid, rate)`` computed on a uniform grid and interpolated back to the stamps
    ``t`` (``func`` must keep the grid's length along axis 0); on uniform stamps ``func(x,
    rate)`` directly. For filters and derivatives of a segment with jitter.

    The grid spans ``[t[0], t[-1]]`` exactly, with as many points as the nominal rate gives
    (its rate is within one sample per span of :func:`nominal_rate`), so that no stamp needs
    extrapolation.
    """
    t = np.asarray(t, dtype=float)
    if is_uniform(t):
        return func(np.asarray(x, dtype=float), 1.0 / float(np.median(np.diff(t))))
    span = float(t[-1] - t[0])
    n = max(int(round(span * nominal_rate(t))) + 1, 2)
    grid = np.linspace(t[0], t[-1], n)
    rate = (n - 1) / span
    yg = np.asarray(func(resample(t, x, grid, method), rate))
    return resample(grid, yg, t, method)

r"""Parallel filtering: one zero-phase low-pass applied alike to the torques and to every column
of the regressor before least squares (Gautier 1997, "Dynamic identification of robots with power
model", ICRA, doi:10.1109/ROBOT.1997.614364; Gautier & Poignet 2001, "Extended Kalman filtering
and weighted least squares dynamic identification of robot", Control Engineering Practice 9(12),
1361–1372: "parallel filtering and decimation").

Why. The positions are differentiated at a cut-off well above the motion's band
(:data:`~consistid.data.filters.CUTOFF_FACTOR` × it), because ``τ = Y(q, q̇, q̈) θ`` is nonlinear
in the motion: products of velocities and ``sin``/``cos`` of the angles put the torque's
harmonics past the band, and a low-pass on ``τ`` alone at 2–4 × the band removes what ``Y`` of
the filtered positions keeps (base parameters 10–100 × less accurate,
``benchmarks/cutoff.py --factors``). The noise that the wide cut-off lets through is removed
afterwards by a low-pass ``H`` on *both* sides: with ``H`` linear,

.. math:: H\tau = H(Y\theta + e) = (HY)\,\theta + He,

so least squares on ``(HY, Hτ)`` is unbiased whatever ``Y`` holds above the cut-off (the Coulomb
column ``sign(q̇)`` included: a torque-only low-pass at 3.5 × the band biased it 7–11 %), and
the noise ``He`` keeps only the band ``[0, f_p]``.

The cut-off :func:`parallel_cutoff` is :data:`PARALLEL_FACTOR` × the motion's band: at 3 × the
band of a 5-harmonic excitation, 0.5–3 % of the power of the columns of ``Y`` (rigid body,
viscous) lies above it on the Panda, UR5 and xArm7 and 10⁻⁷ on the Kinova; the Coulomb
column's step keeps ~10 % above it at any cut-off (its spectrum falls as ``1/f²``), which the
same filter on ``τ`` matches. The noise's power falls by ``f_d / f_p`` ≈ 3.3. With the band
estimated 1.04–1.07 × the true one (:func:`~consistid.data.filters.estimate_bandwidth`), the
chosen cut-off is 3.1–3.2 × the true band, within the ``[1, 4]`` asked of it with room for an
estimate a third too high.

How. :func:`plan` cuts a dataset into *runs* (samples of one recording segment, evenly spaced:
a step more than :data:`RUN_STEP` × the segment's median step, where a selection left a hole,
starts a new run) and each run into *windows*: a core of at least ``chunk`` samples read with
:func:`pad_samples` more on each side within the run. A window filtered alone
(:func:`~consistid.data.filters.lowpass_columns`) gives its core the numbers of the whole run
filtered at once to ``10⁻⁸`` of the signal (the zero-phase impulse response's tail beyond
:data:`PAD_PERIODS` periods of the cut-off holds less than ``10⁻⁸`` of its absolute sum:
7.4 periods measured for order 4), so memory is ``O(max(chunk, rate / f_p))`` rows whatever the
length of the log (a 1.6 Hz cut-off at 2 kHz: windows of 40 000 samples, 160 MB of Panda
regressor). Any window, padded or not, is a linear filter applied alike to both sides, which
biases nothing; the padding makes the rows near a window's seam those of the whole run.
Without a cut-off the windows are the plain chunks ``range(0, N, chunk)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator

import numpy as np

from ..errors import DatasetError, OptionError
from .filters import lowpass_columns

#: Identification cut-off = this × the excitation bandwidth (module docstring).
PARALLEL_FACTOR = 3.0
#: A window reads this many periods of the cut-off beyond its core on each side (module
#: docstring: the order-4 zero-phase impulse response's tail beyond it is below 10⁻⁸).
PAD_PERIODS = 8.0
#: A step longer than this × the segment's median step starts a new run (a hole left by a
#: selection of samples).
RUN_STEP = 1.5
#: Runs shorter than this, or whose rate puts the cut-off above 0.45 × it, are left unfiltered
#: (on both sides alike, which biases nothing either).
MIN_RUN = 16
#: The core of a filtered window is at least this many × :func:`pad_samples`, so that the padding
#: costs at most the regressor's work again (memory: windows of ``(2 + 2) × pad`` samples).
CORE_PADS = 2


def parallel_cutoff(bandwidth: float, derivative_cutoff: float) -> float:
    """``min(PARALLEL_FACTOR × bandwidth, derivative_cutoff)`` (Hz): never above the cut-off at
    which the positions were differentiated and the torques filtered."""
    if not bandwidth > 0:
        raise OptionError(f"bandwidth = {bandwidth} Hz must be positive")
    return float(min(PARALLEL_FACTOR * bandwidth, derivative_cutoff))


#: The highest Butterworth order a recorded filter may claim (a zero-phase filter of this order
#: already rolls off at 2·MAX_ORDER·20 dB/decade; a higher one is a corrupt file, and scipy
#: would build it for minutes).
MAX_ORDER = 32


def check_filter(name: str, value: object) -> tuple[float, int]:
    """A ``(cut-off Hz, order)`` pair as floats/int, or :class:`DatasetError` naming ``name``."""
    try:
        cutoff, order = (float(v) for v in value)            # type: ignore[union-attr]
    except (TypeError, ValueError):
        raise DatasetError(f"{name} = {value!r:.60} is not a (cut-off Hz, order) pair") from None
    if not (np.isfinite(cutoff) and cutoff > 0 and 1 <= order <= MAX_ORDER
            and order == int(order)):
        raise DatasetError(f"{name} = {value!r:.60}: the cut-off must be a positive number of "
                           f"Hz and the order a whole number from 1 to {MAX_ORDER}")
    return cutoff, int(order)


def pad_samples(cutoff: float, rate: float) -> int:
    """Samples read beyond a window's core on each side: :data:`PAD_PERIODS` periods of the
    cut-off."""
    return int(np.ceil(PAD_PERIODS * rate / cutoff))


def runs(t: np.ndarray, segment: np.ndarray) -> list[slice]:
    """The runs of a dataset's samples (module docstring): index ranges within one segment
    label, without a step beyond :data:`RUN_STEP` × that stretch's median step."""
    n = t.size
    cuts = np.flatnonzero(segment[1:] != segment[:-1]) + 1
    edges = [0, *cuts.tolist(), n]
    out = []
    for a, b in zip(edges[:-1], edges[1:]):
        if b - a > 2:
            dt = np.diff(t[a:b])
            holes = (np.flatnonzero(dt > RUN_STEP * np.median(dt)) + 1 + a).tolist()
        else:
            holes = []
        bounds = [a, *holes, b]
        out += [slice(x, y) for x, y in zip(bounds[:-1], bounds[1:])]
    return out


@dataclass(frozen=True)
class Window:
    """Samples read together: ``rows`` of the dataset, of which ``core`` (relative to ``rows``)
    are kept; filtered at ``rate`` (Hz), or not at all (``rate is None``)."""

    rows: slice
    core: slice
    rate: float | None

    @property
    def kept(self) -> slice:
        """The kept samples as a slice of the dataset."""
        return slice(self.rows.start + self.core.start, self.rows.start + self.core.stop)

    def apply(self, x: np.ndarray, cutoff: float | None, order: int = 4) -> np.ndarray:
        """``x`` (the window's rows, along axis 0) low-passed at ``cutoff`` when the window is
        filtered, then its core."""
        if self.rate is None or cutoff is None:
            return x[self.core]
        flat = x.reshape(x.shape[0], -1)
        return lowpass_columns(flat, cutoff, self.rate, order)[self.core].reshape(
            (self.core.stop - self.core.start,) + x.shape[1:])


def plan(t: np.ndarray, segment: np.ndarray, cutoff: float | None, chunk: int
         ) -> Iterator[Window]:
    """The windows that cover every sample once by their cores, in order (module docstring);
    ``cutoff`` ``None``: the chunks ``range(0, N, chunk)``, unfiltered."""
    n = t.size
    if cutoff is None:
        for start in range(0, n, chunk):
            stop = min(start + chunk, n)
            yield Window(slice(start, stop), slice(0, stop - start), None)
        return
    for run in runs(t, segment):
        size = run.stop - run.start
        rate = 1.0 / float(np.median(np.diff(t[run]))) if size > 1 else None
        if size < MIN_RUN or rate is None or cutoff >= 0.45 * rate:
            for start in range(run.start, run.stop, chunk):
                stop = min(start + chunk, run.stop)
                yield Window(slice(start, stop), slice(0, stop - start), None)
            continue
        pad = pad_samples(cutoff, rate)
        core = max(chunk, CORE_PADS * pad)
        for start in range(run.start, run.stop, core):
            stop = min(start + core, run.stop)
            a, b = max(run.start, start - pad), min(run.stop, stop + pad)
            yield Window(slice(a, b), slice(start - a, stop - a), rate)


def lowpass_runs(t: np.ndarray, segment: np.ndarray, x: np.ndarray, cutoff: float | None,
                 order: int = 4) -> np.ndarray:
    """``x`` (N, ...) low-passed at ``cutoff`` per run (:func:`runs`; runs :func:`plan` leaves
    unfiltered stay as they are); ``cutoff`` ``None``: ``x`` itself. Whole runs at once: for
    arrays already in memory (a residual), where windows would save nothing."""
    if cutoff is None:
        return x
    out = np.array(x, dtype=float, copy=True)
    for run in runs(t, segment):
        size = run.stop - run.start
        if size < MIN_RUN:
            continue
        rate = 1.0 / float(np.median(np.diff(t[run])))
        if cutoff < 0.45 * rate:
            out[run] = Window(slice(0, size), slice(0, size), rate).apply(x[run], cutoff, order)
    return out

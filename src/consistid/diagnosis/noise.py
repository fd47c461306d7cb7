r"""The torque noise floor, estimated without the candidate effects.

The diagnosis compares what its effects leave with the noise of the torque channel. That floor
must not come from the candidates: a floor taken as "what every candidate together leaves"
contains the very residual an effect outside the library produces, and hides it. Three sources,
in this order of preference (:func:`estimate_noise_floor` says which one each joint used):

``given``
    ``sigma=`` from the user (a data sheet, a log at rest), or a sensor resolution ``Δ``
    (``torque_resolution=``: a quantiser adds ``Δ/√12``; Widrow 1956, doi:10.1109/TCT.1956.1086334),
    whichever is larger per joint.
``repetition``
    A periodic excitation (the usual case: Fourier series, Swevers et al. 1997,
    doi:10.1109/70.631234) repeats its motion, so every effect that is a function of the state
    repeats too, and ``d(t) = τ(t + P) − τ(t)`` is the difference of two independent noise
    samples: ``σ² = Var(d) / 2``, whatever the noise's colour or filtering (as long as ``P`` is
    much longer than the noise's correlation time); with three periods, second differences
    ``τ(t+2P) − 2τ(t+P) + τ(t)`` (variance ``6σ²``) also cancel a torque whose size drifts
    linearly (friction warming in over the log). The period ``P`` is found on the joint
    positions (:func:`find_period`): the smallest whole number of samples after which ``q``
    repeats to within :data:`REPEAT_TOLERANCE` of its variance, on the longest recording; every
    recording is differenced at its own ``round(P / h)`` samples (logs resampled at other rates
    line up in time), and one whose ``q`` does not repeat after ``P`` is left out. Needs two
    periods within one recording; recordings without are estimated as below. A torque that
    repeats neither with the excitation nor is noise (a disturbance at a frequency of its own, a
    load changed during the log) enters ``d`` as well: where the spectrum below sees the noise
    level and the repetition floor exceeds it by more than the two estimates' joint error
    (:data:`MAX_FLOOR_RATIO`), the floor is the spectral one, and the description says that the
    torque does not repeat (the remainder then shows the component, not a floor that hides it).
``spectrum``
    The residual's Welch spectrum above the motion band (Welch 1967,
    doi:10.1109/TAU.1967.1161901): white noise has a flat level ``S₀``; torques a zero-phase
    Butterworth low-pass filtered show it rolling off. The model
    ``S(f) = S₀ (1 + (f/f_c)^{2n})^{-2}`` (the chain's ``sosfiltfilt``, forward and backward) is
    fitted to the log-spectrum on ``[2 f_s, 0.9 f_N]`` (``f_s``: the band holding 99.9 % of the
    nominal torque's power) with a robust (soft-L1) loss, and

    .. math::  \hat\sigma^2 = S_0 \int_0^{f_N} (1 + (f/f_c)^{2n})^{-2}\, df .

    It cannot see noise coloured or filtered *below* ``2 f_s``: when the fitted cut-off lies
    there the estimate is flagged unreliable (pass ``sigma``).
``spectrum`` through a known filter
    When the dataset records the low-pass the signal chain applied to its torques
    (:attr:`consistid.Dataset.torque_filter`), its power response ``G(f) = |H(f)|⁴`` is known
    and divided out, leaving the spectrum of the noise itself where ``G`` is at least
    :data:`MIN_RESPONSE`. There a first-order (AR(1)) noise spectrum, which white noise is the
    ``φ = 0`` case of,

    .. math::  S(f) = S_0 \frac{(1 - φ)^2}{1 + φ^2 - 2φ\cos(2π f / f_r)}

    (Box & Jenkins, *Time Series Analysis*, §3.2.4; ``f_r`` the sampling rate) is fitted with
    the same robust loss, and :math:`\hat\sigma^2 = \int_0^{f_N} G(f) S(f)\, df`. So coloured
    noise seen through a filter whose cut-off lies in or below the motion band is measured
    rather than flagged, as long as the noise's knee ``f_r \ln(1/φ)/2π`` lies within the fitted
    band (else the level below it is an extrapolation: unreliable), and the fit describes the
    spectrum to within :data:`MAX_MISFIT` (else the torques did not go through the filter
    recorded, or their noise is not first-order: the free fit above is used).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.integrate
import scipy.optimize
import scipy.signal
import scipy.special

from ..data.dataset import Dataset
from ..data.filters import lowpass_power
from .gap import Spectra, residual_spectra

#: ``q`` repeats after a lag when ``mean |q(t+L) − q(t)|² ≤ REPEAT_TOLERANCE · 2 Var(q)``.
REPEAT_TOLERANCE = 1e-4
#: Welch segment length (s) of the spectral estimate.
FINE_SEGMENT = 4.0
#: Shortest period (s) searched, and the least overlap (s) a repetition estimate needs.
MIN_PERIOD = 0.5
MIN_OVERLAP = 2.0
#: Length (s) of the stretches of the difference series whose RMS the repetition floor takes
#: the lower quartile of (:func:`repetition_estimate`): short beside a period (a change spoils
#: few), long beside the noise's correlation under the chain's low-pass (≥ 10 degrees of
#: freedom at 5 Hz).
REPEAT_STRETCH = 1.0
#: Least degrees of freedom of a stretch (``2 B T``, ``B`` the noise bandwidth): a low-pass
#: below ~10 Hz lengthens the stretches beyond :data:`REPEAT_STRETCH`.
STRETCH_DOF = 20.0
#: Least power response ``|H|⁴`` of a known torque filter at which its spectrum is divided by
#: it (50 dB down): further down, leakage of the motion band and round-off outweigh the noise.
MIN_RESPONSE = 1e-5
#: Largest median distance (natural log) of the smoothed noise spectrum from its fitted AR(1)
#: shape (a factor 1.5) for the known-filter estimate to stand; a Welch average of many segments
#: scatters far less.
MAX_MISFIT = np.log(1.5)
#: Largest standard error of the known-filter estimate's ``log σ`` for it to stand (σ known to
#: about ±15 %): a noise knee near the band's lower edge, or few Welch segments, leave the level
#: below the band uncertain, and the verdict is then "undetermined" rather than a guess.
MAX_STDERR = 0.15
#: Largest AR(1) coefficient fitted (its knee at 0.016 % of the sampling rate).
MAX_AR = 0.999
#: What one estimate of the floor promises: within this factor range of the true noise (the
#: margin of :mod:`consistid.diagnosis.remainder` covers its lower end, 1 / 0.7).
FLOOR_ACCURACY = (0.7, 1.5)
#: Two estimates of the same noise, each within :data:`FLOOR_ACCURACY`, differ at most by this
#: factor (1.5 / 0.7); a repetition floor further above a seen spectral one holds a component
#: that is not noise.
MAX_FLOOR_RATIO = FLOOR_ACCURACY[1] / FLOOR_ACCURACY[0]


@dataclass(frozen=True)
class NoiseFloor:
    """The torque noise standard deviation per joint and how it was obtained.

    Attributes
    ----------
    sigma : (nv,) N·m.
    method : (nv,) per joint ``"given"``, ``"repetition"`` or ``"spectrum"``.
    period : the excitation period found (s), or ``None``.
    cutoff : (nv,) cut-off (Hz) of the low-pass the spectrum fit found (``inf``: unfiltered;
        ``nan``: not fitted).
    reliable : (nv,) False where the estimate cannot see the noise (filtered below the motion
        band).
    description : one line for reports.
    stderr : (nv,) standard error of ``log σ`` where the estimate has one (repetition: the
        stretches' spread; spectrum through a known filter: the fit's), else ``nan``.
    raw : (nv,) N·m, the noise of the torques before the chain's low-pass (white noise through
        the recorded filter, :func:`raw_noise`): ``sigma`` where the torques were not filtered
        or the filter is not recorded.
    on_repeating : (nv,) True where ``sigma`` was read on the repeating recordings
        (:func:`estimate_noise_floor`'s ``repeating=``) and is the noise through their
        low-pass, False where on the spectrum's (``spectrum_on=``); ``None``: all one set.
    """

    sigma: np.ndarray
    method: tuple[str, ...]
    period: float | None
    cutoff: np.ndarray
    reliable: np.ndarray
    description: str
    stderr: np.ndarray | None = None
    raw: np.ndarray | None = None
    on_repeating: np.ndarray | None = None


def _lag_mismatch(x: np.ndarray, max_lag: int) -> np.ndarray:
    """``mean_t |x(t+L) − x(t)|²`` summed over columns, for ``L = 0 … max_lag`` (FFT)."""
    n = x.shape[0]
    x = x - x.mean(axis=0)
    size = 1 << int(np.ceil(np.log2(2 * n)))
    f = np.fft.rfft(x, size, axis=0)
    cross = np.fft.irfft(f * np.conj(f), size, axis=0)[:max_lag + 1].sum(axis=1)
    sq = np.sum(x ** 2, axis=1)
    cum = np.concatenate([[0.0], np.cumsum(sq)])
    lags = np.arange(max_lag + 1)
    head = cum[n - lags] - cum[0]          # Σ_{t < n−L} x(t)²
    tail = cum[n] - cum[lags]              # Σ_{t ≥ L} x(t)²
    return (head + tail - 2 * cross) / (n - lags)


def find_period(dataset: Dataset) -> tuple[float | None, int | None]:
    """The excitation period (s, and in samples) after which every joint's position repeats
    within :data:`REPEAT_TOLERANCE`, from the longest uniformly sampled recording; ``(None,
    None)`` when no lag between :data:`MIN_PERIOD` and the recording's length minus
    :data:`MIN_OVERLAP` repeats."""
    best = None
    for s in np.unique(dataset.segment):
        idx = np.flatnonzero(dataset.segment == s)
        t = dataset.t[idx]
        if idx.size < 32:
            continue
        dt = np.diff(t)
        h = float(np.median(dt))
        if np.ptp(dt) > 1e-6 * h:
            continue
        if best is None or idx.size > best[1].size:
            best = (h, idx)
    if best is None:
        return None, None
    h, idx = best
    q = dataset.q[idx]
    lo, hi = int(np.ceil(MIN_PERIOD / h)), idx.size - int(np.ceil(MIN_OVERLAP / h))
    if hi <= lo:
        return None, None
    mismatch = _lag_mismatch(q, hi)
    scale = 2 * np.sum(np.var(q, axis=0))
    if scale <= 0:
        return None, None
    rel = mismatch / scale
    ok = np.flatnonzero(rel[lo:hi + 1] <= REPEAT_TOLERANCE)
    if ok.size == 0:
        return None, None
    lag = lo + int(ok[0])
    # the local minimum at the first lag that repeats
    while lag + 1 <= hi and rel[lag + 1] < rel[lag]:
        lag += 1
    return lag * h, lag


def _repeats(q: np.ndarray, lag: int) -> bool:
    """Whether ``q`` repeats after ``lag`` samples: ``mean_t |q(t+L) − q(t)|²`` at most
    :data:`REPEAT_TOLERANCE` of ``2 Σ_j Var(q_j)`` (the criterion of :func:`find_period`)."""
    scale = 2 * np.sum(np.var(q, axis=0))
    return bool(scale > 0 and np.sum(np.mean((q[lag:] - q[:-lag]) ** 2, axis=0))
                <= REPEAT_TOLERANCE * scale)


@dataclass(frozen=True)
class Repetition:
    """The repetition estimate per joint (:func:`repetition_estimate`).

    Attributes
    ----------
    sigma : (nv,) N·m, ``nan`` where no recording holds two periods.
    order : the order of the differences used (1 or 2; 0: none).
    stderr : (nv,) standard error of ``log σ`` (from the spread of the stretches).
    disturbed : (nv,) fraction of the stretches whose σ exceeds the lower quartile's estimate
        by more than :data:`MAX_FLOOR_RATIO`: where the torque did not repeat (left out).
    stretches : how many stretches of :data:`REPEAT_STRETCH` s there are.
    """

    sigma: np.ndarray
    order: int
    stderr: np.ndarray
    disturbed: np.ndarray
    stretches: int


def _differences(dataset: Dataset, tau: np.ndarray, period: float, order: int
                 ) -> list[tuple[np.ndarray, float]]:
    """Per recording that holds ``order + 1`` periods with :data:`MIN_OVERLAP` to spare and
    whose positions repeat: the differences of ``order`` (``d / √2`` or ``d / √6``: σ each) and
    the recording's step (s)."""
    out = []
    for s in np.unique(dataset.segment):
        idx = np.flatnonzero(dataset.segment == s)
        if idx.size < 2:
            continue                        # one sample: no step, nothing repeats
        h = float(np.median(np.diff(dataset.t[idx])))
        lag = int(round(period / h))
        span = order * lag
        if lag < 1 or idx.size <= span or (idx.size - span) * h < MIN_OVERLAP \
                or not _repeats(dataset.q[idx], lag):
            continue
        x = tau[idx]
        d = (x[lag:] - x[:-lag]) / np.sqrt(2.0) if order == 1 else \
            (x[2 * lag:] - 2 * x[lag:-lag] + x[:-2 * lag]) / np.sqrt(6.0)
        out.append((d, h))
    return out


def repetition_estimate(dataset: Dataset, tau: np.ndarray, period: float,
                        torque_filter: tuple[float, int] | None = None) -> Repetition:
    r"""The noise from the repetition of the excitation every ``period`` seconds (module notes),
    robust to what does not repeat.

    Per order (first differences ``(τ(t+P) − τ(t))/√2``; with three periods or more, second
    differences ``(τ(t+2P) − 2τ(t+P) + τ(t))/√6``, which cancel a linear drift), the difference
    series of every recording that holds it is cut into stretches of :data:`REPEAT_STRETCH` s
    (longer below :data:`STRETCH_DOF` degrees of freedom);
    each stretch gives ``σ_i``, its standard deviation about its own mean (a change offsets the
    stretches it spoils, not the others). The order's estimate is the lower quartile of the
    ``σ_i`` over its value for noise alone, ``σ √(χ²_{ν,0.25}/ν)``, with ``ν = 2 B T − 1``
    degrees of freedom per stretch (``B = ∫|H|⁴ df`` the noise bandwidth of ``torque_filter``,
    the chain's low-pass, or the Nyquist frequency without one), refined as the pooled
    ``√(mean σ_i²)`` of the stretches within :data:`MAX_FLOOR_RATIO` of it (on clean data all of
    them: the efficient estimate). A friction that stepped after a
    pause or a payload released puts a torque that does not repeat into the differences that
    straddle the change (one period of them for first differences, two for second: half the
    first differences of a three-period log), and the quartile ignores it while it holds fewer
    than three quarters of the stretches (a mean of squares swelled 10–26 × there). The
    estimate is the second differences' where there are three periods, unless the first
    differences' is lower by more than :data:`MAX_FLOOR_RATIO` (``order`` is then still 2).

    Its standard error in ``log σ`` is ``s / √K`` over the ``K`` stretches pooled, ``s`` the
    spread of ``log σ_i``: ``1.4826 · MAD``, at least the noise's own ``1/√(2ν)``
    (conservative where the stretches differ by more than noise).
    The lag in samples is each recording's own, ``round(period / h)``: recordings resampled at
    other rates line up in time, not in index."""
    nv = tau.shape[1]
    best = Repetition(np.full(nv, np.nan), 0, np.full(nv, np.inf), np.zeros(nv), 0)
    for order in (1, 2):
        stretches, steps = [], []
        for d, h in _differences(dataset, tau, period, order):
            n = max(int(round(_stretch(torque_filter, h) / h)), 2)
            for a in range(0, d.shape[0] - n + 1, n):
                stretches.append(np.std(d[a:a + n], axis=0))
                steps.append(h)
            if not stretches and d.shape[0] >= 2:
                stretches.append(np.std(d, axis=0))
                steps.append(h)
        if not stretches:
            continue
        sig = np.array(stretches)                                   # (M, nv)
        h = float(np.median(steps))
        factor, dof = _quartile_of_noise(torque_filter, h, _stretch(torque_filter, h))
        quartile = np.percentile(sig, 25, axis=0) / factor
        median = np.median(sig, axis=0)
        logs = np.log(np.maximum(sig, 1e-300))
        mad = np.median(np.abs(logs - np.log(np.maximum(median, 1e-300))), axis=0)
        spread = np.maximum(1.4826 * mad, 1.0 / np.sqrt(2.0 * dof))
        agree = sig <= MAX_FLOOR_RATIO * quartile
        disturbed = 1.0 - np.mean(agree, axis=0)
        # the stretches that agree with the quartile, pooled (the efficient estimate on them)
        quartile = np.sqrt(np.sum(sig ** 2 * agree, axis=0) / np.maximum(agree.sum(axis=0), 1)
                           * (dof + 1.0) / dof)            # each stretch less its own mean
        stderr = spread / np.sqrt(np.maximum(agree.sum(axis=0), 1))
        if best.order == 0:
            best = Repetition(quartile, order, stderr, disturbed, sig.shape[0])
        else:
            # second differences unless the first are lower beyond what two estimates of one
            # noise differ by (a change that spoils all the second differences)
            keep = best.sigma * MAX_FLOOR_RATIO < quartile
            best = Repetition(np.where(keep, best.sigma, quartile), order,
                              np.where(keep, best.stderr, stderr),
                              np.where(keep, best.disturbed, disturbed),
                              max(sig.shape[0], best.stretches))
    return best


def _bandwidth(torque_filter: tuple[float, int] | None, step: float) -> float:
    """The noise bandwidth ``B = ∫₀^{f_N} |H|⁴ df`` (Hz) of ``torque_filter`` at the rate
    ``1 / step``; the Nyquist frequency without one (or one not at that rate)."""
    rate = 1.0 / step
    if torque_filter is None or not torque_filter[0] < 0.45 * rate:
        return 0.5 * rate
    grid = np.linspace(0.0, 0.5 * rate, 4097)
    return 0.5 * rate * float(np.mean(lowpass_power(grid, torque_filter[0], rate,
                                                    torque_filter[1])))


def _stretch(torque_filter: tuple[float, int] | None, step: float) -> float:
    """The stretch length (s): :data:`REPEAT_STRETCH`, longer where the noise's bandwidth
    gives it fewer than :data:`STRETCH_DOF` degrees of freedom (``2 B T``)."""
    return max(REPEAT_STRETCH, STRETCH_DOF / (2.0 * _bandwidth(torque_filter, step)))


def _quartile_of_noise(torque_filter: tuple[float, int] | None, step: float, seconds: float
                       ) -> tuple[float, float]:
    """The lower quartile of ``σ_i / σ`` for a stretch of ``seconds`` of noise through
    ``torque_filter`` sampled every ``step`` s, ``√(χ²_{ν,0.25} / ν)``, and ``ν = 2 B T − 1``
    (:func:`_bandwidth`; one less for the stretch's own mean)."""
    dof = max(2.0 * _bandwidth(torque_filter, step) * seconds - 1.0, 1.0)
    chi2_quartile = 2.0 * scipy.special.gammaincinv(0.5 * dof, 0.25)    # χ²_ν's 25 % point
    return float(np.sqrt(chi2_quartile / dof)), dof


def repetition_floor(dataset: Dataset, tau: np.ndarray, period: float
                     ) -> tuple[np.ndarray, int]:
    """``(σ (nv,), order of the differences)`` of :func:`repetition_estimate` (through the
    dataset's recorded torque filter); σ ``nan`` where no recording holds two periods (order
    0)."""
    rep = repetition_estimate(dataset, tau, period, dataset.torque_filter)
    return rep.sigma, rep.order


def fine_spectra(dataset: Dataset, residual: np.ndarray, tau_nom: np.ndarray,
                 seconds: float = FINE_SEGMENT) -> Spectra:
    """Welch spectra of ``residual`` and ``tau_nom`` with segments of about ``seconds`` (finer
    than the breakdown's, so that a low cut-off and the motion band are resolved), averaged over
    the uniformly sampled recordings."""
    acc_r = acc_n = freqs = None
    weight = segments = 0
    rate = None
    for s in np.unique(dataset.segment):
        idx = np.flatnonzero(dataset.segment == s)
        if idx.size < 64:
            continue
        dt = np.diff(dataset.t[idx])
        h = float(np.median(dt))
        if np.ptp(dt) > 1e-6 * h or (rate is not None and abs(1 / h - rate) > 1e-6 * rate):
            continue
        rate = 1.0 / h
        nper = int(2 ** np.round(np.log2(max(seconds * rate, 64))))
        nper = min(nper, idx.size // 2)
        if nper < 32:
            continue
        segments += (idx.size - nper) // (nper - nper // 2) + 1     # scipy's 50 % overlap
        f, pr = scipy.signal.welch(residual[idx], fs=rate, nperseg=nper, axis=0)
        _, pn = scipy.signal.welch(tau_nom[idx], fs=rate, nperseg=nper, axis=0)
        if freqs is not None and f.size != freqs.size:
            pr = np.column_stack([np.interp(freqs, f, c) for c in pr.T])
            pn = np.column_stack([np.interp(freqs, f, c) for c in pn.T])
            f = freqs
        acc_r = pr * idx.size if acc_r is None else acc_r + pr * idx.size
        acc_n = pn * idx.size if acc_n is None else acc_n + pn * idx.size
        freqs = f
        weight += idx.size
    if freqs is None:
        return residual_spectra(dataset, residual, tau_nom)
    p_res, p_nom = acc_r / weight, acc_n / weight
    power = p_nom[1:].sum(axis=1)
    band = float(freqs[1:][np.searchsorted(np.cumsum(power) / power.sum(), 0.999)]) \
        if power.sum() > 0 else float(freqs[1])
    return Spectra(freqs, p_res, p_nom, band, segments, rate)


def _rolloff(f: np.ndarray, fc: float, n: float) -> np.ndarray:
    return 1.0 / (1.0 + (f / fc) ** (2 * n)) ** 2


def spectral_floor(spectra: Spectra) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per joint, the fit of the module notes: ``(σ, f_c, reliable)``."""
    freqs, psd = spectra.freqs, spectra.residual
    nv = psd.shape[1]
    sigma, cut, reliable = np.zeros(nv), np.full(nv, np.nan), np.zeros(nv, dtype=bool)
    if freqs.size < 8:
        return sigma, cut, reliable
    nyq = float(freqs[-1])
    lo = max(2 * spectra.signal_band, 2 * freqs[1])
    band = (freqs >= lo) & (freqs <= 0.9 * nyq)
    if band.sum() < 6:
        band = freqs >= 0.5 * nyq
        lo = 0.5 * nyq
    f = freqs[band]
    kernel = np.ones(5) / 5.0
    for j in range(nv):
        p = np.maximum(psd[band, j], 1e-300)
        p = np.exp(np.convolve(np.pad(np.log(p), 2, mode="edge"), kernel, mode="valid"))
        y = np.log(p)
        # start: flat at the median of the first fifth of the band, cut-off at the top
        s0 = float(np.median(y[: max(3, y.size // 5)]))

        def res(x: np.ndarray) -> np.ndarray:
            return y - x[0] - np.log(_rolloff(f, np.exp(x[1]), x[2]))

        x0 = np.array([s0, np.log(nyq), 4.0])
        fit = scipy.optimize.least_squares(
            res, x0, loss="soft_l1", f_scale=0.5,
            bounds=([-np.inf, np.log(0.5 * lo), 0.5], [np.inf, np.log(100 * nyq), 10.0]))
        level, fc, order = float(np.exp(fit.x[0])), float(np.exp(fit.x[1])), float(fit.x[2])
        # The bias of a log-averaged periodogram: E log(χ²₂/2) = −γ (Euler's constant) per
        # raw bin; Welch averages many segments first, so the bias is small; left as is.
        integral = scipy.integrate.quad(lambda x: _rolloff(x, fc, order), 0, nyq, limit=200)[0]
        sigma[j] = np.sqrt(level * integral)
        cut[j] = fc if fc < 10 * nyq else np.inf
        reliable[j] = fc >= lo
    return np.maximum(sigma, 1e-12), cut, reliable


def _ar1_shape(f: np.ndarray, phi: float, rate: float) -> np.ndarray:
    """The AR(1) spectrum of the module notes over its value at ``f = 0``."""
    return (1.0 - phi) ** 2 / (1.0 + phi ** 2 - 2.0 * phi * np.cos(2.0 * np.pi * f / rate))


def ar1_knee(phi: float, rate: float) -> float:
    """The knee (Hz) of the AR(1) spectrum of the module notes, ``f_r ln(1/φ) / 2π``, computed as
    ``−f_r ln φ / 2π`` (a fitted ``φ`` of ~1e-309, white noise, overflows ``1/φ``, never
    ``ln φ``); ``inf`` for ``φ ≤ 0``."""
    return float("inf") if phi <= 0 else -rate * float(np.log(phi)) / (2 * np.pi)


def log_periodogram_bias(segments: int) -> float:
    r"""``E[log Ŝ(f)] − log S(f)`` of a Welch estimate averaging ``segments`` Hann-windowed
    segments with 50 % overlap: ``Ŝ/S ~ χ²_ν/ν`` with ``ν ≈ 1.89·K`` equivalent degrees of
    freedom (Percival & Walden, *Spectral Analysis for Physical Applications*, 1993, §6.17), and
    :math:`E \log(χ^2_ν/ν) = ψ(ν/2) − \log(ν/2)` (ψ the digamma function). A fit to the
    log-spectrum sits that far below the true level (−0.09 for six segments); 0 when the count
    is unknown."""
    if segments <= 0:
        return 0.0
    half = 0.5 * 1.89 * segments
    return float(scipy.special.digamma(half) - np.log(half))


def filtered_floor(spectra: Spectra, torque_filter: tuple[float, int] | None, rate: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, str]:
    """Per joint, the known-filter estimate of the module notes: ``(σ, reliable, standard
    error of log σ, shaped, band text)``, ``shaped`` where the AR(1) shape describes the
    spectrum and its knee lies in the band (the estimate is then unbiased, if perhaps too
    uncertain to be reliable); σ ``nan`` where the band holds fewer than six frequencies.
    ``torque_filter`` ``None``: torques not filtered (``G = 1``)."""
    freqs, psd = spectra.freqs, spectra.residual
    nv = psd.shape[1]
    nyq = 0.5 * rate

    def response(x: np.ndarray) -> np.ndarray:
        return (np.ones_like(x) if torque_filter is None
                else lowpass_power(x, torque_filter[0], rate, torque_filter[1]))

    gain = response(freqs)
    lo = max(2 * spectra.signal_band, 2 * freqs[1])
    band = (freqs >= lo) & (freqs <= 0.9 * nyq) & (gain >= MIN_RESPONSE)
    sigma, reliable, stderrs = np.full(nv, np.nan), np.zeros(nv, dtype=bool), np.full(nv, np.inf)
    shaped = np.zeros(nv, dtype=bool)
    if band.sum() < 6:
        return sigma, reliable, stderrs, shaped, "no band"
    f = freqs[band]
    grid = np.linspace(0.0, nyq, 8193)
    g_grid = response(grid)
    kernel = np.ones(5) / 5.0
    bias = log_periodogram_bias(spectra.segments)
    effective = f.size / kernel.size          # each KERNEL bins alike after the smoothing
    for j in range(nv):
        p = np.maximum(psd[band, j], 1e-300) / gain[band]
        y = np.convolve(np.pad(np.log(p), 2, mode="edge"), kernel, mode="valid")

        def res(x: np.ndarray) -> np.ndarray:
            return y - x[0] - np.log(_ar1_shape(f, x[1], rate))

        def log_sigma(x: np.ndarray) -> float:
            power = scipy.integrate.trapezoid(g_grid * _ar1_shape(grid, x[1], rate), grid)
            return 0.5 * float(x[0] + np.log(power))

        fit = scipy.optimize.least_squares(res, np.array([float(np.median(y)), 0.0]),
                                           loss="soft_l1", f_scale=0.5,
                                           bounds=([-np.inf, 0.0], [np.inf, MAX_AR]))
        sigma[j] = np.exp(log_sigma(fit.x) - 0.5 * bias)
        r = res(fit.x)
        misfit = float(np.median(np.abs(r)))
        # the standard error of log σ: the Gauss–Newton covariance of (log S₀, φ) (the
        # residuals' variance over the effective degrees of freedom), propagated by log σ's
        # gradient (central differences)
        scale2 = (float(np.mean(r ** 2)) * kernel.size * effective
                  / max(effective - fit.x.size, 1e-9))
        grad = np.array([(log_sigma(fit.x + e) - log_sigma(fit.x - e)) / 2e-6
                         for e in np.eye(fit.x.size) * 1e-6])
        cov = scale2 * np.linalg.pinv(fit.jac.T @ fit.jac)
        stderr = float(np.sqrt(max(grad @ cov @ grad, 0.0)))
        # the noise's knee below the band: its level there is an extrapolation, unseen
        knee = ar1_knee(float(fit.x[1]), rate)
        shaped[j] = misfit <= MAX_MISFIT and knee >= f[0]
        reliable[j] = shaped[j] and stderr <= MAX_STDERR
        stderrs[j] = stderr
    return sigma, reliable, stderrs, shaped, f"{f[0]:.3g}–{f[-1]:.3g} Hz"


@dataclass(frozen=True)
class SpectralFloor:
    """The spectrum estimate per joint (:func:`spectral_estimate`): ``sigma``, ``cutoff`` and
    ``reliable`` as in :class:`NoiseFloor`, ``known`` (nv,) True where the recorded torque
    filter was divided out, ``text`` how (for the description)."""

    sigma: np.ndarray
    cutoff: np.ndarray
    reliable: np.ndarray
    known: np.ndarray
    text: str
    stderr: np.ndarray | None = None


def spectral_estimate(dataset: Dataset, residual: np.ndarray, tau_nom: np.ndarray
                      ) -> SpectralFloor:
    """The ``spectrum`` floor of the module notes. With the dataset's torque filter recorded:
    the AR(1) fit through it (:func:`filtered_floor`) wherever its shape fits, seen where it is
    reliable or where the free fit (:func:`spectral_floor`, white below the band) is seen and
    agrees with it within two standard errors; the free fit where the AR(1) shape does not fit
    (an effect's tail, a knee below the band). Without: the free fit, and where it cannot see
    the level, the AR(1) fit with no filter (coloured noise that is not a roll-off) if that one
    stands."""
    sp = fine_spectra(dataset, residual, tau_nom)
    sigma, cut, reliable = spectral_floor(sp)
    filt = [f"{c:.3g} Hz" for c in cut if np.isfinite(c)]
    text = ("from the residual spectrum above the motion band "
            f"(> {2 * sp.signal_band:.3g} Hz), a flat level "
            + (f"rolling off as a low-pass at {', '.join(sorted(set(filt)))}" if filt
               else "(white)"))
    if sp.freqs.size < 8:
        return SpectralFloor(np.maximum(sigma, 1e-12), cut, reliable,
                             np.zeros(sigma.size, dtype=bool), text)
    rate = sp.rate if sp.rate > 0 else 2.0 * float(sp.freqs[-1])
    given = dataset.torque_filter
    if given is not None and not given[0] < 0.45 * rate:
        given = None           # not the rate it was filtered at (decimated, selected): unknown
    k_sigma, k_reliable, k_err, shaped, band = filtered_floor(sp, given, rate)
    if given is not None:
        # The AR(1) fit through the recorded filter wherever its shape fits (it knows the
        # filter's shape, which the free fit approximates): seen where its error is small, or
        # where the free fit sees a flat level within two of its standard errors (white noise
        # both ways). Where the shape does not fit (an effect's tail, not first-order noise, or
        # a knee below the band), the free fit as without a filter.
        known = shaped & np.isfinite(k_sigma)
        agree = np.abs(np.log(np.where(known, k_sigma, sigma) / sigma)) <= 2 * k_err
        reliable = k_reliable | (reliable & (~known | agree))
        # a joint nothing sees reports the AR(1) value where it is at least loosely determined
        # (standard error ≤ 1 in log σ): the free fit's roll-off then lies in the motion band
        known |= ~reliable & np.isfinite(k_sigma) & (k_err <= 1.0)
        what = (f"with the chain's low-pass ({given[0]:.3g} Hz, order {given[1]}) divided "
                "out, ")
    else:
        known = ~reliable & k_reliable
        reliable = reliable | known
        what = "on joints the flat level does not fit, "
    sigma = np.where(known, k_sigma, sigma)
    cut = np.where(known, np.inf if given is None else given[0], cut)
    if known.any():
        ar1 = (f"from the residual spectrum {what}an AR(1) noise level fitted on {band} and "
               "extended below it")
        joints = ", ".join(str(j + 1) for j in np.flatnonzero(known))
        text = (ar1 if known.all() else
                f"{text}; {ar1.replace('from the residual spectrum ', '')} (joints {joints})")
    stderr = np.where(known, k_err, np.nan)
    return SpectralFloor(np.maximum(sigma, 1e-12), cut, reliable, known, text, stderr)


def estimate_noise_floor(dataset: Dataset, tau: np.ndarray, residual: np.ndarray,
                         tau_nom: np.ndarray, sigma: np.ndarray | None = None,
                         torque_resolution: np.ndarray | None = None,
                         spectrum_on: tuple[Dataset, np.ndarray, np.ndarray] | None = None,
                         repeating: tuple[Dataset, np.ndarray, np.ndarray] | None = None
                         ) -> NoiseFloor:
    """The noise floor of the module notes. ``tau``: the measured torque (for repetition);
    ``residual``, ``tau_nom``: measured minus nominal torque and the nominal torque (for the
    spectrum); ``sigma``, ``torque_resolution``: (nv,) given values (either may be ``None``);
    ``spectrum_on``: ``(dataset, residual, tau_nom)`` of other samples to estimate the spectrum
    on (e.g. the recordings whose torque filter is recorded); default the ones above;
    ``repeating``: the same for the recordings that repeat the excitation, whose spectral level
    a repetition floor is checked against (:data:`MAX_FLOOR_RATIO`); default ``spectrum_on``.
    Each joint's σ is the noise of the recordings it was read on, through their recorded
    low-pass (:attr:`NoiseFloor.on_repeating` says which), never carried through another: a
    caller comparing it with recordings filtered otherwise scales it, once."""
    nv = tau.shape[1]
    if sigma is not None or torque_resolution is not None:
        s = np.zeros(nv)
        parts = []
        if sigma is not None:
            s = np.maximum(s, sigma)
            parts.append("sigma")
        if torque_resolution is not None:
            s = np.maximum(s, np.asarray(torque_resolution) / np.sqrt(12))
            parts.append("the torque resolution / √12")
        return NoiseFloor(s, ("given",) * nv, None, np.full(nv, np.nan), np.ones(nv, bool),
                          f"given ({' and '.join(parts)})")
    spectral = spectral_estimate(*(spectrum_on or (dataset, residual, tau_nom)))
    spec_sigma, cut, reliable = spectral.sigma, spectral.cutoff, spectral.reliable
    period, _ = find_period(dataset)
    source = (repeating or spectrum_on or (dataset,))[0]
    target = (spectrum_on or (dataset,))[0]
    repetition = (repetition_estimate(dataset, tau, period, source.torque_filter) if period else
                  Repetition(np.full(nv, np.nan), 0, np.full(nv, np.inf), np.zeros(nv), 0))
    rep, order = repetition.sigma, repetition.order
    repeats = np.isfinite(rep)
    # a torque that does not repeat, yet is no noise the spectrum sees (module notes)
    seen = (spectral if repeating is None or not repeats.any()
            else spectral_estimate(*repeating))
    not_noise = repeats & seen.reliable & (rep > MAX_FLOOR_RATIO * seen.sigma)
    use_rep = repeats & ~not_noise
    spec_sigma = np.where(not_noise, seen.sigma, spec_sigma)
    cut = np.where(not_noise, seen.cutoff, cut)
    reliable = np.where(not_noise, True, reliable)
    out = np.where(use_rep, rep, spec_sigma)
    method = tuple("repetition" if u else "spectrum" for u in use_rep)
    reliable = np.where(use_rep, True, reliable)
    if use_rep.all():
        text = (f"from period-to-period repetition of the measured torque (excitation period "
                f"{period:.4g} s found on q): "
                + ("σ² = Var(τ(t+2P) − 2τ(t+P) + τ(t))/6 (a linear drift cancels)" if order == 2
                   else "σ² = Var(τ(t+P) − τ(t))/2 (two periods: a drift would inflate it)"))
    else:
        text = (spectral.text
                + ("" if period is None else
                   f"; repetition (period {period:.4g} s) on "
                   f"{int(use_rep.sum())} of {nv} joints"))
        if period is None:
            text += "; the excitation does not repeat within a recording"
    if not_noise.any():
        text += ("; the torque does not repeat from period to period on "
                 + ", ".join(f"joint {j + 1} ({rep[j]:.3g} N·m, {rep[j] / spec_sigma[j]:.3g} × "
                             "the spectrum's level)" for j in np.flatnonzero(not_noise))
                 + ": a component that is neither locked to the excitation nor noise (a "
                 "disturbance at its own frequency, a change during the log); the floor there "
                 "is the spectrum's of the repeating recordings")
    # each joint's floor stays in the terms of the recordings it was read on (their low-pass):
    # the repeating ones' where repetition (or their spectrum) set it, else the spectrum's; a
    # caller comparing it with recordings filtered otherwise scales it once
    on_repeating = use_rep | not_noise
    if on_repeating.any() and source.torque_filter != target.torque_filter:
        text += ("; the repetition floor is the noise of the repeating recordings' "
                 + (f"{source.torque_filter[0]:.3g} Hz low-pass" if source.torque_filter
                    else "unfiltered torques")
                 + " (the spectrum's recordings are filtered otherwise)")
    disturbed = use_rep & (repetition.disturbed > 0)
    if disturbed.any():
        text += (f"; of {repetition.stretches} stretches of {REPEAT_STRETCH:g} s, those where "
                 "the torque did not repeat were left out (joint "
                 + ", ".join(f"{j + 1}: {repetition.disturbed[j]:.0%}"
                             for j in np.flatnonzero(disturbed)) + ")")
    if not reliable.all():
        text += ("; UNRELIABLE on joints filtered below the motion band (pass sigma): "
                 + ", ".join(str(j + 1) for j in np.flatnonzero(~reliable)))
    def errors(floor: SpectralFloor) -> np.ndarray:
        return np.full(nv, np.nan) if floor.stderr is None else floor.stderr

    stderr = np.where(use_rep, repetition.stderr,
                      np.where(not_noise, errors(seen), errors(spectral)))
    raw = np.where(on_repeating, raw_noise(out, source.torque_filter, _rate(source)),
                   raw_noise(out, target.torque_filter, _rate(target)))
    filters = {(source if r else target).torque_filter for r in on_repeating}
    if filters != {None} and np.all(np.isfinite(raw)):
        cuts = ", ".join(f"{f[0]:.3g} Hz" for f in sorted(x for x in filters if x))
        text += (f"; the raw torques' noise before the chain's low-pass ({cuts}; white "
                 "through it): " + ", ".join(f"{r:.3g}" for r in raw) + " N·m, filtered: "
                 + ", ".join(f"{x:.3g}" for x in out) + " N·m")
    return NoiseFloor(out, method, period, cut, reliable, text, stderr, raw,
                      on_repeating)


def _rate(dataset: Dataset) -> float:
    """The sampling rate (Hz) of the dataset's first recording, ``nan`` with fewer than two
    samples."""
    idx = np.flatnonzero(dataset.segment == dataset.segment[0])
    return 1.0 / float(np.median(np.diff(dataset.t[idx]))) if idx.size > 1 else float("nan")


def raw_noise(sigma: np.ndarray, torque_filter: tuple[float, int] | None, rate: float
              ) -> np.ndarray:
    r"""The standard deviation of white noise that the zero-phase low-pass ``torque_filter``
    (``(cut-off Hz, order)``, run at ``rate``) turns into ``sigma``:
    :math:`σ_{raw} = σ / \sqrt{\frac{1}{f_N}\int_0^{f_N} |H(f)|^4\, df}` (the filter passes
    that fraction of a flat spectrum's power). ``sigma`` itself without a filter, or when the
    filter is not one at ``rate`` (decimated, selected)."""
    sigma = np.asarray(sigma, dtype=float)
    if torque_filter is None or not np.isfinite(rate) or not torque_filter[0] < 0.45 * rate:
        return sigma.copy()
    grid = np.linspace(0.0, 0.5 * rate, 8193)
    passed = float(np.mean(lowpass_power(grid, torque_filter[0], rate, torque_filter[1])))
    return sigma / np.sqrt(passed)


r"""Where a nominal model's torque residual lies: per joint, per motion regime, per frequency band
and over time, plus the torque noise floor it should be compared with.

The residual is ``r = τ_meas − τ_nom``. Its spectrum is Welch's averaged periodogram (Welch 1967,
doi:10.1109/TAU.1967.1161901) of each recording resampled onto a uniform grid.

Noise floor
    White measurement noise has a flat spectrum; the excitation and every effect driven by it
    occupy the low band where the nominal torque has its power. The noise level ``S₀`` is the
    mean residual power density in the band just above it (``[2 f_s, 6 f_s]``, with ``f_s``
    the frequency below which the nominal torque has 99.9 % of its power), and

    .. math::  \hat\sigma^2 = \int_0^{f_N} \min(\bar S_r(f), 1.25\, S_0)\, df

    (``S̄_r`` the spectrum smoothed over 9 bins; the clip at ``1.25 S₀`` leaves its remaining
    scatter unclipped). This equals ``S₀ f_N`` for white noise and stays right when the torques
    were low-pass filtered above ``6 f_s`` (the filtered band contributes what it has). It cannot
    see noise filtered away *below* ``6 f_s``; :func:`high_band_rolloff` detects such
    filtering (the spectrum keeps falling instead of levelling out).
    :func:`consistid.diagnose` takes its floor from :mod:`consistid.diagnosis.noise` (repetition
    of the excitation, or a fitted low-pass roll-off), never from what the candidates leave.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.signal

from ..data.dataset import Dataset
from .gapdata import GapData

REGIMES: tuple[str, ...] = ("near-zero velocity", "moving +", "moving −", "high acceleration",
                            "gravity-dominated")
#: |q̇_j| below this fraction of its 99th percentile counts as near-zero velocity.
REST_FRACTION = 0.05
#: |q̈_j| above this quantile counts as high acceleration.
HIGH_ACCELERATION_QUANTILE = 0.8
#: a pose is gravity-dominated on joint j when |g_j| ≥ this fraction of |τ_nom,j| ...
GRAVITY_SHARE = 0.8
#: ... and |g_j| ≥ this fraction of the joint's largest |g_j|.
GRAVITY_LOAD = 0.25
#: the noise estimate clips the smoothed residual spectrum at this multiple of the noise level.
CLIP = 1.25
#: a high-band roll-off (:func:`high_band_rolloff`) below this marks low-pass filtered torques.
FILTERED_ROLLOFF = 1e-2


@dataclass(frozen=True, eq=False)
class GapBreakdown:
    """The nominal residual decomposed (all arrays per joint along the last axis).

    Attributes
    ----------
    joint_names : names of the joints.
    rms : (nv,) RMS of the residual (N·m).
    share : (nv,) each joint's share of the total sum of squares.
    relative : (nv,) ``‖r_j‖ / ‖τ_j‖``.
    regimes : regime names (:data:`REGIMES`).
    regime_fraction, regime_rms, regime_mean : (R, nv) fraction of samples, RMS and mean of the
        residual in each regime (``nan`` where a regime has no samples).
    band_edges : (B + 1,) frequency band edges (Hz); ``band_rms`` (B, nv) residual RMS per band.
    freqs, psd : (F,), (F, nv) residual power spectral density (N²·m²/Hz).
    signal_band : frequency (Hz) below which the nominal torque has 99.9 % of its power.
    window_t, window_mean : (W,), (W, nv) mean residual in consecutive time windows.
    drift, drift_std : (nv,) slope of the residual over time within recordings (N·m/s), ± std.
    noise_floor : (nv,) noise standard deviation used for comparisons (N·m).
    velocity, residual_sample : (S, nv) a subsample of (q̇, r) for residual-versus-velocity plots.
    """

    joint_names: tuple[str, ...]
    rms: np.ndarray
    share: np.ndarray
    relative: np.ndarray
    regimes: tuple[str, ...]
    regime_fraction: np.ndarray
    regime_rms: np.ndarray
    regime_mean: np.ndarray
    band_edges: np.ndarray
    band_rms: np.ndarray
    freqs: np.ndarray
    psd: np.ndarray
    signal_band: float
    window_t: np.ndarray
    window_mean: np.ndarray
    drift: np.ndarray
    drift_std: np.ndarray
    noise_floor: np.ndarray
    velocity: np.ndarray
    residual_sample: np.ndarray

    @property
    def friction_hint(self) -> np.ndarray:
        """Half the difference of the mean residual moving + and moving − (N·m): an apparent
        Coulomb + viscous friction per joint."""
        i, k = self.regimes.index("moving +"), self.regimes.index("moving −")
        return 0.5 * (self.regime_mean[i] - self.regime_mean[k])


def _uniform_segments(dataset: Dataset, x: np.ndarray) -> list[tuple[float, np.ndarray]]:
    """Each recording segment of ``x`` (N, m) resampled onto a uniform grid at its median step."""
    out = []
    for s in np.unique(dataset.segment):
        idx = np.flatnonzero(dataset.segment == s)
        if idx.size < 16:
            continue
        t = dataset.t[idx]
        dt = float(np.median(np.diff(t)))
        grid = t[0] + dt * np.arange(int(np.floor((t[-1] - t[0]) / dt)) + 1)
        out.append((dt, np.column_stack([np.interp(grid, t, x[idx, i])
                                         for i in range(x.shape[1])])))
    return out


def spectrum(dataset: Dataset, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Welch PSD of ``x`` (N, m) averaged over recordings (weighted by length): ``(f, S)``.

    Recordings are resampled to the median step of the first one; the segment length is the
    largest power of two ≤ an eighth of the shortest recording (at least 64 samples).
    """
    segs = _uniform_segments(dataset, x)
    if not segs:
        return np.zeros(1), np.zeros((1, x.shape[1]))
    dt = segs[0][0]
    shortest = min(s[1].shape[0] for s in segs)
    nper = int(2 ** np.floor(np.log2(max(shortest / 8, 64))))
    nper = min(nper, shortest)
    total, weight, freqs = None, 0.0, None
    for _, seg in segs:
        freqs, p = scipy.signal.welch(seg, fs=1.0 / dt, nperseg=nper, axis=0, detrend="constant")
        total = p * seg.shape[0] if total is None else total + p * seg.shape[0]
        weight += seg.shape[0]
    return freqs, total / weight


def _signal_band(freqs: np.ndarray, p_nominal: np.ndarray) -> float:
    power = p_nominal[1:].sum(axis=1)
    if power.sum() <= 0:
        return float(freqs[1]) if freqs.size > 1 else 0.0
    cum = np.cumsum(power) / power.sum()
    return float(freqs[1:][np.searchsorted(cum, 0.999)])


@dataclass(frozen=True, eq=False)
class Spectra:
    """The spectra :func:`noise_floor`, :func:`high_band_rolloff` and :func:`gap_breakdown` work
    on, computed once by :func:`residual_spectra`.

    Attributes
    ----------
    freqs : (F,) frequencies (Hz).
    residual, nominal : (F, nv) power spectral densities of the residual and the nominal torque.
    signal_band : ``f_s``, the frequency below which the nominal torque has 99.9 % of its power.
    segments : Welch segments averaged (over every recording), 0 when not counted.
    rate : the sampling rate (Hz) they were computed at, 0 when not recorded.
    """

    freqs: np.ndarray
    residual: np.ndarray
    nominal: np.ndarray
    signal_band: float
    segments: int = 0
    rate: float = 0.0

    @property
    def noise_band(self) -> tuple[np.ndarray, float, float]:
        """``(mask over freqs, lo, hi)`` of the noise band ``[2 f_s, min(6 f_s, 0.9 f_N)]``."""
        lo, hi = 2 * self.signal_band, min(6 * self.signal_band, 0.9 * self.freqs[-1])
        return (self.freqs >= lo) & (self.freqs <= hi), lo, hi

    def with_residual(self, dataset: Dataset, residual: np.ndarray) -> "Spectra":
        """The same nominal spectrum and band with another residual's spectrum."""
        return replace(self, residual=spectrum(dataset, residual)[1])


def residual_spectra(dataset: Dataset, residual: np.ndarray, tau_nom: np.ndarray) -> Spectra:
    """Welch spectra (:func:`spectrum`) of ``residual`` and ``tau_nom`` and the nominal torque's
    signal band."""
    freqs, p_res = spectrum(dataset, residual)
    _, p_nom = spectrum(dataset, tau_nom)
    return Spectra(freqs, p_res, p_nom, _signal_band(freqs, p_nom))


def noise_floor(dataset: Dataset, residual: np.ndarray, tau_nom: np.ndarray,
                spectra: Spectra | None = None) -> tuple[np.ndarray, str]:
    """Torque noise standard deviation per joint from a residual's high-frequency spectrum.

    Parameters
    ----------
    dataset : the samples (time stamps, recording segments).
    residual : (N, nv) measured minus modelled torque.
    tau_nom : (N, nv) modelled torque (its spectrum locates the motion's band).
    spectra : :func:`residual_spectra` of these three, when already computed.

    See the module notes. Returns ``(σ (nv,), description)``.
    """
    sp = residual_spectra(dataset, residual, tau_nom) if spectra is None else spectra
    freqs, p_res = sp.freqs, sp.residual
    if freqs.size < 8:
        return np.sqrt(np.mean(residual ** 2, axis=0)), "residual RMS (too few samples)"
    f_s = sp.signal_band
    nyq = freqs[-1]
    band, lo, hi = sp.noise_band
    if band.sum() < 3:
        band = freqs >= 0.5 * nyq
        lo, hi = 0.5 * nyq, nyq
    level = np.mean(p_res[band], axis=0)
    df = freqs[1] - freqs[0]
    kernel = np.ones(9) / 9.0
    smooth = np.column_stack([np.convolve(np.pad(p, 4, mode="edge"), kernel, mode="valid")
                              for p in p_res.T])
    sigma = np.sqrt(np.sum(np.minimum(smooth, CLIP * level), axis=0) * df)
    sigma = np.maximum(sigma, 1e-12)
    return sigma, (f"estimated from the residual spectrum {lo:.3g}–{hi:.3g} Hz "
                   f"(nominal torque band < {f_s:.3g} Hz)")


def high_band_rolloff(dataset: Dataset, residual: np.ndarray, tau_nom: np.ndarray,
                      spectra: Spectra | None = None) -> np.ndarray:
    """Per joint, the residual's mean power density in the top quarter of the spectrum divided
    by that in the noise band of :func:`noise_floor`: about 1 for white noise, orders of
    magnitude below 1 when the torques were low-pass filtered (then the high band no longer
    shows the noise level, :data:`FILTERED_ROLLOFF`). ``spectra``: :func:`residual_spectra`
    of the three arguments, when already computed."""
    sp = residual_spectra(dataset, residual, tau_nom) if spectra is None else spectra
    freqs, p_res = sp.freqs, sp.residual
    if freqs.size < 8:
        return np.ones(residual.shape[1])
    nyq = freqs[-1]
    band = sp.noise_band[0]
    top = freqs >= 0.75 * nyq
    if band.sum() < 3 or top.sum() < 3:
        return np.ones(residual.shape[1])
    return np.mean(p_res[top], axis=0) / np.maximum(np.mean(p_res[band], axis=0), 1e-300)


def _regime_masks(data: GapData) -> np.ndarray:
    """Boolean masks (R, N, nv) of the regimes of :data:`REGIMES`."""
    dq, ddq = data.dataset.dq, data.dataset.ddq
    v0 = REST_FRACTION * np.percentile(np.abs(dq), 99, axis=0)
    a0 = np.quantile(np.abs(ddq), HIGH_ACCELERATION_QUANTILE, axis=0)
    g, tn = np.abs(data.gravity), np.abs(data.tau_nom)
    gmax = np.max(g, axis=0)
    gravity = (g >= GRAVITY_SHARE * tn) & (g >= GRAVITY_LOAD * gmax) & (gmax > 0)
    return np.stack([np.abs(dq) < v0, dq >= v0, dq <= -v0, np.abs(ddq) >= a0, gravity])


def _drift(dataset: Dataset, r: np.ndarray, windows: int = 8
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Window means of ``r`` and the within-recording slope fitted to them (± std)."""
    centres, means, local_t = [], [], []
    for s in np.unique(dataset.segment):
        idx = np.flatnonzero(dataset.segment == s)
        for part in np.array_split(idx, windows):
            if part.size == 0:
                continue
            centres.append(dataset.t[part].mean())
            local_t.append(dataset.t[part].mean() - dataset.t[idx[0]])
            means.append(r[part].mean(axis=0))
    centres, means, local_t = np.array(centres), np.array(means), np.array(local_t)
    seg_of = np.repeat(np.arange(len(centres) // windows + 1), windows)[: len(centres)]
    x = local_t - np.array([local_t[seg_of == k].mean() for k in seg_of])
    y = means - np.array([means[seg_of == k].mean(axis=0) for k in seg_of])
    sxx = float(x @ x)
    nv = r.shape[1]
    if sxx <= 0 or len(x) < 3:
        return centres, means, np.zeros(nv), np.full(nv, np.inf)
    slope = x @ y / sxx
    resid = y - np.outer(x, slope)
    dof = max(len(x) - 1 - (seg_of.max() + 1), 1)
    std = np.sqrt(np.sum(resid ** 2, axis=0) / dof / sxx)
    return centres, means, slope, std


def gap_breakdown(data: GapData, noise: np.ndarray, max_points: int = 4000,
                  seed: int = 0, spectra: Spectra | None = None) -> GapBreakdown:
    """Decompose the nominal residual of ``data`` (see :class:`GapBreakdown`); ``spectra`` is
    :func:`residual_spectra` of its residual and nominal torque, when already computed."""
    r, tau = data.residual, data.tau
    ss = np.sum(r ** 2, axis=0)
    rms = np.sqrt(ss / data.n)
    share = ss / max(ss.sum(), 1e-300)
    relative = np.sqrt(ss) / np.maximum(np.linalg.norm(tau, axis=0), 1e-300)
    masks = _regime_masks(data)
    count = masks.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        regime_rms = np.sqrt(np.einsum("rnj,nj->rj", masks, r ** 2) / count)
        regime_mean = np.einsum("rnj,nj->rj", masks, r) / count
    sp = residual_spectra(data.dataset, r, data.tau_nom) if spectra is None else spectra
    freqs, psd = sp.freqs, sp.residual
    nyq = float(freqs[-1])
    edges = [0.0]
    e = 0.5
    while e < nyq:
        edges.append(e)
        e *= 4
    edges.append(nyq)
    edges = np.array(edges)
    df = freqs[1] - freqs[0] if freqs.size > 1 else 1.0
    # a band holding no bin of the spectrum (a short log: coarse Welch resolution) is unknown,
    # NaN, not a zero that says "nothing there"
    in_band = [(freqs >= a) & (freqs < b) if b < nyq else (freqs >= a)
               for a, b in zip(edges[:-1], edges[1:])]
    band_rms = np.array([np.sqrt(psd[m].sum(axis=0) * df) if m.any()
                         else np.full(psd.shape[1], np.nan) for m in in_band])
    wt, wm, slope, slope_std = _drift(data.dataset, r)
    rng = np.random.default_rng(seed)
    pick = np.sort(rng.choice(data.n, size=min(max_points, data.n), replace=False))
    return GapBreakdown(tuple(data.model.joint_names), rms, share, relative, REGIMES,
                        count / data.n, regime_rms, regime_mean, edges, band_rms, freqs, psd,
                        sp.signal_band, wt, wm, slope, slope_std,
                        np.asarray(noise, dtype=float), data.dataset.dq[pick], r[pick])

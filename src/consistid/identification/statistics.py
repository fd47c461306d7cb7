r"""Least-squares statistics under serially correlated (coloured) residuals.

Filtered torque logs have residuals whose samples are far from independent; counting their rows
as independent makes every least-squares standard deviation too small. Two building blocks:

:func:`autocorrelation_time`
    the integrated autocorrelation time ``τ_j`` (samples) of each joint's residual: its ``N``
    rows are worth ``N / τ_j`` independent ones.
:func:`coloured_covariance`
    the sandwich covariance of (weighted) least squares with joint ``j``'s errors counted that
    way, from the per-joint R factors (no N-row matrices).
:func:`hac_covariance`
    the heteroskedasticity- and autocorrelation-consistent sandwich from batch sums of the
    least-squares scores (:class:`ScoreSums`, one more pass over the regressor).

Used by :mod:`consistid.diagnose` (selection tests and parameter ±) and
:func:`consistid.identify` (``covariance="coloured"``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.fft

from ..data.dataset import Dataset
from ..robot.model import RobotModel
from .regressor import RegressorSpec, iter_filtered


def autocorrelation_time(dataset: Dataset, residual: np.ndarray, c: float = 5.0,
                         max_lag: int = 2000) -> np.ndarray:
    r"""Integrated autocorrelation time per joint, ``τ = 1 + 2 Σ_k ρ_k`` (in samples).

    ``N / τ`` is the number of effectively independent samples of a correlated residual (e.g.
    low-pass filtered noise): least-squares tests that count rows as independent are ``τ`` times
    too confident. Autocorrelations are pooled over recordings (FFT, mean removed per recording),
    and the sum is truncated by Sokal's automatic window, the first lag ``M ≥ c·τ(M)`` (Sokal
    1997, "Monte Carlo methods in statistical mechanics", doi:10.1007/978-1-4899-0319-8_6).
    """
    return integrated_time(autocovariance_sum(dataset, residual, max_lag), residual.shape[1], c)


def autocovariance_sum(dataset: Dataset, residual: np.ndarray, max_lag: int = 2000,
                       pooled: np.ndarray | None = None) -> np.ndarray | None:
    """Autocovariance sums (lags ``0 … max_lag``, per joint) of the residual, pooled over the
    dataset's recordings (mean removed per recording; recordings under 16 samples skipped) and
    added to ``pooled`` (the sums of other data, e.g. earlier chunks of a stream; a shorter
    recording adds nothing at lags beyond its own, :func:`add_lagged`). ``None`` when nothing
    was pooled."""
    acf_sum = pooled
    for idx in _recordings(np.asarray(dataset.segment)):
        part = residual[idx]
        if part.shape[0] < 16:
            continue
        # one joint per row (contiguous transforms), zero-padded to n + L points: the circular
        # autocorrelation is the linear one at lags 0 … L (a wrapped product pairs a sample
        # with the padding), L = min(n − 1, max_lag)
        x = np.ascontiguousarray((part - part.mean(axis=0)).T)
        n = x.shape[1]
        lags = min(n - 1, max_lag)
        size = scipy.fft.next_fast_len(n + lags, real=True)
        f = scipy.fft.rfft(x, n=size, axis=1)
        acov = scipy.fft.irfft(f.real ** 2 + f.imag ** 2, n=size, axis=1)[:, :lags + 1].T
        acf_sum = add_lagged(acf_sum, acov)
    return acf_sum


def add_lagged(a: np.ndarray | None, b: np.ndarray | None) -> np.ndarray | None:
    """The sum of two autocovariance sums ``(lags, nv)`` of different lengths: the shorter one
    holds no pairs at the longer one's extra lags, so it adds zero there (truncating to the
    shorter would cut every recording's window at the shortest one's length, and a recording
    of a few dozen samples would make Sokal's window — and ``τ`` — far too short)."""
    if a is None or b is None:
        return b if a is None else a
    if a.shape[0] < b.shape[0]:
        a, b = b, a
    out = a.copy()
    out[: b.shape[0]] += b
    return out


def _recordings(segment: np.ndarray) -> list[slice | np.ndarray]:
    """The samples of each recording, in increasing label order: slices when the labels never
    decrease (the usual layout: one run after another), index arrays otherwise."""
    if segment.size == 0:
        return []
    if np.all(segment[1:] >= segment[:-1]):
        edges = np.concatenate([[0], np.flatnonzero(segment[1:] != segment[:-1]) + 1,
                                [segment.size]])
        return [slice(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]
    return [np.flatnonzero(segment == s) for s in np.unique(segment)]


def integrated_time(acf_sum: np.ndarray | None, nv: int, c: float = 5.0) -> np.ndarray:
    """``τ_j`` from pooled autocovariance sums (:func:`autocovariance_sum`; Sokal's window, see
    :func:`autocorrelation_time`); all ones when ``acf_sum`` is ``None``."""
    if acf_sum is None:
        return np.ones(nv)
    rho = acf_sum / np.where(acf_sum[0] > 0, acf_sum[0], 1.0)
    tau = np.ones(nv)
    for j in range(nv):
        running = 1.0 + 2.0 * np.cumsum(rho[1:, j])
        lags = np.arange(1, rho.shape[0])
        stop = np.flatnonzero(lags >= c * running)
        tau[j] = max(1.0, running[stop[0]] if stop.size else running[-1])
    return tau


def coloured_covariance(cov: np.ndarray, grams: np.ndarray, weights: np.ndarray,
                        tau: np.ndarray, variances: np.ndarray | None = None) -> np.ndarray:
    r"""Sandwich covariance of weighted least squares whose per-joint errors are coloured.

    .. math::

        \operatorname{Cov}(\hat β) = C \Big(\sum_j τ_j\, w_j^2 v_j\, Φ_j^\top Φ_j\Big) C,
        \qquad C = \Big(\sum_j w_j\, Φ_j^\top Φ_j\Big)^{-1},

    ``C`` the covariance that counts rows as independent (for OLS ``C = s² G⁻¹`` with
    ``w_j = 1/s²``; for WLS ``w_j = 1/σ_j²``), ``Φ_jᵀΦ_j = R_jᵀR_j`` joint ``j``'s Gram matrix
    from its R factor and ``v_j`` joint ``j``'s error variance (default ``1/w_j``, the variance
    the weights assume: then the meat is ``Σ_j τ_j w_j Φ_jᵀΦ_j``; pass the per-joint residual
    variances when the weights do not follow them, e.g. OLS on joints of unequal noise). It is
    the sandwich ``C (Σ_j w_j² Φ_jᵀ Cov(e_j) Φ_j) C`` of least squares
    with serially correlated errors, with ``Φ_jᵀ Cov(e_j) Φ_j ≈ v_j τ_j Φ_jᵀΦ_j`` for columns
    that vary slowly against the residual's correlation time: the variance of a mean of ``N``
    correlated samples is ``τ σ²/N`` (Bayley & Hammersley, "The 'effective' number of
    independent observations in an autocorrelated time series", J. R. Stat. Soc. Suppl. 8(2),
    184–197, 1946; the general lag-window form is Newey & West, Econometrica 55(3), 703–708,
    1987, doi:10.2307/1913610). With every ``τ_j = 1`` it returns ``C``.

    Parameters
    ----------
    cov : (b, b) ``C``; rows/columns with infinite entries (unexcited directions) stay infinite.
    grams : (nv, b, b) ``Φ_jᵀΦ_j``.
    weights : (nv,) ``w_j``.
    tau : (nv,) ``τ_j`` (:func:`autocorrelation_time`).
    variances : (nv,) ``v_j``; default ``1/w_j``.
    """
    cov = np.asarray(cov, dtype=float)
    finite = np.isfinite(np.diag(cov))
    out = np.array(cov, copy=True)
    c = cov[np.ix_(finite, finite)]
    w = np.asarray(weights, dtype=float)
    v = 1.0 / w if variances is None else np.asarray(variances, dtype=float)
    meat = np.einsum("j,jpq->pq", np.asarray(tau, dtype=float) * w ** 2 * v,
                     np.asarray(grams, dtype=float)[:, finite][:, :, finite])
    out[np.ix_(finite, finite)] = c @ meat @ c
    return out


#: Batch sizes (samples) of :class:`ScoreSums`: the HAC bandwidth is rounded up to one of them.
BATCH_SIZES = tuple(2 ** k for k in range(15))


@dataclass(frozen=True)
class ScoreSums:
    r"""What the HAC covariance (:func:`hac_covariance`) needs of the least-squares scores
    ``g_t = Σ_j w_j e_{tj} Φ_{tj}`` (``Φ_{tj}`` joint ``j``'s base-regressor row at sample
    ``t``, ``e_{tj}`` its residual, ``w_j`` its weight), summed so that parts add up
    (recordings, stream parts).

    Attributes
    ----------
    batches : (len(BATCH_SIZES), b, b) ``Σ_k B_k B_kᵀ`` per batch size ``m``, ``B_k`` the sum
        of ``g_t`` over the ``k``-th run of ``m`` consecutive samples of a recording (the last,
        shorter run of each recording included).
    lag0, lag1 : (b,) ``Σ_t g_t²`` and ``Σ_t g_t g_{t−1}`` within recordings, per component.
    n_samples : samples read.
    """

    batches: np.ndarray
    lag0: np.ndarray
    lag1: np.ndarray
    n_samples: int

    def __add__(self, other: "ScoreSums") -> "ScoreSums":
        return ScoreSums(self.batches + other.batches, self.lag0 + other.lag0,
                         self.lag1 + other.lag1, self.n_samples + other.n_samples)

    def bandwidth(self) -> float:
        r"""Andrews' (1991) automatic Bartlett bandwidth from AR(1) fits of the score
        components, each standardised (every component counts alike):
        ``L = 1.1447 (α N)^{1/3}``, ``α = Σ_a 4ρ_a² / ((1 − ρ_a)⁶ (1 + ρ_a)²) /
        Σ_a (1 − ρ_a)^{−4}`` (Andrews, "Heteroskedasticity and autocorrelation consistent
        covariance matrix estimation", Econometrica 59(3), 817–858, 1991, doi:10.2307/2938229,
        eqs. 6.2 and 6.4); ``ρ_a`` clipped to ±0.97 so that a unit root does not give an
        infinite window."""
        ok = self.lag0 > 0
        rho = np.clip(self.lag1[ok] / self.lag0[ok], -0.97, 0.97)
        if rho.size == 0:
            return 1.0
        alpha = (np.sum(4 * rho ** 2 / ((1 - rho) ** 6 * (1 + rho) ** 2))
                 / np.sum((1 - rho) ** -4.0))
        return float(max(1.0, 1.1447 * (alpha * self.n_samples) ** (1.0 / 3.0)))

    def meat(self) -> tuple[np.ndarray, int]:
        """``(Σ_k B_k B_kᵀ, m)`` at the smallest batch size ``m ≥`` :meth:`bandwidth`."""
        want = self.bandwidth()
        k = next((i for i, m in enumerate(BATCH_SIZES) if m >= want), len(BATCH_SIZES) - 1)
        return self.batches[k], BATCH_SIZES[k]


def score_sums(model: RobotModel, spec: RegressorSpec, theta: np.ndarray, columns: np.ndarray,
               weights: np.ndarray, dataset: Dataset) -> ScoreSums:
    """:class:`ScoreSums` of one in-memory dataset (every sample; the regressor in chunks,
    one recording's ``(n, b)`` scores held at a time). The rows are those least squares saw:
    through the dataset's identification low-pass when it records one
    (:func:`~consistid.identification.regressor.iter_filtered`)."""
    b = columns.size
    out = ScoreSums(np.zeros((len(BATCH_SIZES), b, b)), np.zeros(b), np.zeros(b), 0)
    w = np.asarray(weights, dtype=float)
    for idx in _recordings(np.asarray(dataset.segment)):
        part = dataset.select(idx)
        g = np.empty((part.n_samples, b))
        for s, y, measured in iter_filtered(model, part, spec):
            e = measured - y @ theta                                     # (n, nv)
            g[s] = np.einsum("tjp,tj->tp", y[:, :, columns], e * w)
        out = out + _recording_sums(g)
    return out


def _recording_sums(g: np.ndarray) -> ScoreSums:
    """:class:`ScoreSums` of one recording's scores ``(n, b)``."""
    n, b = g.shape
    batches = np.empty((len(BATCH_SIZES), b, b))
    for k, m in enumerate(BATCH_SIZES):
        starts = np.arange(0, n, m)
        sums = np.add.reduceat(g, starts, axis=0) if n else np.zeros((0, b))
        batches[k] = sums.T @ sums
    return ScoreSums(batches, np.sum(g ** 2, axis=0), np.sum(g[1:] * g[:-1], axis=0), n)


def hac_covariance(cov: np.ndarray, meat: np.ndarray) -> np.ndarray:
    r"""The HAC sandwich ``C Ω C`` of (weighted) least squares,
    ``β̂ − β = C Σ_t g_t`` with ``C = (Σ_j w_j Φ_jᵀΦ_j)⁻¹`` (``cov``, the covariance that counts
    rows as independent) and ``Ω`` the long-run variance of ``Σ_t g_t``, estimated by
    non-overlapping batch sums of the scores (:class:`ScoreSums`; the batch-means estimator,
    asymptotically a Bartlett-kernel Newey–West estimator of the same bandwidth with 1.5 × its
    variance: Newey & West, "A simple, positive semi-definite, heteroskedasticity and
    autocorrelation consistent covariance matrix", Econometrica 55(3), 703–708, 1987,
    doi:10.2307/1913610; Meketon & Schmeiser, "Overlapping batch means", Winter Simulation
    Conference 1984; statsmodels' ``cov_type="HAC"`` is the kernel form). It needs neither
    equal noise within a joint nor columns that vary slowly. Rows/columns of ``cov`` with
    infinite entries (unexcited directions) stay infinite."""
    cov = np.asarray(cov, dtype=float)
    finite = np.isfinite(np.diag(cov))
    out = np.array(cov, copy=True)
    c = cov[np.ix_(finite, finite)]
    out[np.ix_(finite, finite)] = c @ meat[np.ix_(finite, finite)] @ c
    return out

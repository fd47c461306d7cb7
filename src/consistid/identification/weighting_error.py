r"""The model error a per-joint weighting puts into a fit: Hausman's test of the weights.

A fit weighted per joint (``w_j = 1/σ_j²``: WLS and the SDP) is the efficient one when each
joint's residual is its noise. When the residual is mostly model error instead — a log through
the signal chain: the filtered noise is a few mN·m, and what remains is the misfit of the
estimated velocities and accelerations and of dry friction at low speed, structured and
correlated with the regressor — the weights ``1/σ_j²`` follow that misfit, and the fit
carries a bias that the residual's sandwich (:mod:`consistid.identification.statistics`) does
not count: a UR5 in MuJoCo with dry friction through the default chain
(``benchmarks/coverage_chain.py``), the residual of joints 1–5 is 0.0075 N·m with noise-free
torques and 0.010 N·m with σ = 0.1 N·m of noise (filtered), the WLS errors are the same with
and without the noise (1.1 × the reported σ in the median; OLS 0.7 ×, its one σ set by the
wrist's 0.064 N·m misfit), and the 95 % intervals of WLS and the SDP held the truth for 0.86–0.89
of the base parameters (10 seeds), OLS's for 0.97–0.99.

Under the model, the estimate does not depend on the weights beyond its noise: the difference
of the fits with weights ``w_j`` and with equal weights (ordinary least squares) on the same
rows,

.. math::  δ = \hat β_w − \hat β_1,
           \qquad \operatorname{Cov}(δ) = \sum_j τ_j v_j\, D_j Φ_j^\top Φ_j D_j^\top,
           \qquad D_j = w_j C_w − C_1,

``C_w = (Σ_j w_j Φ_jᵀΦ_j)⁻¹``, ``C_1 = (Σ_j Φ_jᵀΦ_j)⁻¹`` and ``τ_j``, ``v_j`` the coloured
sandwich's (:func:`~consistid.identification.statistics.coloured_covariance`: exact under that
noise model, no efficiency assumed). This is Hausman's specification test (Hausman 1978,
"Specification tests in econometrics", Econometrica 46(6), 1251–1271, doi:10.2307/1913827)
with the weighting as the specification, as :mod:`consistid.identification.model_error` applies
it to the rows at rest. When ``δ`` exceeds its noise beyond chance (Hausman's statistic
``m = δᵀ Cov(δ)⁺ δ`` against χ² with ``rank Cov(δ)`` degrees of freedom at level
:data:`WEIGHTING_ALPHA`, :func:`hausman_rejects`: one test of the whole difference, since a
misfit moves many parameters at once, each by little), the weights move the estimate, and the
excess

.. math::  b_i^2 = \max\big(0,\ δ_i^2 − \operatorname{Cov}(δ)_{ii}\big)

(an unbiased estimate of the squared difference of the two fits' biases, clipped at zero) is
added to the diagonal of the weighted fit's covariance: its interval widens by at least the
amount by which the weighting alone moves it. Otherwise nothing is added (white noise: the
gate opens in at most :data:`WEIGHTING_ALPHA` of data sets, and then by the noise's size; the
white-noise cells of ``benchmarks/run_all.py --smoke``, 25 runs, are unchanged to 0.002). For
an unweighted fit (equal ``w_j``) ``δ = 0``. Least squares with the fit's weights stands for
the weighted estimate whatever the method (the SDP sits on the same rows and weights).

The part of the bias that the equal-weight fit shares is not seen: on the UR5 above coverage
goes 0.86–0.89 → 0.92–0.96 (10 seeds), and the misses left are parameters that OLS misses by
as much. On the Panda and the xArm7 through the same chain the term opens in 75–100 % of the
runs and leaves coverage at 0.99–1.00 (median half-width × 1.00–1.02).
"""

from __future__ import annotations

import numpy as np
import scipy.stats

from .compression import CompressedProblem
from .model_error import joint_grams

#: Familywise level of the test that the weighting moves some base parameter beyond its noise.
WEIGHTING_ALPHA = 0.05


def weighting_bias(problem: CompressedProblem, columns: np.ndarray, weights: np.ndarray,
                   tau: np.ndarray, variances: np.ndarray,
                   alpha: float = WEIGHTING_ALPHA) -> tuple[np.ndarray, np.ndarray, bool]:
    r"""``(b², z, rejected)`` of the module docstring on the base ``columns`` of the unweighted
    compressed ``problem``: the squared bias per base parameter that the weights ``w_j`` put
    into least squares (zero unless Hausman's test rejects, ``rejected``), and the standardised
    differences ``z_i = δ_i / \sqrt{Cov(δ)_{ii}}`` (0 where ``Cov(δ)_ii = 0``)."""
    zero = np.zeros(columns.size)
    w = np.asarray(weights, dtype=float)
    if np.ptp(w) <= 1e-12 * np.max(np.abs(w)):
        return zero, zero, False                      # equal weights: δ = 0
    try:
        delta, cov = weighting_difference(problem, columns, w, tau, variances)
    except np.linalg.LinAlgError:
        return zero, zero, False
    if not (np.all(np.isfinite(cov)) and np.all(np.isfinite(delta))):
        return zero, zero, False
    var = np.diag(cov)
    z = np.where(var > 0, delta / np.sqrt(np.where(var > 0, var, 1.0)), 0.0)
    if not hausman_rejects(delta, cov, alpha):
        return zero, z, False
    return np.maximum(delta ** 2 - var, 0.0), z, True


def weighting_difference(problem: CompressedProblem, columns: np.ndarray, weights: np.ndarray,
                         tau: np.ndarray, variances: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
    """``(δ, Cov(δ))`` of the module docstring from the per-joint R factors (no N-row
    matrices); raises ``LinAlgError`` when the weighted or the equal-weight fit is singular."""
    g, h = joint_grams(problem, columns)
    w = np.asarray(weights, dtype=float)
    c_w = np.linalg.inv(np.einsum("j,jpq->pq", w, g))
    c_1 = np.linalg.inv(g.sum(axis=0))
    delta = c_w @ (w @ h) - c_1 @ h.sum(axis=0)
    d = w[:, None, None] * c_w[None] - c_1[None]                     # D_j
    scale = np.asarray(tau, dtype=float) * np.asarray(variances, dtype=float)
    return delta, np.einsum("j,jpq,jqr,jsr->ps", scale, d, g, d)     # Σ τ_j v_j D_j G_j D_jᵀ


def hausman_rejects(delta: np.ndarray, cov: np.ndarray, alpha: float = WEIGHTING_ALPHA) -> bool:
    r"""Hausman's statistic ``m = δᵀ Cov(δ)⁺ δ`` against χ² with ``rank Cov(δ)`` degrees of
    freedom (the generalised inverse on the eigenvalues above ``10⁻⁹`` of the largest: the
    directions in which the two fits differ at all): does ``δ`` exceed its noise at level
    ``alpha``? One test of the whole difference, which a bias spread over many parameters
    (each moved by less than a per-parameter test would see) passes far beyond chance."""
    lam, u = np.linalg.eigh(0.5 * (cov + cov.T))
    if lam.size == 0 or lam[-1] <= 0:
        return False
    keep = lam > 1e-9 * lam[-1]
    m = float(np.sum((u[:, keep].T @ delta) ** 2 / lam[keep]))
    return bool(scipy.stats.chi2.sf(m, int(keep.sum())) < alpha)

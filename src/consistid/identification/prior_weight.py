r"""The SDP prior's weight chosen from the data: empirical Bayes on the compressed problem.

The SDP (:mod:`consistid.identification.sdp`) minimises ``‖Rθ − z‖² + γ d(θ‖π₀)`` with the
data term Fisher-weighted (a χ²) and, near the prior, ``d ≈ Δᵀ S Δ`` (``Δ = θ − π₀`` on the
inertial block, ``S = ½H₀`` the prior's curvature). Read as a Gaussian model, the data
``z ~ N(Rθ, 1)`` and the prior ``Δ ~ N(0, (γS)⁻¹)``, the weight that makes the data most probable
(the *evidence*, marginal likelihood, ``θ`` integrated out; directions the prior leaves free
integrated flat) satisfies MacKay's fixed point (MacKay 1992, "Bayesian interpolation", Neural
Computation 4(3), 415–447, doi:10.1162/neco.1992.4.3.415, eq. 4.9; the evidence of a linear
Gaussian model, Bishop 2006, *Pattern Recognition and Machine Learning*, §3.5.2):

.. math::  γ = \frac{k − γ \operatorname{tr}(A^{-1} S)}{Δ_γ^\top S Δ_γ},
           \qquad A = R^\top R + γ S,
           \qquad Δ_γ = A^{-1} R^\top (z − Rπ₀),

``k`` the number of prior-weighted parameters and ``k − γ tr(A⁻¹S)`` the number the data
determine. It asks the prior's spread to match how far the data put the bodies from the CAD
values: a URDF the data contradict gets a small weight (the answer follows the data where they
inform it), one they confirm a large one; unexcited directions (``γ tr(A⁻¹S)`` counts them out)
keep the prior whatever the weight. Chosen on the quadratic model of the prior at ``π₀`` without
the constraints: no extra SDP solve, and the program compiled once is re-solved at that ``γ``.
The answer is clipped to the weights over which every benchmark solve ended ``optimal``
(:data:`~consistid.identification.sdp.PRIOR_WEIGHT_SOLVED`).

Marginal likelihood rather than cross-validation: it needs no split of the recordings (which on
two recordings of one trajectory leaves folds of another motion), no extra solves, and it is
defined on the compressed problem alone (generalised cross-validation also is, but counts the
``N`` rows as independent residuals, which filtered logs are not; the evidence's ``γ`` depends
on the noise level only through ``tr(A⁻¹S)``, the count of directions the data determine).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

#: Fixed-point iterations at most, and the relative change of ``γ`` they stop at.
MAX_ITERATIONS = 100
TOLERANCE = 1e-4


def evidence_weight(a: np.ndarray, s: np.ndarray, b: np.ndarray, k: int,
                    bounds: tuple[float, float], start: float) -> tuple[float, int]:
    r"""``(γ, iterations)``: the fixed point of the module docstring, clipped to ``bounds``.

    Parameters
    ----------
    a : (m, p) the Fisher-weighted R factor (any coordinates ``θ = T y``: then ``s`` is
        ``TᵀST`` and the answer is the same).
    s : (p, p) the prior's curvature per unit weight (zero rows for unweighted parameters).
    b : (m,) ``z − a y₀``, the data less the prior's prediction.
    k : the number of prior-weighted parameters (the rank of ``s``).
    bounds : the smallest and largest weight returned.
    start : the first ``γ`` (e.g. the default weight).
    """
    lo, hi = bounds
    gram, rhs = a.T @ a, a.T @ b
    # parameters neither the data nor the prior weigh (structurally zero columns): a tiny ridge
    ridge = 1e-12 * np.diag(np.maximum(np.diag(gram) + np.diag(s), 1.0))
    gamma = float(np.clip(start, lo, hi))
    for it in range(1, MAX_ITERATIONS + 1):
        chol = np.linalg.cholesky(gram + gamma * s + ridge)
        delta = _solve(chol, rhs)
        spread = float(delta @ s @ delta)
        determined = k - gamma * float(np.trace(_solve(chol, s)))
        new = hi if spread <= 0 else float(np.clip(max(determined, 0.0) / spread, lo, hi))
        done = abs(new - gamma) <= TOLERANCE * gamma
        gamma = new
        if done:
            break
    return gamma, it


def _solve(chol: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``(LLᵀ)⁻¹ rhs`` from the Cholesky factor ``L``."""
    y = scipy.linalg.solve_triangular(chol, rhs, lower=True)
    return scipy.linalg.solve_triangular(chol.T, y, lower=False)

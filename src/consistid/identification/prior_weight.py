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
keep the prior whatever the weight. The per-joint terms (friction, offset) are integrated out
under the joint prior the solve adds (:mod:`consistid.identification.joint_prior`: its rows are
appended to ``R`` and ``z`` first, so the evidence is that of the model solved), flat where it
has none. Chosen on the quadratic model of the prior at ``π₀`` without the constraints: no
extra SDP solve, and the program compiled once is re-solved at that ``γ``.
The answer is clipped to the weights over which every benchmark solve ended ``optimal``
(:data:`~consistid.identification.sdp.PRIOR_WEIGHT_SOLVED`).

Marginal likelihood rather than cross-validation: it needs no split of the recordings (which on
two recordings of one trajectory leaves folds of another motion), no extra solves, and it is
defined on the compressed problem alone (generalised cross-validation also is, but counts the
``N`` rows as independent residuals, which filtered logs are not; the evidence's ``γ`` depends
on the noise level only through ``tr(A⁻¹S)``, the count of directions the data determine).

Where it loses to the fixed weight (``benchmarks/prior_weight.py --friction``, URDF 70 % off,
2 s of small motion: UR5 seeds 0 and 1, Panda seed 2, held-out RMS/σ 1.76 → 2.07, 1.68 → 1.92,
1.32 → 1.37) it returns what the Gaussian model asks: the truth's mean squared deviation from
the prior, in the prior's metric along the directions the data determine, is 2.8, 1.8 and 1.3 ×
what ``2/r²`` assumes, and the weight 0.40, 0.44 and 0.73 × ``2/r²``. But a few directions make
that mean (the three largest hold 84, 53 and 65 % of it; the median one deviates 0.7, 1.2 and
1.1 ×): one weight for every body follows the far ones and under-weights the many near ones,
and the held-out optimum lies at 1–2 × ``2/r²``, in the SDP and in this Gaussian model alike —
neither the constraints the evidence leaves out nor the residual's colour (``τ`` 1.0–1.16) is
the cause. A weight per body (this fixed point per body, MacKay's ARD) in the Gaussian model was
better in 3 of 6 such cases and worse in 3: not adopted.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

#: Fixed-point iterations at most, and the relative change of ``γ`` they stop at.
MAX_ITERATIONS = 100
TOLERANCE = 1e-4


def evidence_weight(a: np.ndarray, s: np.ndarray, b: np.ndarray,
                    bounds: tuple[float, float], start: float) -> tuple[float, int]:
    r"""``(γ, iterations)``: the fixed point of the module docstring, clipped to ``bounds``.

    The parameters the prior does not weigh (zero rows of ``s``: friction, armature) are
    integrated out flat first, by projecting them out of ``a`` and ``b`` (their Schur
    complement; a Gaussian prior on them of fixed precision ``DᵀD`` is rows ``(D, D θ₀)``
    appended to ``a`` and ``b``, :func:`~consistid.identification.joint_prior.append_rows`);
    the prior-weighted block is then whitened by ``s`` and diagonalised once,
    ``cᵀc = V diag(λ) Vᵀ``, so that every iteration is ``O(k)``:
    ``tr(A⁻¹S) = Σ 1/(λ_i + γ)`` and ``ΔᵀSΔ = Σ g_i²/(λ_i + γ)²`` with ``g = Vᵀcᵀb``.

    Parameters
    ----------
    a : (m, p) the Fisher-weighted R factor (any coordinates ``θ = T y``: then ``s`` is
        ``TᵀST`` and the answer is the same).
    s : (p, p) the prior's curvature per unit weight, positive definite on the parameters it
        weighs and zero elsewhere.
    b : (m,) ``z − a y₀``, the data less the prior's prediction.
    bounds : the smallest and largest weight returned.
    start : the first ``γ`` (e.g. the default weight).
    """
    lo, hi = bounds
    weighed = np.any(s != 0.0, axis=1)
    a1, a2 = a[:, weighed], a[:, ~weighed]
    if a2.shape[1]:
        a1 = a1 - a2 @ np.linalg.lstsq(a2, a1, rcond=None)[0]
        b = b - a2 @ np.linalg.lstsq(a2, b, rcond=None)[0]
    chol = np.linalg.cholesky(s[np.ix_(weighed, weighed)])              # S = L Lᵀ
    c = scipy.linalg.solve_triangular(chol, a1.T, lower=True).T         # a₁ L⁻ᵀ
    lam, vec = np.linalg.eigh(c.T @ c)
    lam = np.maximum(lam, 0.0)
    g2 = (vec.T @ (c.T @ b)) ** 2
    k = lam.size
    gamma = float(np.clip(start, lo, hi))
    for it in range(1, MAX_ITERATIONS + 1):
        spread = float(np.sum(g2 / (lam + gamma) ** 2))
        determined = k - gamma * float(np.sum(1.0 / (lam + gamma)))
        new = hi if spread <= 0 else float(np.clip(max(determined, 0.0) / spread, lo, hi))
        done = abs(new - gamma) <= TOLERANCE * gamma
        gamma = new
        if done:
            break
    return gamma, it

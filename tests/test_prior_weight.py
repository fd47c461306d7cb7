"""The SDP prior's weight chosen from the data (identification/prior_weight.py)."""

from __future__ import annotations

import numpy as np
import scipy.optimize
from hypothesis import given, settings, strategies as st

from consistid.identification.prior_weight import evidence_weight


def log_evidence(gamma: float, a: np.ndarray, s: np.ndarray, b: np.ndarray) -> float:
    """``log p(b | γ)`` of ``b ~ N(aθ, 1)``, ``Δ ~ N(0, (γS)⁻¹)`` on the weighted block and flat
    elsewhere, up to a constant: ``½ k log γ − ½ log det(aᵀa + γS) − ½ min_θ(‖aθ − b‖² +
    γ θᵀSθ)``, computed on the full matrices (no projection, no eigen-decomposition)."""
    k = int(np.sum(np.any(s != 0, axis=1)))
    big = a.T @ a + gamma * s
    theta = np.linalg.solve(big, a.T @ b)
    fit = np.sum((a @ theta - b) ** 2) + gamma * theta @ s @ theta
    return 0.5 * k * np.log(gamma) - 0.5 * np.linalg.slogdet(big)[1] - 0.5 * fit


def problem(rng: np.random.Generator, k: int, free: int, spread: float, m: int = 40):
    """A random linear problem with a prior of known spread on ``k`` parameters and ``free``
    unweighted ones."""
    p = k + free
    a = rng.standard_normal((m, p)) * rng.uniform(0.1, 3.0, p)
    root = rng.standard_normal((k, k)) + 2 * np.eye(k)
    s = np.zeros((p, p))
    s[:k, :k] = root @ root.T / k
    delta = np.zeros(p)
    delta[:k] = np.linalg.solve(np.linalg.cholesky(s[:k, :k]).T, spread * rng.standard_normal(k))
    delta[k:] = rng.standard_normal(free)
    return a, s, a @ delta + rng.standard_normal(m)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31), k=st.integers(2, 8), free=st.integers(0, 3),
       spread=st.floats(0.05, 5.0))
def test_the_fixed_point_maximises_the_evidence_computed_by_brute_force(seed, k, free, spread):
    """The weight returned is the maximiser of the log-evidence evaluated on the full matrices
    (a bounded scalar search over log γ), whenever it lies inside the bounds."""
    a, s, b = problem(np.random.default_rng(seed), k, free, spread)
    bounds = (1e-6, 1e6)
    gamma, _ = evidence_weight(a, s, b, bounds, 1.0)
    found = scipy.optimize.minimize_scalar(lambda x: -log_evidence(np.exp(x), a, s, b),
                                           bounds=np.log(bounds), method="bounded",
                                           options={"xatol": 1e-8})
    best = float(np.exp(found.x))
    if bounds[0] * 10 < best < bounds[1] / 10:
        assert log_evidence(gamma, a, s, b) >= log_evidence(best, a, s, b) - 1e-6
        np.testing.assert_allclose(gamma, best, rtol=1e-2)


def test_the_weight_follows_how_far_the_data_put_the_parameters_from_the_prior():
    """Data drawn with the prior's spread ``r`` give ``γ ≈ 1/r²`` on many well-determined
    parameters (the prior's precision), within the sampling error of ``k = 60`` draws; a data
    set that contradicts the prior more gets a smaller weight, and the bounds clip."""
    rng = np.random.default_rng(1)
    k, m = 60, 3000
    a = rng.standard_normal((m, k)) * 3.0
    s = np.eye(k)
    for spread in (0.1, 0.5):
        b = a @ (spread * rng.standard_normal(k)) + rng.standard_normal(m)
        gamma, _ = evidence_weight(a, s, b, (1e-9, 1e9), 1.0)
        assert 0.7 / spread ** 2 < gamma < 1.4 / spread ** 2
    assert evidence_weight(a, s, b, (10.0, 1e9), 1.0)[0] == 10.0


def test_with_the_joint_prior_rows_the_weight_maximises_that_model_s_evidence():
    """The SDP appends the joint prior's rows ``‖Dθ‖²`` (a Gaussian of fixed precision on the
    per-joint terms, :mod:`consistid.identification.joint_prior`) to the data before choosing
    the weight: the weight returned is then the maximiser of the evidence of the model with
    that Gaussian on the free block (brute force on the full matrices), and differs from the
    flat-prior choice where the free block is weakly determined (so this fails there)."""
    from consistid.identification.joint_prior import append_rows

    rng = np.random.default_rng(7)
    k, free, m = 6, 3, 30
    a, s, b = problem(rng, k, free, 0.5, m)
    a[:, k:] *= 0.02                                       # the per-joint terms barely excited
    b = b + a[:, k:] @ (20.0 * rng.standard_normal(free))
    d = np.zeros((free, k + free))
    d[np.arange(free), k + np.arange(free)] = 1.0 / 3.0   # their prior: σ = 3
    precision = d.T @ d

    def log_evidence_gauss(gamma):
        big = a.T @ a + gamma * s + precision
        theta = np.linalg.solve(big, a.T @ b)
        fit = np.sum((a @ theta - b) ** 2) + theta @ (gamma * s + precision) @ theta
        return 0.5 * k * np.log(gamma) - 0.5 * np.linalg.slogdet(big)[1] - 0.5 * fit

    r2, z2 = append_rows(a, b, d, np.zeros(free))
    gamma, _ = evidence_weight(r2, s, z2, (1e-6, 1e6), 1.0)
    found = scipy.optimize.minimize_scalar(lambda x: -log_evidence_gauss(np.exp(x)),
                                           bounds=np.log((1e-6, 1e6)), method="bounded",
                                           options={"xatol": 1e-8})
    np.testing.assert_allclose(gamma, np.exp(found.x), rtol=1e-2)
    flat, _ = evidence_weight(a, s, b, (1e-6, 1e6), 1.0)
    assert abs(np.log(flat / gamma)) > 0.1

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from consistid.identification.statistics import coloured_covariance


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.floats(1.0, 50.0))
def test_sandwich_reduces_to_iid_and_scales_with_common_tau(seed, tau):
    rng = np.random.default_rng(seed)
    phis = rng.standard_normal((3, 40, 4))            # per-joint N-row regressors
    w = rng.uniform(0.5, 4.0, 3)
    grams = np.einsum("jkp,jkq->jpq", phis, phis)
    c = np.linalg.inv(np.einsum("j,jpq->pq", w, grams))
    assert np.allclose(coloured_covariance(c, grams, w, np.ones(3)), c)
    assert np.allclose(coloured_covariance(c, grams, w, np.full(3, tau)), tau * c)
    # Explicit N-row sandwich C Φᵀ diag(τ_j w_j) Φ C with all rows stacked.
    taus = rng.uniform(1.0, 30.0, 3)
    phi = phis.reshape(-1, 4)
    d = np.repeat(taus * w, 40)
    assert np.allclose(coloured_covariance(c, grams, w, taus), c @ (phi.T * d) @ phi @ c)


def test_unexcited_directions_stay_infinite():
    grams = np.stack([np.eye(3), 2 * np.eye(3)])
    c = np.diag([1 / 3, 1 / 3, np.inf])
    c[2, :] = c[:, 2] = np.inf
    out = coloured_covariance(c, grams, np.ones(2), np.array([2.0, 5.0]))
    assert np.all(np.isinf(out[2])) and np.all(np.isinf(out[:, 2]))
    assert np.allclose(out[:2, :2], np.eye(2) * (2 + 10) / 9)

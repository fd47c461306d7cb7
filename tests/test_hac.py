"""The HAC covariance (identification/statistics.py: ScoreSums, hac_covariance;
identify(covariance="hac"))."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import consistid as ci
from consistid.identification.regressor import RegressorSpec, dataset_regressor
from consistid.identification.statistics import BATCH_SIZES, score_sums
from consistid.simulate.experiments import ar1_noise


def noisy_run(model, noise, seed=0, duration=60.0, rate=100.0):
    rng = np.random.default_rng(seed)
    data = ci.FourierTrajectory.random(model, 5, 10.0, rng).sample(rate, duration)
    spec = RegressorSpec.make(model, ("coulomb", "viscous"))
    theta = np.concatenate([model.prior_parameters, [0.4, 0.3, 0.2, 0.1]])
    tau = (dataset_regressor(model, data, spec) @ theta).reshape(-1, model.nv)
    return data.with_torque(tau + noise(tau.shape, rng)), spec, theta


def test_score_sums_are_the_batch_sums_of_the_explicit_scores(planar_2r):
    """Batch sums, lag products and sample count equal those computed from the explicit N-row
    regressor and residual, two recordings summed apart (a batch never spans them)."""
    data, spec, theta = noisy_run(planar_2r, lambda s, r: 0.05 * r.standard_normal(s),
                                  duration=7.0)
    data = ci.Dataset.concatenate([data.select(slice(0, 333)), data.select(slice(333, None))])
    cols = np.array([0, 3, 5, 9, 13, 19, 20, 21])
    w = np.array([2.0, 0.5])
    sums = score_sums(planar_2r, spec, theta * 1.01, cols, w, data)
    y = dataset_regressor(planar_2r, data, spec).reshape(data.n_samples, 2, -1)
    e = data.tau - y @ (theta * 1.01)
    g = np.einsum("tjp,tj->tp", y[:, :, cols], e * w)
    assert sums.n_samples == data.n_samples
    np.testing.assert_allclose(sums.lag0, np.sum(g ** 2, axis=0), rtol=1e-10)
    lag1 = np.sum(g[1:333] * g[:332], axis=0) + np.sum(g[334:] * g[333:-1], axis=0)
    np.testing.assert_allclose(sums.lag1, lag1, rtol=1e-10, atol=1e-12)
    k = BATCH_SIZES.index(64)
    blocks = [g[a:min(a + 64, 333)].sum(axis=0) for a in range(0, 333, 64)]
    blocks += [g[a:min(a + 64, len(g))].sum(axis=0) for a in range(333, len(g), 64)]
    expected = sum(np.outer(b, b) for b in blocks)
    np.testing.assert_allclose(sums.batches[k], expected, rtol=1e-10)


@pytest.mark.parametrize("phi, low, high", [(0.0, 0.6, 1.6), (0.9, 8.0, 40.0)])
def test_hac_variance_follows_the_noise_correlation(planar_2r, phi, low, high):
    """White noise: the HAC variances are the iid ones (ratio ≈ 1); AR(1) noise with φ = 0.9
    (autocorrelation time (1 + φ)/(1 − φ) = 19 samples): about 19 × the iid ones. The bandwidth
    grows with the correlation."""
    data, spec, _ = noisy_run(planar_2r, lambda s, r: ar1_noise(s, phi, 0.05, r))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        iid = ci.identify(planar_2r, data, method="ols", friction=("coulomb", "viscous"),
                          covariance="iid")
        hac = ci.identify(planar_2r, data, method="ols", friction=("coulomb", "viscous"),
                          covariance="hac")
    ratio = np.median(np.diag(hac.base_covariance) / np.diag(iid.base_covariance))
    assert low < ratio < high
    assert hac.details["covariance"].startswith("hac")
    np.testing.assert_allclose(hac.base_parameters, iid.base_parameters)


def test_hac_intervals_cover_ar1_noise_over_seeds(planar_2r):
    """Twelve seeds of AR(1) noise (φ = 0.9): the HAC 95 % intervals hold the truth for at
    least 85 % of the base parameters (intervals half as wide would hold ~67 %; the iid ones
    hold well under half)."""
    inside, inside_iid = [], []
    for seed in range(12):
        data, spec, theta = noisy_run(planar_2r, lambda s, r: ar1_noise(s, 0.9, 0.05, r),
                                      seed=seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for cov, store in (("hac", inside), ("iid", inside_iid)):
                res = ci.identify(planar_2r, data, method="ols",
                                  friction=("coulomb", "viscous"), covariance=cov)
                truth = res.base.project(theta)
                store.append(np.abs(res.base_parameters - truth) <= 1.96 * res.base_std)
    assert np.mean(inside) >= 0.85
    assert np.mean(inside_iid) < 0.6

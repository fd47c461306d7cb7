"""Seams between features merged together: exclude_joints / dead channels with the HAC
covariance, and others found in review. Truth: regressor-built torques with known parameters and
numpy's own least squares on the explicit regressor, independent of the compressed solver."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import consistid as ci
from consistid.errors import DataQualityWarning
from consistid.identification.regressor import RegressorSpec, regressor

FRICTION = ("coulomb", "viscous", "offset")


@pytest.fixture(scope="module")
def panda():
    return ci.RobotModel.example("panda")


@pytest.fixture(scope="module")
def dead_log(panda):
    """Torques Y π + white noise (σ = 0.05 N·m) with joint 3's channel dead (0 throughout)."""
    spec = RegressorSpec.make(panda, FRICTION)
    truth = np.concatenate([panda.prior_parameters, np.full(spec.n_joint_columns, 0.5)])
    data = ci.FourierTrajectory.random(panda, harmonics=5, period=10.0,
                                       seed=3).sample(100.0, 20.0)
    tau = (regressor(panda, data.q, data.dq, data.ddq, spec) @ truth).reshape(-1, 7)
    tau += 0.05 * np.random.default_rng(3).standard_normal(tau.shape)
    tau[:, 2] = 0.0
    return ci.Dataset(t=data.t, q=data.q, dq=data.dq, ddq=data.ddq, tau=tau)


def test_hac_covariance_with_a_dead_channel(panda, dead_log):
    """covariance='hac' on a log with a dead channel (excluded automatically) gives the HAC
    sandwich of the kept rows: on white noise, σ close to numpy's iid covariance of the kept
    rows' explicit base regressor (it used to refuse after the whole fit)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataQualityWarning)
        res = ci.identify(panda, dead_log, method="ols", friction=FRICTION, covariance="hac")
    assert res.excluded_joints == ("panda_joint3",)
    assert res.details["covariance"].startswith("hac")
    kept = [0, 1, 3, 4, 5, 6]
    d = dead_log
    y = regressor(panda, d.q, d.dq, d.ddq, res.spec).reshape(d.n_samples, 7, -1)[:, kept]
    w = res.base.base_columns(y).reshape(-1, res.base.n_base)
    beta, *_ = np.linalg.lstsq(w, d.tau[:, kept].ravel(), rcond=None)
    e = d.tau[:, kept].ravel() - w @ beta
    iid = np.sqrt(np.diag(e @ e / (e.size - beta.size) * np.linalg.inv(w.T @ w)))
    ratio = res.base_std / iid
    assert np.all(np.isfinite(ratio))
    assert 0.7 < np.median(ratio) < 1.5
    assert np.all(ratio > 0.3)

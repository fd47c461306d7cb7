"""Parallel filtering and the figures a user reads: σ and train RMS of the samples as they are,
the rows at rest's model error not hidden by the low-pass, an ``iid`` covariance on filtered
rows warned, and dry friction's rows at rest always suspected (MuJoCo truth)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import consistid as ci
from consistid.data.signals import preprocess
from consistid.errors import DataQualityWarning
from consistid.simulate.mujoco_logs import friction_run

FRICTION = ("coulomb", "viscous", "offset")


def chain(run: "object", seed: int) -> ci.Dataset:
    """The run's log (positions with 1e-5 rad of noise, torques) through the default chain."""
    d = run.dataset
    rng = np.random.default_rng(seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return preprocess(d.t, d.q + 1e-5 * rng.standard_normal(d.q.shape), d.tau).dataset


@pytest.fixture(scope="module")
def panda_chain() -> tuple:
    model = ci.RobotModel.example("panda")
    run = friction_run(model, 2, duration=20.0, rate=500.0, noise=1.0)
    return model, run, chain(run, 2)


def test_sigma_and_train_rms_are_those_of_the_samples(panda_chain):
    model, _, data = panda_chain
    assert data.identification_filter is not None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = ci.identify(model, data, method="wls", friction=FRICTION)
    residual = data.tau - res.predict(data)
    rms = np.sqrt(np.mean(residual ** 2, axis=0))
    np.testing.assert_allclose(res.train_rms, rms, rtol=0.02)
    # σ is the noise of the samples (≈ the residual RMS), not the filtered rows' fraction of it
    assert np.all(res.sigma > 0.8 * rms)
    assert np.all(res.details["filtered_sigma"] < 0.7 * res.sigma)


def test_iid_on_filtered_rows_is_warned(panda_chain):
    model, _, data = panda_chain
    with pytest.warns(DataQualityWarning, match="correlated over about"):
        ci.identify(model, data, method="ols", friction=FRICTION, covariance="iid")


def test_one_pass_iid_is_warned_on_unfiltered_rows(panda_chain):
    """A one-pass generator gets the iid count even without parallel filtering; the chain's
    rows are correlated, so it says σ may be too narrow (UR5 through the chain, one seed:
    22 % of base parameters within 1.96 σ of the simulated truth, with no word before)."""
    model, _, data = panda_chain
    n = data.t.size
    parts = [data.select(slice(i * n // 3, (i + 1) * n // 3)) for i in range(3)]
    with pytest.warns(DataQualityWarning, match="one-pass stream"):
        ci.identify(model, (p for p in parts), method="ols", friction=FRICTION,
                    parallel_filter=False)
    for data, options in ((parts, {}), ((p for p in parts), {"covariance": "iid"})):
        with warnings.catch_warnings(record=True) as caught:   # re-readable, or iid asked for
            warnings.simplefilter("always")
            ci.identify(model, data, method="ols", friction=FRICTION, parallel_filter=False,
                        **options)
        assert not any("one-pass" in str(w.message) for w in caught)


@pytest.mark.slow
def test_rest_error_survives_the_identification_low_pass(panda_chain):
    """Panda, MuJoCo frictionloss, noise 1 N·m, through the chain: with parallel filtering the
    Coulomb and viscous intervals hold the simulated friction (before the rows at rest were
    judged on the samples as they are: joint 5's f_c 3.4 σ off, its model error 0.08 against
    0.35 without the filter)."""
    model, run, data = panda_chain
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        on = ci.identify(model, data, method="ols", friction=FRICTION)
        off = ci.identify(model, data, method="ols", friction=FRICTION, parallel_filter=False)
    names = [on.parameter_names[c] for c in on.base.independent]
    truth = on.base.project(run.truth(model, list(on.parameter_names)))
    friction = [i for i, n in enumerate(names) if n.endswith((".fc", ".fv"))]
    z = (on.base_parameters - truth)[friction] / on.base_std[friction]
    assert np.all(np.abs(z) < 3.0), z
    i = names.index("panda_joint5.fc")
    b_on = np.sqrt(on.details["model_error"][i])
    b_off = np.sqrt(off.details["model_error"][i])
    assert b_on > 0.5 * b_off


@pytest.mark.slow
def test_dry_friction_rows_at_rest_always_get_the_model_error():
    """Noise large beside the friction (3 N·m, 10 s): Hausman's test alone stayed closed and
    left Coulomb terms 6–9 σ off without a warning; a Coulomb column on a joint with rows at
    rest now always opens it."""
    model = ci.RobotModel.example("panda")
    run = friction_run(model, 4, duration=10.0, noise=3.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = ci.identify(model, run.dataset, method="ols", friction=FRICTION)
    names = [res.parameter_names[c] for c in res.base.independent]
    b = np.asarray(res.details["model_error"])
    assert b[names.index("panda_joint7.fc")] > 0


def test_excluded_joints_on_filtered_rows(panda_chain):
    """A joint left out of a parallel-filtered fit: the kept joints' σ are those of the full
    fit's samples (the slope test's σ indexed by kept joint: it raised IndexError)."""
    model, _, data = panda_chain
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        full = ci.identify(model, data, method="wls", friction=FRICTION)
        part = ci.identify(model, data, method="wls", friction=FRICTION, exclude_joints=[2])
    assert np.isnan(part.sigma[2]) and np.isnan(part.train_rms[2])
    for key in ("filtered_sigma", "sample_sigma", "sample_rms", "filtered_train_rms"):
        assert part.details[key].shape == (model.nv,) and np.isnan(part.details[key][2]), key
    kept = [j for j in range(model.nv) if j != 2]
    np.testing.assert_allclose(part.sigma[kept], full.sigma[kept], rtol=0.1)

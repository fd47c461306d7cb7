"""Identification from a subset of the torque channels (issue 26): ``exclude_joints=`` and dead
channels. Truth: regressor-built torques with known parameters, and a direct least squares on
the kept rows of the explicit regressor (numpy), independent of the compressed solver."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

import consistid as ci
from consistid.cli import main
from consistid.errors import DataQualityWarning, OptionError, ResultFileError
from consistid.identification.regressor import RegressorSpec, regressor

FRICTION = ("coulomb", "viscous", "offset")


@pytest.fixture(scope="module")
def panda():
    return ci.RobotModel.example("panda")


@pytest.fixture(scope="module")
def logs(panda):
    """(train, held, truth): torques Y π + noise, friction fc = 1, fv = 0.3, fo = 0.2."""
    spec = RegressorSpec.make(panda, FRICTION)
    truth = np.concatenate([panda.prior_parameters, np.zeros(spec.n_joint_columns)])
    truth[panda.n_inertial:] = [{"fc": 1.0, "fv": 0.3, "fo": 0.2}[n.rsplit(".", 1)[1]]
                                for n in spec.joint_column_names(panda.joint_names)]
    out = []
    for seed in (1, 2):
        data = ci.FourierTrajectory.random(panda, harmonics=5, period=10.0,
                                           seed=seed).sample(100.0, 20.0)
        tau = (regressor(panda, data.q, data.dq, data.ddq, spec) @ truth).reshape(-1, 7)
        noise = 0.05 * np.random.default_rng(seed).standard_normal(tau.shape)
        out.append(ci.Dataset(t=data.t, q=data.q, dq=data.dq, ddq=data.ddq, tau=tau + noise))
    return out[0], out[1], truth


def test_excluded_rows_give_the_least_squares_of_the_other_rows(panda, logs):
    """OLS with joint 7 excluded = numpy's least squares on joints 1–6's rows of the explicit
    base regressor; joint 7's friction is named as lost, and joints 1–6 predict held-out data
    to the noise."""
    train, held, _ = logs
    res = ci.identify(panda, train, method="ols", exclude_joints=["panda_joint7"])
    y = regressor(panda, train.q, train.dq, train.ddq, res.spec).reshape(train.n_samples, 7, -1)
    w = res.base.base_columns(y[:, :6]).reshape(-1, res.base.n_base)
    beta = np.linalg.lstsq(w, train.tau[:, :6].ravel(), rcond=None)[0]
    np.testing.assert_allclose(res.base_parameters, beta, rtol=1e-6, atol=1e-8)
    assert res.excluded_joints == ("panda_joint7",)
    assert np.isnan(res.sigma[6]) and np.isnan(res.train_rms[6])
    lost = res.details["excluded_joints"]
    assert all(f"panda_joint7.{c}" in lost for c in ("fc", "fv", "fo"))
    assert not any(n.startswith("panda_joint7.") for n in res.parameter_names)
    assert np.all(res.rms(held)[:6] < 0.07)                     # noise 0.05
    # the left-out channel judges nothing: NaN there, and the total is over the kept channels
    assert np.isnan(res.rms(held)[6])
    per_joint, total = res.relative_error(held)
    r = held.tau[:, :6] - res.predict(held)[:, :6]
    assert np.isnan(per_joint[6])
    np.testing.assert_allclose(per_joint[:6], np.linalg.norm(r, axis=0)
                               / np.linalg.norm(held.tau[:, :6], axis=0), rtol=1e-12)
    assert total == pytest.approx(np.linalg.norm(r) / np.linalg.norm(held.tau[:, :6]))


@pytest.mark.parametrize("value", [0.0, 3.25])
def test_a_dead_channel_is_warned_and_excluded_like_an_explicit_exclusion(panda, logs, value):
    train, _, _ = logs
    tau = train.tau.copy()
    tau[:, 4] = value
    dead = ci.Dataset(t=train.t, q=train.q, dq=train.dq, ddq=train.ddq, tau=tau)
    with pytest.warns(DataQualityWarning, match=r"\['panda_joint5'\] read one value"):
        res = ci.identify(panda, dead, method="sdp")
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataQualityWarning)
        own = ci.identify(panda, dead, method="sdp", exclude_joints=[4])
    assert res.excluded_joints == own.excluded_joints == ("panda_joint5",)
    np.testing.assert_allclose(res.parameters, own.parameters)


def test_bad_exclusions_are_named(panda, logs):
    train, _, _ = logs
    with pytest.raises(OptionError, match="exclude_joints: 'elbow' is not a joint"):
        ci.identify(panda, train, method="ols", exclude_joints=["elbow"])
    with pytest.raises(OptionError, match="excludes every joint"):
        ci.identify(panda, train, method="ols", exclude_joints=range(7))


def test_exclusion_survives_save_and_load(panda, logs, tmp_path):
    train, held, _ = logs
    res = ci.identify(panda, train, method="ols", exclude_joints=[6])
    back = ci.IdentificationResult.load(res.save(tmp_path / "r.json"), model=panda)
    assert back.excluded_joints == ("panda_joint7",)
    np.testing.assert_array_equal(back.predict(held), res.predict(held))
    doc = json.loads((tmp_path / "r.json").read_text())
    del doc["excluded_joints"]
    for key in ("sigma", "train_rms"):     # a file from before exclude_joints: finite per joint
        doc[key] = [v if isinstance(v, float) else 1.0 for v in doc[key]]
    (tmp_path / "old.json").write_text(json.dumps(doc))
    doc["sigma"][6] = {"__float__": "nan"}     # NaN σ without an excluded joint: tampered
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    with pytest.raises(ResultFileError, match="sigma"):
        ci.IdentificationResult.load(tmp_path / "bad.json", model=panda)
    assert ci.IdentificationResult.load(tmp_path / "old.json", model=panda).excluded_joints == ()


def test_exclude_joints_in_toml_must_be_an_array(cli_project, capsys):
    conf = cli_project / "conf" / "run.toml"
    conf.write_text('root = ".."\n[model]\nurdf = "data/arm.urdf"\ngravity = [0.0, -9.81, 0.0]\n'
                    '[data]\ndir = "data"\nkeys = "consistid"\ntrain = ["run1.npz"]\n'
                    '[identify]\nmethod = "ols"\nexclude_joints = "joint2"\n')
    assert main(["identify", str(conf)]) == 2
    err = capsys.readouterr().err
    assert "[identify] exclude_joints must be an array of joint names" in err
    assert 'exclude_joints = "joint2"' in err

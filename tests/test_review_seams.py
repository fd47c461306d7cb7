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


def ur_rtde_log(path):
    """A UR RTDE recorder CSV: joint angles, commanded joint torques (N·m) and motor currents."""
    t = np.arange(600) * 0.002
    q = 0.5 * np.sin(2 * np.outer(t, np.arange(1, 7)))
    current = np.cos(np.outer(t, np.arange(1, 7)))
    cols = (["timestamp"] + [f"actual_q_{i}" for i in range(6)]
            + [f"actual_current_{i}" for i in range(6)]
            + [f"target_moment_{i}" for i in range(6)])
    np.savetxt(path, np.column_stack([t, q, current, 10 * current]), header=" ".join(cols),
               comments="")
    return path


def test_drives_refused_on_a_log_whose_torques_are_torques(tmp_path):
    """drives= reads the log's tau as motor currents (A); a recognised logger's torque columns
    (UR RTDE: target_moment, N·m) or a header naming N·m are torques: refused, naming columns=,
    never multiplied by the drive gains (it returned 10× the commanded torque, silently)."""
    from consistid.data.recordings import load_recording
    from consistid.drives.transmission import Transmission
    from consistid.errors import OptionError
    drives = Transmission(ratios=[100.0] * 6, torque_constants=[0.1] * 6)
    path = ur_rtde_log(tmp_path / "ur.csv")
    with pytest.raises(OptionError, match="columns="):
        load_recording(path, drives=drives)
    named = tmp_path / "named.csv"
    t = np.arange(600) * 0.002
    np.savetxt(named, np.column_stack([t, np.sin(t), np.cos(t)]), delimiter=",",
               header="t,q1,tau1 [Nm]", comments="")
    with pytest.raises(OptionError, match="N·m"):
        load_recording(named, drives=Transmission(ratios=[50.0], torque_constants=[0.2]))


@pytest.fixture(scope="module")
def excluded_file(panda, dead_log, tmp_path_factory):
    """The saved OLS result of the dead-channel log (joint 3 excluded), as a JSON document."""
    import json
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = ci.identify(panda, dead_log, method="ols", friction=FRICTION)
    path = res.save(tmp_path_factory.mktemp("excluded") / "result.json")
    return json.loads(path.read_text())


def load_tampered(doc, change, tmp_path):
    import json
    doc = json.loads(json.dumps(doc))
    change(doc)
    path = tmp_path / "result.json"
    path.write_text(json.dumps(doc))
    return ci.IdentificationResult.load(path)


NAN = {"__float__": "nan"}


@pytest.mark.parametrize("change, match", [
    (lambda d: d["sigma"].__setitem__(0, NAN), "sigma"),
    (lambda d: d["train_rms"].__setitem__(6, NAN), "train_rms"),
    (lambda d: d.__setitem__("excluded_joints", ["no_such_joint"]), "excluded_joints"),
])
def test_nan_sigma_only_at_the_joints_a_file_excludes(excluded_file, tmp_path, change, match):
    """A result file may hold NaN σ/RMS at the joints it names excluded only, and names only
    the model's joints excluded (a NaN at a kept joint loaded once any joint was excluded)."""
    from consistid.errors import ResultFileError
    back = load_tampered(excluded_file, lambda d: None, tmp_path)   # the file as written
    assert back.excluded_joints == ("panda_joint3",) and np.isnan(back.sigma[2])
    with pytest.raises(ResultFileError, match=match):
        load_tampered(excluded_file, change, tmp_path)


def _set(key, value):
    return lambda d: d["envelope"].__setitem__(key, value)


@pytest.mark.parametrize("change", [
    lambda d: d["envelope"].__setitem__("q_min", d["envelope"]["q_min"][:3]),
    lambda d: d["envelope"]["q_max"].__setitem__(0, NAN),
    _set("joint_names", ["a", "b", "c", "d", "e", "f", "g"]),
    lambda d: d["envelope"]["positive"].__setitem__(1, -5),
    _set("n_samples", "many"),
])
def test_a_tampered_training_envelope_is_named_at_load(excluded_file, panda, tmp_path,
                                                       change):
    """The training envelope of a result file is checked like every other field: a short,
    non-finite or foreign envelope loaded, then predict raised numpy's ValueError or stopped
    warning on data beyond it."""
    from consistid.errors import ResultFileError
    back = load_tampered(excluded_file, lambda d: None, tmp_path)
    assert back.envelope is not None
    assert tuple(back.envelope.joint_names) == tuple(panda.joint_names)
    with pytest.raises(ResultFileError, match="envelope"):
        load_tampered(excluded_file, change, tmp_path)


@pytest.fixture(scope="module")
def diagnosis_doc(panda, tmp_path_factory):
    """A saved diagnosis (MuJoCo Panda, Coulomb friction on joint 3, 4 s at 100 Hz) as JSON."""
    import json

    from consistid.simulate import record
    from consistid.simulate.effects import Effects
    effects = Effects(torque_noise=0.05).with_effect("coulomb", 1.5, joints=[2])
    rec = record(panda, ci.FourierTrajectory.random(panda, 4, 4.0, 5), effects, duration=4.0,
                 rate=100.0, seed=5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        diag = ci.diagnose(panda, ci.Dataset.from_recording(rec.t, rec.q, rec.tau),
                           effects=["coulomb"], progress=False)
    return json.loads(diag.save(tmp_path_factory.mktemp("d") / "d.json").read_text())


@pytest.mark.parametrize("change", [
    lambda d: d["diagnosis"].__setitem__("foo", 1),
    lambda d: d["diagnosis"].pop("rms_final"),
    lambda d: d["diagnosis"].__setitem__("rms_final", "x"),
    lambda d: d["diagnosis"].__setitem__("noise_floor", [1.0, 2.0]),
    lambda d: d.__setitem__("diagnosis", [1]),
    None,                                                   # JSON nested 100 000 deep
])
def test_a_tampered_diagnosis_file_is_named(diagnosis_doc, tmp_path, change):
    """Diagnosis.load names a tampered file (ResultFileError) where it raised TypeError or
    RecursionError, or returned a list, or a diagnosis whose summary() then failed."""
    import json

    from consistid.errors import ResultFileError
    path = tmp_path / "d.json"
    path.write_text(json.dumps(diagnosis_doc))
    ci.Diagnosis.load(path).summary()                      # the file as written
    doc = json.loads(json.dumps(diagnosis_doc))
    if change is None:
        path.write_text('{"format": "consistid.diagnosis", "version": 1, "diagnosis": '
                        + "[" * 100_000 + "]" * 100_000 + "}")
    else:
        change(doc)
        path.write_text(json.dumps(doc))
    with pytest.raises(ResultFileError):
        ci.Diagnosis.load(path)


def test_the_fit_table_leaves_excluded_joints_out_of_its_totals(panda, dead_log):
    """The report's per-joint fit table on data with the dead channel: the excluded joint's
    cells say so (no rows fitted there; its relative error divided by a zero torque), and the
    "all joints" row is that of the kept joints, from numpy on the prediction."""
    from consistid.identification.report import _fit_rows
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataQualityWarning)
        res = ci.identify(panda, dead_log, method="ols", friction=FRICTION)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)          # no division by zero torque
        header, rows = _fit_rows(res, [("held-out", dead_log)])
    assert rows[2][3:] == ["excluded", "excluded"]
    kept = [0, 1, 3, 4, 5, 6]
    e = (dead_log.tau - res.predict(dead_log))[:, kept]
    assert rows[-1][0] == "kept joints"
    np.testing.assert_allclose(rows[-1][3], np.sqrt(np.mean(e ** 2)), rtol=1e-9)
    total = np.linalg.norm(e) / np.linalg.norm(dead_log.tau[:, kept])
    assert rows[-1][4] == f"{100 * total:.2f} %"


def test_the_inertia_prior_of_a_result_with_an_excluded_joint(panda, dead_log):
    """calibrate_simulator(refine_inertia=True)'s inertia prior from a result whose joint 3 was
    excluded (σ NaN there): the kept joints' whitened rows only (R ᵀR = YₖᵀYₖ/σ², numpy), not
    a NaN factor that poisons the refinement."""
    from consistid.simulator.calibrate import InertiaPrior
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataQualityWarning)
        res = ci.identify(panda, dead_log, method="ols", friction=FRICTION)
    data = dead_log.select(np.arange(300))
    prior = InertiaPrior.of(res, data)
    assert np.all(np.isfinite(prior.r))
    spec = RegressorSpec.make(panda, None, False)
    kept = [0, 1, 3, 4, 5, 6]
    y = regressor(panda, data.q, data.dq, data.ddq, spec).reshape(300, 7, -1)[:, kept]
    y = (y / res.sigma[kept][None, :, None]).reshape(-1, y.shape[-1])
    np.testing.assert_allclose(prior.r.T @ prior.r, y.T @ y, rtol=1e-8, atol=1e-8)


def test_a_nonlinear_friction_result_says_weak_directions_were_not_assessed(panda):
    """friction='tanh' goes through the nonlinear search, which does not compute the weakly
    informed directions: the result says so (details['weakly_informed']), as a Dask one's does,
    instead of an empty weakly_informed that reads as 'none'."""
    d = ci.FourierTrajectory.random(panda, harmonics=3, period=5.0, seed=1).sample(100.0, 5.0)
    tau = panda.rnea(d.q, d.dq, d.ddq) + 0.5 * np.sign(d.dq)
    tau += 0.05 * np.random.default_rng(1).standard_normal(tau.shape)
    res = ci.identify(panda, ci.Dataset(t=d.t, q=d.q, dq=d.dq, ddq=d.ddq, tau=tau),
                      method="ols", friction="tanh")
    assert res.weakly_informed == ()
    assert res.details["weakly_informed"].startswith("not assessed")


def test_a_split_log_whose_headers_name_degrees_refuses_angle_unit_deg(tmp_path):
    """A log split over files whose position header names its unit (``a_position [deg]``,
    converted by the reader) with angle_unit='deg' is refused, as a single file is, instead of
    converted twice (positions 57× too small, silently)."""
    from consistid.data.recordings import load_recording
    from consistid.errors import OptionError
    t = np.arange(500) * 0.002
    deg = 30.0 * np.sin(t)
    pos, eff = tmp_path / "pos.csv", tmp_path / "eff.csv"
    np.savetxt(pos, np.column_stack([t, deg]), delimiter=",", header="time,a_position [deg]",
               comments="")
    np.savetxt(eff, np.column_stack([t, np.cos(t)]), delimiter=",", header="time,a_effort",
               comments="")
    rec = load_recording([pos, eff])                          # the header's unit is read
    np.testing.assert_allclose(rec.dataset.q[:, 0], np.deg2rad(deg)[np.isin(t, rec.dataset.t)],
                               rtol=1e-6, atol=1e-6)
    with pytest.raises(OptionError, match="unit"):
        load_recording([pos, eff], angle_unit="deg")

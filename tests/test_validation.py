import numpy as np
import pytest

import consistid as ci
from consistid.robot.urdf import JointDynamics
from consistid.identification.scoring import (refit_joint_terms, rigid_model, score_prediction,
                                  scores_table, with_urdf_friction)

from .conftest import random_states


def test_scores_match_their_formulas():
    rng = np.random.default_rng(1)
    tau, pred = rng.normal(size=(50, 3)), rng.normal(size=(50, 3))
    d = ci.Dataset(t=np.arange(50.0), q=tau, dq=tau, ddq=tau, tau=tau)
    s = score_prediction(pred, d, "x")
    r = tau - pred
    for j in range(3):
        assert s.relative_error[j] == pytest.approx(np.sqrt(np.sum(r[:, j] ** 2)
                                                            / np.sum(tau[:, j] ** 2)))
        assert s.rms[j] == pytest.approx(np.sqrt(np.mean(r[:, j] ** 2)))
    assert s.total_relative_error == pytest.approx(np.sqrt(np.sum(r ** 2) / np.sum(tau ** 2)))
    assert s.total_rms == pytest.approx(np.sqrt(np.mean(r ** 2)))
    assert "x" in scores_table([s]).splitlines()[2]


def test_urdf_friction_prediction_is_rnea_plus_friction(planar_2r):
    q, dq, ddq = random_states(planar_2r, 400, 0)
    d = ci.Dataset(t=np.arange(len(q)) * 0.01, q=q, dq=dq, ddq=ddq)
    dyn = {"joint1": JointDynamics("joint1", 0.5, 0.2), "joint2": JointDynamics("joint2", 0.1, -1)}
    fixed = with_urdf_friction(planar_2r, dyn)
    expected = (planar_2r.rnea(q, dq, ddq) + np.array([0.2, -1.0]) * np.sign(dq)
                + np.array([0.5, 0.1]) * dq)
    np.testing.assert_allclose(fixed.predict(d), expected, atol=1e-12)
    np.testing.assert_allclose(rigid_model(planar_2r).predict(d), planar_2r.rnea(q, dq, ddq))
    with pytest.raises(ci.ModelError, match=r"\['joint2'\].*no <dynamics> tag"):
        with_urdf_friction(planar_2r, {"joint1": dyn["joint1"]})


def test_refit_recovers_friction_and_offset_within_their_std(planar_2r):
    q, dq, ddq = random_states(planar_2r, 2000, 3)
    fc, fv, fo = np.array([0.3, 0.1]), np.array([0.8, 0.2]), np.array([-0.5, 0.25])
    rng = np.random.default_rng(4)
    tau = (planar_2r.rnea(q, dq, ddq) + fc * np.sign(dq) + fv * dq + fo
           + 0.05 * rng.standard_normal(q.shape))
    d = ci.Dataset(t=np.arange(len(q)) * 0.01, q=q, dq=dq, ddq=ddq, tau=tau)
    fit = refit_joint_terms(planar_2r, d)
    truth = np.concatenate([fc, fv, fo])          # columns: coulomb, viscous, offset blocks
    assert fit.parameter_names == ["joint1.fc", "joint2.fc", "joint1.fv", "joint2.fv",
                                   "joint1.fo", "joint2.fo"]
    assert np.all(np.abs(fit.joint_parameters - truth) < 4 * fit.joint_std)
    assert np.all(fit.joint_std < 0.01)
    still = ci.Dataset(t=d.t, q=q, dq=np.zeros_like(dq), ddq=ddq, tau=tau)
    with pytest.raises(ci.ModelError, match="cannot separate"):
        refit_joint_terms(planar_2r, still)


def test_refit_groups_columns_by_joint_index_not_name_prefix(tmp_path):
    """Joint names ``j`` and ``j.b``: a name-prefix match ("j.") would give joint ``j`` the
    columns of ``j.b`` as well."""
    from .conftest import PLANAR_2R, PLANAR_2R_VALUES

    path = tmp_path / "dotted.urdf"
    path.write_text(PLANAR_2R.format(**PLANAR_2R_VALUES).replace('"joint1"', '"j"')
                    .replace('"joint2"', '"j.b"'))
    model = ci.RobotModel.from_urdf(path, gravity=(0.0, -9.81, 0.0))
    assert model.joint_names == ["j", "j.b"]
    q, dq, ddq = random_states(model, 500, 5)
    fc = np.array([0.3, 0.1])
    tau = model.rnea(q, dq, ddq) + fc * np.sign(dq)
    fit = refit_joint_terms(model, ci.Dataset(t=np.arange(len(q)) * 0.01, q=q, dq=dq, ddq=ddq,
                                              tau=tau), friction=("coulomb",))
    assert fit.parameter_names == ["j.fc", "j.b.fc"]
    np.testing.assert_allclose(fit.joint_parameters, fc, atol=1e-9)
    with pytest.raises(ci.DatasetError, match="prediction has shape"):
        score_prediction(np.zeros((3, 2)), ci.Dataset(t=np.arange(4.0), q=np.zeros((4, 2)),
                                                      dq=np.zeros((4, 2)), ddq=np.zeros((4, 2)),
                                                      tau=np.zeros((4, 2))))

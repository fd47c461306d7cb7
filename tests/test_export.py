"""URDF export: exact round trip, CoM-frame inertials, merged links, friction tags, refusals."""

import xml.etree.ElementTree as ET

import numpy as np
import pytest

import consistid as ci
from consistid.errors import InconsistentParametersError
from consistid.robot.export import ExportWarning, write_urdf
from consistid.robot.inertia import from_mass_com_inertia, perturb
from consistid.estimation.recover import recover_standard
from consistid.identification.regressor import RegressorSpec, parameter_names
from consistid.robot.urdf import joint_dynamics


@pytest.fixture(scope="module")
def truth(panda):
    return perturb(panda.prior_parameters, 0.2, np.random.default_rng(5))


def _reload(model, path):
    return ci.RobotModel.from_urdf(path, locked_joints=model.locked_joints,
                                   locked_configuration=model.locked_configuration)


def _inertial(path, link):
    tag = ET.parse(path).getroot().find(f"link[@name='{link}']/inertial")
    return None if tag is None else tag


@pytest.mark.parametrize("merged", ["auto", "lump", "subtract"])
def test_round_trip_is_exact(panda, truth, tmp_path, merged):
    out = panda.with_parameters(truth).to_urdf(tmp_path / "panda.urdf", merged=merged)
    assert np.max(np.abs(_reload(panda, out).prior_parameters - truth)) < 1e-9


def test_round_trip_other_arm(tmp_path):
    ur5 = ci.RobotModel.example("ur5")
    theta = perturb(ur5.prior_parameters, 0.2, np.random.default_rng(2))
    out = write_urdf(ur5, tmp_path / "ur5.urdf", theta)
    assert np.max(np.abs(_reload(ur5, out).prior_parameters - theta)) < 1e-9


def test_inertial_is_about_the_com(panda, truth, tmp_path):
    """Independent check of the written numbers: c = h/m, I_c = I_O − m(‖c‖²1 − c cᵀ)."""
    out = write_urdf(panda, tmp_path / "p.urdf", truth)
    tag = _inertial(out, "panda_link3")
    p = truth[20:30]
    m, c = p[0], p[1:4] / p[0]
    i_o = np.array([[p[4], p[5], p[7]], [p[5], p[6], p[8]], [p[7], p[8], p[9]]])
    i_c = i_o - m * (c @ c * np.eye(3) - np.outer(c, c))
    assert float(tag.find("mass").get("value")) == pytest.approx(m, rel=1e-15)
    assert [float(v) for v in tag.find("origin").get("xyz").split()] == pytest.approx(c, abs=1e-15)
    assert tag.find("origin").get("rpy") == "0 0 0"
    it = tag.find("inertia")
    written = np.array([[float(it.get("ixx")), float(it.get("ixy")), float(it.get("ixz"))],
                        [float(it.get("ixy")), float(it.get("iyy")), float(it.get("iyz"))],
                        [float(it.get("ixz")), float(it.get("iyz")), float(it.get("izz"))]])
    assert np.allclose(written, i_c, atol=1e-14)


def test_merged_links(panda, truth, tmp_path):
    """auto: the fixed hand is lumped into link 7, the locked fingers keep their CAD inertial."""
    source_finger = ET.tostring(_inertial(panda.source, "panda_leftfinger"))
    out = write_urdf(panda, tmp_path / "auto.urdf", truth)
    assert _inertial(out, "panda_hand") is None
    assert ET.tostring(_inertial(out, "panda_leftfinger")) == source_finger
    out = write_urdf(panda, tmp_path / "lump.urdf", truth, merged="lump")
    assert _inertial(out, "panda_leftfinger") is None
    assert float(_inertial(out, "panda_link7").find("mass").get("value")) == pytest.approx(
        truth[60], rel=1e-15)
    # a body lighter than the hand (0.73 kg) cannot keep the hand's CAD inertial
    light = truth.copy()
    light[60:70] = from_mass_com_inertia(0.5, [0.0, 0.0, 0.1], np.diag([2e-3, 2e-3, 1e-3]))
    with pytest.raises(InconsistentParametersError, match="merged='lump'"):
        write_urdf(panda, tmp_path / "x.urdf", light, merged="subtract")
    out = write_urdf(panda, tmp_path / "light.urdf", light, merged="lump")
    assert np.max(np.abs(_reload(panda, out).prior_parameters - light)) < 1e-9


def test_friction_tags_round_trip(panda, truth, tmp_path):
    spec = RegressorSpec.make(panda, ("coulomb", "viscous", "offset", "position"))
    names = parameter_names(panda, spec)
    fc, fv = np.linspace(0.1, 0.7, 7), np.linspace(0.02, 0.3, 7)
    theta = np.concatenate([truth, fc, fv, np.full(7, 0.05), np.full(14, 0.02)])
    with pytest.warns(ExportWarning, match="panda_joint1.fo=0.05, panda_joint1.ps1=0.02"):
        out = write_urdf(panda, tmp_path / "f.urdf", theta, names)
    back = _reload(panda, out)
    assert np.allclose(back.pin_model.friction, fc, atol=1e-15)
    assert np.allclose(back.pin_model.damping, fv, atol=1e-15)
    tags = joint_dynamics(out)
    assert tags["panda_joint3"].friction == fc[2] and tags["panda_joint3"].damping == fv[2]
    assert tags["panda_finger_joint1"].damping == 0.3          # untouched
    theta[70] = -0.1
    with pytest.raises(InconsistentParametersError, match="panda_joint1"):
        write_urdf(panda, tmp_path / "g.urdf", theta, names)


def test_refuses_inconsistent_bodies(panda, truth, tmp_path):
    bad = truth.copy()
    bad[20:30] = from_mass_com_inertia(3.0, [0.0, 0.0, 0.0], np.diag([0.01, 0.01, 0.05]))
    with pytest.raises(InconsistentParametersError, match="panda_link3.*triangle"):
        write_urdf(panda, tmp_path / "bad.urdf", bad)
    assert not (tmp_path / "bad.urdf").exists()


def test_recovered_parameters_to_urdf(panda, truth, tmp_path):
    base = ci.compute_base_parameters(panda)
    rec = recover_standard(panda, base.project(truth), friction=None)
    back = _reload(panda, rec.to_urdf(tmp_path / "rec.urdf"))
    assert np.max(np.abs(back.prior_parameters - rec.inertial_parameters)) < 1e-9

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
    # a body lighter than the two fingers (0.015 kg each) cannot keep them (auto subtracts the
    # locked fingers): auto lumps them, and says so
    lighter = truth.copy()
    lighter[60:70] = from_mass_com_inertia(0.02, [0.0, 0.0, 0.1], np.diag([2e-5, 2e-5, 1e-5]))
    with pytest.warns(ExportWarning, match="merged='auto' lumped them"):
        out = write_urdf(panda, tmp_path / "light_auto.urdf", lighter)
    assert _inertial(out, "panda_leftfinger") is None
    assert np.max(np.abs(_reload(panda, out).prior_parameters - lighter)) < 1e-9


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


# ------------------------------------------------------------------ URDFs with ROS transmissions
#: A spatial 3R arm (no mimic joints) whose joints are named again inside ROS 1 <transmission>,
#: ros2_control and Gazebo blocks placed *after* the real joints: a writer that looks the joint
#: up by tag name anywhere in the tree finds the last of them.
ARM_3R = """<?xml version="1.0"?>
<robot name="arm3r">
  <link name="base"/>
  <link name="l1"><inertial><origin xyz="0 0.02 0.1"/><mass value="3.0"/>
    <inertia ixx="0.03" ixy="0.001" ixz="0" iyy="0.025" iyz="0.002" izz="0.01"/></inertial></link>
  <link name="l2"><inertial><origin xyz="0.2 0 0.01"/><mass value="2.0"/>
    <inertia ixx="0.004" ixy="0" ixz="0.0005" iyy="0.03" iyz="0" izz="0.03"/></inertial></link>
  <link name="l3"><inertial><origin xyz="0.1 0.01 0"/><mass value="1.0"/>
    <inertia ixx="0.002" ixy="0" ixz="0" iyy="0.008" iyz="0.0003" izz="0.008"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="3" effort="100"/>
    <dynamics damping="0.5" friction="0.25"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0 0 0.2" rpy="1.5707963267948966 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" velocity="3" effort="100"/></joint>
  <joint name="j3" type="revolute"><parent link="l2"/><child link="l3"/>
    <origin xyz="0.4 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-2.5" upper="2.5" velocity="3" effort="50"/></joint>
  <transmission name="t1"><type>transmission_interface/SimpleTransmission</type>
    <joint name="j1"><hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface>
    </joint>
    <actuator name="m1"><mechanicalReduction>100</mechanicalReduction></actuator></transmission>
  <transmission name="t2"><type>transmission_interface/SimpleTransmission</type>
    <joint name="j2"><hardwareInterface>EffortJointInterface</hardwareInterface></joint>
    <actuator name="m2"><mechanicalReduction>100</mechanicalReduction></actuator></transmission>
  <transmission name="t3"><type>transmission_interface/SimpleTransmission</type>
    <joint name="j3"><hardwareInterface>EffortJointInterface</hardwareInterface></joint>
    <actuator name="m3"><mechanicalReduction>50</mechanicalReduction></actuator></transmission>
  <ros2_control name="arm" type="system"><hardware><plugin>mock_components/GenericSystem</plugin>
    </hardware>
    <joint name="j1"><command_interface name="effort"/><state_interface name="position"/></joint>
    <joint name="j3"><command_interface name="effort"/><state_interface name="position"/></joint>
  </ros2_control>
  <gazebo reference="j2"><implicitSpringDamper>true</implicitSpringDamper></gazebo>
</robot>
"""


@pytest.fixture(scope="module")
def arm_3r(tmp_path_factory):
    path = tmp_path_factory.mktemp("arm3r") / "arm3r.urdf"
    path.write_text(ARM_3R)
    return ci.RobotModel.from_urdf(path)


def _friction_data(model, fc, fv, n=400, seed=0):
    """Noise-free torques computed independently of the regressor: ``pin.rnea`` plus
    ``fc·sign(q̇) + fv·q̇``."""
    rng = np.random.default_rng(seed)
    q, dq, ddq = rng.uniform(-1.5, 1.5, (n, 3)), rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    tau = model.rnea(q, dq, ddq) + fc * np.sign(dq) + fv * dq
    return ci.Dataset(t=np.arange(n) * 0.01, q=q, dq=dq, ddq=ddq, tau=tau)


def test_friction_goes_into_the_joint_not_the_transmission(arm_3r, tmp_path):
    """The identified friction lands in each real <joint>'s <dynamics>; <transmission>,
    <ros2_control> and <gazebo> blocks are left exactly as they were; Pinocchio reads it back."""
    import pinocchio as pin

    fc, fv = np.array([0.7, 1.1, 0.3]), np.array([0.4, 0.9, 0.15])
    res = ci.identify(arm_3r, _friction_data(arm_3r, fc, fv), method="ols",
                      friction=("coulomb", "viscous"))
    out = res.to_urdf(tmp_path / "identified.urdf")
    root = ET.parse(out).getroot()
    for block in ("transmission", "ros2_control"):
        for joint in root.iter(block):
            assert all(j.find("dynamics") is None for j in joint.iter("joint")), block
    source = ET.parse(arm_3r.source).getroot()
    for block in ("transmission", "ros2_control", "gazebo"):
        assert [ET.tostring(e) for e in root.iter(block)] == \
            [ET.tostring(e) for e in source.iter(block)]
    written = {j.get("name"): j.find("dynamics") for j in root.findall("joint")}
    assert float(written["j2"].get("friction")) == pytest.approx(fc[1], rel=1e-8)
    # an independent reader: Pinocchio's URDF parser
    back = pin.buildModelFromUrdf(str(out))
    assert np.allclose(back.friction, fc, rtol=1e-8)
    assert np.allclose(back.damping, fv, rtol=1e-8)
    assert np.allclose(back.friction, res.parameters[-6:-3], rtol=1e-14)
    # and the inertias: the identified rigid-body torques
    reloaded = ci.RobotModel.from_urdf(out)
    data = _friction_data(arm_3r, fc, fv, n=50, seed=3)
    assert np.allclose(reloaded.rnea(data.q, data.dq, data.ddq),
                       arm_3r.with_parameters(res.parameters).rnea(data.q, data.dq, data.ddq),
                       atol=1e-9)


def test_joint_dynamics_ignores_transmission_joints(arm_3r):
    tags = joint_dynamics(arm_3r.source)
    assert set(tags) == {"j1"}                     # the transmission's <joint name="j1"> has none
    assert tags["j1"].damping == 0.5 and tags["j1"].friction == 0.25


def test_transmission_with_panda_multi_joint(panda, truth, tmp_path):
    """A real multi-joint URDF with a transmission per joint appended: same file as without."""
    tree = ET.parse(panda.source)
    root = tree.getroot()
    for name in panda.joint_names:
        t = ET.SubElement(root, "transmission", name=f"{name}_trans")
        ET.SubElement(ET.SubElement(t, "joint", name=name), "hardwareInterface").text = "Effort"
    src = tmp_path / "panda_trans.urdf"
    tree.write(src)
    with_trans = ci.RobotModel.from_urdf(src, locked_joints=panda.locked_joints)
    spec = RegressorSpec.make(panda, ("coulomb", "viscous"))
    fc, fv = np.linspace(0.2, 0.8, 7), np.linspace(0.05, 0.35, 7)
    theta = np.concatenate([truth, fc, fv])
    out = write_urdf(with_trans, tmp_path / "out.urdf", theta, parameter_names(panda, spec))
    back = _reload(with_trans, out)
    assert np.allclose(back.pin_model.friction, fc, atol=1e-15)
    assert np.allclose(back.pin_model.damping, fv, atol=1e-15)
    assert np.max(np.abs(back.prior_parameters - truth)) < 1e-9


# ------------------------------------------------------------------ MJCF through MuJoCo's MjSpec
def _mj_inverse(path, q, dq, ddq, frictionloss=True):
    import mujoco

    mm = mujoco.MjModel.from_xml_path(str(path))
    if not frictionloss:
        mm.dof_frictionloss[:] = 0.0         # a constraint force: not a function of (q, q̇, q̈)
    d = mujoco.MjData(mm)
    out = np.empty_like(q)
    for k in range(q.shape[0]):
        d.qpos[:], d.qvel[:], d.qacc[:] = q[k], dq[k], ddq[k]
        mujoco.mj_inverse(mm, d)
        out[k] = d.qfrc_inverse
    return out


def _inside_limits(model, n, seed):
    rng = np.random.default_rng(seed)
    lo, hi = model.limits.lower, model.limits.upper
    lo, hi = np.where(np.isfinite(lo), lo, -np.pi), np.where(np.isfinite(hi), hi, np.pi)
    q = rng.uniform(lo + 0.05 * (hi - lo), hi - 0.05 * (hi - lo), (n, model.nv))
    return q, rng.normal(size=(n, model.nv)), rng.normal(size=(n, model.nv))


@pytest.mark.parametrize("name", ["panda", "ur5", "kinova"])
def test_mjcf_inverse_dynamics_equal_rnea(name, tmp_path):
    """MuJoCo's inverse dynamics of the written file = pinocchio.rnea with the identified
    parameters (an independent implementation), under a tilted gravity too."""
    from consistid.robot.mjcf import write_mjcf

    model = ci.RobotModel.example(name).with_gravity([0.4, -0.3, -9.79])
    theta = perturb(model.prior_parameters, 0.2, np.random.default_rng(11))
    out = write_mjcf(model, tmp_path / f"{name}.xml", theta)
    q, dq, ddq = _inside_limits(model, 20, 1)
    expected = model.with_parameters(theta).rnea(q, dq, ddq)
    assert np.max(np.abs(_mj_inverse(out, q, dq, ddq) - expected)) < 1e-9


def test_mjcf_friction_and_armature(arm_3r, tmp_path):
    """fv → damping, fc → frictionloss, Ia → armature: MuJoCo's inverse dynamics carries the
    viscous and rotor terms, Pinocchio's MJCF reader reads all three back."""
    import pinocchio as pin

    fc, fv, ia = np.array([0.7, 1.1, 0.3]), np.array([0.4, 0.9, 0.15]), np.array([0.1, 0.2, 0.05])
    data = _friction_data(arm_3r, fc, fv)
    data = ci.Dataset(t=data.t, q=data.q, dq=data.dq, ddq=data.ddq,
                      tau=data.tau + ia * data.ddq)
    res = ci.identify(arm_3r, data, method="sdp", friction=("coulomb", "viscous"),
                      armature=True)
    assert res.is_consistent
    named = dict(zip(res.parameter_names, res.parameters))
    r_fc, r_fv, r_ia = (np.array([named[f"{j}.{s}"] for j in arm_3r.joint_names])
                        for s in ("fc", "fv", "Ia"))
    assert np.allclose(r_fv, fv, rtol=1e-3) and np.allclose(r_fc, fc, rtol=1e-3)
    out = res.to_mjcf(tmp_path / "arm.xml")
    q, dq, ddq = _inside_limits(arm_3r, 15, 2)
    expected = (arm_3r.with_parameters(res.parameters).rnea(q, dq, ddq) + r_fv * dq
                + r_ia * ddq)
    assert np.max(np.abs(_mj_inverse(out, q, dq, ddq, frictionloss=False) - expected)) < 1e-9
    back = pin.buildModelFromMJCF(str(out))
    assert np.allclose(back.damping, r_fv, rtol=1e-14)
    assert np.allclose(back.friction, r_fc, rtol=1e-14)
    assert np.allclose(back.armature, r_ia, rtol=1e-14)


def test_mjcf_refusals_and_warnings(panda, truth, tmp_path):
    from consistid.robot.mjcf import write_mjcf

    bad = truth.copy()
    bad[20:30] = from_mass_com_inertia(3.0, [0.0, 0.0, 0.0], np.diag([0.01, 0.01, 0.05]))
    with pytest.raises(InconsistentParametersError, match="panda_link3"):
        write_mjcf(panda, tmp_path / "bad.xml", bad)
    assert not (tmp_path / "bad.xml").exists()
    spec = RegressorSpec.make(panda, ("coulomb", "offset"))
    names = parameter_names(panda, spec)
    theta = np.concatenate([truth, np.full(7, 0.3), np.full(7, 0.05)])
    with pytest.warns(ExportWarning, match="panda_joint1.fo=0.05"):
        write_mjcf(panda, tmp_path / "f.xml", theta, names)
    theta[70] = -0.1
    with pytest.raises(InconsistentParametersError, match="panda_joint1.*frictionloss"):
        write_mjcf(panda, tmp_path / "g.xml", theta, names)

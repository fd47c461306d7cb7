"""MJCF both ways: RobotModel.from_mjcf against MuJoCo's own inverse dynamics, and identified
values written into the user's MJCF with every other byte unchanged."""

import difflib
import re
import struct
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

import consistid as ci
from consistid.errors import ExportWarning, InconsistentParametersError, ModelError
from consistid.robot.inertia import from_mass_com_inertia
from consistid.robot.mjcf import write_mjcf
from consistid.robot.mjcf_edit import write_mjcf_into


def _stl_box(path: Path, half=(0.04, 0.04, 0.06)) -> None:
    """A binary STL of a box from z = 0 to 2·half[2]."""
    sx, sy, sz = half
    v = np.array([[x, y, z] for x in (-sx, sx) for y in (-sy, sy) for z in (0, 2 * sz)])
    faces = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1), (2, 3, 7),
             (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]
    out = bytearray(80) + struct.pack("<I", len(faces))
    for f in faces:
        a, b, c = v[list(f)]
        n = np.cross(b - a, c - a)
        out += struct.pack("<12fH", *(n / np.linalg.norm(n)), *a, *b, *c, 0)
    path.write_bytes(bytes(out))


def _obj_tetra(path: Path) -> None:
    v = [(0, 0, 0), (0.1, 0, 0), (0, 0.08, 0), (0, 0, 0.15)]
    f = [(1, 3, 2), (1, 2, 4), (1, 4, 3), (2, 3, 4)]
    path.write_text("# a tetrahedron\n" + "".join(f"v {a} {b} {c}\n" for a, b, c in v)
                    + "".join(f"f {a} {b} {c}\n" for a, b, c in f))


#: A small arm as MuJoCo Menagerie writes them: meshes by file, a defaults class with a nested
#: class, childclass, an inertial with iquat, one with fullinertia, one body whose inertia MuJoCo
#: derives from a mesh, a joint anchor off the body origin, an oblique axis, a welded flange, a
#: slide joint (a gripper to lock), a contact exclusion, three kinds of actuators, site sensors,
#: comments, single quotes and a tilted gravity.
ARM = """<mujoco model="arm">
  <!-- a small arm: meshes, a defaults class, actuators, a site sensor -->
  <compiler angle="radian" meshdir="assets" autolimits="true"/>
  <option timestep="0.002" gravity="0 0.3 -9.81"/>
  <default>
    <default class="arm">
      <joint damping="0.7" armature="0.05" frictionloss="0.2"/>
      <geom contype="0" conaffinity="0"/>
      <default class="wrist">
        <joint armature="0.01" axis="1 0 0"/>
      </default>
    </default>
  </default>
  <asset>
    <mesh name="link" file="link.stl"/>
    <mesh name="tip" file="tip.obj"/>
  </asset>
  <worldbody>
    <light pos="0 0 2"/>
    <body name="base" pos="0 0 0.1">
      <geom type="cylinder" size="0.05 0.05"/>
      <body name="link1" pos="0 0 0.05" quat="0.9238795 0 0 0.3826834" childclass="arm">
        <inertial pos="0.01 0.0 0.06" quat="0.9 0.1 0.3 0.2"
                  mass="2.1" diaginertia="0.02 0.018 0.006"/>
        <joint name="j1" axis="0 0 1" range="-2.9 2.9"/>
        <geom type="mesh" mesh="link"/>
        <body name="link2" pos="0 0.02 0.12" euler="0.3 0 0">
          <joint name='j2' pos="0 0 0.01" axis="0 1 0"   range="-1.8 1.8" damping="1.1" ref="0.3"/>
          <inertial pos="0 0.01 0.1" mass="1.4"
            fullinertia="0.011 0.012 0.004 0.001 -0.0005 0.0008"/>
          <geom type="mesh" mesh="link"/>
          <body name="link3" pos="0 0 0.2">
            <joint name="j3" class="wrist" axis="0.6 0 0.8"/>
            <geom type="mesh" mesh="tip" density="2000"/>
            <site name="tool" pos="0 0 0.1"/>
            <body name="flange" pos="0 0 0.12">
              <inertial pos="0 0 0.01" mass="0.3" diaginertia="0.0004 0.0004 0.0002"/>
              <body pos="0.01 0 0.02"><geom type="sphere" size="0.01" mass="0.05"/></body>
            </body>
            <body name="finger" pos="0.02 0 0.05">
              <joint name="j4" type="slide" axis="0 0 1" range="0 0.04"/>
              <geom type="box" size="0.01 0.02 0.01" mass="0.2"/>
            </body>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <contact>
    <exclude body1="base" body2="link1"/>
  </contact>
  <actuator>
    <motor name="m1" joint="j1" gear="50" ctrlrange="-1 1"/>
    <position name="p2" joint="j2" kp="100" forcerange="-40 40"/>
    <general name="g3" joint="j3" gear="2" ctrlrange="-5 5" ctrllimited="true"/>
  </actuator>
  <sensor>
    <framepos name="tool_pos" objtype="site" objname="tool"/>
    <jointpos name="j1_pos" joint="j1"/>
  </sensor>
</mujoco>
"""


def _arm(folder: Path, text: str = ARM) -> Path:
    (folder / "assets").mkdir(parents=True, exist_ok=True)
    _stl_box(folder / "assets" / "link.stl")
    _obj_tetra(folder / "assets" / "tip.obj")
    (folder / "arm.xml").write_text(text)
    return folder / "arm.xml"


def _mj_inverse(path, q, dq, ddq, damping=False, nv=None):
    """``qfrc_inverse`` of the compiled file (constraints and springs off; damping on request),
    joints beyond ``q``'s columns held at qpos0."""
    import mujoco

    mm = mujoco.MjModel.from_xml_path(str(path))
    mm.opt.disableflags |= (int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
                            | int(mujoco.mjtDisableBit.mjDSBL_SPRING))
    if not damping:
        mm.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_DAMPER)
    d = mujoco.MjData(mm)
    n = q.shape[1]
    out = np.empty_like(q)
    for k in range(q.shape[0]):
        d.qpos[:], d.qvel[:], d.qacc[:] = mm.qpos0, 0.0, 0.0
        d.qpos[:n], d.qvel[:n], d.qacc[:n] = q[k], dq[k], ddq[k]
        mujoco.mj_inverse(mm, d)
        out[k] = d.qfrc_inverse[:n]
    return out


def _states(n, nv, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(-1, 1, (n, nv)), rng.normal(size=(n, nv)), rng.normal(size=(n, nv))


# ----------------------------------------------------------------------------- reading
def test_from_mjcf_equals_mujoco_inverse_dynamics(tmp_path):
    """pin.rnea of the loaded model (armature included) = MuJoCo's mj_inverse, and the file's
    names, gravity, ranges, effort limits, armature, damping and frictionloss are read."""
    path = _arm(tmp_path)
    model = ci.RobotModel.from_mjcf(path)
    assert model.joint_names == ["j1", "j2", "j3", "j4"]
    assert model.body_names == ["link1", "link2", "link3", "finger"]
    assert model.source_format == "mjcf"
    assert np.allclose(model.gravity, [0, 0.3, -9.81])
    assert np.allclose(model.limits.effort[:3], [50.0, 40.0, 10.0])   # motor, forcerange, general
    assert np.allclose(model.limits.upper[[0, 1, 3]], [2.9, 1.8, 0.04])
    assert np.allclose(model.pin_model.armature, [0.05, 0.05, 0.01, 0.05])
    assert np.allclose(model.pin_model.damping, [0.7, 1.1, 0.7, 0.7])
    assert np.allclose(model.pin_model.friction, [0.2, 0.2, 0.2, 0.2])
    q, dq, ddq = _states(25, 4, 0)
    expected = _mj_inverse(path, q, dq, ddq)
    assert np.max(np.abs(model.rnea(q, dq, ddq) - expected)) < 1e-9 * np.abs(expected).max()


def test_locked_joint_merges_its_body(tmp_path):
    """Locking the finger at its qpos0 merges it: the reduced model's rnea = mj_inverse with the
    finger held (its own torque row dropped)."""
    path = _arm(tmp_path)
    model = ci.RobotModel.from_mjcf(path, locked_joints=["j4"])
    assert model.joint_names == ["j1", "j2", "j3"] and model.locked_configuration == {"j4": 0.0}
    q, dq, ddq = _states(20, 3, 1)
    expected = _mj_inverse(path, q, dq, ddq)
    assert np.max(np.abs(model.rnea(q, dq, ddq) - expected)) < 1e-9 * np.abs(expected).max()


def test_from_mjcf_of_a_written_example_arm(tmp_path):
    """A second family of files: the geometry-less MJCF consistid writes for the UR5 reads back
    to the same inverse dynamics (and to MuJoCo's)."""
    ur5 = ci.RobotModel.example("ur5")
    path = write_mjcf(ur5, tmp_path / "ur5.xml")
    back = ci.RobotModel.from_mjcf(path)
    q, dq, ddq = _states(20, ur5.nv, 2)
    assert np.max(np.abs(back.rnea(q, dq, ddq) - ur5.rnea(q, dq, ddq))) < 1e-8
    assert np.max(np.abs(back.rnea(q, dq, ddq) - _mj_inverse(path, q, dq, ddq))) < 1e-9


_unit = st.floats(-1, 1, allow_nan=False)


@settings(max_examples=12, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 2**31 - 1), axis=st.tuples(_unit, _unit, _unit),
       quat=st.tuples(_unit, _unit, _unit, _unit), slide=st.booleans())
def test_random_chains_match_mujoco(tmp_path_factory, seed, axis, quat, slide):
    """Random 3-body chains: oblique axes, rotated bodies and inertials, anchors off the body
    origin, a reference position (``ref``), hinge or slide: rnea = mj_inverse."""
    if np.linalg.norm(axis) < 0.1 or np.linalg.norm(quat) < 0.1:
        return
    rng = np.random.default_rng(seed)
    text, close = ['<mujoco><option gravity="0.5 -0.2 -9.8"/><worldbody>'], []
    for k in range(3):
        r = rng.uniform(-1, 1, 12)
        kind = "slide" if slide and k == 1 else "hinge"
        text.append(
            f'<body name="b{k}" pos="{r[0]:.3f} {r[1]:.3f} {r[2]:.3f}" '
            f'quat="{" ".join(f"{v:.4f}" for v in quat)}">'
            f'<joint name="j{k}" type="{kind}" pos="{r[3]:.3f} {r[4]:.3f} 0" ref="{r[0]:.2f}" '
            f'axis="{" ".join(f"{v:.4f}" for v in axis)}" armature="{abs(r[5]):.3f}"/>'
            f'<inertial pos="{r[6]:.3f} {r[7]:.3f} {r[8]:.3f}" '
            f'quat="{r[9]:.3f} {r[10]:.3f} {r[11]:.3f} 0.5" mass="{1 + abs(r[9]):.3f}" '
            f'diaginertia="0.03 0.035 {0.04 + abs(r[10]) / 50:.4f}"/>')
        close.append("</body>")
    text += close + ["</worldbody></mujoco>"]
    path = tmp_path_factory.mktemp("chain") / "chain.xml"
    path.write_text("".join(text))
    model = ci.RobotModel.from_mjcf(path)
    q, dq, ddq = _states(8, 3, seed % 1000)
    expected = _mj_inverse(path, q, dq, ddq)
    assert np.max(np.abs(model.rnea(q, dq, ddq) - expected)) < 1e-9 * np.abs(expected).max()


@pytest.mark.parametrize("change, match", [
    ('<body name="base" pos="0 0 0.1">', '<body name="base" pos="0 0 0.1"><freejoint name="fly"/>'),
    ('<joint name="j4" type="slide" axis="0 0 1" range="0 0.04"/>',
     '<joint name="j4" type="ball"/>'),
    ('<joint name="j1" axis="0 0 1" range="-2.9 2.9"/>',
     '<joint name="j1" axis="0 0 1"/><joint name="j1b" axis="1 0 0"/>'),
    ('<joint name="j4" type="slide"', '<joint type="slide"'),
])
def test_from_mjcf_refuses_by_name(tmp_path, change, match):
    text = ARM.replace(change, match)
    assert text != ARM
    with pytest.raises(ModelError, match=r"free joint|ball joint|more than one joint|no name"):
        ci.RobotModel.from_mjcf(_arm(tmp_path, text))


def test_from_mjcf_refuses_entities_and_other_files(tmp_path):
    bomb = ('<?xml version="1.0"?><!DOCTYPE m [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;">]>'
            '<mujoco model="&b;"><worldbody/></mujoco>')
    (tmp_path / "bomb.xml").write_text(bomb)
    with pytest.raises(ModelError, match="DTD or entity"):
        ci.RobotModel.from_mjcf(tmp_path / "bomb.xml")
    urdf = ci.RobotModel.example("ur5").source
    with pytest.raises(ModelError, match="not an MJCF"):
        ci.RobotModel.from_mjcf(urdf)
    with pytest.raises(ModelError, match="does not exist"):
        ci.RobotModel.from_mjcf(tmp_path / "none.xml")
    with pytest.raises(ModelError, match="unknown joint"):
        ci.RobotModel.from_mjcf(_arm(tmp_path), locked_joints=["nope"])


# ----------------------------------------------------------------------------- writing
EDITED = ("damping", "frictionloss", "armature", "pos", "mass", "fullinertia", "quat",
          "diaginertia")


def _strip(line: str) -> str:
    """A line without the attributes the writer may set (for comparing what else changed)."""
    for attr in EDITED:
        line = re.sub(rf"\s{attr}\s*=\s*([\"']).*?\1", "", line)
    return line


def _assert_only_edits(before: bytes, after: bytes, joints: set[str]) -> None:
    """Split into tags and text between them: every changed tag is a <joint> of ``joints`` or an
    <inertial> that differs in the edited attributes only; every inserted piece an <inertial/>
    tag with its indentation; all else (comments, spacing, other tags) is byte-identical."""
    token = re.compile(r"<!--.*?-->|<[^>]*>|[^<]+", re.S)
    a, b = token.findall(before.decode()), token.findall(after.decode())
    assert "".join(a) == before.decode() and "".join(b) == after.decode()
    for op, i1, i2, j1, j2 in difflib.SequenceMatcher(None, a, b, autojunk=False).get_opcodes():
        if op == "insert":
            assert re.fullmatch(r"\s*<inertial [^<>]*/>", "".join(b[j1:j2])), b[j1:j2]
            assert b[j1 - 1].startswith("<body "), b[j1 - 1]     # a body's first child
            continue
        if op == "equal":
            continue
        old, new = a[i1:i2], b[j1:j2]
        if len(new) == len(old) + 2 and new[0].startswith("<inertial ") and new[1].isspace():
            assert b[j1 - 2].startswith("<body "), b[j1 - 2]
            new = new[2:]                                  # inserted before a changed tag
        assert op == "replace" and len(old) == len(new), (op, old, new)
        for x, y in zip(old, new):
            name = re.match(r"<joint name=[\"'](\w+)", x)
            assert x.startswith("<inertial ") or (name and name.group(1) in joints), x
            assert _strip(x) == _strip(y), (x, y)


def _identified(model, seed):
    """Consistent 'identified' values: each body scaled and shifted a little (a rigid body
    moved and made heavier stays physically consistent), plus joint terms."""
    rng = np.random.default_rng(seed)
    theta = model.prior_parameters.copy()
    for i in range(model.n_bodies):
        theta[10 * i:10 * i + 10] *= rng.uniform(1.1, 1.4)
    names = list(model.parameter_names) + ["j1.fv", "j1.fc", "j1.Ia", "j2.Ia", "j3.fv", "j3.Ia"]
    return np.concatenate([theta, [0.3, 0.1, 0.07, 0.02, 0.5, 0.015]]), names


def test_written_into_the_users_file(tmp_path):
    """Identified values in, every other byte unchanged, MuJoCo compiles it, and its
    mj_inverse (damping on) = pin.rnea with the identified inertias + Ia·q̈ + f_v·q̇."""
    import pinocchio as pin

    path = _arm(tmp_path)
    model = ci.RobotModel.from_mjcf(path, locked_joints=["j4"])
    params, names = _identified(model, 3)
    before = path.read_bytes()
    with pytest.warns(ExportWarning) as caught:
        out = write_mjcf_into(model, tmp_path / "arm_identified.xml", path,
                                                 params, names)
    text = " ".join(str(w.message) for w in caught)
    assert "['link3'] had no <inertial>" in text                  # inertia from the mesh
    assert "j1.damping (class 'arm'" in text and "j3.armature (class 'wrist'" in text
    assert "j2.damping=1.1" in text                               # kept, not identified
    assert path.read_bytes() == before
    _assert_only_edits(before, out.read_bytes(), {"j1", "j2", "j3"})
    assert b"<!-- a small arm" in out.read_bytes() and b"name='j2'" in out.read_bytes()

    pm = model.with_parameters(params).pin_model
    named = dict(zip(names, params))
    fv = np.array([named.get(f"{j}.fv", d) for j, d in zip(model.joint_names, [0, 1.1, 0])])
    pm.armature = np.array([named[f"{j}.Ia"] for j in model.joint_names])
    data = pm.createData()
    q, dq, ddq = _states(20, 3, 4)
    expected = np.array([pin.rnea(pm, data, *s) for s in zip(q, dq, ddq)]) + fv * dq
    got = _mj_inverse(out, q, dq, ddq, damping=True)
    assert np.max(np.abs(got - expected)) < 1e-9 * np.abs(expected).max()
    back = ci.RobotModel.from_mjcf(out, locked_joints=["j4"])
    assert np.allclose(back.prior_parameters, params[:model.n_inertial], rtol=1e-12, atol=1e-15)


def test_writer_refusals(tmp_path):
    path = _arm(tmp_path)
    model = ci.RobotModel.from_mjcf(path, locked_joints=["j4"])
    params, names = _identified(model, 5)
    with pytest.raises(ModelError, match="write over"):
        write_mjcf_into(model, path, path, params, names)
    bad = params.copy()
    bad[10:20] = from_mass_com_inertia(2.0, [0, 0, 0], np.diag([0.01, 0.01, 0.05]))
    with pytest.raises(InconsistentParametersError, match="link2"):
        write_mjcf_into(model, tmp_path / "o.xml", path, bad, names)
    light = params.copy()
    light[20:30] = from_mass_com_inertia(0.05, [0, 0, 0.05], np.diag([1e-5, 1e-5, 1e-5]))
    with pytest.raises(InconsistentParametersError, match="flange"):   # lighter than its parts
        write_mjcf_into(model, tmp_path / "o.xml", path, light, names)
    negative = params.copy()
    negative[names.index("j1.fv")] = -0.1
    with pytest.raises(InconsistentParametersError, match="j1.*damping"):
        write_mjcf_into(model, tmp_path / "o.xml", path, negative, names)
    assert not (tmp_path / "o.xml").exists() and not list(tmp_path.glob(".o-*"))
    for old, new, match in [
            ('<compiler angle="radian"', '<compiler inertiafromgeom="true" angle="radian"',
             "inertiafromgeom"),
            ("<contact>", '<include file="extra.xml"/><contact>', "includes")]:
        other = tmp_path / "other"
        src = _arm(other, ARM.replace(old, new))
        (other / "extra.xml").write_text("<mujoco/>")
        with pytest.raises(ModelError, match=match):
            write_mjcf_into(model, other / "o.xml", src, params, names)
    bounded = _arm(tmp_path / "bounded", ARM.replace('<compiler angle="radian"',
                                                     '<compiler boundinertia="0.006" '
                                                     'angle="radian"'))
    model_b = ci.RobotModel.from_mjcf(bounded, locked_joints=["j4"])
    small = np.concatenate([model_b.prior_parameters, params[model.n_inertial:]])
    small[10:20] *= 0.4                         # consistent, but below the compiler's bound
    with pytest.raises(ModelError, match="link2.*boundinertia"):
        write_mjcf_into(model_b, tmp_path / "bounded" / "o.xml", bounded, small, names)
    assert sorted(p.name for p in (tmp_path / "bounded").iterdir()) == ["arm.xml", "assets"]
    for where, match in ((tmp_path / "none" / "o.xml", "no folder"), (tmp_path, "a folder")):
        with pytest.raises(ModelError, match=match):
            write_mjcf_into(model, where, path, params, names)
    (tmp_path / "elsewhere").mkdir()
    with pytest.raises(ModelError, match="relative path"):
        write_mjcf_into(model, tmp_path / "elsewhere" / "o.xml", path,
                                           params, names)
    with pytest.raises(ModelError, match="to_mjcf"):
        model.to_urdf(tmp_path / "o.urdf")


def _excitation(nv, seconds, seed, rate=100.0):
    """Sums of sinusoids per joint, with their exact derivatives."""
    rng = np.random.default_rng(seed)
    t = np.arange(0, seconds, 1 / rate)
    w = 2 * np.pi * rng.uniform(0.1, 0.6, (5, nv))
    a = rng.uniform(0.1, 0.35, (5, nv)) * rng.choice([-1, 1], (5, nv))
    ph = rng.uniform(0, 2 * np.pi, (5, nv))
    arg = w[None] * t[:, None, None] + ph[None]
    q = (a * np.sin(arg)).sum(1)
    dq = (a * w * np.cos(arg)).sum(1)
    ddq = (-a * w ** 2 * np.sin(arg)).sum(1)
    return t, q, dq, ddq


def test_identify_on_mujoco_data_and_write_back(tmp_path):
    """A Menagerie-like arm whose file's inertias are off (the nominal) is identified on
    torques MuJoCo computes with the true file (armature and damping on, noise), written back
    into the nominal file; MuJoCo's held-out inverse dynamics of the written file is the
    truth's to the noise level, and far better than the nominal's."""
    truth = _arm(tmp_path / "truth")
    wrong = {'mass="2.1"': 'mass="2.6"', 'mass="1.4"': 'mass="1.0"', 'density="2000"':
             'density="2600"', 'pos="0 0.01 0.1"': 'pos="0.02 0 0.08"',
             'damping="0.7" armature="0.05"': 'damping="0.4" armature="0.02"'}
    text = ARM
    for old, new in wrong.items():
        text = text.replace(old, new)
    nominal = _arm(tmp_path / "nominal", text)
    model = ci.RobotModel.from_mjcf(nominal, locked_joints=["j4"])
    sigma = 0.02
    t, q, dq, ddq = _excitation(3, 30.0, 7)
    tau = _mj_inverse(truth, q, dq, ddq, damping=True)
    tau += np.random.default_rng(8).normal(0, sigma, tau.shape)
    data = ci.Dataset(t=t, q=q, dq=dq, ddq=ddq, tau=tau, joint_names=model.joint_names)
    res = ci.identify(model, data, method="sdp", friction=("viscous",), armature=True)
    assert res.is_consistent
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExportWarning)
        out = res.to_mjcf(tmp_path / "nominal" / "identified.xml", source=nominal)
    t, q, dq, ddq = _excitation(3, 10.0, 99)
    held = _mj_inverse(truth, q, dq, ddq, damping=True)
    err = np.sqrt(np.mean((_mj_inverse(out, q, dq, ddq, damping=True) - held) ** 2, axis=0))
    before = np.sqrt(np.mean((_mj_inverse(nominal, q, dq, ddq, damping=True) - held) ** 2,
                             axis=0))
    assert np.all(err < 3 * sigma), (err, before)
    assert np.all(err < before / 5), (err, before)
    saved = res.save(tmp_path / "result.json")             # the MJCF model reloads from it
    back = type(res).load(saved, urdf=nominal)
    assert back.model.source_format == "mjcf" and back.model.locked_joints == ("j4",)
    assert np.array_equal(back.parameters, res.parameters)


_names = st.sampled_from(["a", "pos", "mass", "b_c", "quat", "x1"])
_values = st.text(st.characters(codec="ascii", categories=["L", "N"],
                                include_characters=" .-=\"'"), max_size=12)


@settings(max_examples=60, deadline=None)
@given(attrs=st.dictionaries(_names, _values, max_size=5),
       quotes=st.lists(st.sampled_from(['"', "'"]), min_size=5, max_size=5),
       seps=st.lists(st.sampled_from([" ", "\n   ", "\t", "  "]), min_size=6, max_size=6),
       closing=st.sampled_from(["/>", " />", "></x>", ">\n</x>"]), name=_names,
       value=_values)
def test_attribute_edits_touch_only_their_span(attrs, quotes, seps, closing, name, value):
    """Setting (or removing) one attribute of a start tag written in any quoting and spacing
    changes that attribute only (as a parser sees it) and leaves the other bytes in place."""
    import xml.etree.ElementTree as ET

    from consistid.robot.xml_spans import apply, elements, remove_attribute, set_attribute

    attrs = {k: v.replace("'", "") if '"' in v else v for k, v in attrs.items()}
    value = value.replace('"', "").replace("'", "")    # written in double quotes
    quotes = ["'" if '"' in v else '"' if "'" in v else q
              for v, q in zip(attrs.values(), quotes)]
    parts = [f"{sep}{k}={q}{v}{q}" for (k, v), q, sep in zip(attrs.items(), quotes, seps)]
    text = f"<r><!-- c --><x{''.join(parts)}{seps[-1] if closing[0] == ' ' else ''}" \
           f"{closing.lstrip()}<y a='1'/></r>"
    data = text.encode()
    x = elements(data)[1]
    edited = apply(data, [set_attribute(data, x, name, value)])
    assert ET.fromstring(edited).find("x").attrib == {**attrs, name: value}
    assert edited.startswith(data[:x.start]) and edited.endswith(data[x.tag_end:])
    gone = remove_attribute(data, x, name)
    if name in attrs:
        removed = apply(data, [gone])
        assert ET.fromstring(removed).find("x").attrib == {k: v for k, v in attrs.items()
                                                           if k != name}
    else:
        assert gone is None


def test_scene_including_the_arm(tmp_path):
    """Menagerie's layout: scene.xml includes the arm's file. The model reads from the scene;
    the writer refuses the scene by name and writes into the included file (matched by names),
    here with the finger locked away from qpos0."""
    arm = _arm(tmp_path)
    scene = tmp_path / "scene.xml"
    scene.write_text('<mujoco model="scene">\n  <include file="arm.xml"/>\n  <worldbody>'
                     '<geom type="plane" size="1 1 0.1"/></worldbody>\n</mujoco>\n')
    lock = {"locked_joints": ["j4"], "locked_configuration": {"j4": 0.02}}
    model = ci.RobotModel.from_mjcf(scene, **lock)
    q, dq, ddq = _states(10, 3, 6)
    held = _mj_inverse(arm, np.c_[q, np.full(10, 0.02)], np.c_[dq, np.zeros(10)],
                       np.c_[ddq, np.zeros(10)])[:, :3]
    assert np.max(np.abs(model.rnea(q, dq, ddq) - held)) < 1e-9 * np.abs(held).max()
    params, names = _identified(model, 9)
    with pytest.raises(ModelError, match=r"includes \['arm.xml'\]"):
        write_mjcf_into(model, tmp_path / "o.xml", scene, params, names)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExportWarning)
        out = write_mjcf_into(model, tmp_path / "arm_identified.xml", arm, params, names)
    back = ci.RobotModel.from_mjcf(out, **lock)
    assert np.allclose(back.prior_parameters, params[:model.n_inertial], rtol=1e-12, atol=1e-15)


def test_cli_model_table_reads_an_mjcf(tmp_path):
    """``[model] mjcf = "…"`` in a run configuration loads the file with from_mjcf; a URDF key
    beside it is refused by name."""
    from consistid.cli.config import config_model, load_config
    from consistid.errors import ConfigError

    _arm(tmp_path)
    conf = tmp_path / "run.toml"
    conf.write_text('[model]\nmjcf = "arm.xml"\nlocked_joints = ["j4"]\nname = "mine"\n')
    model = config_model(load_config(conf))
    assert model.name == "mine" and model.joint_names == ["j1", "j2", "j3"]
    assert model.source_format == "mjcf"
    conf.write_text('[model]\nmjcf = "arm.xml"\nurdf = "arm.urdf"\n')
    with pytest.raises(ConfigError, match="takes no urdf"):
        config_model(load_config(conf))


def _png(path: Path) -> None:
    import matplotlib.pyplot as plt

    plt.imsave(path, np.random.default_rng(0).random((8, 8)), cmap="gray")


#: Source variants: the assets under ``assetdir`` with a texture, or named from the file's folder
#: without any ``<compiler>`` (MuJoCo's defaults then: degrees, no autolimits).
ASSET_LAYOUTS = {
    "assetdir": (ARM.replace('meshdir="assets"', 'assetdir="assets"').replace(
        "  <asset>\n", '  <asset>\n    <texture name="grid" type="2d" file="grid.png"/>\n')),
    "no compiler": (ARM.replace('  <compiler angle="radian" meshdir="assets" autolimits="true"/>\n',
                                "").replace('file="link.stl"', 'file="assets/link.stl"')
                    .replace('file="tip.obj"', 'file="assets/tip.obj"')),
}


def _compiler_attrs(text: bytes) -> dict[str, str]:
    from consistid.robot.xml_spans import elements
    return {k: v for e in elements(text) if e.tag == "compiler" for k, v in e.attrs.items()}


@pytest.mark.parametrize("layout", list(ASSET_LAYOUTS))
def test_written_elsewhere_names_the_asset_folders_absolutely(tmp_path, layout):
    """A copy written outside the source's folder with absolute_assets=True compiles there with
    the source's meshes and textures; its <compiler> names the source's asset folders by
    absolute path and every other byte is the source's (as written in place); without the
    keyword the output is refused by name."""
    import mujoco

    path = _arm(tmp_path / "src", ASSET_LAYOUTS[layout])
    _png(tmp_path / "src" / "assets" / "grid.png")
    model = ci.RobotModel.from_mjcf(path, locked_joints=["j4"])
    params, names = _identified(model, 3)
    (tmp_path / "elsewhere").mkdir()
    with pytest.raises(ModelError, match="absolute_assets=True"):
        write_mjcf_into(model, tmp_path / "elsewhere" / "o.xml", path, params, names)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExportWarning)
        out = write_mjcf_into(model, tmp_path / "elsewhere" / "o.xml", path, params, names,
                              absolute_assets=True)
        beside = write_mjcf_into(model, tmp_path / "src" / "o.xml", path, params, names)
    src, got = mujoco.MjModel.from_xml_path(str(path)), mujoco.MjModel.from_xml_path(str(out))
    assert got.nmesh == 2 and np.array_equal(got.mesh_vert, src.mesh_vert)
    assert got.ntex == src.ntex and np.array_equal(got.tex_data, src.tex_data)
    compiler = _compiler_attrs(out.read_bytes())
    assert compiler.pop("meshdir") == compiler.pop("texturedir") == str(
        (tmp_path / "src" / ("assets" if layout == "assetdir" else "")).resolve())
    before = _compiler_attrs(path.read_bytes())
    before.pop("assetdir", None)
    assert compiler == before
    # every other byte is what the in-place writer writes: the <compiler> tag is the only change
    token = re.compile(rb"<compiler [^>]*>\n?\s*")
    assert token.sub(b"", out.read_bytes()) == token.sub(b"", beside.read_bytes())
    back = ci.RobotModel.from_mjcf(out, locked_joints=["j4"])
    assert np.allclose(back.prior_parameters, params[:model.n_inertial], rtol=1e-12, atol=1e-15)


def test_cli_identify_writes_the_users_mjcf_with_its_meshes(tmp_path, capsys):
    """``consistid identify --output DIR`` of a model read from an MJCF writes robot.xml as a
    copy of that MJCF (meshes by an absolute meshdir) that MuJoCo compiles from DIR, carrying
    the identified inertias; the source is untouched."""
    import mujoco
    from consistid.cli import main

    path = _arm(tmp_path / "arm")
    before = path.read_bytes()
    model = ci.RobotModel.from_mjcf(path, locked_joints=["j4"])
    t, q, dq, ddq = _excitation(3, 30.0, 7)
    tau = _mj_inverse(path, q, dq, ddq, damping=True)          # MuJoCo's torques: the truth
    tau += np.random.default_rng(8).normal(0, 0.02, tau.shape)
    (tmp_path / "data").mkdir()
    ci.Dataset(t=t, q=q, dq=dq, ddq=ddq, tau=tau, joint_names=model.joint_names).save(
        tmp_path / "data" / "run.npz")
    conf = tmp_path / "run.toml"
    conf.write_text('[model]\nmjcf = "arm/arm.xml"\nlocked_joints = ["j4"]\n'
                    '[data]\ndir = "data"\nkeys = "consistid"\ntrain = ["run.npz"]\n'
                    '[identify]\nfriction = ["viscous"]\narmature = true\n')
    out = tmp_path / "out"
    assert main(["identify", str(conf), "--output", str(out)]) == 0
    err = capsys.readouterr().err
    assert f"robot.xml: a copy of {path}" in err, err
    res = ci.IdentificationResult.load(out / "result.json", urdf=path)
    written = mujoco.MjModel.from_xml_path(str(out / "robot.xml"))
    assert written.nmesh == 2 and np.array_equal(
        written.mesh_vert, mujoco.MjModel.from_xml_path(str(path)).mesh_vert)
    assert _compiler_attrs((out / "robot.xml").read_bytes())["meshdir"] == str(
        (tmp_path / "arm" / "assets").resolve())
    back = ci.RobotModel.from_mjcf(out / "robot.xml", locked_joints=["j4"])
    assert np.allclose(back.prior_parameters, res.parameters[:model.n_inertial], rtol=1e-9,
                       atol=1e-12)
    assert path.read_bytes() == before

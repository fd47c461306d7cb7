"""Kinematic calibration against simulated truth.

The truth is always built independently of the estimator: a copy of the URDF whose joint origins
(``xyz``, ``rpy``) are perturbed as text and read back by Pinocchio's parser, encoder zero offsets
added to the joint coordinates, and measurements taken by Pinocchio's forward kinematics of that
model in a tracker frame, plus Gaussian noise.
"""

from __future__ import annotations

import difflib
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import scipy.linalg
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import consistid as ci
from consistid.kinematics import (CalibrationResult, KinematicParameters, calibrate_kinematics,
                                  select_poses)
from consistid.kinematics.measurements import as_measurements, residual_jacobian, residuals
from consistid.kinematics.parameters import random_configurations

from .conftest import PLANAR_2R, PLANAR_2R_VALUES

SIG_P, SIG_R = 1e-4, np.radians(0.05)          # the noise: 0.1 mm, 0.05°
TOOL_JOINT = {"ur5": ("tool0", "wrist_3_link-tool0_fixed_joint"),
              "panda": ("panda_hand_tcp", "panda_hand_tcp_joint")}


# --------------------------------------------------------------------------------- the truth
def perturb_urdf(text: str, edits: dict[str, tuple[np.ndarray, np.ndarray]]) -> str:
    """The URDF with ``xyz += dxyz`` and ``rpy += drpy`` on the named joints (ElementTree)."""
    root = ET.fromstring(text.encode())
    for joint in root.findall("joint"):              # not a <transmission>'s <joint>
        if joint.get("name") not in edits:
            continue
        dxyz, drpy = edits[joint.get("name")]
        origin = joint.find("origin")
        if origin is None:
            origin = ET.SubElement(joint, "origin")
        xyz = np.array([float(v) for v in origin.get("xyz", "0 0 0").split()]) + dxyz
        rpy = np.array([float(v) for v in origin.get("rpy", "0 0 0").split()]) + drpy
        origin.set("xyz", " ".join(repr(float(v)) for v in xyz))
        origin.set("rpy", " ".join(repr(float(v)) for v in rpy))
    return ET.tostring(root, encoding="unicode")


def perturbed_robot(model: ci.RobotModel, tmp: Path, seed: int, tool_joint: str | None,
                    mm: float = 2.0, deg: float = 0.5):
    """(truth model, zero offsets): every moving joint's origin and the tool's fixed joint
    perturbed uniformly by ±mm and ±deg per component, offsets ±deg."""
    rng = np.random.default_rng(seed)
    names = list(model.joint_names) + ([tool_joint] if tool_joint else [])
    edits = {n: (rng.uniform(-mm, mm, 3) * 1e-3, np.radians(rng.uniform(-deg, deg, 3)))
             for n in names}
    path = tmp / f"truth_{model.name}_{seed}.urdf"
    path.write_text(perturb_urdf(Path(model.source).read_text(), edits))
    truth = ci.RobotModel.from_urdf(path, locked_joints=model.locked_joints)
    return truth, np.radians(rng.uniform(-deg, deg, model.nv))


def measure(truth: ci.RobotModel, q: np.ndarray, offsets: np.ndarray, frame: str,
            tracker: pin.SE3, rng=None, kind: str = "pose") -> np.ndarray:
    """Poses (N, 4, 4) / positions (N, 3) of ``frame`` in the tracker frame for encoder
    readings ``q`` (true angles ``q + offsets``), with the issue's noise when ``rng`` is given."""
    pm = truth.pin_model
    data, fid = pm.createData(), pm.getFrameId(frame)
    out = []
    for qk in q:
        pin.framesForwardKinematics(pm, data, truth.configuration(qk + offsets))
        m = tracker * data.oMf[fid]
        rot, pos = np.array(m.rotation), np.array(m.translation)
        if rng is not None:
            pos = pos + rng.normal(0, SIG_P, 3)
            rot = rot @ Rotation.from_rotvec(rng.normal(0, SIG_R, 3)).as_matrix()
        out.append(pos if kind == "position" else np.block([[rot, pos[:, None]],
                                                             [np.zeros((1, 3)), 1.0]]))
    return np.array(out)


TRACKER = pin.SE3(Rotation.from_rotvec([0.3, -0.2, 1.1]).as_matrix(), np.array([1.5, -0.4, 0.3]))


@pytest.fixture(scope="module")
def ur5() -> ci.RobotModel:
    return ci.RobotModel.example("ur5")


@pytest.fixture(scope="module")
def poses50(ur5, panda):
    """50 D-optimal poses per robot (pose measurements, every parameter)."""
    return {name: select_poses(model, 50, TOOL_JOINT[name][0], "pose", seed=1)
            for name, model in (("ur5", ur5), ("panda", panda))}


# --------------------------------------------------------------------------------- derivatives
@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**16), robot=st.sampled_from(["ur5", "panda", "xarm7", "kinova"]))
def test_frame_twists_match_finite_differences(seed, robot):
    model = ci.RobotModel.example(robot)
    chart = KinematicParameters(model, ci.excitation.end_effector_frame(model), "pose")
    rng = np.random.default_rng(seed)
    values = np.zeros(chart.size)
    values[:chart.n_kinematic] = rng.normal(0, 0.02, chart.n_kinematic)
    for name in chart.fixed_axes:
        values[chart.index[name]] = 0.0
    q = random_configurations(model, 3, rng)
    _, _, tw = chart.frame_kinematics(values, q)
    h = 1e-6
    for i in range(chart.n_kinematic):
        if chart.names[i] in chart.fixed_axes:
            continue
        vp, vm = values.copy(), values.copy()
        vp[i] += h
        vm[i] -= h
        pp, rp, _ = chart.frame_kinematics(vp, q, False)
        pm_, rm, _ = chart.frame_kinematics(vm, q, False)
        lin = (pp - pm_) / (2 * h)
        ang = Rotation.from_matrix(np.einsum("nij,nkj->nik", rp, rm)).as_rotvec() / (2 * h)
        err = max(np.abs(lin - tw[:, :3, i]).max(), np.abs(ang - tw[:, 3:, i]).max())
        assert err < 1e-6, f"{robot}: d/d {chart.names[i]} differs from finite differences by {err}"


@pytest.mark.parametrize("kind", ["pose", "position", "distance"])
def test_residual_jacobian_matches_finite_differences(panda, kind):
    chart = KinematicParameters(panda, "panda_hand_tcp", kind)
    rng = np.random.default_rng(4)
    q = random_configurations(panda, 4, rng)
    values = rng.normal(0, 0.01, chart.size)
    base0 = pin.SE3(Rotation.from_rotvec([0.2, 0.1, -0.4]).as_matrix(), np.array([0.5, 0, 1]))
    anchor0 = np.array([0.4, 0.1, 0.2])
    meas = as_measurements(measure(panda, q, np.zeros(7), "panda_hand_tcp", TRACKER, rng,
                                   kind="position" if kind == "position" else "pose")
                           if kind != "distance" else rng.uniform(0.3, 0.6, 4))

    def res(v):
        pos, rot, _ = chart.frame_kinematics(v, q, False)
        base = chart.base_transform(v, base0)
        anchor = anchor0 + v[chart.n_kinematic:][:3] if kind == "distance" else None
        return residuals(meas, pos, rot, base, anchor)

    pos, rot, tw = chart.frame_kinematics(values, q)
    extra = values[chart.n_kinematic:]
    jac = residual_jacobian(meas, pos, rot, tw, chart.base_transform(values, base0),
                            np.zeros(3) if kind == "distance" else extra[3:6],
                            anchor0 + extra[:3] if kind == "distance" else None)
    h = 1e-7
    for i in range(chart.size):
        vp, vm = values.copy(), values.copy()
        vp[i] += h
        vm[i] -= h
        fd = (res(vp) - res(vm)) / (2 * h)
        assert np.allclose(fd, jac[:, :, i], atol=2e-6), chart.names[i]


# --------------------------------------------------------------------------------- exactness
@pytest.mark.parametrize("robot, kind", [("ur5", "pose"), ("panda", "position")])
def test_noise_free_calibration_reproduces_the_truth_everywhere(robot, kind, tmp_path, panda,
                                                                 ur5):
    model = {"ur5": ur5, "panda": panda}[robot]
    frame, tool_joint = TOOL_JOINT[robot]
    truth, offsets = perturbed_robot(model, tmp_path, 7, tool_joint)
    rng = np.random.default_rng(0)
    q = random_configurations(model, 60, rng)
    cal = calibrate_kinematics(model, q, measure(truth, q, offsets, frame, TRACKER, kind=kind),
                               frame=frame, sigma=1e-4 if kind == "position" else (1e-4, 1e-3))
    held = random_configurations(model, 40, rng)
    # the calibrated model and tracker frame predict the truth at configurations never measured
    err = cal.residuals(held, measure(truth, held, offsets, frame, TRACKER, kind=kind))
    assert np.abs(err).max() < 1e-9
    before = np.abs(cal.residuals_before).max()
    assert before > 1e-3                                   # the URDF was mm off
    assert cal.rejected == () and cal.chi2_reduced < 1e-6
    # ... and so does the model itself, through Pinocchio, in the fitted tracker frame
    pm, data = cal.model.pin_model, cal.model.pin_model.createData()
    tracker = pin.SE3(cal.base[:3, :3], cal.base[:3, 3])
    for qk, mk in zip(held[:5], measure(truth, held[:5], offsets, frame, TRACKER, kind="pose")):
        pin.framesForwardKinematics(pm, data, cal.model.configuration(qk))
        got = (tracker * data.oMf[pm.getFrameId(frame)]).homogeneous
        assert np.allclose(got[:3, 3], mk[:3, 3], atol=1e-9)
        if kind == "pose":
            assert np.allclose(got, mk, atol=1e-9)


def test_identifiable_counts_follow_the_complete_model_theory(ur5, panda, tmp_path):
    # Everett, Driels, Mooring 1987: 4 per revolute joint + 6 with pose measurements; position
    # measurements lose the 3 tool orientations. On a real (perturbed) robot:
    for model, (frame, tool_joint) in ((ur5, TOOL_JOINT["ur5"]), (panda, TOOL_JOINT["panda"])):
        truth, offsets = perturbed_robot(model, tmp_path, 2, tool_joint)
        q = random_configurations(model, 40, np.random.default_rng(0))
        poses = measure(truth, q, offsets, frame, TRACKER)
        cal = calibrate_kinematics(model, q, poses, frame=frame, sigma=(1e-4, 1e-3))
        assert cal.identified.sum() == 4 * model.nv + 6
        assert cal.null_residual < 1e-8                   # every reported direction is exact
        cal = calibrate_kinematics(model, q, poses[:, :3, 3], frame=frame, sigma=1e-4)
        assert cal.identified.sum() == 4 * model.nv + 3
        held = {u.held for u in cal.unidentifiable}
        assert {"tool.rx", "tool.ry", "tool.rz"} <= held  # a point has no orientation
        assert cal.null_residual < 1e-8 and not cal.held_at_solution


def test_a_point_on_the_last_axis_hides_that_joint_and_says_so(ur5):
    # the URDF's own tool0 lies on wrist_3's axis: with positions only, two combinations that
    # a real robot shows vanish exactly there; they are held and named, never left singular
    q = random_configurations(ur5, 40, np.random.default_rng(0))
    points = measure(ur5, q, np.zeros(6), "tool0", TRACKER, kind="position")
    cal = calibrate_kinematics(ur5, q, points, frame="tool0", sigma=1e-4)
    assert len(cal.held_at_solution) == 2
    assert cal.identified.sum() == 4 * 6 + 3 - 2
    assert np.all(np.isfinite(cal.std[cal.identified]))
    assert "special geometry" in cal.summary()
    assert np.abs(cal.residuals_after).max() < 1e-9


# --------------------------------------------------------------------------------- acceptance
def _fraction_within_3_sigma(model, frame, tool_joint, q, tmp, seed, kind="pose"):
    truth, offsets = perturbed_robot(model, tmp, seed, tool_joint)
    rng = np.random.default_rng(100 + seed)
    guess = TRACKER * pin.SE3(Rotation.from_rotvec([0.01, -0.02, 0.01]).as_matrix(),
                              np.array([0.01, 0.02, -0.01]))
    sigma = (SIG_P, SIG_R) if kind == "pose" else SIG_P
    cal = calibrate_kinematics(model, q, measure(truth, q, offsets, frame, TRACKER, rng, kind),
                               frame=frame, sigma=sigma, base=guess.homogeneous)
    # the truth in the estimator's chart: the unique corrections, with the held ones at the
    # URDF, that reproduce the (noise-free) truth exactly on many configurations
    dense = random_configurations(model, 200, np.random.default_rng(seed))
    rep = calibrate_kinematics(model, dense, measure(truth, dense, offsets, frame, TRACKER,
                                                     kind=kind), frame=frame, sigma=sigma,
                               base=guess.homogeneous)
    assert rep.chi2_reduced < 1e-8                        # the chart holds the truth exactly
    ok = cal.identified
    z = (cal.values[ok] - rep.values[ok]) / cal.std[ok]
    held = random_configurations(model, 50, rng)
    rms = cal.rms(held, measure(truth, held, offsets, frame, TRACKER, rng, kind))
    return cal, rep, z, rms, truth, offsets


@pytest.mark.parametrize("robot", ["ur5", "panda"])
def test_acceptance_within_3_sigma_and_noise_level(robot, ur5, panda, poses50, tmp_path):
    model = {"ur5": ur5, "panda": panda}[robot]
    frame, tool_joint = TOOL_JOINT[robot]
    cal, rep, z, rms, *_ = _fraction_within_3_sigma(model, frame, tool_joint,
                                                     poses50[robot].q, tmp_path, seed=11)
    assert np.mean(np.abs(z) < 3) >= 0.95, np.round(z, 2)
    assert np.all(np.abs(z) < 5)
    assert 0.7 < cal.chi2_reduced < 1.3                   # σ describes the residuals
    # held-out error within 1.2× the measurement noise (per component)
    assert rms["position"] < 1.2 * SIG_P and rms["orientation"] < 1.2 * SIG_R, rms
    assert cal.errors_before["position"].mean() > 10 * SIG_P      # and it was not before
    assert len(cal.unidentifiable) == len(cal.parameter_names) - cal.identified.sum()
    assert set(cal.identified_names) == set(rep.identified_names)


def _fd_jacobian(model_text: str, model: ci.RobotModel, names, q, frame, tool_joint):
    """d(pose of frame)/d(named correction) by central differences on perturbed URDF texts,
    the parameters' documented meaning implemented on its own (scipy rotations, ElementTree)."""
    root0 = ET.fromstring(model_text.encode())
    joints = {j.get("name"): j for j in root0.findall("joint")}

    def origin(j):
        o = joints[j].find("origin")
        xyz = np.array([float(v) for v in (o.get("xyz", "0 0 0") if o is not None
                                            else "0 0 0").split()])
        rpy = np.array([float(v) for v in (o.get("rpy", "0 0 0") if o is not None
                                            else "0 0 0").split()])
        return xyz, rpy

    def poses(edits, dq=None, axis=None):
        root = ET.fromstring(model_text.encode())
        for j in root.findall("joint"):
            name = j.get("name")
            if name in edits:
                xyz, rpy = edits[name]
                o = j.find("origin")
                if o is None:
                    o = ET.SubElement(j, "origin")
                o.set("xyz", " ".join(repr(float(v)) for v in xyz))
                o.set("rpy", " ".join(repr(float(v)) for v in rpy))
            if axis and name in axis:
                a = j.find("axis")
                a.set("xyz", " ".join(repr(float(v)) for v in axis[name]))
        pm = pin.buildModelFromXML(ET.tostring(root, encoding="unicode"))
        data, fid = pm.createData(), pm.getFrameId(frame)
        out = []
        for qk in q:
            qk = qk + (dq if dq is not None else 0)
            pin.framesForwardKinematics(pm, data, qk)
            out.append(pin.SE3(data.oMf[fid]))
        return out

    def diff(plus, minus, h):
        rows = []
        for mp, mm in zip(plus, minus):
            lin = (mp.translation - mm.translation) / (2 * h)
            ang = Rotation.from_matrix(mp.rotation @ mm.rotation.T).as_rotvec() / (2 * h)
            rows.append(np.concatenate([lin, ang]))
        return np.concatenate(rows)

    h = 1e-6
    cols = []
    for name in names:
        owner, _, suffix = name.rpartition(".")
        joint = tool_joint if owner == "tool" else owner
        plus_minus = []
        for s in (h, -h):
            if suffix == "zero":
                dq = np.zeros(model.nv)
                dq[model.joint_names.index(owner)] = s
                plus_minus.append(poses({}, dq=dq))
                continue
            xyz, rpy = origin(joint)
            if suffix in ("x", "y", "z"):
                xyz = xyz + s * np.eye(3)["xyz".index(suffix)]
                plus_minus.append(poses({joint: (xyz, rpy)}))
            elif suffix in ("rx", "ry", "rz"):
                rot = Rotation.from_euler("xyz", rpy).as_matrix() @ Rotation.from_rotvec(
                    s * np.eye(3)["xyz".index(suffix[1])]).as_matrix()
                plus_minus.append(poses({joint: (xyz, Rotation.from_matrix(rot).as_euler(
                    "xyz"))}))
            else:
                a0 = np.array([float(v) for v in joints[joint].find("axis").get("xyz").split()])
                k = int(np.argmax(np.abs(a0)))
                u, v = np.eye(3)[(k + 1) % 3], np.eye(3)[(k + 2) % 3]
                if a0[k] < 0:
                    u, v = v, u
                turn = u if suffix == "axis_u" else v
                plus_minus.append(poses({}, axis={
                    joint: Rotation.from_rotvec(s * turn).as_matrix() @ a0}))
        cols.append(diff(*plus_minus, h))
    return np.column_stack(cols)


@pytest.mark.filterwarnings("ignore:Gimbal lock")
def test_unidentifiable_directions_are_the_null_space_of_the_jacobian(ur5, tmp_path):
    frame, tool_joint = TOOL_JOINT["ur5"]
    text = Path(ur5.source).read_text()
    q = random_configurations(ur5, 30, np.random.default_rng(5))
    names = [n for n in KinematicParameters(ur5, frame, "pose").names
             if not n.startswith("base.")]
    # at the URDF: noise-free measurements in the robot's base frame, the estimate stays at 0
    cal = calibrate_kinematics(ur5, q, measure(ur5, q, np.zeros(6), frame, pin.SE3.Identity()),
                               frame=frame, parameters=["joints", "tool"], sigma=(1e-4, 1e-3))
    assert np.abs(cal.values).max() < 1e-10
    jac = _fd_jacobian(text, ur5, names, q, frame, tool_joint)
    s = np.linalg.svd(jac, compute_uv=False)
    rank = int(np.sum(s > 1e-6 * s[0]))
    assert rank == cal.identified.sum() == 4 * 6 + 6 - 0
    null_fd = scipy.linalg.null_space(jac, rcond=1e-6)
    angles = scipy.linalg.subspace_angles(null_fd, cal.null_space)
    assert null_fd.shape[1] == cal.null_space.shape[1] == len(names) - rank
    assert angles.max() < 1e-5
    # ... and at a perturbed truth: the calibration's null space is the truth's up to the
    # difference of the two points (parameters 2 mm / 0.5° apart)
    truth, offsets = perturbed_robot(ur5, tmp_path, 3, tool_joint)
    cal = calibrate_kinematics(ur5, q, measure(truth, q, offsets, frame, pin.SE3.Identity(),
                                               np.random.default_rng(1)),
                               frame=frame, parameters=["joints", "tool"], sigma=(SIG_P, SIG_R))
    jac_true = _fd_jacobian(Path(truth.source).read_text(), truth, names, q, frame, tool_joint)
    angles = scipy.linalg.subspace_angles(scipy.linalg.null_space(jac_true, rcond=1e-6),
                                          cal.null_space)
    assert angles.max() < 0.05
    # control: two parameters' meanings swapped gives a subspace the test tells apart
    a, b = names.index("wrist_2_joint.x"), names.index("wrist_2_joint.z")
    swapped = jac_true.copy()
    swapped[:, [a, b]] = swapped[:, [b, a]]
    control = scipy.linalg.subspace_angles(scipy.linalg.null_space(swapped, rcond=1e-6),
                                           cal.null_space)
    assert control.max() > 0.2

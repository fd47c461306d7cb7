"""Bounding ellipsoids from collision geometry: Khachiyan against closed forms, mesh readers,
URDF transforms (origin, fixed and locked joints, scale, package URIs), the Panda against
Pinocchio's own collision model, and the SDP with ``ellipsoids="collision"``.

Expected values are independent of :mod:`consistid.robot.shapes`: rotations from scipy's Euler
angles (URDF rpy = extrinsic x-y-z), the Panda's points from ``pinocchio.buildGeomFromUrdf``
(coal's mesh loader and Pinocchio's placements), realizability from the pseudo-inertia built by
its defining formula.
"""

from __future__ import annotations

import struct
import warnings

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import consistid as ci
from consistid.errors import GeometryWarning, InaccurateSolutionWarning, ModelError, OptionError
from consistid.robot.model import example_robot_data_dir
from consistid.robot.inertia import perturb
from consistid.robot.shapes import (collision_ellipsoids, collision_points,
                                    minimum_volume_ellipsoid, pad, read_mesh, semi_axes, volume)

from .test_sdp import j_matrix


def inside(ellipsoid, points: np.ndarray) -> np.ndarray:
    d = points - ellipsoid.center
    return np.einsum("ij,ij->i", d, np.linalg.solve(ellipsoid.shape, d.T).T)


# ------------------------------------------------------------------------------------ MVEE
def test_box_corners_give_sqrt3_times_the_half_sides():
    half = np.array([0.3, 0.1, 0.05])
    rot = Rotation.from_euler("xyz", [0.4, -0.7, 1.1]).as_matrix()
    centre = np.array([0.2, -0.1, 0.5])
    corners = np.array(np.meshgrid(*[[-1, 1]] * 3, indexing="ij")).reshape(3, -1).T * half
    e = minimum_volume_ellipsoid(corners @ rot.T + centre, tol=1e-10)
    np.testing.assert_allclose(e.center, centre, atol=1e-12)
    np.testing.assert_allclose(e.shape, rot @ np.diag(3 * half ** 2) @ rot.T, atol=1e-12)
    np.testing.assert_allclose(semi_axes(e), np.sort(np.sqrt(3) * half), rtol=1e-12)


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2 ** 32 - 1))
def test_points_on_an_ellipsoid_give_that_ellipsoid(seed):
    """Surface points (plus interior ones) of a random ellipsoid: its MVEE is that ellipsoid."""
    rng = np.random.default_rng(seed)
    axes = rng.uniform(0.05, 0.5, 3)
    rot = Rotation.random(random_state=seed).as_matrix()
    centre = rng.normal(0.0, 0.3, 3)
    dirs = rng.normal(size=(200, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    radii = np.concatenate([np.ones(150), rng.uniform(0.0, 0.9, 50)])
    pts = (dirs * radii[:, None] * axes) @ rot.T + centre
    e = minimum_volume_ellipsoid(pts, tol=1e-9)
    truth = rot @ np.diag(axes ** 2) @ rot.T
    np.testing.assert_allclose(e.center, centre, atol=1e-6 * axes.max())
    np.testing.assert_allclose(e.shape, truth, atol=1e-6 * axes.max() ** 2)
    assert np.all(inside(e, pts) <= 1 + 1e-12)


def test_one_dimension_and_degenerate_sets():
    e = minimum_volume_ellipsoid(np.array([[-1.0], [3.0], [0.5]]))
    assert e.center[0] == pytest.approx(1.0) and e.shape[0, 0] == pytest.approx(4.0)
    with pytest.raises(ModelError, match="span fewer than 3"):
        minimum_volume_ellipsoid(np.random.default_rng(0).normal(size=(20, 2)) @ np.eye(2, 3))


def test_iteration_cap_warns_but_still_encloses():
    pts = np.random.default_rng(1).normal(size=(300, 3))
    with pytest.warns(InaccurateSolutionWarning, match="max_iter=3"):
        e = minimum_volume_ellipsoid(pts, max_iter=3)
    assert np.all(inside(e, pts) <= 1 + 1e-12)
    assert volume(e) >= volume(minimum_volume_ellipsoid(pts, tol=1e-8))


def test_padding_adds_to_every_semi_axis():
    e = pad(ci.Ellipsoid.from_semi_axes([0, 0, 1], [0.1, 0.2, 0.3],
                                                     Rotation.from_euler("z", 0.3).as_matrix()),
            0.01)
    np.testing.assert_allclose(semi_axes(e), [0.11, 0.21, 0.31])


# ------------------------------------------------------------------------------------ meshes
TET = np.array([[0, 0, 0], [1, 0, 0], [0, 2, 0], [0, 0, 3]], dtype=float)
TRIANGLES = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]


def write_binary_stl(path, vertices):
    with open(path, "wb") as f:
        f.write(b"binary solid header".ljust(80, b" ") + struct.pack("<I", len(TRIANGLES)))
        for tri in TRIANGLES:
            f.write(struct.pack("<12fH", 0, 0, 0, *vertices[list(tri)].ravel(), 0))


def test_stl_binary_ascii_and_obj_give_the_vertices(tmp_path):
    write_binary_stl(tmp_path / "tet.stl", TET)
    facets = "".join("facet normal 0 0 0\n outer loop\n" + "".join(
        f"  vertex {x:.6e} {y} {z}\n" for x, y, z in TET[list(t)]) + " endloop\nendfacet\n"
        for t in TRIANGLES)
    (tmp_path / "tet_ascii.STL").write_text(f"solid tet\n{facets}endsolid tet\n")
    (tmp_path / "tet.obj").write_text("# tet\n" + "".join(f"v {x} {y} {z}\n" for x, y, z in TET)
                                      + "vn 0 0 1\nf 1 2 3\n")
    for name in ("tet.stl", "tet_ascii.STL", "tet.obj"):
        np.testing.assert_allclose(read_mesh(tmp_path / name), np.unique(TET, axis=0))
    (tmp_path / "bad.stl").write_bytes(b"\x00" * 90)
    with pytest.raises(ModelError, match="bad.stl"):
        read_mesh(tmp_path / "bad.stl")
    (tmp_path / "cloud.xyz").write_text("0 0 0\n")
    with pytest.raises(ModelError, match=r"cloud\.xyz.*\.xyz"):
        read_mesh(tmp_path / "cloud.xyz")


# ------------------------------------------------------------------------------------ URDF
URDF = """<?xml version="1.0"?>
<robot name="tiny">
  <link name="base"><collision><geometry><box size="1 1 1"/></geometry></collision></link>
  <link name="arm">
    <inertial><origin xyz="0.1 0 0"/><mass value="1"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
    <collision><origin xyz="0.1 0.02 -0.03" rpy="0.3 -0.2 0.5"/>
      <geometry><box size="0.4 0.1 0.06"/></geometry></collision>
  </link>
  <link name="tool">
    <inertial><mass value="0.2"/>
      <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial>
    <collision><origin xyz="0 0 0.05"/>
      <geometry><mesh filename="meshes/tet.stl" scale="0.02 0.02 0.02"/></geometry></collision>
  </link>
  <link name="finger">
    <inertial><mass value="0.05"/>
      <inertia ixx="1e-5" ixy="0" ixz="0" iyy="1e-5" iyz="0" izz="1e-5"/></inertial>
    <collision><geometry><mesh filename="package://tinypkg/tet.stl"/></geometry></collision>
  </link>
  <link name="link2">
    <inertial><origin xyz="0.1 0 0"/><mass value="0.5"/>
      <inertia ixx="0.005" ixy="0" ixz="0" iyy="0.005" iyz="0" izz="0.005"/></inertial>
  </link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/>
    <origin xyz="0 0 0.2" rpy="0 0.4 0"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" velocity="5" effort="50"/></joint>
  <joint name="mount" type="fixed"><parent link="arm"/><child link="tool"/>
    <origin xyz="0.4 0 0.01" rpy="0 0 1.0"/></joint>
  <joint name="slide" type="prismatic"><parent link="tool"/><child link="finger"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 1 0"/>
    <limit lower="0" upper="0.05" velocity="1" effort="10"/></joint>
  <joint name="j2" type="revolute"><parent link="tool"/><child link="link2"/>
    <origin xyz="0 0 0.2"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" velocity="5" effort="50"/></joint>
</robot>
"""


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    root = tmp_path_factory.mktemp("tiny")
    (root / "meshes").mkdir()
    (root / "pkgs" / "tinypkg").mkdir(parents=True)
    write_binary_stl(root / "meshes" / "tet.stl", TET)
    write_binary_stl(root / "pkgs" / "tinypkg" / "tet.stl", TET * 0.01)
    (root / "tiny.urdf").write_text(URDF)
    model = ci.RobotModel.from_urdf(root / "tiny.urdf", locked_joints=["slide"],
                                    locked_configuration={"slide": 0.03})
    return model, root


def rigid(xyz, rpy):
    t = np.eye(4)
    t[:3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()  # URDF rpy: extrinsic x, y, z
    t[:3, 3] = xyz
    return t


def apply(t, pts):
    return pts @ t[:3, :3].T + t[:3, 3]


def test_box_origin_fixed_and_locked_children_land_in_the_body_frame(tiny):
    model, root = tiny
    assert model.body_names == ["arm", "link2"]
    with pytest.warns(GeometryWarning, match="link2"):
        ell = collision_ellipsoids(model, package_dirs=[root / "pkgs"])
    assert list(ell) == ["arm"]  # link2 has no geometry; base is not a moving body
    half = np.array([0.2, 0.05, 0.03])
    box = rigid([0.1, 0.02, -0.03], [0.3, -0.2, 0.5])
    corners = np.array(np.meshgrid(*[[-1, 1]] * 3, indexing="ij")).reshape(3, -1).T * half
    tool = rigid([0.4, 0, 0.01], [0, 0, 1.0])
    finger = tool @ rigid([0, 0.03, 0.1], [0, 0, 0])          # slide locked at 0.03 along y
    expected = np.vstack([apply(box, corners),
                          apply(tool @ rigid([0, 0, 0.05], [0, 0, 0]), 0.02 * TET),
                          apply(finger, 0.01 * TET)])
    got = collision_points(model, package_dirs=[root / "pkgs"])["arm"]
    np.testing.assert_allclose(np.unique(got.round(12), axis=0),
                               np.unique(expected.round(12), axis=0), atol=1e-12)
    # the box alone: closed form in the body frame
    only_box = minimum_volume_ellipsoid(apply(box, corners), tol=1e-10)
    np.testing.assert_allclose(only_box.center, box[:3, 3], atol=1e-12)
    np.testing.assert_allclose(only_box.shape, box[:3, :3] @ np.diag(3 * half ** 2)
                               @ box[:3, :3].T, atol=1e-12)
    assert np.all(inside(ell["arm"], expected) <= 1 + 1e-12)


def test_unresolvable_mesh_names_link_and_uri(tiny):
    model, _ = tiny
    with pytest.raises(ModelError, match=r"link 'finger'.*package://tinypkg/tet\.stl"):
        collision_points(model)  # no package_dirs: tinypkg is nowhere


# ------------------------------------------------------------------------------------ Panda
@pytest.fixture(scope="module")
def panda_ellipsoids(panda):
    return collision_ellipsoids(panda)


def pinocchio_points(model) -> dict[str, np.ndarray]:
    """Body-frame collision vertices by Pinocchio's own geometry model (coal loads meshes)."""
    full = pin.buildModelFromUrdf(str(model.source))
    geom = pin.buildGeomFromUrdf(full, str(model.source), pin.GeometryType.COLLISION,
                                 package_dirs=[str(example_robot_data_dir().parents[1])])
    locked = [full.getJointId(j) for j in model.locked_joints]
    _, geom = pin.buildReducedModel(full, geom, locked, pin.neutral(full))
    out: dict[str, list] = {}
    for obj in geom.geometryObjects:
        if obj.parentJoint == 0:
            continue
        g = obj.geometry
        if type(g).__name__ == "Box":  # the fingers' boxes; meshes are BVH models
            v = np.array(np.meshgrid(*[[-1, 1]] * 3, indexing="ij")).reshape(3, -1).T * g.halfSide
        else:
            v = np.array(g.vertices())
        out.setdefault(model.body_names[obj.parentJoint - 1], []).append(
            v @ obj.placement.rotation.T + obj.placement.translation)
    return {b: np.vstack(v) for b, v in out.items()}


def test_panda_meshes_lie_in_their_not_too_large_ellipsoids(panda, panda_ellipsoids):
    """Every vertex inside; volume ≤ (π√3/2)·(axis-aligned box of the points): the points lie in
    that box, whose own MVEE (semi-axes √3 × half-sides) has exactly that volume."""
    points = pinocchio_points(panda)
    assert list(panda_ellipsoids) == panda.body_names == list(points)
    for body, e in panda_ellipsoids.items():
        pts = points[body]
        assert np.all(inside(e, pts) <= 1 + 1e-9), body
        box = np.prod(pts.max(axis=0) - pts.min(axis=0))
        assert volume(e) <= np.pi * np.sqrt(3) / 2 * box, body
    # the hand and fingers belong to the last body
    assert points["panda_link7"][:, 2].max() > 0.107 + 0.05


def test_panda_prior_centres_of_mass_are_inside(panda, panda_ellipsoids):
    """The URDF CoMs all lie in their bodies' ellipsoids (a check of the frames). The LMI
    tr(J Q) ≥ 0 is NOT asserted: the Panda URDF's inertias are too large for its geometry."""
    prior = panda.prior_parameters.reshape(-1, 10)
    for body, p in zip(panda.body_names, prior):
        assert panda_ellipsoids[body].contains(p[1:4] / p[0]), body


# ------------------------------------------------------------------------------------ SDP
def test_sdp_with_collision_ellipsoids_satisfies_every_ellipsoid(panda, panda_ellipsoids):
    truth = perturb(panda.prior_parameters, 0.2, np.random.default_rng(3))
    data = ci.simulate.excitation_run(panda, truth, 4.0, 50.0, torque_noise=0.1,
                                      friction=None, seed=1).dataset
    res = ci.identify(panda, data, friction=(), constraints="ellipsoid",
                      ellipsoids="collision")
    assert res.solver.status == "optimal"
    for body, x in zip(panda.body_names, res.parameters.reshape(-1, 10)):
        j = j_matrix(x)
        assert np.linalg.eigvalsh(j)[0] > 0, body
        assert np.trace(j @ panda_ellipsoids[body].q_matrix()) >= -1e-6 * x[0], body
    with pytest.raises(OptionError, match="none is"):
        ci.identify(panda, data, friction=(), ellipsoids="collision")
    with pytest.raises(OptionError, match="'collision'"):
        ci.identify(panda, data, friction=(), constraints="ellipsoid", ellipsoids="mesh")


def test_bodies_without_geometry_keep_pseudo_inertia(tiny):
    model, root = tiny
    data = ci.simulate.excitation_run(model, model.prior_parameters, 3.0, 50.0,
                                      torque_noise=0.01, friction=None, seed=2).dataset
    # the finger's package:// mesh needs package_dirs: collision ellipsoids only resolve
    # what the URDF alone names, so drop it from a copy for the SDP's default lookup
    urdf = root / "tiny_nofinger.urdf"
    urdf.write_text(URDF.replace('<geometry><mesh filename="package://tinypkg/tet.stl"/>'
                                 '</geometry>', '<geometry><box size="0.01 0.01 0.01"/>'
                                 '</geometry>'))
    model = ci.RobotModel.from_urdf(urdf, locked_joints=["slide"],
                                    locked_configuration={"slide": 0.03})
    with pytest.warns(GeometryWarning, match="link2"):
        res = ci.identify(model, data, friction=(), constraints="ellipsoid",
                          ellipsoids="collision")
    assert res.details["constraints"].startswith("arm=ellipsoid, link2=pseudo-inertia")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GeometryWarning)
        with pytest.raises(OptionError, match=r"\['link2'\].*no <collision>"):
            ci.identify(model, data, friction=(), constraints={"link2": "ellipsoid"},
                        ellipsoids="collision")


def test_config_passes_collision_on(tmp_path):
    from consistid.cli.config import config_identify, load_config
    from consistid.errors import ConfigError

    path = tmp_path / "run.toml"
    path.write_text('[identify]\nconstraints = "ellipsoid"\nellipsoids = "collision"\n')
    options = config_identify(load_config(path))
    assert options["constraints"] == "ellipsoid" and options["ellipsoids"] == "collision"
    path.write_text('[identify]\nellipsoids = "mesh"\n')
    with pytest.raises(ConfigError, match="identify.ellipsoids"):
        config_identify(load_config(path))

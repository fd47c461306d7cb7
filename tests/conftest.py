"""Shared fixtures: robots built once per session, a planar 2R arm with a closed form."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import consistid as ci
from consistid.identification import base

SHARED = Path(__file__).resolve().parents[1].parent / "shared"

PLANAR_2R = """<?xml version="1.0"?>
<robot name="planar2r">
  <link name="base"/>
  <link name="link1">
    <inertial><origin xyz="{d1} 0 0"/><mass value="{m1}"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.045" iyz="0" izz="{i1}"/></inertial>
  </link>
  <link name="link2">
    <inertial><origin xyz="{d2} 0 0"/><mass value="{m2}"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.03" iyz="0" izz="{i2}"/></inertial>
  </link>
  <joint name="joint1" type="revolute"><parent link="base"/><child link="link1"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="5" effort="100"/></joint>
  <joint name="joint2" type="revolute"><parent link="link1"/><child link="link2"/>
    <origin xyz="{l1} 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" velocity="5" effort="100"/></joint>
</robot>
"""

#: Inertias about the CoM satisfy the triangle inequalities strictly (a solid body), so the 2R
#: arm also serves the SDP, log-det prior, recovery and export tests.
PLANAR_2R_VALUES = dict(m1=2.0, d1=0.4, i1=0.05, m2=1.5, d2=0.3, i2=0.035, l1=0.8)


@pytest.fixture(scope="session")
def panda() -> ci.RobotModel:
    return ci.RobotModel.example("panda")


@pytest.fixture(scope="session")
def planar_2r(tmp_path_factory) -> ci.RobotModel:
    """A planar 2R arm moving in the x-y plane, gravity along −y, CoM on the link axes."""
    path = tmp_path_factory.mktemp("urdf") / "planar2r.urdf"
    path.write_text(PLANAR_2R.format(**PLANAR_2R_VALUES))
    return ci.RobotModel.from_urdf(path, gravity=(0.0, -9.81, 0.0))


@pytest.fixture(scope="session")
def kuka_dir() -> Path:
    folder = SHARED / "data" / "kuka_lwr4"
    if not folder.is_dir():
        pytest.skip(f"real KUKA data not found at {folder} (shared/ is not beside the checkout)")
    return folder


def random_states(model: ci.RobotModel, n: int, seed: int):
    """:func:`consistid.identification.base.random_states` seeded by an integer (hypothesis draws
    integers)."""
    return base.random_states(model, n, np.random.default_rng(seed))


@pytest.fixture()
def cli_project(tmp_path, planar_2r) -> Path:
    """A URDF and two logs (consistid layout) under data/, an empty conf/ for configurations:
    the folder a CLI test writes its TOML into."""
    data = tmp_path / "data"
    data.mkdir()
    (data / "arm.urdf").write_text(PLANAR_2R.format(**PLANAR_2R_VALUES))
    rng = np.random.default_rng(0)
    for k in (1, 2):
        q, dq, ddq = random_states(planar_2r, 300, rng)
        tau = planar_2r.rnea(q, dq, ddq) + 0.01 * rng.standard_normal(q.shape)
        ci.Dataset(t=0.005 * np.arange(300), q=q, dq=dq, ddq=ddq, tau=tau).save(
            data / f"run{k}.npz")
    (tmp_path / "conf").mkdir()
    return tmp_path

"""The UR5, UR10, xArm7 and Kinova example configurations (``examples/<arm>/identify.toml``) run on
their committed logs, each written in its robot's own logger layout, and the generator
reproduces those logs (issue 31)."""

from __future__ import annotations

import runpy
import sys

import numpy as np
import pytest

import consistid as ci
from consistid.cli import main
from consistid.cli.commands import IDENTIFY_OUTPUTS

from .test_examples import EXAMPLES, checkout  # noqa: F401  (the fixture)

ARMS = {"ur5": ("robot_data", "Universal Robots RTDE"),
        "ur10": ("robot_data", "Universal Robots RTDE"),
        "xarm7": ("joint_states", "ROS JointState"),
        "kinova": ("joint_states", "ROS JointState")}


@pytest.mark.slow
@pytest.mark.parametrize("arm", list(ARMS))
def test_arm_example_identifies(checkout, arm, capsys):  # noqa: F811
    out = checkout / "out" / f"{arm}_identify"
    assert main(["-q", "identify", f"examples/{arm}/identify.toml", "--output", str(out)]) == 0
    assert {p.name for p in out.iterdir()} == set(IDENTIFY_OUTPUTS)
    res = ci.IdentificationResult.load(out / "result.json")
    model = ci.RobotModel.example(arm)
    assert list(res.model.joint_names) == list(model.joint_names) and res.is_consistent
    stem, logger = ARMS[arm]
    rec = ci.load_recording(EXAMPLES / arm / "data" / f"{stem}_train.csv", model=model)
    assert logger in rec.steps[0]
    if arm == "ur10":          # the measured torque, not the commanded target_moment beside it
        assert "tau←'actual_current_as_torque_0'" in rec.steps[0]
    # on the held-out log the identified model predicts every joint's torque better than the
    # URDF does (its RNEA torque, no friction: the model a user starts from)
    held = ci.load_recording(EXAMPLES / arm / "data" / f"{stem}_held_out.csv",
                             model=model).dataset
    urdf = np.sqrt(np.mean((held.tau - model.rnea(held.q, held.dq, held.ddq)) ** 2, axis=0))
    assert np.all(res.rms(held) < urdf), (res.rms(held), urdf)
    assert "Torque fit" in capsys.readouterr().out


def test_the_arm_generator_reproduces_the_committed_logs(tmp_path, monkeypatch):
    monkeypatch.setattr(sys, "argv", ["make_arm_logs.py", str(tmp_path)])
    runpy.run_path(str(EXAMPLES / "make_arm_logs.py"), run_name="__main__")
    for arm in ARMS:
        committed = EXAMPLES / arm / "data"
        assert {p.name for p in (tmp_path / arm).iterdir()} == {p.name for p in
                                                                 committed.iterdir()}
        for path in committed.iterdir():
            new, old = (tmp_path / arm / path.name).read_text(), path.read_text()
            assert new.splitlines()[0] == old.splitlines()[0], path.name
            sep = " " if arm == "ur5" else ","
            numeric = [k for k, c in enumerate(old.splitlines()[1].split(sep))
                       if c.lstrip("-").replace(".", "", 1).replace("e", "", 1)
                       .replace("-", "").replace("+", "").isdigit()]
            a = np.loadtxt(path, delimiter=None if sep == " " else sep, skiprows=1,
                           usecols=numeric)
            b = np.loadtxt(tmp_path / arm / path.name, delimiter=None if sep == " " else sep,
                           skiprows=1, usecols=numeric)
            np.testing.assert_allclose(b, a, rtol=1e-5, atol=1e-5, err_msg=path.name)
        assert sum(p.stat().st_size for p in committed.iterdir()) < 400_000

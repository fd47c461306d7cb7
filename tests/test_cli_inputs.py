"""Every ``consistid`` subcommand that reads logs takes what the loader takes — a ROS 2 bag
folder as well as a file — and checks its inputs before the work (issue 31: ``identify
--output`` ran the whole identification on a bag folder, then refused to record it)."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

import consistid as ci
from consistid.cli import main

from .conftest import PLANAR_2R, PLANAR_2R_VALUES
from .test_formats import write_bag

NS0 = 1_700_000_000_000_000_000


def _bag(path: Path, model: ci.RobotModel, seed: int) -> Path:
    """A real ROS 2 bag (rosbags' writer, MCAP) of JointState messages at 500 Hz: a smooth
    motion of the planar 2R arm and its RNEA torque plus noise."""
    n, rng = 2000, np.random.default_rng(seed)
    s = np.arange(n) * 0.002
    w = rng.uniform(0.8, 1.6, 2)
    q = np.column_stack([np.sin(w[0] * s), 0.8 * np.cos(w[1] * s)])
    dq = np.column_stack([w[0] * np.cos(w[0] * s), -0.8 * w[1] * np.sin(w[1] * s)])
    ddq = np.column_stack([-w[0] ** 2 * np.sin(w[0] * s), -0.8 * w[1] ** 2 * np.cos(w[1] * s)])
    tau = model.rnea(q, dq, ddq) + 0.01 * rng.standard_normal(q.shape)
    log = dict(ns=NS0 + np.arange(n, dtype=np.int64) * 2_000_000, names=("joint1", "joint2"),
               q=q, dq=dq, tau=tau)
    return write_bag(path, _three(log))


def _three(log: dict) -> dict:
    """``write_bag`` writes three joints: a gripper that the model does not have."""
    n = log["q"].shape[0]
    return {**log, "names": (*log["names"], "gripper"),
            **{k: np.column_stack([log[k], np.zeros(n)]) for k in ("q", "dq", "tau")}}


@pytest.fixture()
def bag_project(tmp_path, planar_2r):
    pytest.importorskip("rosbags")
    data = tmp_path / "data"
    data.mkdir()
    (data / "arm.urdf").write_text(PLANAR_2R.format(**PLANAR_2R_VALUES))
    _bag(data / "bag_twojs_1", planar_2r, 1)
    _bag(data / "bag_twojs_2", planar_2r, 2)
    config = tmp_path / "identify.toml"
    config.write_text('[model]\nurdf = "data/arm.urdf"\ngravity = [0.0, -9.81, 0.0]\n'
                      '[data]\ndir = "data"\ntrain = ["bag_twojs_1"]\nheld_out = ["bag_twojs_2"]\n'
                      '[identify]\nmethod = "ols"\nfriction = []\n')
    return config


def test_identify_output_records_a_bag_folder(bag_project, tmp_path, capsys):
    """The files are written, and the provenance records the bag folder by the SHA-256 of its
    listing (each file's path and SHA-256), computed here independently."""
    out = tmp_path / "out"
    assert main(["-q", "identify", str(bag_project), "--output", str(out)]) == 0
    assert {"result.json", "parameters.csv", "report.html"} <= {p.name for p in out.iterdir()}
    inputs = json.loads((out / "result.json").read_text())["provenance"]["inputs"]
    bag = (bag_project.parent / "data" / "bag_twojs_1").resolve()
    (record,) = [r for r in inputs if r["path"] == str(bag)]
    files = sorted(p for p in bag.rglob("*") if p.is_file())
    assert {p.name for p in files} >= {"metadata.yaml"} and len(files) >= 2
    listing = "".join(f"{p.relative_to(bag).as_posix()} "
                      f"{hashlib.sha256(p.read_bytes()).hexdigest()}\n" for p in files)
    assert record["sha256"] == hashlib.sha256(listing.encode()).hexdigest()
    assert record["bytes"] == sum(p.stat().st_size for p in files) and record["folder"]
    res = ci.IdentificationResult.load(out / "result.json")
    assert list(res.model.joint_names) == ["joint1", "joint2"]


def test_a_missing_input_is_refused_before_the_work(bag_project, tmp_path, capsys):
    """A bag folder that is not there ends the run before any log is read or fitted, and
    nothing is written."""
    text = bag_project.read_text().replace('held_out = ["bag_twojs_2"]', 'held_out = ["gone"]')
    bag_project.write_text(text)
    out = tmp_path / "out"
    assert main(["identify", str(bag_project), "--output", str(out)]) == 2
    err = capsys.readouterr().err
    assert "gone' does not exist" in err
    assert "identifying" not in err and not out.exists()


def test_recover_reads_a_bag_folder(bag_project, capsys):
    """``recover`` (OLS on the [data] logs) takes the bag folder like ``identify``."""
    bag_project.write_text(bag_project.read_text() + '[recover]\nmode = "nearest"\n')
    assert main(["-q", "recover", str(bag_project)]) == 0
    assert "link2" in capsys.readouterr().out

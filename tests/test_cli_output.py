"""The ``consistid`` command's outputs: identify --output, demo --output, any URDF,
--version, -q, and error hints in TOML syntax."""

from __future__ import annotations

import hashlib
import re
import json
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

import consistid as ci
from consistid.cli import commands, main
from consistid.cli.config import config_identify, config_recordings, load_config
from consistid.cli.hints import toml_hints
from consistid.identification.base import random_states

from .test_export import ARM_3R
from .test_report_html import check_html

CONFIG = """root = ".."
[model]
urdf = "data/arm3r.urdf"
[data]
dir = "data"
joint_names = ["j1", "j2", "j3"]
train = ["run1.npz"]
held_out = ["run2.npz"]
[identify]
method = "sdp"
friction = ["coulomb", "viscous"]
"""
FC, FV = np.array([0.7, 1.1, 0.3]), np.array([0.4, 0.9, 0.15])


@pytest.fixture()
def project(tmp_path):
    """A 3R arm whose URDF has ROS transmissions, two logs (FloBaRoID layout), a config."""
    data = tmp_path / "data"
    data.mkdir()
    (data / "arm3r.urdf").write_text(ARM_3R)
    model = ci.RobotModel.from_urdf(data / "arm3r.urdf")
    rng = np.random.default_rng(0)
    for k in (1, 2):
        q, dq, ddq = random_states(model, 400, rng)
        tau = (model.rnea(q, dq, ddq) + FC * np.sign(dq) + FV * dq
               + 0.01 * rng.standard_normal(q.shape))
        np.savez(data / f"run{k}.npz", times=0.005 * np.arange(400), positions=q,
                 velocities=dq, accelerations=ddq, torques=tau)
    (tmp_path / "conf").mkdir()
    config = tmp_path / "conf" / "run.toml"
    config.write_text(CONFIG)
    return config


def test_version(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith(f"consistid {ci.__version__} (") and "pinocchio" in out


def test_identify_output_writes_every_file(project, tmp_path, capsys):
    import mujoco
    import pinocchio as pin

    out = tmp_path / "out"
    assert main(["-q", "identify", str(project), "--output", str(out)]) == 0
    assert {p.name for p in out.iterdir()} == {"result.json", "parameters.csv", "robot.urdf",
                                               "robot.xml", "report.html"}
    assert f"report: {out / 'report.html'}" in capsys.readouterr().out
    # the JSON is the identification the API gives on the same configuration
    config = load_config(project)
    res = ci.IdentificationResult.load(out / "result.json")
    train, held = config_recordings(config, res.model)
    api = ci.identify(res.model, train.dataset, **config_identify(config))
    assert np.allclose(res.parameters, api.parameters, rtol=1e-9, atol=1e-12)
    assert np.max(np.abs(res.predict(held.dataset) - api.predict(held.dataset))) < 1e-9
    # provenance: the inputs' SHA-256 and the configuration
    records = {r["path"]: r["sha256"] for r in res.provenance["inputs"]}
    for name in ("data/run1.npz", "data/run2.npz", "data/arm3r.urdf", "conf/run.toml"):
        path = (tmp_path / name).resolve()
        assert records[str(path)] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert res.provenance["config"]["identify"] == {"method": "sdp",
                                                    "friction": ["coulomb", "viscous"]}
    # the URDF carries the identified friction in the joints (not the transmissions)
    named = dict(zip(res.parameter_names, res.parameters))
    fc = [named[f"{j}.fc"] for j in res.model.joint_names]
    back = pin.buildModelFromUrdf(str(out / "robot.urdf"))
    assert np.allclose(back.friction, fc, rtol=1e-12)
    assert np.allclose(fc, FC, rtol=0.05)
    mujoco.MjModel.from_xml_path(str(out / "robot.xml"))
    check_html((out / "report.html").read_text(), n_images=9)


def test_identify_output_is_checked_first_and_needs_force(project, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "report.html").write_text("mine")
    assert main(["identify", str(project), "--output", str(out)]) == 2
    err = capsys.readouterr().err
    assert "report.html" in err and "--force" in err
    assert (out / "report.html").read_text() == "mine"
    assert not (out / "result.json").exists()              # refused before any work
    assert main(["-q", "identify", str(project), "--output", str(out), "--force"]) == 0
    assert (out / "report.html").read_text().startswith("<!DOCTYPE html>")


def test_quiet_silences_the_step_messages(project, capsys):
    assert main(["identify", str(project)]) == 0
    assert "identifying" in capsys.readouterr().err
    assert main(["identify", str(project), "-q"]) == 0          # after the subcommand too
    captured = capsys.readouterr()
    assert captured.err == "" and "base parameter" in captured.out


def test_errors_give_toml_hints(project, capsys):
    project.write_text(CONFIG.replace('method = "sdp"', 'method = "sdp"\nprior = "flat"'))
    assert main(["identify", str(project)]) == 2
    err = capsys.readouterr().err
    assert 'prior = "flat"' in err and "prior='flat'" not in err


def test_demo_writes_only_where_asked_from_any_urdf(project, tmp_path, monkeypatch, capsys):
    """Without --output the demo prints and writes nothing (the current folder stays empty);
    with it, the named folder receives the set, and existing files there need --force."""
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    monkeypatch.chdir(cwd)
    urdf = project.parent.parent / "data" / "arm3r.urdf"
    args = ["demo", "--urdf", str(urdf), "--duration", "4", "--rate", "200"]
    assert main(args) == 0
    out = capsys.readouterr()
    assert "no file written; consistid demo --output DIR writes report.html" in out.err
    assert "report:" not in out.out and "j3" in out.out and list(cwd.iterdir()) == []
    folder = tmp_path / "demo"
    assert main(["-q", *args, "--output", str(folder)]) == 0
    assert f"report: {folder / 'report.html'}" in capsys.readouterr().out
    check_html((folder / "report.html").read_text(), n_images=9)
    assert sorted(p.name for p in folder.iterdir()) == sorted(commands.DEMO_OUTPUTS)
    assert ci.IdentificationResult.load(folder / "result.json").model.nv == 3
    monkeypatch.setattr(ci.simulate, "excitation_run", lambda *a, **k: pytest.fail("ran"))
    assert main([*args, "--output", str(folder)]) == 2           # checked before the work
    assert "exists; pass --force" in capsys.readouterr().err


def test_simulate_takes_any_urdf(project, capsys):
    urdf = project.parent.parent / "data" / "arm3r.urdf"
    assert main(["-q", "simulate", "--urdf", str(urdf), "--duration", "2"]) == 0
    assert "j3" in capsys.readouterr().out
    assert main(["-q", "simulate", "--robot", "ur5", "--lock", "elbow_joint"]) == 2


# ------------------------------------------------------------------ hints, as TOML reads them
@pytest.mark.parametrize("message, expected", [
    ("mode='nearest' is not supported; allowed: 'exact', 'nearest'",
     'mode = "nearest" is not supported; allowed: "exact", "nearest"'),
    ("use merged='lump'", 'use merged = "lump"'),
    ("friction=('coulomb', 'viscous'), armature=True", 'friction = ["coulomb", "viscous"], '
                                                       "armature = true"),
    ("prior=None has none", "prior=None has none"),              # TOML has no null
    ("a == b, f(x=g(y)), sigma=0.5", "a == b, f(x=g(y)), sigma = 0.5"),
])
def test_toml_hints(message, expected):
    assert toml_hints(message) == expected


_names = st.from_regex(r"[a-z][a-z_]{0,8}", fullmatch=True)
_scalars = st.one_of(st.booleans(), st.integers(-10**6, 10**6),
                     st.floats(allow_nan=False, allow_infinity=False, width=32),
                     st.text(st.characters(blacklist_categories=("Cs", "Cc")), max_size=10))
_values = st.one_of(_scalars, st.lists(st.text(alphabet="abcxyz_", max_size=6), max_size=3)
                    .map(tuple))


@settings(max_examples=200, deadline=None)
@given(_names, _values)
def test_every_hint_is_valid_toml(name, value):
    """Whatever Python literal a message shows, the rewritten hint parses as TOML to it."""
    hint = toml_hints(f"{name}={value!r}")
    parsed = tomllib.loads(hint)[name]
    assert parsed == (list(value) if isinstance(value, tuple) else value)


# ------------------------------------------------------------------ progress
def test_progress_argument(monkeypatch, capsys):
    """None: a bar only on a terminal; True: a bar; False: nothing; a callable: lines."""
    from consistid.progress import Progress

    class Terminal:
        def __init__(self, tty):
            self.tty, self.text = tty, []

        def isatty(self):
            return self.tty

        def write(self, s):
            self.text.append(s)

        def flush(self):
            pass

    for tty, progress, drawn in ((True, None, True), (False, None, False), (False, True, True),
                                 (True, False, False)):
        stream = Terminal(tty)
        monkeypatch.setattr(sys, "stderr", stream)
        with Progress(progress, 3, "work") as bar:
            for k in range(3):
                bar.step(f"item {k}")
        assert ("work" in "".join(stream.text)) == drawn, (tty, progress)
    from consistid.progress import silenced

    stream = Terminal(True)
    monkeypatch.setattr(sys, "stderr", stream)
    with silenced(), Progress(None, 3, "work") as bar:          # what -q does in the CLI
        bar.step()
    with silenced(), Progress(True, 3, "forced") as bar:
        bar.step()
    assert "work" not in "".join(stream.text) and "forced" in "".join(stream.text)
    lines = []
    with Progress(lines.append, 2, "work") as bar:
        bar.step("a")
        bar.step("b")
    assert lines == ["work 1/2: a", "work 2/2: b"]
    with pytest.raises(ci.OptionError, match="progress"):
        Progress("yes", 2, "work")
    # without tqdm: a bar asked for is a named error, the automatic one is simply not drawn
    monkeypatch.setitem(sys.modules, "tqdm", None)
    monkeypatch.setitem(sys.modules, "tqdm.auto", None)
    with pytest.raises(ci.MissingDependencyError, match="pip install tqdm"):
        Progress(True, 2, "work")
    with Progress(None, 2, "work") as bar:
        bar.step()
        assert bar.bar is None


def test_diagnose_and_design_take_progress(capsys):
    model = ci.RobotModel.example("ur5")
    lines: list[str] = []
    rng = np.random.default_rng(3)
    q, dq, ddq = random_states(model, 600, rng)
    tau = model.rnea(q, dq, ddq) + 0.8 * np.sign(dq) + 0.02 * rng.standard_normal(q.shape)
    data = ci.Dataset(t=0.01 * np.arange(600), q=q, dq=dq, ddq=ddq, tau=tau)
    ci.diagnose(model, data, sigma=0.02, effects=("coulomb", "viscous"), progress=lines.append)
    assert lines and all(line.startswith("step ") for line in lines)
    ci.diagnose(model, data, sigma=0.02, effects=("coulomb",), progress=True)
    assert "diagnosis: selecting effects" in capsys.readouterr().err
    starts: list = []
    ci.design_excitation(model, harmonics=2, period=4.0, n_starts=2, max_iter=3, n_grid=30,
                         n_check=100, progress=starts.append)
    assert [s.index for s in starts] == [0, 1]
    ci.design_excitation(model, harmonics=2, period=4.0, n_starts=2, max_iter=3, n_grid=30,
                         n_check=100, progress=False)
    assert capsys.readouterr().err == ""


@pytest.mark.slow
def test_identify_on_the_kuka_example(kuka_dir, tmp_path, capsys):
    """Issue 15's acceptance: the KUKA example writes the five files; the JSON reloads to an
    equal result; Pinocchio reads the identified friction from the URDF (real logs, ~15 s)."""
    import pinocchio as pin

    config = Path(__file__).resolve().parents[1] / "examples" / "kuka_lwr4" / "identify.toml"
    out = tmp_path / "kuka"
    assert main(["-q", "identify", str(config), "--output", str(out)]) == 0
    assert {p.name for p in out.iterdir()} >= {"result.json", "parameters.csv", "robot.urdf",
                                               "report.html"}
    res = ci.IdentificationResult.load(out / "result.json", follow_source=True)
    saved = json.loads((out / "result.json").read_text())
    assert json.loads(res.save(tmp_path / "again.json").read_text()) == saved
    assert res.model.source == (kuka_dir / "kuka_lwr4.urdf").resolve()  # found by SHA-256
    assert res.solver.status == "optimal" and res.is_consistent
    named = dict(zip(res.parameter_names, res.parameters))
    fc = [named[f"{j}.fc"] for j in res.model.joint_names]
    fv = [named[f"{j}.fv"] for j in res.model.joint_names]
    back = pin.buildModelFromUrdf(str(out / "robot.urdf"))
    assert np.array_equal(back.friction, fc) and np.array_equal(back.damping, fv)
    check_html((out / "report.html").read_text(), n_images=9)


def test_a_large_bag_shows_progress(tmp_path):
    """read_bag / read_log report every ~1 % (at least 1000 messages) of a bag's messages; the
    data read are the same with and without."""
    pytest.importorskip("rosbags")
    from consistid.data.formats import read_log

    from .test_formats import write_bag

    n = 2500
    s = np.arange(n) * 0.002
    log = dict(ns=(1_700_000_000 * 10**9 + np.arange(n) * 2_000_000), names=("a", "b", "c"),
               q=np.column_stack([np.sin(s), np.cos(s), s]), dq=np.ones((n, 3)),
               tau=np.column_stack([s, 2 * s, 3 * s]))
    bag = write_bag(tmp_path / "big", log)
    lines: list[str] = []
    with_bar = read_log(bag, progress=lines.append)
    assert lines == [f"reading big {k}/{n}" for k in (1000, 2000)]
    plain = read_log(bag, progress=False)
    assert np.array_equal(with_bar.t, plain.t) and set(plain.fields) >= {"q", "tau"}
    for key, value in plain.fields.items():
        assert np.array_equal(with_bar.fields[key], value), key


def test_a_failed_demo_leaves_no_folder(tmp_path, monkeypatch):
    """A demo that fails in its work (here: the simulation) leaves neither its --output folder
    nor a temporary or a lock."""
    monkeypatch.chdir(tmp_path)

    def fail(*args, **kwargs):
        raise ci.ModelError("simulated failure")

    monkeypatch.setattr(ci.simulate, "excitation_run", fail)
    assert main(["-q", "demo", "--robot", "ur5", "--output", str(tmp_path / "out")]) == 2
    assert list(tmp_path.iterdir()) == []


def test_the_tracking_warning_says_how_to_stiffen_and_the_advice_works(panda):
    """The warning names the controller setting to raise; taking its advice shrinks the
    tracking error (the PD gains scale with the bandwidth squared)."""
    from consistid.simulate import Effects, TrackingController, record

    trajectory = ci.FourierTrajectory.random(panda, 5, 10.0, seed=3)
    eff = Effects(coulomb={6: 2.0})
    with pytest.warns(ci.TrackingWarning, match=r"TrackingController\(bandwidth=100\)") as w:
        soft = record(panda, trajectory, eff, max_tracking_error=0.05, duration=2.0,
                      settle=0.1)
    bandwidth = float(re.search(r"bandwidth=([0-9.]+)", str(w[0].message)).group(1))
    stiff = record(panda, trajectory, eff, max_tracking_error=1.0, duration=2.0, settle=0.1,
                   controller=TrackingController(bandwidth=bandwidth))
    assert stiff.tracking_error[6] < 0.5 * soft.tracking_error[6]

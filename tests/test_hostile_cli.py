"""Hostile inputs to the ``consistid`` command (issue 14): wrong TOML types, missing or
malformed files, and the file-safety rules of :mod:`consistid.cli.files` — no silent overwrite,
never over an input, paths checked before the long work, atomic writes.

Every case runs ``main([...])`` in-process and asserts exit status 2 with a message naming the
key (as written in the TOML file) or the path, and no traceback. Long work is replaced by a
function that fails the test if it is reached, to prove the paths are checked first.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest

import consistid as ci
from consistid.cli import commands, main
from consistid.cli.files import (atomic_dir, atomic_path, check_output, check_output_dir,
                                 same_file)
from consistid.errors import ConsistidError, OutputPathError



@pytest.fixture()
def project(cli_project):
    """conftest's CLI project: data/ (URDF and two logs) and conf/."""
    return cli_project


MODEL = """root = ".."
[model]
urdf = "data/arm.urdf"
gravity = [0.0, -9.81, 0.0]
"""
DATA = """[data]
dir = "data"
keys = "consistid"
train = ["run1.npz"]
held_out = ["run2.npz"]
"""
IDENTIFY = MODEL + DATA + '[identify]\nmethod = "ols"\nfriction = ["coulomb"]\n'


def write(project, text, name="run.toml"):
    path = project / "conf" / name
    path.write_text(text)
    return path


def run(args, capsys, code=2):
    """Exit status ``code``, no traceback; the error text with option values normalised
    (``name='x'`` and ``name = "x"`` both read ``name="x"``)."""
    got = main([str(a) for a in args])
    out = capsys.readouterr()
    assert got == code, out.err
    assert "Traceback" not in out.err + out.out
    return Said(normal(out.err))


def normal(text: str) -> str:
    return re.sub(r"(\w) = ", r"\1=", text.replace("'", '"'))


class Said(str):
    """Error text in which ``needle in said`` compares normalised forms (:func:`normal`)."""

    def __contains__(self, needle: object) -> bool:
        return str.__contains__(self, normal(str(needle)))


def forbid(monkeypatch, target, name):
    """Make ``target.name`` fail the test if called: the command must stop before it."""
    def reached(*args, **kwargs):
        raise AssertionError(f"{name} ran although the output path is unsafe")
    monkeypatch.setattr(target, name, reached)


# ============================================================ configuration files
@pytest.mark.parametrize("command", ["identify", "excite", "recover", "payload", "diagnose"])
def test_a_missing_configuration_is_named(project, capsys, command):
    err = run([command, project / "nope.toml"], capsys)
    assert "nope.toml' does not exist" in err


@pytest.mark.parametrize("command", ["identify", "excite", "recover", "payload", "diagnose"])
def test_invalid_toml_is_named(project, capsys, command):
    err = run([command, write(project, "[model\nurdf = ")], capsys)
    assert "run.toml is not valid TOML" in err


WRONG_TYPES = [
    ("[model]", 'urdf = "data/arm.urdf"', "urdf = 5", "[model] urdf must be a string"),
    ("[model]", 'urdf = "data/arm.urdf"', 'urdf = ["data/arm.urdf"]',
     "[model] urdf must be a string"),
    ("[model]", "gravity = [0.0, -9.81, 0.0]", 'gravity = "down"', "[model] gravity must be"),
    ("[model]", "gravity = [0.0, -9.81, 0.0]", "gravity = [0, true, 0]",
     "[model] gravity must be"),
    ("[model]", "gravity = [0.0, -9.81, 0.0]", 'locked_joints = "joint1"',
     "[model] locked_joints must be an array of strings"),
    ("[model]", "gravity = [0.0, -9.81, 0.0]", 'strip_dynamics = "yes"',
     "[model] strip_dynamics must be a boolean"),
    ("[model]", "gravity = [0.0, -9.81, 0.0]", "name = 7", "[model] name must be a string"),
    ("[model]", "gravity = [0.0, -9.81, 0.0]", 'tilt = "level"', "tilt = \"estimate\" is the only"),
    ("[data]", 'dir = "data"', "dir = 1", "[data] dir must be a string"),
    ("[data]", 'keys = "consistid"', "keys = 5", "[data] keys must be a string or table"),
    ("[data]", 'train = ["run1.npz"]', "train = 3", "[data] train must be a string or array"),
    ("[data]", 'train = ["run1.npz"]', "train = [1, 2]", "[data] train must be a string or array"),
    ("[data]", 'held_out = ["run2.npz"]', "held_out = true", "[data] held_out must be"),
    ("[data]", 'dir = "data"', 'dir = "data"\ntrim_start = "2 s"',
     "[data] trim_start must be a number"),
    ("[data]", 'dir = "data"', 'dir = "data"\njoint_names = "joint1"',
     "[data] joint_names must be an array of strings"),
    ("[data]", 'dir = "data"', 'dir = "data"\nduplicates = 0',
     "[data] duplicates must be a string"),
    ("[identify]", 'method = "ols"', "method = 5", "method=5 is not supported"),
    ("[identify]", 'method = "ols"', 'method = "ols"\ncovariance = 1', "covariance=1"),
    ("[identify]", 'method = "ols"', 'method = "ols"\nbogus = 1', "unknown key(s) ['bogus']"),
    ("[identify]", 'method = "ols"', 'method = "sdp"\nprior_weight = "heavy"',
     "prior_weight must be a finite number"),
    ("[identify]", 'method = "ols"', 'method = "sdp"\nmass_bounds = 3',
     "mass_bounds must be a mapping"),
    ("[identify]", 'method = "ols"', 'method = "sdp"\nneighbourhood = {mass = "x"}',
     "Neighbourhood.mass must be a finite number"),
    ("[identify]", 'method = "ols"', 'method = "sdp"\nsolver_options = 5',
     "solver_options must be a mapping"),
    ("[identify]", 'method = "ols"', 'method = "sdp"\nscale = "yes"', "scale must be True or"),
    ("[identify]", 'method = "ols"', 'method = "sdp"\nellipsoids = {link1 = 5}',
     "[identify.ellipsoids.link1] must be a table"),
    ("[identify]", 'friction = ["coulomb"]', "friction = 3", "friction must be term names"),
]


@pytest.mark.parametrize("table,old,new,message", WRONG_TYPES,
                         ids=[f"{t}{n.split('=')[0].strip()}-{k}" for k, (t, _, n, _)
                              in enumerate(WRONG_TYPES)])
def test_toml_values_of_the_wrong_type_are_named(project, capsys, table, old, new, message):
    head, _, tail = IDENTIFY.partition(table)
    text = head + table + tail.replace(old, new, 1)
    err = run(["identify", write(project, text)], capsys)
    assert normal(message) in err


def test_unknown_tables_and_root_type(project, capsys):
    assert "unknown table(s)" in run(["identify", write(project, IDENTIFY + "[plots]\n")], capsys)
    assert "root must be a path string" in run(
        ["identify", write(project, IDENTIFY.replace('root = ".."', "root = 5"))], capsys)


def test_missing_files_named_in_config(project, capsys):
    err = run(["identify", write(project, IDENTIFY.replace("run1.npz", "run9.npz"))], capsys)
    assert "run9.npz" in err and "does not exist" in err
    err = run(["identify", write(project, IDENTIFY.replace("arm.urdf", "hand.urdf"))], capsys)
    assert "hand.urdf" in err and "does not exist" in err


@pytest.mark.parametrize("new,message", [
    ('rate = "fast"', "[excite] rate must be a number"),
    ("rate = -5.0", "[excite] rate must be > 0"),
    ("output = 5", "[excite] output must be a string"),
])
def test_excite_values_of_the_wrong_type(project, capsys, monkeypatch, new, message):
    forbid(monkeypatch, commands, "_log")          # nothing may start before the check
    text = MODEL + f"[excite]\nharmonics = 2\nperiod = 4.0\nfriction = []\n{new}\n"
    got = main(["excite", str(write(project, text))])
    assert got == 2 and message in capsys.readouterr().err


@pytest.mark.parametrize("new,message", [
    ("effects = 5", "[diagnose] effects must be a string or array of strings"),
    ('split = "half"', "[diagnose] split must be a number"),
    ('sigma = [1, "x"]', "[diagnose] sigma must be an array of numbers"),
    ("max_steps = 1.5", "[diagnose] max_steps must be an integer"),
    ("output = 3", "[diagnose] output must be a string"),
])
def test_diagnose_values_of_the_wrong_type(project, capsys, monkeypatch, new, message):
    forbid(monkeypatch, ci, "diagnose")
    text = MODEL + DATA + f"[diagnose]\n{new}\n"
    assert message in run(["diagnose", write(project, text)], capsys)


def test_excite_boundary_of_the_wrong_type(project, capsys):
    text = MODEL + '[excite]\nharmonics = 2\nfriction = []\n[excite.boundary]\nq_start = "x"\n'
    assert "[excite.boundary] q_start must be a number" in run(["excite", write(project, text)],
                                                              capsys)


@pytest.mark.parametrize("new,message", [
    ("loaded = 5", "[payload] loaded must be a string or array of strings"),
    ('mass_range = "heavy"', "mass_range must be a pair"),
    ("mass_range = [3.0, 1.0]", "lower bound above the upper"),
    ('route = "magic"', "route='magic' is not supported"),
    ("frame = 3", "[payload] frame must be a string"),
    ("body = [1]", "[payload] body must be a string"),
])
def test_payload_options_of_the_wrong_type(project, capsys, new, message):
    loaded = "" if new.startswith("loaded") else 'loaded = ["run2.npz"]\n'
    text = MODEL + DATA + f"[payload]\n{loaded}{new}\n"
    assert normal(message) in run(["payload", write(project, text)], capsys)


@pytest.mark.parametrize("new,message", [
    ("coefficients = 3", "[recover] coefficients must be a string"),
    ('coefficients = "missing.npz"', "coefficients = 'missing.npz': file"),
    ('coefficients = "data/arm.urdf"', "not a readable .npz file"),
    ('mode = "closest"', "mode='closest'"),
    ("margin = \"wide\"", "[recover] margin must be a number"),
    ("urdf = 5", "[recover] urdf must be a string"),
    ('merged = "glue"', "[recover] merged='glue' is not supported"),
    ('merged = "lump"', "no urdf = \"out.urdf\" to write"),
])
def test_recover_values_are_checked(project, capsys, new, message):
    text = MODEL + DATA + f"[recover]\n{new}\n"
    assert normal(message) in run(["recover", write(project, text)], capsys)


def test_recover_coefficients_without_beta(project, capsys):
    np.savez(project / "coef.npz", gamma=np.ones(3))
    text = MODEL + '[recover]\ncoefficients = "coef.npz"\n'
    err = run(["recover", write(project, text)], capsys)
    assert "needs an array 'beta'; it has ['gamma']" in err


@pytest.mark.parametrize("args,message", [
    (["--robot", "pandas"], "--robot pandas is not an example robot; they are panda, ur3"),
    (["--robot", "iiwa"], "For another arm: --urdf PATH"),
])
def test_demo_and_simulate_name_bad_arguments(capsys, args, message):
    assert normal(message) in run(["demo", *args], capsys)
    assert normal(message) in run(["simulate", *args], capsys)


@pytest.mark.parametrize("args,message", [
    (["demo", "--noise", "-1"], "--noise must be a finite number ≥ 0"),
    (["demo", "--duration", "nan"], "--duration must be a finite number > 0"),
    (["demo", "--rate", "0"], "--rate must be a finite number > 0"),
    (["online", "--robot", "pandas"], "--robot pandas is not an example robot; they are panda"),
    (["online", "--duration", "-1"], "duration must be a finite number > 0"),
    (["online", "--forgetting", "1.5"], "forgetting must lie in (0, 1]"),
    (["simulate", "--duration", "-1", "--robot", "ur5"], "duration = -1.0"),
    (["simulate", "--urdf", "/no/such/arm.urdf"], "'/no/such/arm.urdf' does not exist"),
])
def test_numeric_arguments_are_checked_before_the_work(tmp_path, capsys, monkeypatch, args,
                                                       message):
    monkeypatch.chdir(tmp_path)
    assert message in run(args, capsys)
    assert os.listdir(tmp_path) == []          # no folder or file left behind


def test_demo_output_that_exists_is_refused(tmp_path, capsys, monkeypatch):
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "report.html").write_text("mine")
    forbid(monkeypatch, ci.simulate, "excitation_run")
    assert "--output" in run(["demo", "--output", tmp_path / "out"], capsys)
    assert (tmp_path / "out" / "report.html").read_text() == "mine"


def test_identify_output_refuses_existing_results_before_identifying(project, capsys,
                                                                     monkeypatch):
    out = project / "results"
    out.mkdir()
    for name in commands.IDENTIFY_OUTPUTS:
        (out / name).write_text("mine")
    forbid(monkeypatch, ci, "identify")
    err = run(["identify", write(project, IDENTIFY), "--output", out], capsys)
    assert "exists; pass --force" in err
    assert all((out / name).read_text() == "mine" for name in commands.IDENTIFY_OUTPUTS)
    err = run(["identify", write(project, IDENTIFY), "--output", project / "conf" / "run.toml",
               "--force"], capsys)
    assert "existing file, not a folder" in err or "input of this run" in err


def test_simulate_effect_that_does_not_exist(capsys, monkeypatch):
    err = run(["simulate", "--robot", "ur5", "--effect", "gremlins=1", "--duration", "0.1"],
              capsys)
    assert "gremlins" in err


# ============================================================ outputs: checked first
RECOVER = MODEL + DATA + '[recover]\nmode = "nearest"\nfriction = []\nurdf = "out.urdf"\n'


def test_recover_refuses_an_existing_urdf_before_the_work(project, capsys, monkeypatch):
    (project / "out.urdf").write_text("mine")
    forbid(monkeypatch, ci, "identify")
    err = run(["recover", write(project, RECOVER)], capsys)
    assert "[recover] urdf" in err and "out.urdf' exists; pass --force" in err
    assert (project / "out.urdf").read_text() == "mine"


@pytest.mark.parametrize("target", ["data/arm.urdf", "conf/run.toml", "data/run1.npz"])
def test_recover_never_writes_over_an_input_even_with_force(project, capsys, monkeypatch,
                                                            target):
    text = RECOVER.replace('urdf = "out.urdf"', f'urdf = "{target}"')
    config = write(project, text)
    before = (project / target).read_bytes()
    forbid(monkeypatch, ci, "identify")
    err = run(["recover", config, "--force"], capsys)
    assert "is an input of this run" in err
    assert (project / target).read_bytes() == before


def test_recover_refuses_an_input_reached_through_a_symlink(project, capsys, monkeypatch):
    (project / "alias.urdf").symlink_to(project / "data" / "arm.urdf")
    forbid(monkeypatch, ci, "identify")
    text = RECOVER.replace('urdf = "out.urdf"', 'urdf = "alias.urdf"')
    assert "is an input of this run" in run(["recover", write(project, text), "--force"], capsys)


def test_recover_refuses_an_output_folder_that_does_not_exist(project, capsys, monkeypatch):
    forbid(monkeypatch, ci, "identify")
    text = RECOVER.replace('urdf = "out.urdf"', 'urdf = "no/such/dir/out.urdf"')
    err = run(["recover", write(project, text)], capsys)
    assert "does not exist; create it first" in err


def test_recover_with_force_replaces_atomically(project, capsys):
    (project / "out.urdf").write_text("old")
    run(["recover", write(project, RECOVER), "--force"], capsys, code=0)
    text = (project / "out.urdf").read_text()
    assert "<robot" in text and "old" not in text
    assert ci.RobotModel.from_urdf(project / "out.urdf").nv == 2
    assert not [p for p in project.iterdir() if ".part" in p.name]


def test_recover_failing_while_writing_leaves_the_old_file(project, capsys, monkeypatch):
    (project / "out.urdf").write_text("old")
    from consistid.estimation.recover import RecoveryResult

    def half_written(self, path, merged="auto"):
        Path(path).write_text("<robot half")
        raise ci.ModelError("disk full (simulated)")

    monkeypatch.setattr(RecoveryResult, "to_urdf", half_written)
    assert "disk full" in run(["recover", write(project, RECOVER), "--force"], capsys)
    assert (project / "out.urdf").read_text() == "old"
    assert not [p for p in project.iterdir() if ".part" in p.name]


EXCITE = MODEL + """[excite]
harmonics = 1
period = 4.0
friction = []
n_starts = 1
max_iter = 2
n_grid = 20
rate = 20.0
output = "traj.csv"
"""


def test_excite_refuses_an_existing_csv_before_designing(project, capsys, monkeypatch):
    (project / "traj.csv").write_text("keep")
    from consistid.cli.excite import ExcitationConfig

    forbid(monkeypatch, ExcitationConfig, "run")
    assert "traj.csv' exists; pass --force" in run(["excite", write(project, EXCITE)], capsys)
    assert (project / "traj.csv").read_text() == "keep"


@pytest.mark.parametrize("target", ["conf/run.toml", "data/arm.urdf"])
def test_excite_output_never_replaces_an_input(project, capsys, monkeypatch, target):
    from consistid.cli.excite import ExcitationConfig

    forbid(monkeypatch, ExcitationConfig, "run")
    config = write(project, EXCITE)
    before = (project / target).read_bytes()
    err = run(["excite", config, "--output", project / target, "--force"], capsys)
    assert "--output" in err and "is an input of this run" in err
    assert (project / target).read_bytes() == before


def test_excite_output_that_is_a_folder(project, capsys, monkeypatch):
    from consistid.cli.excite import ExcitationConfig

    forbid(monkeypatch, ExcitationConfig, "run")
    assert "is an existing folder" in run(["excite", write(project, EXCITE), "--output",
                                           project / "data", "--force"], capsys)


def test_excite_with_force_writes_the_csv(project, capsys):
    (project / "traj.csv").write_text("old")
    run(["excite", write(project, EXCITE), "--force"], capsys, code=0)
    assert ci.Dataset.load(project / "traj.csv").nv == 2


def test_simulate_checks_the_plot_path_before_simulating(tmp_path, capsys, monkeypatch):
    from consistid.cli import residual_demo

    forbid(monkeypatch, residual_demo, "run")
    (tmp_path / "r.png").write_bytes(b"png")
    assert "--plot" in run(["simulate", "--plot", tmp_path / "r.png"], capsys)
    assert "does not exist" in run(["simulate", "--plot", tmp_path / "x" / "r.png"], capsys)
    assert (tmp_path / "r.png").read_bytes() == b"png"


class FakeDiagnosis:
    """What ``consistid diagnose`` needs of a Diagnosis: its summary and report writer."""

    def summary(self):
        return "fake diagnosis"

    def report(self, path):
        path = Path(path)
        if path.suffix in (".html", ".txt"):
            path.write_text("report")
        else:
            (path / "report.txt").write_text("report")
            (path / "report.html").write_text("report")
            (path / "plot.png").write_bytes(b"png")
        return path


DIAGNOSE = MODEL + DATA + '[diagnose]\noutput = "report"\n'


def test_diagnose_refuses_existing_report_files_before_the_work(project, capsys, monkeypatch):
    (project / "report").mkdir()
    (project / "report" / "report.txt").write_text("keep")
    forbid(monkeypatch, ci, "diagnose")
    err = run(["diagnose", write(project, DIAGNOSE)], capsys)
    assert "[diagnose] output" in err and "report.txt' exists; pass --force" in err


@pytest.mark.parametrize("output", ["conf/run.toml", "data/run1.npz"])
def test_diagnose_output_never_replaces_an_input(project, capsys, monkeypatch, output):
    forbid(monkeypatch, ci, "diagnose")
    err = run(["diagnose", write(project, DIAGNOSE), "--output", project / output, "--force"],
              capsys)
    assert "input of this run" in err or "existing file, not a folder" in err


def test_diagnose_writes_into_a_folder_with_other_files(project, capsys, monkeypatch):
    """A folder holding unrelated files (e.g. the config) is fine: only report files count."""
    monkeypatch.setattr(ci, "diagnose", lambda *a, **k: FakeDiagnosis())
    run(["diagnose", write(project, DIAGNOSE), "--output", project / "conf"], capsys, code=0)
    assert (project / "conf" / "report.txt").read_text() == "report"
    assert (project / "conf" / "run.toml").read_text() == DIAGNOSE
    # a second run needs --force, and then replaces
    assert "exists; pass --force" in run(["diagnose", write(project, DIAGNOSE), "--output",
                                          project / "conf"], capsys)
    run(["diagnose", write(project, DIAGNOSE), "--output", project / "conf", "--force"], capsys,
        code=0)
    assert not [p for p in (project / "conf").iterdir() if ".part" in p.name]


def test_diagnose_html_report_is_checked_and_written(project, capsys, monkeypatch):
    monkeypatch.setattr(ci, "diagnose", lambda *a, **k: FakeDiagnosis())
    out = project / "r.html"
    run(["diagnose", write(project, DIAGNOSE), "--output", out], capsys, code=0)
    assert out.read_text() == "report"
    assert "r.html' exists" in run(["diagnose", write(project, DIAGNOSE), "--output", out],
                                   capsys)


# ============================================================ the helper itself
def test_check_output_rules(tmp_path):
    src = tmp_path / "in.txt"
    src.write_text("x")
    assert check_output(tmp_path / "new.txt") == (tmp_path / "new.txt").resolve()
    with pytest.raises(OutputPathError, match="exists; pass --force"):
        check_output(src)
    with pytest.raises(OutputPathError, match="input of this run"):
        check_output(src, inputs=[src], force=True)
    os.link(src, tmp_path / "hard.txt")
    with pytest.raises(OutputPathError, match="input of this run"):
        check_output(tmp_path / "hard.txt", inputs=[src], force=True)
    with pytest.raises(OutputPathError, match="existing folder"):
        check_output(tmp_path, force=True)
    with pytest.raises(OutputPathError, match="is empty"):
        check_output("")
    assert same_file(tmp_path / "." / "in.txt", src) and not same_file(src, tmp_path / "b")
    assert isinstance(OutputPathError("x"), ConsistidError)


def test_check_output_dir_rules(tmp_path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(OutputPathError, match="existing file, not a folder"):
        check_output_dir(tmp_path / "f", ["a"])
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "a").write_text("x")
    with pytest.raises(OutputPathError, match="exists; pass --force"):
        check_output_dir(tmp_path / "d", ["a"])
    assert check_output_dir(tmp_path / "d", ["a"], force=True) == (tmp_path / "d").resolve()
    with pytest.raises(OutputPathError, match="does not exist"):
        check_output_dir(tmp_path / "x" / "y", ["a"])


def test_atomic_path_keeps_the_old_file_on_failure(tmp_path):
    target = tmp_path / "out.csv"
    target.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            assert tmp.suffix == ".csv" and tmp.parent == tmp_path
            tmp.write_text("half")
            raise RuntimeError("crash")
    assert target.read_text() == "old" and sorted(os.listdir(tmp_path)) == ["out.csv"]
    with atomic_path(target) as tmp:
        tmp.write_text("new")
    assert target.read_text() == "new" and sorted(os.listdir(tmp_path)) == ["out.csv"]
    with pytest.raises(OutputPathError, match="wrote no file"):
        with atomic_path(tmp_path / "never.csv"):
            pass
    assert not (tmp_path / "never.csv").exists()


def test_atomic_dir_moves_files_only_on_success(tmp_path):
    with pytest.raises(RuntimeError):
        with atomic_dir(tmp_path / "rep") as tmp:
            (tmp / "a.txt").write_text("1")
            raise RuntimeError("crash")
    assert not (tmp_path / "rep").exists() and os.listdir(tmp_path) == []
    with atomic_dir(tmp_path / "rep") as tmp:
        (tmp / "a.txt").write_text("1")
    assert (tmp_path / "rep" / "a.txt").read_text() == "1" and os.listdir(tmp_path) == ["rep"]

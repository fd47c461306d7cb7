"""The ``consistid`` command on mistakes a new user makes (found by probing it; each test failed
before its fix): a folder given as the configuration, a ``[data] dir`` that is a file or under a
missing ``root``, negative trims, ``armature = "yes"``, a held-out log that is also a training
log (scored silently as if it were held out), a demo URDF with a massless body, a ``--plot``
that is no image, and calibration CSVs with semicolons, units, degrees or millimetres."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import consistid as ci
from consistid.cli import main
from consistid.cli.calibrate import read_calibration_data

from .conftest import PLANAR_2R, PLANAR_2R_VALUES

MODEL = """root = ".."
[model]
urdf = "data/arm.urdf"
gravity = [0.0, -9.81, 0.0]
"""


def data_table(train='["run1.npz"]', held_out='["run2.npz"]', extra="", folder='"data"'):
    return (f'[data]\ndir = {folder}\nkeys = "consistid"\ntrain = {train}\n'
            f'held_out = {held_out}\n{extra}')


IDENTIFY = '[identify]\nmethod = "ols"\nfriction = ["coulomb"]\n'


@pytest.fixture()
def project(cli_project):
    """conftest's CLI project: data/ (URDF and two logs) and conf/."""
    return cli_project


def write(project, text, name="run.toml"):
    path = project / "conf" / name
    path.write_text(text)
    return path


def run(args, capsys, code=2):
    got = main([str(a) for a in args])
    out = capsys.readouterr()
    assert got == code, out.err
    assert "Traceback" not in out.err + out.out
    return out.err


def test_a_folder_given_as_the_configuration_is_called_a_folder(project, capsys):
    write(project, MODEL + data_table() + IDENTIFY, "identify.toml")
    err = run(["identify", project / "conf"], capsys)
    assert "is a folder, not a TOML file" in err and "identify.toml" in err
    assert "does not exist" not in err


def test_data_dir_that_is_a_file_is_named(project, capsys):
    err = run(["identify", write(project, MODEL + data_table(folder='"data/run1.npz"')
                                 + IDENTIFY)], capsys)
    assert '[data] dir = "data/run1.npz" is the file' in err and "not a folder" in err


def test_missing_root_is_named_not_the_log(project, capsys):
    text = (MODEL + data_table() + IDENTIFY).replace('root = ".."', 'root = "../nowhere"')
    text = text.replace('urdf = "data/arm.urdf"', f'urdf = "{project / "data" / "arm.urdf"}"')
    err = run(["identify", write(project, text)], capsys)
    assert "root" in err and "nowhere' does not exist" in err


@pytest.mark.parametrize("key", ["trim_start", "trim_end"])
def test_negative_trim_is_named_in_toml(project, capsys, key):
    err = run(["identify", write(project, MODEL + data_table(extra=f"{key} = -1\n")
                                 + IDENTIFY)], capsys)
    assert f"[data] {key} must be seconds ≥ 0" in err and f"{key} = -1" in err


def test_armature_of_the_wrong_type_is_named_in_toml(project, capsys):
    err = run(["identify", write(project, MODEL + data_table()
                                 + IDENTIFY + 'armature = "yes"\n')], capsys)
    assert '[identify] armature must be true, false or an array of joint names' in err
    assert 'armature = "yes"' in err and "joint = " not in err


def test_held_out_that_is_a_training_log_warns(project, capsys):
    path = write(project, MODEL + data_table(train='["run1.npz", "run2.npz"]',
                                             held_out='["run2.npz"]') + IDENTIFY)
    with pytest.warns(ci.errors.DataQualityWarning, match=r"held_out names train log\(s\) "
                                                          r"\['run2.npz'\]"):
        assert main(["-q", "identify", str(path), "--output", str(project / "out")]) == 0


def test_distinct_held_out_does_not_warn(project, capsys, recwarn):
    main(["-q", "identify", str(write(project, MODEL + data_table() + IDENTIFY)),
          "--output", str(project / "out")])
    assert not [w for w in recwarn if "held_out names train" in str(w.message)]


@pytest.mark.parametrize("inertial, reason", [
    ("", "l1: mass 0 kg"),
    ('<inertial><mass value="2"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" '
     'izz="0.1"/></inertial>', "l1: triangle inequality violated")])
def test_demo_names_the_body_it_cannot_use_before_making_a_folder(tmp_path, capsys, inertial,
                                                                   reason):
    text = PLANAR_2R.format(**PLANAR_2R_VALUES)
    start = text.index('<link name="link1">')
    end = text.index("</link>", start) + len("</link>")
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(text[:start] + f'<link name="l1">{inertial}</link>' + text[end:]
                    .replace('<child link="link1"/>', '<child link="l1"/>')
                    .replace('<parent link="link1"/>', '<parent link="l1"/>'))
    err = run(["demo", "--urdf", urdf, "--duration", "2", "--output", tmp_path / "out"], capsys)
    assert "every moving body needs a positive mass and a physical inertia" in err
    assert reason in err                 # was: "mass 0 ≤ 0: the centre of mass is undefined"
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("name", ["plot.txt", "plot"])
def test_simulate_plot_that_is_no_image_is_refused_before_the_run(tmp_path, capsys,
                                                                   monkeypatch, name):
    from consistid.cli import residual_demo

    def reached(*args, **kwargs):
        raise AssertionError("the simulation ran although --plot cannot be written")
    monkeypatch.setattr(residual_demo, "run", reached)
    err = run(["simulate", "--robot", "ur5", "--plot", tmp_path / name], capsys)
    assert "is not an image format; name a .png file" in err   # was: matplotlib's ValueError


# ------------------------------------------------------------------ calibration data files
POSES = Path(__file__).resolve().parents[1] / "examples" / "panda" / "calibration_poses.csv"


def _poses():
    lines = POSES.read_text().splitlines()
    return lines[0].split(","), np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]])


def _write_poses(path, header, table, sep=",", comma=False, bom=False, eol="\n"):
    rows = [sep.join(header)] + [sep.join((f"{v:.12g}".replace(".", ",") if comma
                                           else f"{v:.12g}") for v in r) for r in table]
    path.write_text(eol.join(rows) + eol, encoding="utf-8-sig" if bom else "utf-8")
    return path


def test_calibration_csv_in_other_habits_reads_like_the_plain_one(tmp_path, panda):
    header, table = _poses()
    q0, m0 = read_calibration_data(_write_poses(tmp_path / "plain.csv", header, table), panda)
    variants = {
        "semicolon, decimal comma": _write_poses(tmp_path / "a.csv", header, table, sep=";",
                                                 comma=True),
        "tab, decimal comma": _write_poses(tmp_path / "t.csv", header, table, sep="\t",
                                           comma=True),
        "BOM and CRLF": _write_poses(tmp_path / "b.csv", header, table, bom=True, eol="\r\n"),
        "units in brackets": _write_poses(
            tmp_path / "c.csv", [h + " [deg]" if k < 7 else h + " [mm]" if k < 10 else h
                                 for k, h in enumerate(header)],
            np.column_stack([np.degrees(table[:, :7]), 1e3 * table[:, 7:10], table[:, 10:]]))}
    for what, path in variants.items():          # were: not numeric / no joint columns
        q, m = read_calibration_data(path, panda)
        assert np.allclose(q, q0, atol=1e-9) and np.allclose(m, m0, atol=1e-9), what


def test_calibration_csv_in_degrees_or_mm_without_a_unit_warns(tmp_path, panda):
    header, table = _poses()
    deg = _write_poses(tmp_path / "deg.csv", header,
                       np.column_stack([np.degrees(table[:, :7]), table[:, 7:]]))
    with pytest.warns(ci.errors.DataQualityWarning, match=r"'panda_joint1' spans.*degrees"):
        read_calibration_data(deg, panda)
    mm = _write_poses(tmp_path / "mm.csv", header,
                      np.column_stack([table[:, :7], 1e3 * table[:, 7:10], table[:, 10:]]))
    with pytest.warns(ci.errors.DataQualityWarning, match=r"in millimetres\?"):
        read_calibration_data(mm, panda)
    odd = _write_poses(tmp_path / "odd.csv", [h + " [in]" if h == "x" else h for h in header],
                       table)
    with pytest.raises(ci.errors.ConfigError, match=r"column 'x \[in\]': unit \[in\]"):
        read_calibration_data(odd, panda)


def test_online_change_after_the_run_is_refused_not_moved(capsys, monkeypatch):
    from consistid.online import scenario

    def reached(*args, **kwargs):
        raise AssertionError("the run started although --change lies after it")
    monkeypatch.setattr(scenario, "payload_change_run", reached)
    err = run(["online", "--robot", "ur5", "--duration", "2", "--change", "5"], capsys)
    assert "--change 5 s is not within the run of --duration 2 s" in err   # was: moved to 1.6 s


def test_a_folder_where_a_calibration_file_is_expected_is_called_a_folder(tmp_path, panda):
    with pytest.raises(ci.errors.ConfigError, match="is a folder; \\[calibrate\\] data names"):
        read_calibration_data(tmp_path, panda)                 # was: "does not exist"


def test_a_folder_as_recover_coefficients_is_called_a_folder(project, capsys):
    text = MODEL + data_table() + '[recover]\ncoefficients = "data"\n'
    err = run(["recover", write(project, text)], capsys)
    assert "[recover] coefficients = 'data'" in err and "is a folder" in err

"""Hostile input, round four: the subcommands and subsystems that arrived after round three.

Outputs that are devices, FIFOs or folders; names longer than the filesystem allows; output
folders inside an input folder; a full disk; temporaries of a killed run; Ctrl-C while the
subcommands load; seeds, horizons and grids that numpy or MuJoCo would choke on; the rollout
and calibration entries (models, data, window, step budget, threads, an unstable replay); the
drives package. Each case asserts a named consistid error (exit 2 on the command line) or a
named warning, where the code before this round raised a foreign exception, hung, allocated
terabytes, replaced a device or returned a figure without a word. No timing: the interrupted
import and the killed writer are staged deterministically.
"""

from __future__ import annotations

import errno
import importlib.abc
import os
import sys
import warnings

import numpy as np
import pytest

import consistid as ci
from consistid.cli import main
from consistid.cli.files import check_output, check_output_dir
from consistid.errors import (DataQualityWarning, DatasetError,
                              IdentificationError, JointCountError, ModelMisfitWarning,
                              OptionError, OutputPathError)
from consistid.filesafety import (Terminated, lock_output, release_output_locks, replacing)
from consistid.simulator import PDGains, RolloutOptions, validate_rollout

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX FIFOs and signals")

IDENTIFY = """root = ".."
[model]
urdf = "data/arm.urdf"
gravity = [0.0, -9.81, 0.0]
[data]
dir = "data"
train = ["run1.npz"]
[identify]
method = "ols"
friction = ["coulomb"]
"""
EXCITE = """root = ".."
[model]
urdf = "data/arm.urdf"
[excite]
period = 4.0
friction = []
n_starts = 1
max_iter = 2
n_grid = 20
rate = 20.0
output = "traj.csv"
"""


@pytest.fixture(autouse=True)
def _no_locks_left():
    yield
    release_output_locks()


# ----------------------------------------------------------------------------- output paths
@pytest.mark.parametrize("kind", ["fifo", "folder"])
def test_an_output_that_is_no_regular_file_is_refused_not_replaced(tmp_path, kind):
    """Run as root, ``rename(2)`` over ``/dev/null`` succeeds: the device would be a file."""
    target = tmp_path / "out.html"
    os.mkfifo(target) if kind == "fifo" else target.mkdir()
    with pytest.raises(OutputPathError, match="regular file|folder"):
        check_output(target, force=True, what="--output")
    with pytest.raises(OutputPathError, match="regular file|folder"):
        with replacing(target) as tmp:
            tmp.write_text("x")
    assert target.is_fifo() if kind == "fifo" else target.is_dir()


def test_a_name_longer_than_the_filesystem_allows_is_named(tmp_path):
    long = tmp_path / ("a" * 300 + ".html")
    with pytest.raises(OutputPathError, match="--output .*name too long"):
        check_output(long, what="--output")
    with pytest.raises(OutputPathError, match="--output .*name too long"):
        check_output_dir(tmp_path / ("b" * 300), ["result.json"], what="--output")


def test_an_output_folder_inside_an_input_folder_is_refused(tmp_path):
    bag = tmp_path / "bag"                      # a ROS 2 bag folder is an input as a whole
    bag.mkdir()
    for out in (bag, bag / "results"):
        with pytest.raises(OutputPathError, match="inside the input folder"):
            check_output_dir(out, ["result.json"], inputs=[bag], what="--output")


def test_the_next_writer_removes_what_a_killed_one_left(tmp_path):
    """SIGKILL runs no ``finally``: its staging folder and temporary file stay, until the next
    run holds the same output's lock; other files that look alike stay."""
    staged = tmp_path / ".out.part-ab12cd34"
    staged.mkdir()
    (staged / "result.json").write_text("{}")
    part = tmp_path / ".r.0123456789ab.part.html"
    part.write_text("<html>")
    kept = [tmp_path / ".other.part-ab12cd34", tmp_path / ".r.html.notes"]
    kept[0].mkdir()
    kept[1].write_text("mine")
    lock_output(tmp_path / "out")
    lock_output(tmp_path / "r.html")
    assert not staged.exists() and not part.exists()
    assert all(p.exists() for p in kept)


# ----------------------------------------------------------------------------- the command
def test_a_full_disk_is_named_and_leaves_no_temporary(cli_project, monkeypatch, capsys):
    config = cli_project / "conf" / "run.toml"
    config.write_text(IDENTIFY)
    out = cli_project / "out"

    def full(self, path):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(ci.IdentificationResult, "to_csv", full)
    assert main(["identify", str(config), "--output", str(out)]) == 2
    err = capsys.readouterr().err
    assert "No space left on device" in err and "Traceback" not in err
    assert not out.exists()
    assert not [p for p in cli_project.iterdir() if ".part" in p.name]


class _Interrupting(importlib.abc.MetaPathFinder):
    def __init__(self, exc: BaseException) -> None:
        self.exc = exc

    def find_spec(self, name, path=None, target=None):
        if name == "consistid.cli.commands":
            raise self.exc
        return None


@pytest.mark.parametrize("exc, code", [(KeyboardInterrupt(), 130),
                                       (Terminated("terminated (SIGTERM)"), 143)])
def test_an_interrupt_while_the_subcommands_load_is_one_line(monkeypatch, capsys, exc, code):
    """The signal arrives while ``consistid.cli.commands`` (Pinocchio, cvxpy …) imports."""
    monkeypatch.delitem(sys.modules, "consistid.cli.commands")
    monkeypatch.setattr(sys, "meta_path", [_Interrupting(exc), *sys.meta_path])
    assert main(["--version"]) == code
    err = capsys.readouterr().err
    assert "interrupted" in err and "Traceback" not in err


@pytest.mark.parametrize("argv, needle", [
    (["demo", "--seed", "-1"], "--seed"),
    (["simulate", "--seed", "-1"], "--seed"),
    (["online", "--seed", "-1"], "--seed"),
    (["online", "--periods", "1000000000"], "GiB"),
    (["simulate", "--duration", "1e9"], "GiB"),
])
def test_command_arguments_numpy_or_memory_would_choke_on(argv, needle, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err


@pytest.mark.parametrize("extra, needle", [
    ('via_points = 1000000000\n', "via_points"),
    ('harmonics = 1\n', "torque limit"),
    ('harmonics = 10\n', "Nyquist"),
    ('harmonics = 1\nseed = -1\n', "seed"),
])
def test_excite_keys_that_were_ignored_or_crashed(cli_project, extra, needle, capsys):
    config = cli_project / "conf" / "excite.toml"
    limits = '[excite.limits]\ntorque = "x"\n' if needle == "torque limit" else ""
    config.write_text(EXCITE.replace("[excite]\n", "[excite]\n" + extra, 1) + limits)
    assert main(["excite", str(config)]) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err
    assert not (cli_project / "traj.csv").exists()


# ----------------------------------------------------------------------------- Python entries
def test_excitation_entries_refuse_before_allocating(planar_2r):
    with pytest.raises(OptionError, match="n_grid"):
        ci.design_excitation(planar_2r, harmonics=1, n_grid=10**9)
    with pytest.raises(OptionError, match="seed"):
        ci.simulate.excitation_run(planar_2r, duration=1.0, seed=-1)


@pytest.fixture(scope="module")
def replay_log(planar_2r):
    return ci.simulate.excitation_run(planar_2r, duration=3.0, rate=200.0, harmonics=2,
                                      period=3.0, torque_noise=0.01, seed=1).dataset


@pytest.mark.parametrize("call, error, needle", [
    (lambda m, d: RolloutOptions(threads=10**6), OptionError, "threads"),
    (lambda m, d: PDGains(kp="a", kd="b"), OptionError, "kp and kd must be numbers"),
    (lambda m, d: validate_rollout(d, [m]), OptionError, "mapping"),
    (lambda m, d: validate_rollout(None, {"n": m}), DatasetError, "Dataset"),
    (lambda m, d: validate_rollout(d, {"n": ci.RobotModel.example("panda")}),
     JointCountError, "7 joints, the data 2"),
    (lambda m, d: validate_rollout(d, {"n": m}, options=RolloutOptions(window=1e-9)),
     OptionError, "window"),
    (lambda m, d: validate_rollout(d, {"n": m}, options=RolloutOptions(timestep=1e-12)),
     DatasetError, "timestep"),
])
def test_rollout_entries_name_what_is_wrong(planar_2r, replay_log, call, error, needle):
    with pytest.raises(error, match=needle):
        call(planar_2r, replay_log)


def test_an_unstable_replay_is_flagged_and_warned(planar_2r, replay_log):
    """ω = 10⁶ rad/s at a 2 ms step: MuJoCo resets the state (BADQACC) and the tracking error
    stayed below 1 rad, so the replay read as a plain (large) error before."""
    options = RolloutOptions(controller=PDGains(bandwidth=1e6))
    with pytest.warns(ModelMisfitWarning, match="diverged"):
        v = validate_rollout(replay_log, {"nominal": planar_2r}, options=options)
    assert v.replays[0].diverged and np.all(np.isnan(v.replays[0].q_error))


def test_a_log_shorter_than_one_window_is_warned(planar_2r, replay_log):
    short = replay_log.select(replay_log.t < 0.2)
    with pytest.warns(DataQualityWarning, match="shorter|less than one open-loop window"):
        validate_rollout(short, {"nominal": planar_2r})


def test_drive_entries_name_what_is_wrong(planar_2r, replay_log):
    from consistid.drives.coupled import identify_coupled
    from consistid.drives.gains import identify_drive_gains
    from consistid.drives.transmission import Transmission

    with pytest.raises(OptionError, match="ratios"):
        Transmission(ratios="ab")
    with pytest.raises(OptionError, match="Transmission"):
        identify_coupled(planar_2r, replay_log, "x")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(IdentificationError, match="payload_mass"):
            identify_drive_gains(planar_2r, replay_log, replay_log, payload_mass=1e300)


"""Hostile input, round three (issue 30): runs that are interrupted or run twice at once.

A result set (``consistid identify --output DIR``) is written whole or not at all, by one run at
a time (:mod:`consistid.filesafety`): a second run asking for the same output is refused by
name; SIGINT/SIGTERM before the renames remove the temporaries and leave the output alone,
during them they wait; a run killed (SIGKILL) among the renames into an existing folder leaves
a journal that makes ``load`` refuse the mixed set. Subprocess-heavy cases are ``slow``.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

import consistid as ci
from consistid.cli import commands, main
from consistid.cli.files import atomic_dir
from consistid.errors import OutputPathError, ResultFileError
from consistid.filesafety import JOURNAL, interrupted_files, lock_output, release_output_locks

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals and flock")

IDENTIFY = """root = ".."
[model]
urdf = "data/arm.urdf"
gravity = [0.0, -9.81, 0.0]
[data]
dir = "data"
keys = "consistid"
train = ["run1.npz"]
[identify]
method = "ols"
friction = ["coulomb"]
"""
ENV = {**os.environ, "PYTHONPATH": str(Path(ci.__file__).resolve().parents[1]),
       "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MPLBACKEND": "Agg"}
CLI = "import sys; from consistid.cli import main; sys.exit(main(sys.argv[1:]))"


@pytest.fixture()
def config(cli_project) -> Path:
    path = cli_project / "conf" / "run.toml"
    path.write_text(IDENTIFY)
    return path


def _python(code: str, *args: object, **kwargs) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", code, *map(str, args)], env=ENV,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kwargs)


def _staging(folder: Path) -> list[Path]:
    return [p for p in folder.parent.iterdir() if p.name.startswith(f".{folder.name}.part-")]


# ----------------------------------------------------------------------------- one writer
def test_a_second_writer_of_the_same_output_is_refused_by_name(config, capsys, monkeypatch):
    out = config.parent.parent / "out"
    holder = _python("import sys; from consistid.filesafety import lock_output;"
                     "lock_output(sys.argv[1]); print('held', flush=True); sys.stdin.read()",
                     out, stdin=subprocess.PIPE)
    try:
        assert holder.stdout.readline().strip() == "held"
        monkeypatch.setattr(ci, "identify", lambda *a, **k: pytest.fail("identified anyway"))
        assert main(["identify", str(config), "--output", str(out)]) == 2
        err = capsys.readouterr().err
        assert "being written by another consistid run" in err and f"pid {holder.pid}" in err
        assert "Traceback" not in err and not out.exists()
    finally:
        holder.kill()                              # SIGKILL: the kernel drops the lock
        holder.communicate()
    lock_output(out)                               # no stale lock after a killed holder
    release_output_locks()


@pytest.mark.slow
def test_the_lock_is_released_when_the_command_ends(config, capsys):
    out = config.parent.parent / "out"
    assert main(["-q", "identify", str(config), "--output", str(out)]) == 0
    assert main(["-q", "identify", str(config), "--output", str(out), "--force"]) == 0
    capsys.readouterr()
    assert not list(out.parent.glob(".out.consistid-lock"))
    assert ci.IdentificationResult.load(out / "result.json").n_samples == 300


ROLLOUT = IDENTIFY + """[rollout]
calibrate = false
"""
#: A process that holds what a command takes for its output, then waits: ``check_output_dir``
#: (identify, diagnose: a set of files in a folder) or ``check_output`` (rollout: one file).
HOLD = ("import sys; from consistid.cli import files; from consistid.cli.commands import "
        "IDENTIFY_OUTPUTS as names; kind, path = sys.argv[1:3];"
        "files.check_output_dir(path, names) if kind == 'dir' else files.check_output(path);"
        "print('held', flush=True); sys.stdin.read()")


def _holding(kind: str, path: Path) -> subprocess.Popen:
    holder = _python(HOLD, kind, path, stdin=subprocess.PIPE)
    assert holder.stdout.readline().strip() == "held", holder.communicate(timeout=30)
    return holder


def _stop(holder: subprocess.Popen) -> None:
    holder.kill()
    holder.communicate(timeout=30)


@pytest.mark.parametrize("holds, runs", [("dir", "rollout"), ("file", "identify")])
def test_identify_and_rollout_into_one_folder_cannot_interleave(config, capsys, monkeypatch,
                                                                holds, runs):
    """A set of files (identify) and a file (rollout) written into one folder at once: the
    second writer is refused by name before its work, whichever comes first."""
    out = config.parent.parent / "out"
    out.mkdir()
    rollout = config.with_name("rollout.toml")
    rollout.write_text(ROLLOUT)
    from consistid.cli import rollout as rollout_cli
    monkeypatch.setattr(ci, "identify", lambda *a, **k: pytest.fail("identified anyway"))
    monkeypatch.setattr(rollout_cli, "identify", lambda *a, **k: pytest.fail("ran anyway"))
    holder = _holding(holds, out if holds == "dir" else out / "rollout.html")
    try:
        argv = (["identify", str(config), "--output", str(out)] if runs == "identify" else
                ["rollout", str(rollout), "--output", str(out / "rollout.html")])
        assert main(["-q", *argv, "--force"]) == 2
        err = capsys.readouterr().err
        assert "being written by another consistid run" in err and str(out) in err, err
        assert "Traceback" not in err
        assert not [p for p in out.iterdir() if not p.name.endswith(".consistid-lock")]
    finally:
        _stop(holder)


def test_two_files_into_one_folder_share_it(tmp_path):
    """Runs writing different single files into one folder do not stop each other; the same
    file is refused; the folder's shared lock outlives its first holder, so that a set writer
    is refused until the last file writer ends, and the lock files go with the last one."""
    from consistid.cli.files import check_output, check_output_dir
    holder = _holding("file", tmp_path / "a.html")
    try:
        check_output(tmp_path / "b.html")
        with pytest.raises(OutputPathError, match="another consistid run"):
            check_output(tmp_path / "a.html")
        release_output_locks()
        with pytest.raises(OutputPathError, match="another consistid run"):
            check_output_dir(tmp_path, ["c.csv"])       # the holder still shares the folder
    finally:
        _stop(holder)
    check_output_dir(tmp_path, ["c.csv"])
    release_output_locks()
    assert not list(tmp_path.parent.glob(f".{tmp_path.name}.consistid-lock"))
    assert not (tmp_path / ".b.html.consistid-lock").exists()   # (a killed holder's file stays)


# ----------------------------------------------------------------------------- all or nothing
def _old_set(folder: Path, names=("a.txt", "b.txt", "c.txt")) -> tuple[str, ...]:
    folder.mkdir()
    for name in names:
        (folder / name).write_text("old")
    return names


def test_sigint_during_the_renames_waits_until_the_set_is_whole(tmp_path, monkeypatch):
    out = tmp_path / "set"
    names = _old_set(out)
    real, calls = os.replace, []

    def replace_then_interrupt(src, dst):
        real(src, dst)
        calls.append(dst)
        if len(calls) == 1:
            signal.raise_signal(signal.SIGINT)        # Ctrl-C after the first file

    monkeypatch.setattr(os, "replace", replace_then_interrupt)
    with pytest.raises(KeyboardInterrupt):
        with atomic_dir(out) as tmp:
            for name in names:
                (tmp / name).write_text("new")
    assert [(out / n).read_text() for n in names] == ["new"] * 3
    assert interrupted_files(out) is None and not list(out.glob(".set.part-*"))


def test_an_interruption_while_writing_leaves_the_old_set_and_no_temporary(tmp_path):
    out = tmp_path / "set"
    names = _old_set(out)
    with pytest.raises(KeyboardInterrupt):
        with atomic_dir(out) as tmp:
            (tmp / names[0]).write_text("new")
            signal.raise_signal(signal.SIGINT)
    assert [(out / n).read_text() for n in names] == ["old"] * 3
    assert sorted(p.name for p in out.iterdir()) == sorted(names)


KILL_AFTER_FIRST_RENAME = textwrap.dedent("""
    import os, signal, sys
    from pathlib import Path
    from consistid.cli.files import atomic_dir
    real = os.replace
    def replace_then_die(src, dst):
        real(src, dst)
        os.kill(os.getpid(), signal.SIGKILL)
    os.replace = replace_then_die
    src = Path(sys.argv[1])
    with atomic_dir(sys.argv[2]) as tmp:
        for name in ("result.json", "parameters.csv"):
            (tmp / name).write_bytes((src / name).read_bytes())
""")


def test_killed_among_the_renames_the_mixed_set_is_refused_on_load(config, capsys, tmp_path):
    first, out = tmp_path / "first", tmp_path / "out"
    assert main(["-q", "identify", str(config), "--output", str(first)]) == 0
    capsys.readouterr()
    shutil.copytree(first, out)
    run = _python(KILL_AFTER_FIRST_RENAME, first, out)
    run.communicate(timeout=60)
    assert run.returncode == -signal.SIGKILL
    assert interrupted_files(out) == ["parameters.csv", "result.json"]
    with pytest.raises(ResultFileError, match="interrupted"):
        ci.IdentificationResult.load(out / "result.json")
    # a whole set written again (as --force does) removes the journal
    with atomic_dir(out) as tmp:
        for name in ("result.json", "parameters.csv"):
            shutil.copy(first / name, tmp / name)
    assert not (out / JOURNAL).exists()
    ci.IdentificationResult.load(out / "result.json")


def test_killed_while_a_new_folder_is_committed_leaves_all_or_nothing(tmp_path):
    src, out = tmp_path / "src", tmp_path / "new"
    src.mkdir()
    for name in ("result.json", "parameters.csv"):
        (src / name).write_text(name)
    run = _python(KILL_AFTER_FIRST_RENAME, src, out)
    run.communicate(timeout=60)
    # a new folder is one rename (no per-file rename to be killed after): whole
    assert sorted(p.name for p in out.iterdir()) == ["parameters.csv", "result.json"]
    assert not _staging(out)


def test_a_new_result_folder_gets_the_usual_permissions(tmp_path):
    out = tmp_path / "new"
    with atomic_dir(out) as tmp:
        (tmp / "x.txt").write_text("x")
    mask = os.umask(0o022)
    os.umask(mask)
    assert out.stat().st_mode & 0o777 == 0o777 & ~mask


# ----------------------------------------------------------------------------- real runs
def _whole(out: Path) -> bool:
    """``out`` holds a whole identify set (the 2R arm's has no robot.urdf/xml: gravity −y)."""
    names = {p.name for p in out.iterdir()}
    return {"result.json", "parameters.csv", "report.html"} <= names <= set(
        commands.IDENTIFY_OUTPUTS)


def _wait_for(predicate, timeout: float = 60.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.005)
    return False


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_mid_write_removes_the_temporaries(config, sig):
    out = config.parent.parent / "out"
    run = _python(CLI, "-q", "identify", config, "--output", out)
    try:
        assert _wait_for(lambda: _staging(out) or run.poll() is not None)
        run.send_signal(sig)
        _, err = run.communicate(timeout=60)
    finally:
        run.kill()
    if run.returncode == 0:                    # it finished first: then the set is whole
        assert _whole(out)
    else:
        assert run.returncode == 128 + sig, err
        assert "interrupted" in err and "Traceback" not in err
        # before the renames: nothing; during them (the signal waits): the whole set
        assert not out.exists() or _whole(out)
    assert not _staging(out) and not list(out.parent.glob(".out.consistid-lock"))


@pytest.mark.slow
def test_two_identify_runs_at_once_the_second_is_refused(config):
    out = config.parent.parent / "out"
    first = _python(CLI, "-q", "identify", config, "--output", out)
    lock = out.parent / ".out.consistid-lock"
    assert _wait_for(lambda: lock.exists() or first.poll() is not None)
    first.send_signal(signal.SIGSTOP)          # paused while it holds the output
    try:
        second = _python(CLI, "-q", "identify", config, "--output", out, "--force")
        _, err2 = second.communicate(timeout=120)
    finally:
        first.send_signal(signal.SIGCONT)
    _, err1 = first.communicate(timeout=120)
    assert first.returncode == 0, err1
    assert second.returncode == 2 and "being written by another consistid run" in err2
    doc = json.loads((out / "result.json").read_text())
    assert doc["n_samples"] == 300 and _whole(out)


def test_check_output_dir_refuses_a_folder_another_process_locked(tmp_path):
    from consistid.cli.files import check_output, check_output_dir
    out = tmp_path / "o"
    holder = _python("import sys; from consistid.filesafety import lock_output;"
                     "lock_output(sys.argv[1]); lock_output(sys.argv[2]);"
                     "print('held', flush=True); sys.stdin.read()", out, tmp_path / "f.csv",
                     stdin=subprocess.PIPE)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(OutputPathError, match="another consistid run"):
            check_output_dir(out, ["a.csv"], what="--output")
        with pytest.raises(OutputPathError, match="another consistid run"):
            check_output(tmp_path / "f.csv", what="--output")
    finally:
        holder.kill()
        holder.communicate(timeout=30)

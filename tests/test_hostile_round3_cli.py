"""Hostile input, round three (issue 30): every ``consistid`` subcommand that reads a file,
given a hostile one.

Each case runs ``main([...])`` in-process with a configuration whose URDF or log is hostile (an
XML entity, a newline in a joint name, a forged or pickled ``.npz``, a bad CRC, complex
MATLAB values, a folder where a file belongs) and asserts exit status 2, a message naming the
file, and no traceback: zero foreign exceptions from the command line.
"""

from __future__ import annotations

import io
import struct
import zipfile

import numpy as np
import pytest
import scipy.io

from consistid.cli import main

from .conftest import PLANAR_2R, PLANAR_2R_VALUES

ARM = PLANAR_2R.format(**PLANAR_2R_VALUES)
MODEL = 'root = ".."\n[model]\nurdf = "data/{urdf}"\ngravity = [0.0, -9.81, 0.0]\n'
DATA = '[data]\ndir = "data"\ntrain = ["{log}"]\n'
CONFIGS = {
    "identify": MODEL + DATA + '[identify]\nmethod = "ols"\nfriction = ["coulomb"]\n',
    "recover": MODEL + DATA + '[recover]\nmode = "nearest"\nfriction = []\nurdf = "out.urdf"\n',
    "diagnose": MODEL + DATA + '[diagnose]\noutput = "report"\n',
    "payload": MODEL + DATA + '[payload]\nloaded = ["{log}"]\nbody = "link2"\n',
    "excite": MODEL + '[excite]\nharmonics = 1\nperiod = 4.0\nfriction = []\nn_starts = 1\n'
                      'max_iter = 2\nn_grid = 20\nrate = 20.0\noutput = "traj.csv"\n',
}
URDFS = {
    "entity": ('<?xml version="1.0"?>\n<!DOCTYPE robot [<!ENTITY n "joint1">]>\n'
               + ARM.split("?>", 1)[1].replace('name="joint1"', 'name="&n;"'), "entities"),
    "newline": (ARM.replace('name="joint1"', 'name="joint&#10;1"'), "control character"),
}


def _forged(good: dict[str, bytes]) -> dict[str, bytes]:
    text = "{'descr': '<f8', 'fortran_order': False, 'shape': (4000000000,), }"
    text += " " * (118 - len(text)) + "\n"
    return {**good, "q.npy": b"\x93NUMPY\x01\x00" + struct.pack("<H", len(text))
            + text.encode() + bytes(64)}


def _pickled(good: dict[str, bytes]) -> dict[str, bytes]:
    buf = io.BytesIO()
    np.save(buf, np.array([{"q": 1}] * 300, dtype=object), allow_pickle=True)
    return {**good, "q.npy": buf.getvalue()}


def _write_npz(path, members):
    with zipfile.ZipFile(path, "w") as zf:
        for name, raw in members.items():
            zf.writestr(name, raw)


def _bad_crc(path):
    raw = bytearray(path.read_bytes())
    with zipfile.ZipFile(path) as zf:
        info = zf.getinfo("q.npy")
    raw[info.header_offset + 30 + len(info.filename) + len(info.extra) + 300] ^= 0xFF
    return bytes(raw)


def _logs(data) -> dict[str, str]:
    """Hostile logs beside the good run1.npz: name → what the message must say."""
    with zipfile.ZipFile(data / "run1.npz") as zf:
        good = {i.filename: zf.read(i) for i in zf.infolist()}
    _write_npz(data / "forged.npz", _forged(good))
    _write_npz(data / "pickled.npz", _pickled(good))
    (data / "crc.npz").write_bytes(_bad_crc(data / "run1.npz"))
    (data / "folder.npz").mkdir()
    with np.load(data / "run1.npz") as f:
        scipy.io.savemat(data / "complex.mat", {"t": f["t"], "q": f["q"] + 1j, "tau": f["tau"]})
    return {"forged.npz": "claims shape", "pickled.npz": "Python objects",
            "crc.npz": "crc.npz", "folder.npz": "folder", "complex.mat": "complex"}


CASES = ([(cmd, "urdf", kind) for cmd in CONFIGS for kind in URDFS]
         + [(cmd, "log", name) for cmd in ("identify", "recover", "diagnose", "payload")
            for name in ("forged.npz", "pickled.npz", "crc.npz", "folder.npz", "complex.mat")])


@pytest.mark.parametrize("command, what, kind", CASES)
def test_hostile_files_are_named_by_every_subcommand(cli_project, capsys, command, what, kind):
    data = cli_project / "data"
    said = _logs(data)
    urdf, log, needle = "arm.urdf", "run1.npz", None
    if what == "urdf":
        (data / "hostile.urdf").write_text(URDFS[kind][0])
        urdf, needle = "hostile.urdf", URDFS[kind][1]
    else:
        log, needle = kind, said[kind]
    config = cli_project / "conf" / "run.toml"
    config.write_text(CONFIGS[command].format(urdf=urdf, log=log))
    got = main([command, str(config)])
    out = capsys.readouterr()
    assert got == 2, out.err
    assert "Traceback" not in out.err + out.out
    assert needle in out.err and (urdf if what == "urdf" else log) in out.err


@pytest.mark.parametrize("command", ["demo", "simulate"])
@pytest.mark.parametrize("kind", list(URDFS))
def test_urdf_arguments_are_parsed_safely(tmp_path, capsys, command, kind):
    (tmp_path / "hostile.urdf").write_text(URDFS[kind][0])
    args = [command, "--urdf", str(tmp_path / "hostile.urdf")]
    if command == "demo":
        args += ["--output", str(tmp_path / "out")]
    got = main(args)
    out = capsys.readouterr()
    assert got == 2 and "Traceback" not in out.err + out.out
    assert URDFS[kind][1] in out.err and not (tmp_path / "out").exists()


def test_recover_coefficients_that_are_forged_or_pickled(cli_project, capsys):
    data = cli_project / "data"
    beta = io.BytesIO()
    np.save(beta, np.array([{"b": 1}], dtype=object), allow_pickle=True)
    _write_npz(data / "coef.npz", {"beta.npy": beta.getvalue()})
    config = cli_project / "conf" / "run.toml"
    config.write_text(MODEL.format(urdf="arm.urdf")
                      + '[recover]\nmode = "nearest"\nfriction = []\nurdf = "out.urdf"\n'
                        'coefficients = "data/coef.npz"\n')
    got = main(["recover", str(config)])
    out = capsys.readouterr()
    assert got == 2 and "Traceback" not in out.err and "Python objects" in out.err

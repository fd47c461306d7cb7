"""Hostile input, round three (issue 30): corrupt, forged and oddly encoded logs.

Every reader names the file and what is wrong (a ``DatasetError``) for a corrupt, truncated,
forged-oversized or pickled ``.npz``, a ``.mat`` of strings, ragged cells or complex values, a
bag whose encapsulation rosbags cannot decode or whose message repeats a joint name, a folder
given as a file; and accepts the legal but odd (a BOM, 1 200 columns).
"""

from __future__ import annotations

import io
import struct
import zipfile

import numpy as np
import pytest
import scipy.io

import consistid as ci
from consistid.data.recordings import load_recording
from consistid.errors import DatasetError

from .conftest import random_states

N = 60


@pytest.fixture()
def log(planar_2r):
    rng = np.random.default_rng(3)
    q, dq, ddq = random_states(planar_2r, N, 3)
    tau = planar_2r.rnea(q, dq, ddq) + 0.01 * rng.standard_normal(q.shape)
    return ci.Dataset(t=0.005 * np.arange(N), q=q, dq=dq, ddq=ddq, tau=tau)


def _members(data: ci.Dataset, tmp_path) -> dict[str, bytes]:
    data.save(tmp_path / "good.npz")
    with zipfile.ZipFile(tmp_path / "good.npz") as zf:
        return {i.filename: zf.read(i) for i in zf.infolist()}


def _npz(path, members: dict[str, bytes]):
    with zipfile.ZipFile(path, "w") as zf:
        for name, raw in members.items():
            zf.writestr(name, raw)
    return path


def _npy_header(shape, descr="<f8") -> bytes:
    text = f"{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}"
    text += " " * (118 - len(text)) + "\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(text)) + text.encode()


def _both(path, planar_2r):
    """The errors of both public readers of an .npz (Dataset.load and load_recording)."""
    out = []
    for read in (lambda: ci.Dataset.load(path), lambda: load_recording(path, model=planar_2r)):
        with pytest.raises(DatasetError) as info:
            read()
        out.append(str(info.value))
    return out


def test_a_claimed_4e9_element_array_is_refused_from_its_header(log, tmp_path, planar_2r):
    members = _members(log, tmp_path)
    members["q.npy"] = _npy_header((4_000_000_000,)) + bytes(64)
    for err in _both(_npz(tmp_path / "huge.npz", members), planar_2r):
        assert "'q' claims shape (4000000000,)" in err and "huge.npz" in err


def test_the_size_budget_is_checked_before_allocating(log, tmp_path, planar_2r, monkeypatch):
    from consistid.data import npzfile
    log.save(tmp_path / "log.npz")
    monkeypatch.setattr(npzfile, "BUDGET_BYTES", 1000)
    for err in _both(tmp_path / "log.npz", planar_2r):
        assert "budget" in err and "GiB" in err


def test_object_arrays_are_refused_as_pickles(log, tmp_path, planar_2r):
    members = _members(log, tmp_path)
    buf = io.BytesIO()
    np.save(buf, np.array([{"x": 1}] * N, dtype=object), allow_pickle=True)
    members["q.npy"] = buf.getvalue()
    for err in _both(_npz(tmp_path / "obj.npz", members), planar_2r):
        assert "'q' holds Python objects" in err and "allow_pickle" not in err


@pytest.mark.parametrize("member", ["q.npy", "tau.npy", "t.npy"])
def test_a_bad_crc_is_named(log, tmp_path, planar_2r, member):
    log.save(tmp_path / "log.npz")
    raw = bytearray((tmp_path / "log.npz").read_bytes())
    with zipfile.ZipFile(tmp_path / "log.npz") as zf:
        info = zf.getinfo(member)
    start = info.header_offset + 30 + len(info.filename) + len(info.extra) + 200
    raw[start] ^= 0xFF                                  # a flipped bit in the array's data
    (tmp_path / "bad.npz").write_bytes(bytes(raw))
    for err in _both(tmp_path / "bad.npz", planar_2r):
        assert "bad.npz" in err and ("CRC" in err or "corrupt" in err)


def test_a_truncated_npz_and_a_folder_are_named(log, tmp_path, planar_2r):
    log.save(tmp_path / "log.npz")
    (tmp_path / "cut.npz").write_bytes((tmp_path / "log.npz").read_bytes()[:700])
    for err in _both(tmp_path / "cut.npz", planar_2r):
        assert "cut.npz" in err
    folder = tmp_path / "logs.npz"
    folder.mkdir()
    with pytest.raises(DatasetError, match="is a folder"):
        ci.Dataset.load(folder)
    with pytest.raises(DatasetError, match="folder"):
        load_recording(folder, model=planar_2r)


def test_npz_logs_still_read_back_bit_for_bit(log, tmp_path):
    log.save(tmp_path / "log.npz")
    back = ci.Dataset.load(tmp_path / "log.npz")
    assert np.array_equal(back.q, log.q) and np.array_equal(back.tau, log.tau)


# ----------------------------------------------------------------------------- MATLAB
def _mat(tmp_path, log, **replace):
    arrays = {"t": log.t, "q": log.q, "tau": log.tau, **replace}
    scipy.io.savemat(tmp_path / "log.mat", arrays)
    return tmp_path / "log.mat"


def test_complex_mat_values_are_refused_not_truncated(log, tmp_path, planar_2r):
    path = _mat(tmp_path, log, tau=log.tau + 0.5j)
    with pytest.raises(DatasetError, match="'tau' holds complex numbers"):
        load_recording(path, model=planar_2r)


def test_complex_mat_column_vectors_are_refused(log, tmp_path, planar_2r):
    cols = {"time": log.t, "joint1_position": log.q[:, 0], "joint2_position": log.q[:, 1],
            "joint1_effort": log.tau[:, 0] + 1j, "joint2_effort": log.tau[:, 1]}
    scipy.io.savemat(tmp_path / "cols.mat", cols)
    with pytest.raises(DatasetError, match="'joint1_effort' holds complex"):
        load_recording(tmp_path / "cols.mat", model=planar_2r)


def test_strings_and_ragged_cells_in_a_mat_are_named(log, tmp_path, planar_2r):
    with pytest.raises(DatasetError, match="'q' holds text"):
        load_recording(_mat(tmp_path, log, q=np.array(["a"] * N)), model=planar_2r)
    cell = np.empty(2, dtype=object)
    cell[0], cell[1] = np.zeros(3), np.zeros(5)
    with pytest.raises(DatasetError, match="'q' holds a cell array"):
        load_recording(_mat(tmp_path, log, q=cell), model=planar_2r)


def test_a_truncated_mat_is_named(log, tmp_path, planar_2r):
    path = _mat(tmp_path, log)
    path.write_bytes(path.read_bytes()[:300])
    with pytest.raises(DatasetError, match="log.mat"):
        load_recording(path, model=planar_2r)


# ----------------------------------------------------------------------------- CSV
def _robot_csv(log, extra: int = 0) -> str:
    header = ["time", "joint1_position", "joint2_position", "joint1_effort", "joint2_effort"]
    header += [f"spare{k}" for k in range(extra)]
    rows = [",".join(header)]
    for k in range(N):
        values = [log.t[k], *log.q[k], *log.tau[k], *([0.0] * extra)]
        rows.append(",".join(repr(float(v)) for v in values))
    return "\n".join(rows) + "\n"


def test_a_bom_and_1200_columns_are_accepted(log, tmp_path, planar_2r):
    (tmp_path / "bom.csv").write_bytes(b"\xef\xbb\xbf" + _robot_csv(log).encode())
    (tmp_path / "wide.csv").write_text(_robot_csv(log, extra=1200))
    (tmp_path / "plain.csv").write_text(_robot_csv(log))
    plain = load_recording(tmp_path / "plain.csv", model=planar_2r).dataset
    for name in ("bom.csv", "wide.csv"):
        read = load_recording(tmp_path / name, model=planar_2r).dataset
        assert np.array_equal(read.q, plain.q) and np.array_equal(read.tau, plain.tau)
    log.save(tmp_path / "ds.csv")
    (tmp_path / "ds_bom.csv").write_bytes(b"\xef\xbb\xbf" + (tmp_path / "ds.csv").read_bytes())
    assert np.array_equal(ci.Dataset.load(tmp_path / "ds_bom.csv").q,
                          ci.Dataset.load(tmp_path / "ds.csv").q)


def test_a_latin1_header_is_read_with_a_warning(log, tmp_path, planar_2r):
    text = "# Messung über Gelänk\n" + _robot_csv(log)
    (tmp_path / "latin1.csv").write_bytes(text.encode("latin-1"))
    with pytest.warns(ci.DataQualityWarning, match="latin1.csv, line 1.*Latin-1.*über"):
        rec = load_recording(tmp_path / "latin1.csv", model=planar_2r)
    (tmp_path / "utf8.csv").write_text(text, encoding="utf-8")
    np.testing.assert_array_equal(rec.dataset.q,
                                  load_recording(tmp_path / "utf8.csv", model=planar_2r).dataset.q)
    log.save(tmp_path / "ds.csv")
    raw = (tmp_path / "ds.csv").read_bytes().replace(b"t,", "tä,".encode("latin-1"), 1)
    (tmp_path / "ds_latin1.csv").write_bytes(raw)
    with pytest.raises(DatasetError, match="not UTF-8"):
        ci.Dataset.load(tmp_path / "ds_latin1.csv")


# ----------------------------------------------------------------------------- bags
def _bag(path, log, names=("joint1", "joint2"), encapsulation: bytes | None = None):
    pytest.importorskip("rosbags")
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    js = ts.types["sensor_msgs/msg/JointState"]
    header, stamp = ts.types["std_msgs/msg/Header"], ts.types["builtin_interfaces/msg/Time"]
    k_names = len(names)
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        c = w.add_connection("/joint_states", js.__msgtype__, typestore=ts)
        for k in range(N):
            ns = 10**9 + int(log.t[k] * 1e9)
            msg = js(header=header(stamp=stamp(sec=int(ns // 10**9), nanosec=int(ns % 10**9)),
                                   frame_id=""), name=list(names),
                     position=np.resize(log.q[k], k_names), velocity=np.resize(log.dq[k], k_names),
                     effort=np.resize(log.tau[k], k_names))
            raw = bytes(ts.serialize_cdr(msg, js.__msgtype__))
            if encapsulation is not None:
                raw = encapsulation + raw[4:]
            w.write(c, ns, raw)
    return path


def test_a_bag_with_an_unsupported_encapsulation_is_named(log, tmp_path, planar_2r):
    path = _bag(tmp_path / "xcdr", log, encapsulation=b"\x00\x0b\x00\x00")
    with pytest.raises(DatasetError, match="message 0 .*cannot be decoded"):
        load_recording(path, model=planar_2r)


def test_a_bag_repeating_a_joint_name_is_named(log, tmp_path, planar_2r):
    path = _bag(tmp_path / "twice", log, names=("joint1", "joint2", "joint1"))
    with pytest.raises(DatasetError, match=r"\['joint1'\] appear more than once"):
        load_recording(path, model=planar_2r)


def test_a_plain_bag_still_reads(log, tmp_path, planar_2r):
    data = load_recording(_bag(tmp_path / "plain", log), model=planar_2r).dataset
    assert data.joint_names == ("joint1", "joint2") and data.n_samples >= N // 2

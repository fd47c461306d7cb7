"""Log formats in: CSV (several header styles), DataFrame, Parquet, ROS 2 bags and MCAP, ROS 1 bags
and .mat give the same Datasets; broken files get named errors (file, column, line)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.io
from hypothesis import given, settings
from hypothesis import strategies as st

from consistid.data.formats import read_log
from consistid.data.formats.columns import map_columns, parse_column
from consistid.data.recordings import from_arrays, from_frame, load_recording
from consistid.errors import DatasetError, MissingColumnsError, OptionError

pd = pytest.importorskip("pandas")
NS0 = 1_700_000_000_123_456_789            # a Unix stamp in ns
JOINTS = ("joint1", "joint2")
RATE = 500.0


@pytest.fixture(scope="module")
def log():
    """A 500 Hz log of the planar 2R arm plus a gripper joint the model does not have."""
    n = 2000
    ns = NS0 + np.arange(n, dtype=np.int64) * 2_000_000
    s = (ns - NS0) * 1e-9
    q = np.column_stack([np.sin(1.1 * s), 0.5 * np.cos(0.7 * s), 0.01 * np.sin(3 * s)])
    dq = np.column_stack([1.1 * np.cos(1.1 * s), -0.35 * np.sin(0.7 * s), 0.03 * np.cos(3 * s)])
    tau = np.column_stack([np.cos(0.9 * s) + 2, np.sin(1.3 * s), 0.1 + 0 * s])
    return dict(ns=ns, t=NS0 * 1e-9 + s, q=q, dq=dq, tau=tau, names=(*JOINTS, "gripper"))


def frame_of(log, style="suffix"):
    cols = {"time": log["t"]}
    for j, name in enumerate(log["names"]):
        if style == "suffix":
            cols[f"{name}.q"] = log["q"][:, j]
        else:
            cols[name] = log["q"][:, j]                       # bare joint-name headers
    for j, name in enumerate(log["names"]):
        cols[f"{name}_effort" if style == "suffix" else f"tau_{name}"] = log["tau"][:, j]
    return pd.DataFrame(cols)


def write_csv(path, frame, sep=","):
    with open(path, "w") as fh:
        fh.write("# logged by a controller\n")
        fh.write(sep.join(frame.columns) + "\n")
        for row in frame.to_numpy():
            fh.write(sep.join(f"{v:.17g}" for v in row) + "\n")
    return path


def write_bag(path, log, storage="mcap", shuffle=False):
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    js = ts.types["sensor_msgs/msg/JointState"]
    header, stamp = ts.types["std_msgs/msg/Header"], ts.types["builtin_interfaces/msg/Time"]
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    rng = np.random.default_rng(0)
    with Writer(path, version=9, storage_plugin=plugin) as w:
        c = w.add_connection("/joint_states", js.__msgtype__, typestore=ts)
        for k, ns in enumerate(log["ns"]):
            order = rng.permutation(3) if shuffle else np.arange(3)
            msg = js(header=header(stamp=stamp(sec=int(ns // 10**9), nanosec=int(ns % 10**9)),
                                   frame_id=""),
                     name=[log["names"][i] for i in order], position=log["q"][k, order],
                     velocity=log["dq"][k, order], effort=log["tau"][k, order])
            w.write(c, int(ns) + 5000, ts.serialize_cdr(msg, js.__msgtype__))
    return path


def same(a, b, exact=False):
    """Equal datasets; bitwise for the same float stamps, else within what Unix stamps in float
    seconds (0.24 µs resolution) against integer nanoseconds change after the filters (≤ 1e-7)."""
    assert a.joint_names == b.joint_names
    atol = 0.0 if exact else 1e-6
    np.testing.assert_allclose(a.t, b.t, rtol=0, atol=0.0 if exact else 1e-6)
    for f in ("q", "dq", "ddq", "tau"):
        np.testing.assert_allclose(getattr(a, f), getattr(b, f), rtol=0, atol=atol, err_msg=f)
    np.testing.assert_array_equal(a.segment, b.segment)


# ----------------------------------------------------------------------------- acceptance
def test_csv_parquet_frame_and_bags_give_the_same_dataset(tmp_path, log, planar_2r):
    pytest.importorskip("pyarrow")
    pytest.importorskip("rosbags")
    frame = frame_of(log)
    csv = write_csv(tmp_path / "log.csv", frame_of(log, "bare"), sep=";")
    frame.to_parquet(tmp_path / "log.parquet")
    mcap = write_bag(tmp_path / "bag_mcap", log, "mcap", shuffle=True)
    db3 = write_bag(tmp_path / "bag_db3", log, "sqlite3")
    recs = {
        "csv": load_recording(csv, model=planar_2r),
        "parquet": load_recording(tmp_path / "log.parquet", model=planar_2r),
        "frame": from_frame(frame, joints=JOINTS, model=planar_2r),
        "mcap": load_recording(mcap, model=planar_2r),
        "bare mcap": load_recording(next(mcap.glob("*.mcap")), model=planar_2r),
        "db3": load_recording(db3, model=planar_2r),
    }
    ref = recs["csv"].dataset
    assert ref.joint_names == JOINTS and ref.nv == 2
    for name, rec in recs.items():
        same(ref, rec.dataset, exact=name in ("parquet", "frame"))
        assert rec.time_origin == pytest.approx(NS0 * 1e-9, abs=1e-6), name
        text = "\n".join(rec.steps)
        assert "2023-11-14" in text and "gripper" in text, name      # origin; dropped joint
    assert "';' (sniffed)" in "\n".join(recs["csv"].steps)
    assert "velocities" in "\n".join(recs["mcap"].steps)         # logged dq set aside, said
    # the derivative chain ran on the same numbers: ddq against the closed form
    d = ref
    s = d.t
    np.testing.assert_allclose(d.ddq[:, 0], -1.21 * np.sin(1.1 * s), atol=2e-3)


def test_a_ros1_bag_reads_like_a_ros2_one(tmp_path, log, planar_2r):
    pytest.importorskip("rosbags")
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    js = ts.types["sensor_msgs/msg/JointState"]
    header, stamp = ts.types["std_msgs/msg/Header"], ts.types["builtin_interfaces/msg/Time"]
    path = tmp_path / "log.bag"
    with Writer(path) as w:
        c = w.add_connection("/robot/joint_states", js.__msgtype__, typestore=ts)
        for k, ns in enumerate(log["ns"]):
            msg = js(header=header(seq=k, stamp=stamp(sec=int(ns // 10**9),
                                                     nanosec=int(ns % 10**9)), frame_id=""),
                     name=list(log["names"]), position=log["q"][k], velocity=log["dq"][k],
                     effort=log["tau"][k])
            w.write(c, int(ns), ts.serialize_ros1(msg, js.__msgtype__))
    rec = load_recording(path, model=planar_2r)
    ref = from_arrays(log["t"], log["q"][:, :2], log["tau"][:, :2], joint_names=JOINTS,
                      model=planar_2r)
    same(ref.dataset, rec.dataset)


def test_mat_files_in_both_layouts(tmp_path, log, planar_2r):
    ref = from_arrays(log["t"], log["q"][:, :2], log["tau"][:, :2], joint_names=JOINTS,
                      model=planar_2r).dataset
    scipy.io.savemat(tmp_path / "arrays.mat", {"log": {
        "time": log["t"], "position": log["q"], "effort": log["tau"],
        "joint_names": np.array(log["names"], dtype=object)}})
    scipy.io.savemat(tmp_path / "columns.mat", {
        "t": log["t"], **{f"q_{n}": log["q"][:, j] for j, n in enumerate(log["names"])},
        **{f"tau_{n}": log["tau"][:, j] for j, n in enumerate(log["names"])}})
    for name in ("arrays.mat", "columns.mat"):
        same(ref, load_recording(tmp_path / name, model=planar_2r).dataset)


# ----------------------------------------------------------------------------- column mapping
@pytest.mark.parametrize("name, parsed", [
    ("q1", ("q", 0)), ("q_2", ("q", 1)), ("q_panda_joint1", ("q", "panda_joint1")),
    ("panda_joint1.q", ("q", "panda_joint1")), ("elbow_joint_effort", ("tau", "elbow_joint")),
    ("tau[elbow]", ("tau", "elbow")), ("shoulder/position", ("q", "shoulder")),
    ("dq3 [rad/s]", ("dq", 2)), ("Torque_A1", ("tau", "A1")), ("panda_joint1", None),
    ("time", None)])
def test_column_names(name, parsed):
    assert parse_column(name) == parsed


def test_explicit_mapping_and_time_units(tmp_path, log):
    names = ["stamp_ms", "pos_a", "pos_b", "eff_a", "eff_b"]
    m = map_columns(names, "x.csv", joints=["a", "b"],
                    columns={"t": "stamp_ms", "q": "pos_{joint}", "tau": "eff_{joint}"})
    assert m.fields == {"q": ["pos_a", "pos_b"], "tau": ["eff_a", "eff_b"]}
    assert m.time_unit == "ms"
    path = tmp_path / "ms.csv"
    frame = pd.DataFrame({"time_ms": (log["t"] - log["t"][0]) * 1e3, "q1": log["q"][:, 0],
                          "tau1": log["tau"][:, 0]})
    frame.to_csv(path, index=False, float_format="%.17g")
    rec = load_recording(path)
    assert 3.0 < rec.dataset.duration < 2000 / RATE      # 4 s less the filter edges, not 2000 s
    assert any("time unit 'ms' from the file" in s for s in rec.steps)
    frame.rename(columns={"time_ms": "t"}).to_csv(path, index=False, float_format="%.17g")
    with pytest.raises(DatasetError, match=r"0.5 Hz in seconds.*pass time_unit='ms' \(500 Hz\)$"):
        load_recording(path)
    rec = load_recording(path, time_unit="auto")
    assert any("read as ms (time_unit='auto')" in s for s in rec.steps)
    assert rec.dataset.duration < 5.0


# ----------------------------------------------------------------------------- bad files
def test_bad_files_get_named_errors(tmp_path, log, planar_2r):
    good = frame_of(log)
    text = write_csv(tmp_path / "good.csv", good).read_text().splitlines()

    def put(name, lines):
        path = tmp_path / name
        path.write_text("\n".join(lines) + "\n")
        return path

    with pytest.raises(DatasetError, match="empty.csv is empty"):
        load_recording(put("empty.csv", [""]))
    with pytest.raises(DatasetError, match="no data rows"):
        load_recording(put("header.csv", text[:2]))
    broken = text[:50] + [text[50].replace(text[50].split(",")[2], "abc", 1)] + text[51:]
    with pytest.raises(DatasetError, match=r"broken.csv, line 51, column 'joint2.q': 'abc'"):
        load_recording(put("broken.csv", broken), model=planar_2r)
    ragged = text[:70] + [",".join(text[70].split(",")[:-2])] + text[71:]
    with pytest.raises(DatasetError, match=r"ragged.csv, line 71: 5 fields, the header has 7"):
        load_recording(put("ragged.csv", ragged), model=planar_2r)
    nan = text[:30] + ["nan" + text[30][text[30].index(","):]] + text[31:]
    with pytest.raises(DatasetError, match=r"nan.csv, line 31, column 'time': an empty cell or"):
        load_recording(put("nan.csv", nan), model=planar_2r)
    wrong = [text[0], text[1].replace("joint2_effort", "joint2_current")] + text[2:]
    with pytest.raises(MissingColumnsError, match=r"wrong.csv: tau columns lack joint\(s\) "
                                                  r"\['joint2'\]"):
        load_recording(put("wrong.csv", wrong), model=planar_2r)
    with pytest.raises(MissingColumnsError, match="no time column"):
        load_recording(put("notime.csv", [text[0], text[1].replace("time", "clock")] + text[2:]))
    with pytest.raises(MissingColumnsError, match="is data, not a header"):
        load_recording(put("noheader.csv", text[2:]))
    with pytest.raises(DatasetError, match="unknown log format '.xlsx'"):
        read_log(put("log.xlsx", text))
    with pytest.raises(OptionError, match="topic"):
        read_log(tmp_path / "good.csv", topic="/joint_states")


def test_a_bag_without_joint_states_is_named(tmp_path):
    pytest.importorskip("rosbags")
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    s = ts.types["std_msgs/msg/String"]
    with Writer(tmp_path / "chatter", version=9, storage_plugin=StoragePlugin.MCAP) as w:
        c = w.add_connection("/chatter", s.__msgtype__, typestore=ts)
        w.write(c, 1, ts.serialize_cdr(s(data="hi"), s.__msgtype__))
    with pytest.raises(DatasetError, match=r"chatter has no sensor_msgs/JointState topic; its "
                                           r"topics are \['/chatter \(std_msgs/msg/String\)'\]"):
        load_recording(tmp_path / "chatter")
    (tmp_path / "fake.mcap").write_bytes(b"not a bag")
    with pytest.raises(DatasetError, match="fake.mcap is not a readable ROS bag"):
        load_recording(tmp_path / "fake.mcap")


def test_a_bag_without_efforts_is_named(tmp_path, log):
    pytest.importorskip("rosbags")
    no_effort = dict(log, tau=np.zeros((log["q"].shape[0], 0)))
    no_effort["tau"] = np.empty((log["q"].shape[0], 0))
    path = write_bag(tmp_path / "noeff", {**log, "tau": log["tau"]}, "mcap")
    assert load_recording(path).dataset.nv == 3
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    js = ts.types["sensor_msgs/msg/JointState"]
    header, stamp = ts.types["std_msgs/msg/Header"], ts.types["builtin_interfaces/msg/Time"]
    with Writer(tmp_path / "pos_only", version=9, storage_plugin=StoragePlugin.MCAP) as w:
        c = w.add_connection("/joint_states", js.__msgtype__, typestore=ts)
        for k in range(40):
            msg = js(header=header(stamp=stamp(sec=1, nanosec=k * 1000), frame_id=""),
                     name=["a"], position=np.array([0.1 * k]), velocity=np.array([]),
                     effort=np.array([]))
            w.write(c, k, ts.serialize_cdr(msg, js.__msgtype__))
    with pytest.raises(MissingColumnsError, match="has no effort"):
        load_recording(tmp_path / "pos_only")


# ----------------------------------------------------------------------------- fuzz
STYLES = {"prefix": ("q_{j}", "tau_{j}"), "suffix": ("{j}.q", "{j}.torque"),
          "bracket": ("position[{j}]", "effort[{j}]"), "ros": ("{j}/position", "{j}/effort"),
          "bare": ("{j}", "{j}_effort")}


@settings(max_examples=25, deadline=None)
@given(names=st.lists(st.from_regex(r"[a-z][a-z0-9]{0,6}_joint[0-9]", fullmatch=True),
                      min_size=1, max_size=5, unique=True),
       style=st.sampled_from(sorted(STYLES)), sep=st.sampled_from([",", ";", "\t"]),
       seed=st.integers(0, 2 ** 16), extra=st.booleans())
def test_csv_headers_in_any_style_read_back_exactly(tmp_path_factory, names, style, sep, seed,
                                                    extra):
    """Whatever the header style and delimiter, the columns come back in joints= order, the
    extra joint dropped and said."""
    rng = np.random.default_rng(seed)
    n = 30
    t = np.cumsum(rng.uniform(0.9e-3, 1.1e-3, n))
    q, tau = rng.normal(size=(n, len(names))), rng.normal(size=(n, len(names)))
    qs, ts = STYLES[style]
    cols = {"time": t}
    all_names = [*names, "gripper_joint9"] if extra else names
    qx = np.column_stack([q, rng.normal(size=n)]) if extra else q
    tx = np.column_stack([tau, rng.normal(size=n)]) if extra else tau
    order = rng.permutation(len(all_names))
    for k in order:
        cols[qs.format(j=all_names[k])] = qx[:, k]
    for k in order[::-1]:
        cols[ts.format(j=all_names[k])] = tx[:, k]
    path = tmp_path_factory.mktemp("fuzz") / "log.csv"
    write_csv(path, pd.DataFrame(cols), sep=sep)
    got = read_log(path, joints=names)
    assert got.joint_names == tuple(names)
    np.testing.assert_array_equal(got.fields["q"], q)
    np.testing.assert_array_equal(got.fields["tau"], tau)
    np.testing.assert_array_equal(got.t, t)
    if extra:
        assert "gripper_joint9" in " ".join(got.notes)


def test_missing_values_in_parquet_frames_and_bags_are_named(tmp_path, log):
    pytest.importorskip("pyarrow")
    frame = frame_of(log)
    frame.loc[7, "joint2_effort"] = np.nan
    with pytest.raises(DatasetError, match=r"DataFrame, row 7, column 'joint2_effort': an empty"):
        from_frame(frame)
    frame.to_parquet(tmp_path / "nan.parquet")
    with pytest.raises(DatasetError, match=r"nan.parquet, row 7, column 'joint2_effort'"):
        load_recording(tmp_path / "nan.parquet")
    pytest.importorskip("rosbags")
    q = log["q"].copy()
    q[12, 1] = np.nan
    write_bag(tmp_path / "nanbag", {**log, "q": q})
    with pytest.raises(DatasetError, match=r"message 12 .*position of joint 'joint2' is nan"):
        load_recording(tmp_path / "nanbag")


def test_a_missing_optional_package_names_the_extra(tmp_path, monkeypatch, log):
    import sys

    from consistid.errors import MissingDependencyError

    (tmp_path / "x.parquet").write_bytes(b"PAR1")
    (tmp_path / "x.mcap").write_bytes(b"x")
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    monkeypatch.setitem(sys.modules, "pyarrow.parquet", None)
    monkeypatch.setitem(sys.modules, "rosbags.highlevel", None)
    with pytest.raises(MissingDependencyError, match=r"pyarrow: pip install 'consistid\[io\]'"):
        load_recording(tmp_path / "x.parquet")
    with pytest.raises(MissingDependencyError, match=r"rosbags: pip install 'consistid\[io\]'"):
        load_recording(tmp_path / "x.mcap")
    assert issubclass(MissingDependencyError, ImportError)



def test_load_recording_passes_progress_to_the_bag_reader(tmp_path, log):
    pytest.importorskip("rosbags")
    path = write_bag(tmp_path / "bag", log)
    lines = []
    load_recording(path, progress=lines.append)
    assert lines and all("bag" in line for line in lines)


def test_units_in_column_headers_are_read_or_refused(tmp_path):
    """``q_<joint> [deg]`` is converted (and said so), ``[rad]``/``[Nm]`` read as they are, and a
    unit consistid does not know is refused by column — never silently taken as SI."""
    rng = np.random.default_rng(0)
    t = np.arange(400) / 200.0
    q = 0.5 * np.sin(np.outer(t, [1.0, 1.7])) + rng.normal(0, 1e-4, (400, 2))
    tau = np.cos(np.outer(t, [1.3, 0.7]))

    def write(name, q_unit, values):
        path = tmp_path / name
        header = ["t", f"q_a [{q_unit}]", f"q_b [{q_unit}]", "tau_a [Nm]", "tau_b [N·m]"]
        np.savetxt(path, np.column_stack([t, values, tau]), delimiter=",",
                   header=",".join(header), comments="", encoding="utf-8")
        return path

    rad = load_recording(write("rad.csv", "rad", q))
    deg = load_recording(write("deg.csv", "deg", np.degrees(q)))
    np.testing.assert_allclose(deg.dataset.q, rad.dataset.q, atol=1e-12)
    assert "converted to radians" in deg.summary()
    with pytest.raises(DatasetError, match=r"column 'q_a \[grad\]'.*unit \[grad\]"):
        load_recording(write("grad.csv", "grad", q))

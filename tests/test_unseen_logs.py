"""Loggers with habits nobody tuned to: unit suffixes after an underscore, clocks stepped back,
stamps in milliseconds at 10 kHz, another robot's joint names (found by probing the loaders as a
new user; each test failed before its fix)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import consistid as ci
from consistid.data.formats.columns import column_unit, parse_candidates
from consistid.data.recordings import from_arrays
from consistid.errors import DataQualityWarning, DatasetError, JointNameError

RATE = 500.0
NAMES = ["a1", "a2", "a3"]


def _log(duration: float = 6.0, rate: float = RATE):
    """Three joints in smooth motion (peak speeds 0.9–1.6 rad/s) and torques that depend on
    them: an independent truth for every loader test."""
    t = np.arange(0.0, duration, 1.0 / rate)
    q = np.column_stack([0.5 * np.sin(2 * np.pi * f * t + p)
                         for f, p in ((0.3, 0.0), (0.4, 1.0), (0.5, 2.0))])
    tau = np.column_stack([3.0 * np.cos(q[:, 0]), 2.0 * q[:, 1] + 1.0, np.sin(q[:, 2])])
    return t, q, tau


def _write(path, header, table):
    with open(path, "w") as fh:
        fh.write(",".join(header) + "\n")
        for row in table:
            fh.write(",".join(f"{v:.12g}" for v in row) + "\n")
    return path


def _at(t_out, t, x):
    return np.column_stack([np.interp(t_out, t, c) for c in x.T])


# ------------------------------------------------------------------ units after an underscore
@pytest.mark.parametrize("name, field, joint, unit", [
    ("q1_rad", "q", 0, "rad"), ("q2_deg", "q", 1, "deg"), ("tau3_Nm", "tau", 2, "nm"),
    ("q_a1_rad", "q", "a1", "rad"), ("dq1_rad_s", "dq", 0, "rad/s"),
    ("effort_a2_nm", "tau", "a2", "nm")])
def test_underscore_unit_suffix_is_a_unit_not_part_of_the_name(name, field, joint, unit):
    assert parse_candidates(name)[0] == (field, joint)
    assert column_unit(name) == unit


def test_a_joint_name_ending_like_a_unit_is_left_alone():
    # "rad" after an underscore, but what is left ("wrist") is no per-joint column
    assert column_unit("wrist_rad") is None
    assert parse_candidates("q_wrist") == [("q", "wrist")]


def test_csv_with_q1_rad_and_tau1_nm_headers_reads_like_the_plain_one(tmp_path):
    t, q, tau = _log()
    plain = _write(tmp_path / "plain.csv", ["t", "q1", "q2", "q3", "tau1", "tau2", "tau3"],
                   np.column_stack([t, q, tau]))
    styled = _write(tmp_path / "styled.csv",
                    ["time_s", "q1_rad", "q2_rad", "q3_rad", "tau1 (Nm)", "tau2 (Nm)",
                     "tau3 (Nm)"], np.column_stack([t, q, tau]))
    a = ci.load_recording(plain).dataset
    b = ci.load_recording(styled).dataset
    assert np.array_equal(a.q, b.q) and np.array_equal(a.tau, b.tau)


def test_csv_in_degrees_by_underscore_suffix_is_converted_and_said(tmp_path):
    t, q, tau = _log()
    path = _write(tmp_path / "deg.csv", ["time", "q1_deg", "q2_deg", "q3_deg", "tau1_Nm",
                                         "tau2_Nm", "tau3_Nm"],
                  np.column_stack([t, np.degrees(q), tau]))
    rec = ci.load_recording(path)
    d = rec.dataset
    assert np.max(np.abs(d.q - _at(d.t, t, q))) < 1e-3          # radians, like the truth
    assert any("q1_deg" in s and "converted to radians" in s for s in rec.steps)


# ------------------------------------------------------------------ clocks
def test_reversed_stamps_are_not_called_equal():
    t, q, tau = _log()
    # a logger that writes newest first: every stamp goes back by one step; sorted silently
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataQualityWarning)
        d = ci.Dataset.from_recording(t[::-1].copy(), q[::-1].copy(), tau[::-1].copy())
    assert np.max(np.abs(d.q - _at(d.t, t, q))) < 1e-3


def test_shuffled_rows_are_judged_after_sorting_not_refused_as_milliseconds():
    t, q, tau = _log()
    order = np.random.default_rng(0).permutation(t.size)
    with pytest.warns(DataQualityWarning, match="out of order"):
        d = ci.Dataset.from_recording(t[order], q[order], tau[order])
    assert np.max(np.abs(d.q - _at(d.t, t, q))) < 1e-3


def test_clock_stepped_back_warns_and_names_where():
    t, q, tau = _log()
    t = t.copy()
    t[1500:] -= 0.02                        # an NTP correction: 10 steps back at index 1500
    with pytest.warns(DataQualityWarning, match=r"t\[1500\].*cut the log at index 1500"):
        ci.Dataset.from_recording(t, q, tau)


def test_two_rows_out_of_order_do_not_warn():
    t, q, tau = _log()
    swap = [2000, 2001]
    t, q, tau = (a.copy() for a in (t, q, tau))
    for a in (t, q, tau):
        a[swap] = a[swap[::-1]]
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataQualityWarning)
        ci.Dataset.from_recording(t, q, tau)


def test_backwards_time_message_shows_plain_numbers(tmp_path):
    t, q, tau = _log()
    t = t.copy()
    t[100] = t[90]
    path = _write(tmp_path / "back.csv", ["t", "q1", "q2", "q3", "tau1", "tau2", "tau3"],
                  np.column_stack([t, q, tau]))
    with pytest.raises(DatasetError, match=r"t\[100\] = 0\.18 is before t\[99\] = 0\.198") as e:
        ci.load_recording(path)
    assert "np.float64" not in str(e.value)


def test_10_khz_log_stamped_in_ms_warns_with_the_unit():
    # 0.1 ms steps in ms read as seconds: a plausible "10 Hz" log moving 1000 × too slowly
    t, q, tau = _log(duration=2.0, rate=10_000.0)
    with pytest.warns(DataQualityWarning, match=r"quasi-static.*time_unit='ms' \(1e\+04 Hz"):
        ci.Dataset.from_recording(t * 1e3, q, tau)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataQualityWarning)
        d = ci.Dataset.from_recording(t * 1e3, q, tau, time_unit="ms")
    assert np.max(np.abs(d.q - _at(d.t, t, q))) < 1e-3


def test_a_normal_log_is_not_called_quasi_static():
    t, q, tau = _log()
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataQualityWarning)
        ci.Dataset.from_recording(t, q, tau)


# ------------------------------------------------------------------ another robot's log
def test_log_of_another_robot_names_both_joint_lists(tmp_path):
    t, q, tau = _log()
    path = _write(tmp_path / "other.csv",
                  ["time", "panda_joint1", "panda_joint2", "panda_joint3",
                   "panda_joint1_effort", "panda_joint2_effort", "panda_joint3_effort"],
                  np.column_stack([t, q, tau]))
    with pytest.raises(JointNameError, match=r"panda_joint1.*does not have; its joints are "
                                             r"\['a1', 'a2', 'a3'\]"):
        ci.load_recording(path, joints=NAMES)


# ------------------------------------------------------------------ .mat without joint names
def test_mat_without_joint_names_reads_in_the_models_order(tmp_path, planar_2r):
    scipy_io = pytest.importorskip("scipy.io")
    t, q, tau = _log()
    q, tau = q[:, :2], tau[:, :2]
    scipy_io.savemat(tmp_path / "run.mat", {"t": t, "q": q, "tau": tau})
    scipy_io.savemat(tmp_path / "rows.mat", {"t": t[None], "q": q.T, "tau": tau.T})
    for name in ("run.mat", "rows.mat"):         # joints along columns, or along rows
        rec = ci.load_recording(tmp_path / name, model=planar_2r)   # was: "no joint_names"
        d = rec.dataset
        assert d.joint_names == tuple(planar_2r.joint_names)
        assert np.max(np.abs(d.q - _at(d.t, t, q))) < 1e-3
        assert any("no joint_names variable" in s for s in rec.steps)
    scipy_io.savemat(tmp_path / "three.mat", {"t": t, "q": _log()[1], "tau": _log()[2]})
    with pytest.raises(ci.errors.MissingColumnsError, match=r"names 2 joints.*3 columns"):
        ci.load_recording(tmp_path / "three.mat", model=planar_2r)


# ------------------------------------------------------------------ what a loader returns
def test_a_recording_stands_for_its_dataset_and_a_dataframe_is_explained(planar_2r):
    pd = pytest.importorskip("pandas")
    t = np.arange(0.0, 6.0, 1.0 / RATE)
    q = np.column_stack([0.8 * np.sin(2 * np.pi * 0.3 * t), 0.6 * np.sin(2 * np.pi * 0.5 * t)])
    dq = np.gradient(q, t, axis=0)
    tau = planar_2r.rnea(q, dq, np.gradient(dq, t, axis=0))
    rec = from_arrays(t, q, tau, model=planar_2r)
    a = ci.identify(planar_2r, rec.dataset, method="ols", friction=None)
    b = ci.identify(planar_2r, rec, method="ols", friction=None)     # was: "got Recording"
    assert np.array_equal(a.rms(rec.dataset), b.rms(rec.dataset))
    frame = pd.DataFrame({"t": t, "q1": q[:, 0], "q2": q[:, 1], "tau1": tau[:, 0],
                          "tau2": tau[:, 1]})
    with pytest.raises(DatasetError, match=r"pandas DataFrame.*from_frame"):
        ci.diagnose(planar_2r, frame)                         # was: "dataset[0] is a str"


def test_a_column_of_nan_is_called_unrecorded_not_a_bad_row(tmp_path):
    t, q, tau = _log()
    tau = tau.copy()
    tau[:, 1] = np.nan
    path = _write(tmp_path / "nan.csv", ["t", "q1", "q2", "q3", "tau1", "tau2", "tau3"],
                  np.column_stack([t, q, tau]))
    with pytest.raises(DatasetError, match=r"column 'tau2': every one of its 3000 values is "
                                           r"empty or NaN") as err:
        ci.load_recording(path)
    assert "drop those rows" not in str(err.value)
    tau[:, 1] = 1.0
    tau[7, 1] = np.nan                                     # one bad row: named by its line
    path = _write(tmp_path / "one.csv", ["t", "q1", "q2", "q3", "tau1", "tau2", "tau3"],
                  np.column_stack([t, q, tau]))
    with pytest.raises(DatasetError, match=r"line 9, column 'tau2'"):
        ci.load_recording(path)


def test_collapsed_stamps_message_shows_plain_numbers():
    t, q, tau = _log()
    t = t[np.arange(t.size) // 2 * 2]                      # a clock at half the sampling rate
    with pytest.raises(DatasetError, match=r"collapsed time stamps.*t\[1\] = 0\.0;") as err:
        ci.Dataset.from_recording(t, q, tau)
    assert "np.float64" not in str(err.value)


def test_joints_split_over_two_message_kinds_in_a_bag_are_explained(tmp_path):
    pytest.importorskip("rosbags")
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    state = store.types["sensor_msgs/msg/JointState"]
    header, stamp = store.types["std_msgs/msg/Header"], store.types["builtin_interfaces/msg/Time"]
    t, q, tau = _log(duration=1.0)
    with Writer(tmp_path / "split", version=9, storage_plugin=StoragePlugin.MCAP) as bag:
        conn = bag.add_connection("/joint_states", state.__msgtype__, typestore=store)
        for k in range(t.size):
            ns = int(round(t[k] * 1e9))
            part = [0, 1] if k % 2 == 0 else [2]          # two drivers, one topic
            msg = state(header=header(stamp=stamp(sec=ns // 10**9, nanosec=ns % 10**9),
                                      frame_id=""),
                        name=[NAMES[j] for j in part], position=q[k, part],
                        velocity=np.zeros(0), effort=tau[k, part])
            bag.write(conn, ns, store.serialize_cdr(msg, state.__msgtype__))
    with pytest.raises(DatasetError, match=r"missing everywhere: \[\].*in separate messages"):
        ci.load_recording(tmp_path / "split", joints=NAMES)


# ------------------------------------------------------------------ wrapped angles
def test_angles_wrapped_into_2pi_are_unwrapped_with_a_warning(planar_2r):
    t = np.arange(0.0, 8.0, 1.0 / RATE)
    q = np.column_stack([2.6 + 1.2 * np.sin(2 * np.pi * 0.25 * t),        # crosses π
                         0.7 * np.sin(2 * np.pi * 0.4 * t + 1.0)])
    dq = np.gradient(q, t, axis=0)
    tau = planar_2r.rnea(q, dq, np.gradient(dq, t, axis=0))
    wrapped = (q + np.pi) % (2 * np.pi) - np.pi                         # a ROS driver's habit
    assert np.abs(np.diff(wrapped[:, 0])).max() > 6
    plain = ci.Dataset.from_recording(t, q, tau)
    with pytest.warns(DataQualityWarning, match=r"jump by ±2π.*q\[:, 0\]"):
        fixed = ci.Dataset.from_recording(t, wrapped, tau)
    # the same dynamics: sin and cos of the angles agree, velocities and accelerations too
    assert np.allclose(np.sin(fixed.q), np.sin(plain.q), atol=1e-9)
    assert np.allclose(fixed.dq, plain.dq, atol=1e-9)
    assert np.allclose(fixed.ddq, plain.ddq, atol=1e-7)
    res = ci.identify(planar_2r, fixed, method="ols", friction=None)
    assert np.max(res.rms(fixed)) < 1e-3 * np.max(np.abs(tau))


def test_a_fast_but_real_motion_is_not_unwrapped():
    t, q, tau = _log()
    q = q.copy()
    q[1000, 0] += 4.0                                   # a glitch, not a 2π wrap
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataQualityWarning)
        d = ci.Dataset.from_recording(t, q, tau)        # Hampel deals with the spike
    assert np.max(np.abs(d.q - _at(d.t, t, _log()[1]))) < 1e-2


# ------------------------------------------------------------------ torques against the model
def _ur5_log():
    """A UR5 excitation through MuJoCo with Coulomb and viscous friction and sensor noise."""
    from consistid.simulate import Effects, record

    model = ci.RobotModel.example("ur5")
    traj = ci.FourierTrajectory.random(model, harmonics=5, period=10.0, seed=1)
    sim = record(model, traj, Effects(coulomb=1.0, viscous=0.5, torque_noise=0.05),
                 duration=8.0, rate=500.0, seed=1)
    return model, sim


@pytest.fixture(scope="module")
def ur5_log():
    return _ur5_log()


@pytest.mark.parametrize("factor, message", [
    (1000.0, r"'shoulder_lift_joint' \(1\.0\de\+03 × the model's\).*mN·m"),
    (-1.0, r"'shoulder_lift_joint' \(correlation -1\.00\).*opposite sign"),
    (np.array([1, 1, -1, 1, 1, 1.0]), r"torque of 'elbow_joint' \(correlation -0\.\d\d\) is"),
    ([1, 0, 2, 3, 4, 5], r"column of 'shoulder_pan_joint' follows 'shoulder_lift_joint''s.*"
                         r"another joint order"),
    ([0, 2, 1, 3, 4, 5], r"column of 'shoulder_lift_joint' follows 'elbow_joint''s")])
def test_torques_in_other_units_sign_or_order_warn_against_the_urdf(ur5_log, factor, message):
    model, sim = ur5_log
    tau = sim.tau[:, factor] if isinstance(factor, list) else sim.tau * factor
    with pytest.warns(DataQualityWarning, match=message):
        rec = from_arrays(sim.t, sim.q, tau, model=model)
    assert any("RNEA torque" in s for s in rec.steps)


def test_a_right_log_of_a_robot_near_its_urdf_does_not_warn(ur5_log):
    model, sim = ur5_log
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataQualityWarning)
        from_arrays(sim.t, sim.q, sim.tau, model=model)


def test_real_kuka_logs_against_the_cad_urdf_do_not_warn(kuka_dir):
    # its wrists' torques correlate at -0.7 with the CAD model's (friction and offsets dominate
    # them): not a flipped sign, and not judged
    model = ci.RobotModel.from_urdf(kuka_dir / "kuka_lwr4.urdf")
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataQualityWarning)
        ci.load_recording(kuka_dir / "measurements_1.npz", model=model)


# ------------------------------------------------------------------ time written as text
@pytest.mark.parametrize("style", ["iso", "iso+tz", "T and Z", "clock"])
def test_time_column_written_as_date_times_or_clock_times(tmp_path, style):
    t, q, tau = _log()
    base = np.datetime64("2025-11-24T16:00:00", "ns") + (t * 1e9).astype("timedelta64[ns]")
    text = np.datetime_as_string(base, unit="us")             # 2025-11-24T16:00:00.002000
    cells = {"iso": [c.replace("T", " ") for c in text],
             "iso+tz": [c.replace("T", " ") + "+01:00" for c in text],
             "T and Z": [c + "Z" for c in text],
             "clock": [c.split("T")[1] for c in text]}[style]
    path = tmp_path / "run.csv"
    with open(path, "w") as fh:
        fh.write("time,q1,q2,q3,tau1,tau2,tau3\n")
        for k, cell in enumerate(cells):
            fh.write(cell + "," + ",".join(f"{v:.12g}" for v in (*q[k], *tau[k])) + "\n")
    rec = ci.load_recording(path)                     # was: "'2025-11-24 …' is not a number"
    d = rec.dataset
    assert np.max(np.abs(d.q - _at(d.t, t - t[0], q))) < 1e-3
    assert abs(d.t[-1] - d.t[0] - (t[-1] - t[0])) < 1.0     # the trimmed span, in seconds
    assert any("read as" in s for s in rec.steps)


def test_a_bad_date_time_names_its_row(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("time,q1,tau1\n2025-11-24 16:00:00.000,0.1,1.0\n2025-11-24 16:00:00.002,"
                    "0.2,1.1\nyesterday,0.3,1.2\n")
    with pytest.raises(DatasetError, match=r"data row 3 .*'yesterday' is not an ISO date-time"):
        ci.load_recording(path)


# ------------------------------------------------------------------ float32 stamps
def test_float32_stamps_that_cannot_resolve_their_steps_are_refused(tmp_path):
    pd = pytest.importorskip("pandas")
    pytest.importorskip("pyarrow")
    t, q, tau = _log()
    frame = pd.DataFrame({"q1": q[:, 0], "q2": q[:, 1], "tau1": tau[:, 0], "tau2": tau[:, 1]})
    for offset, what in ((1.764e9, "every stamp collapses"), (5 * 3600.0, "of the median step")):
        frame.insert(0, "time", (t + offset).astype(np.float32))
        frame.to_parquet(tmp_path / "run.parquet")
        frame = frame.drop(columns="time")
        with pytest.raises(DatasetError, match=rf"column 'time': the time stamps are float32.*"
                                               rf"{what}.*float64"):
            ci.load_recording(tmp_path / "run.parquet")      # was: "all equal" / 512 Hz
        with pytest.raises(DatasetError, match=r"float32"):
            ci.Dataset.from_recording((t + offset).astype(np.float32), q, tau)


def test_float32_stamps_of_a_short_log_are_fine():
    t, q, tau = _log()
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataQualityWarning)
        d = ci.Dataset.from_recording(t.astype(np.float32), q, tau)
    assert np.max(np.abs(d.q - _at(d.t, t, q))) < 1e-3


# ------------------------------------------------------------------ logged derivatives
def _logged():
    t, q, tau = _log()
    w = 2 * np.pi * np.array([0.3, 0.4, 0.5])
    phase = np.array([0.0, 1.0, 2.0])
    dq = 0.5 * w * np.cos(w * t[:, None] + phase)
    ddq = -0.5 * w ** 2 * np.sin(w * t[:, None] + phase)
    return t, q, dq, ddq, tau


@pytest.mark.parametrize("case, message", [
    ("ddq zero", r"ddq\[:, 'a1'\] is 0 in every sample while d\(dq\)/dt"),
    ("dq in deg/s", r"dq\[:, 'a2'\] is 57\.3 × d\(q\)/dt \(deg/s against rad\?\)"),
    ("ddq of another joint", r"ddq\[:, 'a3'\] does not follow d\(dq\)/dt")])
def test_logged_derivatives_that_do_not_derive_warn(case, message):
    t, q, dq, ddq, tau = _logged()
    dq, ddq = dq.copy(), ddq.copy()
    if case == "ddq zero":
        ddq[:] = 0.0                                  # a driver that fills the field
    elif case == "dq in deg/s":
        dq[:, 1] = np.degrees(dq[:, 1])
    else:
        ddq[:, 2] = ddq[::-1, 0]
    with pytest.warns(DataQualityWarning, match=message):
        rec = from_arrays(t, q, tau, dq, ddq, joint_names=NAMES)
    assert any("logged derivatives" in s for s in rec.steps)


def test_right_logged_derivatives_and_the_real_kuka_logs_do_not_warn(kuka_dir):
    t, q, dq, ddq, tau = _logged()
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataQualityWarning)
        from_arrays(t, q, tau, dq, ddq, joint_names=NAMES)
        ci.load_recording(kuka_dir / "measurements_2.npz")     # FloBaRoID's logged dq, ddq


# ------------------------------------------------------------------ a logger stopped mid-write
@pytest.mark.parametrize("cut, why", [(-37, r"\d+ of 7 fields"), (-5, r"its last field '.*' has")])
def test_a_last_line_cut_short_is_dropped_with_a_warning(tmp_path, cut, why):
    t, q, tau = _log()
    full = _write(tmp_path / "full.csv", ["t", "q1", "q2", "q3", "tau1", "tau2", "tau3"],
                  np.column_stack([t, q, tau])).read_text()
    last = full.rstrip("\n").rsplit("\n", 1)[1]
    cut_at = len(full.rstrip("\n")) + cut if cut < -10 else len(full.rstrip("\n")) - \
        len(last.rsplit(",", 1)[1]) + 2                      # inside the last field
    (tmp_path / "cut.csv").write_text(full[:cut_at])
    with pytest.warns(DataQualityWarning, match=rf"line 3001: {why}.*cut short"):
        rec = ci.load_recording(tmp_path / "cut.csv")       # was: "line 3001: 5 fields …"
    assert any("cut short" in s for s in rec.steps)
    d = rec.dataset
    assert np.max(np.abs(d.q - _at(d.t, t, q))) < 1e-3


def test_a_whole_last_line_without_a_line_break_is_kept(tmp_path):
    t, q, tau = _log()
    full = _write(tmp_path / "full.csv", ["t", "q1", "q2", "q3", "tau1", "tau2", "tau3"],
                  np.column_stack([t, q, tau])).read_text()
    (tmp_path / "nolf.csv").write_text(full.rstrip("\n"))
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataQualityWarning)
        a = ci.load_recording(tmp_path / "nolf.csv")
    assert a.dataset.n_samples == ci.load_recording(tmp_path / "full.csv").dataset.n_samples


# ------------------------------------------------------------------ joints named by numbers
def test_joints_named_by_numbers_in_another_order_make_q1_ambiguous(tmp_path):
    t, q, tau = _log()
    path = _write(tmp_path / "num.csv", ["t", "q_1", "q_2", "q_3", "tau_1", "tau_2", "tau_3"],
                  np.column_stack([t, q, tau]))
    with pytest.raises(ci.errors.MissingColumnsError, match=r"'q_1' is ambiguous: by number it "
                                                            r"is the q of joint 1 \('3'\)"):
        ci.load_recording(path, joints=["3", "1", "2"])   # was: read by name, joints swapped
    same = ci.load_recording(path, joints=["1", "2", "3"]).dataset     # names = numbers: fine
    d = ci.load_recording(path, joints=["3", "1", "2"],
                          columns={"q": ["q_1", "q_2", "q_3"], "tau": ["tau_1", "tau_2",
                                                                        "tau_3"]}).dataset
    assert np.array_equal(d.q, same.q)


def test_a_10_khz_log_in_ms_is_not_blamed_on_torque_units(ur5_log):
    model, sim = ur5_log
    t = np.arange(sim.t[0], sim.t[0] + 3.0, 1e-4)
    q, tau = _at(t, sim.t, sim.q), _at(t, sim.t, sim.tau)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        from_arrays(t * 1e3, q, tau, model=model)            # a "10 Hz" log, 1000 × too slow
    said = [str(w.message) for w in caught if w.category is DataQualityWarning]
    assert any("quasi-static" in m and "time_unit='ms'" in m for m in said)
    assert not any("RNEA" in m for m in said)   # was: "shoulder_pan_joint (1.18e+06 × …) mN·m"


def test_independent_states_are_not_judged_as_a_trajectory(planar_2r):
    from .conftest import random_states

    q, dq, ddq = random_states(planar_2r, 300, 0)
    tau = planar_2r.rnea(q, dq, ddq)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataQualityWarning)
        rec = from_arrays(0.005 * np.arange(300), q, tau, dq, ddq, model=planar_2r)
    assert any("independent states" in s for s in rec.steps)


def test_torques_in_mnm_read_by_their_unit_and_warned_without_it(tmp_path):
    """A CSV whose torque columns say [mNm] is converted (noted); the same numbers without a
    unit, given to identify as a Dataset, exceed the URDF's effort limits ×1000 and warn by
    joint (the SDP called 1000-fold links 'consistent' silently)."""
    import warnings as _w

    from consistid.data.recordings import load_recording

    model = ci.RobotModel.example("ur5")
    run = ci.simulate.excitation_run(model, duration=6.0, rate=200.0, torque_noise=0.05, seed=3)
    d = run.dataset
    names = model.joint_names
    header = ["t"] + [f"q_{n}" for n in names] + [f"tau_{n} [mNm]" for n in names]
    rows = np.column_stack([d.t, d.q, 1e3 * d.tau])
    path = tmp_path / "milli.csv"
    np.savetxt(path, rows, delimiter=",", header=",".join(header), comments="", fmt="%.10g")
    rec = load_recording(path, model=model)
    assert any("mnm" in n.lower() and "converted to N·m" in n for n in rec.steps), rec.steps
    got = rec.dataset
    ref = np.column_stack([np.interp(got.t + d.t[0], d.t, d.tau[:, j]) for j in range(d.nv)])
    scale = float(np.sum(got.tau * ref) / np.sum(ref * ref))     # N·m again (filtered, trimmed)
    assert scale == pytest.approx(1.0, abs=0.02)
    with pytest.warns(ci.errors.DataQualityWarning, match="effort limits.*'shoulder_pan_joint'"):
        with _w.catch_warnings():
            _w.simplefilter("ignore", ci.errors.PoorExcitationWarning)
            ci.identify(model, d.with_torque(1e3 * d.tau), method="ols", covariance="iid")

import numpy as np
import pytest

from consistid.data.recordings import Recording, from_arrays, load_recording
from consistid.errors import DatasetError, JointNameError, MissingColumnsError, OptionError

T0 = 1460034856.877162  # a Unix stamp (2016-04-07)


def log(n=40, nv=2, seed=0, dt=0.005):
    rng = np.random.default_rng(seed)
    t = T0 + np.cumsum(rng.uniform(0.6, 1.4, n) * dt)
    return dict(t=t, q=rng.normal(size=(n, nv)), dq=rng.normal(size=(n, nv)),
                ddq=rng.normal(size=(n, nv)), tau=rng.normal(size=(n, nv)))


def test_unix_origin_is_subtracted_and_recorded():
    a = log()
    rec = from_arrays(**a)
    assert rec.time_origin == a["t"][0]
    assert rec.dataset.t[0] == 0.0
    np.testing.assert_allclose(rec.dataset.t, a["t"] - a["t"][0], rtol=0, atol=1e-12)
    assert "Unix time stamps" in rec.steps[0] and "2016-04-07" in rec.steps[0]
    assert any("non-uniform" in s for s in rec.steps)


def test_duplicated_stamps_average_first_error():
    a = log(n=10)
    a["t"][4] = a["t"][3]                       # two stamps repeated, with different values
    a["t"][8] = a["t"][7]
    rec = from_arrays(**a, duplicates="average")
    assert rec.dataset.n_samples == 8
    np.testing.assert_allclose(rec.dataset.q[3], 0.5 * (a["q"][3] + a["q"][4]))
    np.testing.assert_allclose(rec.dataset.tau[6], 0.5 * (a["tau"][7] + a["tau"][8]))
    assert any("2 duplicated time stamp(s)" in s and "10 → 8" in s for s in rec.steps)
    first = from_arrays(**a, duplicates="first")
    np.testing.assert_array_equal(first.dataset.q[3], a["q"][3])
    with pytest.raises(DatasetError, match=r"t\[4\].*repeats t\[3\]"):
        from_arrays(**a, duplicates="error")
    with pytest.raises(OptionError, match="duplicates"):
        from_arrays(**a, duplicates="drop")


def test_backwards_time_is_refused_with_its_index():
    a = log()
    a["t"][11] = a["t"][9]
    with pytest.raises(DatasetError, match=r"t\[11\].*before t\[10\]"):
        from_arrays(**a)


def test_joint_columns_are_reordered_to_the_model(planar_2r):
    a = log()
    swapped = {k: (v[:, ::-1] if v.ndim == 2 else v) for k, v in a.items()}
    rec = from_arrays(**swapped, joint_names=["joint2", "joint1"], model=planar_2r)
    for f in ("q", "dq", "ddq", "tau"):
        np.testing.assert_array_equal(getattr(rec.dataset, f), a[f])
    assert rec.dataset.joint_names == ("joint1", "joint2")
    assert any("reordered" in s for s in rec.steps)


def test_joint_name_mismatch_names_both_sides(planar_2r):
    a = log()
    with pytest.raises(JointNameError, match=r"missing from the log \['joint2'\].*not in the "
                                             r"model \['elbow'\]"):
        from_arrays(**a, joint_names=["joint1", "elbow"], model=planar_2r)
    with pytest.raises(JointNameError, match="3 joint columns and no joint names"):
        from_arrays(**log(nv=3), model=planar_2r)
    with pytest.raises(JointNameError, match="appear more than once"):
        from_arrays(**a, joint_names=["joint1", "joint1"], model=planar_2r)


def test_trim_rule_drops_the_stated_durations():
    a = log(n=200)
    rec = from_arrays(**a, trim_start=0.1, trim_end=0.05)
    t = a["t"] - a["t"][0]
    keep = (t >= 0.1) & (t <= t[-1] - 0.05)
    np.testing.assert_array_equal(rec.dataset.q, a["q"][keep])
    assert any(f"({np.argmax(keep)} samples)" in s for s in rec.steps)
    with pytest.raises(DatasetError, match="leaves no sample"):
        from_arrays(**a, trim_start=10.0)


def test_only_one_derivative_is_refused():
    a = log()
    a.pop("ddq")
    with pytest.raises(MissingColumnsError, match="dq is given without ddq"):
        from_arrays(**a)


def test_npz_layouts_ignored_arrays_and_missing_ones(tmp_path, planar_2r):
    a = log()
    path = tmp_path / "run.npz"
    np.savez(path, times=a["t"], positions=a["q"], velocities=a["dq"], accelerations=a["ddq"],
             torques=a["tau"], target_positions=a["q"] * 0.0174)
    rec = load_recording(path, model=planar_2r)
    np.testing.assert_array_equal(rec.dataset.tau, a["tau"])
    assert "ignored arrays ['target_positions']" in rec.steps[0]
    assert isinstance(rec, Recording) and rec.source == str(path)
    custom = load_recording(path, keys={"t": "times", "q": "positions", "dq": "velocities",
                                        "ddq": "accelerations", "tau": "target_positions"})
    np.testing.assert_array_equal(custom.dataset.tau, a["q"] * 0.0174)
    names = np.array(["joint2", "joint1"])                  # a numpy array of names
    swapped = load_recording(path, joint_names=names, model=planar_2r)
    np.testing.assert_array_equal(swapped.dataset.tau, a["tau"][:, ::-1])
    bad = tmp_path / "bad.npz"
    np.savez(bad, times=a["t"], positions=a["q"])
    with pytest.raises(MissingColumnsError, match="match no known layout"):
        load_recording(bad)
    with pytest.raises(MissingColumnsError, match=r"tau \('torques'\)"):
        load_recording(bad, keys="flobaroid")


def test_concatenate_keeps_segments_and_steps():
    r1, r2 = from_arrays(**log(seed=1)), from_arrays(**log(seed=2))
    both = Recording.concatenate([r1, r2])
    assert np.array_equal(np.unique(both.dataset.segment), [0, 1])
    assert both.steps[0].startswith("[segment 0: arrays]")
    assert both.dataset.n_samples == r1.dataset.n_samples + r2.dataset.n_samples


def test_raw_log_goes_through_the_signal_chain_and_is_trimmed_after_it():
    rate, f = 500.0, 0.4
    rng = np.random.default_rng(5)
    t = T0 + np.arange(5000) / rate + rng.uniform(-1e-4, 1e-4, 5000)
    t[100] = t[99]                                              # a duplicated stamp
    w = 2 * np.pi * f * (t - T0)
    q = np.column_stack([np.sin(w), 0.5 * np.cos(w)])
    tau = np.column_stack([np.cos(w), np.sin(w)])
    rec = from_arrays(t, q, tau, trim_start=1.0, cutoff=5.0)
    text = "\n".join(rec.steps)
    assert "1 duplicated time stamp(s)" in text and "the signal chain" in text
    assert rec.dataset.t[0] >= 1.0
    w_ds = 2 * np.pi * f * rec.dataset.t
    inner = slice(50, -50)
    np.testing.assert_allclose(rec.dataset.dq[inner, 0], 2 * np.pi * f * np.cos(w_ds[inner]),
                               atol=2e-3)


# ----------------------------------------------------------------------------- new in loaders
def test_interval_stamped_torques_with_logged_derivatives_are_shifted():
    a = log(n=400, dt=0.002)
    a["t"] = T0 + np.arange(400) * 0.002
    s = a["t"] - T0
    a["tau"] = np.column_stack([np.sin(5 * s), np.cos(5 * s)])
    h = 0.002
    averaged = np.column_stack([(np.cos(5 * (s - h)) - np.cos(5 * s)) / (5 * h),
                                (np.sin(5 * s) - np.sin(5 * (s - h))) / (5 * h)])
    rec = from_arrays(**{**a, "tau": averaged}, timestamp="end")
    kept = rec.dataset.t
    np.testing.assert_allclose(rec.dataset.tau, np.column_stack([np.sin(5 * kept),
                                                                 np.cos(5 * kept)]),
                               atol=1.1 * (5 * h) ** 2 / 24 + 1e-9)
    assert rec.dataset.n_samples == 399 and any("interval end" in x for x in rec.steps)
    with pytest.raises(DatasetError, match=r"signal-chain options \['cutoff'\]"):
        from_arrays(**a, cutoff=5.0)


def test_time_units_in_the_loader():
    a = log(n=200, dt=0.002)
    a["t"] = np.arange(200) * 2.0                           # milliseconds
    with pytest.raises(DatasetError, match=r"arrays: the median time step 2 is 0.5 Hz"):
        from_arrays(**a)
    rec = from_arrays(**a, time_unit="ms")
    assert rec.dataset.duration == pytest.approx(0.398)
    assert any("converted from ms" in s for s in rec.steps)


def test_the_cli_reads_csv_and_bags(tmp_path, planar_2r):
    """[data] with a CSV to train on and a ROS 2 bag held out; the .npz path keeps working
    (tests/test_config.py)."""
    pytest.importorskip("rosbags")
    from consistid.cli.config import config_recordings, load_config
    from consistid.errors import ConfigError

    from .conftest import PLANAR_2R, PLANAR_2R_VALUES
    from .test_formats import frame_of, write_bag, write_csv

    n = 1500
    ns = 1_700_000_000_000_000_000 + np.arange(n, dtype=np.int64) * 2_000_000
    s = (ns - ns[0]) * 1e-9
    q = np.column_stack([np.sin(s), np.cos(0.5 * s), 0 * s])
    lg = dict(ns=ns, t=ns[0] * 1e-9 + s, q=q, dq=q, tau=q + 1, names=("joint1", "joint2", "grip"))
    (tmp_path / "data").mkdir()
    write_csv(tmp_path / "data" / "train.csv", frame_of(lg))
    write_bag(tmp_path / "data" / "held", lg)
    (tmp_path / "arm.urdf").write_text(PLANAR_2R.format(**PLANAR_2R_VALUES))
    (tmp_path / "run.toml").write_text(
        '[model]\nurdf = "arm.urdf"\n'
        '[data]\ndir = "data"\ntrain = ["train.csv"]\nheld_out = ["held"]\ntimestamp = "centre"\n'
        '[data.signals]\ncutoff = 8.0\n')
    cfg = load_config(tmp_path / "run.toml")
    train, held = config_recordings(cfg, planar_2r)
    assert train.dataset.joint_names == ("joint1", "joint2") and held is not None
    assert any("8 Hz (given)" in x for x in train.steps)
    np.testing.assert_allclose(train.dataset.q, held.dataset.q, atol=1e-6)
    (tmp_path / "bad.toml").write_text(
        '[model]\nurdf = "arm.urdf"\n[data]\ntrain = ["data/train.csv"]\n'
        '[data.signals]\ncutof = 8.0\n')
    with pytest.raises(ConfigError, match=r"unknown key\(s\) \['cutof'\] in \[data.signals\]"):
        config_recordings(load_config(tmp_path / "bad.toml"), planar_2r)


def test_collapsed_stamps_are_refused_by_the_loader_unless_a_policy_is_given():
    a = log(n=200, dt=0.001)
    a["t"] = T0 + np.floor(np.arange(200) / 10) * 0.01          # a 10 ms clock, 1 kHz samples
    with pytest.raises(DatasetError, match="collapsed time stamps: 180 of 200"):
        from_arrays(**a)
    spread = from_arrays(**a, duplicates="spread")
    assert spread.dataset.n_samples == 200
    np.testing.assert_allclose(np.diff(spread.dataset.t), 0.001, atol=1e-6)
    assert from_arrays(**a, duplicates="average").dataset.n_samples == 20


def test_a_recording_renders_its_record():
    rec = from_arrays(**log())
    assert rec.summary() == str(rec) and rec.summary().count("\n  - ") == len(rec.steps)
    page = rec._repr_html_()
    assert page.count("<li>") == len(rec.steps) and "Unix time stamps" in page

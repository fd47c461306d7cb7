"""Loggers recognised without a column mapping (issue 31): UR RTDE recorder, franka_ros and
libfranka logs, ROS JointState CSV exports; templates with an explicit index base; the
tutorial's names reachable after ``import consistid``.

Each file is written here in its logger's own layout (header spellings, delimiter, time unit)
from a simulated run; it must load to the same dataset as the same numbers written in
consistid's plain layout (``time, q_<joint>, tau_<joint>``), which the format tests check
against independent closed forms."""

from __future__ import annotations

import re
import subprocess
import sys

import numpy as np
import pytest

import consistid as ci
from consistid.data.recordings import load_recording
from consistid.errors import JointNameError, MissingColumnsError

NS0 = 1_700_000_000_000_000_000


@pytest.fixture(scope="module")
def ur5():
    model = ci.RobotModel.example("ur5")
    return model, ci.simulate.excitation_run(model, duration=3.0, seed=5).dataset


@pytest.fixture(scope="module")
def panda_run(panda):
    return panda, ci.simulate.excitation_run(panda, duration=3.0, seed=6).dataset


def write(path, columns: dict, sep=",", fmt="%.17g"):
    """A table of named columns (numbers, or strings for joint names)."""
    names = list(columns)
    n = len(next(iter(columns.values())))
    with open(path, "w") as fh:
        fh.write(sep.join(names) + "\n")
        for k in range(n):
            fh.write(sep.join(v[k] if isinstance(v[k], str) else fmt % v[k]
                              for v in columns.values()) + "\n")
    return path


def plain(path, d, t):
    cols = {"time": t}
    cols.update({f"q_{n}": d.q[:, j] for j, n in enumerate(d.joint_names)})
    cols.update({f"tau_{n}": d.tau[:, j] for j, n in enumerate(d.joint_names)})
    return write(path, cols)


def as_read(ns):
    """The seconds the loader makes of integer ns stamps read as float64 (a CSV cell is parsed
    as a float: 256 ns resolution at Unix stamps in ns)."""
    f = ns.astype(float)
    return (f - f[0]) * 1e-9


def same(a, b):
    assert a.joint_names == b.joint_names
    for f in ("t", "q", "dq", "ddq", "tau"):
        np.testing.assert_allclose(getattr(a, f), getattr(b, f), rtol=0, atol=1e-9, err_msg=f)


def test_ur_rtde_recorder_log(tmp_path, ur5):
    """Space-separated, as RTDE's record_data.py writes it: timestamp in s since the controller
    started, actual_q_0..5, actual_qd_0..5, actual_current_0..5 (A), target_moment_0..5."""
    model, d = ur5
    t = 8123.456 + d.t
    cols = {"timestamp": t}
    for name, a in (("target_q", d.q + 0.01), ("actual_q", d.q), ("actual_qd", d.dq),
                    ("actual_current", d.tau / 10.0), ("target_moment", d.tau)):
        cols.update({f"{name}_{j}": a[:, j] for j in range(6)})
    cols["robot_mode"] = np.full(t.size, 7.0)
    rec = load_recording(write(tmp_path / "robot_data.csv", cols, sep=" "), model=model)
    ref = load_recording(plain(tmp_path / "plain.csv", d, t), model=model)
    same(rec.dataset, ref.dataset)
    text = "\n".join(rec.steps)
    assert "Universal Robots RTDE" in text and "numbered from 0" in text
    assert "commanded joint torque" in text and "'actual_current_0'" in text     # ignored
    # a logged actual_current_as_torque is preferred over the commanded torque
    cols.update({f"actual_current_as_torque_{j}": d.tau[:, j] + 1.0 for j in range(6)})
    both = load_recording(write(tmp_path / "new.csv", cols, sep=" "), model=model)
    np.testing.assert_allclose(both.dataset.tau, ref.dataset.tau + 1.0, atol=1e-9)


def test_templates_take_an_index_base(tmp_path, ur5):
    """``{i0}`` counts from 0, ``{i}``/``{i1}`` from 1; ``{i}`` on a 0-based log says so."""
    model, d = ur5
    cols = {"timestamp": d.t, **{f"actual_q_{j}": d.q[:, j] for j in range(6)},
            **{f"target_moment_{j}": d.tau[:, j] for j in range(6)}}
    path = write(tmp_path / "ur.csv", cols)
    rec = load_recording(path, model=model,
                         columns={"t": "timestamp", "q": "actual_q_{i0}",
                                  "tau": "target_moment_{i0}"})
    same(rec.dataset, load_recording(plain(tmp_path / "p.csv", d, d.t), model=model).dataset)
    with pytest.raises(MissingColumnsError, match=r"write 'actual_q_\{i0\}'"):
        load_recording(path, model=model, columns={"t": "timestamp", "q": "actual_q_{i}",
                                                   "tau": "target_moment_{i0}"})


def test_franka_ros_state_from_rostopic(tmp_path, panda_run):
    """``rostopic echo -p /franka_state_controller/franka_states``: %time and header stamps in
    ns, field.q0..6, field.dq0..6, field.tau_J0..6 beside set-points (q_d, tau_J_d) that must
    not be read."""
    model, d = panda_run
    ns = NS0 + np.round(d.t * 1e9).astype(np.int64)
    cols = {"%time": ns + 40_000, "field.header.seq": np.arange(ns.size),
            "field.header.stamp": ns, "field.header.frame_id": ["base"] * ns.size}
    for name, a in (("q", d.q), ("q_d", d.q * 0), ("dq", d.dq), ("tau_J", d.tau),
                    ("tau_J_d", d.tau * 0), ("dtau_J", d.tau * 0)):
        cols.update({f"field.{name}{j}": a[:, j] for j in range(7)})
    cols["field.time"] = d.t
    rec = load_recording(write(tmp_path / "franka_states.csv", cols, fmt="%.17g"),
                         model=model)
    ref = load_recording(plain(tmp_path / "plain.csv", d, as_read(ns)), model=model)
    same(rec.dataset, ref.dataset)
    assert "franka_ros" in rec.steps[0] and "(ns)" in rec.steps[0]


def test_libfranka_robot_state_log(tmp_path, panda_run):
    model, d = panda_run
    cols = {"time": d.t}
    for name, a in (("q", d.q), ("dq", d.dq), ("tau_J", d.tau), ("tau_J_d", d.tau * 0)):
        cols.update({f"{name}[{j}]": a[:, j] for j in range(7)})
    rec = load_recording(write(tmp_path / "libfranka.csv", cols), model=model)
    same(rec.dataset, load_recording(plain(tmp_path / "p.csv", d, d.t), model=model).dataset)
    assert "libfranka" in rec.steps[0]


def test_ros_joint_states_csv(tmp_path, panda_run):
    """``rostopic echo -p /joint_states``: joint names in the rows (field.name0..8, here in
    another order than the model's, with the two finger joints), positions, velocities and
    efforts numbered from 0."""
    model, d = panda_run
    names = [*model.joint_names, "panda_finger_joint1", "panda_finger_joint2"]
    order = np.random.default_rng(0).permutation(9)
    n = d.t.size
    full = {"q": np.column_stack([d.q, np.full((n, 2), 0.02)]),
            "dq": np.column_stack([d.dq, np.zeros((n, 2))]),
            "tau": np.column_stack([d.tau, np.ones((n, 2))])}
    ns = NS0 + np.round(d.t * 1e9).astype(np.int64)
    cols = {"%time": ns, "field.header.seq": np.arange(n), "field.header.stamp": ns,
            "field.header.frame_id": [""] * n}
    cols.update({f"field.name{k}": [names[i]] * n for k, i in enumerate(order)})
    for field, key in (("position", "q"), ("velocity", "dq"), ("effort", "tau")):
        cols.update({f"field.{field}{k}": full[key][:, i] for k, i in enumerate(order)})
    path = write(tmp_path / "joint_states.csv", cols)
    rec = load_recording(path, model=model)
    ref = load_recording(plain(tmp_path / "p.csv", d, as_read(ns)), model=model)
    same(rec.dataset, ref.dataset)
    assert "panda_finger_joint1" in rec.steps[0]                        # dropped, listed
    with pytest.raises(JointNameError, match="no joint"):
        load_recording(path, joints=["panda_joint1", "elbow"])


def test_tutorial_names_reachable_after_import_consistid():
    """A fresh interpreter: submodules of the subpackages load on first use."""
    code = ("import consistid as ci; ci.data.recordings.from_arrays; "
            "ci.identification.summary.table; ci.online.rls.RecursiveEstimator; "
            "ci.RecursiveEstimator\n"
            "try:\n    ci.data.no_such_module\nexcept AttributeError as e:\n    print(e)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert "has no attribute 'no_such_module'" in out


def test_every_name_the_docs_use_resolves_in_a_fresh_interpreter():
    """In one fresh interpreter, every top-level name first (``ci.Dataset`` imports
    ``consistid.data`` on the way, not all its modules), then every ``ci.a.b`` the README and
    the docs pages write, and every module of every subpackage as an attribute
    (``ci.data.recordings.from_arrays``, as the logs tutorial writes it): a subpackage imported
    on the way still loads its modules on use."""
    import pkgutil
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    pages = [root / "README.md", *sorted((root / "docs").rglob("*.md"))]
    names = list(dict.fromkeys(re.findall(r"\bci\.((?:[A-Za-z_]\w*\.)*[A-Za-z_]\w*)",
                                          "\n".join(p.read_text() for p in pages))))
    assert "data.recordings.from_arrays" in names
    names = [n for n in ci.__all__ if n != "cli"] + names
    names += [f"{sub}.{m.name}" for sub in ("data", "identification", "diagnosis", "robot")
              for m in pkgutil.iter_modules([str(root / "src" / "consistid" / sub)])]
    code = ("import consistid as ci\nmissing = []\n"
            f"for name in {names!r}:\n"
            "    try:\n        eval('ci.' + name)\n"
            "    except AttributeError as exc:\n        missing.append(f'{name}: {exc}')\n"
            "print(missing)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]", out


def test_logged_velocities_are_used_when_asked(tmp_path, ur5):
    """velocities="logged": dq is the RTDE log's actual_qd through the chain (not q's
    derivative) — shown by logging a velocity with a known bias, which q's derivative lacks —
    and ddq is its derivative; the [data] key reaches the loader."""
    model, d = ur5
    cols = {"timestamp": d.t, **{f"actual_q_{j}": d.q[:, j] for j in range(6)},
            **{f"actual_qd_{j}": d.dq[:, j] + 0.05 for j in range(6)},
            **{f"target_moment_{j}": d.tau[:, j] for j in range(6)}}
    path = write(tmp_path / "ur.csv", cols, sep=" ")
    auto = load_recording(path, model=model).dataset
    logged = load_recording(path, model=model, velocities="logged")
    mid = slice(100, -100)
    np.testing.assert_allclose(logged.dataset.dq[mid] - auto.dq[mid], 0.05, atol=2e-3)
    np.testing.assert_allclose(logged.dataset.ddq[mid], auto.ddq[mid], atol=0.05)
    np.testing.assert_array_equal(logged.dataset.q, auto.q)
    assert any("velocities='logged'" in s for s in logged.steps)
    assert not any("no logged velocities" in s for s in logged.steps)   # the record agrees
    from consistid.cli.config import config_recordings, load_config

    config = tmp_path / "run.toml"
    config.write_text('[model]\nexample = "ur5"\n[data]\ntrain = ["ur.csv"]\n'
                      'velocities = "logged"\n')
    train, _ = config_recordings(load_config(config), model)
    np.testing.assert_array_equal(train.dataset.dq, logged.dataset.dq)
    with pytest.raises(ci.OptionError, match="velocities='fast'"):
        load_recording(path, model=model, velocities="fast")


def test_a_log_split_over_three_files(tmp_path, panda_run):
    """Positions, velocities and efforts in three CSVs with ``- <joint>_position`` headers (as
    FIGAROH's TIAGo logs are), the efforts' logger on its own clock (stamps 1 ms later): read as
    one log, equal to the same numbers in one table where the stamps agree."""
    model, d = panda_run
    names = model.joint_names
    write(tmp_path / "positions.csv",
          {"time": d.t, **{f"- {n}_position": d.q[:, j] for j, n in enumerate(names)}})
    write(tmp_path / "velocities.csv",
          {"time": d.t, **{f"- {n}_velocity": d.dq[:, j] for j, n in enumerate(names)}})
    write(tmp_path / "efforts.csv",
          {"time": d.t, **{f"- {n}_effort": d.tau[:, j] for j, n in enumerate(names)}})
    files = [tmp_path / f for f in ("positions.csv", "velocities.csv", "efforts.csv")]
    rec = load_recording(files, model=model, velocities="logged")
    ref = load_recording(plain(tmp_path / "p.csv", d, d.t), model=model)
    np.testing.assert_array_equal(rec.dataset.q, ref.dataset.q)
    np.testing.assert_array_equal(rec.dataset.tau, ref.dataset.tau)
    assert rec.dataset.joint_names == tuple(names)
    assert "velocities.csv" in rec.source and any("velocities='logged'" in s for s in rec.steps)
    # efforts on another clock: interpolated onto the positions' stamps, said
    write(tmp_path / "efforts.csv",
          {"time": d.t + 1e-3, **{f"- {n}_effort": d.tau[:, j] for j, n in enumerate(names)}})
    shifted = load_recording(files, model=model)
    assert any("interpolated" in s for s in shifted.steps)
    with pytest.raises(MissingColumnsError, match="no tau columns"):
        load_recording(files[:2], model=model)
    # in a configuration: an array inside train is one log split over its files
    from consistid.cli.config import config_inputs, config_recordings, load_config

    config = tmp_path / "run.toml"
    config.write_text('[model]\nexample = "panda"\n[data]\n'
                      'train = [["positions.csv", "velocities.csv", "efforts.csv"]]\n')
    conf = load_config(config)
    train, _ = config_recordings(conf, model)
    np.testing.assert_array_equal(train.dataset.tau, shifted.dataset.tau)
    assert {p.name for p in config_inputs(conf)} >= {f.name for f in files}

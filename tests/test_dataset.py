import numpy as np
import pytest

import consistid as ci
from consistid.data.signals import preprocess
from consistid.errors import (DatasetError, JointCountError, JointNameError, MissingColumnsError,
                             OptionError)


def make(n=50, nv=3, seed=0, **over):
    rng = np.random.default_rng(seed)
    fields = dict(t=np.arange(n) * 0.01, q=rng.normal(size=(n, nv)), dq=rng.normal(size=(n, nv)),
                  ddq=rng.normal(size=(n, nv)), tau=rng.normal(size=(n, nv)))
    fields.update(over)
    return ci.Dataset(**fields)


def test_nan_is_named_by_field_index_and_joint():
    tau = np.zeros((50, 3))
    tau[12, 1] = np.nan
    with pytest.raises(DatasetError, match=r"dataset\.tau\[12, 'j2'\] is NaN"):
        make(tau=tau, joint_names=("j1", "j2", "j3"))
    q = np.zeros((50, 3))
    q[7, 2] = np.inf
    with pytest.raises(DatasetError, match=r"dataset\.q\[7, 2\] is infinite"):
        make(q=q)


def test_too_few_joint_names_is_named_before_any_value_check():
    tau = np.zeros((50, 3))
    tau[3, 2] = np.nan
    with pytest.raises(DatasetError, match="1 names for 3 joints"):
        make(tau=tau, joint_names=("a",))


def test_segment_must_hold_integers():
    with pytest.raises(DatasetError, match=r"dataset\.segment\[10\] = 0.5"):
        make(segment=np.where(np.arange(50) == 10, 0.5, 0.0))


def test_joint_names_must_match_the_model_and_each_other(panda):
    names = tuple(reversed(panda.joint_names))
    d = make(nv=7, joint_names=names)
    with pytest.raises(JointNameError, match="differ from the model's"):
        ci.identify(panda, d, method="ols")
    with pytest.raises(JointNameError):
        ci.Dataset.concatenate([make(joint_names=("a", "b", "c")),
                                make(joint_names=("x", "y", "z"))])


def test_shape_errors_name_the_field():
    with pytest.raises(DatasetError, match=r"dataset\.dq has shape \(49, 3\)"):
        make(dq=np.zeros((49, 3)))
    with pytest.raises(DatasetError, match=r"dataset\.tau has 2 joints"):
        make(tau=np.zeros((50, 2)))
    with pytest.raises(DatasetError, match="1-D"):
        make(t=np.zeros((50, 2)))


def test_time_must_increase():
    t = np.arange(50) * 0.01
    t[20] = t[19]
    with pytest.raises(DatasetError, match=r"t\[20\].*strictly increasing"):
        make(t=t)


def test_joint_count_mismatch_is_named(panda):
    with pytest.raises(JointCountError, match="3 joints but the model has 7"):
        ci.identify(panda, make(), method="ols")


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_save_load_round_trip(tmp_path, suffix):
    d = make(seed=3, joint_names=("a", "b", "c"))
    d.save(tmp_path / f"run{suffix}")
    back = ci.Dataset.load(tmp_path / f"run{suffix}", joint_names=("a", "b", "c"))
    for f in ("t", "q", "dq", "ddq", "tau", "segment", "joint_names"):
        assert np.array_equal(getattr(d, f), getattr(back, f)), f


def test_npz_keeps_joint_names_and_refuses_other_ones(tmp_path):
    make(joint_names=("a", "b", "c")).save(tmp_path / "run.npz")
    assert ci.Dataset.load(tmp_path / "run.npz").joint_names == ("a", "b", "c")
    with pytest.raises(JointNameError, match="names its joints"):
        ci.Dataset.load(tmp_path / "run.npz", joint_names=("x", "y", "z"))


def test_csv_with_some_torque_columns_is_refused(tmp_path):
    path = tmp_path / "partial.csv"
    make().save(path)
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    drop = header.index("tau2")
    path.write_text("\n".join(",".join(c for i, c in enumerate(line.split(",")) if i != drop)
                              for line in lines))
    with pytest.raises(MissingColumnsError, match=r"lacks \['tau2'\]"):
        ci.Dataset.load(path)


def test_csv_missing_columns_are_listed(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("t,q1,q2,dq1,dq2,ddq1\n0,0,0,0,0,0\n1,0,0,0,0,0\n")
    with pytest.raises(MissingColumnsError, match=r"\['ddq2'\]"):
        ci.Dataset.load(path)


def test_split_by_time_and_by_segment():
    a, b = make(n=100, seed=1), make(n=60, seed=2)
    both = ci.Dataset.concatenate([a, b])
    assert both.n_samples == 160 and set(both.segment) == {0, 1}
    assert np.all(np.diff(both.t) > 0)
    train, held = both.split(0.75)
    assert train.n_samples + held.n_samples == 160
    # each segment contributes its first 75 % to training
    assert np.sum(train.segment == 0) == 75 and np.sum(train.segment == 1) == 45
    train, held = both.split_segments([1])
    assert np.array_equal(held.q, b.q) and np.array_equal(train.q, a.q)
    with pytest.raises(DatasetError):
        both.split(1.5)


def test_a_loggers_csv_is_pointed_to_load_recording(tmp_path):
    path = tmp_path / "log.csv"
    path.write_text("time;joint1;joint2;joint1_effort;joint2_effort\n0;0;0;0;0\n")
    with pytest.raises(MissingColumnsError, match="use consistid.load_recording"):
        ci.Dataset.load(path)
    path.write_text("time,joint1,joint1_effort\n0,0,0\n0.1,0,0\n")
    with pytest.raises(MissingColumnsError, match="use consistid.load_recording"):
        ci.Dataset.load(path)


def test_the_data_package_has_no_import_cycle_and_no_function_level_imports():
    """Imports between modules of consistid.data point one way (an import cycle fails here);
    inside functions only optional heavy dependencies are imported."""
    import ast
    from pathlib import Path

    import consistid.data

    root = Path(consistid.data.__file__).parent
    modules = {p: ".".join(p.relative_to(root).with_suffix("").parts) for p in root.rglob("*.py")}
    graph = {}
    for path, name in modules.items():
        tree = ast.parse(path.read_text())
        package = name.split(".")[:-1] if not name.endswith("__init__") else name.split(".")[:-1]
        deps = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.level:
                base = package[:len(package) - (node.level - 1)] if node.level > 1 else package
                if node.level - 1 > len(package):
                    continue                                  # above consistid.data
                target = ".".join([*base, node.module] if node.module else base)
                for alias in node.names:
                    full = f"{target}.{alias.name}" if target else alias.name
                    for cand in (full, target):
                        if cand in modules.values() or f"{cand}.__init__" in modules.values():
                            deps.add(cand if cand in modules.values() else f"{cand}.__init__")
                            break
        graph[name] = deps - {name}
        for fn in ast.walk(tree):
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                for node in ast.walk(fn):
                    if isinstance(node, (ast.Import, ast.ImportFrom)):
                        mod = node.module if isinstance(node, ast.ImportFrom) else \
                            node.names[0].name
                        assert (mod or "").split(".")[0] in ("pyarrow", "rosbags", "pandas"), (
                            f"{name}.{fn.name} imports {mod} inside the function")
    state: dict = {}

    def visit(node, trail):
        if state.get(node) == "done":
            return
        assert state.get(node) != "open", f"import cycle: {' → '.join([*trail, node])}"
        state[node] = "open"
        for dep in graph.get(node, ()):
            visit(dep, [*trail, node])
        state[node] = "done"

    for name in graph:
        visit(name, [])
    assert "chain" in graph["dataset"] and "dataset" not in graph["chain"]
    assert "dataset" in graph["signals"]


def _logged(rate=200.0, seconds=8.0, nv=2):
    t = np.arange(int(rate * seconds)) / rate
    q = np.column_stack([0.5 * np.sin(2 * np.pi * 0.4 * (j + 1) * t) for j in range(nv)])
    tau = np.column_stack([np.cos(2 * np.pi * 0.4 * (j + 1) * t) for j in range(nv)])
    return t, q, tau + 0.01 * np.random.default_rng(0).standard_normal(tau.shape)


def test_the_chain_records_its_torque_filter_and_files_keep_it(tmp_path):
    """from_recording's dataset carries the (cut-off, order) of the low-pass its torques went
    through, the chain's own; none when the torques were not filtered, or were smoothed another
    way; selection and .npz keep it, a stack of datasets filtered differently has none."""
    t, q, tau = _logged()
    rec = preprocess(t, q, tau)
    data = rec.dataset
    assert data.torque_filter == (rec.derivative_cutoff, rec.options.order)
    assert rec.options.order >= 1
    assert ci.Dataset.from_recording(t, q, tau, filter_torque=False).torque_filter is None
    assert ci.Dataset.from_recording(t, q, tau, derivative="savgol").torque_filter is None
    assert ci.Dataset.from_recording(t, q, tau, decimate=4).torque_filter is None
    assert data.with_torque(data.tau + 1.0).torque_filter is None          # made elsewhere
    assert data.with_torque(data.tau - 1.0, keep_filter=True).torque_filter == data.torque_filter
    assert data.select(slice(10, 100)).torque_filter == data.torque_filter
    data.save(tmp_path / "d.npz")
    assert ci.Dataset.load(tmp_path / "d.npz").torque_filter == data.torque_filter
    with np.load(tmp_path / "d.npz") as f:
        arrays = dict(f)
    np.savez(tmp_path / "bad.npz", **{**arrays, "torque_filter": np.array(5.0)})
    with pytest.raises(DatasetError, match="torque_filter"):
        ci.Dataset.load(tmp_path / "bad.npz")
    other = ci.Dataset.from_recording(t, q, tau, cutoff=3.0)
    assert other.torque_filter[0] == 3.0
    assert ci.Dataset.concatenate([data, data]).torque_filter == data.torque_filter
    assert ci.Dataset.concatenate([data, other]).torque_filter is None


@pytest.mark.parametrize("value", [(0.0, 4), (np.nan, 4), (5.0, 0), (5.0, 2.5), "5 Hz", (5.0,)])
def test_a_bad_torque_filter_is_named(value):
    t, q, tau = _logged()
    with pytest.raises(DatasetError, match="torque_filter"):
        ci.Dataset(t=t, q=q, dq=q, ddq=q, tau=tau, torque_filter=value)


def test_the_chain_records_its_identification_filter_and_files_keep_it(tmp_path):
    """The identification cut-off (parallel filtering) is 3 × the bandwidth, below the one q
    and τ were filtered at; a given cutoff alone keeps its meaning (none); savgol and decimated
    datasets keep it (identification filters both sides at their own rate); fourier, unfiltered
    torques and parallel=False have none. select, with_torque, concatenate of equals and .npz
    keep it, a stack of parts that all have one the highest; a malformed one in a file is a named
    error."""
    t, q, tau = _logged()
    rec = preprocess(t, q, tau, bandwidth=1.0)
    data = rec.dataset
    assert data.identification_filter == (3.0, 4) and rec.cutoff == 3.0
    assert rec.derivative_cutoff == 10.0 and data.torque_filter == (10.0, 4)
    assert any("τ and Y filtered alike" in s.detail for s in rec.steps)
    assert preprocess(t, q, tau, cutoff=5.0).dataset.identification_filter is None
    assert preprocess(t, q, tau, cutoff=5.0, parallel_cutoff=2.0).cutoff == 2.0
    assert preprocess(t, q, tau, parallel=False).dataset.identification_filter is None
    assert preprocess(t, q, tau, filter_torque=False).dataset.identification_filter is None
    assert preprocess(t, q, tau, derivative="savgol", bandwidth=1.0
                      ).dataset.identification_filter == (3.0, 4)
    assert preprocess(t, q, tau, bandwidth=1.0, decimate=2).dataset.identification_filter \
        == (3.0, 4)
    with pytest.raises(OptionError, match="parallel_cutoff"):
        preprocess(t, q, tau, cutoff=5.0, parallel_cutoff=6.0)
    with pytest.raises(OptionError, match="parallel"):
        preprocess(t, q, tau, parallel="yes")
    assert data.select(slice(10, 100)).identification_filter == (3.0, 4)
    assert data.with_torque(data.tau + 1.0).identification_filter == (3.0, 4)
    data.save(tmp_path / "d.npz")
    assert ci.Dataset.load(tmp_path / "d.npz").identification_filter == (3.0, 4)
    with np.load(tmp_path / "d.npz") as f:
        arrays = dict(f)
    np.savez(tmp_path / "bad.npz", **{**arrays, "identification_filter": np.array([0.0, 4.0])})
    with pytest.raises(DatasetError, match="identification_filter"):
        ci.Dataset.load(tmp_path / "bad.npz")
    other = preprocess(t, q, tau, bandwidth=0.8).dataset
    assert ci.Dataset.concatenate([data, data]).identification_filter == (3.0, 4)
    assert ci.Dataset.concatenate([other, data]).identification_filter == (3.0, 4)  # the highest
    unfiltered = preprocess(t, q, tau, parallel=False).dataset
    assert ci.Dataset.concatenate([data, unfiltered]).identification_filter is None

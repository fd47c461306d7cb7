"""Hostile input, round four (issue 30): the readers, loaded files and writers that arrived
after round three.

* A result file whose fields restate each other (standard parameters and base values, σ and the
  covariance, the consistency verdict) is refused by name when they disagree, as are an
  unknown regressor term, ``extra`` fields that would replace core ones, a covariance that is
  no covariance and an absurd gravity (each a tampering that used to load and change the
  answer without a word, or raise ``KeyError``/``AttributeError``).
* A diagnosis file: an unimportable class, a robot with a negative armature, NaN or negative
  per-joint figures, a corrected model whose arrays do not fit (``matmul`` errors before) or
  predict NaN, breakdown tables of the wrong shape: all ``ResultFileError``.
* Readers: an MJCF joint name with a control character, a NaN that MuJoCo would compile as 0,
  non-UTF-8 bytes, a folder; ``Transmission`` values that are text or ragged; a split log with
  a NaN stamp; date-time, float16 or text arrays in a dataset; a saved identification filter
  above Nyquist or of absurd order; ns stamps read as s (year 5e10) — all named. A Latin-1
  CSV is read, with a warning (the issue asks it accepted).
* Writers: every one writes through :func:`consistid.filesafety.replacing` (never
  half-written), refuses a missing folder, an existing folder and a NUL in the path by name,
  and never writes over the URDF the model was read from.
"""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import consistid as ci
from consistid.data.recordings import load_recording
from consistid.errors import (ConsistidError, DataQualityWarning, DatasetError, ModelError,
                              OptionError, OutputPathError, ResultFileError)

from .conftest import PLANAR_2R, PLANAR_2R_VALUES, random_states

ARM = PLANAR_2R.format(**PLANAR_2R_VALUES)
N = 200


def _data(model: ci.RobotModel, n: int = N, seed: int = 0) -> ci.Dataset:
    rng = np.random.default_rng(seed)
    q, dq, ddq = random_states(model, n, seed)
    tau = model.rnea(q, dq, ddq) + 0.01 * rng.standard_normal(q.shape)
    return ci.Dataset(t=0.005 * np.arange(n), q=q, dq=dq, ddq=ddq, tau=tau)


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    """The 2R arm read from its URDF, its data, an OLS result and that result's document."""
    tmp = tmp_path_factory.mktemp("round4")
    (tmp / "arm.urdf").write_text(ARM)
    model = ci.RobotModel.from_urdf(tmp / "arm.urdf", gravity=(0.0, -9.81, 0.0))
    data = _data(model)
    res = ci.identify(model, data, method="ols")
    doc = json.loads(res.save(tmp / "result.json").read_text())
    return model, data, res, doc


def _load(tmp: Path, doc: dict) -> ci.IdentificationResult:
    path = tmp / "tampered.json"
    path.write_text(json.dumps(doc))
    return ci.IdentificationResult.load(path)


# ----------------------------------------------------------------------------- result files
def _scale_covariance(doc, f):
    doc["base"]["covariance"] = f(np.array(doc["base"]["covariance"], dtype=float)).tolist()


RESTATED = [
    ("negative variance", lambda d: _scale_covariance(d, lambda c: c - 2 * np.diag(np.diag(c))),
     "variance must be ≥ 0"),
    ("correlation beyond 1", lambda d: _scale_covariance(
        d, lambda c: c + 1e3 * (np.ones_like(c) - np.eye(len(c)))), "correlation beyond"),
    ("not symmetric", lambda d: _scale_covariance(d, lambda c: c + np.triu(np.full_like(c, 1e-3),
                                                                            1)),
     "not symmetric|correlation beyond"),
    ("covariance 1e300", lambda d: _scale_covariance(d, lambda c: c * 0 + 1e300),
     "'base.std' is not the square root"),
    ("std edited", lambda d: d["base"].__setitem__("std", [1.0] * len(d["base"]["std"])),
     "'base.std' is not the square root"),
    ("base values 1e300", lambda d: d["base"].__setitem__("values", [1e300] * len(
        d["base"]["values"])), "'parameters' and 'base.values' disagree"),
    ("parameters 1e300", lambda d: d.__setitem__("parameters", [1e300] * len(d["parameters"])),
     "'parameters' and 'base.values' disagree"),
    ("a negative mass under 'ok'", lambda d: d["parameters"].__setitem__(0, -5.0),
     "'consistency.ok' is True"),
    ("names reordered", lambda d: d.__setitem__("parameter_names", d["parameter_names"][::-1]),
     "'parameter_names' is not the list"),
    ("gravity 1e300", lambda d: d["model"].__setitem__("gravity", [0, -1e300, 0]),
     "'gravity'.*beyond"),
    ("an unknown term", lambda d: d["spec"]["masks"].__setitem__("warp", [True, True]),
     "masks\\['warp'\\] is not a joint term"),
    ("coulomb switched off", lambda d: d["spec"]["masks"].__setitem__("coulomb", [False, False]),
     "'parameter_names' is not the list"),
    ("extra replaces the model", lambda d: d.__setitem__("extra", {"model": "x"}),
     "'extra' holds \\['model'\\]"),
]


@pytest.mark.parametrize("edit, message", [pytest.param(e, m, id=i) for i, e, m in RESTATED])
def test_result_fields_that_disagree_are_named(arm, tmp_path, edit, message):
    doc = copy.deepcopy(arm[3])
    edit(doc)
    with pytest.raises(ResultFileError, match=message):
        _load(tmp_path, doc)


def test_an_untampered_result_still_loads_bit_for_bit(arm, tmp_path):
    _, data, res, doc = arm
    back = _load(tmp_path, copy.deepcopy(doc))
    np.testing.assert_array_equal(back.predict(data), res.predict(data))
    np.testing.assert_array_equal(back.base_std, res.base_std)


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(index=st.integers(0, 10**6), value=st.one_of(
    st.floats(allow_nan=False, allow_infinity=False), st.just(-1.0), st.just(1e300)),
    target=st.sampled_from(["parameters", "values", "std", "covariance"]))
def test_one_number_changed_anywhere_is_named_or_changes_nothing(arm, tmp_path, index, value,
                                                                 target):
    """Change one number of the fields the answer is built from: the load refuses it by name,
    or the loaded result predicts what the saved one did (the number was not read)."""
    _, data, res, doc = arm
    doc = copy.deepcopy(doc)
    where = doc if target == "parameters" else doc["base"]
    flat = np.array(where[target], dtype=float)
    k = index % flat.size
    if flat.flat[k] == value:
        return
    flat.flat[k] = value
    where[target] = flat.tolist()
    try:
        back = _load(tmp_path, doc)
    except ResultFileError:
        return
    np.testing.assert_allclose(back.predict(data), res.predict(data), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(back.base_std, res.base_std, rtol=1e-9)


# ----------------------------------------------------------------------------- diagnosis files
@pytest.fixture(scope="module")
def diagnosed(tmp_path_factory):
    """A diagnosis of a MuJoCo UR5 with Coulomb friction on one joint (100 Hz, train 4 s,
    held out 2 s), saved; its document and the held-out data."""
    from consistid.excitation import FourierTrajectory
    from consistid.simulate import record
    from consistid.simulate.effects import Effects

    ur5 = ci.RobotModel.example("ur5")
    effects = Effects(torque_noise=0.05).with_effect("coulomb", 1.5, joints=[2])
    data = []
    for seed, duration in ((21, 4.0), (22, 2.0)):
        rec = record(ur5, FourierTrajectory.random(ur5, 4, 6.0, seed), effects,
                     duration=duration, rate=100.0, seed=seed)
        data.append(ci.Dataset.from_recording(rec.t, rec.q, rec.tau))
    diag = ci.diagnose(ur5, data[0], held_out=data[1], effects=["coulomb", "viscous"],
                       progress=False)
    tmp = tmp_path_factory.mktemp("diag")
    doc = json.loads(diag.save(tmp / "diagnosis.json").read_text())
    return diag, doc, data[1]


def _nd(values):
    a = np.asarray(values, dtype=float)
    return {"__ndarray__": a.tolist(), "dtype": "<f8", "shape": list(a.shape)}


def _robot(g):
    return g["fit"]["model"]["__robot__"]


DIAGNOSIS_EDITS = [
    ("module", lambda g: g.__setitem__("__dataclass__", "consistid.diagnosis.nope:X"),
     "names no module"),
    ("negative armature", lambda g: _robot(g).__setitem__("armature", [-1.0] * 6),
     "'armature'\\[0\\]"),
    ("NaN noise floor", lambda g: g.__setitem__("noise_floor", {
        "__ndarray__": [{"__float__": "nan"}] * 6, "dtype": "<f8", "shape": [6]}),
     "'noise_floor'\\[0\\]"),
    ("negative RMS", lambda g: g.__setitem__("rms_final", _nd([-1.0] * 6)), "'rms_final'"),
    ("newline in a joint name", lambda g: g["joint_names"]["__tuple__"].__setitem__(0, "a\nb"),
     "control character"),
    ("theta NaN", lambda g: g["fit"].__setitem__("theta", {"__tuple__": [
        _nd([np.nan] * len(t["__ndarray__"])) for t in g["fit"]["theta"]["__tuple__"]]}),
     "'fit.theta'"),
    ("theta of another length", lambda g: g["fit"]["theta"]["__tuple__"].__setitem__(
        0, _nd([1.0, 2.0, 3.0, 4.0, 5.0])), "do not fit together"),
    ("theta dropped", lambda g: g["fit"].__setitem__("theta", {"__tuple__": []}),
     "'fit.theta'"),
    ("nominal of another shape", lambda g: g["fit"].__setitem__("nominal", _nd([1.0, 2.0])),
     "'fit.nominal'"),
    ("ripple order -3", lambda g: g["fit"]["library"]["__effect_library__"].__setitem__(
        "ripple_orders", [-3]), "'ripple_orders'"),
    ("delays on no atom", lambda g: g["fit"].__setitem__("delays", {"__items__": [[7, 0.01]]}),
     "'fit.delays'"),
    ("psd of another shape", lambda g: g["where"].__setitem__("psd", _nd([1.0, 2.0])),
     "'where.psd'"),
    ("effects not a tuple", lambda g: g.__setitem__("effects", 5), "do not fit together"),
]


@pytest.mark.parametrize("edit, message",
                         [pytest.param(e, m, id=i) for i, e, m in DIAGNOSIS_EDITS])
def test_tampered_diagnosis_files_are_named(diagnosed, tmp_path, edit, message):
    doc = copy.deepcopy(diagnosed[1])
    edit(doc["diagnosis"])
    path = tmp_path / "d.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(ResultFileError, match=message):
        ci.Diagnosis.load(path)


def test_an_untampered_diagnosis_still_predicts_bit_for_bit(diagnosed, tmp_path):
    diag, doc, held = diagnosed
    assert [e.name for e in diag.effects], "the fixture must select an effect"
    path = tmp_path / "d.json"
    path.write_text(json.dumps(doc))
    np.testing.assert_array_equal(ci.Diagnosis.load(path).fit.predict(held),
                                  diag.fit.predict(held))


def test_a_rollout_file_naming_a_joint_twice_is_named(tmp_path):
    from consistid.simulator import RolloutValidation

    doc = {"format": "consistid.rollout", "joint_names": ["a", "a"], "timestep": 0.001,
           "integrator": "implicitfast", "window": 1.0, "kp": [1.0, 1.0], "kd": [1.0, 1.0],
           "duration": 1.0, "controller": "PD", "replays": []}
    (tmp_path / "v.json").write_text(json.dumps(doc))
    with pytest.raises(ResultFileError, match="'joint_names'.*each once"):
        RolloutValidation.load(tmp_path / "v.json")


# ----------------------------------------------------------------------------- MJCF
MJCF = """<mujoco model="m">
  <worldbody>
    <body name="l1">
      <joint name="{joint}" type="hinge" axis="0 0 1"/>
      <inertial pos="{pos} 0 0" mass="2" diaginertia="0.01 0.2 0.2"/>
      <body name="l2" pos="1 0 0">
        <joint name="j2" type="hinge" axis="0 0 1"/>
        <inertial pos="0.5 0 0" mass="1" diaginertia="0.01 0.1 0.1"/>
      </body>
    </body>
  </worldbody>
</mujoco>"""


@pytest.mark.parametrize("joint, pos, message", [
    ("a&#10;b", "0.5", "control character"),
    ("j1", "nan", "holds 'nan'; MuJoCo would compile it as 0"),
    ("j1", "inf", "holds 'inf'"),
])
def test_mjcf_names_and_numbers_that_cannot_be_kept_are_named(tmp_path, joint, pos, message):
    path = tmp_path / "m.xml"
    path.write_text(MJCF.format(joint=joint, pos=pos))
    with pytest.raises(ModelError, match=message):
        ci.RobotModel.from_mjcf(path)


def test_mjcf_markup_names_load_and_a_joint_named_inf_is_a_name(tmp_path):
    path = tmp_path / "m.xml"
    path.write_text(MJCF.format(joint="a&lt;b&gt;&quot;", pos="0.5").replace(
        'name="j2"', 'name="inf"'))
    assert list(ci.RobotModel.from_mjcf(path).joint_names) == ["a<b>\"", "inf"]


def test_a_non_utf8_mjcf_and_a_folder_are_named(tmp_path):
    path = tmp_path / "m.xml"
    path.write_bytes(('<?xml version="1.0" encoding="ISO-8859-1"?>'
                      + MJCF.format(joint="jé", pos="0.5")).encode("latin-1"))
    with pytest.raises(ModelError, match="not UTF-8.*iconv"):
        ci.RobotModel.from_mjcf(path)
    with pytest.raises(ModelError, match="is a folder"):
        ci.RobotModel.from_mjcf(tmp_path)


# ----------------------------------------------------------------------------- logs and arrays
@pytest.mark.parametrize("kwargs, message", [
    ({"ratios": ["a", "b"]}, "ratios must hold numbers"),
    ({"ratios": [1.0, 1.0], "coupling": [["a", 0], [0, 1]]}, "coupling must hold numbers"),
    ({"ratios": [1.0, 1.0], "coupling": [[1.0], [0.0, 1.0]]}, "coupling must hold numbers"),
    ({"ratios": [1.0, 1.0], "torque_constants": {"a": 1}}, "torque_constants must hold"),
])
def test_transmission_values_that_are_not_numbers_are_named(kwargs, message):
    with pytest.raises(OptionError, match=message):
        ci.Transmission(**kwargs)


def _npz(tmp: Path, data: ci.Dataset, **over) -> Path:
    arrays = {"t": data.t, "q": data.q, "dq": data.dq, "ddq": data.ddq, "tau": data.tau}
    arrays.update(over)
    np.savez(tmp / "d.npz", **arrays)
    return tmp / "d.npz"


@pytest.mark.parametrize("over, message", [
    ({"identification_filter": np.array([1e6, 4.0])}, "not below the Nyquist"),
    ({"identification_filter": np.array([5.0, 1e300])}, "whole number from 1 to"),
    ({"t": np.arange(N).astype("datetime64[ms]")}, "date-times"),
    ({"t": (0.005 * np.arange(N) + 40.0).astype(np.float16)}, "float16|resolve"),
    ({"segment": np.array(["a"] * N)}, "dataset.segment holds"),
])
def test_forged_dataset_arrays_are_named(arm, tmp_path, over, message):
    with pytest.raises(DatasetError, match=message):
        ci.Dataset.load(_npz(tmp_path, arm[1], **over))


def test_a_saved_filter_below_nyquist_still_loads(arm, tmp_path):
    back = ci.Dataset.load(_npz(tmp_path, arm[1], identification_filter=np.array([5.0, 4.0])))
    assert back.identification_filter == (5.0, 4)


def _csv(path: Path, head: list[str], rows: np.ndarray) -> Path:
    path.write_text(",".join(head) + "\n" + "\n".join(",".join(repr(float(v)) for v in r)
                                                      for r in rows) + "\n")
    return path


def test_a_split_log_with_a_nan_stamp_is_named(arm, tmp_path):
    model, data = arm[0], arm[1]
    pos = _csv(tmp_path / "pos.csv", ["time", "joint1_position", "joint2_position"],
               np.column_stack([data.t, data.q]))
    t = data.t.copy()
    t[-1] = np.nan
    eff = _csv(tmp_path / "eff.csv", ["time", "joint1_effort", "joint2_effort"],
               np.column_stack([t, data.tau]))
    with pytest.raises(DatasetError, match="eff.csv, column 'time'.*non-finite"):
        load_recording([pos, eff], model=model)


def test_a_single_row_of_ns_stamps_is_named_not_an_oserror(arm, tmp_path):
    """One franka_ros row: its ns stamp cannot be told from seconds, and read as seconds it
    is a date no clock can show (``datetime`` raised OSError before)."""
    model, data = arm[0], arm[1]
    head = ["%time", "field.header.stamp", "field.q0", "field.q1", "field.dq0", "field.dq1",
            "field.tau_J0", "field.tau_J1"]
    row = np.column_stack([[1.7e18], [1.7e18], data.q[:1], data.dq[:1], data.tau[:1]])
    with pytest.raises(ConsistidError):
        load_recording(_csv(tmp_path / "franka.csv", head, row), model=model)


def test_a_latin1_column_name_is_read_with_a_warning(arm, tmp_path):
    model, data = arm[0], arm[1]
    head = ["timestamp", "actual_q_0", "actual_q_1", "actual_qd_0", "actual_qd_1",
            "actual_current_as_torque_0", "actual_current_as_torque_1", "température"]
    rows = np.column_stack([data.t + 1000.0, data.q, data.dq, data.tau, np.zeros(N)])
    utf8 = _csv(tmp_path / "utf8.csv", head, rows)
    path = tmp_path / "rtde.csv"
    path.write_bytes(utf8.read_text().encode("latin-1"))
    with pytest.warns(DataQualityWarning, match="rtde.csv, line 1.*Latin-1.*température"):
        rec = load_recording(path, model=model)
    np.testing.assert_array_equal(rec.dataset.q, load_recording(utf8, model=model).dataset.q)


# ----------------------------------------------------------------------------- writers
_CONSISTENT: dict[int, ci.IdentificationResult] = {}


def _consistent(model: ci.RobotModel, data: ci.Dataset) -> ci.IdentificationResult:
    """The default (consistent) identification, once per module: the exporters refuse the
    OLS one's slightly negative friction."""
    if id(model) not in _CONSISTENT:
        _CONSISTENT[id(model)] = ci.identify(model, data)
    return _CONSISTENT[id(model)]


def _writers(arm, diagnosed):
    model, data, res, _ = arm
    return {
        "save": lambda p: res.save(p.with_suffix(".json")),
        "to_csv": lambda p: res.to_csv(p.with_suffix(".csv")),
        "report": lambda p: res.report(p.with_suffix(".html")),
        "report txt": lambda p: res.report(p.with_suffix(".txt")),
        "to_mjcf": lambda p: _consistent(model, data).to_mjcf(p.with_suffix(".xml")),
        "to_urdf": lambda p: _consistent(model, data).to_urdf(p.with_suffix(".urdf")),
        "Dataset npz": lambda p: data.save(p.with_suffix(".npz")),
        "Dataset csv": lambda p: data.save(p.with_suffix(".csv")),
        "Diagnosis": lambda p: diagnosed[0].save(p.with_suffix(".json")),
        "Diagnosis txt": lambda p: diagnosed[0].report(p.with_suffix(".txt")),
    }


WRITERS = ["save", "to_csv", "report", "report txt", "to_mjcf", "to_urdf", "Dataset npz",
           "Dataset csv", "Diagnosis", "Diagnosis txt"]


@pytest.mark.parametrize("writer", WRITERS)
def test_writers_name_a_bad_destination(arm, diagnosed, tmp_path, writer):
    write = _writers(arm, diagnosed)[writer]
    with pytest.raises(OutputPathError, match="does not exist"):
        write(tmp_path / "missing" / "out")
    folder = tmp_path / "out"
    for suffix in (".json", ".csv", ".html", ".txt", ".xml", ".urdf", ".npz"):
        folder.with_suffix(suffix).mkdir()
    with pytest.raises(OutputPathError, match="existing folder"):
        write(folder)
    with pytest.raises(OutputPathError, match="NUL"):
        write(tmp_path / "a\0b")


@pytest.mark.parametrize("writer", WRITERS)
def test_an_interrupted_writer_keeps_the_old_file(arm, diagnosed, tmp_path, writer,
                                                  monkeypatch):
    """The writer is stopped as it renames its file into place: the old file stays whole and
    no temporary file is left beside it."""
    import consistid.filesafety as fs

    write = _writers(arm, diagnosed)[writer]
    target = tmp_path / "out"
    for suffix in (".json", ".csv", ".html", ".txt", ".xml", ".urdf", ".npz"):
        target.with_suffix(suffix).write_text("old")

    def stop(*_):
        raise KeyboardInterrupt

    monkeypatch.setattr(fs.os, "replace", stop)
    with pytest.raises(KeyboardInterrupt):
        write(target)
    assert sorted(p.read_text() for p in tmp_path.iterdir()) == ["old"] * 7


@pytest.mark.parametrize("writer", ["save", "to_csv", "report", "report txt"])
def test_no_writer_replaces_the_urdf_it_was_read_from(arm, diagnosed, tmp_path, writer):
    model, data, _, _ = arm
    source = Path(model.source)
    before = source.read_bytes()
    res = ci.identify(model, data, method="ols")
    write = {"save": res.save, "to_csv": res.to_csv, "report": res.report,
             "report txt": res.report}[writer]
    with pytest.raises(ModelError, match="would write over"):
        write(source)
    assert source.read_bytes() == before


def test_a_zip_bomb_member_is_refused_before_it_inflates(arm, tmp_path):
    """A deflated member of zeros whose header claims 80 MB: refused from its sizes, before
    numpy would inflate it (the claim is honest, so the header check alone admits it)."""
    import io
    import zipfile

    data = arm[1]
    path = tmp_path / "bomb.npz"
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for key in ("t", "dq", "ddq", "tau"):
            buf = io.BytesIO()
            np.save(buf, getattr(data, key))
            zf.writestr(f"{key}.npy", buf.getvalue())
        buf = io.BytesIO()
        np.save(buf, np.zeros((5_000_000, 2)))
        zf.writestr("q.npy", buf.getvalue())
    with pytest.raises(DatasetError, match="array 'q' inflates .*fold.: a zip bomb"):
        ci.Dataset.load(path)
    np.savez_compressed(tmp_path / "real.npz", t=data.t, q=data.q, dq=data.dq, ddq=data.ddq,
                        tau=data.tau)
    assert ci.Dataset.load(tmp_path / "real.npz").q.shape == data.q.shape

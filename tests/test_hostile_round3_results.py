"""Hostile input, round three (issue 30): result files that lie, names that are code, XML that
expands.

* ``IdentificationResult.load`` never opens a path the file names unless asked
  (``follow_source=True``), and checks the whole document (types, shapes, finiteness, sizes,
  nesting) before building anything: every tampering gives a ``ResultFileError`` naming the
  field (a fuzzer tampers with random fields; any other exception fails).
* Names that a CSV/TOML/URDF/MJCF cannot carry (a newline) are refused; names that a
  spreadsheet would run as formulas are written defused; markup in names stays text in HTML.
* URDFs are parsed with entity expansion off: an entity is refused by name, a namespaced but
  valid URDF is accepted.
"""

from __future__ import annotations

import copy
import csv
import json
import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import consistid as ci
from consistid.cli.hints import toml_value
from consistid.errors import ConsistidError, ModelError, ResultFileError
from consistid.identification import persistence
from consistid.textsafety import FORMULA_STARTS, spreadsheet_cell

from .conftest import PLANAR_2R, PLANAR_2R_VALUES, random_states

ARM = PLANAR_2R.format(**PLANAR_2R_VALUES)


def _arm(tmp: Path, text: str = ARM, name: str = "arm.urdf") -> Path:
    path = tmp / name
    path.write_text(text)
    return path


def _data(model: ci.RobotModel, seed: int = 0) -> ci.Dataset:
    rng = np.random.default_rng(seed)
    q, dq, ddq = random_states(model, 200, seed)
    tau = model.rnea(q, dq, ddq) + 0.01 * rng.standard_normal(q.shape)
    return ci.Dataset(t=0.005 * np.arange(200), q=q, dq=dq, ddq=ddq, tau=tau)


@pytest.fixture(scope="module")
def saved(tmp_path_factory) -> tuple[Path, dict]:
    """A saved OLS result of the 2R arm (its URDF beside it) and its JSON document."""
    tmp = tmp_path_factory.mktemp("saved")
    model = ci.RobotModel.from_urdf(_arm(tmp), gravity=(0.0, -9.81, 0.0))
    res = ci.identify(model, _data(model), method="ols")
    path = res.save(tmp / "result.json")
    return path, json.loads(path.read_text())


def _load_doc(tmp: Path, doc: object, text: str | None = None):
    path = tmp / "tampered.json"
    path.write_text(json.dumps(doc) if text is None else text)
    return ci.IdentificationResult.load(path)


# ----------------------------------------------------------------------------- paths
def test_load_never_opens_the_path_the_file_names(saved, tmp_path, monkeypatch):
    path, doc = saved
    bait = _arm(tmp_path, name="bait.urdf")            # what a tampered file points at
    doc = copy.deepcopy(doc)
    doc["model"]["source"] = str(bait)
    doc["model"]["urdf_sha256"] = persistence.sha256(bait)
    opened = []
    real = persistence.sha256
    monkeypatch.setattr(persistence, "sha256", lambda p: opened.append(str(p)) or real(p))
    res = _load_doc(tmp_path, doc)
    assert opened == [] and res.model.source is None
    # asked: the named URDF is used when its SHA-256 matches
    path2 = tmp_path / "asked.json"
    path2.write_text(json.dumps(doc))
    assert ci.IdentificationResult.load(path2, follow_source=True).model.source == bait
    # saving the reloaded result writes the file's URDF record back, unopened
    again = json.loads(res.save(tmp_path / "again.json").read_text())
    assert again["model"]["urdf"] == doc["model"]["urdf"]
    assert again["model"]["source"] == str(bait)


# ----------------------------------------------------------------------------- tampering
def _set(keys: tuple, value):
    def edit(doc):
        target = doc
        for k in keys[:-1]:
            target = target[k]
        target[keys[-1]] = value(target[keys[-1]]) if callable(value) else value
    return edit


def _drop(keys: tuple):
    def edit(doc):
        target = doc
        for k in keys[:-1]:
            target = target[k]
        del target[keys[-1]]
    return edit


def _deep(n: int):
    value: object = 0
    for _ in range(n):
        value = [value]
    return value


TAMPERED = [
    *[(_drop((key,)), f"'{key}' is missing") for key in (
        "parameter_names", "parameters", "prior", "base", "sigma", "condition_number",
        "train_rms", "n_samples", "solver", "spec", "model", "method")],
    *[(_drop(("model", key)), f"'{key}' is missing") for key in (
        "joint_names", "body_names", "inertias", "armature", "gravity")],
    *[(_drop(("base", key)), f"'{key}' is missing") for key in (
        "independent", "dependent", "K", "values", "covariance")],
    (_set(("parameters",), "abc"), "'parameters' must be list"),
    (_set(("parameters",), {"a": 1}), "'parameters' must be list"),
    (_set(("parameters",), lambda v: v[:-1]), "'parameters' has shape"),
    (_set(("parameters",), lambda v: [{"__float__": "nan"}] + v[1:]), "'parameters'\\[0\\]"),
    (_set(("sigma",), lambda v: ["x"] * len(v)), "'sigma'\\[0\\]"),
    (_set(("sigma",), lambda v: [-1.0] * len(v)), "'sigma'\\[0\\].*≥ 0"),
    (_set(("n_samples",), "10"), "'n_samples' must be int"),
    (_set(("n_samples",), 1.5), "'n_samples' must be int"),
    (_set(("n_samples",), -3), "'n_samples' must be ≥ 0"),
    (_set(("solver",), []), "'solver' must be dict"),
    (_set(("solver", "status"), 3), "'status' must be str"),
    (_set(("base", "independent"), [1.5]), "'independent' must list distinct"),
    (_set(("base", "independent"), lambda v: [10**6] + v[1:]), "'independent' must list"),
    (_set(("base", "independent"), lambda v: [v[0]] + v[:-1]), "'independent' must list"),
    (_set(("base", "K"), [[1.0]]), "'K' has shape"),
    (_set(("base", "covariance"), lambda v: [[{"__float__": "nan"}] * len(v)] + v[1:]),
     "'covariance'\\[0, 0\\]"),
    (_set(("base", "rtol"), "tiny"), "'rtol' must be"),
    (_set(("model", "armature"), lambda v: [-0.5] * len(v)), "'armature'\\[0\\].*≥ 0"),
    (_set(("model", "gravity"), [0, 0, {"__float__": "nan"}]), "'gravity'\\[2\\]"),
    (_set(("model", "joint_names"), ["joint1\nx", "joint2"]), "'joint_names'\\[0\\]"),
    (_set(("model", "joint_names"), ["joint1"]), "'armature' has shape"),
    (_set(("spec", "nv"), 10**9), "'nv' is 1000000000"),
    (_set(("spec", "masks"), {"coulomb": [1, 0]}), "masks"),
    (_set(("condition_number",), "big"), "'condition_number'"),
    (_set(("details",), {"x": {"__ndarray__": [1], "dtype": "U1000000000", "shape": [1]}}),
     "dtype 'U1000000000'"),
    (_set(("details",), {"x": {"__ndarray__": [1], "dtype": "U100000", "shape": [1]}}),
     "not a numeric dtype"),
    (_set(("details",), {"x": {"__ndarray__": [1, 2, 3], "dtype": "<f8", "shape": [5, 5]}}),
     "'details' holds a malformed"),
    (_set(("details",), {"x": {"__ndarray__": [1], "dtype": "object", "shape": [1]}}),
     "not a numeric dtype"),
    (_set(("details",), _deep(200)), "nested deeper"),
    (_set(("details",), "x"), "'details' must be dict"),
    (_set(("uninformed",), [1]), "'uninformed' must list strings"),
    # the names restate the robot's bodies and the spec's terms: other names are an edit
    (_set(("parameter_names",), lambda v: ["=1+1"] * len(v)), "'parameter_names' is not the"),
]


@pytest.mark.parametrize("edit, message", TAMPERED)
def test_tampered_fields_are_named(saved, tmp_path, edit, message):
    doc = copy.deepcopy(saved[1])
    edit(doc)
    if message is None:
        _load_doc(tmp_path, doc)
        return
    with pytest.raises(ResultFileError, match=message):
        _load_doc(tmp_path, doc)


@pytest.mark.parametrize("text, message", [
    ("[" * 100_000 + "]" * 100_000, "nested deeper|not a JSON"),
    ('{"format": ' + "9" * 10_000 + "}", "not a JSON"),
    ("\xff\xfe{}", "not a JSON|not UTF-8"),
    ("[1, 2]", "not a consistid identification result"),
    ("", "not a JSON"),
])
def test_malformed_documents_are_named(tmp_path, text, message):
    with pytest.raises(ResultFileError, match=message):
        _load_doc(tmp_path, None, text=text)


def test_a_huge_string_or_file_is_refused_before_parsing(saved, tmp_path, monkeypatch):
    from consistid.identification import resultschema
    doc = copy.deepcopy(saved[1])
    doc["method"] = "x" * 5000
    monkeypatch.setattr(resultschema, "MAX_TEXT", 4000)
    with pytest.raises(ResultFileError, match="5000 characters"):
        _load_doc(tmp_path, doc)
    monkeypatch.setattr(resultschema, "MAX_BYTES", 1000)
    with pytest.raises(ResultFileError, match="more than a result file can"):
        _load_doc(tmp_path, saved[1])


def test_a_folder_given_as_result_file_is_named(tmp_path):
    with pytest.raises(ResultFileError, match="is a folder"):
        ci.IdentificationResult.load(tmp_path)


JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers(-10**6, 10**6) | st.floats(allow_nan=False)
    | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner,
                                                                max_size=4),
    max_leaves=10)


def _paths(doc, prefix=()):
    yield prefix
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from _paths(v, (*prefix, k))
    elif isinstance(doc, list) and doc:
        yield from _paths(doc[0], (*prefix, 0))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                 HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_fuzzed_result_files_load_or_are_named(saved, tmp_path, data):
    """Replace a random node (or delete a random key) of a saved result by a random JSON value:
    ``load`` either succeeds, with finite parameters, or raises a consistid error."""
    doc = copy.deepcopy(saved[1])
    paths = [p for p in _paths(doc) if p and p[0] not in ("provenance", "consistency")]
    where = data.draw(st.sampled_from(paths))
    target = doc
    for k in where[:-1]:
        target = target[k]
    if isinstance(target, dict) and data.draw(st.booleans()):
        del target[where[-1]]
    else:
        target[where[-1]] = data.draw(JSON_VALUES)
    try:
        res = _load_doc(tmp_path, doc)
    except ConsistidError:
        return
    assert np.all(np.isfinite(res.parameters)) and np.all(res.model.pin_model.armature >= 0)


# ----------------------------------------------------------------------------- names as code
def _named(tmp: Path, joint1: str, link1: str = "link1") -> Path:
    text = ARM.replace('name="joint1"', f'name="{joint1}"').replace(
        '"link1"', f'"{link1}"')
    return _arm(tmp, text, "named.urdf")


FORMULAS = ["=HYPERLINK(&quot;http://x&quot;)", "+1+2", "@SUM(A1)", "-2+3"]


@pytest.mark.parametrize("name", FORMULAS)
def test_formula_names_are_defused_in_the_parameter_csv(tmp_path, name):
    model = ci.RobotModel.from_urdf(_named(tmp_path, name, link1=name),
                                    gravity=(0.0, -9.81, 0.0))
    res = ci.identify(model, _data(model), method="ols")
    rows = list(csv.DictReader(res.to_csv(tmp_path / "p.csv").open(encoding="utf-8")))
    cells = [r[k] for r in rows for k in ("name", "definition")]
    assert not [c for c in cells if c.startswith(FORMULA_STARTS)]
    # the name is kept, behind the quote a spreadsheet shows as text
    assert any(c.startswith("'" + name.replace("&quot;", '"')[:3]) for c in cells)


def test_spreadsheet_cell_leaves_plain_text_alone():
    assert spreadsheet_cell("link1.m") == "link1.m"
    assert spreadsheet_cell("=1") == "'=1"
    assert spreadsheet_cell("a\nb") == "a\\nb"


@pytest.mark.parametrize("name", ["joint&#10;1", "joint&#13;1", "a&#9;b"])
def test_a_joint_name_with_a_control_character_is_refused(tmp_path, name):
    with pytest.raises(ModelError, match="control character"):
        ci.RobotModel.from_urdf(_named(tmp_path, name))


def test_a_ramp_plan_with_a_newline_in_a_joint_name_is_refused(tmp_path, planar_2r):
    import dataclasses

    from consistid.friction import ramp_plan
    bad = dataclasses.replace(ramp_plan(planar_2r), joint_names=("joint1\n# injected", "joint2"))
    with pytest.raises(ModelError, match="control character"):
        bad.to_csv(tmp_path / "ramp.csv")
    assert not (tmp_path / "ramp.csv").exists()


def test_markup_in_names_stays_text_in_the_html_report(tmp_path):
    name = "&lt;script&gt;alert(1)&lt;/script&gt;"
    model = ci.RobotModel.from_urdf(_named(tmp_path, name), gravity=(0.0, -9.81, 0.0))
    res = ci.identify(model, _data(model), method="ols")
    page = res.report(tmp_path / "r.html").read_text(encoding="utf-8")
    assert "<script>alert(1)" not in page and "&lt;script&gt;alert(1)" in page


def test_a_quote_in_a_link_name_exports_to_mjcf(tmp_path):
    import mujoco
    model = ci.RobotModel.from_urdf(_named(tmp_path, "joint'1", link1="link'1"))
    res = ci.identify(model, _data(model), method="ols", friction=None)
    out = res.to_mjcf(tmp_path / "robot.xml")
    back = mujoco.MjModel.from_xml_path(str(out))
    assert mujoco.mj_name2id(back, mujoco.mjtObj.mjOBJ_BODY, "link'1") > 0


@pytest.mark.parametrize("key", ["a = b", "x\ny = 1", "[t]", "ok_key"])
def test_toml_keys_that_are_not_bare_are_quoted(key):
    text = f"v = {toml_value({key: 1.5})}"
    assert tomllib.loads(text) == {"v": {key: 1.5}}


# ----------------------------------------------------------------------------- XML
ENTITY = ('<?xml version="1.0"?>\n<!DOCTYPE robot [<!ENTITY n "joint1">]>\n'
          + ARM.split("?>", 1)[1].replace('name="joint1"', 'name="&n;"'))
LAUGHS = ('<?xml version="1.0"?>\n<!DOCTYPE robot [<!ENTITY a "aaaaaaaaaa">'
          + "".join(f'<!ENTITY {c} "{("&" + p + ";") * 10}">'
                    for p, c in zip("abcdefgh", "bcdefghi"))
          + "]>\n" + ARM.split("?>", 1)[1].replace('name="joint1"', 'name="&i;"'))
EXTERNAL = ('<?xml version="1.0"?>\n<!DOCTYPE robot [<!ENTITY x SYSTEM "file:///etc/hostname">]>\n'
            + ARM.split("?>", 1)[1].replace('name="joint1"', 'name="&x;"'))


@pytest.mark.parametrize("text", [ENTITY, LAUGHS, EXTERNAL], ids=["entity", "laughs", "external"])
def test_xml_entities_in_a_urdf_are_refused_by_name(tmp_path, text):
    with pytest.raises(ModelError, match="entities"):
        ci.RobotModel.from_urdf(_arm(tmp_path, text))


def test_a_namespaced_urdf_is_accepted(tmp_path):
    text = ARM.replace('<robot name="planar2r">',
                       '<robot name="planar2r" xmlns="http://www.ros.org" '
                       'xmlns:xacro="http://www.ros.org/wiki/xacro">')
    model = ci.RobotModel.from_urdf(_arm(tmp_path, text), gravity=(0.0, -9.81, 0.0))
    plain = ci.RobotModel.from_urdf(_arm(tmp_path, ARM, "plain.urdf"),
                                    gravity=(0.0, -9.81, 0.0))
    assert model.joint_names == plain.joint_names
    assert np.array_equal(model.prior_parameters, plain.prior_parameters)


# ----------------------------------------------------------------------------- half-writes
def test_an_interrupted_save_leaves_the_old_files_whole(saved, tmp_path, monkeypatch):
    res = ci.IdentificationResult.load(saved[0])
    json_path, csv_path = res.save(tmp_path / "r.json"), res.to_csv(tmp_path / "p.csv")
    old_json, old_csv = json_path.read_bytes(), csv_path.read_bytes()
    real_write = Path.write_text

    def half_then_interrupt(self, text, *args, **kwargs):
        real_write(self, text[: len(text) // 2], *args, **kwargs)
        raise KeyboardInterrupt

    monkeypatch.setattr(Path, "write_text", half_then_interrupt)
    with pytest.raises(KeyboardInterrupt):
        res.save(json_path)
    monkeypatch.undo()
    rows = []

    class Writer:
        def __init__(self, fh):
            self.fh = fh

        def writerow(self, row):
            rows.append(row)
            self.fh.write(",".join(map(str, row)) + "\n")
            if len(rows) == 3:
                raise KeyboardInterrupt

    monkeypatch.setattr(persistence.csv, "writer", Writer)
    with pytest.raises(KeyboardInterrupt):
        res.to_csv(csv_path)
    assert json_path.read_bytes() == old_json and csv_path.read_bytes() == old_csv
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.csv", "r.json"]

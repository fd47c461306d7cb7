"""The schema of a saved identification result, checked before anything is built from it.

A result file is data written by a program, read back perhaps after a copy, an edit or an
attack: every field is checked for its type, shape, size and finiteness (and the armature for
its sign) before :mod:`consistid.identification.persistence` builds a robot, a base map or a
covariance from it, so that a tampered file gives one :class:`~consistid.errors.ResultFileError`
naming the file and the field, never a raw ``KeyError``/``TypeError``/``RecursionError``, a
huge allocation or a hang.

Limits (a saved result is far below each: a 500-link robot's is a few MB):
:data:`MAX_BYTES` for the file, :data:`MAX_DEPTH` for the nesting of JSON values,
:data:`MAX_TEXT` for one string (the stored URDF) and :data:`MAX_NAME` for a name.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..errors import ResultFileError
from ..robot.joint_terms import JOINT_TERMS

__all__ = ["MAX_BYTES", "MAX_DEPTH", "MAX_TEXT", "MAX_NAME", "read_document",
           "check_document", "check_dtype", "check_model"]

MAX_BYTES = 256 * 2**20
MAX_DEPTH = 64
MAX_TEXT = 64 * 2**20
MAX_NAME = 1000
#: The largest gravity a saved robot may have (m/s²): beyond any unit slip (mm/s² gives
#: 9 810, which a model warns about but builds), far below what overflows a torque.
MAX_GRAVITY = 1e6
#: Fields every result has, which a kind's ``extra`` fields may not replace.
CORE_FIELDS = frozenset({"method", "model", "spec", "base", "parameters", "parameter_names",
                         "prior", "base_parameters", "base_covariance", "sigma",
                         "condition_number", "train_rms", "n_samples", "solver"})
#: numpy kinds an ``__ndarray__`` may have: bool, integers, floats (no strings, objects, voids).
DTYPE_KINDS = "biuf"


def read_document(path: Path, where: str) -> Any:
    """The JSON document at ``path``, within the size and nesting limits."""
    if path.is_dir():
        raise ResultFileError(f"result file {where!r} is a folder; give the result.json inside")
    if not path.is_file():
        raise ResultFileError(f"result file {where!r} does not exist")
    size = path.stat().st_size
    if size > MAX_BYTES:
        raise ResultFileError(f"{where} holds {size / 2**20:.0f} MB, more than a result file "
                              f"can ({MAX_BYTES / 2**20:.0f} MB): not a consistid result")
    try:
        doc = json.loads(path.read_bytes().decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise ResultFileError(f"{where} is not a JSON file (not UTF-8: {exc})") from exc
    except RecursionError as exc:
        raise ResultFileError(f"{where}: JSON nested deeper than {MAX_DEPTH} levels; not a "
                              "consistid result") from exc
    except ValueError as exc:                   # JSONDecodeError, an integer of 5000 digits
        raise ResultFileError(f"{where} is not a JSON file: {exc}") from exc
    _check_tree(doc, where)
    return doc


def _check_tree(doc: Any, where: str) -> None:
    """Nesting depth and string lengths of every value (iteratively: no recursion limit)."""
    stack = [(doc, 1, "")]
    while stack:
        value, depth, key = stack.pop()
        if depth > MAX_DEPTH:
            raise ResultFileError(f"{where}: field {key or 'top'!r} is nested deeper than "
                                  f"{MAX_DEPTH} levels; not a consistid result")
        if isinstance(value, str) and len(value) > MAX_TEXT:
            raise ResultFileError(f"{where}: a string in field {key!r} holds {len(value)} "
                                  f"characters, more than {MAX_TEXT}")
        elif isinstance(value, dict):
            for k, v in value.items():
                if len(k) > MAX_NAME:
                    raise ResultFileError(f"{where}: a key in field {key!r} holds {len(k)} "
                                          f"characters, more than {MAX_NAME}")
                stack.append((v, depth + 1, key or k))
        elif isinstance(value, list):
            stack.extend((v, depth + 1, key) for v in value)


def check_dtype(dtype: Any, where: str) -> np.dtype:
    """A numeric numpy dtype of at most 16 bytes an item, else :class:`ResultFileError` (a
    string or void dtype of a billion characters would allocate gigabytes)."""
    try:
        out = np.dtype(dtype)
    except (TypeError, ValueError) as exc:
        raise ResultFileError(f"{where}: dtype {dtype!r:.60} is not a numpy dtype") from exc
    if out.kind not in DTYPE_KINDS or out.itemsize > 16:
        raise ResultFileError(f"{where}: dtype {dtype!r:.60} is not a numeric dtype; result "
                              "files hold arrays of booleans, integers and floats")
    return out


# ----------------------------------------------------------------------------- fields
def _get(doc: Mapping[str, Any], key: str, where: str, kind: type | tuple) -> Any:
    if not isinstance(doc, dict):
        raise ResultFileError(f"{where}: expected a table holding {key!r}, got "
                              f"{type(doc).__name__}")
    if key not in doc:
        raise ResultFileError(f"{where}: field {key!r} is missing")
    value = doc[key]
    kinds = kind if isinstance(kind, tuple) else (kind,)
    if not isinstance(value, kinds) or isinstance(value, bool) and bool not in kinds:
        names = " or ".join(k.__name__ for k in kinds)
        raise ResultFileError(f"{where}: field {key!r} must be {names}, got "
                              f"{type(value).__name__}")
    return value


def _names(doc: Mapping[str, Any], key: str, where: str, n: int | None = None) -> list[str]:
    value = _get(doc, key, where, list)
    for k, name in enumerate(value):
        if not isinstance(name, str) or not 0 < len(name) <= MAX_NAME \
                or any(ord(c) < 32 or ord(c) == 127 for c in name):
            raise ResultFileError(f"{where}: field {key!r}[{k}] is not a name (a string of 1 to "
                                  f"{MAX_NAME} printable characters): {name!r:.80}")
    if n is not None and len(value) != n:
        raise ResultFileError(f"{where}: field {key!r} holds {len(value)} names, expected {n}")
    return value


def _number(value: Any) -> float | None:
    """A JSON number or a tagged non-finite one (``{"__float__": "inf"}``), else ``None``."""
    if isinstance(value, dict) and set(value) == {"__float__"} \
            and value["__float__"] in ("inf", "-inf", "nan"):
        return float(value["__float__"])
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        try:
            return float(value)
        except OverflowError:
            return None
    return None


def _numbers(doc: Mapping[str, Any], key: str, where: str, shape: tuple[int, ...], *,
             nan: bool = False, inf: bool = False, minimum: float | None = None) -> None:
    """Field ``key`` is nested lists of ``shape`` numbers (tagged non-finite ones only where
    allowed), each ``≥ minimum`` when given."""
    value = _get(doc, key, where, list)
    rows = [value]
    for depth, size in enumerate(shape):
        for row in rows:
            if not isinstance(row, list) or len(row) != size:
                got = len(row) if isinstance(row, list) else type(row).__name__
                raise ResultFileError(f"{where}: field {key!r} has shape other than {shape}: "
                                      f"level {depth + 1} holds {got}, expected {size}")
        rows = [v for row in rows for v in row]
    for k, v in enumerate(rows):
        x = _number(v)
        bad = (x is None or math.isnan(x) and not nan or math.isinf(x) and not inf
               or minimum is not None and x < minimum)
        if bad:
            index = np.unravel_index(k, shape) if shape else ()
            need = "a number" + ("" if minimum is None else f" ≥ {minimum:g}")
            raise ResultFileError(f"{where}: field {key!r}{list(map(int, index))} is {v!r:.60}, "
                                  f"expected {need}" + ("" if nan or inf else " (finite)"))


def _indices(doc: Mapping[str, Any], key: str, where: str, p: int) -> list[int]:
    value = _get(doc, key, where, list)
    if any(not isinstance(i, int) or isinstance(i, bool) or not 0 <= i < p for i in value) \
            or len(set(value)) != len(value):
        raise ResultFileError(f"{where}: field {key!r} must list distinct parameter indices "
                              f"0 … {p - 1}")
    return value


def check_document(doc: Mapping[str, Any], where: str) -> None:
    """Every field :func:`~consistid.identification.persistence.read_result_fields` uses has
    its type, shape, finiteness and sign (module docstring); else :class:`ResultFileError`
    naming the field."""
    names = _names(doc, "parameter_names", where)
    p = len(names)
    _get(doc, "method", where, str)
    for key in ("parameters", "prior"):
        _numbers(doc, key, where, (p,))
    check_model(_get(doc, "model", where, dict), f"{where} [model]")
    model = doc["model"]
    nv = len(model["joint_names"])
    spec = _get(doc, "spec", where, dict)
    if _get(spec, "nv", f"{where} [spec]", int) != nv:
        raise ResultFileError(f"{where} [spec]: field 'nv' is {spec['nv']}, but the model has "
                              f"{nv} joints")
    for term, mask in _get(spec, "masks", f"{where} [spec]", dict).items():
        if term not in JOINT_TERMS:
            raise ResultFileError(f"{where} [spec]: masks[{term!r:.60}] is not a joint term "
                                  f"(known: {', '.join(JOINT_TERMS)})")
        if not isinstance(mask, list) or len(mask) != nv \
                or not all(isinstance(v, bool) for v in mask):
            raise ResultFileError(f"{where} [spec]: masks[{term!r}] must be {nv} booleans")
    _check_base(_get(doc, "base", where, dict), f"{where} [base]", p)
    # a joint whose torque rows were left out (exclude_joints=) has no σ and no RMS: NaN
    excluded = _excluded(doc, where, model["joint_names"])
    for key in ("sigma", "train_rms"):
        _numbers(doc, key, where, (nv,), minimum=0.0, nan=bool(excluded))
        for j, v in enumerate(doc[key]):
            if math.isnan(_number(v)) and model["joint_names"][j] not in excluded:
                raise ResultFileError(f"{where}: field {key!r}[{j}] is NaN, but joint "
                                      f"{model['joint_names'][j]!r} is not excluded (only an "
                                      "excluded joint has no σ and no RMS)")
    cond = _number(_get(doc, "condition_number", where, (int, float, dict)))
    if cond is None or math.isnan(cond) or cond < 0:
        raise ResultFileError(f"{where}: field 'condition_number' must be a number ≥ 0")
    if _get(doc, "n_samples", where, int) < 0:
        raise ResultFileError(f"{where}: field 'n_samples' must be ≥ 0")
    solver = _get(doc, "solver", where, dict)
    for key in ("name", "status"):
        _get(solver, key, f"{where} [solver]", str)
    for key in ("solve_time", "compile_time"):
        if key in solver or key == "solve_time":
            _numbers({key: [solver.get(key)]}, key, f"{where} [solver]", (1,), inf=True)
    if solver.get("iterations") is not None:
        _get(solver, "iterations", f"{where} [solver]", int)
    for key in ("uninformed", "weakly_informed", "excluded_joints"):
        if key in doc:
            _get(doc, key, where, list)
            if not all(isinstance(v, str) for v in doc[key]):
                raise ResultFileError(f"{where}: field {key!r} must list strings")
    if doc.get("envelope") is not None:
        _check_envelope(_get(doc, "envelope", where, dict), f"{where} [envelope]",
                        model["joint_names"])
    for key, kind in (("details", dict), ("provenance", dict), ("extra", dict), ("kind", str)):
        if key in doc:
            _get(doc, key, where, kind)
    shadowed = sorted(set(doc.get("extra", {})) & CORE_FIELDS)
    if shadowed:
        raise ResultFileError(f"{where}: field 'extra' holds {shadowed}, fields of every result "
                              "that it may not replace")


def _excluded(doc: Mapping[str, Any], where: str, joints: list[str]) -> set[str]:
    """The joints field ``excluded_joints`` names (optional), each a joint of the model."""
    if "excluded_joints" not in doc:
        return set()
    names = _get(doc, "excluded_joints", where, list)
    for name in names:
        if not isinstance(name, str) or name not in joints:
            raise ResultFileError(f"{where}: field 'excluded_joints' names {name!r:.80}, not "
                                  f"a joint of the model ({len(joints)} joints)")
    return set(names)


def _check_envelope(e: Mapping[str, Any], where: str, joints: list[str]) -> None:
    """The training envelope (:class:`~consistid.identification.envelope.TrainingEnvelope`):
    the model's joints, finite ranges and speeds, counts ≥ 0."""
    if _names(e, "joint_names", where) != list(joints):
        raise ResultFileError(f"{where}: field 'joint_names' is not the model's joints")
    if _get(e, "n_samples", where, int) < 0:
        raise ResultFileError(f"{where}: field 'n_samples' must be ≥ 0")
    for key in ("q_min", "q_max"):
        _numbers(e, key, where, (len(joints),))
    for key in ("dq_max", "ddq_max", "positive", "negative"):
        _numbers(e, key, where, (len(joints),), minimum=0.0)


def check_model(m: Mapping[str, Any], where: str) -> None:
    """A saved robot (:func:`~consistid.identification.persistence.model_dict`): names, the
    stored URDF as text, finite inertias, gravity within :data:`MAX_GRAVITY`, armature ≥ 0."""
    _get(m, "name", where, str)
    joints = _names(m, "joint_names", where)
    bodies = _names(m, "body_names", where)
    for key in ("source", "urdf", "urdf_sha256"):
        if m.get(key) is not None:
            _get(m, key, where, str)
    _names(m, "locked_joints", where)
    for k, v in _get(m, "locked_configuration", where, dict).items():
        x = _number(v)
        if x is None or not math.isfinite(x):
            raise ResultFileError(f"{where}: locked_configuration[{k!r}] must be a finite "
                                  "number")
    _numbers(m, "gravity", where, (3,))
    if math.hypot(*(_number(g) for g in m["gravity"])) > MAX_GRAVITY:
        raise ResultFileError(f"{where}: field 'gravity' {m['gravity']} is beyond "
                              f"{MAX_GRAVITY:g} m/s² (the Earth's is 9.81): not a robot's")
    _numbers(m, "inertias", where, (10 * len(bodies),))
    _numbers(m, "armature", where, (len(joints),), minimum=0.0)


def _check_base(b: Mapping[str, Any], where: str, p: int) -> None:
    independent = _indices(b, "independent", where, p)
    dependent = _indices(b, "dependent", where, p)
    if set(independent) & set(dependent):
        raise ResultFileError(f"{where}: a parameter is both independent and dependent")
    ni, nd = len(independent), len(dependent)
    _numbers(b, "K", where, (ni, nd))
    diag_r = _get(b, "diag_r", where, list)     # R's diagonal: one per regressor column
    _numbers(b, "diag_r", where, (min(len(diag_r), p),))
    rtol = _number(_get(b, "rtol", where, (int, float)))
    if rtol is None or not math.isfinite(rtol) or rtol < 0:
        raise ResultFileError(f"{where}: field 'rtol' must be a finite number ≥ 0")
    _numbers(b, "values", where, (ni,))
    # unidentified directions may carry an infinite variance, never a NaN
    _numbers(b, "covariance", where, (ni, ni), inf=True)
    _check_covariance(np.array([[_number(v) for v in row] for row in b["covariance"]]), where)


#: Relative tolerance of a saved covariance's symmetry and correlations (of ``√(C_ii C_jj)``).
COVARIANCE_RTOL = 1e-6


def _check_covariance(cov: np.ndarray, where: str) -> None:
    """A covariance: symmetric, non-negative variances, and no correlation beyond ±1
    (``|C_ij| ≤ √(C_ii C_jj)``, a necessary condition of positive semi-definiteness), each to
    :data:`COVARIANCE_RTOL` of ``√(C_ii C_jj)`` (a sandwich or a nonlinear search's covariance
    is symmetric only to its rounding: 1e-9 relative refused a Panda Stribeck fit's own file)."""
    with np.errstate(invalid="ignore", over="ignore"):
        var = np.diag(cov)
        bad = np.flatnonzero(var < 0)
        if bad.size:
            raise ResultFileError(f"{where}: field 'covariance'[{bad[0]}][{bad[0]}] is "
                                  f"{var[bad[0]]:g}: a variance must be ≥ 0")
        finite = np.isfinite(cov)
        scale = np.sqrt(np.outer(var, var))
        asym = finite & finite.T & (np.abs(cov - cov.T)
                                    > COVARIANCE_RTOL * np.maximum(scale, 1e-300))
        corr = finite & np.isfinite(scale) & (np.abs(cov) > (1 + COVARIANCE_RTOL) * scale
                                                + 1e-300)
    for what, mask in (("is not symmetric", asym), ("holds a correlation beyond ±1 (not a "
                                                    "covariance)", corr)):
        if mask.any():
            i, j = (int(k) for k in np.argwhere(mask)[0])
            raise ResultFileError(f"{where}: field 'covariance' {what} at [{i}][{j}]")

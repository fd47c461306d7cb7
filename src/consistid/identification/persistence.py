"""Identification results on disk: one JSON file that reloads to an equal result, and a CSV table.

The JSON file (``IdentificationResult.save``) is plain, standard JSON (no ``NaN``/``Infinity``
literals, readable by ``jq`` or any language) with these top-level keys:

``format``, ``version``
    ``"consistid.identification-result"`` and :data:`VERSION`; :func:`read_result` refuses
    anything else.
``method``, ``parameter_names``, ``parameters``, ``prior``
    the standard vector (10 per body, then the per-joint terms) and the URDF prior it started
    from.
``base``
    the base-parameter map (``independent``, ``dependent``, ``K``, ``diag_r``, ``rtol``), and for
    a reader: each base parameter's ``names`` (``*`` marks a regrouped one), ``groupings``,
    ``values``, ``std`` and ``covariance``.
``sigma``, ``condition_number``, ``train_rms``, ``n_samples``, ``uninformed``, ``weakly_informed``
    per-joint noise, cond(W_b), training RMS per joint, samples, the base-parameter
    directions the data do not inform and those they inform weakly (optional: files written
    before it have none).
``envelope``
    where the training data went per joint (``q_min``, ``q_max``, ``dq_max``, ``ddq_max``, the
    ``positive``/``negative`` moving-sample counts): optional, ``null`` or absent in a file
    without it, whose ``predict`` then does not warn on extrapolation.
``excluded_joints``
    the joints whose torque rows were left out (optional; none in older files).
``solver``
    the solver report: name, status, times, iterations.
``consistency``
    per body: ``ok``, the violated ``condition`` and ``reason``, mass, the smallest eigenvalue of
    the pseudo-inertia (the margin of density realisability) and the principal moments.
``spec``, ``model``
    the regressor's per-joint columns and the robot: name, gravity, locked joints, the model's
    inertias and armature, the source URDF's path and SHA-256, and the URDF text itself (so the
    file is self-contained: it reloads where the URDF is gone).
``details``
    the method's extra figures (SDP margins, active constraints, prior weight …).
``provenance``
    when and with what it was computed: package versions, platform, the input files (path,
    size, SHA-256; a ROS 2 bag folder: total size and the SHA-256 of its file listing,
    :func:`tree_sha256`) and the run configuration.
``kind``, ``extra``
    which result class wrote it (``"identification"``, or ``"nonlinear_friction"`` for
    :class:`consistid.friction.NonlinearFrictionResult`) and the fields that class adds (its
    friction laws, shape parameters and their σ): ``load`` gives back that class, so its
    ``predict`` equals the original's.

Arrays are nested lists; a value JSON cannot hold is tagged: ``{"__ndarray__": …, "dtype": …}``
for an array inside ``details``, ``{"__float__": "inf"}`` for a non-finite number, ``{"__tuple__":
[…]}``. Floats are written with 17 significant digits (Python's shortest repr), so every number
reloads bit for bit and ``predict`` of the reloaded result equals the original's.
"""

from __future__ import annotations

import csv
import datetime as _dt
import hashlib
import importlib.metadata
import json
import math
import platform
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Mapping

import numpy as np

from ..errors import ModelError, ResultFileError
from ..filesafety import interrupted_files, replacing
from ..textsafety import spreadsheet_cell
from ..robot.export import check_not_source
from ..robot.inertia import is_physically_consistent
from ..robot.model import RobotModel, model_without_dynamics
from .base import BaseParameters
from ..robot.mjcf_in import is_mjcf
from .envelope import TrainingEnvelope
from .regressor import RegressorSpec, parameter_names
from .resultschema import check_document, check_dtype, read_document
from .solver import SolverReport

if TYPE_CHECKING:
    from .result import IdentificationResult

FORMAT = "consistid.identification-result"
VERSION = 1
#: Distributions whose versions go into the provenance (``None`` when not installed).
PACKAGES = ("consistid", "numpy", "scipy", "pin", "cvxpy", "clarabel", "mujoco",
            "example-robot-data", "matplotlib")


# ----------------------------------------------------------------------------- JSON values
def encode(value: Any) -> Any:
    """``value`` as JSON-safe data: arrays, tuples, non-finite floats and numpy scalars tagged
    (module docstring); :class:`ResultFileError` for a value JSON cannot carry."""
    if isinstance(value, np.ndarray):
        return {"__ndarray__": encode(value.tolist()), "dtype": value.dtype.str,
                "shape": list(value.shape)}
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return v if math.isfinite(v) else {"__float__": repr(v)}
    if isinstance(value, str) or value is None:
        return value
    if isinstance(value, tuple):
        return {"__tuple__": [encode(v) for v in value]}
    if isinstance(value, list):
        return [encode(v) for v in value]
    if isinstance(value, Mapping):
        if all(isinstance(k, str) for k in value):
            return {k: encode(v) for k, v in value.items()}
        return {"__items__": [[encode(k), encode(v)] for k, v in value.items()]}
    if isinstance(value, (_dt.date, _dt.time)):      # TOML dates in a configuration
        return value.isoformat()
    if isinstance(value, Path):
        return str(value)
    raise ResultFileError(f"cannot save a {type(value).__name__} ({value!r:.80}) in a result "
                          "file; details and configurations hold numbers, strings, arrays, "
                          "lists and tables")


def decode(value: Any) -> Any:
    """The inverse of :func:`encode`."""
    if isinstance(value, list):
        return [decode(v) for v in value]
    if not isinstance(value, dict):
        return value
    if "__ndarray__" in value:
        return np.array(decode(value["__ndarray__"]),
                        dtype=check_dtype(value["dtype"], "__ndarray__")).reshape(value["shape"])
    if "__float__" in value:
        return float(value["__float__"])
    if "__tuple__" in value:
        return tuple(decode(v) for v in value["__tuple__"])
    if "__items__" in value:
        return {_hashable(decode(k)): decode(v) for k, v in value["__items__"]}
    return {k: decode(v) for k, v in value.items()}


def _hashable(value: Any) -> Any:
    return tuple(_hashable(v) for v in value) if isinstance(value, list) else value


def _floats(values: np.ndarray) -> Any:
    """A float array as nested lists, non-finite entries tagged."""
    return encode(np.asarray(values, dtype=float).tolist())


# ----------------------------------------------------------------------------- provenance
def sha256(path: str | Path) -> str:
    """The SHA-256 of a file's bytes (hex)."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def package_versions() -> dict[str, str | None]:
    """Installed versions of :data:`PACKAGES` and of Python."""
    out: dict[str, str | None] = {"python": platform.python_version()}
    for name in PACKAGES:
        try:
            out[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            out[name] = None
    return out


def check_input(path: str | Path) -> Path:
    """``path`` resolved, if it can be recorded as an input: a file, or a folder (a ROS 2 bag
    folder: ``metadata.yaml`` and its storage files); else :class:`ResultFileError`."""
    p = Path(path).expanduser().resolve()
    if not (p.is_file() or p.is_dir()):
        raise ResultFileError(f"provenance input {str(path)!r} is not a file nor a folder (it "
                              "does not exist)")
    return p


def tree_sha256(folder: Path) -> tuple[int, str]:
    """``(bytes, SHA-256)`` of a folder: the SHA-256 of the lines ``<relative path> <SHA-256
    of its bytes>`` of every file under it, sorted by path (the files' contents and names, not
    their times), and the sum of their sizes."""
    files = sorted(f for f in folder.rglob("*") if f.is_file())
    listing = "".join(f"{f.relative_to(folder).as_posix()} {sha256(f)}\n" for f in files)
    return (sum(f.stat().st_size for f in files),
            hashlib.sha256(listing.encode("utf-8")).hexdigest())


def input_record(path: str | Path) -> dict[str, Any]:
    """``{"path", "bytes", "sha256"}`` of an input file, or of a folder (a ROS 2 bag folder:
    the total size and :func:`tree_sha256`, and ``"folder": True``); :class:`ResultFileError`
    if it is neither."""
    p = check_input(path)
    if p.is_dir():
        size, digest = tree_sha256(p)
        return {"path": str(p), "bytes": size, "sha256": digest, "folder": True}
    return {"path": str(p), "bytes": p.stat().st_size, "sha256": sha256(p)}


def make_provenance(previous: Mapping[str, Any] | None = None,
                    inputs: Iterable[str | Path] = (),
                    config: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Provenance of a result: ``created`` (UTC), ``packages``, ``platform``, ``inputs`` and
    ``config``. What ``previous`` already records (a reloaded result: the run that computed it)
    is kept; ``inputs`` and ``config`` are added to it."""
    out: dict[str, Any] = dict(previous or {})
    out.setdefault("created", _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"))
    out.setdefault("packages", package_versions())
    out.setdefault("platform", platform.platform())
    records = [dict(r) for r in out.get("inputs", [])]
    known = {r["path"] for r in records}
    for path in inputs:
        record = input_record(path)
        if record["path"] not in known:
            records.append(record)
            known.add(record["path"])
    out["inputs"] = records
    if config is not None:
        out["config"] = decode(encode(dict(config)))
    return out


# ----------------------------------------------------------------------------- pieces
def model_dict(model: RobotModel) -> dict[str, Any]:
    """What it takes to rebuild ``model``: the source URDF (path, SHA-256 and text), locks,
    gravity, and the inertias and armature it carries (which may differ from the URDF's)."""
    source = Path(model.source).resolve() if model.source is not None else None
    text = source.read_text(encoding="utf-8") if source is not None and source.is_file() \
        else None
    record = {"source": None if source is None else str(source),
              "urdf_sha256": None if text is None else sha256(source), "urdf": text}
    if source is None and model.urdf_record is not None:     # a reloaded result's, as read
        record = dict(model.urdf_record)
    return {"name": model.name, **record,
            "locked_joints": list(model.locked_joints),
            "locked_configuration": {k: float(v) for k, v in model.locked_configuration.items()},
            "gravity": _floats(model.gravity),
            "joint_names": list(model.joint_names),
            "body_names": list(model.body_names),
            "inertias": _floats(model.prior_parameters),
            "armature": _floats(model.pin_model.armature)}


def _rebuild(m: Mapping[str, Any], urdf: Path, source: Path | None) -> RobotModel:
    options = dict(locked_joints=m["locked_joints"],
                   locked_configuration=m["locked_configuration"], gravity=m["gravity"],
                   name=m["name"])
    if is_mjcf(urdf):                       # a model read by RobotModel.from_mjcf
        try:
            built = RobotModel.from_mjcf(urdf, **options)
        except ModelError as exc:
            if source is not None:
                raise
            raise ModelError(f"the model was read from the MJCF {m.get('source')}, whose text is "
                             f"stored without the files it refers to (meshes): {exc}; load with "
                             "urdf='path/to/robot.xml' (the MJCF) or model=") from exc
        return RobotModel(built.pin_model, name=built.name, source=source,
                          locked_joints=built.locked_joints,
                          locked_configuration=built.locked_configuration)
    try:
        built = RobotModel.from_urdf(urdf, **options)
    except ModelError:                      # e.g. negative <dynamics>, which Pinocchio refuses
        built = model_without_dynamics(urdf, **options)[0]
    return RobotModel(built.pin_model, name=built.name, source=source,
                      locked_joints=built.locked_joints,
                      locked_configuration=built.locked_configuration)


def model_from_dict(m: Mapping[str, Any], where: str, model: RobotModel | None = None,
                    urdf: str | Path | None = None, follow_source: bool = False) -> RobotModel:
    """The robot of :func:`model_dict`. Order of preference: ``model`` as given (its joints and
    bodies must match), ``urdf``, the saved source path when ``follow_source`` and its SHA-256
    still matches, else the URDF text stored in the file (the model then has no ``source``:
    pass ``urdf=`` to export it). The saved inertias, armature and gravity are applied.

    A result file is data: the path it names is opened only when the caller asks
    (``follow_source=True``), never because the file says so."""
    if model is None:
        if urdf is not None:
            model = _rebuild(m, Path(urdf), Path(urdf))
        elif follow_source and m.get("source") and Path(m["source"]).is_file() \
                and sha256(m["source"]) == m.get("urdf_sha256"):
            model = _rebuild(m, Path(m["source"]), Path(m["source"]))
        elif m.get("urdf"):
            with tempfile.TemporaryDirectory(prefix="consistid-result-") as tmp:
                path = Path(tmp) / "robot.urdf"
                path.write_text(m["urdf"], encoding="utf-8")
                model = _rebuild(m, path, None)
        else:
            raise ResultFileError(f"{where}: the model's URDF is not stored in the file; pass "
                                  "model= or urdf= to load() (or follow_source=True to use "
                                  f"{m.get('source')!r}, the path it names)")
    for key, have in (("joint_names", model.joint_names), ("body_names", model.body_names)):
        if list(have) != list(m[key]):
            raise ResultFileError(f"{where}: the model's {key} {list(have)} differ from the "
                                  f"saved ones {list(m[key])}; load with the robot it was "
                                  "identified on")
    inertias = np.asarray(decode(m["inertias"]), dtype=float)
    if not np.array_equal(inertias, model.prior_parameters):
        model = model.with_parameters(inertias)
    gravity = np.asarray(decode(m["gravity"]), dtype=float)
    armature = np.asarray(decode(m["armature"]), dtype=float)
    if not np.array_equal(gravity, model.gravity) or not np.array_equal(
            armature, model.pin_model.armature):
        pm = model.pin_model.copy()
        pm.gravity.linear = gravity
        pm.armature = armature
        model = RobotModel(pm, name=model.name, source=model.source,
                           locked_joints=model.locked_joints,
                           locked_configuration=model.locked_configuration)
    if model.source is None:
        model.urdf_record = {key: m.get(key) for key in ("source", "urdf_sha256", "urdf")}
    return model


def spec_dict(spec: RegressorSpec) -> dict[str, Any]:
    return {"nv": spec.nv, "masks": {term: list(mask) for term, mask in spec.masks}}


def spec_from_dict(s: Mapping[str, Any]) -> RegressorSpec:
    return RegressorSpec(int(s["nv"]), tuple((term, tuple(bool(v) for v in mask))
                                             for term, mask in s["masks"].items()))


def base_dict(res: "IdentificationResult") -> dict[str, Any]:
    base = res.base
    return {"independent": base.independent.tolist(), "dependent": base.dependent.tolist(),
            "K": _floats(base.K), "diag_r": _floats(base.diag_r), "rtol": base.rtol,
            "names": base.names, "groupings": base.groupings,
            "values": _floats(res.base_parameters), "std": _floats(res.base_std),
            "covariance": _floats(res.base_covariance)}


def base_from_dict(b: Mapping[str, Any], names: tuple[str, ...]) -> BaseParameters:
    K = np.asarray(decode(b["K"]), dtype=float).reshape(len(b["independent"]),
                                                        len(b["dependent"]))
    return BaseParameters(tuple(names), np.asarray(b["independent"], dtype=int),
                          np.asarray(b["dependent"], dtype=int), K,
                          np.asarray(decode(b["diag_r"]), dtype=float), float(b["rtol"]))


def consistency_dict(res: "IdentificationResult") -> dict[str, Any]:
    cons = res.consistency
    return {"level": cons.level, "ok": cons.ok, "bodies": [
        {"body": b.body, "ok": b.ok, "condition": b.condition, "reason": b.reason,
         "mass": encode(b.mass), "min_pseudo_inertia_eigenvalue":
             encode(b.min_pseudo_inertia_eigenvalue),
         "principal_moments": None if b.principal_moments is None
         else _floats(b.principal_moments)} for b in cons.bodies]}


# ----------------------------------------------------------------------------- whole results
def result_dict(res: "IdentificationResult") -> dict[str, Any]:
    """The JSON document of a result (module docstring)."""
    s = res.solver
    return {
        "format": FORMAT, "version": VERSION, "method": res.method,
        "parameter_names": list(res.parameter_names), "parameters": _floats(res.parameters),
        "prior": _floats(res.prior), "base": base_dict(res), "sigma": _floats(res.sigma),
        "condition_number": encode(res.condition_number), "train_rms": _floats(res.train_rms),
        "n_samples": int(res.n_samples),
        "solver": {"name": s.name, "status": s.status, "solve_time": s.solve_time,
                   "compile_time": s.compile_time, "iterations": s.iterations},
        "uninformed": list(getattr(res, "uninformed", ())),
        "weakly_informed": list(getattr(res, "weakly_informed", ())),
        "excluded_joints": list(getattr(res, "excluded_joints", ())),
        "envelope": None if getattr(res, "envelope", None) is None
        else encode(res.envelope.to_dict()),
        "consistency": consistency_dict(res), "spec": spec_dict(res.spec),
        "model": model_dict(res.model), "details": encode(dict(res.details)),
        "provenance": encode(make_provenance(res.provenance)),
        "kind": res.kind, "extra": encode(res.persisted_fields())}


def write_result(res: "IdentificationResult", path: str | Path) -> Path:
    """Write ``res`` as JSON to ``path`` (module docstring); returns the path."""
    path = check_not_source(res.model, path, "save")
    text = json.dumps(result_dict(res), indent=1, allow_nan=False, ensure_ascii=False)
    with replacing(path) as tmp:                # never a half-written result file
        tmp.write_text(text + "\n", encoding="utf-8")
    return path


def _field(doc: Mapping[str, Any], key: str, where: str) -> Any:
    if key not in doc:
        raise ResultFileError(f"{where}: field {key!r} is missing")
    return doc[key]


def _array(doc: Mapping[str, Any], key: str, where: str, shape: tuple[int, ...]) -> np.ndarray:
    value = _field(doc, key, where)
    try:
        out = np.asarray(decode(value), dtype=float)
    except (TypeError, ValueError) as exc:
        raise ResultFileError(f"{where}: field {key!r} is not an array of numbers") from exc
    if out.shape != shape:
        raise ResultFileError(f"{where}: field {key!r} has shape {out.shape}, expected {shape}")
    return out


def _envelope(value: Any, where: str) -> TrainingEnvelope | None:
    """The training envelope of a result file; ``None`` when the file has none (written before
    results kept it, or from a stream)."""
    if value is None:
        return None
    try:
        return TrainingEnvelope.from_dict(decode(value))
    except (KeyError, TypeError, ValueError) as exc:
        raise ResultFileError(f"{where}: field 'envelope' is not a training envelope "
                              f"({exc})") from exc


def read_result_fields(path: str | Path, model: RobotModel | None = None,
                       urdf: str | Path | None = None,
                       follow_source: bool = False) -> dict[str, Any]:
    """The constructor arguments of the result saved at ``path`` (:func:`write_result`), with
    its ``kind`` and the ``extra`` fields of that kind. The whole document is checked
    (:func:`~consistid.identification.resultschema.check_document`) before anything is built;
    the URDF path it names is opened only with ``follow_source=True``.

    Raises
    ------
    ResultFileError : the file is missing, not JSON, not a consistid result of a known
        version, part of a result set whose writing was interrupted, or a field is missing, of
        the wrong type or shape, not finite, too large or too deep (named).
    """
    path = Path(path)
    where = str(path)
    doc = read_document(path, where)
    interrupted = interrupted_files(path.parent)
    if interrupted is not None and (path.name in interrupted or not interrupted):
        raise ResultFileError(f"{where}: the writing of the result set in {str(path.parent)!r} "
                              f"was interrupted ({', '.join(interrupted) or 'files'} being "
                              "replaced): its files may come from two runs; run again with "
                              "--force, or remove the file '.consistid-incomplete' if you know "
                              "the set is whole")
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ResultFileError(f"{where} is not a consistid identification result (format "
                              f"{doc.get('format') if isinstance(doc, dict) else None!r}, "
                              f"expected {FORMAT!r})")
    if doc.get("version") != VERSION:
        raise ResultFileError(f"{where}: result file version {doc.get('version')!r}; this "
                              f"consistid reads version {VERSION}")
    check_document(doc, where)
    names = tuple(_field(doc, "parameter_names", where))
    p = len(names)
    robot = model_from_dict(_field(doc, "model", where), where, model, urdf, follow_source)
    spec = spec_from_dict(_field(doc, "spec", where))
    b = _field(doc, "base", where)
    base = base_from_dict(b, names)
    nb, nv = base.n_base, robot.nv
    _check_agreement(doc, where, robot, spec, base)
    s = _field(doc, "solver", where)
    return dict(
        method=_field(doc, "method", where), model=robot, spec=spec, base=base,
        parameters=_array(doc, "parameters", where, (p,)), parameter_names=names,
        prior=_array(doc, "prior", where, (p,)),
        base_parameters=_array(b, "values", f"{where} [base]", (nb,)),
        base_covariance=_array(b, "covariance", f"{where} [base]", (nb, nb)),
        sigma=_array(doc, "sigma", where, (nv,)),
        condition_number=float(decode(_field(doc, "condition_number", where))),
        train_rms=_array(doc, "train_rms", where, (nv,)),
        n_samples=int(_field(doc, "n_samples", where)),
        solver=SolverReport(s["name"], s["status"], float(s["solve_time"]),
                            float(s.get("compile_time", 0.0)), s.get("iterations")),
        details=_decoded(doc, "details", where), uninformed=tuple(doc.get("uninformed", ())),
        weakly_informed=tuple(doc.get("weakly_informed", ())),
        excluded_joints=tuple(doc.get("excluded_joints", ())),
        envelope=_envelope(doc.get("envelope"), where),
        provenance=_decoded(doc, "provenance", where),
        kind=str(doc.get("kind", "identification")), extra=_decoded(doc, "extra", where))


def _check_agreement(doc: Mapping[str, Any], where: str, robot: RobotModel,
                     spec: RegressorSpec, base: Any) -> None:
    """The fields that restate each other agree: the parameter names are the robot's and the
    spec's (an identification result), and the base values are the base map of the standard
    parameters, ``β = π_I + K π_D`` (to rounding); else :class:`ResultFileError`."""
    names = list(doc["parameter_names"])
    if doc.get("kind", "identification") == "identification" \
            and names != parameter_names(robot, spec):
        raise ResultFileError(f"{where}: field 'parameter_names' is not the list the robot's "
                              f"bodies and the spec's terms give ({len(names)} names)")
    pi = np.array([float(decode(v)) for v in doc["parameters"]])
    beta = np.array([float(decode(v)) for v in doc["base"]["values"]])
    with np.errstate(over="ignore", invalid="ignore"):
        mapped = base.project(pi)
        gap = np.abs(mapped - beta)
        tol = 1e-6 * max(1.0, float(np.max(np.abs(beta), initial=0.0)))
    bad = np.flatnonzero(~(gap <= tol))
    if bad.size:
        k = int(bad[0])
        raise ResultFileError(f"{where}: fields 'parameters' and 'base.values' disagree: base "
                              f"parameter {base.names[k]!r} is {beta[k]:.6g} in the file but "
                              f"{mapped[k]:.6g} from the standard parameters; the file was "
                              "edited or corrupted")
    _check_restated(doc, where, robot, pi)


def _check_restated(doc: Mapping[str, Any], where: str, robot: RobotModel,
                    pi: np.ndarray) -> None:
    """The figures a result file restates for readers agree with those it is rebuilt from:
    ``base.std`` with the covariance's diagonal (``σ = √C_ii``) and ``consistency.ok`` with
    the consistency of the standard parameters (both optional: older files lack them)."""
    b = doc["base"]
    if isinstance(b.get("std"), list):
        cov = np.array([[float(decode(v)) for v in row] for row in b["covariance"]])
        try:
            std = np.array([float(decode(v)) for v in b["std"]])
        except (TypeError, ValueError):
            std = np.array([np.nan])
        with np.errstate(invalid="ignore", over="ignore"):
            ok = std.shape == (len(cov),) and bool(np.all(
                np.isclose(std, np.sqrt(np.diag(cov)), rtol=1e-9, atol=0)
                | (np.isinf(std) & np.isinf(np.diag(cov)))))
        if not ok:
            raise ResultFileError(f"{where}: field 'base.std' is not the square root of the "
                                  "covariance's diagonal; the file was edited or corrupted")
    said = doc.get("consistency", {}).get("ok") if isinstance(doc.get("consistency"), dict) \
        else None
    if isinstance(said, bool):
        try:
            found = is_physically_consistent(pi[:robot.n_inertial], "pseudo-inertia",
                                             robot.body_names).ok
        except np.linalg.LinAlgError as exc:    # numbers no body has (1e300 …)
            raise ResultFileError(f"{where}: field 'parameters' holds values whose inertia "
                                  f"has no eigenvalues ({exc}); the file was edited or "
                                  "corrupted") from exc
        if found != said:
            raise ResultFileError(f"{where}: field 'consistency.ok' is {said} but the standard "
                                  f"parameters are {'' if found else 'not '}physically "
                                  "consistent; the file was edited or corrupted")


def _decoded(doc: Mapping[str, Any], key: str, where: str) -> Any:
    """:func:`decode` of the free-form field ``key``; a malformed tag named."""
    try:
        return decode(doc.get(key, {}))
    except (TypeError, ValueError, KeyError, AttributeError, OverflowError) as exc:
        raise ResultFileError(f"{where}: field {key!r} holds a malformed tagged value "
                              f"({type(exc).__name__}: {exc})") from exc


# ----------------------------------------------------------------------------- CSV
CSV_COLUMNS = ("kind", "name", "value", "std", "relative_std_percent", "prior", "definition")


def write_csv(res: "IdentificationResult", path: str | Path) -> Path:
    """The parameter table as CSV (``CSV_COLUMNS``): one row per base parameter (``kind =
    base``: value ± std, relative std in %, the prior's value, its grouping as ``definition``),
    then one per standard parameter (``kind = standard``: value and prior; ``std`` is empty,
    since only base parameters have a standard deviation from the data), then one per shape
    parameter of a nonlinear friction law (``kind = shape``: value ± std, its unit as
    ``definition``). Numbers carry 17 significant digits; a text cell that a spreadsheet would
    read as a formula is written with a leading ``'`` (:mod:`consistid.textsafety`)."""
    path = check_not_source(res.model, path, "to_csv")
    prior_beta = res.base.project(res.prior)

    def num(x: float) -> str:
        return repr(float(x))

    with replacing(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(CSV_COLUMNS)
        for i, (name, grouping) in enumerate(zip(res.base.names, res.base.groupings)):
            w.writerow(["base", spreadsheet_cell(name), num(res.base_parameters[i]),
                        num(res.base_std[i]), num(res.relative_std[i]), num(prior_beta[i]),
                        spreadsheet_cell(grouping)])
        for name, value, prior in zip(res.parameter_names, res.parameters, res.prior):
            w.writerow(["standard", spreadsheet_cell(name), num(value), "", "", num(prior), ""])
        for name, value, std, unit in res.shape_rows():
            w.writerow(["shape", spreadsheet_cell(name), num(value), num(std),
                        num(100 * std / abs(value)) if value else "", "",
                        spreadsheet_cell(unit)])
    return path

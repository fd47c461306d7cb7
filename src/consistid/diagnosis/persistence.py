"""A diagnosis on disk: one plain JSON file that reloads to a diagnosis with the same tables,
verdict, report and corrected model (``Diagnosis.save`` / ``Diagnosis.load``).

The file holds ``format`` (``"consistid.diagnosis"``), ``version`` (:data:`VERSION`) and
``diagnosis``: the :class:`~consistid.diagnosis.diagnose.Diagnosis` written field by field. A
dataclass of :mod:`consistid.diagnosis` is ``{"__dataclass__": "module:Class", fields…}``
(only classes under ``consistid.diagnosis`` are rebuilt); the robot is written as an
identification result writes it (:func:`consistid.identification.persistence.model_dict`:
URDF path, SHA-256 and text, inertias, gravity), the effect library as its effect names and
ripple orders (its base parameters are recomputed from the robot); arrays, tuples, dicts with
non-string keys and non-finite numbers are tagged as in
:mod:`consistid.identification.persistence`, every float written with 17 significant digits,
so the reloaded corrected model predicts the same torques bit for bit.
"""

from __future__ import annotations

import dataclasses
import importlib
import json
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ResultFileError
from ..filesafety import replacing
from ..textsafety import check_writable_name
from ..identification.persistence import decode, encode, model_dict, model_from_dict
from ..identification.resultschema import check_model, read_document
from ..robot.model import RobotModel
from .candidates import EffectLibrary

FORMAT = "consistid.diagnosis"
VERSION = 1
#: The modules whose dataclasses a diagnosis file may rebuild: the diagnosis' own, and the
#: rollout validation it may carry (:meth:`~consistid.diagnosis.diagnose.Diagnosis.with_rollout`).
REBUILT = ("consistid.diagnosis.", "consistid.simulator.rollout")
_MODEL, _LIBRARY, _CLASS = "__robot__", "__effect_library__", "__dataclass__"


def to_plain(value: Any) -> Any:
    """``value`` with dataclasses, robots and effect libraries as tagged dicts (module
    docstring); arrays and the rest are left to :func:`encode`."""
    if isinstance(value, RobotModel):
        return {_MODEL: model_dict(value)}
    if isinstance(value, EffectLibrary):
        return {_LIBRARY: {"model": to_plain(value.model), "effects": list(value.effects),
                           "ripple_orders": list(value.ripple_orders)}}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        cls = type(value)
        out = {_CLASS: f"{cls.__module__}:{cls.__qualname__}"}
        out.update({f.name: to_plain(getattr(value, f.name)) for f in dataclasses.fields(value)
                    if f.init})
        return out
    if isinstance(value, tuple):
        return tuple(to_plain(v) for v in value)
    if isinstance(value, list):
        return [to_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: to_plain(v) for k, v in value.items()}
    return value


def _class(path: str, where: str) -> type:
    module, _, name = path.partition(":")
    if not module.startswith(REBUILT):
        raise ResultFileError(f"{where}: class {path!r} is not a consistid.diagnosis class (nor "
                              "a rollout validation it carries)")
    try:
        cls = importlib.import_module(module)
    except ImportError:
        raise ResultFileError(f"{where}: class {path!r:.80} names no module of consistid's "
                              "diagnosis") from None
    for part in name.split("."):
        cls = getattr(cls, part, None)
    if not (isinstance(cls, type) and dataclasses.is_dataclass(cls)):
        raise ResultFileError(f"{where}: {path!r} names no diagnosis dataclass")
    return cls


def from_plain(value: Any, where: str, models: dict[str, RobotModel]) -> Any:
    """The inverse of :func:`to_plain` after :func:`decode`; one robot per saved URDF text
    (``models`` caches them, so the diagnosis' parts share it as the original's did)."""
    if isinstance(value, dict):
        if _MODEL in value:
            key = json.dumps(value[_MODEL], sort_keys=True, default=str)
            if key not in models:
                check_model(value[_MODEL], f"{where} [robot]")
                models[key] = model_from_dict(value[_MODEL], where)
            return models[key]
        if _LIBRARY in value:
            lib = value[_LIBRARY]
            return EffectLibrary(from_plain(lib["model"], where, models), tuple(lib["effects"]),
                                 ripple_orders=tuple(lib["ripple_orders"]))
        if _CLASS in value:
            cls = _class(value[_CLASS], where)
            fields = {k: from_plain(v, where, models) for k, v in value.items() if k != _CLASS}
            return cls(**fields)
        return {k: from_plain(v, where, models) for k, v in value.items()}
    if isinstance(value, tuple):
        return tuple(from_plain(v, where, models) for v in value)
    if isinstance(value, list):
        return [from_plain(v, where, models) for v in value]
    return value


def write_diagnosis(diagnosis: Any, path: str | Path) -> Path:
    """Write ``diagnosis`` as JSON at ``path`` (module docstring); returns the path."""
    path = Path(path)
    doc = {"format": FORMAT, "version": VERSION, "diagnosis": encode(to_plain(diagnosis))}
    text = json.dumps(doc, allow_nan=False)
    with replacing(path) as tmp:                # never a half-written diagnosis file
        tmp.write_text(text, encoding="utf-8")
    return path


def read_diagnosis(path: str | Path, cls: type | None = None) -> Any:
    """The diagnosis written by :func:`write_diagnosis` (an instance of ``cls`` when given);
    :class:`ResultFileError` for a file that is not one: not JSON, beyond the size and nesting
    limits of a result file (:func:`~consistid.identification.resultschema.read_document`), or
    a field missing, unknown or of another type or shape (named)."""
    path = Path(path)
    where = path.name
    doc = read_document(path, where)
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ResultFileError(f"{where}: not a consistid diagnosis file (format "
                              f"{doc.get('format') if isinstance(doc, dict) else None!r})")
    if doc.get("version") != VERSION:
        raise ResultFileError(f"{where}: diagnosis file version {doc.get('version')!r}; this "
                              f"consistid reads version {VERSION}")
    try:
        out = from_plain(decode(doc["diagnosis"]), where, {})
    except (TypeError, ValueError, KeyError, AttributeError) as exc:
        raise ResultFileError(f"{where}: a field of the diagnosis is missing, unknown or "
                              f"malformed ({type(exc).__name__}: {exc})") from exc
    if cls is not None:
        _check_diagnosis(out, cls, where)
        _check_fit(out.fit, where)
        _check_breakdown(out.where, len(out.joint_names), where)
        try:
            out.summary()
        except (TypeError, ValueError, KeyError, IndexError, AttributeError) as exc:
            raise ResultFileError(f"{where}: the diagnosis' tables do not fit together "
                                  f"({type(exc).__name__}: {exc})") from exc
    return out


#: The per-joint arrays of a diagnosis (``None`` allowed for the optional ones).
JOINT_ARRAYS = ("noise_floor", "rms_nominal", "rms_final", "library_floor", "rms_left",
                "held_floor")


def _check_diagnosis(out: Any, cls: type, where: str) -> None:
    """``out`` is a ``cls`` whose per-joint arrays (:data:`JOINT_ARRAYS`) hold one number per
    joint."""
    if not isinstance(out, cls):
        raise ResultFileError(f"{where}: field 'diagnosis' holds a {type(out).__name__}, not "
                              f"a {cls.__name__}")
    nv = len(out.joint_names) if isinstance(out.joint_names, (tuple, list)) else -1
    for k, name in enumerate(out.joint_names if nv > 0 else ()):
        check_writable_name(name, f"{where}: field 'joint_names'[{k}]", ResultFileError)
    for name in JOINT_ARRAYS:
        value = getattr(out, name)
        if value is None and name in ("rms_left", "held_floor"):
            continue
        a = np.asarray(value)
        if a.dtype.kind not in "biuf" or a.shape != (nv,):
            raise ResultFileError(f"{where}: field {name!r} must hold one number per joint "
                                  f"({nv}), got {a.dtype} of shape {a.shape}")
        ok = a >= 0                             # an RMS or a floor: NaN and < 0 refused,
        if name == "rms_left":                  # but an RMS over no judged sample is NaN
            ok |= np.isnan(a)
        if not np.all(ok):
            j = int(np.flatnonzero(~ok)[0])
            raise ResultFileError(f"{where}: field {name!r}[{j}] is {a[j]:g}; an RMS or noise "
                                  "floor is a number ≥ 0")


#: The per-joint tables of the gap breakdown (``Diagnosis.where``): field → the field whose
#: length gives its rows (``None``: one row per joint only).
BREAKDOWN = {"rms": None, "share": None, "relative": None, "drift": None, "drift_std": None,
             "noise_floor": None, "regime_fraction": "regimes", "regime_rms": "regimes",
             "regime_mean": "regimes", "band_rms": "band_edges", "psd": "freqs",
             "window_mean": "window_t", "residual_sample": "velocity"}


def _check_breakdown(where_: Any, nv: int, where: str) -> None:
    """Every table of the gap breakdown has one column per joint and the rows its axis gives
    (one band fewer than ``band_edges``), as the report and plots read them."""
    for name, axis in BREAKDOWN.items():
        a = np.asarray(getattr(where_, name, None))
        if axis is None:
            expected: tuple[int, ...] = (nv,)
        else:
            rows = len(np.atleast_1d(np.asarray(getattr(where_, axis, ()), dtype=object)))
            expected = (rows - (axis == "band_edges"), nv)
        if a.dtype.kind not in "biuf" or a.shape != expected:
            raise ResultFileError(f"{where}: field 'where.{name}' must be numbers of shape "
                                  f"{expected}, got {a.dtype} of shape {a.shape}")


def _check_fit(fit: Any, where: str) -> None:
    """The corrected model: a 10-per-body finite nominal vector, one finite parameter array
    per selected atom (``theta``), delays on atoms that exist, and a prediction of finite
    torques at rest (every array's shape exercised)."""
    from ..data.dataset import Dataset

    model = getattr(fit, "model", None)
    if not isinstance(model, RobotModel) or not isinstance(fit.atoms, tuple) \
            or not isinstance(fit.theta, tuple) or not isinstance(fit.delays, dict):
        raise ResultFileError(f"{where}: field 'fit' is not a corrected model (robot, atoms, "
                              "theta, delays)")
    nominal = np.asarray(fit.nominal)
    if nominal.dtype.kind not in "biuf" or nominal.shape != (10 * len(model.body_names),) \
            or not np.all(np.isfinite(nominal)):
        raise ResultFileError(f"{where}: field 'fit.nominal' must hold 10 finite numbers per "
                              f"body ({10 * len(model.body_names)}), got shape {nominal.shape}")
    if len(fit.theta) != len(fit.atoms) or not all(
            np.asarray(th).dtype.kind in "biuf" and np.all(np.isfinite(th)) for th in fit.theta):
        raise ResultFileError(f"{where}: field 'fit.theta' must hold one finite parameter "
                              f"array per atom ({len(fit.atoms)})")
    inertial = fit.inertial
    if inertial is not None and (np.shape(inertial) != nominal.shape
                                 or not np.all(np.isfinite(np.asarray(inertial, dtype=float)))):
        raise ResultFileError(f"{where}: field 'fit.inertial' must be None or 10 finite numbers "
                              f"per body ({nominal.size})")
    orders = fit.library.ripple_orders
    if not all(isinstance(k, int) and not isinstance(k, bool) and k >= 1 for k in orders):
        raise ResultFileError(f"{where}: field 'ripple_orders' {list(orders)!r:.80} must list "
                              "whole numbers ≥ 1")
    if any(not isinstance(i, int) or not 0 <= i < len(fit.atoms) for i in fit.delays):
        raise ResultFileError(f"{where}: field 'fit.delays' names atoms that do not exist")
    z = np.zeros((3, model.nv))
    try:
        tau = fit.predict(Dataset(t=np.arange(3.0), q=z, dq=z, ddq=z, tau=z))
    except (TypeError, ValueError, KeyError, IndexError, AttributeError) as exc:
        raise ResultFileError(f"{where}: the corrected model's fields do not fit together "
                              f"({type(exc).__name__}: {exc})") from exc
    if np.shape(tau) != z.shape or not np.all(np.isfinite(tau)):
        raise ResultFileError(f"{where}: the corrected model predicts non-finite torques")

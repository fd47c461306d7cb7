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
from ..identification.persistence import decode, encode, model_dict, model_from_dict
from ..identification.resultschema import read_document
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
    cls = importlib.import_module(module)
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
    for name in JOINT_ARRAYS:
        value = getattr(out, name)
        if value is None and name in ("rms_left", "held_floor"):
            continue
        a = np.asarray(value)
        if a.dtype.kind not in "biuf" or a.shape != (nv,):
            raise ResultFileError(f"{where}: field {name!r} must hold one number per joint "
                                  f"({nv}), got {a.dtype} of shape {a.shape}")

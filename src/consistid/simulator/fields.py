"""Checked fields of a saved simulator result (a rollout validation, a calibration): each reader
names the file and the field of a value that is missing or of another type, shape or sign, with
a :class:`~consistid.errors.ResultFileError`, never a raw ``KeyError`` or ``TypeError``."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import ResultFileError


def field(doc: Any, key: str, kind: type | tuple[type, ...], where: str) -> Any:
    """``doc[key]``, of type ``kind`` (a bool is not taken for a number)."""
    if not isinstance(doc, dict) or key not in doc:
        raise ResultFileError(f"{where}: field {key!r} is missing")
    value = doc[key]
    kinds = kind if isinstance(kind, tuple) else (kind,)
    if not isinstance(value, kinds) or (isinstance(value, bool) and bool not in kinds):
        raise ResultFileError(f"{where}: field {key!r} must be "
                              f"{' or '.join(k.__name__ for k in kinds)}, got "
                              f"{type(value).__name__}")
    return value


def number(doc: Any, key: str, where: str, *, positive: bool = True) -> float:
    """Field ``key``: a finite number, > 0 (``positive``) or ≥ 0."""
    value = field(doc, key, (int, float), where)
    if not (np.isfinite(value) and (value > 0 if positive else value >= 0)):
        raise ResultFileError(f"{where}: field {key!r} is {value!r:.40}, expected a finite "
                              f"number {'>' if positive else '≥'} 0")
    return float(value)


def vector(doc: Any, key: str, n: int, where: str, *, nan: bool = False, inf: bool = False,
           signed: bool = False, what: str = "one per joint") -> np.ndarray:
    """Field ``key``: ``n`` finite numbers, ≥ 0 unless ``signed`` (NaN allowed when ``nan``,
    +inf when ``inf``)."""
    value = field(doc, key, list, where)
    ok = len(value) == n and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                 for v in value)
    arr = np.asarray(value, dtype=float) if ok else np.empty(0)
    allowed = np.isfinite(arr) | (nan & np.isnan(arr)) | (inf & (arr == np.inf))
    if not ok or not np.all(allowed) or (not signed and np.any(arr[~np.isnan(arr)] < 0)):
        extra = "".join([", NaN where the replay diverged" if nan else "",
                         ", inf where not informed" if inf else ""])
        raise ResultFileError(f"{where}: field {key!r} must hold {n} "
                              f"{'finite numbers' if signed else 'numbers ≥ 0'} ({what}"
                              f"{extra}), got {str(value):.60}")
    return arr

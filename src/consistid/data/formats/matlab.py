r"""MATLAB ``.mat`` logs (v4–v7, read with ``scipy.io.loadmat``).

Two layouts are recognised, at the top level or inside one struct variable:

arrays
    a time vector and one ``(N, n)`` matrix per field, named like the columns of a CSV
    (``t``/``time``, ``q``/``pos``/``position``, ``dq``/``vel``, ``ddq``/``acc``,
    ``tau``/``effort``/``torque``), and optionally ``joint_names`` (a cell array or char
    matrix);
columns
    one vector per column, named as in a CSV (``q_joint1``, ``joint1_effort`` …;
    :mod:`consistid.data.formats.columns`).

MATLAB 7.3 files are HDF5, which scipy does not read: the error says to save with ``-v7``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
import scipy.io

from ...errors import DatasetError, MissingColumnsError
from .columns import FIELD_ALIASES, Log, log_file, log_from_columns, map_columns, time_unit_of


def _strings(value: np.ndarray) -> list[str]:
    a = np.asarray(value)
    if a.dtype == object:
        return [str(np.asarray(v).ravel()[0]) if np.size(v) else "" for v in a.ravel()]
    if a.dtype.kind == "U":
        return [str(s).strip() for s in a.ravel()] if a.ndim <= 1 else \
            ["".join(row).strip() for row in a]
    raise DatasetError(f"joint_names has dtype {a.dtype}: expected a cell array of strings")


def _numeric(value: object, name: str, source: str) -> np.ndarray:
    """Variable ``name`` as a float array; :class:`DatasetError` for complex values (their
    imaginary part would be dropped), strings, cell arrays (ragged or not) and structs."""
    a = np.asarray(value)
    if a.dtype.kind == "c":
        raise DatasetError(f"{source}: variable {name!r} holds complex numbers; consistid does "
                           "not drop imaginary parts silently: save the real signal "
                           "(real(x) in MATLAB) if that is what was logged")
    if a.dtype.kind not in "fiub":
        what = {"U": "text", "S": "text", "O": "a cell array or struct"}.get(a.dtype.kind,
                                                                             str(a.dtype))
        raise DatasetError(f"{source}: variable {name!r} holds {what}, not numbers; save it as "
                           "a numeric matrix (cell2mat in MATLAB, when its cells are of one "
                           "length)")
    return a.astype(float)


def _variables(path: Path) -> dict[str, np.ndarray]:
    try:
        raw = scipy.io.loadmat(path, squeeze_me=False, struct_as_record=False)
    except NotImplementedError:
        raise DatasetError(f"{path.name} is a MATLAB 7.3 (HDF5) file, which scipy cannot read: "
                           "save it with save(..., '-v7') or export CSV") from None
    except (ValueError, TypeError, OSError) as exc:
        raise DatasetError(f"{path.name} is not a readable MATLAB file: {exc}") from None
    variables = {k: v for k, v in raw.items() if not k.startswith("__")}
    structs = [k for k, v in variables.items() if isinstance(v, np.ndarray) and v.dtype == object
               and v.size == 1 and hasattr(v.ravel()[0], "_fieldnames")]
    if len(variables) == 1 and structs:
        s = variables[structs[0]].ravel()[0]
        variables = {f: getattr(s, f) for f in s._fieldnames}
    return variables


def read_mat(path: str | Path, *, joints: Sequence[str] | None = None,
             columns: Mapping[str, str | Sequence[str]] | None = None) -> Log:
    """Read a ``.mat`` log into a :class:`~consistid.data.formats.columns.Log` (module
    docstring for the layouts; ``joints``, ``columns`` as for CSV)."""
    path = log_file(path)
    variables = _variables(path)
    source = path.name
    lower = {k.lower(): k for k in variables}
    matrix = {f: next((lower[a] for a in aliases if a in lower), None)
              for f, aliases in FIELD_ALIASES.items()}
    time = next((k for k in variables if time_unit_of(k)[0]), None)
    if matrix["q"] is not None and matrix["tau"] is not None and not columns:
        if time is None:
            raise MissingColumnsError(f"{source}: no time variable (t, time, timestamp …); "
                                      f"variables are {sorted(variables)}")
        t = _numeric(variables[time], time, source).ravel()
        fields = {}
        for f, k in matrix.items():
            if k is None:
                continue
            a = _numeric(variables[k], k, source)
            a = a[:, None] if a.ndim == 1 else a
            if a.ndim != 2 or t.size not in a.shape:
                raise DatasetError(f"{source}: variable {k!r} has shape {a.shape}; expected "
                                   f"({t.size}, n) to match {time!r}")
            fields[f] = a if a.shape[0] == t.size else a.T
        names = None
        key = lower.get("joint_names")
        if key is not None:
            names = tuple(_strings(variables[key]))
        nv = fields["q"].shape[1]
        if names is not None and len(names) != nv:
            raise DatasetError(f"{source}: joint_names has {len(names)} names for {nv} columns")
        notes = [f"read {source}: arrays " + ", ".join(f"{f}←{k!r}" for f, k in
                                                     [("t", time), *matrix.items()] if k)]
        if joints is not None and names is None:
            if len(joints) != nv:
                raise MissingColumnsError(f"{source}: joints= (or the model) names "
                                          f"{len(joints)} joints {list(joints)}, the file has "
                                          f"{nv} columns and no joint_names variable to select "
                                          "them by; add joint_names to the file")
            names = tuple(joints)   # as an .npz without names: the columns in joints= order
            notes.append(f"no joint_names variable: its {nv} columns taken in the order "
                         f"{list(joints)}")
        if joints is not None:
            missing = [j for j in joints if j not in names]
            if missing:
                raise MissingColumnsError(f"{source}: joint(s) {missing} not in its joint_names "
                                          f"{list(names)}")
            idx = [names.index(j) for j in joints]
            dropped = [n for n in names if n not in joints]
            fields = {f: a[:, idx] for f, a in fields.items()}
            names = tuple(joints)
            if dropped:
                notes.append(f"dropped the unselected joints {dropped}")
        for f, a in fields.items():
            bad = np.argwhere(~np.isfinite(a))
            if bad.size:
                raise DatasetError(f"{source}: {matrix[f]}[{bad[0][0]}, {bad[0][1]}] is "
                                   f"{a[tuple(bad[0])]} ({len(bad)} non-finite value(s))")
        bad = np.flatnonzero(~np.isfinite(t))
        if bad.size:
            raise DatasetError(f"{source}: {time}[{bad[0]}] is {t[bad[0]]} ({bad.size} "
                               "non-finite stamp(s))")
        return Log(t, fields, names, source, tuple(notes), time_unit_of(time)[1])
    # complex vectors are matched too, and refused by name if a column uses one
    vectors = {k: np.asarray(v).ravel() for k, v in variables.items()
               if isinstance(v, np.ndarray) and v.dtype.kind in "fiuc" and min(v.shape) == 1}
    if not vectors:
        raise MissingColumnsError(f"{source}: no time/q/tau arrays and no column vectors; "
                                  f"variables are {sorted(variables)}")
    lengths = {v.size for v in vectors.values()}
    if len(lengths) > 1:
        n = max(lengths, key=lambda m: sum(v.size == m for v in vectors.values()))
        vectors = {k: v for k, v in vectors.items() if v.size == n}
    cmap = map_columns(list(vectors), source, joints=joints, columns=columns)
    return log_from_columns(lambda k: _numeric(vectors[k], k, source), cmap, source,
                            vectors[cmap.time].size)

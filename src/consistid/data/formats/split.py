r"""Logs split over several files: positions, velocities and torques each in a table of its own.

Some loggers write one file per signal — FIGAROH's TIAGo logs hold positions, velocities and
efforts in three CSV files whose headers read ``time, - torso_lift_joint_position, …``.
:func:`read_split` reads each table (:func:`~consistid.data.formats.csv.read_table`), drops a
leading list marker (``- ``) from the column names, reads every other column as a joint's field
by name (:func:`~consistid.data.formats.columns.parse_candidates`: ``<joint>_position``,
``effort_<joint>``, ``q_<joint>`` …; a unit in brackets is converted as in a single table), and
joins the files on the time stamps of the file that holds the positions. A file whose stamps
are not those is interpolated onto them (:func:`consistid.data.resample.resample`, cubic spline;
the stamps outside its span are dropped), and the record says so. A field found in two files,
a joint without its position or torque, or a file without a time column is refused by name.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from ...errors import DatasetError, MissingColumnsError
from ..resample import resample
from ..timestamps import check_stamps
from .columns import Log, column_unit, parse_candidates, time_unit_of, unit_factor
from .csv import read_table


def _clean(name: str) -> str:
    """A column name without a YAML list marker (``"- arm_1_joint_position"``)."""
    text = str(name).strip()
    return text[1:].strip() if text.startswith("- ") or text == "-" else text


def _columns(path: Path, joints: Sequence[str] | None, delimiter: str | None
             ) -> tuple[np.ndarray, str | None, dict[str, dict[str, np.ndarray]], list[str],
                        set[str]]:
    """One file: its stamps, their unit, ``field → joint → column``, the notes and the fields
    whose header named their unit."""
    names, table, note = read_table(path, delimiter)
    clean = [_clean(n) for n in names]
    times = [k for k, n in enumerate(clean) if time_unit_of(n)[0]]
    if not times:
        raise MissingColumnsError(f"{path.name}: no time column (t, time, timestamp, stamp …); "
                                  f"the columns are {names}")
    wanted = {j.lower(): j for j in joints} if joints is not None else None
    fields: dict[str, dict[str, np.ndarray]] = {}
    ignored, converted, named = [], [], set()
    for k, name in enumerate(clean):
        if k == times[0]:
            continue
        found = [(f, j) for f, j in parse_candidates(name) if isinstance(j, str)]
        if wanted is not None:
            found = [(f, wanted[j.lower()]) for f, j in found if j.lower() in wanted]
        if not found:
            ignored.append(names[k])
            continue
        f, joint = found[0]
        factor, said = unit_factor(f, name, path.name)
        converted += [said] if said else []
        fields.setdefault(f, {})[joint] = table[:, k] * factor
        if column_unit(name) is not None:
            named.add(f)
    read = ", ".join(f"{f} of {len(cols)} joints" for f, cols in fields.items())
    notes = [f"read {path.name} ({note}): t←{names[times[0]]!r}, {read or 'nothing'}"
             + (f"; ignored columns {ignored}" if ignored else ""), *converted]
    stamps = check_stamps(table[:, times[0]], f"{path.name}, column {names[times[0]]!r}")
    return stamps, time_unit_of(clean[times[0]])[1], fields, notes, named


def read_split(paths: Sequence[str | Path], *, joints: Sequence[str] | None = None,
               delimiter: str | None = None) -> Log:
    """Read a log split over ``paths`` (module docstring) into one
    :class:`~consistid.data.formats.columns.Log`; ``joints`` select and order the joints
    (default: those of the positions' file, in its order)."""
    paths = [Path(p) for p in paths]
    if len(paths) < 2:
        raise DatasetError("a split log needs at least two files (positions, torques …); "
                           "read one file with load_recording(path)")
    files = [(p, *_columns(p, joints, delimiter)) for p in paths]
    owner: dict[str, Path] = {}
    for path, _, _, fields, _, _ in files:
        for f in fields:
            if f in owner:
                raise MissingColumnsError(f"{f} columns in both {owner[f].name} and {path.name}; "
                                          "name the files that hold each signal once")
            owner[f] = path
    for f in ("q", "tau"):
        if f not in owner:
            raise MissingColumnsError(f"no {f} columns in {[p.name for p in paths]} (positions "
                                      "as <joint>_position, torques as <joint>_effort …)")
    ref = next(f for f in files if f[0] == owner["q"])
    t, unit = ref[1], ref[2]
    names = list(joints) if joints is not None else list(ref[3]["q"])
    keep = np.ones(t.size, bool)
    for path, ts, u, _, _, _ in files:
        if u != unit:
            raise DatasetError(f"{path.name} stamps in {u or 's'}, {ref[0].name} in {unit or 's'}")
        if not (ts.size == t.size and np.array_equal(ts, t)):
            keep &= (t >= ts[0]) & (t <= ts[-1])
    out, notes = {}, [n for f in files for n in f[4]]
    for f, path in owner.items():
        _, ts, _, fields, _, _ = next(x for x in files if x[0] == path)
        missing = [j for j in names if j not in fields[f]]
        if missing:
            raise MissingColumnsError(f"{path.name}: no {f} column for joint(s) {missing}; it "
                                      f"has {list(fields[f])}")
        a = np.column_stack([fields[f][j] for j in names])
        if ts.size == t.size and np.array_equal(ts, t):
            out[f] = a[keep]
        else:
            out[f] = resample(ts, a, t[keep])
            notes.append(f"{path.name}: its stamps are not {ref[0].name}'s; {f} interpolated "
                         "onto them (cubic spline)")
    if not keep.all():
        notes.append(f"{int((~keep).sum())} sample(s) of {ref[0].name} outside another file's "
                     "span dropped")
    named = tuple(sorted({f for x in files for f in x[5] if owner.get(f) == x[0]}))
    return Log(t[keep], out, tuple(names), " + ".join(p.name for p in paths), tuple(notes),
               unit, unit_fields=named)

r"""pandas DataFrames: the columns are matched by name as in a CSV
(:mod:`consistid.data.formats.columns`).

The time is a column (``t``, ``time``, ``timestamp_ns`` …) or, when there is none, the index if
it is a ``DatetimeIndex``, a ``TimedeltaIndex`` or a numeric index named like a time column.
Two-level column labels (``("q", "joint1")`` or ``("joint1", "position")``) are joined with a
dot (``q.joint1``). pandas is not imported here: the frame is read through its own methods.
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from ...errors import DatasetError
from .columns import Log, check_selection, log_from_columns, map_columns, time_unit_of


def read_frame(frame: Any, *, joints: Sequence[str] | None = None,
               columns: Mapping[str, str | Sequence[str]] | None = None,
               source: str = "DataFrame") -> Log:
    """A :class:`~consistid.data.formats.columns.Log` from a pandas ``DataFrame`` (rows are
    samples). ``joints``, ``columns``: as for CSV."""
    check_selection(joints, columns)
    if not hasattr(frame, "columns") or not hasattr(frame, "index"):
        raise DatasetError(f"{source}: expected a pandas DataFrame, got {type(frame).__name__}")
    labels = [".".join(str(p) for p in c) if isinstance(c, tuple) else str(c)
              for c in frame.columns]
    if len(frame) == 0:
        raise DatasetError(f"{source} has no rows")
    values = {lab: frame.iloc[:, i].to_numpy() for i, lab in enumerate(labels)}
    notes = []
    if not any(time_unit_of(lab)[0] for lab in labels) and not (columns and "t" in columns):
        index = frame.index
        kind = getattr(index, "inferred_type", "")
        named_time = index.name is not None and time_unit_of(str(index.name))[0]
        if getattr(index.dtype, "kind", "") in "mM" or kind in ("datetime64", "timedelta64"):
            stamps = np.asarray(index.to_numpy())
            if stamps.dtype.kind == "M":
                ns = (stamps - stamps[0]).astype("timedelta64[ns]").astype(np.int64)
            else:
                ns = stamps.astype("timedelta64[ns]").astype(np.int64)
            values["t"] = ns * 1e-9
            labels = ["t", *labels]
            notes.append(f"time from the {type(index).__name__} (origin {stamps[0]})")
        elif named_time:
            name = str(index.name)
            values[name] = np.asarray(index.to_numpy())
            labels = [name, *labels]
            notes.append(f"time from the index {name!r}")
    cmap = map_columns(labels, source, joints=joints, columns=columns,
                       first_row=[str(values[lab][0]) for lab in labels])

    def get(name: str) -> np.ndarray:
        a = values[name]
        if a.dtype.kind == "M":
            return (a - a[0]).astype("timedelta64[ns]").astype(np.int64) * 1e-9
        if a.dtype.kind == "m":
            return a.astype("timedelta64[ns]").astype(np.int64) * 1e-9
        return a

    log = log_from_columns(get, cmap, source, len(frame), None, notes)
    if values[cmap.time].dtype.kind in "mM":
        return Log(log.t, log.fields, log.joint_names, log.source,
                   log.notes + (f"{cmap.time!r} holds {values[cmap.time].dtype} stamps: "
                                "converted to seconds",), "s", log.rows,
                   unit_fields=log.unit_fields, preset=log.preset)
    return log

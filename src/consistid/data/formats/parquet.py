r"""Parquet logs (Apache Arrow's columnar files), read with ``pyarrow`` (the ``[io]``
extra): the columns are matched by name as in a CSV (:mod:`consistid.data.formats.columns`);
a timestamp- or duration-typed time column is converted to seconds.
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ...errors import DatasetError, MissingDependencyError
from ..timestamps import seconds_of
from .columns import Log, log_file, log_from_columns, map_columns


def read_parquet(path: str | Path, *, joints: Sequence[str] | None = None,
                 columns: Mapping[str, str | Sequence[str]] | None = None) -> Log:
    """Read a Parquet log into a :class:`~consistid.data.formats.columns.Log` (``joints``,
    ``columns`` as for CSV). Raises :class:`~consistid.errors.MissingDependencyError` without
    pyarrow, :class:`~consistid.errors.DatasetError` for a file that is not Parquet."""
    try:
        import pyarrow.parquet as pq
    except ImportError:
        raise MissingDependencyError("reading Parquet needs pyarrow: pip install "
                                     "'consistid[io]' (or pip install pyarrow)") from None
    path = log_file(path)
    try:
        table = pq.read_table(path)
    except Exception as exc:                      # pyarrow raises its own ArrowInvalid, OSError
        raise DatasetError(f"{path.name} is not a readable Parquet file: {exc}") from None
    names = [str(n) for n in table.column_names]
    cmap = map_columns(names, path.name, joints=joints, columns=columns)

    def get(name: str) -> np.ndarray:
        col = table.column(name)
        a = col.to_numpy(zero_copy_only=False)
        if a.dtype.kind in "Mm":        # timestamps, durations (unit in the type); nulls: NaN
            return seconds_of(a)
        if a.dtype == object:                     # nulls come back as None
            a = np.array([np.nan if v is None else v for v in a], dtype=object)
        return a

    log = log_from_columns(get, cmap, path.name, table.num_rows, None,
                           (f"{table.num_rows} rows, {len(names)} columns",))
    kind = str(table.schema.field(cmap.time).type)
    if kind.startswith(("timestamp", "duration")):
        what = ("timestamps: converted to seconds from the first" if kind.startswith("timestamp")
                else f"durations ({kind}): converted to seconds")
        return Log(log.t, log.fields, log.joint_names, log.source,
                   log.notes + (f"{cmap.time!r} holds {what}",), "s", log.rows,
                   unit_fields=log.unit_fields, preset=log.preset)
    return log

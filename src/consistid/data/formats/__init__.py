r"""Log file formats in: CSV, pandas DataFrames, Parquet, ROS 1/2 bags and MCAP, MATLAB ``.mat``.

Every reader returns a :class:`~consistid.data.formats.columns.Log` (stamps and per-joint
arrays, joint names, the record of what was read from where); :func:`read_log` picks the reader
by the file's suffix, and :func:`consistid.data.recordings.load_recording` turns the log into a
:class:`~consistid.data.recordings.Recording` (time stamps, signal chain, joint matching).

=================  =====================================  ============================
suffix             reader                                 needs
=================  =====================================  ============================
``.csv .tsv .txt`` :func:`~.csv.read_csv`                  (numpy)
``.parquet .pq``   :func:`~.parquet.read_parquet`          ``pyarrow`` (``[io]``)
``.bag .mcap .db3`` :func:`~.rosbag.read_bag`              ``rosbags`` (``[io]``)
or a bag folder
``.mat``           :func:`~.matlab.read_mat`               (scipy)
DataFrame          :func:`~.frame.read_frame`              (pandas, any version)
several files      :func:`~.split.read_split`              (numpy)
=================  =====================================  ============================
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

from ...errors import DatasetError, OptionError
from ...progress import ProgressArg
from .columns import Log, check_selection
from .csv import read_csv
from .frame import read_frame
from .matlab import read_mat
from .parquet import read_parquet
from .rosbag import read_bag
from .split import read_split

SUFFIXES = {".csv": "csv", ".tsv": "csv", ".txt": "csv", ".parquet": "parquet", ".pq": "parquet",
            ".bag": "bag", ".mcap": "bag", ".db3": "bag", ".mat": "mat"}

__all__ = ["Log", "SUFFIXES", "format_of", "read_bag", "read_csv", "read_frame", "read_log",
           "read_mat", "read_parquet", "read_split"]


def format_of(path: str | Path) -> str:
    """``"csv"``, ``"parquet"``, ``"bag"``, ``"mat"`` or ``"npz"`` by the suffix (a folder with
    a ``metadata.yaml`` is a ROS 2 bag)."""
    path = Path(path)
    if path.is_dir():
        if (path / "metadata.yaml").is_file():
            return "bag"
        logs = sorted(p.name for p in path.iterdir()
                      if p.suffix.lower() in (*SUFFIXES, ".npz") and p.is_file())
        held = (f"; it holds the logs {logs[:6]}{' …' if len(logs) > 6 else ''}: name each one "
                "(a folder is read only as a ROS 2 bag)" if logs else "")
        raise DatasetError(f"{str(path)!r} is a folder without metadata.yaml: not a ROS 2 bag"
                           + held)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        return "npz"
    if suffix not in SUFFIXES:
        raise DatasetError(f"{path.name}: unknown log format {suffix!r}; known: "
                           f"{sorted([*SUFFIXES, '.npz'])} and ROS 2 bag folders")
    return SUFFIXES[suffix]


def read_log(path: str | Path, *, joints: Sequence[str] | None = None,
             columns: Mapping[str, Any] | None = None, topic: str | None = None,
             delimiter: str | None = None, stamp: str = "header",
             progress: ProgressArg = None) -> Log:
    """Read a log file by its suffix (module table). ``topic``/``stamp`` apply to bags,
    ``delimiter`` to text, ``columns`` to tables; giving one where it does not apply raises
    :class:`OptionError`. ``progress`` (:mod:`consistid.progress`) shows a bar over a bag's
    messages; the other formats are read in one call."""
    kind = format_of(path)
    check_selection(joints, columns)
    if kind == "npz":
        raise DatasetError(f"{Path(path).name}: .npz logs are read by "
                           "consistid.data.recordings.load_recording")
    if kind != "bag" and (topic is not None or stamp != "header"):
        raise OptionError(f"topic=/stamp= apply to ROS bags, not to {Path(path).name}")
    if kind != "csv" and delimiter is not None:
        raise OptionError(f"delimiter= applies to CSV, not to {Path(path).name}")
    if kind == "bag":
        if columns:
            raise OptionError("columns= does not apply to ROS bags (JointState fields are fixed)")
        return read_bag(path, joints=joints, topic=topic, stamp=stamp, progress=progress)
    if kind == "csv":
        return read_csv(path, joints=joints, columns=columns, delimiter=delimiter)
    if kind == "parquet":
        return read_parquet(path, joints=joints, columns=columns)
    return read_mat(path, joints=joints, columns=columns)

r"""CSV (and other delimited text) logs: one header line naming the columns, one row per sample.

The delimiter is sniffed from the first lines (``,``, ``;``, tab, ``|`` or spaces; Python's
``csv.Sniffer``), and said in the record; with any delimiter but ``,`` (``;``, a tab: a
spreadsheet's export in a European locale) a decimal comma (``1,25``) is read as ``1.25``.
Lines starting with ``#`` are comments (before the header too). A time column written as ISO
8601 date-times (``2025-11-24 16:00:00.002``, pandas' ``to_csv`` of a datetime column) or as
times of day (``16:00:00.002``) is parsed. Text is UTF-8 (a byte-order mark dropped); a file
that is not, but holds no NUL byte (an older Windows tool's Latin-1 ``°`` or ``é``), is read as
Latin-1 with a warning naming the line. A last line cut short by a logger
stopped mid-write (no line break after it; too few fields, or a last field under half its
usual length) is dropped with a warning. The columns are
matched by name (:mod:`consistid.data.formats.columns`). Numbers are parsed by ``numpy.loadtxt``;
a broken file is re-read line by line to name the line and column of the first bad value
(:class:`~consistid.errors.DatasetError`).
"""

from __future__ import annotations

import csv
import io
import re
import warnings
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ...errors import DataQualityWarning, DatasetError, MissingColumnsError
from .columns import Log, log_file, log_from_columns, map_columns

DELIMITERS = ",;\t| "
#: Characters read to sniff the delimiter.
SNIFF_CHARS = 16384


def _header(lines: list[str], source: str) -> tuple[int, str]:
    for k, line in enumerate(lines):
        if line.strip() and not line.lstrip().startswith("#"):
            return k, line
    raise DatasetError(f"{source} is empty (no header line, no data)")


def sniff_delimiter(sample: str, source: str) -> str:
    """The delimiter of the text ``sample`` (header and a few rows)."""
    lines = [ln for ln in sample.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    text = "\n".join(lines[:20])
    try:
        return csv.Sniffer().sniff(text, delimiters=DELIMITERS).delimiter
    except csv.Error:
        for d in DELIMITERS:
            if lines and d in lines[0]:
                return d
        raise DatasetError(f"{source}: cannot tell the delimiter of the header {lines[:1]}; "
                           "pass delimiter=") from None


def _locate(text: str, start: int, delimiter: str, names: list[str], decimal_comma: bool,
            source: str, read: Sequence[int]) -> None:
    """Read the file's ``text`` (as :func:`read_text` gave it) line by line from line ``start``
    (0-based) and raise a DatasetError
    naming the first bad line/column among the columns ``read``; an empty cell is counted down
    its column (a column empty in every row is a signal the logger did not record)."""
    empty: tuple[int, int] | None = None              # (line, column) of the first empty cell
    rows = blanks = 0
    with io.StringIO(text, newline="") as fh:
        for lineno, line in enumerate(fh):
            if lineno < start or not line.strip() or line.lstrip().startswith("#"):
                continue
            cells = next(csv.reader([line], delimiter=delimiter,
                                    skipinitialspace=delimiter == " "))
            if delimiter == " ":
                cells = [c for c in cells if c != ""]
            if empty is not None:
                rows += 1
                blanks += len(cells) > empty[1] and not cells[empty[1]].strip()
                continue
            if len(cells) != len(names):
                raise DatasetError(f"{source}, line {lineno + 1}: {len(cells)} fields, the header "
                                   f"has {len(names)} ({line.strip()[:80]!r})")
            for c, (name, cell) in enumerate(zip(names, cells)):
                if c not in read:
                    continue
                text = cell.strip().replace(",", ".") if decimal_comma else cell.strip()
                if not text:
                    empty, rows, blanks = (lineno + 1, c), rows + 1, 1
                    break
                try:
                    float(text)
                except ValueError:
                    raise DatasetError(f"{source}, line {lineno + 1}, column {name!r}: "
                                       f"{cell!r} is not a number") from None
            else:
                rows += 1
    if empty is None:
        return
    name = names[empty[1]]
    if blanks == rows:
        raise DatasetError(f"{source}, column {name!r}: every one of its {rows} cells is empty: "
                           "the logger did not record it. Log that signal, or leave the joint "
                           "out (joints=[...]; a model with that joint locked)")
    raise DatasetError(f"{source}, line {empty[0]}, column {name!r}: an empty cell, the first of "
                       f"{blanks} in that column ({rows} rows); repair or drop those rows")


def read_csv(path: str | Path, *, joints: Sequence[str] | None = None,
             columns: Mapping[str, str | Sequence[str]] | None = None,
             delimiter: str | None = None) -> Log:
    """Read a delimited text log into a :class:`~consistid.data.formats.columns.Log`.

    Parameters
    ----------
    path : the file.
    joints : joints to keep, in this order (other joints' columns are dropped and recorded).
    columns : explicit column mapping (:mod:`consistid.data.formats.columns`).
    delimiter : default sniffed.

    Raises
    ------
    DatasetError : empty file, no data rows, a line with the wrong number of fields or a value
        that is not a number (naming the line and the column), a non-finite stamp or value.
    MissingColumnsError : no time, position or torque columns (listing the header).
    """
    path = log_file(path)
    source = path.name
    raw_text = read_text(path, source)
    head = raw_text[:SNIFF_CHARS]
    if not head.strip():
        raise DatasetError(f"{source} is empty")
    lines = head.splitlines()
    k, header_line = _header(lines, source)
    how = "given" if delimiter is not None else "sniffed"
    if delimiter is None:
        delimiter = sniff_delimiter(head, source)
    names = next(csv.reader([header_line], delimiter=delimiter,
                            skipinitialspace=delimiter == " "))
    names = [n.strip() for n in names if not (delimiter == " " and n == "")]
    if all(_is_number(n) for n in names):
        raise MissingColumnsError(f"{source}: the first line {header_line.strip()[:80]!r} is data,"
                                  " not a header naming the columns; add a header line or pass "
                                  "the arrays to consistid.data.recordings.from_arrays")
    data_lines = [ln for ln in lines[k + 1:] if ln.strip() and not ln.lstrip().startswith("#")]
    cmap = map_columns(names, source, joints=joints, columns=columns,
                       first_row=_cells(data_lines[0], delimiter) if data_lines else None)
    decimal_comma = bool(data_lines) and reads_decimal_comma(delimiter, data_lines[0])
    wanted = [cmap.time] + [c for cols in cmap.fields.values() for c in cols]
    usecols = sorted({names.index(c) for c in wanted})
    text = raw_text.replace("\r\n", "\n").replace("\r", "\n")     # universal line breaks
    if not data_lines:
        raise DatasetError(f"{source}: a header ({len(names)} columns) but no data rows")
    first = [c for c in _cells(data_lines[0], delimiter) if c]
    if first and not any(_is_number(c) or _time_kind([c]) for c in first):
        raise DatasetError(f"{source}: the line after the header holds no number "
                           f"({first[:6]}{' …' if len(first) > 6 else ''}): a second header "
                           "line, e.g. of units? Put each unit in its column's header "
                           "('q1 [rad]', 'tau1 [Nm]', 't [ms]') and remove that line")
    text, cut = _drop_cut_last_line(text, k, delimiter, len(names), source)
    time_idx = names.index(cmap.time)
    clock = _time_kind(_cells(data_lines[0], delimiter)[time_idx:time_idx + 1])
    if clock:                       # date-times or times of day: read apart, the rest as numbers
        body = [ln for ln in text.splitlines()[k + 1:] if ln.strip()
                and not ln.lstrip().startswith("#")]
        stamps = _parse_times([(_cells(ln, delimiter) + [""] * (time_idx + 1))[time_idx]
                               for ln in body], clock, cmap.time, k, source)
        usecols = [c for c in usecols if c != time_idx]
    if decimal_comma:
        text = text.replace(",", ".")
    try:
        table = np.loadtxt(io.StringIO(text), delimiter=None if delimiter == " " else delimiter,
                           skiprows=k + 1, comments="#", ndmin=2, dtype=float, usecols=usecols,
                           quotechar='"')
    except ValueError as exc:
        _locate(raw_text, k + 1, delimiter, names, decimal_comma, source, usecols)
        raise DatasetError(f"{source}: not readable as numbers after the header ({exc})") from None
    if table.shape[0] == 0:
        raise DatasetError(f"{source}: a header ({len(names)} columns) but no data rows")
    all_lines = text.splitlines()
    rows = np.array([n + 1 for n, ln in enumerate(all_lines) if n > k and ln.strip()
                     and not ln.lstrip().startswith("#")])
    if rows.size != table.shape[0]:
        rows = None
    col = {names[c]: table[:, i] for i, c in enumerate(usecols)}
    note = (f"delimiter {delimiter!r} ({how})" + (", decimal comma" if decimal_comma else "")
            + f", {table.shape[0]} rows")
    if cut:
        note += f"; {cut}"
    if clock:
        if stamps.size != table.shape[0]:
            raise DatasetError(f"{source}: {stamps.size} time stamps but {table.shape[0]} rows "
                               "of numbers")
        col[cmap.time] = stamps
        note += (f"; column {cmap.time!r} read as {CLOCKS[clock]}")
    return log_from_columns(col.__getitem__, cmap, source, table.shape[0], rows, (note,))


def read_table(path: str | Path, delimiter: str | None = None
               ) -> tuple[list[str], np.ndarray, str]:
    """``(column names, (N, k) numbers, note)`` of a delimited text file with one header line,
    every column numeric (comments, delimiter sniffing and decimal commas as for
    :func:`read_csv`; a bad value is named by line and column)."""
    path = log_file(path)
    source = path.name
    text = read_text(path, source)
    lines = text[:SNIFF_CHARS].splitlines()
    k, header_line = _header(lines, source)
    how = "given" if delimiter is not None else "sniffed"
    delimiter = delimiter or sniff_delimiter(text[:SNIFF_CHARS], source)
    names = _cells(header_line, delimiter)
    rows = [ln for ln in lines[k + 1:] if ln.strip() and not ln.lstrip().startswith("#")]
    comma = bool(rows) and reads_decimal_comma(delimiter, rows[0])
    body = text.replace("\r\n", "\n").replace("\r", "\n")
    try:
        table = np.loadtxt(io.StringIO(body.replace(",", ".") if comma else body),
                           delimiter=None if delimiter == " " else delimiter, skiprows=k + 1,
                           comments="#", ndmin=2, dtype=float)
    except ValueError:
        _locate(text, k + 1, delimiter, names, comma, source, range(len(names)))
        raise DatasetError(f"{source}: not readable as numbers after the header") from None
    if table.shape[0] == 0 or table.shape[1] != len(names):
        raise DatasetError(f"{source}: {table.shape[0]} rows of {table.shape[1]} numbers under "
                           f"a header of {len(names)} columns")
    return names, table, f"delimiter {delimiter!r} ({how}), {table.shape[0]} rows"


def reads_decimal_comma(delimiter: str, first_row: str) -> bool:
    """Whether the rows write decimal commas (``1,25``): a comma in the first data row when
    the delimiter is another character (``;``, a tab, ``|``, spaces: module notes)."""
    return delimiter != "," and "," in first_row


def read_text(path: Path, source: str) -> str:
    """The file's text decoded as UTF-8 (a byte-order mark dropped, line breaks as written).
    A file that is not UTF-8 but holds no NUL byte (a Latin-1 ``°`` or ``µ`` in a header or a
    comment, written by an older Windows tool) is read as Latin-1 with a
    :class:`~consistid.errors.DataQualityWarning` naming the line; one with NUL bytes (UTF-16,
    binary) is refused (:class:`DatasetError`)."""
    raw = path.read_bytes()
    body = raw[3:] if raw.startswith(b"\xef\xbb\xbf") else raw
    try:
        return body.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = body[:exc.start].count(b"\n") + 1
        start = body.rfind(b"\n", 0, exc.start) + 1
        around = body[max(start, exc.start - 30):exc.start + 30].split(b"\n")[0]
        shown = around.decode("latin-1").rstrip("\r")
        byte = body[exc.start:exc.start + 1]
        if b"\x00" in body:
            raise DatasetError(f"{source}, line {line}: byte {byte!r} is not UTF-8 text and the "
                               "file holds NUL bytes (UTF-16 or binary?); save the log as "
                               "UTF-8 text") from None
        warnings.warn(f"{source}, line {line}: byte {byte!r} is not UTF-8; the file was read "
                      f"as Latin-1 (ISO 8859-1), which gives {shown!r}; save it as UTF-8 if that "
                      "is not what it says", DataQualityWarning, stacklevel=3)
        return body.decode("latin-1")


def _drop_cut_last_line(text: str, header: int, delimiter: str, n_names: int,
                        source: str) -> tuple[str, str | None]:
    """``text`` without its last data line when that line was cut short — the file does not
    end with a line break, and the line has fewer fields than the header or its last field is
    under half as long as in the lines before it (a logger stopped mid-write) — and the sentence
    that says so (also warned, :class:`DataQualityWarning`); else ``(text, None)``."""
    if text.endswith(("\n", "\r")):
        return text, None
    lines = text.splitlines()
    rows = [n for n, ln in enumerate(lines) if n > header and ln.strip()
            and not ln.lstrip().startswith("#")]
    if len(rows) < 2:
        return text, None
    last = lines[rows[-1]]
    cells = _cells(last, delimiter)
    before = [_cells(lines[n], delimiter) for n in rows[-51:-1]]
    typical = float(np.median([len(c[-1]) if c else 0 for c in before]))
    short = len(cells) < n_names
    if not (short or (cells and len(cells[-1]) < 0.5 * typical)):
        return text, None
    why = (f"{len(cells)} of {n_names} fields" if short
           else f"its last field {cells[-1]!r} has {len(cells[-1])} characters where the lines "
                f"before have {typical:.0f}")
    sentence = (f"its last line (line {rows[-1] + 1}: {why}, no line break after it) was cut "
                "short, as by a logger stopped mid-write: dropped")
    warnings.warn(f"{source}: {sentence}", DataQualityWarning, stacklevel=5)
    return "\n".join(lines[:rows[-1]]) + "\n", sentence


#: Time columns written as text that the reader parses, and how the record names them.
CLOCKS = {"datetime": "ISO 8601 date-times (time zone offset dropped: only differences matter)",
          "clock": "times of day hh:mm:ss[.f] (seconds since midnight; a log across midnight "
                   "goes back in time and is refused)"}
_DATETIME = re.compile(r"^\d{4}-\d{2}-\d{2}[T ]\d{2}:\d{2}(:\d{2}(\.\d+)?)?"
                       r"(Z|[+-]\d{2}:?\d{2})?$")
_CLOCK = re.compile(r"^\d{1,2}:\d{2}:\d{2}(\.\d+)?$")


def _cells(line: str, delimiter: str) -> list[str]:
    cells = next(csv.reader([line], delimiter=delimiter, skipinitialspace=delimiter == " "))
    return [c.strip() for c in cells if not (delimiter == " " and c == "")]


def _time_kind(cells: list[str]) -> str | None:
    """``"datetime"``, ``"clock"`` or ``None`` (a number, or anything else) for a time cell."""
    if not cells or _is_number(cells[0]):
        return None
    if _DATETIME.match(cells[0]):
        return "datetime"
    return "clock" if _CLOCK.match(cells[0]) else None


def _parse_times(cells: list[str], kind: str, column: str, header: int,
                 source: str) -> np.ndarray:
    """The time cells as ``datetime64[ns]`` (``"datetime"``) or seconds since midnight
    (``"clock"``); :class:`DatasetError` naming the line of the first cell that is not one."""
    pattern = _DATETIME if kind == "datetime" else _CLOCK
    for n, cell in enumerate(cells):
        if not pattern.match(cell):
            raise DatasetError(f"{source}, data row {n + 1} (after the header on line "
                               f"{header + 1}), column {column!r}: {cell!r} is not "
                               f"{'an ISO date-time' if kind == 'datetime' else 'hh:mm:ss'} like "
                               f"the first row's")
    if kind == "datetime":
        bare = [re.sub(r"(Z|[+-]\d{2}:?\d{2})$", "", c).replace(" ", "T") for c in cells]
        return np.array(bare, dtype="datetime64[ns]")
    parts = np.array([c.split(":") for c in cells], dtype=float)
    return parts[:, 0] * 3600.0 + parts[:, 1] * 60.0 + parts[:, 2]


def _is_number(text: str) -> bool:
    try:
        float(text.replace(",", "."))
        return True
    except ValueError:
        return False

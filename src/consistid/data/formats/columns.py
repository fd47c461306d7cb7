r"""Named columns to a log: which column is time, which are each joint's position, velocity,
acceleration and torque — the one column mapping of every tabular format (CSV, Parquet,
DataFrame, flat MATLAB variables).

Recognised names (case-insensitive; a unit in brackets, ``"q1 [rad]"``, or after an underscore,
``"q1_rad"``, ``"tau1_Nm"``, is read as the column's unit: SI as is, degrees converted):

time
    ``t``, ``time``, ``times``, ``timestamp``, ``stamp``, ``%time`` (``rostopic echo -p``),
    ``header.stamp``; a unit suffix ``_s``, ``_ms``, ``_us``, ``_ns`` or ``[ms]`` gives the unit
    (``time_ms``, ``timestamp_ns``), recorded in the loader's record.
fields (:data:`FIELD_ALIASES`)
    ``q``/``pos``/``position``; ``dq``/``qd``/``vel``/``velocity``; ``ddq``/``qdd``/``acc``/
    ``acceleration``; ``tau``/``effort``/``torque``/``trq`` (plurals too).
one column per joint and field, any of
    ``q1`` or ``q_1`` (1-based joint index), ``q_<joint>``, ``q.<joint>``, ``q[<joint>]``,
    ``<joint>.q``, ``<joint>_q``, ``<joint>/position`` — and bare joint names (``panda_joint1``),
    read as positions.

``columns=`` overrides the recognition: ``{"t": "stamp", "q": "pos_{joint}", "tau":
"eff_{joint}"}`` (``{joint}`` is filled with each joint name, ``{i}`` with the 1-based index) or
explicit lists ``{"q": ["a1", "a2"], ...}``. ``joints=`` selects and orders the joints; the other
joints' columns (a gripper) are dropped and listed in the record.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Mapping, Sequence

import numpy as np

from ...errors import DatasetError, JointNameError, MissingColumnsError, OptionError
from ..timestamps import check_resolution
from .presets import PresetMatch, match_preset

FIELDS = ("q", "dq", "ddq", "tau")
#: Column-name spellings of each dataset field.
FIELD_ALIASES: dict[str, tuple[str, ...]] = {
    "q": ("q", "pos", "position", "positions", "angle", "angles"),
    "dq": ("dq", "qd", "qdot", "vel", "velocity", "velocities"),
    "ddq": ("ddq", "qdd", "qddot", "acc", "accel", "acceleration", "accelerations"),
    "tau": ("tau", "effort", "efforts", "torque", "torques", "trq", "force", "forces"),
}
TIME_NAMES = ("t", "time", "times", "timestamp", "timestamps", "stamp", "%time",
              "header.stamp", "field.header.stamp", "time_stamp")
_UNITS = r"(?:s|ms|us|µs|ns)"
_UNIT_SUFFIX = re.compile(rf"^(?P<base>.*?)[_\s]*(?:\[(?P<b>{_UNITS})\]|\((?P<p>{_UNITS})\)"
                          r"|_(?P<u>s|sec|ms|us|ns))$")
_BRACKET_UNIT = re.compile(r"\s+[\[(][^\])]*[\])]\s*$")
#: Units written as a suffix after an underscore (``q1_rad``, ``q1_deg``, ``tau1_Nm``), and the
#: bracket spelling each stands for (:func:`column_unit`).
SUFFIX_UNITS = {"rad": "rad", "deg": "deg", "degree": "deg", "degrees": "deg", "nm": "nm",
                "rad_s": "rad/s", "deg_s": "deg/s"}
_SUFFIX_UNIT = re.compile(r"^(?P<base>.+?)_(?P<unit>" + "|".join(
    sorted(SUFFIX_UNITS, key=len, reverse=True)) + r")$", re.I)


def log_file(path: str | Path) -> Path:
    """``path`` as a :class:`~pathlib.Path` if it names a file, else :class:`DatasetError`
    (every log reader's first check)."""
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f"log file {str(path)!r} does not exist")
    return path


def _strip_suffix_unit(name: str) -> tuple[str, str | None]:
    """``(name without a trailing _<unit>, the unit's bracket spelling)`` when the name ends in
    one of :data:`SUFFIX_UNITS` and what is left reads as a per-joint column, else
    ``(name, None)``."""
    m = _SUFFIX_UNIT.match(name)
    if m and _parse(m.group("base")):
        return m.group("base"), SUFFIX_UNITS[m.group("unit").lower()]
    return name, None
_SEP = r"[_.\-/: ]"


@dataclass(frozen=True)
class Log:
    """A log as read from a file, before the signal chain: stamps and named per-joint arrays.

    Attributes
    ----------
    t : (N,) stamps as stored (seconds unless ``time_unit`` says otherwise).
    fields : field name (``q``, ``dq``, ``ddq``, ``tau``) → (N, n) array, columns in
        ``joint_names`` order.
    joint_names : the joints, or ``None`` when the columns are numbered only.
    source : the file name (or ``"DataFrame"``).
    notes : what was read from where, for the loader's record.
    time_unit : the stamps' unit when the source says it (a column suffix, ROS stamps), else
        ``None``.
    rows : the file line of each sample (text files), for messages.
    origin : seconds already subtracted from ``t`` (ROS stamps are read as integer nanoseconds
        and made relative before they become floats, which keeps their resolution).
    unit_fields : the fields whose column headers named their unit (converted to SI already).
    preset : the logger recognised by its columns (:mod:`consistid.data.formats.presets`),
        whose ``tau`` is a joint torque (N·m), or ``None``.
    """

    t: np.ndarray
    fields: Mapping[str, np.ndarray]
    joint_names: tuple[str, ...] | None
    source: str
    notes: tuple[str, ...] = ()
    time_unit: str | None = None
    rows: np.ndarray | None = field(default=None)
    origin: float = 0.0
    unit_fields: tuple[str, ...] = ()
    preset: str | None = None


def _clean(name: str) -> str:
    return str(name).strip().strip('"').strip("'").lower()


def time_unit_of(name: str) -> tuple[bool, str | None]:
    """Whether column ``name`` is a time column, and the unit its name gives."""
    n = _clean(name)
    if n in TIME_NAMES:
        return True, None
    m = _UNIT_SUFFIX.match(n)
    if m and m.group("base").strip() in TIME_NAMES:
        unit = m.group("b") or m.group("p") or m.group("u")
        unit = {"sec": "s", "µs": "us"}.get(unit, unit)
        return True, unit
    return False, None


def _field_of(word: str) -> str | None:
    for f, aliases in FIELD_ALIASES.items():
        if word in aliases:
            return f
    return None


def parse_candidates(name: str) -> list[tuple[str, str | int]]:
    """Every ``(field, joint)`` reading of a per-joint column name (module docstring), most
    likely first; the joint is a name, or a 0-based index for ``q1``-style names. A name such
    as ``q_joint0_effort`` has two readings (``q`` of ``joint0_effort``, ``tau`` of
    ``q_joint0``): the joints the caller knows decide. A unit in brackets (``q1 [rad]``) or
    after an underscore (``q1_rad``, ``tau1_Nm``; :data:`SUFFIX_UNITS`) is not part of it."""
    raw = _BRACKET_UNIT.sub("", str(name).strip().strip('"').strip("'"))
    base, unit = _strip_suffix_unit(raw)
    if unit is not None:
        found = _parse(base)
        return found + [c for c in _parse(raw) if c not in found]
    return _parse(raw)


#: A consistid Dataset file's Coulomb signal columns (``Dataset.dq_sign``): not a joint's dq.
_DQ_SIGN = re.compile(r"dq_sign\d+")


def _parse(raw: str) -> list[tuple[str, str | int]]:
    n = raw.lower()
    out: list[tuple[str, str | int]] = []
    if _DQ_SIGN.fullmatch(n):
        return out
    m = re.fullmatch(r"([a-z]+)_?(\d+)", n)
    if m and _field_of(m.group(1)):
        out.append((_field_of(m.group(1)), int(m.group(2)) - 1))
    m = re.fullmatch(r"([a-z]+)\[(.+)\]", n)
    if m and _field_of(m.group(1)):
        out.append((_field_of(m.group(1)), raw[len(m.group(1)) + 1:-1]))
    m = re.fullmatch(rf"(.+){_SEP}([a-z]+)", n)
    suffix = (_field_of(m.group(2)), raw[:len(m.group(1))]) if m and _field_of(m.group(2)) \
        else None
    m = re.fullmatch(rf"([a-z]+){_SEP}(.+)", n)
    if m and _field_of(m.group(1)):
        out.append((_field_of(m.group(1)), raw[len(m.group(1)) + 1:]))
    if suffix:
        out.append(suffix)
    return out


def parse_column(name: str) -> tuple[str, str | int] | None:
    """The most likely ``(field, joint)`` of a per-joint column name (:func:`parse_candidates`),
    or ``None`` when the name is not one."""
    found = parse_candidates(name)
    return found[0] if found else None


def _template(spec: str | Sequence[str], joints: Sequence[str] | None, field_name: str,
              source: str) -> list[str]:
    if isinstance(spec, str):
        if "{joint}" in spec and joints is None:
            raise MissingColumnsError(f"{source}: columns[{field_name!r}] = {spec!r} needs joint "
                                      "names: pass joints=[...] or a model")
        if not any(k in spec for k in ("{joint}", "{i}", "{i0}", "{i1}")):
            raise MissingColumnsError(f"{source}: columns[{field_name!r}] = {spec!r} must contain "
                                      "{joint}, {i} (= {i1}, counting from 1) or {i0} (from 0), "
                                      "or be a list of column names")
        n = len(joints) if joints is not None else None
        if n is None:
            raise MissingColumnsError(f"{source}: columns[{field_name!r}] = {spec!r} needs the "
                                      "joint count: pass joints=[...] or a model")
        return [spec.format(joint=joints[i] if joints else i + 1, i=i + 1, i1=i + 1, i0=i)
                for i in range(n)]
    return [str(c) for c in spec]


def _base_hint(spec: object, joints: Sequence[str] | None, names: Sequence[str]) -> str:
    """A hint when a template counting from 1 (``{i}``) misses columns that counting from 0
    (``{i0}``) finds: ``actual_q_{i}`` looks for ``actual_q_6`` in a log of ``actual_q_0..5``."""
    if not isinstance(spec, str) or "{i}" not in spec and "{i1}" not in spec or not joints:
        return ""
    zero = spec.replace("{i}", "{i0}").replace("{i1}", "{i0}")
    cols = [zero.format(joint=j, i0=k) for k, j in enumerate(joints)]
    if all(c in names for c in cols):
        return f" ({{i}} counts from 1; these columns count from 0: write {zero!r})"
    return ""


@dataclass(frozen=True)
class ColumnMap:
    """Which column holds what: ``time`` the time column, ``fields[f][j]`` the column of field
    ``f`` for joint ``j`` of ``joint_names``; ``dropped`` the per-joint columns of joints not
    selected, ``ignored`` the columns nothing reads."""

    time: str
    fields: dict[str, list[str]]
    joint_names: tuple[str, ...] | None
    time_unit: str | None
    dropped: tuple[str, ...]
    ignored: tuple[str, ...]
    #: the logger recognised (:mod:`consistid.data.formats.presets`) and what it adds
    preset: str | None = None
    preset_notes: tuple[str, ...] = ()

    def describe(self, source: str) -> str:
        parts = [f"t←{self.time!r}" + (f" ({self.time_unit})" if self.time_unit else "")]
        for f, cols in self.fields.items():
            parts.append(f"{f}←{cols[0]!r}…{cols[-1]!r}" if len(cols) > 1 else f"{f}←{cols[0]!r}")
        text = f"read {source}: " + ", ".join(parts)
        if self.preset:
            text = (f"read {source} as {self.preset} (recognised by its columns; columns= "
                    "overrides): " + ", ".join(parts))
            text += "".join(f"; {n}" for n in self.preset_notes)
        if self.joint_names:
            text += f"; joints {list(self.joint_names)}"
        if self.dropped:
            text += f"; dropped the columns of unselected joints {list(self.dropped)}"
        if self.ignored:
            text += f"; ignored columns {list(self.ignored)}"
        if any(_DQ_SIGN.fullmatch(c.lower()) for c in self.ignored):
            text += (" (dq_sign…: a consistid Dataset's Coulomb signal through its torque filter; "
                     "consistid.Dataset.load keeps it, and a Coulomb term fitted without it is "
                     "biased low on filtered torques)")
        return text


def check_selection(joints: object, columns: object) -> None:
    """:class:`OptionError` unless ``joints`` is ``None`` or a collection of names (a list, a
    tuple, ``df.columns``, ``dict.keys()`` …; not a single string, which would be read letter
    by letter) and ``columns`` ``None`` or a mapping."""
    if isinstance(joints, (str, bytes)):
        raise OptionError(f"joints= must be a list of joint names (e.g. joints=[{joints!r}]), got "
                          f"the string {joints!r}")
    if joints is not None and not isinstance(joints, Iterable):
        raise OptionError(f"joints= must be a list of joint names, got {joints!r}")
    if columns is not None and not isinstance(columns, Mapping):
        raise OptionError("columns= must be a mapping from fields to column names (e.g. "
                          f"columns={{'t': 'stamp', 'q': 'pos_{{joint}}'}}), got {columns!r}")


def map_columns(names: Sequence[str], source: str, *, joints: Sequence[str] | None = None,
                columns: Mapping[str, str | Sequence[str]] | None = None,
                first_row: Sequence[str] | None = None) -> ColumnMap:
    """The :class:`ColumnMap` of a table with column ``names`` (module docstring); without
    ``columns``, a logger's own layout is recognised first
    (:mod:`~consistid.data.formats.presets`; ``first_row``, the cells of the first data row,
    gives the joint names a ROS ``JointState`` log writes in its rows).

    Raises :class:`MissingColumnsError` naming the file, the field or joint that has no column
    and the columns the file has.
    """
    names = [str(n) for n in names]
    have = f"; the columns are {names}"
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise MissingColumnsError(f"{source}: column name(s) {dup} appear more than once")
    joints = None if joints is None else [str(j) for j in joints]
    if not columns:
        preset = match_preset(names, first_row)
        if preset is not None:
            return _preset_map(preset, names, source, joints)
    if columns:
        unknown = sorted(set(columns) - {"t", *FIELDS})
        if unknown:
            raise MissingColumnsError(f"{source}: columns= keys {unknown} are not t, q, dq, ddq, "
                                      "tau")
        explicit = {f: _template(v, joints, f, source) for f, v in columns.items() if f != "t"}
        for f, cols in explicit.items():
            missing = [c for c in cols if c not in names]
            if missing:
                raise MissingColumnsError(f"{source}: columns[{f!r}] names {missing}, which the "
                                          f"file lacks{_base_hint(columns[f], joints, names)}"
                                          f"{have}")
        lengths = {len(c) for c in explicit.values()}
        if len(lengths) > 1:
            raise MissingColumnsError(f"{source}: columns= gives different joint counts "
                                      f"{ {f: len(c) for f, c in explicit.items()} }")
    else:
        explicit = {}
    # time
    if columns and "t" in columns:
        time = str(columns["t"])
        if time not in names:
            raise MissingColumnsError(f"{source}: columns['t'] = {time!r} is not a column{have}")
        unit = time_unit_of(time)[1]
    else:
        found = [(n, time_unit_of(n)[1]) for n in names if time_unit_of(n)[0]]
        if not found:
            raise MissingColumnsError(f"{source}: no time column (t, time, timestamp, stamp, "
                                      f"time_ms …){have}; pass columns={{'t': 'name'}}")
        time, unit = found[0]
    # per-joint columns
    parsed: dict[str, dict[str | int, str]] = {f: {} for f in FIELDS}
    used = {time} | {c for cols in explicit.values() for c in cols}
    by_name = {j.lower(): j for j in joints} if joints else {}
    for n in names:
        if n in used:
            continue
        bare = n.strip()
        found = parse_candidates(n)
        if joints:
            _check_number_names(n, found, joints, by_name, source)
        if joints and bare in joints:
            p = ("q", bare)                           # a joint's own name: its position
        elif joints and any(isinstance(j, str) and j.lower() in by_name for _, j in found):
            p = next((f, j) for f, j in found if isinstance(j, str) and j.lower() in by_name)
        elif found:
            p = found[0]
        elif not joints and re.search(r"joint|^j\d+$", bare, re.I):
            p = ("q", bare)
        else:
            continue
        f, j = p
        if isinstance(j, str) and j.lower() in by_name:
            j = by_name[j.lower()]
        if j in parsed[f]:
            raise MissingColumnsError(f"{source}: columns {parsed[f][j]!r} and {n!r} are both "
                                      f"{f} of joint {j!r}; pass columns= to choose")
        parsed[f][j] = n
    fields: dict[str, list[str]] = {}
    dropped: list[str] = []
    if explicit:
        fields = dict(explicit)
        names_out = tuple(joints) if joints else None
        for f in FIELDS:
            if f not in fields and parsed[f] and joints:
                if all(j in parsed[f] for j in joints):
                    fields[f] = [parsed[f][j] for j in joints]
    else:
        if not parsed["q"] and joints:
            foreign = [n for n in names if n not in used
                       and re.search(r"joint|^j\d+$", n.strip(), re.I)]
            if foreign:
                raise JointNameError(
                    f"{source}: the columns {foreign[:6]}{' …' if len(foreign) > 6 else ''} "
                    f"name joints the model does not have; its joints are {list(joints)}. Load "
                    "the model of the robot that wrote this log, or map the columns by hand "
                    "(columns={'q': [...], 'tau': [...]}, one column per model joint)")
        if not parsed["q"]:
            raise MissingColumnsError(f"{source}: no joint position columns (q1.., q_<joint>, "
                                      f"<joint>.q, position_<joint>, or joint-name headers){have}"
                                      "; pass columns={'q': [...]} ")
        keys = list(parsed["q"])
        kinds = {type(k) for k in keys}
        if len(kinds) > 1:
            raise MissingColumnsError(f"{source}: position columns mix numbered and named joints "
                                      f"{[parsed['q'][k] for k in keys]}; pass columns=")
        if kinds == {int}:
            keys = sorted(keys)
            if keys != list(range(len(keys))):
                raise MissingColumnsError(f"{source}: numbered position columns are not q1..qn: "
                                          f"{[parsed['q'][k] for k in keys]}")
            if joints is not None and len(joints) != len(keys):
                raise MissingColumnsError(f"{source}: {len(keys)} numbered joint columns but "
                                          f"joints= names {len(joints)}: {joints}")
            selected: list = keys
            names_out = tuple(joints) if joints is not None else None
        else:
            if joints is not None:
                missing = [j for j in joints if j not in parsed["q"]]
                if missing:
                    raise MissingColumnsError(f"{source}: no position column for joint(s) "
                                              f"{missing}{have}")
                selected = list(joints)
            else:
                selected = keys
            names_out = tuple(str(j) for j in selected)
        for f in FIELDS:
            if not parsed[f]:
                continue
            missing = [j for j in selected if j not in parsed[f]]
            if missing and f in ("q", "tau"):
                label = [(k + 1 if isinstance(k, int) else k) for k in missing]
                raise MissingColumnsError(f"{source}: {f} columns lack joint(s) {label} (the "
                                          f"{f} columns are {list(parsed[f].values())}){have}")
            if not missing:
                fields[f] = [parsed[f][j] for j in selected]
            dropped += [c for j, c in parsed[f].items() if j not in selected]
    if "tau" not in fields:
        raise MissingColumnsError(f"{source}: no torque columns (tau.., effort_<joint>, "
                                  f"<joint>.torque …): identification needs measured torques{have}")
    if "q" not in fields:
        raise MissingColumnsError(f"{source}: no position columns{have}")
    read = {time} | {c for cols in fields.values() for c in cols} | set(dropped)
    ignored = tuple(n for n in names if n not in read)
    return ColumnMap(time, fields, names_out, unit, tuple(dropped), ignored)


def _preset_map(match: PresetMatch, names: Sequence[str], source: str,
                joints: Sequence[str] | None) -> ColumnMap:
    """The :class:`ColumnMap` of a recognised logger's table; ``joints`` select by name when
    the log names its joints, else must be as many as its numbered columns."""
    count = len(match.fields["q"])
    label = f"{match.preset.label} (joints numbered from {match.base})"
    names_out, keep = match.joint_names, list(range(count))
    if joints is not None and match.joint_names is not None:
        missing = [j for j in joints if j not in match.joint_names]
        if missing:
            raise JointNameError(f"{source} ({match.preset.label}) has no joint(s) {missing}; "
                                 f"its joints are {list(match.joint_names)}")
        keep = [match.joint_names.index(j) for j in joints]
        names_out = tuple(joints)
    elif joints is not None:
        if len(joints) != count:
            raise MissingColumnsError(f"{source} ({match.preset.label}): {count} numbered joint "
                                      f"columns but joints= names {len(joints)}: {list(joints)}; "
                                      "pass columns= to choose")
        names_out = tuple(joints)
    fields = {f: [cols[k] for k in keep] for f, cols in match.fields.items()}
    dropped = tuple(c for cols in match.fields.values() for k, c in enumerate(cols)
                    if k not in keep)
    unit = match.preset.time_unit or time_unit_of(match.time)[1]
    read = {match.time, *match.names_columns, *dropped} | {c for v in fields.values() for c in v}
    notes = match.notes
    if match.names_columns:
        notes = (*notes, f"joint names from the first row of {match.names_columns[0]!r}…")
    if match.joint_names is not None and len(keep) < count:
        notes = (*notes, "joints not selected: "
                 f"{[n for k, n in enumerate(match.joint_names) if k not in keep]}")
    return ColumnMap(match.time, fields, names_out, unit, dropped,
                     tuple(n for n in names if n not in read), label, tuple(notes))


def _check_number_names(column: str, found: list[tuple[str, str | int]], joints: list[str],
                        by_name: Mapping[str, str], source: str) -> None:
    """:class:`MissingColumnsError` when ``column`` reads as two different joints: by number
    (``q_1``: the first joint) and by name (a joint called ``"1"`` that is not the first)."""
    for f, j in found:
        if not isinstance(j, int) or not 0 <= j < len(joints):
            continue
        named = [by_name[str(k).lower()] for g, k in found
                 if g == f and isinstance(k, str) and str(k).lower() in by_name]
        if named and named[0] != joints[j]:
            raise MissingColumnsError(
                f"{source}: column {column!r} is ambiguous: by number it is the {f} of joint "
                f"{j + 1} ({joints[j]!r}), by name the {f} of joint {named[0]!r}; the joints' "
                "names are numbers in another order. Map the columns by hand: columns={"
                f"'{f}': [...]}} in the joints' order {joints}")


#: SI spellings of each field's unit in a ``name [unit]`` header: read as they are.
SI_UNITS: dict[str, tuple[str, ...]] = {
    "q": ("rad", "m"), "dq": ("rad/s", "m/s"), "ddq": ("rad/s^2", "rad/s2", "rad/s²", "m/s^2",
                                                     "m/s2", "m/s²"),
    "tau": ("nm", "n.m", "n*m", "n m", "n·m", "newton-metre", "newton-meter", "n")}
#: Degree spellings of each angular field's unit, converted by π/180 (and said so).
DEGREE_UNITS: dict[str, tuple[str, ...]] = {
    "q": ("deg", "degree", "degrees", "°"), "dq": ("deg/s", "°/s", "degree/s"),
    "ddq": ("deg/s^2", "deg/s2", "deg/s²", "°/s^2", "°/s²")}


#: Milli spellings of the torque's unit, converted by 1e-3 (and said so).
MILLI_UNITS: dict[str, tuple[str, ...]] = {"tau": ("mnm", "mn.m", "mn*m", "mn m", "mn·m")}


def column_unit(name: str) -> str | None:
    """The unit written in brackets at the end of a column name (``"q1 [deg]"`` → ``"deg"``),
    lower case without spaces at the ends, or after an underscore (``"q1_deg"`` → ``"deg"``,
    :data:`SUFFIX_UNITS`), or ``None``."""
    m = re.search(r"[\[(]([^\])]*)[\])]\s*$", str(name).strip())
    if m and _BRACKET_UNIT.search(str(name).strip()):
        return m.group(1).strip().lower()
    return _strip_suffix_unit(str(name).strip().strip('"').strip("'"))[1]


def unit_factor(field_name: str, column: str, source: str) -> tuple[float, str | None]:
    """``(factor to SI, note)`` for a per-joint column whose header names a unit: 1 for SI,
    π/180 for degrees of an angle, 1e-3 for mN·m (both noted), :class:`DatasetError` for any
    other unit, which consistid will not guess (convert the column, or rename it without the
    unit)."""
    unit = column_unit(column)
    if unit is None or unit in SI_UNITS[field_name]:
        return 1.0, None
    if unit in DEGREE_UNITS.get(field_name, ()):
        return float(np.pi / 180.0), f"{column!r} in {unit}: converted to radians"
    if unit in MILLI_UNITS.get(field_name, ()):
        return 1e-3, f"{column!r} in {unit}: converted to N·m"
    raise DatasetError(f"{source}, column {column!r}: unit [{unit}] is not one consistid "
                       f"reads for {field_name} (SI: {', '.join(SI_UNITS[field_name])}"
                       + (f"; degrees: {', '.join(DEGREE_UNITS[field_name])}"
                          if field_name in DEGREE_UNITS else "")
                       + (f"; milli: {', '.join(MILLI_UNITS[field_name])}"
                          if field_name in MILLI_UNITS else "")
                       + "); convert the column to SI units or name its unit")


def log_from_columns(get, cmap: ColumnMap, source: str, n_rows: int,
                     rows: np.ndarray | None = None, extra_notes: Sequence[str] = ()) -> Log:
    """A :class:`Log` from a column getter ``get(name) -> (N,) array`` and a column map;
    non-numeric or non-finite values raise :class:`DatasetError` naming the file, the column and
    the row (or line)."""

    def column(name: str) -> np.ndarray:
        a = np.asarray(get(name))
        if a.dtype.kind == "M":
            return a
        try:
            a = a.astype(float)
        except (TypeError, ValueError):
            for k, v in enumerate(a):
                try:
                    float(v)
                except (TypeError, ValueError):
                    where = f"line {int(rows[k])}" if rows is not None else f"row {k}"
                    raise DatasetError(f"{source}, {where}, column {name!r}: {v!r} is not a "
                                       "number") from None
            raise
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size and bad.size == a.size and a.size > 1:
            raise DatasetError(f"{source}, column {name!r}: every one of its {a.size} values is "
                               "empty or NaN: the logger did not record it. Log that signal, or "
                               "leave the joint out (joints=[...]; a model with that joint "
                               "locked)")
        if bad.size:
            k = int(bad[0])
            where = f"line {int(rows[k])}" if rows is not None else f"row {k}"
            what = "an empty cell or NaN" if np.isnan(a[k]) else "infinite"
            raise DatasetError(f"{source}, {where}, column {name!r}: {what} ({bad.size} "
                               f"non-finite value(s) in that column); repair or drop those rows")
        return a

    check_resolution(np.asarray(get(cmap.time)), f"{source}, column {cmap.time!r}")
    t = column(cmap.time)
    fields, unit_notes = {}, []
    for f, cols in cmap.fields.items():
        factors = [unit_factor(f, c, source) for c in cols]
        unit_notes += [note for _, note in factors if note]
        fields[f] = np.column_stack([column(c) * k for c, (k, _) in zip(cols, factors)])
    if t.size != n_rows or t.size == 0:
        raise DatasetError(f"{source}: no data rows")
    notes = (cmap.describe(source), *unit_notes, *extra_notes)
    named = tuple(f for f, cols in cmap.fields.items()
                  if any(column_unit(c) is not None for c in cols))
    return Log(t, fields, cmap.joint_names, source, notes, cmap.time_unit, rows,
               unit_fields=named, preset=cmap.preset)

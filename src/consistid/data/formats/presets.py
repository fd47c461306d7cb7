r"""Loggers recognised by their column names, without a column mapping.

A robot's own logger writes one column per joint and signal, numbered from 0 (``actual_q_0``,
``field.position0``, ``tau_J[0]``). When no ``columns=`` is given and a table's header holds a
logger's time column and its position and torque arrays, the columns are read as that logger
writes them (:func:`match_preset`) and the record says which logger was recognised:

==================  ==============================================  ===========================
preset              columns                                         time
==================  ==============================================  ===========================
``ur_rtde``         Universal Robots RTDE recorder
                    (``record_data.py``, ``rtde_control``):
                    ``actual_q_i``, ``actual_qd_i``, torque from    ``timestamp`` (s since the
                    ``actual_current_as_torque_i`` (PolyScope ≥      controller started)
                    5.23) or else ``target_moment_i`` (the
                    commanded torque its current loop tracks)
``franka_ros``      ``rostopic echo -p`` of franka_ros'             ``field.header.stamp`` or
                    ``FrankaState``: ``field.q0``, ``field.dq0``,   ``%time`` (ns)
                    ``field.tau_J0`` …
``libfranka``       a libfranka ``RobotState`` log: ``q_0``/        ``time``, ``t`` or
                    ``q[0]``, ``dq_0``, ``tau_J_0``                 ``timestamp`` (unit as the
                                                                    column names it)
``ros_joint_states`` ``rostopic echo -p`` of ``sensor_msgs/          ``field.header.stamp`` or
                    JointState``: ``field.name0`` (joint names,     ``%time`` (ns)
                    read from the first row), ``field.position0``,
                    ``field.velocity0``, ``field.effort0``
==================  ==============================================  ===========================

Indices count from 0 or from 1 (one base per file, the same for every array). Set-points
(``target_q``, ``q_d``, ``tau_J_d``), currents in amperes and every other column are listed as
ignored; ``tau_J_d`` (franka's desired torque) is never read as a measurement.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Mapping, Sequence


@dataclass(frozen=True)
class Preset:
    """How one logger names its columns.

    Attributes
    ----------
    name, label : short name and how the record names the logger.
    time : candidate time columns, the first present is read.
    time_unit : the unit of those stamps when the logger fixes it (``None``: as the column
        name says, :func:`~consistid.data.formats.columns.time_unit_of`).
    arrays : dataset field → candidate array names, the first present is read.
    prefix : written before every array name (``"field."`` for ``rostopic echo -p``).
    names_array : the array whose cells (first row) name the joints, if any.
    notes : array name → what the record says about reading it.
    """

    name: str
    label: str
    time: tuple[str, ...]
    time_unit: str | None
    arrays: Mapping[str, tuple[str, ...]]
    prefix: str = ""
    names_array: str | None = None
    notes: Mapping[str, str] = field(default_factory=dict)


PRESETS: tuple[Preset, ...] = (
    Preset("ur_rtde", "a Universal Robots RTDE recorder log", ("timestamp",), "s",
           {"q": ("actual_q",), "dq": ("actual_qd",),
            "tau": ("actual_current_as_torque", "target_moment")},
           notes={"target_moment": "target_moment is the controller's commanded joint torque, "
                                   "which its current loop tracks (not a torque measurement; "
                                   "log actual_current_as_torque where PolyScope has it)"}),
    Preset("franka_ros", "a franka_ros FrankaState log (rostopic echo -p)",
           ("field.header.stamp", "%time"), "ns",
           {"q": ("q",), "dq": ("dq",), "tau": ("tau_J",)}, prefix="field."),
    Preset("libfranka", "a libfranka RobotState log", ("time", "t", "timestamp"), None,
           {"q": ("q",), "dq": ("dq",), "tau": ("tau_J",)}),
    Preset("ros_joint_states", "a ROS JointState log (rostopic echo -p)",
           ("field.header.stamp", "%time"), "ns",
           {"q": ("position",), "dq": ("velocity",), "tau": ("effort",)}, prefix="field.",
           names_array="name"),
)


@dataclass(frozen=True)
class PresetMatch:
    """A header read as a :class:`Preset` writes it: ``fields[f][k]`` is the column of field
    ``f`` for the ``k``-th joint; ``joint_names`` from the log (``None``: numbered only);
    ``base`` the first index; ``notes`` what the record should say."""

    preset: Preset
    time: str
    fields: dict[str, list[str]]
    joint_names: tuple[str, ...] | None
    base: int
    notes: tuple[str, ...]
    names_columns: tuple[str, ...] = ()


def indexed_columns(names: Sequence[str], array: str) -> dict[int, str]:
    """Index → column of the columns ``<array><k>``, ``<array>_<k>``, ``<array>.<k>`` or
    ``<array>[<k>]`` (case-insensitive)."""
    pattern = re.compile(rf"{re.escape(array)}(?:[_.]?(\d+)|\[(\d+)\])", re.I)
    out: dict[int, str] = {}
    for n in names:
        m = pattern.fullmatch(str(n).strip())
        if m:
            out[int(m.group(1) or m.group(2))] = n
    return out


def _contiguous(found: dict[int, str]) -> int | None:
    """The first index when the indices run ``b, b+1, …`` from ``b`` ∈ {0, 1}, else ``None``."""
    keys = sorted(found)
    if keys and keys[0] in (0, 1) and keys == list(range(keys[0], keys[0] + len(keys))):
        return keys[0]
    return None


def match_preset(names: Sequence[str], first_row: Sequence[str] | None = None
                 ) -> PresetMatch | None:
    """The first :data:`PRESETS` logger whose time column, position array and torque array
    are all in the header ``names`` (contiguous indices, one base, one count), else ``None``.
    ``first_row`` (the cells of the first data row) gives the joint names of a preset with a
    ``names_array``."""
    for preset in PRESETS:
        time = next((t for t in preset.time if t in names), None)
        if time is None:
            continue
        fields, notes, base, count = {}, [], None, None
        for f, candidates in preset.arrays.items():
            for array in candidates:
                found = indexed_columns(names, preset.prefix + array)
                b = _contiguous(found)
                if b is None or (base is not None and (b, len(found)) != (base, count)):
                    continue
                base, count = b, len(found)
                fields[f] = [found[k] for k in sorted(found)]
                if array in preset.notes:
                    notes.append(preset.notes[array])
                break
        if "q" not in fields or "tau" not in fields:
            continue
        joint_names, named = None, ()
        if preset.names_array is not None:
            found = indexed_columns(names, preset.prefix + preset.names_array)
            if first_row is not None and len(found) == count and _contiguous(found) == base:
                named = tuple(found[k] for k in sorted(found))
                joint_names = tuple(str(first_row[list(names).index(c)]).strip().strip('"')
                                    for c in named)
        return PresetMatch(preset, time, fields, joint_names, base, tuple(notes), named)
    return None

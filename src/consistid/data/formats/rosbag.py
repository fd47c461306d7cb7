r"""ROS bags of ``sensor_msgs/JointState``: ROS 2 bags (a folder with ``metadata.yaml``, SQLite
``.db3`` or ``.mcap`` storage), bare ``.mcap`` files and ROS 1 ``.bag`` files, read with the
pure-Python ``rosbags`` package (the ``[io]`` extra).

One ``JointState`` topic is read (``topic=``; by default the only one in the bag). Each message
carries ``name``, ``position``, ``velocity`` and ``effort`` arrays; joints are matched *by name*
in every message, so messages may list them in any order, and messages that lack a selected
joint (e.g. a gripper driver publishing its own ``JointState`` on the same topic) are skipped and
counted in the record. Samples are stamped with ``header.stamp`` (``stamp="header"``, the
default, as ROS drivers stamp the reading) or the time the recorder received the message
(``stamp="receive"``; also used, and said, when every header stamp is zero). Velocities are
read when every kept message has them; efforts are the torques: messages without them (a driver
starting up) are skipped and counted, and a bag with none is refused.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ...errors import DatasetError, MissingColumnsError, MissingDependencyError, check_option
from ...progress import Progress, ProgressArg
from .columns import Log

JOINT_STATE = ("sensor_msgs/msg/JointState", "sensor_msgs/JointState")
STAMPS = ("header", "receive")


def _reader(path: Path):
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise MissingDependencyError("reading ROS bags and MCAP needs rosbags: pip install "
                                     "'consistid[io]' (or pip install rosbags)") from None
    try:
        return AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
    except Exception as exc:                      # rosbags raises its own error classes
        raise DatasetError(f"{path.name} is not a readable ROS bag: {exc}") from None


def _deserialize(reader: Any, raw: bytes, conn: Any, source: str, k: int) -> Any:
    """Message ``k`` of ``conn``, or :class:`DatasetError` naming it when rosbags cannot decode
    it (an unsupported CDR encapsulation, a truncated or foreign message)."""
    try:
        return reader.deserialize(raw, conn.msgtype)
    except Exception as exc:        # rosbags raises its own SerdeError and plain ones
        raise DatasetError(f"{source}, {conn.topic} message {k} ({conn.msgtype}) cannot be "
                           f"decoded: {type(exc).__name__}: {exc}; the bag's serialization "
                           "(e.g. its CDR encapsulation) is not one rosbags reads: re-record "
                           "or convert it (ros2 bag convert)") from None


def read_bag(path: str | Path, *, joints: Sequence[str] | None = None, topic: str | None = None,
             stamp: str = "header", progress: ProgressArg = None) -> Log:
    """Read ``JointState`` messages of a ROS 1/2 bag or MCAP file into a
    :class:`~consistid.data.formats.columns.Log` (module docstring).

    Parameters
    ----------
    path : a ``.bag`` / ``.mcap`` / ``.db3`` file or a ROS 2 bag folder.
    joints : joints to keep, in this order; default every joint of the first message.
    topic : the ``JointState`` topic; default the only one.
    stamp : ``"header"`` or ``"receive"``.
    progress : ``None`` (a bar over the messages when stderr is a terminal), ``True``,
        ``False`` or a callable given a line per step (:mod:`consistid.progress`).

    Raises
    ------
    DatasetError : not a bag; no ``JointState`` topic, or several and no ``topic=``; no
        message with every selected joint. MissingColumnsError : no efforts (torques).
    MissingDependencyError : rosbags is not installed.
    """
    check_option("stamp", stamp, STAMPS)
    path = Path(path)
    if not path.exists():
        raise DatasetError(f"bag {str(path)!r} does not exist")
    source = path.name
    reader = _reader(path)
    try:
        reader.open()
    except Exception as exc:
        raise DatasetError(f"{source} is not a readable ROS bag: {exc}") from None
    bar: Progress | None = None
    try:
        conns = [c for c in reader.connections if c.msgtype in JOINT_STATE]
        topics = sorted({c.topic for c in conns})
        if not topics:
            others = sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})
            raise DatasetError(f"{source} has no sensor_msgs/JointState topic; its topics are "
                               f"{others}")
        if topic is None:
            if len(topics) > 1:
                raise DatasetError(f"{source} has several JointState topics {topics}; pass "
                                   "topic=")
            topic = topics[0]
        elif topic not in topics:
            raise DatasetError(f"{source}: topic {topic!r} is not a JointState topic; those are "
                               f"{topics}")
        conns = [c for c in conns if c.topic == topic]
        header_t, receive_t, pos, vel, eff = [], [], [], [], []
        selected = list(joints) if joints is not None else None
        skipped, n_msgs = 0, 0
        seen: set[str] = set()
        total = sum(int(getattr(c, "msgcount", 0) or 0) for c in conns) or None
        chunk = max(1000, (total or 0) // 100)          # at most ~100 updates
        bar = Progress(progress, total, f"reading {source}", "msg")
        for conn, t_recv, raw in reader.messages(connections=conns):
            n_msgs += 1
            if n_msgs % chunk == 0:
                bar.step(n=chunk)
            msg = _deserialize(reader, raw, conn, source, n_msgs - 1)
            names = [str(n) for n in msg.name]
            if len(set(names)) != len(names):
                twice = sorted({n for n in names if names.count(n) > 1})
                raise DatasetError(f"{source}, {topic} message {n_msgs - 1}: joint name(s) "
                                   f"{twice} appear more than once in one message; which value "
                                   "is the joint's is undefined: fix the driver's names")
            seen.update(names)
            if selected is None:
                selected = names
            where = {n: i for i, n in enumerate(names)}
            if not all(j in where for j in selected):
                skipped += 1
                continue
            idx = [where[j] for j in selected]
            p, v, e = (np.asarray(a, dtype=float) for a in (msg.position, msg.velocity,
                                                             msg.effort))
            if p.size != len(names):
                raise DatasetError(f"{source}, {topic} message {n_msgs - 1}: {p.size} positions "
                                   f"for {len(names)} names")
            pos.append(p[idx])
            vel.append(v[idx] if v.size == len(names) else None)
            eff.append(e[idx] if e.size == len(names) else None)
            s = msg.header.stamp
            header_t.append(int(s.sec) * 10 ** 9 + int(s.nanosec))
            receive_t.append(int(t_recv))
    finally:
        if bar is not None:
            bar.close()
        reader.close()
    if n_msgs == 0:
        raise DatasetError(f"{source}: topic {topic!r} has no messages")
    if not pos:
        missing = sorted(set(selected or []) - seen)
        hint = ("" if missing else ": every selected joint is published, but in separate "
                "messages (one per controller or driver, each with some of the joints). "
                "consistid reads one message per sample with every joint: merge them onto common "
                "stamps first (e.g. into a CSV or DataFrame), or select the joints of one "
                "message (joints=[...] with a model that locks the others)")
        raise DatasetError(f"{source}: no {topic} message has every selected joint (missing "
                           f"everywhere: {missing}; names seen: {sorted(seen)}){hint}")
    no_effort = [k for k, e in enumerate(eff) if e is None]
    if len(no_effort) == len(eff):
        raise MissingColumnsError(f"{source}: every {topic} message has no effort for the "
                                  "selected joints: the log has no torques to identify from")
    if no_effort:       # e.g. a driver's first messages, before its torque sensing is up
        keep = [k for k, e in enumerate(eff) if e is not None]
        header_t, receive_t, pos, vel, eff = ([a[k] for k in keep] for a in
                                              (header_t, receive_t, pos, vel, eff))
    notes = [f"read {source}: topic {topic!r} (sensor_msgs/JointState), {len(pos)} of {n_msgs} "
             f"messages, joints {list(selected)}"]
    if skipped:
        notes.append(f"{skipped} message(s) without every selected joint skipped (e.g. another "
                     "driver's joints on the same topic)")
    if no_effort:
        notes.append(f"{len(no_effort)} message(s) without an effort for every joint skipped "
                     f"(kept messages {no_effort[0]}–{no_effort[-1]}; e.g. a driver starting up): "
                     "no torque to fit there")
    dropped = sorted(seen - set(selected))
    if dropped:
        notes.append(f"dropped the unselected joints {dropped}")
    stamps = np.array(header_t if stamp == "header" else receive_t, dtype=np.int64)
    if stamp == "header" and not np.any(stamps):
        stamps = np.array(receive_t, dtype=np.int64)
        notes.append("every header.stamp is zero: samples stamped with the receive time")
    else:
        which = "header.stamp" if stamp == "header" else "receive time"
        notes.append(f"samples stamped with the {which}")
    # integer nanoseconds: subtract the origin before going to float (keeps ns resolution)
    t0 = int(stamps[0])
    t = (stamps - t0).astype(float) * 1e-9
    fields = {"q": np.vstack(pos), "tau": np.vstack(eff)}
    if all(v is not None for v in vel):
        fields["dq"] = np.vstack(vel)
    for f, ros in (("q", "position"), ("tau", "effort"), ("dq", "velocity")):
        bad = np.argwhere(~np.isfinite(fields[f])) if f in fields else np.zeros((0, 2))
        if bad.size:
            k, j = (int(i) for i in bad[0])
            raise DatasetError(f"{source}, {topic} message {k} (of the kept ones): {ros} of "
                               f"joint {selected[j]!r} is {fields[f][k, j]} ({len(bad)} "
                               f"non-finite {ros} value(s))")
    return Log(t, fields, tuple(selected), source, tuple(notes), "s", origin=t0 * 1e-9)

"""Datasets: joint positions, velocities, accelerations and torques along time, validated.

A :class:`Dataset` holds arrays with samples along axis 0 (``q.shape == (N, nv)``). It is
immutable: every operation returns a new dataset. Recordings stacked with
:meth:`Dataset.concatenate` keep a ``segment`` index per sample, so that a split or a filter never
mixes two recordings.

File formats
------------
NPZ
    arrays ``t, q, dq, ddq, tau`` (optionally ``segment`` and ``joint_names``).
CSV
    a header line and one row per sample; columns ``t``, ``q1..qn``, ``dq1..dqn``, ``ddq1..ddqn``,
    ``tau1..taun`` (1-based joint index), optionally ``segment``. Column order is free.

These are the dataset's own files. A robot's log (CSV with joint names, Parquet, ROS bags, MCAP,
``.mat``) is read by :func:`consistid.data.recordings.load_recording`.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Sequence

import numpy as np

from ..errors import DatasetError, JointCountError, JointNameError, MissingColumnsError
from .chain import ChainResult, PreprocessOptions, run_chain
from .filters import real_array
from ..filesafety import replacing
from .npzfile import open_npz
from .parallel import check_filter
from .timestamps import check_resolution

FIELDS = ("q", "dq", "ddq", "tau")


def _check_below_nyquist(data: "Dataset", source: str) -> None:
    """A saved ``identification_filter`` (applied to these samples' regressor rows later, so
    its cut-off must lie below the Nyquist frequency ``1 / (2 Δt)`` of their median step); a
    file that says otherwise was edited or corrupted (:class:`DatasetError`)."""
    flt = data.identification_filter
    if flt is None or data.t.size < 2:
        return
    step = float(np.median(np.diff(data.t)))
    if step > 0 and flt[0] >= 0.5 / step:
        raise DatasetError(f"{source}: identification_filter = {flt}: its cut-off {flt[0]:g} Hz "
                           f"is not below the Nyquist frequency {0.5 / step:g} Hz of the "
                           f"samples (step {step:g} s); the file is corrupt: drop that array")


def _check_finite(name: str, a: np.ndarray, joint_names: Sequence[str] | None) -> None:
    bad = np.argwhere(~np.isfinite(a))
    if bad.size:
        idx = tuple(int(i) for i in bad[0])
        what = "NaN" if np.isnan(a[idx]) else "infinite"
        where = f"{idx[0]}" if len(idx) == 1 else (
            f"{idx[0]}, {joint_names[idx[1]]!r}" if joint_names else f"{idx[0]}, {idx[1]}")
        raise DatasetError(f"dataset.{name}[{where}] is {what} ({len(bad)} non-finite value(s) "
                           f"in {name})")


@dataclass(frozen=True, eq=False)
class Dataset:
    """Samples of ``(t, q, dq, ddq, tau)``; validated on construction.

    Parameters
    ----------
    t : (N,) seconds, strictly increasing within each segment.
    q, dq, ddq : (N, nv) rad, rad/s, rad/s² (m, m/s, m/s² for prismatic joints).
    tau : (N, nv) joint torques in N·m (or forces in N), or ``None`` for a trajectory without
        measurements (e.g. a designed excitation).
    joint_names : optional names, used in error messages and reports.
    segment : (N,) integer recording index; default all zeros.
    dq_sign : (N, nv) ``sign(q̇)`` as the torque channel sees it, when the signal chain low-pass
        filtered the torques: the same filter applied to ``sign(q̇)`` (set by the chain,
        :mod:`consistid.data.chain`). The regressor's Coulomb column is this signal, so that
        both sides of ``τ = Y θ`` went through the same filter (parallel filtering; without it
        the sharp ``sign`` of the filtered ``q̇`` against the smoothed step in the filtered
        torque biases ``f_c`` low by ~10 % at a 5 Hz cut-off); ``None``: ``sign(dq)``.
    torque_filter : ``(cut-off Hz, order)`` of the zero-phase Butterworth low-pass
        (:func:`consistid.data.filters.lowpass`) the signal chain applied to ``tau`` (set by the
        chain at the dataset's rate); ``None``: unfiltered, or not known (the chain also leaves
        it out when it decimates after filtering). The diagnosis divides its response out of the
        torque spectrum for the noise floor (:mod:`consistid.diagnosis.noise`) and judges dry
        friction at rest through it (:mod:`consistid.diagnosis.remainder`). Kept by
        :meth:`select` (a selection at another spacing makes it wrong: consumers ignore a
        cut-off above 0.45 × the rate), by :meth:`concatenate` when every part has the same, and
        in ``.npz`` files (not in ``.csv``); dropped by :meth:`with_torque` unless asked.
    identification_filter : ``(cut-off Hz, order)`` of the zero-phase Butterworth low-pass that
        identification applies alike to ``tau`` and to every column of the regressor, per
        segment (parallel filtering, :mod:`consistid.data.parallel`), set by the signal chain at
        a few times the motion's band; ``None``: least squares on the samples as they are. Kept
        by :meth:`select` (a selection that leaves holes splits the filtering there), by
        :meth:`with_torque` (it applies to any torques), by :meth:`concatenate` when every part
        has one (the highest: no part is filtered below its own), and in ``.npz`` files (not in
        ``.csv``).

    Raises
    ------
    DatasetError
        naming the field, the index and the problem (shape, NaN/inf, non-increasing time).
    """

    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray
    tau: np.ndarray | None = None
    joint_names: tuple[str, ...] | None = None
    segment: np.ndarray | None = field(default=None)
    dq_sign: np.ndarray | None = None
    torque_filter: tuple[float, int] | None = None
    identification_filter: tuple[float, int] | None = None

    def __post_init__(self) -> None:
        if self.t is not None and np.asarray(self.t).dtype.kind == "f":
            check_resolution(np.asarray(self.t), "dataset.t")     # float16 stamps
        t = real_array("dataset.t", self.t)
        if t.ndim != 1:
            raise DatasetError(f"dataset.t must be 1-D (N,), got shape {t.shape}")
        n = t.shape[0]
        if n == 0:
            raise DatasetError("dataset is empty (t has no samples)")
        object.__setattr__(self, "t", t)
        nv = None
        names = tuple(self.joint_names) if self.joint_names is not None else None
        if names is not None:
            if isinstance(self.joint_names, str):
                raise JointNameError(f"dataset.joint_names must be a list of names, got the "
                                     f"string {self.joint_names!r}")
            dup = sorted({str(n) for n in names if names.count(n) > 1})
            if dup:
                raise JointNameError(f"dataset.joint_names names {dup} more than once: "
                                     f"{list(names)}")
        object.__setattr__(self, "joint_names", names)
        for name in FIELDS:
            value = getattr(self, name)
            if value is None:
                if name != "tau":
                    raise DatasetError(f"dataset.{name} is missing")
                continue
            a = real_array(f"dataset.{name}", value)
            if a.ndim == 1:
                a = a[:, None]
            if a.ndim != 2 or a.shape[0] != n:
                raise DatasetError(f"dataset.{name} has shape {np.shape(value)}; expected "
                                   f"({n}, nv) to match t's {n} samples")
            if nv is None:
                nv = a.shape[1]
                if names is not None and len(names) != nv:
                    raise DatasetError(f"dataset.joint_names has {len(names)} names for {nv} "
                                       "joints")
            elif a.shape[1] != nv:
                raise DatasetError(f"dataset.{name} has {a.shape[1]} joints; dataset.q has {nv}")
            _check_finite(name, a, names)
            object.__setattr__(self, name, a)
        _check_finite("t", t, None)
        seg = np.zeros(n, dtype=int) if self.segment is None else np.asarray(self.segment)
        if seg.dtype.kind not in "biuf":
            raise DatasetError(f"dataset.segment holds {seg.dtype} values, not integer "
                               "recording indices")
        if seg.shape != (n,):
            raise DatasetError(f"dataset.segment has shape {seg.shape}; expected ({n},)")
        if seg.dtype.kind not in "iu":
            if not np.all(np.isfinite(seg)) or np.any(seg != np.round(seg)):
                k = int(np.flatnonzero(~np.isfinite(seg) | (seg != np.round(seg)))[0])
                raise DatasetError(f"dataset.segment[{k}] = {float(seg[k])} is not an integer "
                                   "recording index")
            seg = seg.astype(int)
        object.__setattr__(self, "segment", seg)
        if self.dq_sign is not None:
            sign = np.asarray(self.dq_sign, dtype=float)
            if sign.ndim == 1:
                sign = sign[:, None]
            if sign.shape != self.dq.shape:
                raise DatasetError(f"dataset.dq_sign has shape {sign.shape}; expected "
                                   f"{self.dq.shape} like dq")
            _check_finite("dq_sign", sign, names)
            object.__setattr__(self, "dq_sign", sign)
        if self.torque_filter is not None:
            object.__setattr__(self, "torque_filter",
                               check_filter("dataset.torque_filter", self.torque_filter))
        if self.identification_filter is not None:
            object.__setattr__(self, "identification_filter",
                               check_filter("dataset.identification_filter",
                                            self.identification_filter))
        same = seg[1:] == seg[:-1]
        bad = np.flatnonzero(same & (np.diff(t) <= 0))
        if bad.size:
            k = int(bad[0]) + 1
            raise DatasetError(f"dataset.t[{k}] = {t[k]!r} is not after t[{k - 1}] = {t[k - 1]!r}: "
                               "time must be strictly increasing")

    # ----------------------------------------------------------------------------- basics
    @property
    def n_samples(self) -> int:
        return int(self.t.shape[0])

    @property
    def nv(self) -> int:
        return int(self.q.shape[1])

    def __len__(self) -> int:
        return self.n_samples

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    def require_torque(self) -> np.ndarray:
        if self.tau is None:
            raise DatasetError("dataset.tau is missing: this operation needs measured torques")
        return self.tau

    def check_joints(self, nv: int, joint_names: Sequence[str] | None = None) -> None:
        """Raise :class:`JointCountError` unless the dataset has ``nv`` joints, and
        :class:`JointNameError` when both sides name their joints and the names differ."""
        if self.nv != nv:
            where = f" ({', '.join(joint_names)})" if joint_names else ""
            raise JointCountError(f"dataset has {self.nv} joints but the model has {nv}{where}")
        if joint_names is not None and self.joint_names is not None \
                and tuple(joint_names) != self.joint_names:
            raise JointNameError(f"dataset joints {list(self.joint_names)} differ from the "
                                 f"model's {list(joint_names)} (same count, other names or "
                                 "order)")

    def fingerprint(self) -> str:
        """A digest (BLAKE2b) of ``t``, ``q`` and ``tau``: equal for the same recording given
        twice, whatever the object."""
        h = hashlib.blake2b(digest_size=16)
        for a in (self.t, self.q, self.tau):
            if a is not None:
                h.update(np.ascontiguousarray(a).tobytes())
                h.update(str(a.shape).encode())
        return h.hexdigest()

    def select(self, index: np.ndarray | slice) -> "Dataset":
        """The samples at ``index`` (boolean mask, integer array or slice)."""
        return replace(self, t=self.t[index], q=self.q[index], dq=self.dq[index],
                       ddq=self.ddq[index], tau=None if self.tau is None else self.tau[index],
                       segment=self.segment[index],
                       dq_sign=None if self.dq_sign is None else self.dq_sign[index])

    def with_torque(self, tau: np.ndarray, keep_filter: bool = False) -> "Dataset":
        """The same samples with the torques ``tau``. Their :attr:`torque_filter` is dropped
        unless ``keep_filter`` (the new torques went through the same low-pass, e.g. the old
        ones minus a correction filtered alike): torques made elsewhere (simulated, raw plus
        noise) did not."""
        return replace(self, tau=tau, torque_filter=self.torque_filter if keep_filter else None)

    # ----------------------------------------------------------------------------- splitting
    def split(self, fraction: float = 0.7) -> tuple["Dataset", "Dataset"]:
        """Split into (train, held-out) by time: the first ``fraction`` of each segment trains.

        Use :meth:`split_segments` to hold out whole recordings instead.
        """
        if not 0.0 < fraction < 1.0:
            raise DatasetError(f"split fraction must lie in (0, 1), got {fraction}")
        train = np.zeros(self.n_samples, dtype=bool)
        for s in np.unique(self.segment):
            idx = np.flatnonzero(self.segment == s)
            cut = self.t[idx[0]] + fraction * (self.t[idx[-1]] - self.t[idx[0]])
            train[idx[self.t[idx] <= cut]] = True
        if train.all() or not train.any():
            raise DatasetError("split leaves one side empty; the dataset is too short")
        return self.select(train), self.select(~train)

    def split_segments(self, held_out: Sequence[int]) -> tuple["Dataset", "Dataset"]:
        """Split into (train, held-out) by recording: the segments in ``held_out`` are held out."""
        mask = np.isin(self.segment, list(held_out))
        if mask.all() or not mask.any():
            raise DatasetError(f"held-out segments {list(held_out)} leave one side empty; "
                               f"segments are {np.unique(self.segment).tolist()}")
        return self.select(~mask), self.select(mask)

    @staticmethod
    def concatenate(datasets: Sequence["Dataset"]) -> "Dataset":
        """Stack recordings; each becomes its own segment and time is shifted to stay increasing."""
        if not datasets:
            raise DatasetError("nothing to concatenate")
        nv, names = datasets[0].nv, datasets[0].joint_names
        parts, offset, seg0 = [], 0.0, 0
        for d in datasets:
            d.check_joints(nv, names)
            shift = offset - d.t[0] if parts else 0.0
            parts.append((d.t + shift, d, d.segment - d.segment.min() + seg0))
            offset = d.t[-1] + shift + (np.median(np.diff(d.t)) if d.n_samples > 1 else 1.0)
            seg0 = parts[-1][2].max() + 1
        has_tau = all(d.tau is not None for d in datasets)
        return Dataset(
            t=np.concatenate([p[0] for p in parts]),
            q=np.concatenate([d.q for d in datasets]),
            dq=np.concatenate([d.dq for d in datasets]),
            ddq=np.concatenate([d.ddq for d in datasets]),
            tau=np.concatenate([d.tau for d in datasets]) if has_tau else None,
            joint_names=datasets[0].joint_names,
            segment=np.concatenate([p[2] for p in parts]),
            dq_sign=None if all(d.dq_sign is None for d in datasets) else np.concatenate(
                [np.sign(d.dq) if d.dq_sign is None else d.dq_sign for d in datasets]),
            torque_filter=datasets[0].torque_filter
            if all(d.torque_filter == datasets[0].torque_filter for d in datasets) else None,
            identification_filter=_widest([d.identification_filter for d in datasets]),
        )

    # ----------------------------------------------------------------------------- files
    def columns(self) -> dict[str, np.ndarray]:
        """Named columns ``t, q1.., dq1.., ddq1.., tau1.., segment`` (CSV layout), then
        ``dq_sign1..`` when the dataset has them."""
        cols = {"t": self.t}
        for name in FIELDS:
            a = getattr(self, name)
            if a is not None:
                cols.update({f"{name}{j + 1}": a[:, j] for j in range(self.nv)})
        cols["segment"] = self.segment.astype(float)
        if self.dq_sign is not None:
            cols.update({f"dq_sign{j + 1}": self.dq_sign[:, j] for j in range(self.nv)})
        return cols

    def save(self, path: str | Path) -> None:
        """Write NPZ or CSV, chosen by the file suffix."""
        path = Path(path)
        if path.suffix == ".npz":
            arrays = {k: getattr(self, k) for k in ("t", *FIELDS, "dq_sign")
                      if getattr(self, k) is not None}
            if self.joint_names is not None:
                arrays["joint_names"] = np.array(self.joint_names)
            for name in ("torque_filter", "identification_filter"):
                if getattr(self, name) is not None:
                    arrays[name] = np.array(getattr(self, name), dtype=float)
            with replacing(path) as tmp:        # never a half-written archive
                np.savez(tmp, segment=self.segment, **arrays)
        elif path.suffix == ".csv":
            cols = self.columns()
            with replacing(path) as tmp:
                np.savetxt(tmp, np.column_stack(list(cols.values())), delimiter=",",
                           header=",".join(cols), comments="", fmt="%.17g")
        else:
            raise DatasetError(f"unknown dataset format {path.suffix!r}; use .npz or .csv")

    @classmethod
    def from_recording(cls, t: np.ndarray, q: np.ndarray, tau: np.ndarray, *,
                       joint_names: Sequence[str] | None = None, **options) -> "Dataset":
        """A dataset from a robot log: time stamps fixed, outliers removed, jittered stamps
        resampled at the rate the log supports, zero-phase filtered, ``dq`` and ``ddq``
        estimated (the default chain of :mod:`consistid.data.chain`; ``options`` are the fields
        of :class:`~consistid.data.chain.PreprocessOptions`, e.g. ``timestamp="end"`` for
        torques a logger averaged over each interval and stamped at its end, ``time_unit="ms"``).

        The steps applied are logged at INFO level on the ``consistid.data.chain`` logger;
        :func:`consistid.data.signals.preprocess` returns them with the dataset, and
        :func:`consistid.data.recordings.from_arrays` in a loader's record.
        """
        return cls.from_chain(run_chain(t, q, tau, PreprocessOptions.from_kwargs(options)),
                              joint_names)

    @classmethod
    def from_chain(cls, result: ChainResult, joint_names: Sequence[str] | None = None
                   ) -> "Dataset":
        """The dataset of the signal chain's arrays (:func:`consistid.data.chain.run_chain`)."""
        return cls(t=result.t, q=result.q, dq=result.dq, ddq=result.ddq, tau=result.tau,
                   segment=result.segment, dq_sign=result.dq_sign,
                   joint_names=tuple(joint_names) if joint_names is not None else None,
                   torque_filter=result.torque_filter,
                   identification_filter=result.identification_filter)

    @classmethod
    def load(cls, path: str | Path, joint_names: Sequence[str] | None = None) -> "Dataset":
        """Read a dataset written by :meth:`save` (or any file with the documented columns)."""
        path = Path(path)
        if path.is_dir():
            raise DatasetError(f"dataset file {str(path)!r} is a folder; name a .npz or .csv "
                               "file in it")
        if not path.is_file():
            raise DatasetError(f"dataset file {str(path)!r} does not exist")
        if path.suffix == ".npz":
            with open_npz(path) as f:
                missing = [k for k in ("t", "q", "dq", "ddq") if k not in f]
                if missing:
                    raise MissingColumnsError(f"{path.name} lacks arrays {missing}; it has "
                                              f"{sorted(f.files)}")
                arrays = {k: f[k] for k in f.files if k in ("t", *FIELDS, "segment", "dq_sign")}
                stored = array_names(f["joint_names"]) if "joint_names" in f else None
                for name in ("torque_filter", "identification_filter"):
                    if name in f:
                        arrays[name] = np.atleast_1d(f[name]).tolist()
            if joint_names is not None and stored is not None and tuple(joint_names) != stored:
                raise JointNameError(f"{path.name} names its joints {list(stored)}, not "
                                     f"{list(joint_names)}")
            out = cls(joint_names=joint_names if joint_names is not None else stored, **arrays)
            _check_below_nyquist(out, path.name)
            return out
        if path.suffix == ".csv":
            try:                        # a UTF-8 byte-order mark (Excel) is not a name
                with open(path, encoding="utf-8-sig") as fh:
                    header = fh.readline().strip().split(",")
            except UnicodeDecodeError as exc:
                raise DatasetError(f"{path.name}: the header line is not UTF-8 text ({exc}); "
                                   "a Dataset CSV's header is t, q1.., dq1.., ddq1.., tau1..; "
                                   "for a robot's log use consistid.load_recording") from None
            if len(header) < 2:
                raise MissingColumnsError(f"{path.name}: the header {header} is not a "
                                          "comma-separated Dataset CSV (t, q1.., dq1.., ddq1.., "
                                          "tau1..); for a robot's log use consistid.load_recording")
            try:
                data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
            except ValueError as exc:   # text or ragged rows
                raise DatasetError(f"{path.name}: the rows below the header are not all "
                                   f"numbers ({exc})") from None
            if data.shape[1] != len(header):
                raise MissingColumnsError(f"{path.name}: the header names {len(header)} "
                                          f"columns, the rows have {data.shape[1]}")
            col = {name.strip(): data[:, i] for i, name in enumerate(header)}
            named = [name[2:] for name in col if name.startswith("q_")]
            if named and not any(name.startswith("q") and name[1:].isdigit() for name in col):
                # columns named by joint (an excitation design's CSV): renamed q1.. in order
                if joint_names is not None and tuple(joint_names) != tuple(named):
                    raise JointNameError(f"{path.name} names its joints {named}, not "
                                         f"{list(joint_names)}")
                joint_names = tuple(named)
                col = {_numbered(name, named): v for name, v in col.items()}
            nv = sum(1 for name in col if name.startswith("q") and name[1:].isdigit())
            raw_log = ("; for a robot's log (joint names in the header, no dq/ddq, any "
                       "delimiter) use consistid.load_recording")
            if nv == 0:
                raise MissingColumnsError(f"{path.name} has no q1..qn columns; header is {header}"
                                          + raw_log)
            needed = ["t"] + [f"{f}{j + 1}" for f in ("q", "dq", "ddq") for j in range(nv)]
            missing = [c for c in needed if c not in col]
            if missing:
                raise MissingColumnsError(f"{path.name} lacks columns {missing}" + raw_log)
            stack = {f: np.column_stack([col[f"{f}{j + 1}"] for j in range(nv)])
                     for f in ("q", "dq", "ddq")}
            tau_cols = [f"tau{j + 1}" for j in range(nv)]
            missing_tau = [c for c in tau_cols if c not in col]
            if missing_tau and len(missing_tau) < nv:
                raise MissingColumnsError(f"{path.name} has some torque columns but lacks "
                                          f"{missing_tau}")
            tau = None if missing_tau else np.column_stack([col[c] for c in tau_cols])
            sign = [f"dq_sign{j + 1}" for j in range(nv)]
            return cls(t=col["t"], tau=tau, joint_names=joint_names,
                       segment=col.get("segment"), **stack,
                       dq_sign=np.column_stack([col[c] for c in sign])
                       if all(c in col for c in sign) else None)
        raise DatasetError(f"unknown dataset format {path.suffix!r}; use .npz or .csv")


def _numbered(column: str, joints: Sequence[str]) -> str:
    """``q_<joint>`` → ``q<k>`` (1-based, in the order of ``joints``); other names as they
    are."""
    for f in ("q", "dq", "ddq", "tau", "dq_sign"):
        joint = column[len(f) + 1:]
        if column.startswith(f + "_") and joint in joints:
            return f"{f}{list(joints).index(joint) + 1}"
    return column


def _widest(filters: Sequence[tuple[float, int] | None]) -> tuple[float, int] | None:
    """The identification filter of stacked recordings: the highest cut-off when every part has
    one of the same order (each part is then filtered at or above its own, which loses none of
    its motion), else ``None``."""
    if any(f is None for f in filters) or len({f[1] for f in filters}) != 1:
        return None
    return max(filters)


def array_names(names: np.ndarray) -> tuple[str, ...]:
    """The names held by an array read from a file: ``str`` (unicode) or ``bytes`` elements
    (``np.savez`` of ``[b"joint1", …]``, Python 2 era logs) decoded as UTF-8, not written
    ``"b'joint1'"``."""
    return tuple(n.decode("utf-8", "replace") if isinstance(n, bytes) else str(n)
                 for n in np.atleast_1d(names))


def _unwrap(data: object) -> object:
    """A loader's :class:`~consistid.data.recordings.Recording` (anything holding a Dataset in
    ``.dataset``) as its dataset; anything else unchanged."""
    inner = getattr(data, "dataset", None)
    return inner if isinstance(inner, Dataset) and not isinstance(data, Dataset) else data


def as_dataset(data: "Dataset | Sequence[Dataset]", name: str = "dataset") -> Dataset:
    """``data`` itself, or several recordings stacked as segments (:meth:`Dataset.concatenate`);
    a loader's :class:`~consistid.data.recordings.Recording` stands for its ``.dataset``.
    Anything else raises :class:`DatasetError` naming ``name`` and what it got (a pandas
    DataFrame: how to read it)."""
    data = _unwrap(data)
    if isinstance(data, Dataset):
        return data
    if type(data).__name__ == "DataFrame":
        raise DatasetError(f"{name} is a pandas DataFrame, not a Dataset: read it with "
                           "consistid.data.recordings.from_frame(df, model=model).dataset (its "
                           "columns are matched by name, dq/ddq estimated when absent)")
    try:
        if isinstance(data, (str, bytes)):
            raise TypeError
        parts = list(data)  # type: ignore[arg-type]
    except TypeError:
        raise DatasetError(f"{name} must be a Dataset or a list of Datasets, got "
                           f"{type(data).__name__} {data!r:.60}") from None
    if not parts:
        raise DatasetError(f"{name} is an empty list: give at least one Dataset")
    parts = [_unwrap(d) for d in parts]
    seen: dict[str, int] = {}
    for k, d in enumerate(parts):
        if not isinstance(d, Dataset):
            raise DatasetError(f"{name}[{k}] is a {type(d).__name__}, not a Dataset")
        first = seen.setdefault(d.fingerprint(), k)
        if first != k:
            raise DatasetError(f"{name}[{k}] is the recording {name}[{first}] again (identical "
                               "t, q and tau): stacked twice, its samples would count twice and "
                               "every σ would shrink by √2; pass each recording once")
    return Dataset.concatenate(parts)

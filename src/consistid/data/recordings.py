r"""Robot logs to :class:`~consistid.Dataset`: named arrays, time stamps, joint names, trimming.

A real log is rarely a clean ``(t, q, dq, ddq, tau)`` table. :func:`from_arrays` and
:func:`load_recording` turn one into a :class:`Recording` — the validated dataset plus the list of
every step applied to it (``Recording.steps``), so that a user can see, and a report can quote,
what was done:

1. **Arrays** are read by name. ``.npz``: the layout is given (``keys``) or recognised
   (:data:`NPZ_LAYOUTS`); arrays the layout does not name (e.g. ``target_*`` set-points) are
   listed and never read. CSV, Parquet, DataFrames, ROS 1/2 bags and MCAP, ``.mat``: read by
   :mod:`consistid.data.formats` (columns matched by name, :mod:`~consistid.data.formats.columns`;
   ``JointState`` messages by joint name); the joints of ``joints=`` (default: the model's)
   are kept and the others' columns (a gripper) dropped and listed.
2. **Time** is shifted so that the first sample is at 0 s (Unix stamps are recognised and their
   origin recorded). Stamps must not go backwards (:class:`~consistid.errors.DatasetError`
   naming the index) nor be NaN. Their unit is checked: an implausible log in seconds (a
   "1 Hz" robot whose stamps are milliseconds) is refused naming the likely unit, and converted
   only with ``time_unit=`` (or a unit the file gives: a ``time_ms`` column, ROS stamps).
   Samples sharing a stamp are merged (``duplicates="average"``: the mean of the group, equal to
   dropping exact repeats), kept first (``"first"``), spread evenly (``"spread"``) or refused
   (``"error"``); by default they are averaged unless the stamps are *collapsed* (more than
   10 % of the samples share one: a clock coarser than the sampling), which is refused.
   Non-uniform sampling is reported (rate, steps, gaps longer than :data:`GAP_FACTOR` median
   steps). Torques that the logger averaged over each interval and stamped at its start or end
   (``timestamp=``) are moved to the interval centres.
3. **Derivatives**: logged velocities and accelerations are used as recorded at their own stamps
   (the log is taken to be filtered already; nothing is filtered again). A raw log without them
   goes through the signal chain (:mod:`consistid.data.chain`: outliers, resampling of jittered
   stamps at the rate the log supports, zero-phase filtering, differentiation, edge trimming),
   whose steps are appended.
4. **Joint names**: the log's columns are matched to the model's joints by name and reordered
   to the model's order; a name missing on either side raises
   :class:`~consistid.errors.JointNameError` listing both sides. A log without names must have
   exactly the model's joint count and is taken to be in the model's order (recorded as a step).
5. **Trimming** (the rule): samples with ``t < trim_start`` or ``t > t_end − trim_end`` are
   dropped, ``t`` counted from the log's first stamp and ``t_end`` its last (after the signal
   chain for raw logs, so its filter edges fall inside the trimmed part where they overlap).
   The start of an excitation run — the move away from rest, the filters' start-up — is not
   described by a steady model; how long it lasts depends on the set-up, so the durations are
   explicit arguments (0 by default) and always recorded. For the KUKA LWR4+ logs the tutorial
   measures it (``docs/tutorials/real_kuka.md``: a model fitted on the steady part leaves 2–5×
   its steady residual during the first 2 s): 2 s.
6. **Torques against the model** (with a model): on the joints whose measured torque follows
   the URDF's RNEA torque closely (``|correlation| > 0.9``), a flipped sign or a scale beyond
   10× (other units) warns (:class:`~consistid.errors.DataQualityWarning`) and is recorded.
"""

from __future__ import annotations

import html
import warnings
from dataclasses import dataclass, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..drives.transmission import Transmission
from ..errors import (DataQualityWarning, DatasetError, JointNameError, MissingColumnsError,
                      OptionError, check_option)
from ..progress import ProgressArg
from ..robot.model import RobotModel
from .chain import PreprocessOptions, run_chain
from .dataset import Dataset, array_names, open_npz
from .filters import held_still, real_array, transposed_hint
from .formats import Log, format_of, read_frame, read_log, read_split
from .resample import resample
from .units import (check_angle_unit, convert_angles, degree_message, degree_suspects,
                    degree_torque_evidence, model_limits, revolute_joints)
from .timestamps import (
    DUPLICATES,
    check_stamps,
    check_timestamp,
    convert_units,
    interval_centres,
    long_steps,
    median_step,
    merge_duplicates,
)

#: Known ``.npz`` layouts: dataset field → array name. ``"flobaroid"`` is the layout of the
#: FloBaRoID project's measurement files (e.g. the KUKA LWR4+ recordings).
NPZ_LAYOUTS: dict[str, dict[str, str]] = {
    "consistid": {"t": "t", "q": "q", "dq": "dq", "ddq": "ddq", "tau": "tau"},
    "flobaroid": {"t": "times", "q": "positions", "dq": "velocities", "ddq": "accelerations",
                  "tau": "torques"},
}
#: Optional array holding the column (joint) names, in any layout.
JOINT_NAMES_KEY = "joint_names"
#: Stamps later than this (s) are read as Unix time (after 2001-09-09).
UNIX_TIME_MIN = 1.0e9
#: Stamps beyond this (s; the year 9999) are not dated (nanoseconds read as seconds).
UNIX_TIME_MAX = 2.5e11
#: A time step longer than this many median steps is reported as a gap.
GAP_FACTOR = 5.0
REQUIRED = ("t", "q", "tau")


@dataclass(frozen=True)
class Recording:
    """A dataset read from a log, and what was done to get it.

    Attributes
    ----------
    dataset : the validated :class:`~consistid.Dataset` (time from 0 s, joints in model order).
    steps : one sentence per processing step, in order.
    source : the file (or ``"arrays"``) the data came from.
    time_origin : the stamp subtracted from the log's time (s; Unix time for Unix stamps).
    """

    dataset: Dataset
    steps: tuple[str, ...]
    source: str
    time_origin: float = 0.0

    def __str__(self) -> str:
        return self.summary()

    def summary(self) -> str:
        """The source, the size, and one line per step applied."""
        d = self.dataset
        head = (f"recording {self.source}: {d.n_samples} samples × {d.nv} joints, "
                f"{d.duration:.3f} s")
        return "\n".join([head, *(f"  - {s}" for s in self.steps)])

    def _repr_html_(self) -> str:
        d = self.dataset
        items = "".join(f"<li>{html.escape(s)}</li>" for s in self.steps)
        return (f"<p><b>recording</b> {html.escape(self.source)}: {d.n_samples} samples × "
                f"{d.nv} joints, {d.duration:.3f} s</p><ol>{items}</ol>")

    @staticmethod
    def concatenate(recordings: Sequence["Recording"]) -> "Recording":
        """Stack recordings as separate segments (:meth:`Dataset.concatenate`); steps are kept
        per recording, prefixed by its segment index."""
        if not recordings:
            raise DatasetError("nothing to concatenate")
        steps = [f"[segment {i}: {r.source}] {s}" for i, r in enumerate(recordings)
                 for s in r.steps]
        steps.append(f"stacked {len(recordings)} recordings as segments 0..{len(recordings) - 1}")
        return Recording(Dataset.concatenate([r.dataset for r in recordings]), tuple(steps),
                         " + ".join(r.source for r in recordings), recordings[0].time_origin)


def _describe_origin(t0: float) -> str:
    if UNIX_TIME_MIN <= t0 < UNIX_TIME_MAX:
        stamp = datetime.fromtimestamp(t0, tz=timezone.utc).isoformat(timespec="milliseconds")
        return f"Unix time stamps: origin {t0:.6f} s ({stamp}) subtracted, time starts at 0 s"
    return f"time origin {t0:.6g} s subtracted, time starts at 0 s"


def _match_joints(names: Sequence[str] | None, nv: int, model: RobotModel | None,
                  source: str, steps: list[str]
                  ) -> tuple[np.ndarray | None, tuple[str, ...] | None]:
    """Column order that puts the log's joints in the model's order (``None``: keep)."""
    if names is not None:
        names = tuple(str(n) for n in names)
        if len(names) != nv:
            raise JointNameError(f"{source}: {len(names)} joint names for {nv} columns: "
                                 f"{list(names)}")
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise JointNameError(f"{source}: joint name(s) {dup} appear more than once")
    if model is None:
        if names is None:
            steps.append(f"no joint names and no model: {nv} unnamed columns kept in file order")
        else:
            steps.append(f"joints named {list(names)} (no model given to match)")
        return None, names
    wanted = tuple(model.joint_names)
    if names is None:
        if nv != model.nv:
            raise JointNameError(f"{source} has {nv} joint columns and no joint names; "
                                 f"{model.name} has {model.nv} joints {list(wanted)}")
        steps.append(f"no joint names in the log: its {nv} columns taken in {model.name}'s "
                     f"joint order {list(wanted)}")
        return None, wanted
    missing = [n for n in wanted if n not in names]
    extra = [n for n in names if n not in wanted]
    if missing or extra:
        raise JointNameError(f"{source}: joint names do not match {model.name}: missing from the "
                             f"log {missing}, not in the model {extra}; log has {list(names)}, "
                             f"model has {list(wanted)}")
    order = np.array([names.index(n) for n in wanted])
    if np.array_equal(order, np.arange(nv)):
        steps.append(f"joint names match {model.name}'s joints in order")
        return None, wanted
    steps.append(f"joint columns reordered to {model.name}'s order {list(wanted)} "
                 f"(log order was {list(names)})")
    return order, wanted


def from_arrays(t: np.ndarray, q: np.ndarray, tau: np.ndarray, dq: np.ndarray | None = None,
                ddq: np.ndarray | None = None, *, joint_names: Sequence[str] | None = None,
                model: RobotModel | None = None, trim_start: float = 0.0,
                trim_end: float = 0.0, duplicates: str | None = None,
                time_unit: str | None = None, timestamp: str | Mapping[str, str] = "centre",
                source: str = "arrays", drives: Transmission | None = None,
                angle_unit: str | None = None, velocities: str = "auto",
                **signal_options: object) -> Recording:
    """A :class:`Recording` from logged arrays (steps 2–5 of the module docstring).

    Parameters
    ----------
    t : (N,) time stamps in s (any origin, e.g. Unix time); non-decreasing.
    q, tau : (N, n) joint positions (rad or m) and measured joint torques (N·m or N).
    dq, ddq : (N, n) logged velocities and accelerations, used as recorded; both ``None``
        to estimate them with the signal chain (:mod:`consistid.data.chain`; ``signal_options``
        are its :class:`~consistid.data.chain.PreprocessOptions`, e.g. ``cutoff``,
        ``derivative``, ``rate``).
    joint_names : names of the log's columns, matched to ``model``'s joints.
    model : the robot; its joint order is the dataset's.
    trim_start, trim_end : seconds dropped at the start and at the end (the trimming rule).
    duplicates : ``"average"``, ``"first"``, ``"error"`` or ``"spread"`` for samples sharing a
        time stamp; ``None`` (default): average, but refuse collapsed stamps — more than 10 % of
        the samples sharing a stamp (:func:`consistid.data.timestamps.merge_duplicates`).
    time_unit : the stamps' unit: ``None`` (seconds; implausible stamps — a "1 Hz" log that is
        really milliseconds — raise :class:`DatasetError` naming the likely unit), ``"auto"``
        (convert to the one plausible unit and record it), ``"s"``, ``"ms"``, ``"us"``,
        ``"ns"``.
    timestamp : how the logger stamps the torques it averaged over each sample interval:
        ``"centre"`` (default; no shift), ``"start"`` or ``"end"`` (moved half a step to the
        interval centre and interpolated at the positions' stamps), or a mapping per field.
    source : label used in messages and in :attr:`Recording.source`.
    drives : a :class:`~consistid.drives.transmission.Transmission` with torque constants: the
        log's ``q`` are then motor angles and its ``tau`` motor currents (A), one column per
        motor in the joints' order, converted after trimming (and before the checks against
        ``model``) to joint angles ``q = G⁻¹(q_m / r)`` (and their derivatives) and joint
        torques ``τ = Gᵀ(r ⊙ k_t ⊙ i)``, recorded in the steps. Without torque constants
        only the angles are converted and ``tau`` stays in A, for
        :func:`consistid.identify_drive_gains` (the steps say so).
    velocities : ``"auto"`` (``dq`` and ``ddq`` both given, or neither) or ``"logged"``:
        ``dq`` given without ``ddq`` is the logged velocity — run through the same signal
        chain as ``q`` (resampling, zero-phase low-pass at the positions' cut-off) and
        differentiated for ``ddq``; the positions' own derivative is set aside (said) and
        compared with it (:func:`_check_logged`).
    angle_unit : the unit of ``q`` (and ``dq``, ``ddq``) of the revolute joints: ``"rad"``,
        ``"deg"`` (converted by π/180; a model's prismatic joints stay in metres), or ``None``
        (default: radians, and a log that looks like degrees — a range beyond two turns, speeds
        beyond 720 °/s, positions beyond the model's limits that degrees would fit — warns
        :class:`~consistid.errors.DataQualityWarning` naming the joints;
        :mod:`consistid.data.units`).

    Raises
    ------
    DatasetError for backwards time, implausible units, refused duplicates, a trim that leaves
    no sample, or bad shapes/values; JointNameError when the joint names do not match the
    model; MissingColumnsError when only one of ``dq``/``ddq`` is given.
    """
    check_option("duplicates", duplicates, (None, *DUPLICATES))
    shifts = check_timestamp(timestamp)
    factor = check_angle_unit(angle_unit)
    steps: list[str] = []
    t = check_stamps(t, source)
    arrays = {"q": q, "tau": tau, "dq": dq, "ddq": ddq}
    check_option("velocities", velocities, ("auto", "logged"))
    if velocities == "logged" and dq is None:
        raise MissingColumnsError(f"{source}: velocities='logged' but no logged velocities "
                                  "(dq) are given")
    if (dq is None) != (ddq is None) and not (velocities == "logged" and ddq is None):
        given = "dq" if ddq is None else "ddq"
        raise MissingColumnsError(f"{source}: {given} is given without "
                                  f"{'ddq' if given == 'dq' else 'dq'}; give both or neither "
                                  "(neither: they are estimated from q)")
    arrays = {k: np.atleast_2d(real_array(f"{source}: {k}", a).T).T
              for k, a in arrays.items() if a is not None}
    for k, a in arrays.items():
        if a.shape[0] != t.size:
            raise DatasetError(f"{source}: {k} has {a.shape[0]} samples but t has {t.size}"
                               + transposed_hint(a.shape, t.size))
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        k = int(back[0]) + 1
        raise DatasetError(f"{source}: t[{k}] = {float(t[k])!r} is before t[{k - 1}] = "
                           f"{float(t[k - 1])!r} (time goes back {back.size} time(s)); sort the "
                           "log first, or cut it there if the logger's clock was stepped back")
    t0 = float(t[0])
    t = t - t0
    t, note, scale = convert_units(t, time_unit, source)
    t0 *= scale
    steps.append(_describe_origin(t0))
    if note:
        steps.append(note)
    t, arrays, dup = merge_duplicates(t, arrays, duplicates, 0.0, source)
    steps.append(dup)
    if t.size > 1:
        dt = np.diff(t)
        med = median_step(t)
        spread = (f"sampling {1.0 / med:.1f} Hz median; steps {dt.min() * 1e3:.2f}–"
                  f"{dt.max() * 1e3:.2f} ms")
        uniform = dt.max() - dt.min() <= 1e-6 * med
        spread += " (uniform)" if uniform else " (non-uniform)"
        gaps = long_steps(t, GAP_FACTOR)[0]
        if gaps.size:
            spread += (f"; {gaps.size} gap(s) longer than {GAP_FACTOR:g} median steps, first "
                       f"after t = {t[gaps[0]]:.4f} s ({dt[gaps[0]] * 1e3:.1f} ms)")
        steps.append(spread)
    nv = arrays["q"].shape[1]
    order, names = _match_joints(joint_names, nv, model, source, steps)
    if order is not None:
        arrays = {k: a[:, order] for k, a in arrays.items()}
    revolute = revolute_joints(model) if model is not None else np.ones(nv, bool)
    if angle_unit == "deg":
        arrays = convert_angles(arrays, factor, revolute)
        steps.append(f"angle_unit='deg': q, dq, ddq of {int(revolute.sum())} revolute joint(s) "
                     "converted to radians (× π/180)")
    for name, value in (("trim_start", trim_start), ("trim_end", trim_end)):
        if isinstance(value, (bool, np.bool_)) \
                or not isinstance(value, (int, float, np.integer, np.floating)):
            raise OptionError(f"{source}: {name} must be seconds (a number), got {value!r}")
    if trim_start < 0 or trim_end < 0 or not np.isfinite(trim_start + trim_end):
        raise DatasetError(f"{source}: trim_start and trim_end must be finite seconds ≥ 0, got "
                           f"{trim_start}, {trim_end}")
    if "ddq" in arrays:
        if signal_options:
            raise DatasetError(f"{source}: signal-chain options {sorted(signal_options)} apply "
                               "only to logs without velocities/accelerations (these are used as "
                               "logged)")
        t, arrays = _shift_logged(t, arrays, shifts, steps)
        steps.append("velocities and accelerations used as logged (taken as already filtered; "
                     "not filtered again); samples kept at their own time stamps (least squares "
                     "uses samples, not a time grid)")
        dataset = Dataset(t=t, q=arrays["q"], dq=arrays["dq"], ddq=arrays["ddq"],
                          tau=arrays["tau"], joint_names=names)
        _check_logged(t, arrays, names, source, steps)
    else:
        options = PreprocessOptions.from_kwargs({"timestamp": timestamp,
                                                 "duplicates": duplicates, **signal_options})
        pre = run_chain(t, arrays["q"], arrays["tau"], options)
        cut = (f"cut-off {pre.derivative_cutoff:.4g} Hz" if pre.parallel_cutoff is None else
               f"cut-off {pre.parallel_cutoff:.4g} Hz (τ and Y filtered alike at "
               f"identification); positions differentiated at {pre.derivative_cutoff:.4g} Hz")
        why = ("logged velocities, no logged accelerations" if "dq" in arrays
               else "no logged velocities/accelerations")
        steps.append(f"{why}: the signal chain ({pre.t.size} samples at {pre.rate:.6g} Hz, "
                     f"{cut}):")
        steps.extend(f"  {s}" for s in pre.steps)
        dataset = Dataset.from_chain(pre, names)
        if "dq" in arrays:
            dataset = _logged_velocities(t, arrays, options, pre, dataset, source, steps)
    end = t[-1]
    keep = (dataset.t >= trim_start) & (dataset.t <= end - trim_end)
    if not keep.any():
        raise DatasetError(f"{source}: trimming {trim_start} s at the start and {trim_end} s at "
                           f"the end leaves no sample of {end:.3f} s")
    if trim_start or trim_end:
        first, last = np.flatnonzero(keep)[[0, -1]]
        steps.append(f"trimmed {trim_start:g} s at the start ({first} samples) and {trim_end:g} s "
                     f"at the end ({dataset.n_samples - 1 - last} samples): kept t ∈ "
                     f"[{dataset.t[first]:.4f}, {dataset.t[last]:.4f}] s")
        dataset = dataset.select(keep)
    else:
        steps.append("no trim_start/trim_end requested")
    if drives is not None:
        dataset = joint_side(dataset, drives, steps)
    in_newton_metres = drives is None or drives.torque_constants is not None
    if angle_unit is None:          # currents (A) are not the model's torque: positions only
        _check_degrees(dataset, model, revolute, source, steps, by_torque=in_newton_metres)
    if model is not None and in_newton_metres:
        _check_against_model(dataset, model, source, steps)    # currents: no torque units
    return Recording(dataset, tuple(steps), source, t0)


def joint_side(dataset: Dataset, drives: Transmission, steps: list[str]) -> Dataset:
    """A motor-side dataset (motor angles, currents) on the joint side through ``drives``
    (:mod:`consistid.drives.transmission`), the conversion appended to ``steps``. The Coulomb
    signal of filtered currents (``dq_sign``) follows a diagonal transmission (its sign flips
    with the ratio's); through a coupling it is not the filtered sign of a joint's speed, and
    is dropped (the regressor then uses ``sign(q̇)``), which the step says."""
    drives.check_joints(dataset.nv, dataset.joint_names)
    known = drives.torque_constants is not None          # else the currents stay currents
    tau = drives.current_torque(dataset.require_torque()) if known else dataset.tau
    coupled = bool(drives.coupled_motors.size)
    dq_sign = None if dataset.dq_sign is None or coupled else \
        dataset.dq_sign * np.sign(drives.ratios)
    out = replace(dataset, q=drives.joint_positions(dataset.q),
                  dq=drives.joint_positions(dataset.dq), ddq=drives.joint_positions(dataset.ddq),
                  tau=tau, dq_sign=dq_sign)
    torque = (f"τ = Gᵀ(κ ⊙ i), drive gains κ = r ⊙ k_t = "
              f"[{', '.join(f'{g:.4g}' for g in drives.gains)}] N·m/A" if known else
              "tau kept as motor currents (A): no torque constants, the drive gains are to "
              "be identified (consistid.identify_drive_gains)")
    steps.append(f"motor side to joint side (drives=): q = G⁻¹(q_m / r) with ratios "
                 f"{', '.join(f'{r:g}' for r in drives.ratios)}"
                 f"{' and a coupling G' if coupled else ''}; {torque}" + (
                     "; the filtered Coulomb signal is dropped (coupled motors)"
                     if coupled and dataset.dq_sign is not None else ""))
    return out


def _logged_velocities(t: np.ndarray, arrays: Mapping[str, np.ndarray],
                       options: PreprocessOptions, pre: object, dataset: Dataset, source: str,
                       steps: list[str]) -> Dataset:
    """``dataset`` (the chain's, from ``q``) with ``dq`` the logged velocities through the same
    chain — same grid, same cut-off — and ``ddq`` their derivative (``velocities="logged"``)."""
    same = replace(options, cutoff=pre.derivative_cutoff, rate=pre.rate, parallel_cutoff=None)
    vel = run_chain(t, arrays["dq"], arrays["tau"], same)
    if vel.t.shape != pre.t.shape or not np.allclose(vel.t, pre.t, rtol=0, atol=1e-9):
        raise DatasetError(f"{source}: the logged velocities came out of the signal chain on "
                           "other samples than the positions; load with velocities='auto'")
    steps.append(f"velocities='logged': dq is the logged velocity through the same chain "
                 f"(cut-off {pre.derivative_cutoff:.4g} Hz), ddq its derivative; the derivative "
                 "of q set aside")
    _check_logged(dataset.t, {"q": dataset.q, "dq": vel.q, "ddq": vel.dq},
                  dataset.joint_names, source, steps)
    return replace(dataset, dq=vel.q, ddq=vel.dq)


def _check_degrees(dataset: Dataset, model: RobotModel | None, revolute: np.ndarray,
                   source: str, steps: list[str], by_torque: bool = True) -> None:
    """Warn (:class:`DataQualityWarning`) and record the joints whose positions look like
    degrees read as radians (:func:`consistid.data.units.degree_suspects`), or whose torque
    the model explains as degrees (:func:`consistid.data.units.degree_torque_evidence`; not
    ``by_torque``: ``tau`` holds no N·m, e.g. motor currents)."""
    found = degree_suspects(dataset.q, dataset.dq, dataset.joint_names, revolute,
                            model_limits(model) if model is not None else None)
    torque = (degree_torque_evidence(model, dataset.q, dataset.dq, dataset.ddq, dataset.tau)
              if by_torque and model is not None and dataset.tau is not None else None)
    found += [torque] if torque else []
    if found:
        text = degree_message(found, source)
        steps.append(text)
        warnings.warn(text, DataQualityWarning, stacklevel=4)


#: Logged derivatives are compared with differences of what they derive over about this many
#: seconds (:func:`_check_logged`).
DERIVATIVE_WINDOW = 0.01


def _check_logged(t: np.ndarray, arrays: Mapping[str, np.ndarray],
                  names: Sequence[str] | None, source: str, steps: list[str]) -> None:
    """Warn (:class:`DataQualityWarning`) when logged velocities or accelerations are not the
    derivatives of what they derive from: per joint, logged ``dq`` against central differences
    of ``q`` and logged ``ddq`` against those of the logged ``dq`` (over
    :data:`DERIVATIVE_WINDOW`, which keeps sensor noise out). A column of zeros while the joint
    moves (a driver that fills the field), a slope far from 1 (deg/s against rad: 57.3) or no
    correlation is named; ``derivatives="estimate"`` derives them from ``q`` instead. Samples
    that are independent states rather than a trajectory (every joint varies, and consecutive
    positions differ as much as the whole log does, :func:`~consistid.data.filters.held_still`,
    as in simulated regressor tests) have no derivatives to compare and
    are not checked (said in the record)."""
    if t.size < 8:
        return
    pos = np.diff(t)
    h = float(np.median(pos[pos > 0])) if np.any(pos > 0) else 0.0
    if h == 0.0:
        return
    q = arrays["q"]
    if np.all(held_still(q) & (np.ptp(q, axis=0) > 0)):
        steps.append("samples are independent states, not a trajectory (consecutive positions "
                     "differ as much as the whole log does): logged derivatives not checked")
        return
    stride = max(1, int(round(DERIVATIVE_WINDOW / h)))
    sub = slice(None, None, stride)
    ts = t[sub]
    if ts.size < 5 or np.any(np.diff(ts) <= 0):
        return
    found = []
    for field, of in (("dq", "q"), ("ddq", "dq")):
        logged, base = arrays[field][sub], arrays[of][sub]
        numeric = np.gradient(base, ts, axis=0)
        for j in range(logged.shape[1]):
            x, y = numeric[2:-2, j], logged[2:-2, j]
            scale = float(np.sqrt(np.mean(x ** 2)))
            if scale == 0.0 or not np.isfinite(scale):
                continue                                      # this joint does not move
            joint = names[j] if names is not None and j < len(names) else j
            if not np.any(y):
                found.append(f"{field}[:, {joint!r}] is 0 in every sample while d({of})/dt has "
                             f"RMS {scale:.3g}")
                continue
            r = float(np.corrcoef(x, y)[0, 1]) if np.std(y) > 0 else 0.0
            slope = float(np.dot(x, y) / np.dot(x, x))
            if r < 0.5:
                found.append(f"{field}[:, {joint!r}] does not follow d({of})/dt (correlation "
                             f"{r:.2f})")
            elif not 0.5 < slope < 2.0:
                unit = " (deg/s against rad?)" if 50 < slope < 65 and field == "dq" else ""
                found.append(f"{field}[:, {joint!r}] is {slope:.3g} × d({of})/dt{unit}")
    if found:
        text = (f"{source}: logged derivatives that are not the derivatives of the logged "
                f"signals: {'; '.join(found[:6])}{' …' if len(found) > 6 else ''}")
        steps.append(text)
        warnings.warn(text + ". Identification would use them as logged: fix the columns, or "
                      "leave them out (derivatives=\"estimate\" derives them from q)",
                      DataQualityWarning, stacklevel=3)


#: Joints whose measured torque follows the model's RNEA with |correlation| above this are
#: compared in sign and scale (:func:`_check_against_model`).
MODEL_CORRELATION = 0.9
#: RMS ratio (measured / model) beyond which such a joint's torque is in other units.
MODEL_SCALE = 10.0
#: Joints whose model torque RMS is below this fraction of the largest joint's are not judged.
MODEL_NEGLIGIBLE = 1e-3
#: Samples at most used for the comparison (evenly spaced).
MODEL_SAMPLES = 20_000


def _correlation(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.corrcoef(a, b)[0, 1]) if np.std(a) > 0 and np.std(b) > 0 else 0.0


def _check_against_model(dataset: Dataset, model: RobotModel, source: str,
                         steps: list[str]) -> None:
    """Warn (:class:`DataQualityWarning`) about torque channels that are the model's torque
    with the wrong sign or in other units: per joint, the correlation ``r`` of the measured τ
    with the URDF's RNEA torque and their RMS ratio. Only joints the model's torque explains
    (``|r| > MODEL_CORRELATION``: the gravity-loaded ones; friction-dominated wrists are not
    judged) are compared — ``r < −0.9`` is a flipped sign, a ratio beyond ``MODEL_SCALE`` (or
    below its inverse) other units (mN·m: 1000) — and a channel that follows another joint's
    model torque (``r > 0.9``, better than that joint's own channel) but not its own
    (``|r| < 0.5``) is a column of another joint. A URDF within tens of percent of the robot
    gives ``r ≈ 1`` and a ratio near 1 on those joints."""
    if dataset.tau is None or dataset.n_samples < 10 or dataset.nv != model.nv:
        return
    pick = np.unique(np.linspace(0, dataset.n_samples - 1,
                                 min(dataset.n_samples, MODEL_SAMPLES)).astype(int))
    u = model.rnea(dataset.q[pick], dataset.dq[pick], dataset.ddq[pick])
    y = dataset.tau[pick]
    flipped, scaled, swapped = [], [], []
    names = model.joint_names
    moving = [k for k in range(model.nv) if np.std(u[:, k]) > 0]
    size = np.sqrt(np.mean(u ** 2, axis=0))
    for j, name in enumerate(names):
        su, sy = float(np.std(u[:, j])), float(np.std(y[:, j]))
        if su == 0 or sy == 0 or size[j] < MODEL_NEGLIGIBLE * size.max():
            continue                # the model puts (next to) no torque there: nothing to judge
        r = float(np.corrcoef(u[:, j], y[:, j])[0, 1])
        others = {k: float(np.corrcoef(u[:, k], y[:, j])[0, 1]) for k in moving if k != j}
        best = max(others, key=lambda k: others[k], default=None)
        if best is not None and abs(r) < 0.5 and others[best] > MODEL_CORRELATION \
                and others[best] > _correlation(u[:, best], y[:, best]):
            swapped.append(f"{name!r} follows {names[best]!r}'s (correlation "
                           f"{others[best]:.2f}, with its own {r:.2f})")
            continue
        ratio = float(np.sqrt(np.mean(y[:, j] ** 2) / np.mean(u[:, j] ** 2)))
        if r < -MODEL_CORRELATION:
            flipped.append(f"{name!r} (correlation {r:.2f})")
        elif r > MODEL_CORRELATION and not 1 / MODEL_SCALE < ratio < MODEL_SCALE:
            scaled.append(f"{name!r} ({ratio:.3g} × the model's)")
    found = []
    if swapped:
        found.append(f"the torque column of {', '.join(swapped)}: the columns are in another "
                     "joint order than the model's; name them after the joints, or reorder them")
    if flipped:
        found.append(f"the torque of {', '.join(flipped)} is the model's torque with the opposite "
                     "sign: a driver that logs the reaction torque, or a joint axis flipped "
                     "between the log and the URDF; negate those columns")
    if scaled:
        found.append(f"the torque of {', '.join(scaled)} follows the model's in shape but not "
                     "in size: other units (mN·m reads 1000 ×), or a gear ratio left in; "
                     "convert those columns to N·m")
    if found:
        text = f"{source}: compared with {model.name}'s RNEA torque (URDF inertias): " \
               + "; ".join(found)
        steps.append(text)
        warnings.warn(text + ". Identification would fit them as they are",
                      DataQualityWarning, stacklevel=3)


def _shift_logged(t: np.ndarray, arrays: dict[str, np.ndarray], shifts: Mapping[str, str],
                  steps: list[str]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Logged signals stamped at their interval's start or end, moved to the interval centres
    and interpolated (:func:`consistid.data.resample.resample`) at the stamps of the others;
    the edge samples outside are dropped."""
    moved = {f: c for f, c in shifts.items() if c != "centre" and f in arrays}
    if not moved:
        return t, arrays
    centres = {f: interval_centres(t, c) for f, c in moved.items()}
    lo = max([t[0], *(c[0] for c in centres.values())])
    hi = min([t[-1], *(c[-1] for c in centres.values())])
    keep = (t >= lo - 1e-12) & (t <= hi + 1e-12)
    out = {}
    for f, a in arrays.items():
        out[f] = resample(centres[f], a, np.clip(t[keep], centres[f][0], centres[f][-1])) \
            if f in centres else a[keep]
    what = ", ".join(f"{f} stamped at the interval {c}" for f, c in moved.items())
    steps.append(f"{what}: moved to the interval centres (half a step) and interpolated at the "
                 f"other signals' stamps by cubic spline; {int((~keep).sum())} edge sample(s) "
                 "dropped")
    return t[keep], out


def from_log(log: Log, *, model: RobotModel | None = None, trim_start: float = 0.0,
             trim_end: float = 0.0, duplicates: str | None = None,
             time_unit: str | None = None, timestamp: str | Mapping[str, str] = "centre",
             derivatives: str = "auto", angle_unit: str | None = None,
             velocities: str = "auto", **signal_options: object) -> Recording:
    """A :class:`Recording` from a log read by :mod:`consistid.data.formats`: the reader's notes
    first, then :func:`from_arrays`. ``time_unit`` defaults to the unit the file gives (a
    ``time_ms`` column, ROS stamps). ``derivatives``: ``"auto"`` (use logged ``dq`` and ``ddq``
    when both are there, else estimate both from ``q``; a logged ``dq`` alone is then set aside
    and said), ``"logged"`` (refuse a log without them) or ``"estimate"``. ``angle_unit``
    (:func:`from_arrays`) applies to columns whose header names no unit: with ``"deg"``, a
    header that names one for an angle (``q1 [rad]``) raises :class:`OptionError`."""
    check_option("derivatives", derivatives, ("auto", "logged", "estimate"))
    check_option("velocities", velocities, ("auto", "logged"))
    check_angle_unit(angle_unit)
    if velocities == "logged" and derivatives == "estimate":
        raise OptionError(f"{log.source}: velocities='logged' uses the logged velocities and "
                          "derivatives='estimate' sets them aside; choose one")
    named = [f for f in ("q", "dq", "ddq") if f in log.unit_fields]
    if angle_unit == "deg" and named:
        raise OptionError(f"{log.source}: angle_unit='deg' converts columns without a unit, and "
                          f"the header names the unit of {named}; leave angle_unit out (the "
                          "header's units are read), or remove the units from the header")
    if signal_options.get("drives") is not None and (log.preset or "tau" in log.unit_fields):
        where = (f"{log.preset}'s torque columns" if log.preset
                 else "the torque columns' header")
        raise OptionError(f"{log.source}: drives= reads tau as motor currents (A), but "
                          f"{where} hold joint torques (N·m); name every column with "
                          "columns= (e.g. columns={'t': 'timestamp', 'q': 'actual_q_{i0}', "
                          "'tau': 'actual_current_{i0}'} and joints=[...]), or leave drives= "
                          "out")
    fields = dict(log.fields)
    notes = list(log.notes)
    have = [f for f in ("dq", "ddq") if f in fields]
    if derivatives == "logged" and len(have) < 2:
        raise MissingColumnsError(f"{log.source}: derivatives='logged' but the log lacks "
                                  f"{[f for f in ('dq', 'ddq') if f not in fields]}")
    if velocities == "logged" and have == ["dq"]:
        notes.append("logged dq used (velocities='logged'); ddq derived from it")
    elif derivatives == "estimate" or len(have) < 2:
        if have:
            notes.append(f"logged {' and '.join(have)} set aside: "
                         + ("derivatives='estimate'" if derivatives == "estimate" else
                            "without both dq and ddq, both are estimated from q"))
        fields.pop("dq", None), fields.pop("ddq", None)
    if time_unit is None and log.time_unit not in (None, "s"):
        time_unit = log.time_unit
        notes.append(f"time unit {time_unit!r} from the file")
    names = log.joint_names
    if model is not None and names is not None:
        extra = [n for n in names if n not in model.joint_names]
        missing = [n for n in model.joint_names if n not in names]
        if extra and not missing:
            keep = [names.index(n) for n in model.joint_names]
            fields = {f: a[:, keep] for f, a in fields.items()}
            notes.append(f"dropped the joints {extra} that {model.name} does not have")
            names = tuple(model.joint_names)
    rec = from_arrays(log.t, fields["q"], fields["tau"], fields.get("dq"), fields.get("ddq"),
                      joint_names=names, model=model, trim_start=trim_start, trim_end=trim_end,
                      duplicates=duplicates, time_unit=time_unit, timestamp=timestamp,
                      source=log.source, angle_unit=angle_unit, velocities=velocities,
                      **signal_options)
    steps = list(rec.steps)
    if log.origin:
        steps[0] = _describe_origin(log.origin + rec.time_origin)
    return Recording(rec.dataset, (*notes, *steps), rec.source, log.origin + rec.time_origin)


def from_frame(frame: object, *, joints: Sequence[str] | None = None,
               columns: Mapping[str, object] | None = None, source: str = "DataFrame",
               **options: object) -> Recording:
    """A :class:`Recording` from a pandas ``DataFrame`` (columns named as in a CSV,
    :mod:`consistid.data.formats.columns`); ``options`` as for :func:`from_log`."""
    return from_log(read_frame(frame, joints=joints, columns=columns, source=source), **options)


def _resolve_layout(files: Sequence[str], keys: str | Mapping[str, str], source: str
                    ) -> dict[str, str]:
    if isinstance(keys, Mapping):
        layout = dict(keys)
        unknown = [k for k in layout if k not in ("t", "q", "dq", "ddq", "tau", JOINT_NAMES_KEY)]
        if unknown:
            raise DatasetError(f"keys {unknown} are not dataset fields; use t, q, dq, ddq, tau, "
                               f"{JOINT_NAMES_KEY}")
    elif keys == "auto":
        fits = [name for name, lay in NPZ_LAYOUTS.items()
                if all(lay[k] in files for k in REQUIRED)]
        if not fits:
            known = {n: list(lay.values()) for n, lay in NPZ_LAYOUTS.items()}
            raise MissingColumnsError(f"{source}: arrays {sorted(files)} match no known layout "
                                      f"{known}; pass keys={{'t': ..., 'q': ..., 'tau': ...}}")
        layout = dict(NPZ_LAYOUTS[fits[0]])
    else:
        check_option("keys", keys, ("auto", *NPZ_LAYOUTS))
        layout = dict(NPZ_LAYOUTS[keys])
    missing = [f"{k} ({layout.get(k, '?')!r})" for k in REQUIRED if layout.get(k) not in files]
    if missing:
        raise MissingColumnsError(f"{source} lacks arrays for {missing}; it has {sorted(files)}")
    return layout


def load_recording(path: str | Path | Sequence[str | Path],
                   keys: str | Mapping[str, str] = "auto", *,
                   joints: Sequence[str] | None = None,
                   columns: Mapping[str, object] | None = None, topic: str | None = None,
                   stamp: str = "header", delimiter: str | None = None,
                   joint_names: Sequence[str] | None = None, model: RobotModel | None = None,
                   trim_start: float = 0.0, trim_end: float = 0.0,
                   duplicates: str | None = None, time_unit: str | None = None,
                   timestamp: str | Mapping[str, str] = "centre", derivatives: str = "auto",
                   progress: ProgressArg = None, drives: Transmission | None = None,
                   angle_unit: str | None = None, velocities: str = "auto",
                   **signal_options: object) -> Recording:
    """Read a log file into a :class:`Recording` (module docstring: what is done, in order).

    The format is chosen by the suffix: ``.npz`` (below), ``.csv``/``.tsv``/``.txt``,
    ``.parquet``, ``.bag``/``.mcap``/``.db3`` or a ROS 2 bag folder, ``.mat``
    (:mod:`consistid.data.formats`; their columns are matched by name,
    :mod:`consistid.data.formats.columns`).

    A list of files is a log split over them (positions, velocities, torques each in a
    table of its own, :mod:`consistid.data.formats.split`), joined on the positions' stamps.

    Parameters
    ----------
    path : the file (or ROS 2 bag folder), or a list of the files of a split log.
    keys : ``.npz`` only: ``"auto"`` (recognise a :data:`NPZ_LAYOUTS` layout), a layout name,
        or a mapping ``{"t": ..., "q": ..., "dq": ..., "ddq": ..., "tau": ...[, "joint_names":
        ...]}`` from dataset fields to array names (``dq``/``ddq`` may be left out to estimate
        them).
    joints : joints to read, in this order; other joints' columns (a gripper) are dropped and
        listed in the record. Default: the model's joints when a model is given, else all.
    columns : tables only: an explicit column mapping, e.g. ``{"t": "stamp", "q": "pos_{joint}",
        "tau": "eff_{joint}"}``.
    topic, stamp : ROS bags only: the ``JointState`` topic (default the only one) and
        ``"header"`` or ``"receive"`` stamps.
    delimiter : text only; default sniffed.
    joint_names : ``.npz`` only: names of the log's joint columns; default the file's
        ``joint_names`` array if any (a mismatch between the two raises
        :class:`~consistid.errors.JointNameError`).
    model, trim_start, trim_end, duplicates, time_unit, timestamp, drives, signal_options : see
        :func:`from_arrays` (``drives=``: a motor-side log of motor angles and currents).
    angle_unit : ``"rad"``, ``"deg"`` or ``None`` (radians, checked for degrees): see
        :func:`from_arrays` (a unit in a column's header wins, :func:`from_log`).
    derivatives : see :func:`from_log` (not for ``.npz``, whose ``keys`` say it).
    velocities : ``"logged"`` uses a log's velocities (``actual_qd``, ``dq``, ``velocity``)
        and derives the accelerations from them (:func:`from_arrays`); ``"auto"`` (default)
        sets logged velocities without accelerations aside and derives both from ``q``.
    progress : ROS bags and MCAP: ``None`` (a bar on a terminal), ``True``, ``False`` or a
        callable (:mod:`consistid.progress`); the other formats read fast and ignore it.

    Examples
    --------
    >>> rec = load_recording("measurements_2.npz", model=model, trim_start=2.0)  # doctest: +SKIP
    >>> rec = load_recording("run.mcap", model=model, timestamp="end")          # doctest: +SKIP
    >>> print(rec)                       # the steps applied            # doctest: +SKIP
    """
    common = dict(model=model, trim_start=trim_start, trim_end=trim_end, duplicates=duplicates,
                  time_unit=time_unit, timestamp=timestamp, angle_unit=angle_unit,
                  drives=drives, **signal_options)
    if isinstance(path, (list, tuple)):
        if keys != "auto" or joint_names is not None or columns is not None or topic is not None:
            raise DatasetError("keys=, joint_names=, columns= and topic= do not apply to a log "
                               "split over several files (its columns are read by name)")
        log = read_split(path, delimiter=delimiter,
                         joints=joints if joints is not None or model is None
                         else model.joint_names)
        rec = from_log(log, derivatives=derivatives, velocities=velocities, **common)
        return Recording(rec.dataset, rec.steps, log.source, rec.time_origin)
    path = Path(path)
    if not path.exists():
        raise DatasetError(f"recording {str(path)!r} does not exist")
    kind = format_of(path)
    if kind != "npz":
        if keys != "auto" or joint_names is not None:
            raise DatasetError(f"{path.name}: keys= and joint_names= apply to .npz logs; for "
                               "other formats use columns= and joints=")
        if joints is None and model is not None:
            joints = model.joint_names
        log = read_log(path, joints=joints, columns=columns, topic=topic, delimiter=delimiter,
                       stamp=stamp, progress=progress if kind == "bag" else None)
        rec = from_log(log, derivatives=derivatives, velocities=velocities, **common)
        return Recording(rec.dataset, rec.steps, str(path), rec.time_origin)
    if columns is not None or topic is not None or delimiter is not None or joints is not None:
        raise DatasetError(f"{path.name}: columns=, topic=, delimiter= and joints= apply to "
                           "CSV/Parquet/bag/.mat logs; for .npz use keys= and joint_names=")
    with open_npz(path) as f:
        files = list(f.files)
        layout = _resolve_layout(files, keys, path.name)
        used = {v for k, v in layout.items() if v in files}
        arrays = {k: f[v] for k, v in layout.items() if v in files and k != JOINT_NAMES_KEY}
        names_key = layout.get(JOINT_NAMES_KEY, JOINT_NAMES_KEY)
        file_names = list(array_names(f[names_key])) if names_key in files else None
        used |= {names_key} if file_names is not None else set()
    if file_names is not None and joint_names is not None and list(joint_names) != file_names:
        raise JointNameError(f"{path.name}: joint_names {list(joint_names)} differ from the "
                             f"file's {file_names}")
    ignored = sorted(set(files) - used)
    read = ", ".join(f"{k}←{layout[k]!r}" for k in ("t", "q", "dq", "ddq", "tau") if k in arrays)
    first = f"read {path.name}: {read}" + (f"; ignored arrays {ignored}" if ignored else "")
    rec = from_arrays(arrays["t"], arrays["q"], arrays["tau"], arrays.get("dq"),
                      arrays.get("ddq"),
                      joint_names=joint_names if joint_names is not None else file_names,
                      source=path.name, velocities=velocities, **common)
    return Recording(rec.dataset, (first, *rec.steps), str(path), rec.time_origin)

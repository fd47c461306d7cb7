r"""The signals every diagnosis effect's columns need, computed once per recording.

:class:`GapData` holds one dataset seen through the nominal model: the nominal torque
``τ_nom = Y(q, q̇, q̈) π₀`` (Pinocchio's joint torque regressor), the residual ``r = τ − τ_nom``,
the gravity torque, Savitzky–Golay time derivatives of the nominal torque (Savitzky & Golay 1964,
doi:10.1021/ac60214a047) and the RNEA derivatives (Carpentier & Mansard 2018,
doi:10.15607/RSS.2018.XIV.038). :func:`lowpass_segments` passes a column through the signal
chain's zero-phase low-pass per recording segment, for effects seen through filtered torques.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import pinocchio as pin
import scipy.signal

from ..data.dataset import Dataset
from ..data.signals import lowpass
from ..errors import DatasetError, ModelError
from ..estimation.mounting import tilt_axes
from ..identification.regressor import batch_rnea, rigid_body_regressor
from ..robot.model import RobotModel

#: Savitzky–Golay window (s) for the time derivatives of the nominal torque (delay, elasticity).
DERIVATIVE_WINDOW = 0.04


@dataclass(frozen=True, eq=False)
class Segment:
    """One recording segment of a dataset: where its samples are and its time steps.

    Attributes
    ----------
    index : its samples, a ``slice`` when they are contiguous (a view, no copy), else indices.
    t : (n,) its time stamps.
    step : median time step (s); ``nan`` for a single sample.
    uniform : its steps differ by at most ``1e-6`` of the median step.
    """

    index: slice | np.ndarray
    t: np.ndarray
    step: float
    uniform: bool

    @property
    def size(self) -> int:
        return self.t.size


def segments(dataset: Dataset) -> tuple[Segment, ...]:
    """The recording segments of ``dataset`` in increasing segment label (the order every
    per-segment computation of the diagnosis follows), each found once: filters and
    derivatives applied hundreds of times per diagnosis reuse them."""
    seg = dataset.segment
    out = []
    for s in np.unique(seg):
        idx = np.flatnonzero(seg == s)
        index: slice | np.ndarray = (slice(int(idx[0]), int(idx[-1]) + 1)
                                     if idx[-1] - idx[0] + 1 == idx.size else idx)
        t = dataset.t[index]
        if t.size > 1:
            steps = np.diff(t)
            step = float(np.median(steps))
            uniform = bool(np.ptp(steps) <= 1e-6 * step)
        else:
            step, uniform = float("nan"), True
        out.append(Segment(index, t, step, uniform))
    return tuple(out)


def _segment_derivatives(t: np.ndarray, x: np.ndarray, window: float
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Savitzky–Golay smoothed value, first and second time derivative of ``x`` (n, m).

    Savitzky & Golay 1964, doi:10.1021/ac60214a047: local cubic fits over ``window`` seconds,
    on a uniform grid at the median step (the samples are interpolated onto it and back).
    """
    n = t.size
    if n < 7:
        raise DatasetError(f"a recording segment has only {n} samples; time derivatives "
                           "need at least 7")
    dt = float(np.median(np.diff(t)))
    grid = t[0] + dt * np.arange(int(np.floor((t[-1] - t[0]) / dt)) + 1)
    xi = np.column_stack([np.interp(grid, t, x[:, i]) for i in range(x.shape[1])])
    length = max(7, int(round(window / dt)) | 1)
    length = min(length, grid.size if grid.size % 2 else grid.size - 1)
    out = []
    for deriv in (0, 1, 2):
        y = scipy.signal.savgol_filter(xi, length, 3, deriv=deriv, delta=dt, axis=0,
                                       mode="interp")
        out.append(np.column_stack([np.interp(t, grid, y[:, i]) for i in range(x.shape[1])]))
    return out[0], out[1], out[2]


def time_derivatives(dataset: Dataset, x: np.ndarray, window: float = DERIVATIVE_WINDOW
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Smoothed ``x``, ``ẋ`` and ``ẍ`` for each recording segment of ``dataset`` (never across)."""
    out = [np.empty_like(x) for _ in range(3)]
    for seg in segments(dataset):
        for o, v in zip(out, _segment_derivatives(seg.t, x[seg.index], window)):
            o[seg.index] = v
    return out[0], out[1], out[2]


def tilt_directions(gravity: np.ndarray) -> np.ndarray:
    """``(∂g/∂a₁, ∂g/∂a₂)`` at ``a = 0`` of ``g(a) = R_v(a₂) R_u(a₁) g₀``
    (:func:`consistid.estimation.mounting.gravity_from_tilt`): ``u × g₀`` and ``v × g₀`` with
    ``u, v`` the axes of :func:`consistid.estimation.mounting.tilt_axes` (``x``, ``y`` for
    ``g₀ ∥ −z``), shape (2, 3)."""
    g0 = np.asarray(gravity, dtype=float)
    return np.cross(tilt_axes(g0), g0)


@dataclass(frozen=True, eq=False)
class GapData:
    """One dataset seen through the nominal model: the signals every effect's columns need.

    Parameters
    ----------
    model : the robot (joint order, kinematics).
    dataset : measured samples with torques.
    nominal : (10·nbodies,) the nominal (simulator) standard inertial parameters ``π₀``.
    nominal_extra : (N, nv) torque the nominal model adds beyond the rigid body (e.g. the friction
        of an :class:`~consistid.IdentificationResult` used as nominal), or ``None``.
    derivative_window : Savitzky–Golay window (s) for ``τ̇_nom`` and ``τ̈_nom``.
    rigid_regressor : the rigid-body regressor of ``dataset``'s samples, (N, nv, 10·nbodies), if
        already computed; default computed on first use of :attr:`rigid`. Not checked against
        the samples, only its shape.
    parts : the parts this one stacks (:meth:`concatenate`): the nominal torque and, when first
        needed, the regressor are stacked from theirs instead of recomputed.

    Raises
    ------
    DatasetError : ``rigid_regressor`` of the wrong shape.
    """

    model: RobotModel
    dataset: Dataset
    nominal: np.ndarray
    nominal_extra: np.ndarray | None = None
    derivative_window: float = DERIVATIVE_WINDOW
    rigid_regressor: np.ndarray | None = field(default=None, repr=False)
    parts: tuple["GapData", ...] = field(default=(), repr=False)

    def __post_init__(self) -> None:
        expected = (self.dataset.n_samples, self.model.nv, self.model.n_inertial)
        if self.rigid_regressor is not None and np.shape(self.rigid_regressor) != expected:
            raise DatasetError(f"GapData.rigid_regressor has shape "
                               f"{np.shape(self.rigid_regressor)}; the dataset's samples need "
                               f"{expected} (N, nv, 10·nbodies)")

    @classmethod
    def concatenate(cls, parts: Sequence["GapData"]) -> "GapData":
        """The parts stacked as :meth:`Dataset.concatenate` stacks their datasets (same model,
        nominal parameters and derivative window), kept as :attr:`parts`: the nominal torque is
        the parts' stacked, and the rigid-body regressor, if ever needed, the parts' (computed
        once each) stacked instead of recomputed on every sample (it is per sample, so stacking
        equals recomputing)."""
        first = parts[0]
        if any(p.model is not first.model or not np.array_equal(p.nominal, first.nominal)
               or p.derivative_window != first.derivative_window
               or (p.nominal_extra is None) != (first.nominal_extra is None) for p in parts):
            raise ModelError("GapData.concatenate: the parts differ in model, nominal "
                             "parameters, nominal extra torque or derivative window")
        extra = (None if first.nominal_extra is None
                 else np.concatenate([p.nominal_extra for p in parts]))
        return cls(first.model, Dataset.concatenate([p.dataset for p in parts]), first.nominal,
                   extra, first.derivative_window, parts=tuple(parts))

    @property
    def n(self) -> int:
        return self.dataset.n_samples

    @property
    def nv(self) -> int:
        return self.model.nv

    @cached_property
    def segments(self) -> tuple[Segment, ...]:
        """The dataset's recording segments (:func:`segments`), found once."""
        return segments(self.dataset)

    @cached_property
    def step(self) -> float:
        """Median time step of all samples (s): the time-stamp resolution."""
        return float(np.median(np.diff(self.dataset.t)))

    @cached_property
    def sign_unresolved(self) -> np.ndarray:
        """(N, nv) bool: samples whose ``sign(q̇_j)`` the sampling does not resolve,
        ``|q̇_j| < h · median|q̈_j|`` (``h`` the :attr:`step`). A zero crossing at the joint's
        typical acceleration spends about one sample in that band, and a joint held by
        stiction stays in it: there the dry friction is set-valued (any torque within its
        cone), and a point-valued law of ``sign(q̇)`` fits the sign of numerical noise."""
        d = self.dataset
        return np.abs(d.dq) < self.step * np.median(np.abs(d.ddq), axis=0)

    @cached_property
    def tau(self) -> np.ndarray:
        return self.dataset.require_torque()

    @cached_property
    def rigid(self) -> np.ndarray:
        """Rigid-body regressor ``(N, nv, 10·nbodies)``: ``rigid_regressor`` if given, else the
        :attr:`parts`' stacked, else computed (once)."""
        if self.rigid_regressor is not None:
            return np.asarray(self.rigid_regressor, dtype=float)
        if self.parts:
            return np.concatenate([p.rigid for p in self.parts])
        d = self.dataset
        return rigid_body_regressor(self.model, d.q, d.dq, d.ddq)

    @cached_property
    def tau_nom(self) -> np.ndarray:
        """Nominal torque ``Y π₀`` (+ ``nominal_extra``), (N, nv); the :attr:`parts`' stacked
        when this one stacks parts (no regressor of the whole)."""
        if self.parts and self.rigid_regressor is None:
            return np.concatenate([p.tau_nom for p in self.parts])
        tau = self.rigid @ self.nominal
        return tau if self.nominal_extra is None else tau + self.nominal_extra

    @cached_property
    def residual(self) -> np.ndarray:
        """Measured minus nominal torque, (N, nv)."""
        return self.tau - self.tau_nom

    def gravity_torque(self, gravity: np.ndarray) -> np.ndarray:
        """Nominal gravity torque ``Y(q, 0, 0; g) π₀`` under the gravity vector ``g`` (base frame,
        m/s²), (N, nv): ``pinocchio.rnea`` of the model carrying ``π₀`` at rest (one C++ call for
        all samples; 10× cheaper than building the regressor), or, when a nominal body has no
        positive mass (its centre of mass undefined for Pinocchio), the regressor times ``π₀``."""
        d = self.dataset
        zero = np.zeros_like(d.dq)
        if np.all(self.nominal[0::10] > 0):
            carrier = self.model.with_parameters(self.nominal).with_gravity(gravity)
            return batch_rnea(carrier, carrier.pin_model, d.q, zero, zero)
        return rigid_body_regressor(self.model.with_gravity(gravity), d.q, zero, zero) \
            @ self.nominal

    @cached_property
    def gravity(self) -> np.ndarray:
        """Nominal gravity torque ``g(q)``, (N, nv)."""
        return self.gravity_torque(self.model.gravity)

    @cached_property
    def tilt_gravity(self) -> np.ndarray:
        """Nominal gravity torque under the tilt derivatives of gravity, (N, nv, 2): column ``k``
        is ``Y(q, 0, 0; ∂g/∂a_k) π₀`` (:func:`tilt_directions`), the ``tilt`` atom's columns."""
        return np.stack([self.gravity_torque(dg)
                         for dg in tilt_directions(self.model.gravity)], axis=2)

    @cached_property
    def tau_nom_derivatives(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Smoothed ``τ_nom``, ``τ̇_nom``, ``τ̈_nom`` (each (N, nv))."""
        return time_derivatives(self.dataset, self.tau_nom, self.derivative_window)

    @cached_property
    def rnea_derivatives(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``∂τ/∂q``, ``∂τ/∂q̇`` and ``M(q)`` of the nominal model, each (N, nv, nv)."""
        m = self.model.with_parameters(self.nominal).pin_model
        m.armature[:] = 0.0
        data = m.createData()
        d = self.dataset
        out = [np.empty((self.n, self.nv, self.nv)) for _ in range(3)]
        for k in range(self.n):
            out[0][k], out[1][k], out[2][k] = pin.computeRNEADerivatives(
                m, data, self.model.configuration(d.q[k]), d.dq[k], d.ddq[k])
        # Pinocchio fills the upper triangle of M: mirror it (all samples at once)
        upper, lower = np.triu_indices(self.nv, 1)
        out[2][:, lower, upper] = out[2][:, upper, lower]
        return out[0], out[1], out[2]




def lowpass_segments(dataset: Dataset, x: np.ndarray, cutoff: float,
                     plan: Sequence[Segment] | None = None) -> np.ndarray:
    """``x`` (N,) or (N, m) through the signal chain's zero-phase Butterworth low-pass
    (:func:`consistid.data.signals.lowpass`) at ``cutoff`` Hz, per recording segment (resampled to a
    uniform grid at its median step and back when the steps vary); ``inf``: ``x`` unchanged.
    ``plan``: :func:`segments` of ``dataset`` when already found (:attr:`GapData.segments`).
    Columns are filtered independently: filtering several at once gives each the same numbers."""
    if not np.isfinite(cutoff):
        return x
    flat = x.reshape(x.shape[0], -1)
    out = np.empty_like(flat)
    for seg in segments(dataset) if plan is None else plan:
        idx, t = seg.index, seg.t
        if seg.size < 8:
            out[idx] = flat[idx]
            continue
        dt = seg.step
        rate = 1.0 / dt
        if cutoff >= 0.45 * rate:
            out[idx] = flat[idx]
            continue
        if seg.uniform:
            out[idx] = lowpass(flat[idx], cutoff, rate)
        else:
            grid = t[0] + dt * np.arange(int(np.floor((t[-1] - t[0]) / dt)) + 1)
            xi = np.column_stack([np.interp(grid, t, c) for c in flat[idx].T])
            yi = lowpass(xi, cutoff, rate)
            out[idx] = np.column_stack([np.interp(t, grid, c) for c in yi.T])
    return out.reshape(x.shape)


def smooth_sign(x: np.ndarray, speed: float) -> np.ndarray:
    """``tanh(x / speed)``, or ``sign(x)`` when ``speed`` is 0."""
    return np.sign(x) if speed <= 0 else np.tanh(x / speed)


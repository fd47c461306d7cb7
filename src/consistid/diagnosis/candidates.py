r"""Candidate effects that may explain a sim-to-real torque gap, each a named model extension.

The nominal (simulator) model predicts ``τ_nom = Y(q, q̇, q̈) π₀``. An effect adds a correction
that is linear in its parameters ``θ`` once its *setting* (a harmonic order) is fixed:

.. math::  \tau \approx \tau_\text{nom} + \Phi_e(q, \dot q, \ddot q, \tau_\text{nom})\,\theta_e

Each effect offers *atoms*: the effect on one joint (``coulomb`` on joint 3) or on the whole arm
(``inertia``, ``payload``, ``tilt``, a ``delay`` common to all channels). :mod:`consistid.diagnose`
selects atoms greedily by their held-out residual reduction. The linearisations (delay,
elasticity, tilt) are first-order Taylor expansions; :mod:`consistid.diagnose` refines the delay
exactly afterwards.

Effects and their signatures (what each looks like in the residual ``r = τ − τ_nom``):

``inertia``
    Rigid-body parameter mismatch: ``r = W_b δβ`` with ``W_b`` the base regressor (Gautier 1991,
    doi:10.1002/rob.4620080405). Couples joints, scales with q̈ and with gravity-loaded poses.
``coulomb``
    ``r_j = f_c L[tanh(q̇_j / v_s)]`` (``v_s = 0``: ``sign``): a step at ``q̇_j = 0`` in
    residual-versus-velocity. ``v_s`` (a smooth friction law) is chosen from
    :data:`COULOMB_SPEEDS` and ``L`` from :data:`FILTER_CUTOFFS` on the training data: ``L`` is
    the identity, or, when the torques were low-pass filtered, the zero-phase Butterworth filter
    of the signal chain (:func:`consistid.data.signals.lowpass`) at cut-off ``f_c``, which smears the
    step over its response time and does not commute with the sign.
``viscous``
    ``r_j = f_v q̇_j``: a straight line through the origin in residual-versus-velocity.
``offset``
    ``r_j = f_o``: a constant bias, the same at rest and moving either way (torque-sensor offset).
``gain``
    ``τ_meas,j = (1 + g_j) τ_j``: ``r_j = g_j τ_nom,j``, proportional to the joint's own torque.
``armature``
    Rotor inertia reflected through the gear, ``r_j = I_a q̈_j`` on joint ``j`` alone (Pinocchio's
    ``model.armature``).
``payload``
    A rigid load on the last body: ``r = Y_n δπ_n``, the regressor block of the last body; acts on
    every joint, following the flange pose. A subset of ``inertia``.
``delay``
    The torque channel lags the position channel by ``d``: ``τ_meas(t) = τ(t − d)``, so
    ``r ≈ −d τ̇_nom`` (first order), in quadrature with the torque and growing with frequency.
    Offered per joint and as one delay common to all channels.
``elasticity``
    A spring of compliance ``c_j = 1/k_j`` between the measured (motor-side) position and the
    link, with the torque measured at the spring (the two-mass model; Spong 1987,
    doi:10.1115/1.3143884): the link is at ``q − c_j τ_j e_j``, so to first order
    ``r = −c_j (∂τ/∂q_j τ_j + ∂τ/∂q̇_j τ̇_j + M_{:,j} τ̈_j)``. Acts on every joint; grows with
    frequency towards the joint resonance.
``ripple``
    Position-dependent torque ripple (cogging, gear-tooth or encoder eccentricity), periodic in
    the joint angle: ``r_j = L[a sin(k q_j) + b cos(k q_j)]`` with integer ``k ≥ 2`` cycles per
    radian, seen at least twice over the joint's range of motion, found by a periodogram search,
    and ``L`` the identity or, for low-pass filtered torques, the chain's filter at a cut-off
    chosen from :data:`FILTER_CUTOFFS` and refined between its grid neighbours: ``k q̇_j / 2π``
    easily exceeds the cut-off. Order 2 (twice per revolution) thus needs a joint range of a
    full revolution; over less, the data do not tell it from ``position`` plus ``offset``.
``position``
    A torque that turns with the joint, once per revolution: ``r_j = p_s sin q_j + p_c cos q_j``,
    the identification's ``position`` columns (:mod:`consistid.regressor`, names
    ``<joint>.ps1``, ``.pc1``), offered on every joint without a search. Physically:
    cross-talk of the bending moments a joint torque sensor carries, whose direction in the
    sensor frame turns with the joint (Lee, Kim & Song 2010, doi:10.1007/s12541-010-0025-0), or
    a mounting eccentricity or misalignment of sensor or bearing. Unlike ``ripple`` it needs no
    full period in the data: over part of a revolution it is a slow, smooth function of ``q_j``
    alone (nearly ``offset`` when the joint moves little). Gravity torques are harmonics of the
    same order: where a link's gravity torque on its joint is exactly ``a sin q_j + b cos q_j``
    (a joint whose axis keeps its direction to gravity), the atom lies in the span of
    ``inertia``, and :mod:`consistid.diagnose` reports the two as indistinguishable
    alternatives. The torque filter is ignored: ``|q̇_j| / 2π`` stays far below the cut-offs.
``tilt``
    The robot's base is not level: gravity in the base frame is ``g(a) = R_v(a₂) R_u(a₁) g₀``
    (rad; for ``g₀ ∥ −z`` roll ``a₁`` about the base ``x`` axis, then pitch ``a₂`` about ``y``)
    instead of the URDF's ``g₀``. The torques are linear in gravity (:mod:`consistid.estimation.mounting`,
    whose :func:`~consistid.estimation.mounting.estimate_mounting` finds the tilt alone by variable
    projection, Golub & Pereyra 1973), and ``∂g/∂a₁ = u × g₀``, ``∂g/∂a₂ = v × g₀`` at
    ``a = 0`` (:func:`tilt_directions`), so to first order

    .. math::  r = a_1\, Y(q, 0, 0;\, u \times g_0)\, \pi_0
               + a_2\, Y(q, 0, 0;\, v \times g_0)\, \pi_0,

    the nominal gravity torque under a horizontal gravity: one arm-wide atom of two
    parameters. It loads a vertical first joint, which a level base leaves without gravity
    torque, with a torque that turns with ``q₁``; on the other joints it shows as a gravity
    torque of the wrong direction. Part of it lies in the span of ``inertia``: turning gravity
    within the plane of the arm is what a change of the links' mass moments does, and only the
    first joint's motion tells the two apart (on the Panda over a random excitation, 76 % of
    the roll column's norm and 13 % of the pitch column's lie outside the base regressor's
    span); :mod:`consistid.diagnose` reports indistinguishable candidates as alternatives and
    names a candidate inside the selected ones in a note. The tilt stays first order, with no
    exact refinement after the selection: ``O(a²)`` of the gravity torque is left out
    (1.5·10⁻⁴ of it at 1°), and the columns use the nominal ``π₀``, so with the rigid body
    also wrong the angles carry a relative error of the order of the gravity-loaded
    parameters' (2 % of the roll with the Panda's inertias perturbed by 20 %). Offered only for
    a model with gravity.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Callable, Sequence

import numpy as np
import pinocchio as pin
import scipy.optimize
import scipy.signal

from ..identification.base import BaseParameters, compute_base_parameters
from ..data.dataset import Dataset
from ..errors import DatasetError, ModelError, check_option
from ..robot.model import RobotModel
from ..estimation.mounting import tilt_axes
from ..robot.inertia import INERTIAL_NAMES
from ..identification.regressor import TERM_COLUMNS, RegressorSpec, joint_columns, rigid_body_regressor

#: Effect names in the order reports list them (the names of the design document).
EFFECT_NAMES: tuple[str, ...] = ("inertia", "coulomb", "viscous", "offset", "gain", "armature",
                                 "payload", "delay", "elasticity", "ripple", "position", "tilt")

SIGNATURES: dict[str, str] = {
    "inertia": "follows the rigid-body regressor: scales with q̈ and gravity poses, couples joints",
    "coulomb": "a step at q̇ = 0 in residual-versus-velocity",
    "viscous": "a line through the origin in residual-versus-velocity",
    "offset": "a constant bias, at rest and moving either way",
    "gain": "proportional to the joint's own torque",
    "armature": "proportional to the joint's own acceleration q̈_j",
    "payload": "a load on the last body: gravity/inertia residual on all joints",
    "delay": "≈ −d·τ̇: in quadrature with the torque, grows with frequency",
    "elasticity": "spring deflection τ/k: grows with frequency towards a resonance",
    "ripple": "periodic in the joint angle (k cycles per radian)",
    "position": "turns with the joint, once per revolution: a sin q_j + b cos q_j",
    "tilt": "gravity torque of a tilted base, also on a vertical first joint (turns with it)",
}

UNITS = {"inertia": "", "coulomb": "N·m", "viscous": "N·m·s/rad", "offset": "N·m", "gain": "",
         "armature": "kg·m²", "payload": "", "delay": "s", "elasticity": "rad/(N·m)",
         "ripple": "N·m", "position": "N·m", "tilt": "rad"}

INERTIAL_UNITS = dict(zip(INERTIAL_NAMES, ("kg", "kg·m", "kg·m", "kg·m", *["kg·m²"] * 6)))

#: Smoothing speeds (rad/s) tried for the ``coulomb`` atom; 0 is the sign function.
COULOMB_SPEEDS: tuple[float, ...] = (0.0, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1)

#: Low-pass cut-offs (Hz) tried for Coulomb steps and ripple seen through filtered torques;
#: ``inf``: unfiltered.
FILTER_CUTOFFS: tuple[float, ...] = (np.inf, 50.0, 30.0, 20.0, 12.0, 8.0, 5.0, 3.0, 2.0)

#: Savitzky–Golay window (s) for the time derivatives of the nominal torque (delay, elasticity).
DERIVATIVE_WINDOW = 0.04


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
    for s in np.unique(dataset.segment):
        idx = np.flatnonzero(dataset.segment == s)
        for o, v in zip(out, _segment_derivatives(dataset.t[idx], x[idx], window)):
            o[idx] = v
    return out[0], out[1], out[2]


def tilt_directions(gravity: np.ndarray) -> np.ndarray:
    """``(∂g/∂a₁, ∂g/∂a₂)`` at ``a = 0`` of ``g(a) = R_v(a₂) R_u(a₁) g₀``
    (:func:`consistid.estimation.mounting.gravity_from_tilt`): ``u × g₀`` and ``v × g₀`` with ``u, v`` the
    axes of :func:`consistid.estimation.mounting.tilt_axes` (``x``, ``y`` for ``g₀ ∥ −z``), shape (2, 3)."""
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
        already computed (e.g. stacked from parts by :meth:`concatenate`); default computed on
        first use of :attr:`rigid`. Not checked against the samples, only its shape.

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

    def __post_init__(self) -> None:
        expected = (self.dataset.n_samples, self.model.nv, self.model.n_inertial)
        if self.rigid_regressor is not None and np.shape(self.rigid_regressor) != expected:
            raise DatasetError(f"GapData.rigid_regressor has shape "
                               f"{np.shape(self.rigid_regressor)}; the dataset's samples need "
                               f"{expected} (N, nv, 10·nbodies)")

    @classmethod
    def concatenate(cls, parts: Sequence["GapData"]) -> "GapData":
        """The parts stacked as :meth:`Dataset.concatenate` stacks their datasets (same model,
        nominal parameters and derivative window), with the rigid-body regressor of the parts
        (computed once each) stacked and passed as ``rigid_regressor`` instead of recomputed on
        every sample (it is per sample, so stacking equals recomputing)."""
        first = parts[0]
        if any(p.model is not first.model or not np.array_equal(p.nominal, first.nominal)
               or p.derivative_window != first.derivative_window
               or (p.nominal_extra is None) != (first.nominal_extra is None) for p in parts):
            raise ModelError("GapData.concatenate: the parts differ in model, nominal "
                             "parameters, nominal extra torque or derivative window")
        extra = (None if first.nominal_extra is None
                 else np.concatenate([p.nominal_extra for p in parts]))
        return cls(first.model, Dataset.concatenate([p.dataset for p in parts]), first.nominal,
                   extra, first.derivative_window,
                   rigid_regressor=np.concatenate([p.rigid for p in parts]))

    @property
    def n(self) -> int:
        return self.dataset.n_samples

    @property
    def nv(self) -> int:
        return self.model.nv

    @cached_property
    def tau(self) -> np.ndarray:
        return self.dataset.require_torque()

    @cached_property
    def rigid(self) -> np.ndarray:
        """Rigid-body regressor ``(N, nv, 10·nbodies)``: ``rigid_regressor`` if given, else
        computed (once)."""
        if self.rigid_regressor is not None:
            return np.asarray(self.rigid_regressor, dtype=float)
        d = self.dataset
        return rigid_body_regressor(self.model, d.q, d.dq, d.ddq)

    @cached_property
    def tau_nom(self) -> np.ndarray:
        """Nominal torque ``Y π₀`` (+ ``nominal_extra``), (N, nv)."""
        tau = self.rigid @ self.nominal
        return tau if self.nominal_extra is None else tau + self.nominal_extra

    @cached_property
    def residual(self) -> np.ndarray:
        """Measured minus nominal torque, (N, nv)."""
        return self.tau - self.tau_nom

    @cached_property
    def gravity(self) -> np.ndarray:
        """Nominal gravity torque ``g(q)``, (N, nv)."""
        d = self.dataset
        zero = np.zeros_like(d.q)
        return rigid_body_regressor(self.model, d.q, zero, zero) @ self.nominal

    @cached_property
    def tilt_gravity(self) -> np.ndarray:
        """Nominal gravity torque under the tilt derivatives of gravity, (N, nv, 2): column ``k``
        is ``Y(q, 0, 0; ∂g/∂a_k) π₀`` (:func:`tilt_directions`), the ``tilt`` atom's columns."""
        d = self.dataset
        zero = np.zeros_like(d.dq)
        return np.stack([rigid_body_regressor(self.model.with_gravity(dg), d.q, zero, zero)
                         @ self.nominal for dg in tilt_directions(self.model.gravity)], axis=2)

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
            dq_, dv_, mm = pin.computeRNEADerivatives(m, data, self.model.configuration(d.q[k]),
                                                      d.dq[k], d.ddq[k])
            out[0][k], out[1][k] = dq_, dv_
            out[2][k] = np.triu(mm) + np.triu(mm, 1).T
        return out[0], out[1], out[2]


@dataclass(frozen=True)
class Atom:
    """One candidate: an effect on one joint (or on the whole arm) with its parameter columns.

    Attributes
    ----------
    effect : effect name (one of :data:`EFFECT_NAMES`).
    joint : the joint index it acts on, or ``None`` for an arm-wide atom.
    parameter_names : names of its parameters (columns), e.g. ``("panda_joint2.fc",)``.
    units : unit of each parameter.
    setting : the nonlinear setting fixed before the linear fit (ripple order ``k``, Coulomb
        smoothing speed ``v_s``), or ``None``.
    cutoff : for Coulomb and ripple, the low-pass cut-off (Hz) through which the torque sees
        them (``inf``: none).
    """

    effect: str
    joint: int | None
    parameter_names: tuple[str, ...]
    units: tuple[str, ...]
    setting: float | None = None
    cutoff: float = np.inf

    @property
    def n_parameters(self) -> int:
        return len(self.parameter_names)

    def label(self, joint_names: list[str]) -> str:
        where = "all joints" if self.joint is None else joint_names[self.joint]
        extra = ""
        if self.setting is not None and self.effect == "ripple":
            extra = f", k={self.setting:g}"
        elif self.setting:
            extra = f", v_s={self.setting:g}"
        if np.isfinite(self.cutoff):
            extra += f", seen below {self.cutoff:.3g} Hz"
        return f"{self.effect} ({where}{extra})"


def lowpass_segments(dataset: Dataset, x: np.ndarray, cutoff: float) -> np.ndarray:
    """``x`` (N,) or (N, m) through the signal chain's zero-phase Butterworth low-pass
    (:func:`consistid.data.signals.lowpass`) at ``cutoff`` Hz, per recording segment (resampled to a
    uniform grid at its median step and back when the steps vary); ``inf``: ``x`` unchanged."""
    if not np.isfinite(cutoff):
        return x
    from ..data.signals import lowpass

    flat = x.reshape(x.shape[0], -1)
    out = np.empty_like(flat)
    for s in np.unique(dataset.segment):
        idx = np.flatnonzero(dataset.segment == s)
        t = dataset.t[idx]
        if idx.size < 8:
            out[idx] = flat[idx]
            continue
        dt = float(np.median(np.diff(t)))
        rate = 1.0 / dt
        if cutoff >= 0.45 * rate:
            out[idx] = flat[idx]
            continue
        uniform = np.ptp(np.diff(t)) <= 1e-6 * dt
        if uniform:
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


def _on_row(data: GapData, joint: int, cols: np.ndarray) -> np.ndarray:
    """Columns ``(N, k)`` placed on the row of ``joint`` of an ``(N, nv, k)`` block."""
    cols = cols.reshape(data.n, -1)
    out = np.zeros((data.n, data.nv, cols.shape[1]))
    out[:, joint, :] = cols
    return out


class EffectLibrary:
    """The candidate effects for one robot: builds atoms and evaluates their columns.

    Parameters
    ----------
    model : the robot.
    effects : names among :data:`EFFECT_NAMES`.
    base : base parameters of the rigid body (computed when ``None``); the ``inertia`` atom's
        columns are the base regressor.
    ripple_orders : (min, max) integer ripple orders ``k`` searched (min is further raised so that
        the joint's range holds two periods, max lowered by the sampling rate and speed so that
        ``k·|q̇|·Δt < π/2``; order 1 is the ``position`` effect).
    """

    def __init__(self, model: RobotModel, effects: tuple[str, ...] | list[str] = EFFECT_NAMES,
                 base: BaseParameters | None = None,
                 ripple_orders: tuple[int, int] = (2, 400)) -> None:
        for e in effects:
            check_option("effect", e, EFFECT_NAMES)
        if len(set(effects)) != len(effects):
            raise ModelError(f"effects list {list(effects)} names an effect twice")
        self.model = model
        self.effects = tuple(effects)
        self.base = base if base is not None else compute_base_parameters(model)
        self.ripple_orders = ripple_orders
        self._columns: dict[str, Callable[[Atom, GapData], np.ndarray]] = {
            "inertia": self._inertia, "coulomb": self._coulomb, "viscous": self._viscous,
            "offset": self._offset, "gain": self._gain, "armature": self._armature,
            "payload": self._payload, "delay": self._delay, "elasticity": self._elasticity,
            "ripple": self._ripple, "position": self._position, "tilt": self._tilt,
        }

    # ----------------------------------------------------------------------------- atoms
    def atoms(self, tuning: GapData | None = None,
              tuning_residual: np.ndarray | None = None) -> list[Atom]:
        """All candidate atoms; ``ripple`` orders are tuned on ``tuning_residual`` (N, nv) of the
        ``tuning`` data (needed when ``ripple`` is among the effects)."""
        names = self.model.joint_names
        out: list[Atom] = []
        for e in self.effects:
            if e == "inertia":
                units = tuple(INERTIAL_UNITS[n.rstrip("*").split(".")[-1]]
                              for n in self.base.names)
                out.append(Atom(e, None, tuple(f"δ{n}" for n in self.base.names), units))
            elif e == "payload":
                out.append(Atom(e, None, tuple(f"payload.{p}" for p in INERTIAL_NAMES),
                                tuple(INERTIAL_UNITS[p] for p in INERTIAL_NAMES)))
            elif e == "tilt":
                if np.any(self.model.gravity):
                    out.append(Atom(e, None, ("tilt.roll", "tilt.pitch"), (UNITS[e],) * 2))
            elif e == "position":
                out += [Atom(e, j, tuple(f"{names[j]}.{c}" for c in TERM_COLUMNS[e]),
                             (UNITS[e],) * 2) for j in range(self.model.nv)]
            elif e == "ripple":
                if tuning is None or tuning_residual is None:
                    raise ModelError("ripple atoms need tuning data and a residual")
                for j in range(self.model.nv):
                    k = self.ripple_order(tuning, tuning_residual[:, j], j)
                    if k is not None:
                        atom = Atom(e, j, (f"{names[j]}.ripple_sin", f"{names[j]}.ripple_cos"),
                                    ("N·m", "N·m"), float(k))
                        out.append(self.tune_cutoff(tuning, tuning_residual[:, j], atom)[0])
            else:
                suffix = (TERM_COLUMNS[e][0] if e in TERM_COLUMNS else
                          {"gain": "gain", "delay": "delay", "elasticity": "compliance"}[e])
                if e == "delay":
                    out.append(Atom(e, None, ("delay",), ("s",)))
                out += [Atom(e, j, (f"{names[j]}.{suffix}",), (UNITS[e],))
                        for j in range(self.model.nv)]
        return out

    def columns(self, atom: Atom, data: GapData) -> np.ndarray:
        """The atom's columns on ``data``, shape ``(N, nv, n_parameters)``."""
        return self._columns[atom.effect](atom, data)

    # ----------------------------------------------------------------------------- columns
    def _inertia(self, atom: Atom, data: GapData) -> np.ndarray:
        return data.rigid[..., self.base.independent]

    def _payload(self, atom: Atom, data: GapData) -> np.ndarray:
        return data.rigid[..., -10:]

    def _coulomb(self, atom: Atom, data: GapData) -> np.ndarray:
        col = smooth_sign(data.dataset.dq[:, atom.joint], atom.setting or 0.0)
        return _on_row(data, atom.joint, lowpass_segments(data.dataset, col, atom.cutoff))

    def _viscous(self, atom: Atom, data: GapData) -> np.ndarray:
        return _on_row(data, atom.joint, data.dataset.dq[:, atom.joint])

    def _offset(self, atom: Atom, data: GapData) -> np.ndarray:
        return _on_row(data, atom.joint, np.ones(data.n))

    def _gain(self, atom: Atom, data: GapData) -> np.ndarray:
        return _on_row(data, atom.joint, data.tau_nom[:, atom.joint])

    def _armature(self, atom: Atom, data: GapData) -> np.ndarray:
        return _on_row(data, atom.joint, data.dataset.ddq[:, atom.joint])

    def _delay(self, atom: Atom, data: GapData) -> np.ndarray:
        rate = data.tau_nom_derivatives[1]
        if atom.joint is None:
            return -rate[:, :, None]
        return _on_row(data, atom.joint, -rate[:, atom.joint])

    def _elasticity(self, atom: Atom, data: GapData) -> np.ndarray:
        j = atom.joint
        tau, tau_d, tau_dd = (x[:, j] for x in data.tau_nom_derivatives)
        d_q, d_v, mass = data.rnea_derivatives
        col = d_q[:, :, j] * tau[:, None] + d_v[:, :, j] * tau_d[:, None] \
            + mass[:, :, j] * tau_dd[:, None]
        return -col[:, :, None]

    def _ripple(self, atom: Atom, data: GapData) -> np.ndarray:
        phase = atom.setting * data.dataset.q[:, atom.joint]
        cols = np.column_stack([np.sin(phase), np.cos(phase)])
        return _on_row(data, atom.joint, lowpass_segments(data.dataset, cols, atom.cutoff))

    def _position(self, atom: Atom, data: GapData) -> np.ndarray:
        d = data.dataset
        spec = RegressorSpec.make(self.model, {"position": [atom.joint]})
        return joint_columns(d.q, d.dq, d.ddq, spec)

    def _tilt(self, atom: Atom, data: GapData) -> np.ndarray:
        return data.tilt_gravity

    # ----------------------------------------------------------------------------- tuning
    def tune_cutoff(self, data: GapData, residual: np.ndarray, atom: Atom
                    ) -> tuple[Atom, float]:
        """The atom (Coulomb or ripple, one joint) with the cut-off of :data:`FILTER_CUTOFFS`
        (below the Nyquist frequency), refined between its grid neighbours, whose columns
        explain most of ``residual`` (N,) by least squares; and that explained sum of squares."""
        nyquist = 0.5 / float(np.median(np.diff(data.dataset.t)))

        def explained(fc: float) -> float:
            a = self.columns(replace(atom, cutoff=fc), data)[:, atom.joint, :]
            g, c = a.T @ a, a.T @ residual
            if np.linalg.cond(g) > 1e12:
                return -np.inf
            return float(c @ np.linalg.solve(g, c))

        grid = [fc for fc in FILTER_CUTOFFS if not (np.isfinite(fc) and fc >= 0.9 * nyquist)]
        scores = [explained(fc) for fc in grid]
        i = int(np.argmax(scores))
        if not np.isfinite(grid[i]):
            return replace(atom, cutoff=np.inf), scores[i]
        lo = grid[i + 1] if i + 1 < len(grid) else grid[i] / 2
        hi = grid[i - 1] if np.isfinite(grid[i - 1]) else min(2 * grid[i], nyquist)
        res = scipy.optimize.minimize_scalar(lambda x: -explained(float(np.exp(x))),
                                             bounds=(np.log(lo), np.log(hi)), method="bounded",
                                             options={"xatol": 1e-3})
        if -res.fun > scores[i]:
            return replace(atom, cutoff=float(np.exp(res.x))), float(-res.fun)
        return replace(atom, cutoff=grid[i]), scores[i]

    def tune_coulomb(self, data: GapData, residual: np.ndarray, atom: Atom) -> Atom:
        """The Coulomb atom with the smoothing speed of :data:`COULOMB_SPEEDS` and the cut-off
        (:meth:`tune_cutoff`) that together explain most of ``residual`` (N,)."""
        trials = [self.tune_cutoff(data, residual, replace(atom, setting=v))
                  for v in COULOMB_SPEEDS]
        return max(trials, key=lambda t: t[1])[0]

    def ripple_order(self, data: GapData, residual: np.ndarray, joint: int) -> int | None:
        """The integer order ``k`` whose ``sin(k q_j), cos(k q_j)`` pair explains most of
        ``residual`` (a periodogram over ``k``, Lomb 1976, doi:10.1007/BF00648343, with exact
        least squares per ``k``); ``None`` when no order is resolvable at this sampling."""
        q = data.dataset.q[:, joint]
        dt = float(np.median(np.diff(data.dataset.t)))
        speed = float(np.percentile(np.abs(data.dataset.dq[:, joint]), 99))
        k_lo, k_hi = self.ripple_orders
        k_hi = min(k_hi, int(np.pi / (2 * max(speed, 1e-9) * dt)))
        span = float(np.ptp(q))
        k_lo = max(k_lo, int(np.ceil(2 * 2 * np.pi / max(span, 1e-12))))  # ≥ 2 periods seen
        if k_hi < k_lo:
            return None
        r = residual - residual.mean()
        best_k, best = None, -np.inf
        for start in range(k_lo, k_hi + 1, 64):
            ks = np.arange(start, min(start + 64, k_hi + 1))
            phase = np.outer(q, ks)
            s, c = np.sin(phase), np.cos(phase)
            s -= s.mean(axis=0)
            c -= c.mean(axis=0)
            ss, cc, sc = (s * s).sum(0), (c * c).sum(0), (s * c).sum(0)
            rs, rc = r @ s, r @ c
            det = ss * cc - sc ** 2
            ok = det > 1e-9 * ss * cc
            explained = np.where(ok, (cc * rs ** 2 - 2 * sc * rs * rc + ss * rc ** 2)
                                 / np.where(ok, det, 1.0), -np.inf)
            i = int(np.argmax(explained))
            if explained[i] > best:
                best, best_k = float(explained[i]), int(ks[i])
        return best_k

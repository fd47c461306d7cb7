r"""Excitation trajectories: Fourier series (with a boundary polynomial) and B-splines.

Every parameterisation here is *affine* in its coefficients: with the coefficients of joint ``j``
in row ``X[j]`` (the same basis for every joint),

.. math::  q^{(d)}_j(t) = O_d(t)_j + G_d(t)\, X_j, \qquad d = 0, 1, 2,

so joint position, velocity and acceleration limits are linear constraints on ``X`` and the
chain rule from sampled states to coefficients is a matrix product (:meth:`Parameterisation.basis`).

:class:`FourierPolynomial`
    Finite Fourier series per joint (Swevers, Ganseman, Tükel, De Schutter, Van Brussel 1997,
    "Optimal robot excitation and identification", IEEE T-RA 13(5) 730–740,
    doi:10.1109/70.631234) plus a fifth-order polynomial that imposes position, velocity and
    acceleration at both ends (Haddadin, *Advanced Robot Control* lecture notes ch. 6, "a polynomial
    term is added"):

    .. math::

        q_j(t) = q_{0,j} + \sum_{l=1}^{H} \frac{a_{jl}}{\omega_f l}\sin(\omega_f l t)
                 - \frac{b_{jl}}{\omega_f l}\cos(\omega_f l t) + \sum_{k=0}^{5} c_{jk} (t/T)^k ,

    with ``ω_f = 2π/T``; the six ``c_jk`` solve the six boundary conditions exactly.
:class:`BSplineParameterisation`
    A B-spline of degree ``p`` (4 by default: continuous jerk) through via-points ``q_k`` at times
    ``t_k`` with velocity and acceleration imposed at both ends (Rackl, Lampariello, Hirzinger 2012,
    "Robot excitation trajectories for dynamic parameter estimation using optimized B-splines",
    ICRA, doi:10.1109/ICRA.2012.6225279, eqs. 19–32): the ``n + 5`` control points solve the
    square collocation system ``A p = c`` (eq. 31).
:class:`FourierTrajectory`
    The plain periodic Fourier series (no polynomial), used by :mod:`consistid.simulate`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from math import factorial
from pathlib import Path
from typing import Sequence

import numpy as np
import scipy.interpolate

from ..data.dataset import Dataset
from ..errors import ExcitationError, JointCountError, check_number
from ..robot.model import RobotModel

#: Default acceleration bound (rad/s²) when a model has none: URDFs carry no acceleration limits.
DEFAULT_ACCELERATION_LIMIT = 10.0


def joint_vector(name: str, value: float | Sequence[float] | np.ndarray, nv: int,
                  allow_infinite: bool = False) -> np.ndarray:
    """``value`` (a scalar for every joint, or ``nv`` values) as an (nv,) float array.

    Raises :class:`JointCountError` for another shape and :class:`ExcitationError` for NaN, or
    for ``±inf`` unless ``allow_infinite`` (limits, where ``inf`` means unbounded).
    """
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ExcitationError(f"{name} must be a number or one number per joint ({nv}), got "
                              f"{value!r}") from None
    if a.ndim == 0:
        a = np.full(nv, float(a))
    elif a.shape != (nv,):
        raise JointCountError(f"{name} has shape {a.shape}; expected a scalar or ({nv},)")
    bad = np.isnan(a) if allow_infinite else ~np.isfinite(a)
    if bad.any():
        kind = "NaN" if allow_infinite else "not finite"
        raise ExcitationError(f"{name} = {a} is {kind} (joint {int(np.argmax(bad))})")
    return a.copy()


def position_range(lower: np.ndarray, upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Finite stand-ins for position limits, per joint: the limits where both are finite, one
    turn ``2π`` from the finite one when only one is, ``±π`` when neither is.

    They give unbounded joints a centre and a range to draw from, and one-sided limits a finite
    scale (``upper − lower = 2π``) for their relative margins.
    """
    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    has_lo, has_hi = np.isfinite(lower), np.isfinite(upper)
    lo = np.where(has_lo, lower, np.where(has_hi, upper - 2 * np.pi, -np.pi))
    hi = np.where(has_hi, upper, np.where(has_lo, lower + 2 * np.pi, np.pi))
    return lo, hi



#: The most bytes a sampled trajectory (t, q, q̇, q̈ in float64) may take: 2 GiB, about 4 h of
#: a 7-joint arm at 1 kHz. More is refused before anything is allocated.
MAX_SAMPLE_BYTES = 2 * 2**30


def sample_count(rate: float, duration: float, nv: int) -> int:
    """``round(duration · rate)`` samples, or :class:`ExcitationError` (before allocating)
    when they would take more than :data:`MAX_SAMPLE_BYTES`."""
    if not (np.isfinite(rate) and rate > 0):
        raise ExcitationError(f"sampling rate = {rate} Hz; must be positive")
    if not (np.isfinite(duration) and duration > 0):
        raise ExcitationError(f"duration = {duration} s; must be positive")
    n = duration * rate
    size = n * (1 + 3 * nv) * 8
    if size > MAX_SAMPLE_BYTES:
        raise ExcitationError(f"{n:.3g} samples ({duration:g} s at {rate:g} Hz) of t, q, dq, "
                              f"ddq take {size / 2**30:.3g} GiB, more than "
                              f"{MAX_SAMPLE_BYTES / 2**30:g} GiB: lower the rate or the "
                              "duration (a controller replays one period in a loop)")
    return int(round(n))

@dataclass(frozen=True, eq=False)
class BoundaryConditions:
    """Joint states imposed at the start (``t = 0``) and the end (``t = T``) of a trajectory.

    Parameters
    ----------
    q_start : (nv,) rad, or ``None`` for a free start position (chosen by the optimiser).
    q_end : (nv,) rad, or ``None`` for ``q_end = q_start`` (a closed trajectory).
    dq_start, dq_end, ddq_start, ddq_end : scalars or (nv,), rad/s and rad/s²; default 0.

    Notes
    -----
    A trajectory whose end state equals its start state is *periodic*: repeating it keeps
    ``q, q̇, q̈`` continuous, which allows averaging over periods.
    """

    q_start: np.ndarray | Sequence[float] | None = None
    q_end: np.ndarray | Sequence[float] | None = None
    dq_start: float | np.ndarray | Sequence[float] = 0.0
    dq_end: float | np.ndarray | Sequence[float] = 0.0
    ddq_start: float | np.ndarray | Sequence[float] = 0.0
    ddq_end: float | np.ndarray | Sequence[float] = 0.0

    def resolved(self, nv: int) -> "BoundaryConditions":
        """A copy with every entry an (nv,) array (``q_start`` stays ``None`` when free)."""
        if self.q_start is None and self.q_end is not None:
            raise ExcitationError("boundary q_end is given but q_start is free; give q_start too "
                                  "(q_end defaults to q_start)")
        q_start = None if self.q_start is None else joint_vector("q_start", self.q_start, nv)
        q_end = None if q_start is None else (
            q_start.copy() if self.q_end is None else joint_vector("q_end", self.q_end, nv))
        return BoundaryConditions(
            q_start, q_end, *(joint_vector(n, getattr(self, n), nv)
                              for n in ("dq_start", "dq_end", "ddq_start", "ddq_end")))

    @property
    def free_position(self) -> bool:
        return self.q_start is None

    @property
    def closed(self) -> bool:
        """End state equals start state (resolved conditions only)."""
        same_q = self.q_start is None or np.array_equal(self.q_start, self.q_end)
        return bool(same_q and np.array_equal(self.dq_start, self.dq_end)
                    and np.array_equal(self.ddq_start, self.ddq_end))


class Parameterisation(ABC):
    """A family of joint trajectories on ``[0, duration]``, affine in per-joint coefficients.

    Subclasses set ``nv``, ``duration`` and ``boundary`` (resolved) and implement
    :meth:`basis`, :meth:`rest`, :meth:`random_direction` and :attr:`coefficient_names`.
    """

    nv: int
    duration: float
    boundary: BoundaryConditions

    @property
    @abstractmethod
    def coefficient_names(self) -> list[str]:
        """Names of one joint's coefficients (the columns of ``X``)."""

    @property
    def n_coefficients(self) -> int:
        return len(self.coefficient_names)

    @property
    def periodic(self) -> bool:
        return self.boundary.closed

    @abstractmethod
    def basis(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(G, O)`` with ``G`` (3, N, n_coefficients) and ``O`` (3, N, nv) such that
        ``q^{(d)}(t_i) = O[d, i] + X @ G[d, i]`` for ``d = 0, 1, 2`` (times in
        ``[0, duration]``)."""

    @abstractmethod
    def rest(self, q_centre: np.ndarray) -> np.ndarray:
        """Coefficients (nv, n) of the motionless trajectory at ``q_centre`` (when the start
        position is free; with imposed positions, of the trajectory with no excitation term)."""

    @abstractmethod
    def random_direction(self, rng: np.random.Generator) -> np.ndarray:
        """Random coefficients (nv, n) of a motion added to :meth:`rest` (zero offsets)."""

    def evaluate(self, coefficients: np.ndarray, t: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(q, dq, ddq)``, each (len(t), nv), for coefficients (nv, n) at times in [0, T]."""
        g, o = self.basis(np.atleast_1d(np.asarray(t, dtype=float)))
        out = o + np.einsum("dic,jc->dij", g, coefficients)
        return out[0], out[1], out[2]

    def check_coefficients(self, coefficients: np.ndarray) -> np.ndarray:
        x = np.asarray(coefficients, dtype=float)
        if x.shape != (self.nv, self.n_coefficients):
            raise JointCountError(f"coefficients have shape {x.shape}; this {type(self).__name__} "
                                  f"needs ({self.nv}, {self.n_coefficients})")
        return x

    def trajectory(self, coefficients: np.ndarray) -> "Trajectory":
        return Trajectory(self, self.check_coefficients(coefficients))


def _fourier_basis(t: np.ndarray, omega: float, harmonics: int) -> np.ndarray:
    """Columns ``[a_1..a_H, b_1..b_H, q0]`` of the Fourier series and its two derivatives,
    shape (3, N, 2H + 1)."""
    w = omega * np.arange(1, harmonics + 1)
    s, c = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))
    one, zero = np.ones((t.size, 1)), np.zeros((t.size, 1))
    return np.stack([np.hstack([s / w, -c / w, one]),
                     np.hstack([c, s, zero]),
                     np.hstack([-s * w, c * w, zero])])


def _polynomial_basis(t: np.ndarray, duration: float, degree: int = 5) -> np.ndarray:
    """``d^d/dt^d (t/T)^k`` for ``k = 0..degree``, ``d = 0, 1, 2``, shape (3, N, degree + 1)."""
    s = np.asarray(t, dtype=float) / duration
    out = np.zeros((3, s.size, degree + 1))
    for d in range(3):
        for k in range(d, degree + 1):
            out[d, :, k] = factorial(k) / factorial(k - d) * s ** (k - d) / duration ** d
    return out


class FourierPolynomial(Parameterisation):
    r"""Fourier series plus a quintic boundary polynomial (see the module docstring).

    Coefficients per joint: ``a_1..a_H`` and ``b_1..b_H`` (rad/s), then ``q0`` (rad) when the
    start position is free. The polynomial ``λ_j(s) = Σ_k c_jk s^k``, ``s = t/T``, solves

    .. math:: λ^{(d)}(0) = q^{(d)}_\text{start} - δ^{(d)}(0), \quad
              λ^{(d)}(T) = q^{(d)}_\text{end} - δ^{(d)}(T), \quad d = 0, 1, 2,

    where ``δ`` is the Fourier part; with a free start position the position conditions read
    ``λ(0) = λ(T) = 0`` (start and end at ``δ(0) = δ(T)``). The polynomial is therefore a linear
    function of the coefficients and of the boundary values, which is how :meth:`basis` is built.

    Parameters
    ----------
    nv : number of joints.
    harmonics : ``H``.
    period : ``T`` in seconds (``ω_f = 2π/T``); the trajectory is defined on ``[0, T]``.
    boundary : imposed start/end states; default free position, zero velocity and acceleration.
    """

    def __init__(self, nv: int, harmonics: int = 5, period: float = 10.0,
                 boundary: BoundaryConditions | None = None) -> None:
        if int(harmonics) < 1:
            raise ExcitationError(f"harmonics = {harmonics}; need at least 1")
        if not period > 0:
            raise ExcitationError(f"period = {period} s; must be positive")
        self.nv, self.harmonics, self.duration = int(nv), int(harmonics), float(period)
        self.boundary = (boundary or BoundaryConditions()).resolved(self.nv)
        self.omega = 2.0 * np.pi / self.duration
        ends = np.array([0.0, self.duration])
        p = _polynomial_basis(ends, self.duration)                  # (3, 2, 6)
        rows = np.concatenate([p[:, 0], p[:, 1]])                   # start d=0,1,2 then end
        self._boundary_inverse = np.linalg.inv(rows)                # (6, 6), well conditioned
        fb = _fourier_basis(ends, self.omega, self.harmonics)       # (3, 2, 2H+1)
        f_rows = np.concatenate([fb[:, 0], fb[:, 1]])               # (6, 2H+1)
        bc = self.boundary
        if bc.free_position:
            f_rows[[0, 3]] = 0.0                                    # λ(0) = λ(T) = 0
            q_s = q_e = np.zeros(self.nv)
        else:
            f_rows = f_rows[:, :-1]                                 # q0 is absorbed by λ
            q_s, q_e = bc.q_start, bc.q_end
        self._fourier_rows = f_rows
        self._targets = np.stack([q_s, bc.dq_start, bc.ddq_start, q_e, bc.dq_end, bc.ddq_end])

    @property
    def coefficient_names(self) -> list[str]:
        names = [f"a{k}" for k in range(1, self.harmonics + 1)]
        names += [f"b{k}" for k in range(1, self.harmonics + 1)]
        return names + (["q0"] if self.boundary.free_position else [])

    def basis(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        f = _fourier_basis(t, self.omega, self.harmonics)
        if not self.boundary.free_position:
            f = f[..., :-1]
        p = _polynomial_basis(t, self.duration) @ self._boundary_inverse   # (3, N, 6)
        return f - p @ self._fourier_rows, p @ self._targets

    def unpack(self, coefficients: np.ndarray) -> dict[str, np.ndarray]:
        """Named parts: ``a, b`` (nv, H), ``q0`` (nv,), ``polynomial`` (nv, 6) in powers of t/T."""
        x = self.check_coefficients(coefficients)
        h = self.harmonics
        q0 = x[:, 2 * h] if self.boundary.free_position else np.zeros(self.nv)
        poly = (self._boundary_inverse @ (self._targets - self._fourier_rows @ x.T)).T
        return {"a": x[:, :h], "b": x[:, h:2 * h], "q0": q0, "polynomial": poly}

    def rest(self, q_centre: np.ndarray) -> np.ndarray:
        x = np.zeros((self.nv, self.n_coefficients))
        if self.boundary.free_position:
            x[:, -1] = q_centre
        return x

    def random_direction(self, rng: np.random.Generator) -> np.ndarray:
        x = rng.standard_normal((self.nv, self.n_coefficients))
        if self.boundary.free_position:
            x[:, -1] = 0.0
        return x

    def __repr__(self) -> str:
        return (f"FourierPolynomial(nv={self.nv}, harmonics={self.harmonics}, "
                f"period={self.duration:g})")


class BSplineParameterisation(Parameterisation):
    r"""B-spline joint trajectories through via-points (Rackl et al. 2012, eqs. 19–32).

    Via-points ``q_k`` at times ``0 = t_0 < t_1 < … < t_n = T``; with velocity and acceleration
    imposed at both ends there are ``n + 5`` conditions and as many control points. For degree 4
    the knot vector is Rackl's (eq. 22): ``t_0`` and ``t_n`` repeated 5 times and the midpoints
    ``(t_{k-1} + t_k)/2`` inside; for other degrees the interior knots are de Boor's averages of
    ``p`` consecutive condition sites. The control points solve ``A p = c`` (eq. 31), built with
    :class:`scipy.interpolate.BSpline`.

    Coefficients per joint: the free via-points — ``q_0 … q_{n-1}`` with a free start (and
    ``q_n = q_0``), or ``q_1 … q_{n-1}`` when ``q_start``/``q_end`` are imposed.

    Parameters
    ----------
    nv : number of joints.
    times : (n + 1,) increasing via-point times starting at 0, or an int ``n`` for ``n`` equal
        intervals of ``duration``.
    duration : seconds (ignored when ``times`` is an array: ``duration = times[-1]``).
    degree : spline degree ``p`` (3 … n + 4); 4 gives continuous jerk.
    boundary : imposed start/end states; default free (closed) position, zero velocity and
        acceleration.
    """

    def __init__(self, nv: int, times: int | Sequence[float] | np.ndarray = 10,
                 duration: float = 10.0, degree: int = 4,
                 boundary: BoundaryConditions | None = None) -> None:
        if np.ndim(times) == 0:
            n = int(times)
            if n < 2:
                raise ExcitationError(f"B-spline needs at least 2 intervals, got {n}")
            if not duration > 0:
                raise ExcitationError(f"duration = {duration} s; must be positive")
            t = np.linspace(0.0, float(duration), n + 1)
        else:
            t = np.asarray(times, dtype=float)
            if t.ndim != 1 or t.size < 3 or t[0] != 0.0 or np.any(np.diff(t) <= 0):
                raise ExcitationError(f"via-point times {t.tolist()} must be increasing, start "
                                      "at 0 and have at least 3 entries")
        n = t.size - 1
        degree = int(degree)
        if not 3 <= degree <= n + 4:
            raise ExcitationError(f"B-spline degree {degree} must lie in 3..{n + 4} for {n} "
                                  "intervals")
        self.nv, self.times, self.degree = int(nv), t, degree
        self.duration = float(t[-1])
        self.boundary = (boundary or BoundaryConditions()).resolved(self.nv)
        self.knots = self._knot_vector(t, degree)
        n_ctrl = n + 5
        ends = np.array([t[0], t[-1]])
        # Collocation rows: q(t_0), q'(t_0), q''(t_0), q(t_1..t_{n-1}), q''(t_n), q'(t_n), q(t_n).
        rows = np.vstack([self._basis_functions(ends[:1], 0), self._basis_functions(ends[:1], 1),
                          self._basis_functions(ends[:1], 2), self._basis_functions(t[1:-1], 0),
                          self._basis_functions(ends[1:], 2), self._basis_functions(ends[1:], 1),
                          self._basis_functions(ends[1:], 0)])
        if np.linalg.cond(rows) > 1e12:
            raise ExcitationError(f"B-spline collocation matrix is singular for times "
                                  f"{t.tolist()} and degree {degree}")
        self._collocation_inverse = np.linalg.inv(rows)             # (n+5, n+5)
        # rhs = S x + r: position rows from coefficients, derivative rows from the boundary.
        bc = self.boundary
        pos_rows = [0, *range(3, n + 2), n_ctrl - 1]                # q_0, q_1..q_{n-1}, q_n
        n_coef = n if bc.free_position else n - 1
        select = np.zeros((n_ctrl, n_coef))
        rhs = np.zeros((n_ctrl, self.nv))
        if bc.free_position:
            select[pos_rows[:-1], np.arange(n)] = 1.0
            select[pos_rows[-1], 0] = 1.0                           # q_n = q_0
        else:
            select[pos_rows[1:-1], np.arange(n - 1)] = 1.0
            rhs[0], rhs[n_ctrl - 1] = bc.q_start, bc.q_end
        rhs[1], rhs[2] = bc.dq_start, bc.ddq_start
        rhs[n_ctrl - 3], rhs[n_ctrl - 2] = bc.ddq_end, bc.dq_end
        self._select, self._rhs = select, rhs

    @staticmethod
    def _knot_vector(t: np.ndarray, p: int) -> np.ndarray:
        if p == 4:
            interior = 0.5 * (t[:-1] + t[1:])                       # Rackl eq. 22
        else:
            sites = np.concatenate([[t[0]] * 3, t[1:-1], [t[-1]] * 3])
            interior = np.array([sites[j + 1:j + p + 1].mean()
                                 for j in range(sites.size - p - 1)])
        return np.concatenate([[t[0]] * (p + 1), interior, [t[-1]] * (p + 1)])

    def _basis_functions(self, t: np.ndarray, nu: int) -> np.ndarray:
        n_ctrl = self.knots.size - self.degree - 1
        spline = scipy.interpolate.BSpline(self.knots, np.eye(n_ctrl), self.degree)
        return spline(np.clip(t, self.knots[0], self.knots[-1]), nu=nu)

    @property
    def coefficient_names(self) -> list[str]:
        n = self.times.size - 1
        ks = range(n) if self.boundary.free_position else range(1, n)
        return [f"q@{self.times[k]:g}s" for k in ks]

    def basis(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        b = np.stack([self._basis_functions(t, d) for d in range(3)]) @ self._collocation_inverse
        return b @ self._select, b @ self._rhs

    def control_points(self, coefficients: np.ndarray) -> np.ndarray:
        """Control points (n + 5, nv) of the spline for the given via-point coefficients."""
        x = self.check_coefficients(coefficients)
        return self._collocation_inverse @ (self._select @ x.T + self._rhs)

    def spline(self, coefficients: np.ndarray) -> scipy.interpolate.BSpline:
        """The joint trajectory as a vector-valued :class:`scipy.interpolate.BSpline`."""
        return scipy.interpolate.BSpline(self.knots, self.control_points(coefficients),
                                         self.degree)

    def rest(self, q_centre: np.ndarray) -> np.ndarray:
        return np.repeat(np.asarray(q_centre, dtype=float)[:, None], self.n_coefficients, axis=1)

    def random_direction(self, rng: np.random.Generator) -> np.ndarray:
        return rng.standard_normal((self.nv, self.n_coefficients))

    def __repr__(self) -> str:
        return (f"BSplineParameterisation(nv={self.nv}, intervals={self.times.size - 1}, "
                f"degree={self.degree}, duration={self.duration:g})")


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A joint trajectory: a :class:`Parameterisation` and its coefficients (nv, n).

    A periodic trajectory (end state = start state) repeats beyond ``duration``; a non-periodic
    one is defined on ``[0, duration]`` only.
    """

    parameterisation: Parameterisation
    coefficients: np.ndarray = field(repr=False)

    @property
    def duration(self) -> float:
        return self.parameterisation.duration

    @property
    def period(self) -> float:
        return self.parameterisation.duration

    @property
    def nv(self) -> int:
        return self.parameterisation.nv

    @property
    def periodic(self) -> bool:
        """End state = start state: the trajectory repeats beyond ``duration`` (and before 0)."""
        return self.parameterisation.periodic

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(q, dq, ddq)`` at times ``t`` (s), each (len(t), nv)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        T = self.duration
        if self.parameterisation.periodic:
            t = np.mod(t, T)
        elif t.size and (t.min() < -1e-9 * T or t.max() > T * (1 + 1e-9)):
            raise ExcitationError(f"times [{t.min():g}, {t.max():g}] s lie outside this "
                                  f"non-periodic trajectory's [0, {T:g}] s (its end state "
                                  "differs from its start state, so it cannot repeat)")
        return self.parameterisation.evaluate(self.coefficients, np.clip(t, 0.0, T))

    def sample(self, rate: float, duration: float | None = None, t0: float = 0.0,
               joint_names: Sequence[str] | None = None) -> Dataset:
        """The trajectory sampled at ``rate`` Hz over ``duration`` s (default one period), as a
        :class:`Dataset` without torques."""
        if not rate > 0:
            raise ExcitationError(f"sampling rate = {rate} Hz; must be positive")
        duration = self.duration if duration is None else float(duration)
        n = sample_count(rate, duration, self.nv)
        if not self.parameterisation.periodic and abs(duration - self.duration) < 0.5 / rate:
            n += 1                                                  # include the end state
        t = t0 + np.arange(n) / rate
        q, dq, ddq = self.evaluate(t - t0)
        return Dataset(t=t, q=q, dq=dq, ddq=ddq,
                       joint_names=None if joint_names is None else tuple(joint_names))

    def save_csv(self, path: str | Path, rate: float, duration: float | None = None,
                 joint_names: Sequence[str] | None = None) -> Path:
        """Write ``t, q_<joint>.., dq_<joint>.., ddq_<joint>..`` (``joint_names``; without
        them ``q1..qn``, ``dq1..``, ``ddq1..``) at ``rate`` Hz to a CSV file for a robot
        controller (readable by :meth:`Dataset.load`). Returns the path."""
        data = self.sample(rate, duration)
        path = Path(path)
        if joint_names is not None and len(joint_names) != data.nv:
            raise ExcitationError(f"{len(joint_names)} joint names for {data.nv} joints")
        label = ((lambda f, j: f"{f}_{joint_names[j]}") if joint_names is not None
                 else (lambda f, j: f"{f}{j + 1}"))
        cols = {"t": data.t}
        for name in ("q", "dq", "ddq"):
            cols.update({label(name, j): getattr(data, name)[:, j] for j in range(data.nv)})
        np.savetxt(path, np.column_stack(list(cols.values())), delimiter=",",
                   header=",".join(cols), comments="", fmt="%.10g")
        return path


@dataclass(frozen=True, eq=False)
class FourierTrajectory:
    """A periodic joint trajectory ``q(t)`` as a finite Fourier series (no polynomial term).

    Swevers et al. 1997 (doi:10.1109/70.631234):
    ``q_j(t) = q0_j + Σ_l a_jl/(ω_f l) sin(ω_f l t) − b_jl/(ω_f l) cos(ω_f l t)``.

    Attributes
    ----------
    a, b : (nv, H) sine and cosine coefficients (rad/s), ``H ≥ 1``, finite.
    q0 : (nv,) offsets (rad).
    period : seconds, ``2π/ω_f``, > 0.

    Raises :class:`ExcitationError` for other shapes, non-finite values or a period ≤ 0
    (:class:`JointCountError` when ``q0`` has another joint count than ``a``).
    """

    a: np.ndarray
    b: np.ndarray
    q0: np.ndarray
    period: float

    def __post_init__(self) -> None:
        a, b = np.asarray(self.a, dtype=float), np.asarray(self.b, dtype=float)
        if a.ndim != 2 or a.shape[1] < 1 or b.shape != a.shape:
            raise ExcitationError(f"Fourier coefficients a {a.shape} and b {b.shape} must both "
                                  "be (nv, H) with H ≥ 1 harmonics")
        q0 = np.asarray(self.q0, dtype=float)
        if q0.shape != (a.shape[0],):
            raise JointCountError(f"q0 has shape {q0.shape}; a and b have {a.shape[0]} joints")
        for name, value in (("a", a), ("b", b), ("q0", q0)):
            if not np.all(np.isfinite(value)):
                raise ExcitationError(f"Fourier {name} has non-finite entries")
        if not (np.isfinite(self.period) and self.period > 0):
            raise ExcitationError(f"period = {self.period} s; must be positive")
        for name, value in (("a", a), ("b", b), ("q0", q0), ("period", float(self.period))):
            object.__setattr__(self, name, value)

    @property
    def omega(self) -> float:
        return 2.0 * np.pi / self.period

    @property
    def harmonics(self) -> int:
        return int(self.a.shape[1])

    @property
    def periodic(self) -> bool:
        """Always: a Fourier series repeats with its period."""
        return True

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(q, dq, ddq)`` at times ``t`` (s), each (len(t), nv)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        f = _fourier_basis(t, self.omega, self.harmonics)[..., :-1]
        coef = np.hstack([self.a, self.b])
        return f[0] @ coef.T + self.q0, f[1] @ coef.T, f[2] @ coef.T

    def sample(self, rate: float, duration: float | None = None, t0: float = 0.0) -> Dataset:
        """The trajectory sampled at ``rate`` Hz over ``duration`` s (default one period)."""
        if not (np.isfinite(rate) and rate > 0):
            raise ExcitationError(f"sampling rate = {rate} Hz; must be positive")
        duration = self.period if duration is None else float(duration)
        if not (np.isfinite(duration) and duration > 0):
            raise ExcitationError(f"duration = {duration} s; must be positive")
        t = t0 + np.arange(sample_count(rate, duration, len(self.q0))) / rate
        q, dq, ddq = self.evaluate(t)
        return Dataset(t=t, q=q, dq=dq, ddq=ddq)

    @classmethod
    def random(cls, model: RobotModel, harmonics: int = 5, period: float = 10.0,
               seed: int | np.random.Generator = 0, amplitude: float = 0.8,
               acceleration_limit: float | np.ndarray = DEFAULT_ACCELERATION_LIMIT
               ) -> "FourierTrajectory":
        """Random coefficients, scaled per joint to use ``amplitude`` of the position range,
        velocity limit and acceleration limit (whichever binds first), centred in the range.

        Unbounded joints are treated as having the range ±π, joints bounded on one side only as
        having one turn (2π) from that bound.
        """
        harmonics = check_number("harmonics", harmonics, 1, integer=True)
        period = check_number("period", period, 0, strict=True)
        amplitude = check_number("amplitude", amplitude, 0, strict=True)
        rng = np.random.default_rng(seed)
        lim = model.limits
        lo, hi = position_range(lim.lower, lim.upper)
        a = rng.standard_normal((model.nv, harmonics))
        b = rng.standard_normal((model.nv, harmonics))
        q0 = 0.5 * (lo + hi)
        trial = cls(a, b, np.zeros(model.nv), period)
        q, dq, ddq = trial.evaluate(np.linspace(0.0, period, 50 * harmonics * 4, endpoint=False))
        acc = np.broadcast_to(np.asarray(acceleration_limit, dtype=float), (model.nv,))
        scale = amplitude * np.minimum.reduce([
            0.5 * (hi - lo) / np.max(np.abs(q), axis=0),
            lim.velocity / np.max(np.abs(dq), axis=0),
            acc / np.max(np.abs(ddq), axis=0)])
        return cls(a * scale[:, None], b * scale[:, None], q0, period)

r"""The Slotine–Li regressor and adaptive controller, with a cheap exact parameter projection.

Control law and adaptation (Slotine & Li, "On the adaptive control of robot manipulators", IJRR
6(3), 1987, doi:10.1177/027836498700600303; *Applied Nonlinear Control*, Prentice Hall 1991,
§9.2; the lecture notes in consistid's seeds):

.. math::

    \tilde q = q - q_d, \quad \dot q_r = \dot q_d - \Lambda \tilde q, \quad
    \ddot q_r = \ddot q_d - \Lambda \dot{\tilde q}, \quad s = \dot q - \dot q_r, \\
    \tau = \hat M(q)\,\ddot q_r + \hat C(q, \dot q)\,\dot q_r + \hat g(q) - K s
         = Y(q, \dot q, \dot q_r, \ddot q_r)\,\hat\pi - K s, \qquad
    \dot{\hat\pi} = -\Gamma\, Y^\top s .

With ``Ṁ − 2C`` skew-symmetric, ``V = ½ sᵀMs + ½ π̃ᵀΓ⁻¹π̃`` has ``V̇ = −sᵀKs ≤ 0``: ``s → 0``,
hence ``q̃ → 0``, whatever the initial parameter error.

The regressor, with Pinocchio. ``C`` must be the Christoffel one (the one with ``Ṁ − 2C``
skew). Its product ``C(q, u) w = Σ_jk Γ_ijk u_j w_k`` is a symmetric bilinear form of ``(u, w)``
(``Γ_ijk = Γ_ikj``), and ``C(q, v) v = rnea(q, v, 0) − g(q)``; by polarisation,

.. math::

    Y(q, \dot q, \dot q_r, \ddot q_r) = Y_{rnea}(q, 0, \ddot q_r)
      + \tfrac14\,[\,Y_{rnea}(q, \dot q + \dot q_r, 0) - Y_{rnea}(q, \dot q - \dot q_r, 0)\,],

three calls of ``pinocchio.computeJointTorqueRegressor`` (the gravity columns cancel in the
difference). Per-joint columns (:mod:`consistid.identification.regressor`) use the measured
``q, q̇`` (Coulomb ``sign q̇``, viscous ``q̇``, offset, position) and ``q̈_r`` for the armature:
each is exactly linear in its parameter, so the same law adapts it.

Projection. The adaptation can leave the physically consistent set (a body with a negative
mass or an impossible inertia: ``M̂`` indefinite). After each step, every body's
normalised pseudo-inertia ``Ĵ = L⁻¹ J(π̂) L⁻ᵀ`` (``J_ref = LLᵀ``, the reference body: by default
the URDF's) has its eigenvalues
clipped at ``ε`` and Coulomb, viscous and armature entries are clipped at 0. Clipping is the
Frobenius projection onto ``{Ĵ ⪰ ε 1}``. With the *natural* gain ``Γ = γ G⁻¹``, ``G`` block
diagonal with ``‖δπ_i‖²_G = ‖δĴ_i‖²_F`` (the log-det divergence's Hessian at the prior,
:func:`consistid.identification.priors.logdet_metric`; Lee, Wensing, Park 2019,
doi:10.1109/TRO.2019.2926491), the Frobenius metric *is* ``Γ⁻¹``'s, so the clip is the exact
projection in the metric of ``V``, which never increases the distance to the (consistent)
truth: the Lyapunov argument survives (Ioannou & Sun, *Robust Adaptive Control*, 1996, §4.10;
the discrete step is the projection of a non-expansive map). With a matrix ``gamma`` the clip
still returns a consistent estimate, but in another metric, which the argument does not cover.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import pinocchio as pin

from ..errors import DatasetError, JointCountError, OptionError, check_number
from ..identification.constraints import BodyScaling
from ..identification.priors import logdet_metric
from ..identification.regressor import (FrictionArg, RegressorSpec, joint_columns,
                                        parameter_names, prior_vector)
from ..robot.inertia import from_pseudo_inertia, pseudo_inertia, pseudo_inertia_map
from ..robot.model import RobotModel, require_model

#: Relative tolerance below ``margin`` before a body is clipped (round-off of a clipped body).
CLIP_RTOL = 1e-6
#: Natural gain of a per-joint column (friction, offset, armature), relative to ``γ``:
#: ``Γ_jj = γ·JOINT_GAIN²``.
JOINT_GAIN = 1.0


def slotine_li_regressor(model: RobotModel, q: np.ndarray, dq: np.ndarray, dq_r: np.ndarray,
                         ddq_r: np.ndarray, spec: RegressorSpec | None = None,
                         data: pin.Data | None = None) -> np.ndarray:
    """``Y(q, q̇, q̇_r, q̈_r)`` with ``Y π = M q̈_r + C(q, q̇) q̇_r + g`` (+ per-joint terms),
    shape ``(nv, p)`` for one sample (module docstring).

    ``C`` is the Christoffel matrix: ``Y(q, q̇, q̇, q̈)`` is the ordinary regressor, and
    ``Ṁ − 2C`` is skew-symmetric. ``data`` may be a reused ``pinocchio.Data`` of ``model``.
    """
    m = model.pin_model
    data = data if data is not None else m.createData()
    q, dq, dq_r, ddq_r = (np.asarray(a, dtype=float) for a in (q, dq, dq_r, ddq_r))
    for name, a in (("q", q), ("dq", dq), ("dq_r", dq_r), ("ddq_r", ddq_r)):
        if a.shape != (model.nv,):
            raise JointCountError(f"{name} has shape {a.shape}; {model.name} needs ({model.nv},)")
    qc = q if m.nq == m.nv else model.configuration(q)
    zero = np.zeros(model.nv)
    y = pin.computeJointTorqueRegressor(m, data, qc, zero, ddq_r).copy()
    y += 0.25 * pin.computeJointTorqueRegressor(m, data, qc, dq + dq_r, zero)
    y -= 0.25 * pin.computeJointTorqueRegressor(m, data, qc, dq - dq_r, zero)
    if spec is None or spec.n_joint_columns == 0:
        return y
    return np.hstack([y, joint_columns(q[None], dq[None], ddq_r[None], spec)[0]])


def natural_metric(model: RobotModel, spec: RegressorSpec,
                   prior: np.ndarray | None = None) -> np.ndarray:
    """``G`` (p × p): ``δπᵀ G δπ = Σ_i ‖L_i⁻¹ δJ_i L_i⁻ᵀ‖²_F + Σ_j δπ_j²/JOINT_GAIN²`` (module
    docstring), ``L_i L_iᵀ = J_i(prior)``; ``prior`` (the reference bodies, then the per-joint
    entries) defaults to the URDF's."""
    prior = prior_vector(model, spec) if prior is None else np.asarray(prior, dtype=float)
    g = np.zeros((prior.size, prior.size))
    for i in range(model.n_bodies):
        sl = slice(10 * i, 10 * i + 10)
        w = logdet_metric(prior[sl])
        g[sl, sl] = 2.0 * w.T @ w                      # ‖W δ‖² = ½ ‖δĴ‖²_F
    n_in = model.n_inertial
    g[n_in:, n_in:] = np.eye(prior.size - n_in) / JOINT_GAIN ** 2
    return g


@dataclass(frozen=True, eq=False)
class ProjectionStep:
    """What one projection did: ``clipped`` bodies and per-joint entries, and the smallest
    prior-normalised eigenvalue of each body after it (``≥ margin``)."""

    clipped_bodies: tuple[int, ...]
    clipped_joint_columns: int
    min_normalised_eigenvalues: np.ndarray


class SlotineLiController:
    r"""The Slotine–Li adaptive controller (module docstring).

    Parameters
    ----------
    model : the robot (kinematics, gravity, and the prior ``π₀`` that normalises the bodies).
    lam : ``Λ`` (1/s), a number or ``(nv,)``, > 0.
    k : ``K`` (N·m·s/rad), a number, ``(nv,)`` or a symmetric positive definite ``(nv, nv)``.
    gamma : a number ``γ > 0`` (the natural gain ``Γ = γ G⁻¹``, :func:`natural_metric`), or a
        ``(p, p)`` symmetric positive definite matrix ``Γ``, or ``(p,)`` positive diagonal.
    initial : (p,) the initial estimate ``π̂(0)`` (10 per body, then the per-joint terms);
        default the URDF's inertias and zero friction. Must be consistent.
    friction, armature : per-joint columns (:meth:`RegressorSpec.make`); default none.
    projection : ``"clip"`` (default) or ``None`` (no projection: the estimate may leave the
        consistent set; for comparison).
    margin : ``ε`` of the clip (prior-normalised).
    project_every : project after every this many adaptation steps.
    reference : (10·nbodies,) the bodies that normalise ``Ĵ`` (the natural gain and the clip);
        default the URDF's. Each must be realisable (``J ≻ 0``). A body expected to change a
        lot (a link that grasps payloads heavier than itself) adapts faster with a larger
        reference body (:func:`consistid.online.adaptive_run.adaptive_run` adds its
        ``payload_capacity``).
    composite : ``μ ∈ [0, 2)``, the normalised step of the prediction-error term
        (:meth:`observe`; 0: the pure Slotine–Li law).

    Raises
    ------
    OptionError : a gain not positive (``Γ`` not symmetric positive definite: its smallest
        eigenvalue is named), a wrong shape, an inconsistent ``initial``.
    """

    def __init__(self, model: RobotModel, lam: float | Sequence[float] = 5.0,
                 k: float | Sequence[float] = 10.0, gamma: float | np.ndarray = 1.0, *,
                 initial: np.ndarray | None = None, friction: FrictionArg = None,
                 armature: bool | Sequence[int | str] = False, projection: str | None = "clip",
                 margin: float = 1e-6, project_every: int = 1,
                 composite: float = 0.0, reference: np.ndarray | None = None) -> None:
        self.model = require_model(model)
        nv = model.nv
        self.spec = RegressorSpec.make(model, friction, armature)
        self.parameter_names = tuple(parameter_names(model, self.spec))
        p = len(self.parameter_names)
        self.lam = self._gain("lam", lam, nv)
        self.k = self._k_matrix(k, nv)
        self.composite = check_number("composite", composite, 0)
        if self.composite >= 2:
            raise OptionError(f"composite = {composite!r}: the normalised prediction-error step "
                              "must lie in [0, 2) to be stable")
        if projection not in ("clip", None):
            raise OptionError(f"projection={projection!r} is not supported; allowed: 'clip', "
                              "None")
        self.projection = projection
        self.margin = check_number("margin", margin, 0)
        self.project_every = check_number("project_every", project_every, 1, integer=True)
        prior = prior_vector(model, self.spec)
        if reference is not None:
            ref = np.asarray(reference, dtype=float)
            if ref.shape != (model.n_inertial,) or not np.all(np.isfinite(ref)):
                raise OptionError(f"reference must be {model.n_inertial} finite numbers (10 per "
                                  f"body), got shape {ref.shape}")
            prior = np.concatenate([ref, prior[model.n_inertial:]])
        self.reference = prior[:model.n_inertial].copy()
        self._scalings = tuple(BodyScaling.from_reference(prior[10 * i:10 * i + 10])
                               for i in range(model.n_bodies))
        self._l = tuple(np.linalg.inv(sc.l_inv) for sc in self._scalings)
        # vec(Ĵ_i) = (L_i⁻¹ ⊗ L_i⁻¹) P π_i, one (16, 10) map per body (row-major = column-major
        # for the symmetric Ĵ)
        pmap = pseudo_inertia_map()
        self._normalised_map = np.stack([np.kron(sc.l_inv, sc.l_inv) @ pmap
                                         for sc in self._scalings])
        self.gamma = self._gamma(gamma, p, prior)
        self.natural = np.ndim(gamma) == 0
        pi = prior.copy() if initial is None else np.array(initial, dtype=float)
        if pi.shape != (p,) or not np.all(np.isfinite(pi)):
            raise OptionError(f"initial must be {p} finite numbers ({self.spec.describe()}), got "
                              f"shape {pi.shape}")
        bad = [b for i, b in enumerate(model.body_names)
               if np.linalg.eigvalsh(pseudo_inertia(pi[10 * i:10 * i + 10]))[0] < 0]
        if bad:
            raise OptionError(f"initial parameters are not physically consistent (bodies {bad});"
                              " the adaptation starts from a consistent estimate")
        self.parameters = pi
        self._data = model.pin_model.createData()
        self._y: np.ndarray | None = None
        self._s: np.ndarray | None = None
        self.steps = 0
        #: smallest prior-normalised pseudo-inertia eigenvalue over the bodies after each
        #: projection (one entry per projection), and ``(step, ProjectionStep)`` of those that
        #: clipped something
        self.projected_minimum: list[float] = []
        self.clips: list[tuple[int, ProjectionStep]] = []

    @classmethod
    def _k_matrix(cls, k: float | Sequence[float] | np.ndarray, nv: int) -> np.ndarray:
        a = np.asarray(k, dtype=float)
        if a.ndim < 2:
            return np.diag(cls._gain("k", k, nv))
        if a.shape != (nv, nv) or not np.all(np.isfinite(a)) or not np.allclose(a, a.T):
            raise OptionError(f"k as a matrix must be symmetric ({nv}, {nv}), got {a.shape}")
        low = float(np.linalg.eigvalsh(a)[0])
        if not low > 0:
            raise OptionError(f"k is not positive definite (smallest eigenvalue {low:.3g})")
        return a

    @staticmethod
    def _gain(name: str, value: float | Sequence[float], nv: int) -> np.ndarray:
        a = np.asarray(value, dtype=float)
        a = np.full(nv, float(a)) if a.ndim == 0 else a
        if a.shape != (nv,) or not np.all(np.isfinite(a)) or np.any(a <= 0):
            raise OptionError(f"{name} must be a positive number or {nv} positive numbers, got "
                              f"{value!r}")
        return a

    def _gamma(self, gamma: float | np.ndarray, p: int, prior: np.ndarray) -> np.ndarray:
        g = np.asarray(gamma, dtype=float)
        if g.ndim == 0:
            value = check_number("gamma", float(g), 0, strict=True)
            return value * np.linalg.inv(natural_metric(self.model, self.spec, prior))
        if g.ndim == 1:
            if g.shape != (p,) or not np.all(np.isfinite(g)) or np.any(g <= 0):
                raise OptionError(f"gamma as a diagonal must be {p} positive numbers; got shape "
                                  f"{g.shape}, smallest {np.min(g) if g.size else 'n/a'}")
            return np.diag(g)
        if g.shape != (p, p) or not np.all(np.isfinite(g)):
            raise OptionError(f"gamma must be a number, ({p},) or ({p}, {p}); got shape {g.shape}")
        if not np.allclose(g, g.T, rtol=1e-10, atol=1e-12 * np.max(np.abs(g))):
            raise OptionError("gamma is not symmetric: Γ must be symmetric positive definite")
        lam_min = float(np.linalg.eigvalsh(0.5 * (g + g.T))[0])
        if not lam_min > 0:
            raise OptionError(f"gamma is not positive definite (smallest eigenvalue "
                              f"{lam_min:.3g}): Γ must be symmetric positive definite")
        return 0.5 * (g + g.T)

    # ----------------------------------------------------------------------------- the loop
    def _vectors(self, what: str, names: tuple[str, ...], values: tuple) -> tuple[np.ndarray, ...]:
        """The arguments as ``(nv,)`` float vectors; a wrong shape or a NaN/inf raises naming the
        argument and the joint (a NaN would otherwise reach the motors as a NaN torque, or the
        estimate as NaN parameters). One finite-sum test on the fast path."""
        nv = self.model.nv
        out = tuple(np.asarray(v, dtype=float) for v in values)
        if all(a.shape == (nv,) for a in out) and math.isfinite(float(sum(a.sum() for a in out))):
            return out
        for name, a in zip(names, out):
            if a.shape != (nv,):
                raise JointCountError(f"{what}: {name} has shape {a.shape}; {self.model.name} "
                                      f"needs a vector of {nv}")
            bad = np.flatnonzero(~np.isfinite(a))
            if bad.size:
                raise DatasetError(f"{what}: {name}[{self.model.joint_names[bad[0]]!r}] is "
                                   f"{a[bad[0]]}; nothing was computed and the parameters are "
                                   "unchanged (hold the last torque, or stop)")
        raise DatasetError(f"{what}: the sample overflows (sum of its entries is not finite)")

    def torque(self, q: np.ndarray, dq: np.ndarray, q_d: np.ndarray, dq_d: np.ndarray,
               ddq_d: np.ndarray) -> np.ndarray:
        """``τ = Y π̂ − K s`` at the measured ``(q, q̇)`` and the desired ``(q_d, q̇_d, q̈_d)``;
        keeps ``Y`` and ``s`` for the next :meth:`adapt`."""
        q, dq, q_d, dq_d, ddq_d = self._vectors("torque", ("q", "dq", "q_d", "dq_d", "ddq_d"),
                                                (q, dq, q_d, dq_d, ddq_d))
        e, de = q - q_d, dq - dq_d
        dq_r = dq_d - self.lam * e
        ddq_r = ddq_d - self.lam * de
        s = dq - dq_r
        y = slotine_li_regressor(self.model, q, dq, dq_r, ddq_r, self.spec, self._data)
        self._y, self._s = y, s
        return y @ self.parameters - self.k @ s

    def adapt(self, dt: float) -> None:
        """One explicit Euler step ``π̂ ← π̂ − dt Γ Yᵀ s`` of the adaptation law (``Y``, ``s`` of
        the last :meth:`torque`), then the projection every ``project_every`` steps."""
        if self._y is None:
            raise OptionError("adapt() needs a torque() call first (it uses that Y and s)")
        dt = check_number("dt", dt, 0.0, strict=True)
        self.parameters = self.parameters - dt * (self.gamma @ (self._y.T @ self._s))
        self.steps += 1
        if self.projection == "clip" and self.steps % self.project_every == 0:
            self.parameters, step = self.project(self.parameters)
            self.projected_minimum.append(float(step.min_normalised_eigenvalues.min()))
            if step.clipped_bodies or step.clipped_joint_columns:
                self.clips.append((self.steps, step))

    def observe(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray, tau: np.ndarray) -> float:
        r"""Composite adaptation (``composite = μ > 0``): one normalised gradient step on the
        torque prediction error of a measured sample ``(q, q̇, q̈, τ)``,

        .. math:: \hat\pi \leftarrow \hat\pi - \mu\,
                  \frac{\Gamma W^\top (W\hat\pi - \tau)}{1 + \|W \Gamma W^\top\|_2},

        ``W`` the ordinary regressor (with the per-joint columns). Slotine & Li, "Composite
        adaptive control of robot manipulators", Automatica 25(4), 1989,
        doi:10.1016/0005-1098(89)90094-0, combine the tracking error with the prediction error;
        the normalised (NLMS) step, ``0 < μ < 2``, never increases ``‖π̃‖_Γ⁻¹`` on exact data
        (Goodwin & Sin, *Adaptive Filtering, Prediction and Control*, 1984, §3.3), so it keeps
        the Lyapunov function's parameter part non-increasing. Returns the prediction error's
        norm (N·m) before the step; does nothing (returns it) with ``composite = 0``.
        """
        q, dq, ddq, tau = self._vectors("observe", ("q", "dq", "ddq", "tau"), (q, dq, ddq, tau))
        m = self.model.pin_model
        qc = q if m.nq == m.nv else self.model.configuration(q)
        w = pin.computeJointTorqueRegressor(m, self._data, qc, dq, ddq)
        if self.spec.n_joint_columns:
            w = np.hstack([w, joint_columns(q[None], dq[None], ddq[None], self.spec)[0]])
        error = w @ self.parameters - tau
        if self.composite > 0:
            gw = self.gamma @ w.T
            scale = 1.0 + float(np.linalg.norm(w @ gw, 2))
            self.parameters = self.parameters - (self.composite / scale) * (gw @ error)
        return float(np.linalg.norm(error))

    def step(self, q: np.ndarray, dq: np.ndarray, q_d: np.ndarray, dq_d: np.ndarray,
             ddq_d: np.ndarray, dt: float) -> np.ndarray:
        """:meth:`torque` then :meth:`adapt`: the torque to apply over the next ``dt``."""
        tau = self.torque(q, dq, q_d, dq_d, ddq_d)
        self.adapt(dt)
        return tau

    def project(self, parameters: np.ndarray) -> tuple[np.ndarray, ProjectionStep]:
        """The clip of the module docstring: each body's ``Ĵ`` eigenvalues at ``≥ margin``,
        Coulomb, viscous and armature entries at ``≥ 0``. All bodies' ``Ĵ`` are checked in one
        batched eigenvalue call; only the bodies below ``margin`` are decomposed and clipped."""
        pi = np.array(parameters, dtype=float)
        nb = self.model.n_bodies
        j_hat = self._normalised_map @ pi[:10 * nb].reshape(nb, 10, 1)        # (nb, 16, 1)
        j_hat = j_hat.reshape(nb, 4, 4)
        lows = np.linalg.eigvalsh(j_hat)[:, 0]
        # a body clipped before sits at ``margin`` up to round-off: not clipped again
        clipped = np.flatnonzero(lows < self.margin * (1.0 - CLIP_RTOL))
        for i in clipped:
            lam, vec = np.linalg.eigh(j_hat[i])
            clipped_j = (vec * np.maximum(lam, self.margin)) @ vec.T
            l_mat = self._l[i]
            pi[10 * i:10 * i + 10] = from_pseudo_inertia(l_mat @ clipped_j @ l_mat.T)
            lows[i] = max(lam[0], self.margin)
        keep = self.model.n_inertial + self.spec.nonnegative_columns
        negative = int(np.sum(pi[keep] < 0))
        pi[keep] = np.maximum(pi[keep], 0.0)
        return pi, ProjectionStep(tuple(int(i) for i in clipped), negative, lows)

    def __repr__(self) -> str:
        return (f"SlotineLiController({self.model.name!r}, {len(self.parameter_names)} "
                f"parameters, Γ {'natural' if self.natural else 'given'}, projection="
                f"{self.projection}, {self.steps} steps)")

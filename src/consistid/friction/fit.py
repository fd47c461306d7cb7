r"""Rigid body and nonlinear joint friction identified together, by variable projection.

The torque model with a nonlinear friction law on some joints (:mod:`consistid.friction.models`)
is linear in the rigid-body base parameters ``β``, the linear per-joint terms (viscous, offset,
Coulomb on the other joints, armature …) and the friction amplitudes ``c``, and nonlinear only in
the few shape parameters ``η`` (``v_s, δ`` of a Stribeck joint, ``φ₂, φ₃`` of a sigmoid,
``v_s`` of a tanh):

.. math::  τ = X β + C(\dot q; η)\, c + ε, \qquad
           \hat η = \arg\min_η \|Σ^{-1/2} P^\perp_{[X\,C(η)]}\, τ\|^2

Variable projection (Golub & Pereyra 1973, "The differentiation of pseudo-inverses and nonlinear
least squares problems whose variables separate", SIAM J. Numer. Anal. 10(2),
doi:10.1137/0710036; Golub & Pereyra 2003, Inverse Problems 19(2), doi:10.1088/0266-5611/19/2/201):
for each ``η`` the linear parameters are eliminated by least squares — the fixed columns ``X``
through their R factor (the compression of :mod:`consistid.identification.compression`), the
``C`` columns, which act on their own joint only, by a Schur complement — and
:func:`scipy.optimize.least_squares` searches ``η`` with Kaufman's Jacobian
``J = −P^⊥ (∂C/∂η) c`` (Kaufman 1975, BIT 15, doi:10.1007/BF01932995). ``Σ = diag(σ_j²)`` per
joint (one common ``σ`` for ``method="ols"``), re-estimated once from the residual at the first
optimum.

At ``η̂`` the linear parameters are solved by the chosen method: OLS/WLS is the projection
itself; for ``method="sdp"`` the amplitudes are profiled out of each joint's compressed problem
(the R factor of ``[C_j | Y_j | τ_j]``, whose trailing block is that of
``P^⊥_{C_j}[Y_j | τ_j]``), the consistent SDP (:func:`consistid.identification.sdp.identify_sdp`)
solves the rest, and the amplitudes follow from the leading rows. The inertias are therefore
exactly as consistent as with linear friction.

Uncertainty: the Gauss–Newton covariance of all of ``(β, c, u)`` (``u`` the search coordinates of
``η``, log of the positive ones) from the full Jacobian ``[X, C, (∂C/∂u) c]`` with whitened rows,
``s² (JᵀJ)⁻¹``; with ``covariance="coloured"`` each joint's rows count as ``N/τ_j`` independent
ones (the sandwich of :func:`consistid.identification.statistics.coloured_covariance`). The
``η`` block of ``(JᵀJ)⁻¹`` equals ``(J_Kᵀ J_K)⁻¹`` of the projected problem. Shape parameters get
``σ_η = σ_u · dη/du``.

Selecting models: ``identify(model, data, friction=...)`` accepts (:func:`parse_friction`)

* a model name, ``"stribeck" | "sigmoid" | "tanh"``: that law on every joint, with the linear
  viscous and offset columns;
* a sequence of terms with one model name in place of ``"coulomb"``, e.g.
  ``("stribeck", "viscous", "offset")`` or ``("sigmoid", "offset")``;
* a mapping ``{joint name or index: law}``, law among the model names and ``"coulomb"`` (the
  linear ``f_c sign q̇``): the listed joints get their law, the others ``"coulomb"``, every joint
  the viscous and offset columns.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar, Mapping, Sequence

import numpy as np
import scipy.linalg
import scipy.optimize
import scipy.stats

from ..data.dataset import Dataset, as_dataset
from ..errors import (DataQualityWarning, ExportWarning, InaccurateSolutionWarning,
                      OptionError, PoorExcitationError, PoorExcitationWarning, check_number,
                      check_option)
from ..identification.base import RANK_RTOL, BaseParameters, compute_base_parameters
from ..identification.compression import SIGMA_FLOOR, CompressedProblem, accumulate
from ..identification.regressor import (FRICTION_TERMS, RegressorSpec, parameter_names,
                                        prior_vector, regressor)
from ..identification.result import IdentificationResult
from ..identification.solver import SolverReport
from ..identification.statistics import autocorrelation_time
from ..identification.summary import table
from ..robot.joint_terms import STANDSTILL_SPEED
from ..robot.model import RobotModel
from .models import LINEAR, MODELS, get_model

#: Linear per-joint terms that come with a nonlinear selection given as a name or a mapping.
DEFAULT_LINEAR: tuple[str, ...] = ("viscous", "offset")
#: Keyword options of :func:`identify_nonlinear` that ``identify`` passes for every method.
NONLINEAR_OPTIONS: tuple[str, ...] = ("start", "max_nfev", "min_speed")
#: Evaluations allowed to :func:`scipy.optimize.least_squares` per search (two searches run).
MAX_EVALUATIONS = 200


# ------------------------------------------------------------------------------ the spelling
def is_nonlinear(friction: object) -> bool:
    """Whether an ``identify(friction=...)`` value asks for a nonlinear law (module docstring);
    never raises (malformed values are left to the parsers to name)."""
    try:
        if isinstance(friction, str):
            return friction in MODELS
        if isinstance(friction, Mapping):     # {joint: law}, "coulomb" for all included
            return any(isinstance(v, str) and (v in MODELS or v == LINEAR)
                       for v in friction.values())
        if isinstance(friction, (Sequence, np.ndarray)):
            return any(isinstance(v, str) and v in MODELS for v in friction)
    except TypeError:
        return False
    return False


@dataclass(frozen=True)
class FrictionSelection:
    """A parsed selection: the law of every joint (``"coulomb"`` or a model name) and the
    ``friction`` argument of :meth:`RegressorSpec.make` for the linear columns."""

    laws: tuple[str, ...]
    linear: Mapping[str, tuple[int, ...]]

    @property
    def nonlinear_joints(self) -> tuple[int, ...]:
        return tuple(j for j, law in enumerate(self.laws) if law != LINEAR)


def parse_friction(model: RobotModel, friction: object) -> FrictionSelection:
    """The :class:`FrictionSelection` of an ``identify(friction=...)`` value that names a
    nonlinear law (module docstring). Raises :class:`OptionError` naming what is wrong."""
    nv, names = model.nv, model.joint_names
    every = tuple(range(nv))
    if isinstance(friction, str):
        laws = (get_model(friction).name,) * nv
        return FrictionSelection(laws, {t: every for t in DEFAULT_LINEAR})
    if isinstance(friction, Mapping):
        laws = [LINEAR] * nv
        for key, law in friction.items():
            if isinstance(key, str) and key in FRICTION_TERMS:
                raise OptionError(f"friction mixes a term ({key!r}) with per-joint laws: give "
                                  "either {term: joints} or {joint: law}, e.g. "
                                  f"{{{names[0]!r}: 'stribeck'}}")
            if isinstance(key, str):
                check_option("friction joint", key, names)
                j = names.index(key)
            elif isinstance(key, (int, np.integer)) and not isinstance(key, bool) \
                    and 0 <= int(key) < nv:
                j = int(key)
            else:
                raise OptionError(f"friction key {key!r} is neither a joint of {model.name} "
                                  f"({names}) nor an index 0..{nv - 1}")
            if law != LINEAR:
                law = get_model(law).name
            laws[j] = law
        return FrictionSelection(tuple(laws), {t: every for t in DEFAULT_LINEAR})
    terms = list(friction)  # type: ignore[arg-type]
    chosen = [t for t in terms if isinstance(t, str) and t in MODELS]
    if len(chosen) != 1:
        raise OptionError(f"friction={tuple(terms)!r} names {len(chosen)} nonlinear laws; a "
                          "sequence of terms takes one (it replaces 'coulomb' on every joint): "
                          "use {joint: law} for different laws per joint")
    if LINEAR in terms:
        raise OptionError(f"friction={tuple(terms)!r} has both 'coulomb' and {chosen[0]!r}: the "
                          "nonlinear law replaces the Coulomb column")
    rest = [t for t in terms if t != chosen[0]]
    for t in rest:
        check_option("friction term", t, FRICTION_TERMS)
    return FrictionSelection((chosen[0],) * nv, {t: every for t in rest})


def linear_spec(model: RobotModel, selection: FrictionSelection,
                armature: bool | Sequence[int | str]) -> RegressorSpec:
    """The spec of the linear columns: the selection's terms, and Coulomb on the joints whose
    law is ``"coulomb"``."""
    terms = {t: list(j) for t, j in selection.linear.items()}
    coulomb = [j for j, law in enumerate(selection.laws) if law == LINEAR]
    if coulomb:
        terms["coulomb"] = coulomb
    return RegressorSpec.make(model, terms, armature)


# ------------------------------------------------------------------------------ the result
@dataclass(frozen=True, eq=False)
class NonlinearFrictionResult(IdentificationResult):
    """An :class:`IdentificationResult` whose joints may carry nonlinear friction laws.

    ``parameters`` holds the standard vector of the linear columns (``spec``), then the friction
    amplitudes (``"<joint>.fc"``, ``".fs"``, ``".phi1"``); ``base_parameters`` the base
    parameters then the amplitudes, with their covariance (which includes the shape parameters'
    uncertainty). Extra attributes:

    Attributes
    ----------
    laws : (nv,) the law of each joint (``"coulomb"`` or a model name).
    shape_names : names of the shape parameters, ``"<joint>.vs"``, ``".delta"``, ``".phi2"`` …
    shape_parameters, shape_std : their estimates and standard deviations.
    search : what :func:`scipy.optimize.least_squares` reported (status, message, evaluations,
        cost) for each of its two searches.
    """

    laws: tuple[str, ...] = ()
    shape_names: tuple[str, ...] = ()
    shape_parameters: np.ndarray = field(default_factory=lambda: np.zeros(0))
    shape_std: np.ndarray = field(default_factory=lambda: np.zeros(0))
    amplitude_names: tuple[str, ...] = ()
    search: tuple[dict[str, Any], ...] = ()

    kind: ClassVar[str] = "nonlinear_friction"

    def persisted_fields(self) -> dict[str, Any]:
        """The laws, shapes, amplitude names and search reports, as ``save`` writes them."""
        return {"laws": list(self.laws), "shape_names": list(self.shape_names),
                "shape_parameters": self.shape_parameters, "shape_std": self.shape_std,
                "amplitude_names": list(self.amplitude_names), "search": list(self.search)}

    def shape_rows(self) -> list[tuple[str, float, float, str]]:
        """Each law's shape parameters with σ and unit (the CSV's ``shape`` rows)."""
        out = []
        for name, v, sd in zip(self.shape_names, self.shape_parameters, self.shape_std):
            law = MODELS[self.laws[self.model.joint_names.index(name.split(".", 1)[0])]]
            out.append((name, float(v), float(sd),
                        law.shape_units[law.shapes.index(name.split(".", 1)[1])]))
        return out

    def exported_terms(self) -> tuple[np.ndarray, tuple[str, ...]]:
        """The linear terms, and for each law joint its Coulomb level ``f_c`` — the law's
        ``max |C(±∞)|``: Stribeck's and tanh's ``f_c``, the sigmoid's larger asymptote — which
        is all URDF ``<dynamics friction>`` and MJCF ``frictionloss`` hold. Warns
        :class:`~consistid.errors.ExportWarning` naming what is left out (the laws' shapes, the
        static friction)."""
        p = self.model.n_inertial + self.spec.n_joint_columns
        names, values = list(self.parameter_names[:p]), list(self.parameters[:p])
        far = np.full((1, self.model.nv), 1e6)
        level = np.maximum(np.abs(self.friction_torque(far)),
                           np.abs(self.friction_torque(-far)))[0]
        lost = []
        for j, law in enumerate(self.laws):
            if law == LINEAR:
                continue
            joint = self.model.joint_names[j]
            names.append(f"{joint}.fc")
            values.append(float(level[j]))
            lost.append(f"{joint} ({law}: {', '.join(MODELS[law].shapes)}"
                        + (", fs" if law == "stribeck" else "") + ")")
        if lost:
            warnings.warn(ExportWarning(
                "URDF/MJCF friction holds a Coulomb level only: written as each law's f_c; left "
                "out: " + "; ".join(lost) + ". Keep the laws with res.save (JSON)"), stacklevel=3)
        return np.array(values), tuple(names)

    def __post_init__(self) -> None:
        # Read back from a file (save/load): the tuples and arrays of the constructor.
        for name in ("laws", "shape_names", "amplitude_names", "search"):
            object.__setattr__(self, name, tuple(getattr(self, name)))
        for name in ("shape_parameters", "shape_std"):
            object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=float))

    @property
    def amplitudes(self) -> np.ndarray:
        """The friction amplitudes (the tail of ``parameters``)."""
        return self.parameters[len(self.parameters) - len(self.amplitude_names):]

    def shapes_of(self, joint: int | str) -> dict[str, float]:
        """``{shape suffix: value}`` of one joint's law (empty for ``"coulomb"``)."""
        name = joint if isinstance(joint, str) else self.model.joint_names[joint]
        return {n.split(".", 1)[1]: float(v) for n, v in zip(self.shape_names,
                                                              self.shape_parameters)
                if n.split(".", 1)[0] == name}

    def friction_torque(self, dq: np.ndarray) -> np.ndarray:
        """The nonlinear laws' torque ``C(q̇; η̂) ĉ`` for velocities ``(N, nv)`` (zero on the
        ``"coulomb"`` joints, whose friction is in the linear columns)."""
        dq = np.atleast_2d(np.asarray(dq, dtype=float))
        out = np.zeros_like(dq)
        amps, offset = self.amplitudes, 0
        for j, law in enumerate(self.laws):
            if law == LINEAR:
                continue
            m = MODELS[law]
            k = len(m.amplitudes)
            eta = np.array(list(self.shapes_of(j).values()))
            out[:, j] = m.value(dq[:, j], amps[offset:offset + k], eta)
            offset += k
        return out

    @property
    def static_friction(self) -> np.ndarray:
        """(nv,) N·m: the torque dry friction holds a joint at rest with, up to — each law's
        limit ``max |C(±0; η̂) ĉ|`` (``f_s`` for Stribeck; 0 for the continuous sigmoid and tanh
        laws), the linear ``f_c`` on ``"coulomb"`` joints."""
        tiny = np.full((1, self.model.nv), 1e-12)
        limit = np.maximum(np.abs(self.friction_torque(tiny)),
                           np.abs(self.friction_torque(-tiny)))[0]
        return np.where(self._dry_laws(), limit, 0.0) + super().static_friction

    def dry_friction(self, dq: np.ndarray, sign: np.ndarray | None = None) -> np.ndarray:
        """The friction the prediction holds at velocities ``dq`` that a joint at rest replaces
        by its cone (N, nv): a dry law's torque (Stribeck), ``f_c sign(q̇)`` (or ``sign``) on
        ``"coulomb"`` joints; nothing for the continuous laws (sigmoid, tanh)."""
        return super().dry_friction(dq, sign) + np.where(self._dry_laws(),
                                                         self.friction_torque(dq), 0.0)

    def _dry_laws(self) -> np.ndarray:
        """(nv,) joints whose law steps at ``q̇ = 0``."""
        return np.array([law != LINEAR and MODELS[law].dry for law in self.laws])

    def predict(self, dataset: Dataset) -> np.ndarray:
        """``Y(q, q̇, q̈) θ + C(q̇; η̂) ĉ`` for a dataset's samples, (N, nv)."""
        p = self.model.n_inertial + self.spec.n_joint_columns
        dataset = as_dataset(dataset)
        dataset.check_joints(self.model.nv, self.model.joint_names)
        linear = np.empty((dataset.n_samples, self.model.nv))
        for start in range(0, dataset.n_samples, 4096):
            s = slice(start, min(start + 4096, dataset.n_samples))
            y = regressor(self.model, dataset.q[s], dataset.dq[s], dataset.ddq[s], self.spec,
                          dq_sign=None if dataset.dq_sign is None else dataset.dq_sign[s])
            linear[s] = (y @ self.parameters[:p]).reshape(-1, self.model.nv)
        return linear + self.friction_torque(dataset.dq)

    def shape_conf_int(self, alpha: float = 0.05) -> np.ndarray:
        """Two-sided ``1 − alpha`` intervals of the shape parameters, (m, 2) (normal, in the
        search coordinates ``u`` — log of the positive ones — mapped back, so never < 0 for
        those)."""
        z = scipy.stats.norm.ppf(1 - alpha / 2)
        out = np.empty((self.shape_parameters.size, 2))
        for i, (v, s) in enumerate(zip(self.shape_parameters, self.shape_std)):
            law = self.laws[self.model.joint_names.index(self.shape_names[i].split(".", 1)[0])]
            m = MODELS[law]
            positive = m.positive[m.shapes.index(self.shape_names[i].split(".", 1)[1])]
            if positive and v > 0:
                out[i] = v * np.exp(np.array([-z, z]) * s / v)
            else:
                out[i] = v - z * s, v + z * s
        return out

    def friction_table(self) -> str:
        """One row per shape parameter and amplitude: joint, law, estimate ± σ."""
        rows = []
        base_index = {self.base.standard_names[c]: r for r, c in enumerate(self.base.independent)}
        for name in self.amplitude_names:
            r = base_index[name]
            rows.append([name, self.laws[self.model.joint_names.index(name.split(".", 1)[0])],
                         self.base_parameters[r], self.base_std[r]])
        for name, v, s in zip(self.shape_names, self.shape_parameters, self.shape_std):
            rows.append([name, self.laws[self.model.joint_names.index(name.split(".", 1)[0])],
                         v, s])
        return table(["parameter", "law", "estimate", "± std"], rows)

    def summary(self, max_rows: int | None = None) -> str:
        text = super().summary(max_rows=max_rows)
        searches = "; ".join(f"{s['status']} after {s['nfev']} evaluations" for s in self.search)
        return (f"{text}\n\nNonlinear friction (variable projection; search: {searches})\n"
                f"{self.friction_table()}")

    def _repr_html_(self) -> str:
        from html import escape

        return f"<pre>{escape(self.summary(max_rows=20))}</pre>"


# ------------------------------------------------------------------------------ the projection
@dataclass(eq=False)
class Projection:
    """A variable-projection problem (module docstring), rows whitened per joint by ``1/σ_j``.

    ``x`` (N, nv, b) the fixed base columns, ``tau`` (N, nv), ``dq`` (N, nv), ``laws`` per
    joint, ``sigma`` (nv,), ``keep`` (N, nv) row weights 0/1 (rows left out have weight 0).
    :meth:`fun` is the projected residual ``P^⊥ τ`` (whitened, flattened) at search
    coordinates ``u`` and :meth:`jac` Kaufman's Jacobian, for
    :func:`scipy.optimize.least_squares`; :meth:`solve` gives the linear parameters."""

    x: np.ndarray
    tau: np.ndarray
    dq: np.ndarray
    laws: tuple[str, ...]
    sigma: np.ndarray
    keep: np.ndarray
    r: np.ndarray = field(init=False)
    z: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.x = self.x * self.keep[:, :, None]
        self.tau = self.tau * self.keep
        self.set_sigma(self.sigma)

    def set_sigma(self, sigma: np.ndarray) -> None:
        self.sigma = np.asarray(sigma, dtype=float)
        n, nv, b = self.x.shape
        a = np.concatenate([self.x / self.sigma[None, :, None],
                            (self.tau / self.sigma)[:, :, None]], axis=2).reshape(n * nv, b + 1)
        r_aug = np.linalg.qr(a, mode="r")                 # R of [X | τ]: no Q formed
        self.r, self.z = r_aug[:b, :b], r_aug[:b, b]
        d = np.abs(np.diag(self.r))
        if d.size and d.min() < RANK_RTOL * max(d.max(), 1e-300):
            raise PoorExcitationError(
                f"the data do not excite the {b} base parameters of the linear columns "
                f"(R factor diagonal ratio {d.min() / max(d.max(), 1e-300):.3g}): nonlinear "
                "friction needs a richer excitation")

    @property
    def joints(self) -> list[int]:
        return [j for j, law in enumerate(self.laws) if law != LINEAR]

    def split(self, u: np.ndarray) -> list[np.ndarray]:
        """Per nonlinear joint, its search coordinates."""
        out, k = [], 0
        for j in self.joints:
            m = MODELS[self.laws[j]].shapes
            out.append(u[k:k + len(m)])
            k += len(m)
        return out

    def columns(self, u: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Whitened ``C_j`` (N, k) and ``∂C_j/∂u`` (N, k, m) per nonlinear joint."""
        cols, ders = [], []
        for j, uj in zip(self.joints, self.split(u)):
            m = MODELS[self.laws[j]]
            eta = m.from_internal(uj)
            w = self.keep[:, j] / self.sigma[j]
            cols.append(m.columns(self.dq[:, j], eta) * w[:, None])
            ders.append(m.column_derivatives(self.dq[:, j], eta)
                        * m.internal_jacobian(eta)[None, None, :] * w[:, None, None])
        return cols, ders

    def solve(self, cols: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                     np.ndarray]:
        """``(β, c, U, S)``: least squares in ``(β, c)`` through the R factor of ``X`` and the
        Schur complement ``S = CᵀC − UᵀU``, ``U = R⁻ᵀ XᵀC``."""
        u_mat, s_mat, rhs = self._schur(cols)
        c = _solve_sym(s_mat, rhs)
        beta = scipy.linalg.solve_triangular(self.r, self.z - u_mat @ c)
        return beta, c, u_mat, s_mat

    def _schur(self, cols: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        b = self.r.shape[0]
        k_all = sum(c.shape[1] for c in cols)
        f = np.zeros((b, k_all))
        g = np.zeros((k_all, k_all))
        ct = np.zeros(k_all)
        k = 0
        for j, c in zip(self.joints, cols):
            sl = slice(k, k + c.shape[1])
            f[:, sl] = self.x[:, j, :].T @ c / self.sigma[j]
            g[sl, sl] = c.T @ c
            ct[sl] = c.T @ (self.tau[:, j] / self.sigma[j])
            k += c.shape[1]
        u_mat = scipy.linalg.solve_triangular(self.r, f, trans="T")
        return u_mat, g - u_mat.T @ u_mat, ct - u_mat.T @ self.z

    def residual(self, beta: np.ndarray, c: np.ndarray, cols: list[np.ndarray]) -> np.ndarray:
        """Whitened residual ``(N, nv)``: ``τ/σ − X β/σ − C c``."""
        out = self.tau / self.sigma - np.einsum("njb,b->nj", self.x, beta) / self.sigma
        k = 0
        for j, col in zip(self.joints, cols):
            out[:, j] -= col @ c[k:k + col.shape[1]]
            k += col.shape[1]
        return out

    def project_out(self, v: np.ndarray, j: int, cols: list[np.ndarray], u_mat: np.ndarray,
                    s_mat: np.ndarray) -> np.ndarray:
        """``P^⊥ v`` for a whitened vector ``v`` (N,) on joint ``j``'s rows, as (N, nv)."""
        xv = self.x[:, j, :].T @ v / self.sigma[j]
        zv = scipy.linalg.solve_triangular(self.r, xv, trans="T")
        cv = np.zeros(u_mat.shape[1])
        k = 0
        for jj, col in zip(self.joints, cols):
            if jj == j:
                cv[k:k + col.shape[1]] = col.T @ v
            k += col.shape[1]
        cc = _solve_sym(s_mat, cv - u_mat.T @ zv)
        bb = scipy.linalg.solve_triangular(self.r, zv - u_mat @ cc)
        out = -np.einsum("njb,b->nj", self.x, bb) / self.sigma
        out[:, j] += v
        k = 0
        for jj, col in zip(self.joints, cols):
            out[:, jj] -= col @ cc[k:k + col.shape[1]]
            k += col.shape[1]
        return out

    # --------------------------------------------------------------- for least_squares
    def fun(self, u: np.ndarray) -> np.ndarray:
        cols, _ = self.columns(u)
        beta, c, _, _ = self.solve(cols)
        return self.residual(beta, c, cols).ravel()

    def jac(self, u: np.ndarray) -> np.ndarray:
        cols, ders = self.columns(u)
        beta, c, u_mat, s_mat = self.solve(cols)
        out = np.empty((self.tau.size, u.size))
        col, k = 0, 0
        for j, der, cj in zip(self.joints, ders, cols):
            amps = c[k:k + cj.shape[1]]
            for i in range(der.shape[2]):
                out[:, col] = -self.project_out(der[:, :, i] @ amps, j, cols, u_mat,
                                                s_mat).ravel()
                col += 1
            k += cj.shape[1]
        return out

    def full_jacobian_grams(self, u: np.ndarray, c: np.ndarray) -> np.ndarray:
        """Per joint, the Gram matrix of its whitened rows of the full Jacobian
        ``[X/σ, C, (∂C/∂u) c]``, (nv, b + K + M, b + K + M)."""
        cols, ders = self.columns(u)
        n, nv, b = self.x.shape
        k_all = sum(col.shape[1] for col in cols)
        m_all = u.size
        grams = np.zeros((nv, b + k_all + m_all, b + k_all + m_all))
        k, m = 0, 0
        blocks = {}
        for j, col, der in zip(self.joints, cols, ders):
            d = np.einsum("nkm,k->nm", der, c[k:k + col.shape[1]])
            blocks[j] = (k, col, m, d)
            k += col.shape[1]
            m += d.shape[1]
        for j in range(nv):
            rows = np.zeros((n, b + k_all + m_all))
            rows[:, :b] = self.x[:, j, :] / self.sigma[j]
            if j in blocks:
                kk, col, mm, d = blocks[j]
                rows[:, b + kk:b + kk + col.shape[1]] = col
                rows[:, b + k_all + mm:b + k_all + mm + d.shape[1]] = d
            grams[j] = rows.T @ rows
        return grams


def _names(model: RobotModel, laws: Sequence[str]) -> tuple[list[str], list[str]]:
    """Amplitude and shape parameter names in column order."""
    amps, shapes = [], []
    for j, law in enumerate(laws):
        if law == LINEAR:
            continue
        m = MODELS[law]
        amps += [f"{model.joint_names[j]}.{a}" for a in m.amplitudes]
        shapes += [f"{model.joint_names[j]}.{s}" for s in m.shapes]
    return amps, shapes


def _solve_sym(s_mat: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solution of the (small) Schur system, of least ``‖D c‖`` where it is singular: a column
    that vanishes at some shape (the search's bounds keep it rare) leaves its amplitude
    undetermined, not NaN. Solved equilibrated, ``D⁻¹ S D⁻¹ (D c) = D⁻¹ rhs`` with
    ``D = diag(S)^½`` (Jacobi scaling): the rank tolerance then judges directions, not the
    columns' units (a Stribeck term whose shape leaves it 10⁻⁴ of the Coulomb column's size was
    cut as if it were collinear)."""
    if rhs.size == 0:
        return rhs
    d = np.sqrt(np.abs(np.diag(s_mat)))
    d = np.where(d > 0, d, 1.0)
    return np.linalg.lstsq(s_mat / np.outer(d, d), rhs / d, rcond=1e-12)[0] / d


def _search(problem: Projection, u0: np.ndarray, max_nfev: int) -> tuple[np.ndarray, dict]:
    lo, hi = [], []
    for j in problem.joints:
        a, b = MODELS[problem.laws[j]].internal_bounds()
        lo.append(a)
        hi.append(b)
    lo_all, hi_all = np.concatenate(lo), np.concatenate(hi)
    u0 = np.clip(u0, lo_all + 1e-9, hi_all - 1e-9)
    sol = scipy.optimize.least_squares(problem.fun, u0, jac=problem.jac, method="trf",
                                       bounds=(lo_all, hi_all),
                                       x_scale="jac", max_nfev=max_nfev, xtol=1e-10,
                                       ftol=1e-12, gtol=1e-10)
    report = {"status": "converged" if sol.status > 0 else "stopped", "message": sol.message,
              "nfev": int(sol.nfev), "cost": float(sol.cost)}
    if sol.status <= 0 or not np.all(np.isfinite(sol.x)):
        warnings.warn(f"nonlinear friction search did not converge: {sol.message} "
                      f"({sol.nfev} evaluations); the shape parameters are where it stopped "
                      "(raise max_nfev, or use a richer excitation at low speed)",
                      InaccurateSolutionWarning, stacklevel=4)
    return sol.x, report


def _starts(problem: Projection, shapes: Mapping[str, float] | None,
            model: RobotModel) -> np.ndarray:
    """Search start: each law's :meth:`FrictionModel.start`, or given ``shapes``
    (``{"<joint>.<shape>": value}``)."""
    u0 = []
    given = dict(shapes or {})
    for j in problem.joints:
        m = MODELS[problem.laws[j]]
        eta = m.start(problem.dq[:, j])
        for i, s in enumerate(m.shapes):
            key = f"{model.joint_names[j]}.{s}"
            if key in given:
                eta[i] = check_number(f"start[{key!r}]", given.pop(key))
        u0.append(m.to_internal(eta))
    if given:
        raise OptionError(f"start names {sorted(given)}, which are not shape parameters of the "
                          "selected laws")
    return np.concatenate(u0) if u0 else np.zeros(0)


def identify_nonlinear(model: RobotModel, dataset: Dataset, method: str, friction: object,
                       armature: bool | Sequence[int | str] = False,
                       constraints: str | dict[str, str] = "auto", prior: str | None = "auto",
                       covariance: str = "coloured", *, start: Mapping[str, float] | None = None,
                       max_nfev: int = MAX_EVALUATIONS, min_speed: float | None = None,
                       **options: Any) -> NonlinearFrictionResult:
    """Identify rigid body and nonlinear friction (module docstring); called by
    :func:`consistid.identify` when ``friction`` names a nonlinear law.

    Parameters
    ----------
    model, dataset, method, armature, constraints, prior : as for :func:`consistid.identify`
        (``method="sdp"`` keeps every body consistent; OLS/WLS take no constraints or prior).
    friction : a nonlinear selection (:func:`parse_friction`).
    covariance : ``"coloured"`` or ``"iid"`` (``identify`` resolves ``"auto"``).
    start : optional starting shape parameters ``{"<joint>.<shape>": value}`` (natural units);
        default each law's :meth:`~consistid.friction.models.FrictionModel.start` from the data.
    max_nfev : evaluations allowed per search (a stopped search warns
        :class:`~consistid.errors.InaccurateSolutionWarning` and says so in ``search``).
    min_speed : rows of joint ``j`` with ``|q̇_j| < min_speed`` (rad/s) are left out of the fit
        (weight 0), everything else unchanged: at standstill stiction holds the joint with any
        torque up to the break-away, which no law of ``q̇`` predicts (the seed lecture's advice:
        discard near-zero velocities unless the friction model covers them). Default
        :data:`~consistid.robot.joint_terms.STANDSTILL_SPEED` (0.02 rad/s); 0 keeps every row.
        ``details["rows_used"]`` gives the count per joint.
    **options : options of :func:`consistid.identification.sdp.identify_sdp` (SDP only;
        ``loss="huber"`` is refused: its re-weighting re-compresses without the nonlinear
        columns).
    """
    t_start = time.perf_counter()
    check_option("covariance", covariance, ("iid", "coloured"))
    if options.get("loss", "squared") != "squared":
        raise OptionError("loss='huber' is not available with nonlinear friction (its IRLS "
                          "passes re-compress the linear columns only); use loss='squared'")
    max_nfev = check_number("max_nfev", max_nfev, 1, integer=True)
    selection = parse_friction(model, friction)
    spec = linear_spec(model, selection, armature)
    base = compute_base_parameters(model, spec)
    tau = dataset.require_torque()
    if dataset.dq_sign is not None and any(law != LINEAR for law in selection.laws):
        warnings.warn("the signal chain low-pass filtered these torques: a friction law's step "
                      "at q̇ = 0 reaches them smoothed over the filter's response, which the "
                      "law (a function of q̇) does not model, and its static friction and "
                      "shapes are biased; load the log with filter_torque=False (the fit "
                      "averages the noise), or fit 'coulomb', whose column is filtered like "
                      "the torques", DataQualityWarning, stacklevel=3)
    n, nv = tau.shape
    y = regressor(model, dataset.q, dataset.dq, dataset.ddq, spec,
                  dq_sign=dataset.dq_sign).reshape(n, nv, -1)
    x = np.ascontiguousarray(y[:, :, base.independent])
    b = base.n_base
    min_speed = (STANDSTILL_SPEED if min_speed is None
                 else check_number("min_speed", min_speed, 0))
    keep = (np.abs(dataset.dq) >= min_speed).astype(float)
    n_kept = keep.sum(axis=0)
    still = [name for name, k in zip(model.joint_names, n_kept) if k == 0]
    if still:
        # its rows all left out and its friction columns zero: the least-squares step would
        # fail on a rank test naming no joint
        raise PoorExcitationError(
            f"{', '.join(still)} never move{'s' if len(still) == 1 else ''} in these data "
            f"(|q̇| < min_speed = {min_speed:g} rad/s on every sample): no friction law can be "
            f"fitted there; lock {'it' if len(still) == 1 else 'them'} "
            f"(RobotModel.from_urdf(path, locked_joints={still!r}, locked_configuration=...)) "
            "or record a motion that moves every joint")
    problem = Projection(x, tau, dataset.dq, selection.laws, np.ones(nv), keep)
    u = _starts(problem, start, model)
    amp_names, shape_names = _names(model, selection.laws)
    k_all, m_all = len(amp_names), u.size
    n_par = b + k_all + m_all
    dof = float(n_kept.sum()) - n_par
    if dof <= 0:
        raise PoorExcitationError(f"{int(n_kept.sum())} rows (|q̇| ≥ min_speed = {min_speed:g}) "
                                  f"give too few equations for {n_par} parameters")

    def sigma_of(res: np.ndarray) -> np.ndarray:
        """σ per joint of a whitened residual (in N·m), or one common σ for OLS."""
        raw = res * problem.sigma
        if method == "ols":
            return np.full(nv, np.sqrt(np.sum(raw ** 2) / dof))
        sse = np.sum(raw ** 2, axis=0)
        rms = np.sqrt(np.sum((tau * keep) ** 2, axis=0) / np.maximum(n_kept, 1.0))
        sig = np.sqrt(sse / np.maximum(n_kept - n_par / nv, 1.0))
        return np.maximum(sig, SIGMA_FLOOR * np.maximum(rms, 1e-300))

    searches = []
    # σ from the residual at the start, a search, σ re-estimated at its optimum, a second search
    cols, _ = problem.columns(u)
    beta, c, _, _ = problem.solve(cols)
    problem.set_sigma(sigma_of(problem.residual(beta, c, cols)))
    for _ in range(2):
        if m_all:
            u, report = _search(problem, u, max_nfev)
            searches.append(report)
        cols, _ = problem.columns(u)
        beta, c, u_mat, s_mat = problem.solve(cols)
        residual = problem.residual(beta, c, cols)
        if _ == 0:
            problem.set_sigma(sigma_of(residual))
    search_time = time.perf_counter() - t_start
    at_bounds = _at_bounds(problem, u, shape_names)
    if at_bounds:
        warnings.warn(f"nonlinear friction: {', '.join(at_bounds)} ended at the search's bounds "
                      "(models.FrictionModel.bounds): the data do not determine them and that "
                      "joint's law degenerates (e.g. a Stribeck hump too wide or too narrow to "
                      "see); their σ is not meaningful — prefer another law for that joint",
                      PoorExcitationWarning, stacklevel=3)

    # --- covariance of (β, c, u): Gauss–Newton on whitened rows, optionally coloured
    grams = problem.full_jacobian_grams(u, c)
    info = grams.sum(axis=0)
    s2 = float(np.sum(residual ** 2) / dof)
    info_inv = _pinv_sym(info)
    raw_residual = residual * problem.sigma
    if covariance == "coloured":
        tau_j = autocorrelation_time(dataset, raw_residual)
        variances = np.sum(residual ** 2, axis=0) / np.maximum(n_kept - tau_j * n_par / nv, 1.0)
        meat = np.einsum("j,jpq->pq", tau_j * variances, grams)
        ok = np.all(np.isfinite(info_inv), axis=1)          # unexcited rows stay infinite
        cov = np.full_like(info_inv, np.inf)
        cov[np.ix_(ok, ok)] = info_inv[np.ix_(ok, ok)] @ meat[np.ix_(ok, ok)] @ info_inv[
            np.ix_(ok, ok)]
        cov_note = ("coloured (sandwich, N/τ_j effective rows; τ_j in samples: "
                    + ", ".join(f"{nm} {t:.3g}" for nm, t in zip(model.joint_names, tau_j)) + ")")
    else:
        tau_j = np.ones(nv)
        cov = s2 * info_inv
        cov_note = "iid (every row an independent sample)"
    # the linear and amplitude block alone (shapes held: a degenerate shape is warned about
    # above); singular as with identify(method="ols") and linear friction, which raises
    # (e.g. a joint turning one way only: its Coulomb amplitude equals its offset)
    n_lin = b + k_all
    unseen = _unexcited(info[:n_lin, :n_lin], _extended_base(base, amp_names).names)
    if unseen and method != "sdp":
        raise PoorExcitationError(
            f"the data do not determine {', '.join(unseen[:6])}{' …' if len(unseen) > 6 else ''}"
            f" (a direction of [rigid body | friction] not excited) which "
            f"least squares ({method}) cannot pick; use a richer excitation (a joint moving "
            "both ways, a speed range that shows the law's shape), or method='sdp' with a "
            "prior (res.uninformed names what the prior decides)")
    cov_lin = cov[:b + k_all, :b + k_all]
    std_u = np.sqrt(np.clip(np.diag(cov)[b + k_all:], 0.0, None))
    eta_all, jac_all = [], []
    for j, uj in zip(problem.joints, problem.split(u)):
        m = MODELS[selection.laws[j]]
        eta = m.from_internal(uj)
        eta_all.append(eta)
        jac_all.append(m.internal_jacobian(eta))
    eta_vec = np.concatenate(eta_all) if eta_all else np.zeros(0)
    eta_std = std_u * (np.concatenate(jac_all) if jac_all else np.zeros(0))

    # --- the linear parameters by the chosen method
    prior_lin = prior_vector(model, spec)
    names_lin = parameter_names(model, spec)
    sv = np.linalg.svd(np.block([[problem.r, u_mat],
                                 [np.zeros((k_all, b)), _sqrt_spd(s_mat)]]), compute_uv=False)
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
    details: dict[str, Any] = {"covariance": cov_note, "autocorrelation_time": tau_j,
                               "friction_laws": ", ".join(
                                   f"{nm}={law}" for nm, law in zip(model.joint_names,
                                                                    selection.laws)),
                               "variable_projection_time": search_time,
                               "rows_used": n_kept.astype(int), "min_speed": min_speed,
                               "shapes_at_bounds": ", ".join(at_bounds) or "none"}
    if method == "sdp":
        theta, amps, sdp_res = _sdp(model, y * keep[:, :, None], tau * keep, spec, base, problem,
                                    u, constraints, prior, options)
        details.update({k: v for k, v in sdp_res.details.items()
                        if k not in ("covariance", "autocorrelation_time")})
        solver = sdp_res.solver
        sigma = sdp_res.sigma
        parameters = np.concatenate([theta, amps])
        beta_out = np.concatenate([base.project(theta), amps])
    else:
        theta = _nearest_standard(base, beta, prior_lin)
        solver = SolverReport("variable projection (numpy QR + scipy least_squares)",
                              "optimal" if all(s["status"] == "converged" for s in searches)
                              else "stopped", time.perf_counter() - t_start)
        sigma = problem.sigma
        parameters = np.concatenate([theta, c])
        beta_out = np.concatenate([beta, c])
    ext_base = _extended_base(base, amp_names)
    fitted = NonlinearFrictionResult(
        method=method, model=model, spec=spec, base=ext_base, parameters=parameters,
        parameter_names=tuple([*names_lin, *amp_names]),
        prior=np.concatenate([prior_lin, np.zeros(k_all)]), base_parameters=beta_out,
        base_covariance=cov_lin, sigma=np.asarray(sigma, dtype=float), condition_number=cond,
        train_rms=np.zeros(nv), n_samples=n, solver=solver, details=details,
        laws=selection.laws, shape_names=tuple(shape_names), shape_parameters=eta_vec,
        shape_std=eta_std, amplitude_names=tuple(amp_names), search=tuple(searches))
    train_rms = np.sqrt(np.sum(fitted.residual(dataset) ** 2 * keep, axis=0)
                        / np.maximum(n_kept, 1.0))
    return replace(fitted, train_rms=train_rms)


def _nearest_standard(base: BaseParameters, beta: np.ndarray, prior: np.ndarray) -> np.ndarray:
    """The standard vector closest to ``prior`` with ``B π = β`` (as OLS results report)."""
    mat = base.matrix
    return prior + np.linalg.lstsq(mat, beta - mat @ prior, rcond=None)[0]


def _at_bounds(problem: Projection, u: np.ndarray, names: Sequence[str]) -> list[str]:
    """Names of the shape parameters within 0.01 (search coordinates: 1 % for the positive
    ones) of a search bound."""
    out, k = [], 0
    for j in problem.joints:
        lo, hi = MODELS[problem.laws[j]].internal_bounds()
        near = (np.abs(u[k:k + lo.size] - lo) < 1e-2) | (np.abs(u[k:k + lo.size] - hi) < 1e-2)
        out += [names[k + i] for i in np.flatnonzero(near)]
        k += lo.size
    return out


def _extended_base(base: BaseParameters, amplitude_names: Sequence[str]) -> BaseParameters:
    """``base`` with the amplitude columns appended as independent base parameters."""
    p, k = base.n_standard, len(amplitude_names)
    return BaseParameters(
        standard_names=(*base.standard_names, *amplitude_names),
        independent=np.concatenate([base.independent, p + np.arange(k)]).astype(int),
        dependent=base.dependent, K=np.vstack([base.K, np.zeros((k, base.dependent.size))]),
        diag_r=base.diag_r, rtol=base.rtol)


def _pinv_sym(info: np.ndarray) -> np.ndarray:
    """Inverse of a Gauss–Newton information matrix; parameters touched by directions the data
    do not excite (singular value of ``J`` below ``RANK_RTOL`` of the largest) get infinite
    variance, never a small one."""
    lam, vec = np.linalg.eigh(0.5 * (info + info.T))
    top = max(float(lam[-1]), 1e-300)
    keep = np.sqrt(np.clip(lam, 0.0, None)) > RANK_RTOL * np.sqrt(top)
    cov = (vec[:, keep] / lam[keep]) @ vec[:, keep].T
    if not np.all(keep):
        touched = np.linalg.norm(vec[:, ~keep], axis=1) > 1e-6
        cov[touched, :] = np.inf
        cov[:, touched] = np.inf
    return cov


def _unexcited(info: np.ndarray, names: Sequence[str]) -> list[str]:
    """Names in the directions the information matrix ``info`` (a Gram matrix ``JᵀJ``) leaves
    unexcited, largest share first. Its diagonal is scaled to 1 so that units do not decide;
    a direction is unexcited when its eigenvalue is at the rounding floor of the Gram matrix,
    ``λ ≤ λ_max · p · ε`` (the default tolerance of ``numpy.linalg.matrix_rank``: an exactly
    collinear pair of columns lands there, not at ``RANK_RTOL²``); each parameter is ranked by
    its norm over those eigenvectors."""
    d = np.sqrt(np.clip(np.diag(info), 1e-300, None))
    lam, vec = np.linalg.eigh(info / np.outer(d, d))
    null = lam <= lam[-1] * lam.size * np.finfo(float).eps
    if not null.any():
        return []
    share = np.linalg.norm(vec[:, null], axis=1)
    order = np.argsort(-share)
    return [names[i] for i in order if share[i] > 1e-3 * share[order[0]]]


def _sqrt_spd(s_mat: np.ndarray) -> np.ndarray:
    """An upper factor ``L`` with ``LᵀL = S`` for the condition number (zeros where ``S`` is
    not positive definite)."""
    if s_mat.size == 0:
        return s_mat
    lam, vec = np.linalg.eigh(0.5 * (s_mat + s_mat.T))
    return (vec * np.sqrt(np.clip(lam, 0.0, None))).T


def _sdp(model: RobotModel, y: np.ndarray, tau: np.ndarray, spec: RegressorSpec,
         base: BaseParameters, problem: Projection, u: np.ndarray, constraints: object,
         prior: object, options: dict[str, Any]) -> tuple[np.ndarray, np.ndarray, Any]:
    """The consistent SDP at ``η̂``: each joint's amplitudes profiled out of its compressed
    problem (R factor of ``[C_j | Y_j | τ_j]``, trailing block), the SDP on the rest, then the
    amplitudes from the leading rows. Returns ``(θ, c, the SDP's result)``."""
    from ..identification.sdp import identify_sdp     # cvxpy is loaded at the first SDP

    n, nv, p = y.shape
    factors = np.zeros((nv, p + 1, p + 1))
    leading: dict[int, np.ndarray] = {}
    etas = dict(zip(problem.joints, problem.split(u)))
    for j in range(nv):
        if j in etas:
            m = MODELS[problem.laws[j]]
            cols = m.columns(problem.dq[:, j], m.from_internal(etas[j])) * problem.keep[:, [j]]
        else:
            cols = np.zeros((n, 0))
        k = cols.shape[1]
        full = np.zeros((1, k + p + 1, k + p + 1))
        accumulate(full, np.concatenate([cols, y[:, j, :]], axis=1)[:, None, :],
                   tau[:, [j]])
        factors[j] = full[0, k:, k:]
        leading[j] = full[0, :k, :]
    compressed = CompressedProblem(factors, n, np.sum(tau ** 2, axis=0))
    res = identify_sdp(model, compressed, base, spec,
                       constraints="pseudo-inertia" if constraints == "auto" else constraints,
                       prior="logdet" if prior == "auto" else prior, **options)
    theta = res.parameters
    amps = []
    for j in problem.joints:
        lead = leading[j]
        k = lead.shape[0]
        amps.append(np.linalg.lstsq(lead[:, :k], lead[:, -1] - lead[:, k:k + p] @ theta,
                                    rcond=1e-12)[0])
    return theta, (np.concatenate(amps) if amps else np.zeros(0)), res

r"""The standard inertial parameters of a rigid body and their physical consistency.

Layout (Pinocchio's ``Inertia.toDynamicParameters`` order), inertia about the body-frame origin:

.. math::

    \pi = [m,\; m c_x,\; m c_y,\; m c_z,\;
           I_{xx},\; I_{xy},\; I_{yy},\; I_{xz},\; I_{yz},\; I_{zz}]

Equivalent representations, converted by Pinocchio where it can:

* ``(m, c, I_c)``: mass, centre of mass, rotational inertia about the CoM
  (:func:`to_mass_com_inertia`, :func:`from_mass_com_inertia`; ``I = I_c + m [c]_×ᵀ[c]_×``);
* the 4×4 pseudo-inertia ``J = [[Σ, h], [hᵀ, m]]`` with ``Σ = ½ tr(I) 1 − I`` and ``h = m c``
  (:func:`pseudo_inertia`, :func:`from_pseudo_inertia`; ``pinocchio.PseudoInertia``).

Physical consistency, from weakest to strongest (each implies the ones before):

``"mass-inertia"``
    ``m > 0`` and ``I_c ≻ 0``.
``"triangle"``
    additionally, the principal moments satisfy ``I_k ≤ I_l + I_m`` (Traversaro et al. 2016,
    "Identification of fully physical consistent inertial parameters using optimization on
    manifolds", IROS, doi:10.1109/IROS.2016.7759801).
``"pseudo-inertia"``
    ``J ≻ 0``: the parameters are realised by a positive mass density (Wensing, Kim, Slotine
    2017, "Linear matrix inequalities for physically consistent inertial parameter
    identification", IEEE RA-L 3(1), doi:10.1109/LRA.2017.2729659). For a single body this is
    equivalent to ``m > 0`` and the triangle inequalities on ``I_c``; it is the form that becomes
    a linear matrix inequality.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import pinocchio as pin

from ..errors import (InconsistentParametersError, OptionError, ParameterShapeError,
                     check_option)

INERTIAL_NAMES: tuple[str, ...] = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
CONSISTENCY_LEVELS: tuple[str, ...] = ("mass-inertia", "triangle", "pseudo-inertia")


def _body(p: np.ndarray) -> np.ndarray:
    p = np.asarray(p, dtype=float)
    if p.shape != (10,):
        raise ParameterShapeError(
            f"a body's standard parameters have shape (10,), got {p.shape}")
    if not np.all(np.isfinite(p)):
        k = int(np.flatnonzero(~np.isfinite(p))[0])
        raise InconsistentParametersError(
            f"a body's standard parameters must be finite; {INERTIAL_NAMES[k]} = {p[k]}")
    return p


def inertia_about_origin(p: np.ndarray) -> np.ndarray:
    """The 3×3 rotational inertia about the body-frame origin from a 10-vector."""
    _, _, _, _, ixx, ixy, iyy, ixz, iyz, izz = _body(p)
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])


def to_mass_com_inertia(p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """``(m, c, I_c)`` from a 10-vector; ``I_c = I − m [c]_×ᵀ[c]_×`` (parallel axes).

    Raises :class:`InconsistentParametersError` (a ``ValueError``) for a non-positive mass,
    where the centre of mass is undefined.
    """
    p = _body(p)
    m = p[0]
    if not m > 0:
        raise InconsistentParametersError(f"mass {m:.6g} ≤ 0: the centre of mass is undefined")
    c = p[1:4] / m
    cx = pin.skew(c)
    return float(m), c, inertia_about_origin(p) + m * cx @ cx


def from_mass_com_inertia(m: float, c: Sequence[float], inertia_com: np.ndarray) -> np.ndarray:
    """10-vector from mass, CoM and inertia about the CoM: ``h = m c``,
    ``I = I_c + m [c]_×ᵀ[c]_×`` (what ``pinocchio.Inertia(m, c, I_c).toDynamicParameters()``
    gives, but also for inconsistent input, which Pinocchio refuses, so that it can be checked).
    """
    c = np.asarray(c, dtype=float)
    inertia_com = np.asarray(inertia_com, dtype=float)
    if c.shape != (3,) or inertia_com.shape != (3, 3):
        raise ParameterShapeError(
            f"c must have shape (3,) and inertia_com (3, 3), got {c.shape} and "
            f"{inertia_com.shape}")
    if not (np.isfinite(float(m)) and np.all(np.isfinite(c)) and np.all(np.isfinite(inertia_com))):
        raise InconsistentParametersError(
            f"mass, centre of mass and inertia must be finite, got m = {m}, c = {c.tolist()}, "
            f"I_c = {inertia_com.tolist()}")
    cx = pin.skew(c)
    i = 0.5 * (inertia_com + inertia_com.T) - float(m) * cx @ cx
    return np.array([m, *(float(m) * c), i[0, 0], i[0, 1], i[1, 1], i[0, 2], i[1, 2], i[2, 2]])


def pseudo_inertia(p: np.ndarray) -> np.ndarray:
    """The 4×4 pseudo-inertia ``J`` of one body (``pinocchio.PseudoInertia``)."""
    return np.array(pin.PseudoInertia.FromDynamicParameters(_body(p)).toMatrix())


#: A pseudo-inertia whose smallest eigenvalue is at most this fraction of its largest is singular
#: to working precision: a body with no extent along some direction (a point mass, a rod, a
#: plate). It is physical, but no log-det prior can be centred on it (its divergence
#: ``−log det(J₀⁻¹J) + tr(J₀⁻¹J)`` weighs that direction by ``1/λ_min``).
DEGENERATE_RTOL = 1e-9


def is_degenerate(p: np.ndarray) -> bool:
    """Whether one body's pseudo-inertia is not positive definite to working precision,
    ``λ_min(J) ≤`` :data:`DEGENERATE_RTOL` ``· max(λ_max(J), 0)``."""
    lam = np.linalg.eigvalsh(pseudo_inertia(p))
    return not lam[0] > DEGENERATE_RTOL * max(lam[-1], 0.0)


def degenerate_bodies(parameters: np.ndarray, names: Sequence[str]) -> list[str]:
    """The ``names`` of the bodies (10 inertial parameters each, in order, from the start of
    ``parameters``) that are :func:`is_degenerate`."""
    bodies = np.asarray(parameters, dtype=float)[:10 * len(names)].reshape(-1, 10)
    return [name for name, body in zip(names, bodies) if is_degenerate(body)]


def pseudo_inertia_map() -> np.ndarray:
    r"""The constant (16, 10) matrix ``P`` with ``vec(J) = P π`` (column-major ``vec``).

    From ``Σ = ½ tr(I) 1 − I``: ``Σ_xx = ½(−I_xx + I_yy + I_zz)`` (and cyclic), ``Σ_xy = −I_xy``
    (and the other products), ``J[:3, 3] = h``, ``J[3, 3] = m``. ``P`` has full column rank and
    ``pinv(P) vec(J)`` inverts it for a symmetric ``J``; cvxpy builders use it so that the
    pseudo-inertia of a parameter expression is one matrix product.
    """
    out = np.zeros((16, 10))
    for k in range(10):
        e = np.zeros(10)
        e[k] = 1.0
        out[:, k] = pseudo_inertia(e).ravel(order="F")
    return out


def from_pseudo_inertia(J: np.ndarray) -> np.ndarray:
    """The 10-vector of a 4×4 pseudo-inertia (inverse of :func:`pseudo_inertia`)."""
    J = np.asarray(J, dtype=float)
    if J.shape != (4, 4):
        raise ParameterShapeError(f"a pseudo-inertia is 4×4, got {J.shape}")
    return np.array(pin.PseudoInertia.FromMatrix(0.5 * (J + J.T)).toDynamicParameters())


def inertias_from_vector(parameters: np.ndarray) -> list[pin.Inertia]:
    """``pinocchio.Inertia`` objects from a stacked standard vector (10 per body)."""
    parameters = np.asarray(parameters, dtype=float)
    if parameters.ndim != 1 or parameters.size % 10:
        raise ParameterShapeError(
            f"stacked standard parameters need 10 per body, got {parameters.shape}")
    return [pin.Inertia.FromDynamicParameters(_body(parameters[i:i + 10]))
            for i in range(0, parameters.size, 10)]


@dataclass(frozen=True, eq=False)
class BodyConsistency:
    """The verdict for one body: ``ok``, the first violated condition, and the margins."""

    body: str
    ok: bool
    reason: str
    mass: float
    min_pseudo_inertia_eigenvalue: float
    principal_moments: np.ndarray | None
    #: the violated condition: ``"mass"``, ``"inertia"`` (``I_c`` not positive definite),
    #: ``"triangle"``, ``"pseudo-inertia"``; ``""`` when ``ok``.
    condition: str = ""


def check_body(p: np.ndarray, level: str = "pseudo-inertia", body: str = "body",
               tol: float = 0.0) -> BodyConsistency:
    """Check one body's 10-vector against a consistency level.

    Every condition is a margin that must exceed ``−tol``: ``eig(I_c) > −tol``, triangle slack
    ``I_1 + I_2 − I_3 > −tol``, ``λ_min(J) > −tol`` (kg·m²); the mass must be positive whatever
    ``tol`` (the CoM is undefined otherwise). At the default ``tol = 0`` this is strict: a solid
    body. A positive ``tol`` forgives round-off (and accepts boundary bodies such as thin rods);
    a negative one demands that much margin.
    """
    check_option("level", level, CONSISTENCY_LEVELS)
    p = _body(p)
    lam_j = float(np.linalg.eigvalsh(pseudo_inertia(p))[0])
    if not p[0] > max(0.0, -tol):
        return BodyConsistency(body, False, f"{body}: mass {p[0]:.6g} kg ≤ {max(0.0, -tol):g}",
                               p[0], lam_j, None, "mass")
    _, _, inertia_com = to_mass_com_inertia(p)
    moments = np.linalg.eigvalsh(inertia_com)
    if not moments[0] > -tol:
        return BodyConsistency(body, False,
                               f"{body}: inertia about the CoM not positive definite "
                               f"(smallest principal moment {moments[0]:.3g} kg·m²)",
                               p[0], lam_j, moments, "inertia")
    if level in ("triangle", "pseudo-inertia"):
        slack = moments[0] + moments[1] - moments[2]
        if not slack > -tol:
            return BodyConsistency(body, False,
                                   f"{body}: triangle inequality violated "
                                   f"(I1 + I2 − I3 = {slack:.3g} kg·m²)", p[0], lam_j, moments,
                                   "triangle")
    if level == "pseudo-inertia" and not lam_j > -tol:
        return BodyConsistency(body, False,
                               f"{body}: pseudo-inertia min eigenvalue {lam_j:.3g}",
                               p[0], lam_j, moments, "pseudo-inertia")
    return BodyConsistency(body, True, "", p[0], lam_j, moments)


@dataclass(frozen=True)
class ConsistencyReport:
    """Per-body consistency of a stacked parameter vector; truthy when every body passes."""

    level: str
    bodies: tuple[BodyConsistency, ...]

    @property
    def ok(self) -> bool:
        return all(b.ok for b in self.bodies)

    @property
    def violations(self) -> list[str]:
        return [b.reason for b in self.bodies if not b.ok]

    @property
    def min_eigenvalues(self) -> np.ndarray:
        return np.array([b.min_pseudo_inertia_eigenvalue for b in self.bodies])

    def __bool__(self) -> bool:
        return self.ok

    def __str__(self) -> str:
        if self.ok:
            return f"all {len(self.bodies)} bodies consistent ({self.level})"
        return "; ".join(self.violations)


def is_physically_consistent(parameters: np.ndarray, level: str = "pseudo-inertia",
                             body_names: Sequence[str] | None = None,
                             tol: float = 0.0) -> ConsistencyReport:
    """Check every body of a stacked standard vector.

    Parameters
    ----------
    parameters : (10·n,) standard parameters; with ``body_names`` given, entries after the
        ``10·len(body_names)`` inertial ones (friction, armature) are ignored.
    level : one of :data:`CONSISTENCY_LEVELS`.
    body_names : names used in the verdicts, default ``body1, body2, …``.
    tol : absolute tolerance on the margins, see :func:`check_body`.

    Returns a :class:`ConsistencyReport` that is truthy when all bodies pass and names the first
    violated condition of each failing body otherwise (``BodyConsistency.condition``).
    """
    parameters = np.asarray(parameters, dtype=float)
    if parameters.ndim != 1:
        raise ParameterShapeError(
            f"parameters must be a 1-D vector, got shape {parameters.shape}")
    if body_names is None:
        if parameters.size % 10:
            raise ParameterShapeError(
                f"{parameters.size} parameters are not 10 per body; pass body_names to check "
                "the inertial part of a vector with friction entries")
        n = parameters.size // 10
        names = [f"body{i + 1}" for i in range(n)]
    else:
        names = list(body_names)
        n = len(names)
        if parameters.size < 10 * n:
            raise ParameterShapeError(
                f"{parameters.size} parameters for {n} bodies; need {10 * n}")
    return ConsistencyReport(level, tuple(
        check_body(body, level, name, tol) for body, name in zip(bodies(parameters, n), names)))


def perturb(parameters: np.ndarray, relative: float, rng: np.random.Generator) -> np.ndarray:
    """A physically consistent random perturbation of a stacked standard vector.

    Each body's mass, each CoM coordinate and the inertia about the CoM (one common factor, so
    the triangle inequalities are kept) are multiplied by independent factors drawn uniformly
    from ``[1 − relative, 1 + relative]``. Used to make "true" robots that differ from the CAD
    prior in simulation. ``relative`` must lie in ``[0, 1)`` so that masses stay positive.
    """
    if not 0.0 <= relative < 1.0:
        raise OptionError(f"perturb: relative = {relative} must lie in [0, 1)")
    out = np.array(parameters, dtype=float)
    if out.ndim != 1 or out.size % 10:
        raise ParameterShapeError(
            f"perturb: a stacked standard vector has 10 entries per body, got shape {out.shape}")
    for body in bodies(out):  # rows are views: written in place
        m, c, inertia_com = to_mass_com_inertia(body)
        f = rng.uniform(1 - relative, 1 + relative, size=5)
        body[:] = from_mass_com_inertia(m * f[0], c * f[1:4], inertia_com * f[4])
    return out


def body_slice(i: int) -> slice:
    """The entries of body ``i`` (0-based) in a stacked standard vector: ``10 i … 10 i + 9``.

    For numpy arrays prefer :func:`bodies`; this serves cvxpy expressions and index arrays.
    """
    return slice(10 * i, 10 * i + 10)


def bodies(parameters: np.ndarray, n: int | None = None) -> np.ndarray:
    """The first ``n`` bodies of a stacked standard vector as an ``(n, 10)`` view (row ``i`` is
    body ``i``; writing to it writes to ``parameters``). ``n`` defaults to ``size // 10`` and
    must then divide the size exactly."""
    parameters = np.asarray(parameters)
    if parameters.ndim != 1:
        raise ParameterShapeError(f"a stacked standard vector is 1-D, got shape "
                                  f"{parameters.shape}")
    if n is None:
        if parameters.size % 10:
            raise ParameterShapeError(f"{parameters.size} entries are not 10 per body")
        n = parameters.size // 10
    if parameters.size < 10 * n:
        raise ParameterShapeError(f"{parameters.size} entries for {n} bodies; need {10 * n}")
    return parameters[:10 * n].reshape(n, 10)


@dataclass(frozen=True, eq=False)
class InertialParameters:
    r"""One rigid body's standard inertial parameters, as a value.

    .. math:: \pi = [m,\; h_x,\; h_y,\; h_z,\; I_{xx},\; I_{xy},\; I_{yy},\; I_{xz},\;
              I_{yz},\; I_{zz}], \qquad h = m c,

    the inertia ``I`` about the body-frame origin (Pinocchio's ``Inertia.toDynamicParameters``
    order). The same body is also ``(m, c, I_c)`` and the pseudo-inertia
    ``J = [[½ tr(I) 1 − I, h], [hᵀ, m]]`` (Wensing, Kim, Slotine 2017), which is linear in ``π``
    and transforms as ``J' = T J Tᵀ`` under a rigid motion ``T`` (homogeneous 4×4). Modelled on
    rigeo's ``InertialParameters`` (constructors from a vector or a pseudo-inertia, ``.J``,
    ``.consistent()``, ``.transform()``).

    >>> body = InertialParameters.from_mass_com_inertia(2.0, [0, 0, 0.1], np.eye(3) * 0.01)
    >>> body.consistent(), body.mass, body.com
    """

    vector: np.ndarray

    def __post_init__(self) -> None:
        v = np.array(self.vector, dtype=float)  # a private copy: the value cannot change
        if v.shape != (10,):
            raise ParameterShapeError(f"a body's standard parameters have shape (10,), got "
                                      f"{v.shape}")
        if not np.all(np.isfinite(v)):
            raise InconsistentParametersError(
                f"a body's standard parameters must be finite, got {v.tolist()}")
        v.flags.writeable = False
        object.__setattr__(self, "vector", v)

    # ------------------------------------------------------------------------ constructors
    @classmethod
    def from_mass_com_inertia(cls, mass: float, com: Sequence[float],
                              inertia_com: np.ndarray) -> "InertialParameters":
        """From mass (kg), centre of mass (m) and the 3×3 inertia about the CoM (kg·m²)."""
        return cls(from_mass_com_inertia(mass, com, inertia_com))

    @classmethod
    def from_pseudo_inertia(cls, J: np.ndarray) -> "InertialParameters":
        """From a symmetric 4×4 pseudo-inertia (its symmetric part is used)."""
        return cls(from_pseudo_inertia(J))

    @classmethod
    def from_pinocchio(cls, inertia: pin.Inertia) -> "InertialParameters":
        return cls(np.asarray(inertia.toDynamicParameters()))

    @classmethod
    def split(cls, parameters: np.ndarray, n: int | None = None
              ) -> tuple["InertialParameters", ...]:
        """Every body of a stacked standard vector (the first ``n`` bodies, see :func:`bodies`)."""
        return tuple(cls(row) for row in bodies(np.asarray(parameters, dtype=float), n))

    # ------------------------------------------------------------------------ views
    @property
    def mass(self) -> float:
        return float(self.vector[0])

    @property
    def first_moment(self) -> np.ndarray:
        """``h = m c`` (kg·m)."""
        return self.vector[1:4].copy()

    @property
    def com(self) -> np.ndarray:
        """The centre of mass ``c = h / m`` (m); :class:`InconsistentParametersError` if
        ``m ≤ 0``."""
        return to_mass_com_inertia(self.vector)[1]

    @property
    def inertia(self) -> np.ndarray:
        """The 3×3 rotational inertia about the body-frame origin (kg·m²)."""
        return inertia_about_origin(self.vector)

    @property
    def inertia_com(self) -> np.ndarray:
        """The 3×3 rotational inertia about the centre of mass (kg·m²)."""
        return to_mass_com_inertia(self.vector)[2]

    @property
    def J(self) -> np.ndarray:  # noqa: N802 — the symbol of the literature
        """The 4×4 pseudo-inertia."""
        return pseudo_inertia(self.vector)

    def to_pinocchio(self) -> pin.Inertia:
        return pin.Inertia.FromDynamicParameters(self.vector)

    # ------------------------------------------------------------------------ physics
    def consistent(self, level: str = "pseudo-inertia", tol: float = 0.0,
                   name: str = "body") -> BodyConsistency:
        """The check of :func:`check_body` (truthy through ``.ok``)."""
        return check_body(self.vector, level, name, tol)

    def transform(self, rotation: np.ndarray, translation: Sequence[float]
                  ) -> "InertialParameters":
        """The same body expressed in a frame where the old frame has orientation ``rotation``
        and origin ``translation``: ``J' = T J Tᵀ`` with ``T = [[R, p], [0, 1]]``."""
        t = np.eye(4)
        t[:3, :3] = np.asarray(rotation, dtype=float)
        t[:3, 3] = np.asarray(translation, dtype=float)
        return InertialParameters.from_pseudo_inertia(t @ self.J @ t.T)

    def __add__(self, other: "InertialParameters") -> "InertialParameters":
        """Two bodies rigidly joined, both expressed in the same frame (parameters add)."""
        return InertialParameters(self.vector + other.vector)

    def __sub__(self, other: "InertialParameters") -> "InertialParameters":
        """What remains of this body when the part ``other`` (same frame) is taken away."""
        return InertialParameters(self.vector - other.vector)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, InertialParameters) and bool(np.array_equal(self.vector,
                                                                             other.vector))

    def __hash__(self) -> int:
        return hash(self.vector.tobytes())

    def __repr__(self) -> str:
        return (f"InertialParameters(m={self.mass:.6g} kg, h={np.round(self.vector[1:4], 6)}, "
                f"I_origin=[{', '.join(f'{x:.4g}' for x in self.vector[4:])}])")


def writable_bodies(parameters: np.ndarray, names: Sequence[str]) -> list[InertialParameters]:
    """Each named body of the stacked standard vector ``parameters`` as
    :class:`InertialParameters`, for a writer of model files, which never writes an
    inconsistent body: :class:`InconsistentParametersError` names the first one (pseudo-inertia
    level, :func:`check_body`)."""
    out = []
    for i, name in enumerate(names):
        body = InertialParameters(np.asarray(parameters[body_slice(i)], dtype=float))
        verdict = body.consistent(name=name)
        if not verdict.ok:
            raise InconsistentParametersError(f"refusing to write an inconsistent body: "
                                              f"{verdict.reason}")
        out.append(body)
    return out


r"""Nonlinear joint-friction models: value, regressor columns and derivatives.

Each model is linear in a few *amplitudes* ``a`` and nonlinear in one or two *shape*
parameters ``η``: ``τ_f(q̇) = C(q̇; η) a``. Variable projection
(:mod:`consistid.friction.fit`) eliminates ``a`` (with the rigid-body parameters) by least
squares and searches ``η`` alone, which needs the columns ``C`` and their derivatives
``∂C/∂η``. The shape parameters are searched in *internal* coordinates ``u`` (a logarithm for
the positive ones) so that a plain unconstrained search keeps them physical; ``∂C/∂u`` is
returned in those coordinates.

``stribeck`` — Stribeck curve with Coulomb and static friction (Armstrong-Hélouvry, Dupont,
Canudas de Wit 1994, "A survey of models, analysis tools and compensation methods for the
control of machines with friction", Automatica 30(7), doi:10.1016/0005-1098(94)90209-7, eq. 3;
Bo & Pavelescu 1982 for the exponent ``δ``):

.. math::  τ_f = \big(f_c + (f_s - f_c)\,e^{-|\dot q / v_s|^{δ}}\big)\operatorname{sign}\dot q,
           \qquad C = \big[\operatorname{sign}\dot q\,(1 - e),\; \operatorname{sign}\dot q\,e\big],
           \quad e = e^{-|\dot q / v_s|^{δ}}

amplitudes ``(f_c, f_s)`` (N·m), shape ``(v_s, δ)`` (rad/s, –). The viscous ``f_v q̇`` of the
Stribeck curve is the linear ``viscous`` column of :mod:`consistid.identification.regressor`.

``sigmoid`` — the Panda friction model of Gaz, Cognetti, Oliva, Robuffo Giordano, De Luca
2019, "Dynamic identification of the Franka Emika Panda robot with retrieval of feasible
parameters using penalty-based optimization", IEEE RA-L 4(4), doi:10.1109/LRA.2019.2931248,
eq. 8 (also the seed lecture's KUKA LWR4 slide):

.. math::  τ_f = \frac{φ_1}{1 + e^{-φ_2(\dot q + φ_3)}} - \frac{φ_1}{1 + e^{-φ_2 φ_3}}

amplitude ``φ_1`` (N·m), shape ``(φ_2, φ_3)`` (s/rad, rad/s); ``τ_f(0) = 0``.

``tanh`` — a smooth Coulomb friction with a fitted velocity scale (e.g. Makkar, Dixon, Sawyer,
Hu 2005, "A new continuously differentiable friction model for control systems design", IEEE/ASME
AIM, doi:10.1109/AIM.2005.1511037, its first term):

.. math::  τ_f = f_c \tanh(\dot q / v_s)

amplitude ``f_c`` (N·m), shape ``v_s`` (rad/s).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..errors import OptionError


def _logistic(x: np.ndarray) -> np.ndarray:
    return 0.5 * (1.0 + np.tanh(0.5 * x))          # 1/(1 + e^{-x}) without overflow


@dataclass(frozen=True)
class FrictionModel:
    """A friction law ``τ_f = C(q̇; η) a`` (module docstring). Subclasses define the class
    attributes and :meth:`columns` / :meth:`column_derivatives`."""

    name: ClassVar[str] = ""
    #: suffixes of the amplitude parameters (``"<joint>.<suffix>"``), in column order
    amplitudes: ClassVar[tuple[str, ...]] = ()
    #: suffixes of the shape parameters, in the order of ``η``
    shapes: ClassVar[tuple[str, ...]] = ()
    #: units of the shape parameters, for tables
    shape_units: ClassVar[tuple[str, ...]] = ()
    #: which shape parameters are positive (searched as their logarithm)
    positive: ClassVar[tuple[bool, ...]] = ()
    #: (lower, upper) of each shape parameter for the search (natural units): wide, only to
    #: keep a column from vanishing (``v_s → ∞`` flattens a Stribeck hump into nothing)
    bounds: ClassVar[tuple[tuple[float, float], ...]] = ()
    #: A step at ``q̇ = 0`` (``sign``): at rest such a law holds any torque within its limit
    #: ``|C(±0; η) a|`` (set-valued); a continuous law (sigmoid, tanh) is 0 there.
    dry: ClassVar[bool] = False

    # ------------------------------------------------------------------ coordinates
    def to_internal(self, eta: np.ndarray) -> np.ndarray:
        """Search coordinates ``u`` of shape parameters ``η`` (log of the positive ones)."""
        eta = np.asarray(eta, dtype=float)
        bad = [s for s, p, v in zip(self.shapes, self.positive, eta) if p and not v > 0]
        if bad or not np.all(np.isfinite(eta)):
            raise OptionError(f"{self.name} shape parameters {dict(zip(self.shapes, eta))} must "
                              f"be finite, and {list(bad) or 'the positive ones'} > 0")
        return np.where(self.positive, np.log(np.where(self.positive, eta, 1.0)), eta)

    def from_internal(self, u: np.ndarray) -> np.ndarray:
        """Shape parameters ``η`` of search coordinates ``u``."""
        u = np.asarray(u, dtype=float)
        return np.where(self.positive, np.exp(np.where(self.positive, u, 0.0)), u)

    def internal_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """:attr:`bounds` in search coordinates, as ``(lower, upper)`` arrays."""
        lo, hi = (np.array([b[i] for b in self.bounds], dtype=float) for i in (0, 1))
        return (np.where(self.positive, np.log(np.where(self.positive, lo, 1.0)), lo),
                np.where(self.positive, np.log(np.where(self.positive, hi, 1.0)), hi))

    def internal_jacobian(self, eta: np.ndarray) -> np.ndarray:
        """``dη/du`` (diagonal, as a vector): ``η`` for a log coordinate, 1 otherwise."""
        return np.where(self.positive, np.asarray(eta, dtype=float), 1.0)

    # ------------------------------------------------------------------ the law
    def columns(self, dq: np.ndarray, eta: np.ndarray) -> np.ndarray:
        """``C(q̇; η)``, shape ``(N, len(amplitudes))``."""
        raise NotImplementedError

    def column_derivatives(self, dq: np.ndarray, eta: np.ndarray) -> np.ndarray:
        """``∂C/∂η``, shape ``(N, len(amplitudes), len(shapes))`` (natural coordinates)."""
        raise NotImplementedError

    def value(self, dq: np.ndarray, amplitudes: np.ndarray, eta: np.ndarray) -> np.ndarray:
        """``τ_f(q̇)``, shape of ``dq``."""
        dq = np.asarray(dq, dtype=float)
        return (self.columns(dq.ravel(), eta) @ np.asarray(amplitudes, dtype=float)
                ).reshape(dq.shape)

    def derivatives(self, dq: np.ndarray, amplitudes: np.ndarray, eta: np.ndarray
                    ) -> np.ndarray:
        """``∂τ_f/∂η``, shape ``(N, len(shapes))`` (natural coordinates)."""
        return np.einsum("nks,k->ns", self.column_derivatives(np.ravel(dq), eta),
                         np.asarray(amplitudes, dtype=float))

    def start(self, dq: np.ndarray) -> np.ndarray:
        """A starting ``η`` for the search from the joint's velocities (scale-aware)."""
        raise NotImplementedError


@dataclass(frozen=True)
class Stribeck(FrictionModel):
    """Stribeck curve (module docstring): amplitudes ``fc, fs``; shape ``vs, delta``."""

    name: ClassVar[str] = "stribeck"
    amplitudes: ClassVar[tuple[str, ...]] = ("fc", "fs")
    shapes: ClassVar[tuple[str, ...]] = ("vs", "delta")
    shape_units: ClassVar[tuple[str, ...]] = ("rad/s", "")
    positive: ClassVar[tuple[bool, ...]] = (True, True)
    bounds: ClassVar[tuple[tuple[float, float], ...]] = ((1e-4, 10.0), (0.25, 10.0))
    dry: ClassVar[bool] = True

    def columns(self, dq: np.ndarray, eta: np.ndarray) -> np.ndarray:
        vs, delta = eta
        s, e = np.sign(dq), np.exp(-(np.abs(dq) / vs) ** delta)
        return np.column_stack([s * (1.0 - e), s * e])

    def column_derivatives(self, dq: np.ndarray, eta: np.ndarray) -> np.ndarray:
        vs, delta = eta
        x = np.abs(dq) / vs
        xd = x ** delta
        s, e = np.sign(dq), np.exp(-xd)
        with np.errstate(divide="ignore", invalid="ignore"):
            logx = np.where(x > 0, np.log(np.where(x > 0, x, 1.0)), 0.0)
        de_dvs = e * delta * xd / vs                 # ∂e/∂v_s
        de_ddelta = -e * xd * logx                   # ∂e/∂δ
        out = np.empty((dq.size, 2, 2))
        out[:, 0, 0], out[:, 0, 1] = -s * de_dvs, -s * de_ddelta
        out[:, 1, 0], out[:, 1, 1] = s * de_dvs, s * de_ddelta
        return out

    def start(self, dq: np.ndarray) -> np.ndarray:
        speed = np.abs(dq[dq != 0])
        return np.array([max(float(np.quantile(speed, 0.2)) if speed.size else 0.1, 1e-3), 1.0])


@dataclass(frozen=True)
class GazSigmoid(FrictionModel):
    """Gaz et al.'s sigmoid (module docstring): amplitude ``phi1``; shape ``phi2, phi3``."""

    name: ClassVar[str] = "sigmoid"
    amplitudes: ClassVar[tuple[str, ...]] = ("phi1",)
    shapes: ClassVar[tuple[str, ...]] = ("phi2", "phi3")
    shape_units: ClassVar[tuple[str, ...]] = ("s/rad", "rad/s")
    positive: ClassVar[tuple[bool, ...]] = (True, False)
    bounds: ClassVar[tuple[tuple[float, float], ...]] = ((1e-2, 1e4), (-2.0, 2.0))

    def columns(self, dq: np.ndarray, eta: np.ndarray) -> np.ndarray:
        phi2, phi3 = eta
        return (_logistic(phi2 * (dq + phi3)) - _logistic(phi2 * phi3))[:, None]

    def column_derivatives(self, dq: np.ndarray, eta: np.ndarray) -> np.ndarray:
        phi2, phi3 = eta
        sa, sb = _logistic(phi2 * (dq + phi3)), _logistic(phi2 * phi3)
        da, db = sa * (1.0 - sa), sb * (1.0 - sb)     # logistic' at a = φ2(q̇+φ3), b = φ2φ3
        out = np.empty((dq.size, 1, 2))
        out[:, 0, 0] = da * (dq + phi3) - db * phi3
        out[:, 0, 1] = (da - db) * phi2
        return out

    def start(self, dq: np.ndarray) -> np.ndarray:
        speed = np.abs(dq[dq != 0])
        scale = max(float(np.quantile(speed, 0.2)) if speed.size else 0.1, 1e-3)
        return np.array([2.0 / scale, 0.0])


@dataclass(frozen=True)
class TanhCoulomb(FrictionModel):
    """Smooth Coulomb friction (module docstring): amplitude ``fc``; shape ``vs``."""

    name: ClassVar[str] = "tanh"
    amplitudes: ClassVar[tuple[str, ...]] = ("fc",)
    shapes: ClassVar[tuple[str, ...]] = ("vs",)
    shape_units: ClassVar[tuple[str, ...]] = ("rad/s",)
    positive: ClassVar[tuple[bool, ...]] = (True,)
    bounds: ClassVar[tuple[tuple[float, float], ...]] = ((1e-5, 10.0),)

    def columns(self, dq: np.ndarray, eta: np.ndarray) -> np.ndarray:
        (vs,) = eta
        return np.tanh(dq / vs)[:, None]

    def column_derivatives(self, dq: np.ndarray, eta: np.ndarray) -> np.ndarray:
        (vs,) = eta
        return (-(dq / vs ** 2) / np.cosh(np.clip(dq / vs, -350, 350)) ** 2)[:, None, None]

    def start(self, dq: np.ndarray) -> np.ndarray:
        speed = np.abs(dq[dq != 0])
        return np.array([max(0.5 * float(np.quantile(speed, 0.1)) if speed.size else 0.05,
                             1e-3)])


#: name → model; the names ``identify(..., friction=...)`` accepts for a joint's nonlinear law.

MODELS: dict[str, FrictionModel] = {m.name: m for m in (Stribeck(), GazSigmoid(), TanhCoulomb())}
#: The name of the linear law (``fc·sign q̇``, the ``coulomb`` column) in per-joint selections.
LINEAR = "coulomb"


def get_model(name: str) -> FrictionModel:
    """The model called ``name`` (:data:`MODELS`), else :class:`OptionError` listing them."""
    if not isinstance(name, str) or name not in MODELS:
        raise OptionError(f"friction model {name!r} is not known; nonlinear models: "
                          f"{sorted(MODELS)} (or {LINEAR!r} for the linear fc·sign(q̇))")
    return MODELS[name]

r"""Base parameters: the identifiable linear combinations of the standard parameters.

Numerical method of Gautier (1991), "Numerical calculation of the base inertial parameters of
robots", J. Robotic Systems 8(4), doi:10.1002/rob.4620080405: stack the regressor ``W`` of many
random states, take a QR decomposition with column pivoting ``W P = Q R``; the rank ``b`` is the
number of diagonal entries of ``R`` above ``rtol · |R₀₀|``, the first ``b`` pivoted columns are
*independent*, the others *dependent*, and

.. math::  W_d = W_b K, \qquad \tau = W \pi = W_b (\pi_b + K \pi_d) = W_b \beta .

So ``β = B π`` with ``B = [1 | K]`` (columns placed back in standard order). The independent
columns are kept in standard order, so ``β_i`` reads as "``π_{b,i}`` plus the regrouped ones".
Which columns pivoting picks can change with BLAS threading; the rank and the identity
``W π = W_b B π`` do not.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import scipy.linalg

from ..errors import OptionError, check_number
from ..robot.model import RobotModel
from .regressor import RegressorSpec, parameter_names, regressor

#: Above this condition number of the (weighted) base regressor, a PoorExcitationWarning is issued.
COND_WARN = 1e4
#: Below this ratio of the smallest to the largest singular value, the base regressor is singular.
RANK_RTOL = 1e-11


def random_states(model: RobotModel, n: int, rng: np.random.Generator
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Random (q, dq, ddq), q uniform within finite limits (else in ±π), dq, ddq standard normal."""
    lim = model.limits
    lo = np.where(np.isfinite(lim.lower), lim.lower, -np.pi)
    hi = np.where(np.isfinite(lim.upper), lim.upper, np.pi)
    q = rng.uniform(lo, hi, size=(n, model.nv))
    return q, rng.standard_normal((n, model.nv)), rng.standard_normal((n, model.nv))


def _format_term(coef: float, name: str) -> str:
    return name if abs(abs(coef) - 1.0) < 1e-9 else f"{abs(coef):.4g}·{name}"


@dataclass(frozen=True, eq=False)
class BaseParameters:
    """The map from standard to base parameters, ``β = B π``.

    Attributes
    ----------
    standard_names : names of the ``p`` standard columns (rigid body and per-joint blocks).
    independent : (b,) indices of the independent standard columns, increasing.
    dependent : (p − b,) indices of the others.
    K : (b, p − b) regrouping matrix, ``β = π[independent] + K π[dependent]``.
    diag_r : |diagonal of R| from the pivoted QR (in pivot order), for diagnosing the rank.
    rtol : the relative rank tolerance used.
    """

    standard_names: tuple[str, ...]
    independent: np.ndarray
    dependent: np.ndarray
    K: np.ndarray
    diag_r: np.ndarray
    rtol: float

    @property
    def n_base(self) -> int:
        return int(self.independent.size)

    @property
    def n_standard(self) -> int:
        return len(self.standard_names)

    @property
    def matrix(self) -> np.ndarray:
        """``B`` (b × p) with ``β = B π``."""
        B = np.zeros((self.n_base, self.n_standard))
        B[np.arange(self.n_base), self.independent] = 1.0
        B[:, self.dependent] = self.K
        return B

    def project(self, parameters: np.ndarray) -> np.ndarray:
        """Base parameters ``β = B π`` of a standard vector (or of each row of a 2-D array)."""
        return np.asarray(parameters) @ self.matrix.T

    def base_columns(self, y: np.ndarray) -> np.ndarray:
        """The base regressor ``W_b`` (the independent columns of a full regressor)."""
        return y[..., self.independent]

    @property
    def unidentifiable(self) -> list[str]:
        """Standard parameters that do not act on the torques at all (zero columns)."""
        zero = np.all(np.abs(self.K) < 1e-12, axis=0)
        return [self.standard_names[i] for i in self.dependent[zero]]

    @property
    def names(self) -> list[str]:
        """A short name per base parameter: the independent standard parameter it starts from."""
        return [self.standard_names[i] + ("*" if np.any(np.abs(self.K[r]) > 1e-9) else "")
                for r, i in enumerate(self.independent)]

    @property
    def groupings(self) -> list[str]:
        """Each base parameter as a readable linear combination of named standard parameters,
        e.g. ``"panda_link2.Izz + 0.1·panda_link3.mz − 0.0975·panda_link4.m"``."""
        out = []
        for r, i in enumerate(self.independent):
            text = self.standard_names[i]
            for c in np.argsort(-np.abs(self.K[r])):
                coef = self.K[r, c]
                if abs(coef) <= 1e-9:
                    break
                text += (" + " if coef > 0 else " − ") + _format_term(coef, self.standard_names[
                    self.dependent[c]])
            out.append(text)
        return out

    def __str__(self) -> str:
        lines = [f"{self.n_base} base parameters of {self.n_standard} standard ones"]
        lines += [f"  β{r + 1:<3d} = {g}" for r, g in enumerate(self.groupings)]
        return "\n".join(lines)


def base_parameters_from_regressor(y: np.ndarray, names: Sequence[str],
                                   rtol: float = 1e-8) -> BaseParameters:
    """Base parameters from a tall regressor ``y`` (rows ≫ columns) of exciting states."""
    _, r, piv = scipy.linalg.qr(y, mode="economic", pivoting=True)
    d = np.abs(np.diag(r))
    rank = int(np.sum(d > rtol * d[0])) if d.size and d[0] > 0 else 0
    independent = np.sort(piv[:rank])
    dependent = np.setdiff1d(np.arange(y.shape[1]), independent)
    # Regrouping W_d = W_b K, solved on the R factor of W (same column relations, p rows).
    rf = np.empty_like(r)
    rf[:, piv] = r
    K = np.linalg.lstsq(rf[:, independent], rf[:, dependent], rcond=None)[0]
    K[np.abs(K) < 1e-10] = 0.0
    return BaseParameters(tuple(names), independent, dependent, K, d, rtol)


def compute_base_parameters(model: RobotModel, spec: RegressorSpec | None = None,
                            n_samples: int | None = None, seed: int = 0,
                            rtol: float = 1e-8) -> BaseParameters:
    """Numerical base parameters of ``model`` with the per-joint columns of ``spec``.

    Parameters
    ----------
    spec : friction/armature columns; default rigid body only.
    n_samples : random states to stack; default ``max(200, 4·p/nv)``.
    seed : random states are drawn from ``numpy.random.default_rng(seed)``.
    rtol : rank tolerance relative to the largest diagonal entry of ``R``.
    """
    if n_samples is not None:
        check_number("n_samples", n_samples, 1, integer=True)
    rtol = check_number("rtol", rtol, 0, strict=True)
    if rtol >= 1:
        raise OptionError(f"rtol is a relative rank tolerance in (0, 1), got {rtol!r}")
    spec = spec or RegressorSpec.make(model, friction=None)
    names = parameter_names(model, spec)
    n = n_samples or max(200, 4 * len(names) // model.nv)
    q, dq, ddq = random_states(model, n, np.random.default_rng(seed))
    return base_parameters_from_regressor(regressor(model, q, dq, ddq, spec), names, rtol)

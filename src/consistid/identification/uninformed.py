r"""Directions of the base parameters that the data do not inform, named as base groupings.

The weighted base regressor's R factor ``R_b`` (``‖Σ^{-1/2}(W_b β − τ)‖² = ‖R_b β − z‖² + ρ²``)
has right singular vectors ``v_k`` with singular values ``s_k``; a direction with
``s_k ≤ rtol · s_1`` (``rtol`` = :data:`~consistid.identification.base.RANK_RTOL`) changes the
fit by nothing measurable, so whatever value the answer gives it comes from the prior (or the
constraints) alone (Gautier & Khalil 1990 on identifiability; Golub & Van Loan §5.5 on numerical
rank). The null space ``N`` (rows ``v_k``) is reported in reduced row-echelon form,
``M = N[:, P]⁻¹ N`` with ``P`` the columns a pivoted QR of ``N`` picks (Businger & Golub 1965):
each direction then leads with one base parameter, with the fewest others attached, e.g.
``"β7 = panda_link2.Izz + 0.1·panda_link3.mz"`` or ``"β3 − 0.5·β9 (β3 = …; β9 = …)"``.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from .base import RANK_RTOL, BaseParameters
from ..errors import IdentificationError

__all__ = ["uninformed_directions", "null_directions"]

#: Coefficients below this (relative to the direction's largest) are not printed.
SHOWN_TOL = 1e-6


def null_directions(r_b: np.ndarray, rtol: float = RANK_RTOL) -> np.ndarray:
    """Rows spanning the directions of ``β`` that ``r_b`` does not inform, in reduced
    row-echelon form (module docstring), shape ``(k, b)``; ``(0, b)`` when there are none."""
    r_b = np.asarray(r_b, dtype=float)
    b = r_b.shape[1]
    if not np.all(np.isfinite(r_b)):
        raise IdentificationError("the weighted base regressor has non-finite entries (noise "
                                  "weights 1/σ overflowed?): check the torques' magnitudes")
    _, s, vt = np.linalg.svd(r_b, full_matrices=True)
    s = np.concatenate([s, np.zeros(b - s.size)])
    dead = vt[s <= rtol * s[0]] if s[0] > 0 else np.eye(b)
    if dead.shape[0] == 0:
        return np.zeros((0, b))
    _, _, piv = scipy.linalg.qr(dead, mode="economic", pivoting=True)
    lead = piv[:dead.shape[0]]
    rref = np.linalg.solve(dead[:, lead], dead)
    rref[np.abs(rref) < SHOWN_TOL] = 0.0
    return rref[np.argsort(lead)]


def _term(coef: float, name: str, first: bool) -> str:
    sign = ("−" if coef < 0 else "") if first else (" − " if coef < 0 else " + ")
    size = "" if abs(abs(coef) - 1.0) < 1e-9 else f"{abs(coef):.3g}·"
    return f"{sign}{size}{name}"


def uninformed_directions(r_b: np.ndarray, base: BaseParameters,
                          rtol: float = RANK_RTOL) -> tuple[str, ...]:
    """Each uninformed direction of the base parameters as readable text (module docstring):
    ``"β7 = <grouping>"`` when it is one base parameter, else its combination with the
    groupings of the base parameters it involves (at most 4 terms shown)."""
    rows = null_directions(r_b, rtol)
    groupings = base.groupings
    out = []
    for row in rows:
        idx = np.flatnonzero(row)
        idx = idx[np.argsort(-np.abs(row[idx]), kind="stable")]
        if idx.size == 1:
            out.append(f"β{idx[0] + 1} = {groupings[idx[0]]}")
            continue
        shown = idx[:4]
        text = "".join(_term(row[i], f"β{i + 1}", k == 0) for k, i in enumerate(shown))
        if idx.size > shown.size:
            text += f" + … ({idx.size - shown.size} more)"
        out.append(text + " (" + "; ".join(f"β{i + 1} = {groupings[i]}" for i in shown) + ")")
    return tuple(out)

r"""Which kinematic parameters the measurements fix, and which combinations they cannot see.

With the weighted residual Jacobian ``J`` (rows: whitened residuals, columns: the selected
parameters, each scaled to unit norm so that metres and radians compare), a parameter is
*identifiable beside the ones before it* when its column leaves a residual after projection on
the earlier kept columns (a Gram–Schmidt pass in a fixed priority order, like the sequential
choice of base inertial parameters, Gautier 1990, doi:10.1109/ROBOT.1990.126105). The columns that
leave none are held at the URDF's values (their correction stays 0): each is an exact combination
of kept ones,

.. math::  J_d = \sum_i c_{di} J_i \quad\Longrightarrow\quad
           n_d = e_d - \sum_i c_{di} e_i \in \ker J,

and the ``n_d`` span the null space of ``J``: moving the held parameter by ``δ`` and the kept ones
by ``−c δ`` changes no measurement (to first order; the redundancies of the complete model are
exact group identities, e.g. a joint's origin rotation about its own axis *is* a zero offset).

The priority order — measurement frame, anchor, then per joint zero offset, translation,
rotation, axis, then the tool — keeps the parameters a user expects (zero offsets, link lengths)
and holds their aliases. The kept set is decided once per (model, frame, kind, selection) on
generic configurations (:attr:`KinematicParameters.random_configurations`), so it does not depend
on the noise; the data then must reach the same rank, else
:class:`~consistid.errors.PoorExcitationError` says what they miss.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: relative residual below which a column counts as a combination of the kept ones
RANK_TOL = 1e-8


@dataclass(frozen=True)
class Unidentifiable:
    """One direction of parameter space the measurements cannot see.

    Attributes
    ----------
    held : the parameter held at the URDF value (its correction is 0).
    combination : ``((name, coefficient), ...)``, the null direction ``n = e_held − Σ c_i e_i``
        with the held parameter's coefficient 1 (units: the kept parameter's per the held
        one's, m/m, rad/rad or m/rad).
    """

    held: str
    combination: tuple[tuple[str, float], ...]

    @property
    def aliases(self) -> tuple[str, ...]:
        """The kept parameters that absorb the held one."""
        return tuple(n for n, _ in self.combination if n != self.held)

    def __str__(self) -> str:
        return self.describe()

    def describe(self, smallest: float = 0.01) -> str:
        """The combination, terms with ``|c| < smallest`` counted but not written."""
        terms, small = [], 0
        for name, c in self.combination:
            if abs(c) < smallest:
                small += 1
                continue
            sign = "−" if c < 0 else "+"
            mag = "" if abs(abs(c) - 1) < 5e-4 else f"{abs(c):.3g}·"
            terms.append(f"{sign} {mag}{name}")
        text = " ".join(terms).lstrip("+ ")
        more = f" + {small} term(s) < {smallest:g}" if small else ""
        return f"{text}{more}  (held: {self.held})"


def normalised(jac: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Columns scaled to unit norm and the norms; a column below ``RANK_TOL × `` the largest
    norm is rounding noise of an exact zero (e.g. a joint's zero offset seen from a point on
    its axis) and counts as zero (norm 0, column 0), not as a direction."""
    norms = np.linalg.norm(jac, axis=0)
    norms = np.where(norms > RANK_TOL * (norms.max() if norms.size else 0.0), norms, 0.0)
    return jac / np.where(norms > 0, norms, 1.0) * (norms > 0), norms


def sequential_selection(jac: np.ndarray, order: np.ndarray | None = None,
                         tol: float = RANK_TOL) -> np.ndarray:
    """Boolean mask of the columns kept by the ordered Gram–Schmidt pass (module docstring).

    ``order`` gives the priority (default: column order); a zero column is never kept.
    """
    a, norms = normalised(jac)
    order = np.arange(a.shape[1]) if order is None else np.asarray(order)
    kept = np.zeros(a.shape[1], dtype=bool)
    basis = np.zeros((a.shape[0], 0))
    for c in order:
        if norms[c] == 0:
            continue
        r = a[:, c] - basis @ (basis.T @ a[:, c])
        r -= basis @ (basis.T @ r)                 # twice is enough (Giraud et al. 2005)
        nr = np.linalg.norm(r)
        if nr > tol:
            kept[c] = True
            basis = np.column_stack([basis, r / nr])
    return kept


def null_directions(jac: np.ndarray, kept: np.ndarray, names: list[str] | tuple[str, ...],
                    tol: float = 1e-9) -> tuple[tuple[Unidentifiable, ...], np.ndarray, float]:
    """The held parameters' null directions at ``jac`` (columns named by ``names``).

    Returns the :class:`Unidentifiable` list, the (p, k) matrix of directions and the largest
    relative residual ``‖J n_d‖ / ‖J_d‖`` (≈ 1e-12 when every held column is an exact
    combination of the kept ones at this point).
    """
    p = jac.shape[1]
    kept_idx = np.flatnonzero(kept)
    held_idx = np.flatnonzero(~kept)
    out, mat, worst = [], np.zeros((p, held_idx.size)), 0.0
    jk = jac[:, kept_idx]
    for col, d in enumerate(held_idx):
        coef = np.linalg.lstsq(jk, jac[:, d], rcond=None)[0] if kept_idx.size else np.zeros(0)
        nd = np.zeros(p)
        nd[d] = 1.0
        nd[kept_idx] = -coef
        scale = np.linalg.norm(jac[:, d])
        if scale > 0:
            worst = max(worst, float(np.linalg.norm(jac @ nd) / scale))
        mat[:, col] = nd
        big = np.abs(nd) > tol * max(1.0, np.abs(nd).max())
        terms = tuple((names[i], float(nd[i])) for i in [d, *kept_idx[big[kept_idx]]])
        out.append(Unidentifiable(names[d], terms))
    return tuple(out), mat, worst


#: relative residual a column must leave at the generic point to be added (first-order weak
#: directions, ~1e-3 for a measured point a millimetre off an axis, are added; second-order ones,
#: ~1e-6, would have σ a million times the noise and are held)
GENERIC_TOL = 1e-4


def structural_selection(nominal: np.ndarray, generic: np.ndarray, order: np.ndarray,
                         tol: float = RANK_TOL) -> np.ndarray:
    """The kept columns: first those the URDF's own Jacobian ``nominal`` keeps (in ``order``),
    then, among the rest, those the Jacobian at a nearby generic point ``generic`` adds.

    The URDF can be special (a measured point on the last joint's axis, parallel axes): a
    combination exact there may not be exact for the real robot a few mm and tenths of a degree
    away, and holding it would leave a bias. Such parameters are kept when their column leaves
    a relative residual above :data:`GENERIC_TOL` there (they are identified, though weakly
    where the geometry is nearly special: their σ says how weakly); the ones the URDF already
    identifies keep their priority.
    """
    kept = sequential_selection(nominal, order, tol)
    order = np.asarray(order)
    more = sequential_selection(generic, np.concatenate([order[kept[order]],
                                                         order[~kept[order]]]), GENERIC_TOL)
    return kept | more

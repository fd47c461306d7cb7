r"""Candidates that interact: an atom scored with the atoms it trades off against left free.

The greedy selection (:mod:`consistid.diagnosis.diagnose`) fits each candidate jointly with the
atoms already chosen. On the commonest real mismatch, CAD inertias off on every body *and*
friction on every joint, friction enters joint by joint; while some joint's friction is still
missing, the least-squares ``inertia`` atom (tens of base parameters, whose columns hold velocity
terms) takes that friction up: it fits the training trajectory and fails on another one, so its
held-out gain is negative at every step and it never enters, nor does ``payload`` (a subset of
its columns); the residual the inertia leaves is then taken up by per-joint stand-ins (a gain, a
position torque) or left on the joint.

An effect names its *companions* (:attr:`consistid.diagnosis.effects.base.Effect.companions`,
e.g. ``inertia`` and ``payload``: Coulomb and viscous friction). Its atom is scored
*conditionally*: the reference fit holds the chosen atoms plus every companion atom not yet
chosen, the candidate fit the same plus the atom, and its tests (training ΔBIC, held-out F,
relevance) compare the two. This is the partial F-test of a block of regressors in the presence
of nuisance regressors: by the Frisch–Waugh–Lovell theorem the block is then tested on the part
of its columns and of the residual orthogonal to the nuisance columns (Seber & Lee, *Linear
Regression Analysis*, 2nd ed., Wiley 2003, §4.5; Lovell, J. Am. Stat. Assoc. 58(304), 993–1010,
1963). Only the atom enters when it passes; each companion still earns its place by its own
tests in the steps that follow.

Such an atom spans every joint, and its fit pools them. Weighted by each joint's noise floor
(``1/σ_j²``), a joint whose residual is mostly model error the candidates cannot express (a
wrist held within its friction cone at rest leaves 3–7 × its floor, at a floor of 0.03 N·m)
weighs tens of times more than its variance warrants: the inertia columns fit that joint's
training-trajectory model error, and on another trajectory predict it and the joints at their
floor worse (Kinova mixed case, seed 1: joint 3, left at 39 × its floor's variance, fitted down
to 25 ×, and on held-out data up from 50 × to 66 ×; joint 6, at its floor, made 4 × worse;
held-out F-test p = 1, though the simulated inertias cut joint 2's held-out RMS by 39 %). The
atom is therefore fitted and tested by feasible generalised least squares (Aitken,
Proc. R. Soc. Edinb. 55, 42–48, 1935; Greene, *Econometric Analysis*, 7th ed., §9.4): each
joint weighted by the inverse of what the fit leaves there, ``SSE_j/N`` — the per-joint
maximum-likelihood variance that ``identify`` also weights its fit with (its σ from an
ordinary least-squares pass), not the floor, which may be read too high or too low — the
reference fit with the same weights, so that both sides of every test see one likelihood (the
case above: joint 6 stays at its floor, p = 6·10⁻⁶). Once such an atom is chosen, the
selection's later fits keep the weights it was scored with.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..identification.compression import SIGMA_FLOOR
from .effects import REGISTRY, Atom


def companions(atoms: Sequence[Atom], chosen: Sequence[int], i: int) -> list[int]:
    """Indices of the atoms of ``atoms[i]``'s companion effects that are not yet in ``chosen``
    (``[]`` for an effect without companions): fitted beside ``atoms[i]`` when it is scored."""
    wanted = REGISTRY[atoms[i].effect].companions
    if not wanted:
        return []
    taken = set(chosen)
    return [m for m, a in enumerate(atoms) if a.effect in wanted and m not in taken and m != i]


def residual_scale(sse: np.ndarray, n: int) -> np.ndarray:
    """(nv,) factors on the floor weights ``1/σ_j²`` that weight each joint by the inverse of
    the variance a fit leaves there, ``N / SSE_j`` (module docstring): ``sse`` the fit's
    per-joint training sum of squares in units of the floor (``Σ r_j² / σ_j²``), ``n`` the rows
    per joint. A joint at its floor keeps its weight; one left at ``k × σ_j²`` (model error)
    gets ``1/k`` of it, and one below it (a floor read too high) more. Kept finite as
    ``identify`` keeps its σ (:data:`~consistid.identification.compression.SIGMA_FLOOR`, here
    of the largest variance)."""
    var = np.asarray(sse, dtype=float) / max(n, 1)
    return 1.0 / np.maximum(var, SIGMA_FLOOR ** 2 * max(float(var.max(initial=0.0)), 1e-300))

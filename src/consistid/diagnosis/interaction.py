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
"""

from __future__ import annotations

from collections.abc import Sequence

from .effects import REGISTRY, Atom


def companions(atoms: Sequence[Atom], chosen: Sequence[int], i: int) -> list[int]:
    """Indices of the atoms of ``atoms[i]``'s companion effects that are not yet in ``chosen``
    (``[]`` for an effect without companions): fitted beside ``atoms[i]`` when it is scored."""
    wanted = REGISTRY[atoms[i].effect].companions
    if not wanted:
        return []
    taken = set(chosen)
    return [m for m, a in enumerate(atoms) if a.effect in wanted and m not in taken and m != i]

r"""Directions of the base parameters that the data inform only weakly, named in words.

An uninformed direction (:mod:`consistid.identification.uninformed`) has no data at all; a
*weakly informed* one has so little that its estimate is free to move predictions by a large
share of the torque wherever the robot goes slightly otherwise than in the training data. The
criterion is in torque, not in parameter units (a relative σ of ``f_c − f_o`` or of a regrouped
inertia has no common scale):

    A unit-χ² move of the base parameters (one standard deviation of the data's information,
    ``‖R_b δβ‖ = 1``, ``R_b`` the noise-weighted base factor) along direction ``v`` changes the
    predicted torque on *reference states* by ``Δτ = W_b^{ref} v``. The direction is weakly
    informed when ``sqrt(Σ_j mean_ref(Δτ_j / s_j)²) > WEAK_RATIO``, ``s_j`` joint ``j``'s
    torque RMS in the training data.

The reference states are the training envelope (:class:`~consistid.identification.envelope.
TrainingEnvelope`) with every sign allowed: ``q_j`` uniform over the trained range, ``q̇_j``
and ``q̈_j`` uniform in ``±`` their trained largest magnitude (seeded). So only what the data
could have seen by running the same motions either way counts: a joint that moved one way only
puts its Coulomb-minus-offset direction here, a position range never visited does not (that is
extrapolation, warned by ``predict``). The directions are the right singular vectors of
``W_b^{ref} R_b⁻¹`` over the informed subspace (a generalised eigenproblem of the reference
and data information matrices: Golub & Van Loan §8.7), those with singular value above
:data:`WEAK_RATIO`.

:data:`WEAK_RATIO` = 0.25: one σ moving predictions by a quarter of the torque, an estimate
that says next to nothing there. On random 5-harmonic Fourier excitations (30 s, 500 Hz,
σ = 0.1 N·m, MuJoCo Coulomb + viscous friction) the largest ratio was 0.002–0.004 on the Panda
and UR5, 0.006–0.02 on the xArm7 and 0.05–0.07 on the Kinova (whose wrist barely moves in
them); a joint moving one way only gives 10² and more (``benchmarks/weak_directions.py``).

A joint that moved one way only (:meth:`TrainingEnvelope.one_way`) is named explicitly whatever
its ratio: its Coulomb and offset are told apart by a few samples (or none), near reversals
where stiction dominates the residual.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from .base import RANK_RTOL, BaseParameters
from .envelope import TrainingEnvelope
from .regressor import RegressorSpec, regressor
from ..robot.model import RobotModel

__all__ = ["WEAK_RATIO", "weak_directions", "weakly_informed", "one_way_note"]

#: Relative torque (of each joint's training RMS, root-sum-square over joints) that a 1σ move
#: along a direction may change on the sign-symmetric envelope before it is weakly informed.
WEAK_RATIO = 0.25
#: Reference states drawn from the envelope.
REFERENCE_SAMPLES = 256
#: Terms of a direction shown: those carrying at least this share of its largest torque effect.
SHOWN_SHARE = 0.1
#: ... at most this many.
SHOWN_TERMS = 4

_WORDS = {"fc": "Coulomb", "fv": "viscous", "fo": "offset", "Ia": "armature"}


def reference_states(envelope: TrainingEnvelope, n: int = REFERENCE_SAMPLES, seed: int = 0
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(q, q̇, q̈)``, each ``(n, nv)``: the envelope with both signs (module docstring)."""
    rng = np.random.default_rng(seed)
    nv = envelope.q_min.size
    q = rng.uniform(envelope.q_min, envelope.q_max, size=(n, nv))
    dq = rng.uniform(-1.0, 1.0, size=(n, nv)) * envelope.dq_max
    ddq = rng.uniform(-1.0, 1.0, size=(n, nv)) * envelope.ddq_max
    return q, dq, ddq


def weak_directions(model: RobotModel, spec: RegressorSpec, base: BaseParameters,
                    r_b: np.ndarray, envelope: TrainingEnvelope, torque_rms: np.ndarray,
                    ratio: float = WEAK_RATIO, rtol: float = RANK_RTOL,
                    joints: np.ndarray | None = None
                    ) -> list[tuple[np.ndarray, float, np.ndarray]]:
    """The weakly informed directions (module docstring), largest ratio first, as
    ``(v, ratio, effect)``: ``v`` (b,) the 1σ move of the base parameters, ``ratio`` its relative
    torque on the reference states, ``effect`` (b,) each base parameter's share of it (RMS
    relative torque of ``v_i`` alone). Directions the data do not inform at all (singular
    value below ``rtol``) are left to :func:`~consistid.identification.uninformed.
    uninformed_directions`. ``joints``: the joints whose torque rows the data hold (default
    all; ``torque_rms`` is theirs)."""
    _, s, vt = np.linalg.svd(r_b)
    keep = s > rtol * s[0] if s.size and s[0] > 0 else np.zeros(s.size, dtype=bool)
    if not np.any(keep):
        return []
    q, dq, ddq = reference_states(envelope)
    n, nv = q.shape
    rows = np.arange(nv) if joints is None else np.asarray(joints)
    scale = np.where(torque_rms > 0, torque_rms, max(float(np.max(torque_rms)), 1.0))
    w = base.base_columns(regressor(model, q, dq, ddq, spec)).reshape(n, nv, -1)[:, rows]
    nv = rows.size
    w = (w / scale[None, :, None] / np.sqrt(n)).reshape(n * nv, -1)
    to_beta = vt[keep].T / s[keep]                         # unit χ² coordinates → δβ
    _, a, qt = np.linalg.svd(w @ to_beta, full_matrices=False)
    out = []
    for k in np.flatnonzero(a > ratio):
        v = to_beta @ qt[k]
        effect = np.linalg.norm(w * v, axis=0)
        out.append((v, float(a[k]), effect))
    return out


def _in_words(names: Sequence[str]) -> str:
    """``["j1.fc", "j1.fo"]`` → ``"j1's Coulomb and offset"``; otherwise the names joined."""
    parts = [n.rsplit(".", 1) for n in names]
    if all(len(p) == 2 and p[1] in _WORDS for p in parts) and len({p[0] for p in parts}) == 1:
        words = [_WORDS[p[1]] for p in parts]
        listed = words[0] if len(words) == 1 else ", ".join(words[:-1]) + " and " + words[-1]
        return f"{parts[0][0]}'s {listed}"
    return " and ".join(names) if len(names) == 2 else ", ".join(names)


def _standard(name: str) -> str:
    return name.rstrip("*")


def weakly_informed(model: RobotModel, spec: RegressorSpec, base: BaseParameters,
                    r_b: np.ndarray, envelope: TrainingEnvelope, torque_rms: np.ndarray,
                    joints: np.ndarray | None = None, ratio: float = WEAK_RATIO
                    ) -> tuple[str, ...]:
    """The weakly informed directions in words (module docstring): each joint that moved one way
    only (``"j's Coulomb and offset: j moves one way only in these data (…)"``), then each
    direction of :func:`weak_directions` not already said so, with the base parameters that
    carry it and how much a 1σ move changes the predicted torque."""
    names = base.names
    out, said = [], set()
    columns = set(base.standard_names)
    for j, _ in envelope.one_way():
        joint = model.joint_names[j]
        pair = [f"{joint}.{c}" for c in ("fc", "fo") if f"{joint}.{c}" in columns]
        if f"{joint}.fc" not in pair:
            continue                                    # no Coulomb column: nothing to confuse
        said.add(frozenset(pair))
        out.append(f"{_in_words(pair)}: {envelope.describe_one_way(j)}, so the data cannot "
                   f"tell f_c·sign(q̇) from f_o; predictions with {joint} moving the other way "
                   "are extrapolation")
    for v, r, effect in weak_directions(model, spec, base, r_b, envelope, torque_rms, ratio,
                                        joints=joints):
        order = np.argsort(-effect)
        shown = [i for i in order[:SHOWN_TERMS] if effect[i] >= SHOWN_SHARE * effect[order[0]]]
        terms = [names[i] for i in shown]
        if frozenset(_standard(t) for t in terms) in said:
            continue
        out.append(f"{_in_words(terms)} ({', '.join(f'β{i + 1}' for i in shown)}): a 1σ move "
                   f"changes the predicted torque by {r:.3g} × the joints' torque RMS on the "
                   "trained motions run with either velocity sign")
    return tuple(out)


def one_way_note(model: RobotModel, spec: RegressorSpec, envelope: TrainingEnvelope) -> str:
    """What to add to a least-squares refusal when joints with a Coulomb column moved one way
    only (their Coulomb and offset columns are then equal): ``""`` when none did."""
    coulomb = dict(spec.masks)["coulomb"]
    said = [envelope.describe_one_way(j) for j, _ in envelope.one_way() if coulomb[j]]
    if not said:
        return ""
    return (f". {'; '.join(said)}: its Coulomb f_c·sign(q̇) and offset f_o are the same column "
            "there. Record motion in both directions, or use method='sdp', whose joint prior "
            "splits them (predictions for the other direction then warn)")

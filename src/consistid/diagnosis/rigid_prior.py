r"""The rigid-body candidates scored as the final fit makes them: near the nominal bodies.

The ``inertia`` atom (every base parameter, ``δβ``) and the ``payload`` atom (the last body's ten
parameters) have tens of columns, some barely excited by one trajectory: unregularised least
squares sets those directions from the noise, and on another trajectory (held out) the fit is
worse than none (the xArm7 and Kinova mixed cases: negative held-out gain at every step, though
the simulated inertias are 12 % off). The final fit
(:func:`consistid.diagnosis.diagnose._sdp_inertia`) is the consistent SDP with a log-det prior
around the nominal; the selection scores the candidates with that prior's quadratic model
(:mod:`consistid.identification.prior_weight`): the data term, Fisher-weighted, plus

.. math::  γ\, δπ^\top S\, δπ, \qquad S = \operatorname{blkdiag}_b W_bᵀW_b,

``W_b`` the log-det metric of nominal body ``b``
(:func:`consistid.identification.priors.logdet_metric`,
``d(J₀ + Δ ‖ J₀) ≈ ‖W_b δπ_b‖²``). Seen on the base parameters ``β = Bπ`` (the ``inertia``
columns), the Gaussian prior ``δπ ~ N(0, (γS)⁻¹)`` is ``δβ ~ N(0, B S⁻¹ Bᵀ / γ)``: the precision
``γ (B S⁻¹ Bᵀ)⁻¹``; on the payload, the last body's block ``γ W_nᵀW_n``. The weight ``γ`` is the
one of greatest evidence (MacKay's fixed point,
:func:`~consistid.identification.prior_weight.evidence_weight`), on the inertia fitted with the
Coulomb and viscous friction of every joint beside it, within the SDP's range
(:data:`~consistid.identification.sdp.EVIDENCE_RANGE` × the default weight): the same rule the
SDP uses, on the selection's own problem. Tests of significance still count the parameters the
*data* determine (the rank of their Gram matrix), not the prior.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.linalg

from ..robot.inertia import degenerate_bodies
from .candidates import Atom, EffectLibrary

#: Effects whose atoms are scored with the prior, and which bodies' parameters they change.
RIGID_EFFECTS = ("inertia", "payload")


def prior_curvature(library: EffectLibrary, atoms: Sequence[Atom], nominal: np.ndarray
                    ) -> np.ndarray | None:
    """``(P, P)`` prior curvature per unit weight on every atom's columns (module docstring;
    zero outside the ``inertia`` and ``payload`` columns), or ``None`` when no atom is rigid or
    a nominal body is not realisable (no log-det metric there: the final fit then has no prior
    either)."""
    from ..identification.priors import logdet_metric

    model = library.model
    sizes = [a.n_parameters for a in atoms]
    if not any(a.effect in RIGID_EFFECTS for a in atoms) or \
            degenerate_bodies(nominal, model.body_names):
        return None
    metrics = [logdet_metric(nominal[10 * b:10 * b + 10]) for b in range(model.n_bodies)]
    s_std = scipy.linalg.block_diag(*(w.T @ w for w in metrics))
    out = np.zeros((sum(sizes), sum(sizes)))
    o = 0
    for a, k in zip(atoms, sizes):
        block = slice(o, o + k)
        if a.effect == "inertia":
            b = library.base.matrix
            out[block, block] = np.linalg.inv(b @ np.linalg.solve(s_std, b.T))
        elif a.effect == "payload":
            out[block, block] = metrics[-1].T @ metrics[-1]
        o += k
    return out


def evidence_prior_weight(g: np.ndarray, c: np.ndarray, s: np.ndarray) -> float:
    """The prior weight ``γ`` of greatest evidence for the weighted least-squares problem of
    Gram matrix ``g`` and right-hand side ``c`` (``‖Aθ − z‖²`` with ``AᵀA = g``, ``Aᵀz = c``) and
    prior curvature ``s`` (prior mean 0: the nominal), within the SDP's range; computed on
    column-scaled coordinates (``θ = y / d``), where the answer is the same."""
    from ..identification.prior_weight import evidence_weight
    from ..identification.sdp import EVIDENCE_RANGE, default_prior_weight

    d = np.sqrt(np.clip(np.diag(g), 0, None))
    d[d == 0] = 1.0
    lam, v = np.linalg.eigh(g / np.outer(d, d))
    keep = lam > 1e-12 * max(lam[-1], 1e-300)
    a = np.sqrt(lam[keep])[:, None] * v[:, keep].T              # aᵀa = g (scaled)
    b = (v[:, keep].T @ (c / d)) / np.sqrt(lam[keep])          # aᵀb = c (scaled)
    default = default_prior_weight()
    lo, hi = EVIDENCE_RANGE
    gamma, _ = evidence_weight(a, s / np.outer(d, d), b, (lo * default, hi * default), default)
    return float(gamma)

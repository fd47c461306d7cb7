r"""The SDP's default prior on the per-joint terms (friction, offset): weak, in torque units.

The log-det prior holds the inertial directions the data leave free at the CAD bodies; nothing
held the per-joint columns. A joint that moves one way only has equal Coulomb and offset columns
(``sign(q̇) = 1 = `` the offset's signal on every sample), so the data fix ``f_c + f_o`` and
leave ``f_c − f_o`` to the solver: on a real 7-DoF arm it returned ``f_c = 859.5``,
``f_o = −859.7`` N·m and predicted reversed motion worse than the CAD model.

The default adds, in the same χ² units as the Fisher-weighted data term, the independent
Gaussian prior

.. math::  f_{c,j},\, f_{o,j} \sim \mathcal N(f^0, \bar\tau_j^2), \qquad
           f_{v,j} \sim \mathcal N(f_v^0, (\bar\tau_j / \bar v_j)^2)

centred on the prior vector's per-joint entries (0: the nominal model has no friction nor
offset, :func:`~consistid.identification.regressor.prior_vector`), ``τ̄_j`` joint
``j``'s effort limit and ``v̄_j`` its velocity limit: no friction or offset alone reaches the
actuator's torque (at one σ), or the joint could not move. Against data it is negligible (a
direction the data fix to ``σ_data`` moves by the share ``σ_data² / τ̄²`` towards the prior,
``10⁻⁸`` for ``σ_data = 0.01`` N·m and ``τ̄ = 87`` N·m); a direction the data leave free or
nearly so (``σ_data ≫ τ̄``) is decided by it. For a one-way joint it splits the seen constant
``c = f_c + f_o`` equally (the minimum of ``f_c² + f_o²``), so on reversed motion the friction
prediction ``−f_c + f_o = 0`` is the nominal model's: never worse than it, while forward motion
keeps the data's fit. A prior that preferred ``f_o = 0`` would do better when the offset is
small and worse (``2 f_c`` instead of ``f_c``) when it is not; the symmetric one is the minimax
choice against the nominal model. ``joint_prior=False`` switches it off; joints without a
finite effort (viscous: velocity) limit get no prior on those columns, and
``details["joint_prior"]`` says so.
"""

from __future__ import annotations

import numpy as np

from .regressor import RegressorSpec
from ..robot.model import RobotModel

__all__ = ["joint_prior_rows", "append_rows"]


def joint_prior_rows(model: RobotModel, spec: RegressorSpec, prior_vec: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, str]:
    """``(D, t, text)``: the prior as extra least-squares rows ``‖D θ − t‖²`` (``D`` (k, p),
    one row per prior column, ``1/std`` at it) and what it holds, for ``details``
    (module docstring). ``k = 0`` when no column has a finite limit to scale it."""
    n_in, p = model.n_inertial, prior_vec.size
    effort, velocity = model.limits.effort, model.limits.velocity
    rows, stds, held, skipped = [], [], [], []
    for c, (_, j, suffix) in enumerate(spec.columns):
        if suffix in ("fc", "fo"):
            std = effort[j]
        elif suffix == "fv":
            std = effort[j] / velocity[j]
        else:
            continue                                    # armature, position terms: not here
        name = f"{model.joint_names[j]}.{suffix}"
        if not (np.isfinite(std) and std > 0):
            skipped.append(name)
            continue
        rows.append(n_in + c)
        stds.append(std)
        held.append(name)
    d = np.zeros((len(rows), p))
    d[np.arange(len(rows)), rows] = 1.0 / np.asarray(stds, dtype=float)
    text = (f"Gaussian around 0 on {len(held)} column(s), σ = the effort limit "
            "(f_c, f_o; N·m) or effort/velocity limit (f_v)" if held else "none")
    if skipped:
        text += f"; none on {', '.join(skipped)} (no finite effort/velocity limit)"
    return d, d @ prior_vec, text


def append_rows(r: np.ndarray, z: np.ndarray, d: np.ndarray, t: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """``(R', z')`` square with ``‖R' θ − z'‖² = ‖R θ − z‖² + ‖D θ − t‖² − const`` (one QR of
    the stacked rows): the prior folded into the compressed data term."""
    if d.shape[0] == 0:
        return r, z
    q, r2 = np.linalg.qr(np.vstack([r, d]))
    return r2, q.T @ np.concatenate([z, t])

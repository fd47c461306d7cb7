r"""The log-Cholesky parameters of a rigid body: an unconstrained vector ``u ∈ ℝ¹⁰`` whose every
value is a physically consistent body, so that a refinement cannot leave the consistent set.

The pseudo-inertia ``J = [[Σ, h], [hᵀ, m]]``, ``Σ = ½ tr(I) 1 − I``, ``h = m c`` (Wensing, Kim,
Slotine 2017, doi:10.1109/LRA.2017.2729659) is ``J = U Uᵀ`` with ``U`` upper triangular and a
positive diagonal; ``u`` holds the logarithms of that diagonal and the six entries above it
(Rucker & Wensing 2022, "Smooth parameterization of rigid-body inertia",
doi:10.1109/LRA.2022.3144517, who also show the map is a diffeomorphism onto ``J ≻ 0``). Order:
``u = [ln U₀₀, ln U₁₁, ln U₂₂, ln U₃₃, U₀₁, U₀₂, U₀₃, U₁₂, U₁₃, U₂₃]``. The standard vector is
Pinocchio's ``[m, h_x, h_y, h_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz]`` about the joint frame.
"""

from __future__ import annotations

import numpy as np

_UPPER = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
_EXCHANGE = np.eye(4)[::-1]


def pseudo_inertia(pi: np.ndarray) -> np.ndarray:
    """``J`` (4, 4) of a standard 10-vector."""
    m, h = pi[0], pi[1:4]
    inertia = np.array([[pi[4], pi[5], pi[7]], [pi[5], pi[6], pi[8]], [pi[7], pi[8], pi[9]]])
    out = np.empty((4, 4))
    out[:3, :3] = 0.5 * np.trace(inertia) * np.eye(3) - inertia
    out[:3, 3] = out[3, :3] = h
    out[3, 3] = m
    return out


def to_log_cholesky(pi: np.ndarray, floor: float = 1e-9) -> np.ndarray:
    """``u`` of a consistent body; a body on the boundary (``J`` singular, e.g. a point mass)
    is first moved inside by raising ``J``'s smallest eigenvalues to ``floor · tr J``."""
    j = pseudo_inertia(np.asarray(pi, dtype=float))
    w, v = np.linalg.eigh(j)
    j = (v * np.maximum(w, floor * max(np.trace(j), 1e-12))) @ v.T
    lower = np.linalg.cholesky(_EXCHANGE @ j @ _EXCHANGE)
    upper = _EXCHANGE @ lower @ _EXCHANGE
    return np.concatenate([np.log(np.diag(upper)), [upper[a, b] for a, b in _UPPER]])


def from_log_cholesky(u: np.ndarray) -> np.ndarray:
    """The standard 10-vector of ``u`` (always consistent: ``J = U Uᵀ ≻ 0``)."""
    upper = np.diag(np.exp(u[:4]))
    for k, (a, b) in enumerate(_UPPER):
        upper[a, b] = u[4 + k]
    j = upper @ upper.T
    sigma = j[:3, :3]
    inertia = np.trace(sigma) * np.eye(3) - sigma
    return np.array([j[3, 3], *j[:3, 3], inertia[0, 0], inertia[0, 1], inertia[1, 1],
                     inertia[0, 2], inertia[1, 2], inertia[2, 2]])

r"""``ripple``: position-dependent torque ripple (cogging, gear-tooth or encoder eccentricity),
periodic in the joint angle: ``r_j = L[a sin(k q_j) + b cos(k q_j)]`` with integer ``k ≥ 2``
cycles per radian, seen at least twice over the joint's range of motion, found by a periodogram
search on the training residual (Lomb 1976, doi:10.1007/BF00648343, exact least squares per
``k``), and ``L`` the identity or, for low-pass filtered torques, the chain's filter at a cut-off
chosen from :data:`~consistid.diagnosis.effects.base.FILTER_CUTOFFS` and refined between its grid
neighbours: ``k q̇_j / 2π`` easily exceeds the cut-off. Order 2 thus needs a joint range of a
full revolution; over less, the data do not tell it from ``position`` plus ``offset``."""

from __future__ import annotations

import numpy as np

from ...errors import ModelError
from ..gapdata import GapData
from .base import Atom, Effect, EffectParameter, tune_cutoff


def ripple_order(data: GapData, residual: np.ndarray, joint: int,
                 orders: tuple[int, int] = (2, 400)) -> int | None:
    """The integer order ``k`` whose ``sin(k q_j), cos(k q_j)`` pair explains most of
    ``residual`` (a periodogram over ``k`` with exact least squares per ``k``); ``None`` when no
    order is resolvable at this sampling. ``orders``: (min, max) searched; min is raised so that
    the joint's range holds two periods, max lowered so that ``k·|q̇|·Δt < π/2``."""
    q = data.dataset.q[:, joint]
    dt = float(np.median(np.diff(data.dataset.t)))
    speed = float(np.percentile(np.abs(data.dataset.dq[:, joint]), 99))
    k_lo, k_hi = orders
    k_hi = min(k_hi, int(np.pi / (2 * max(speed, 1e-9) * dt)))
    span = float(np.ptp(q))
    k_lo = max(k_lo, int(np.ceil(2 * 2 * np.pi / max(span, 1e-12))))  # ≥ 2 periods seen
    if k_hi < k_lo:
        return None
    r = residual - residual.mean()
    n = q.size
    sum_r = float(r.sum())
    best_k, best = None, -np.inf
    # e^{ikq} for a block of 64 orders k = k₀ + m as e^{ik₀q}·e^{imq} (the table of e^{imq},
    # m < 64, made once): one complex product per entry instead of a sine and a cosine. The
    # centred sums of the 2×2 least squares per k follow from three sums over the samples,
    # Σe^{ikq}, Σr e^{ikq} and Σe^{2ikq}:  Σs² = n/2 − ½ Re Σe^{2ikq},  Σc² = n/2 + ½ Re Σe^{2ikq},
    # Σsc = ½ Im Σe^{2ikq}, each minus n × the product of the means; r·(s − s̄) = r·s − s̄ Σr.
    width = min(64, k_hi + 1 - k_lo)
    table = np.empty((n, width), dtype=complex)      # e^{imq}, m < width, by doubling:
    table[:, 0] = 1.0                                 # columns [h, 2h) = [0, h) · e^{ihq}
    h = 1
    while h < width:
        step = min(h, width - h)
        table[:, h:h + step] = table[:, :step] * np.exp(1j * h * q)[:, None]
        h += step
    for start in range(k_lo, k_hi + 1, 64):
        ks = np.arange(start, min(start + 64, k_hi + 1))
        e = np.exp(1j * start * q)[:, None] * table[:, :ks.size]
        mean = e.mean(axis=0)
        s_bar, c_bar = mean.imag, mean.real
        double = np.einsum("ij,ij->j", e, e)
        ss = 0.5 * n - 0.5 * double.real - n * s_bar ** 2
        cc = 0.5 * n + 0.5 * double.real - n * c_bar ** 2
        sc = 0.5 * double.imag - n * s_bar * c_bar
        proj = (r @ e.view(float)).reshape(ks.size, 2)   # (B, 2): r·cos kq, r·sin kq
        rc, rs = proj[:, 0] - c_bar * sum_r, proj[:, 1] - s_bar * sum_r
        det = ss * cc - sc ** 2
        ok = det > 1e-9 * ss * cc
        explained = np.where(ok, (cc * rs ** 2 - 2 * sc * rs * rc + ss * rc ** 2)
                             / np.where(ok, det, 1.0), -np.inf)
        i = int(np.argmax(explained))
        if explained[i] > best:
            best, best_k = float(explained[i]), int(ks[i])
    return best_k


class Ripple(Effect):
    name = "ripple"
    order = 100
    signature = "periodic in the joint angle (k cycles per radian)"
    equation = ("`L[a sin(k q_j) + b cos(k q_j)]`, integer `k ≥ 2` found by periodogram, at "
                "least two periods over the joint's range")
    unit = "N·m"
    row_only = True
    searched = True

    def atoms(self, library, tuning=None, residual=None) -> list[Atom]:
        if tuning is None or residual is None:
            raise ModelError("ripple atoms need tuning data and a residual")
        names = library.model.joint_names
        out = []
        for j in range(library.model.nv):
            k = ripple_order(tuning, residual[:, j], j, library.ripple_orders)
            if k is not None:
                atom = Atom(self.name, j, (f"{names[j]}.ripple_sin", f"{names[j]}.ripple_cos"),
                            (self.unit,) * 2, float(k), setting_name="k")
                out.append(tune_cutoff(self, library, tuning, residual[:, j], atom)[0])
        return out

    def unfiltered(self, library, atom, data) -> np.ndarray:
        phase = atom.setting * data.dataset.q[:, atom.joint]
        return np.column_stack([np.sin(phase), np.cos(phase)])

    def parameters(self, library, atom, theta, std, joint, fit) -> list[EffectParameter]:
        amp = float(np.hypot(*theta))
        amp_std = float(np.sqrt((theta[0] * std[0]) ** 2 + (theta[1] * std[1]) ** 2)
                        / max(amp, 1e-300))
        seen = (f", seen through a ≈{atom.cutoff:.3g} Hz low-pass" if np.isfinite(atom.cutoff)
                else "")
        return [EffectParameter(f"{joint} ripple amplitude (k = {atom.setting:g}/rad{seen})",
                                amp, amp_std, self.unit, joint, self.name)]


EFFECT = Ripple()

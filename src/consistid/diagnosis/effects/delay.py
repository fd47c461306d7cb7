r"""``delay``: the torque channel lags the position channel by ``d``:
``τ_meas(t) = τ(t − d)``, so ``r ≈ −d τ̇_nom`` (first order; :func:`consistid.diagnose` refines it
exactly, ``τ_nom(t − d) − τ_nom(t)``), in quadrature with the torque and growing with frequency.
Offered per joint and as one delay common to all channels.

Physical rules: ``d ≥ 0`` (a torque cannot be measured before it acts), and ``d`` above the
time-stamp resolution: a logger that averages torques over each sample interval ``Δt`` and
stamps the average at the interval's end shifts them by ``Δt/2`` (the mean of a signal over an
interval is its value at the centre, to second order), which is not a delay of the channel (the
loader's ``timestamp=`` option corrects it). A delay is named only when it exceeds that half
sample by :data:`HALF_SAMPLE_MARGIN` of it; a shift within it (either sign: a logger stamping
the interval's start leads by half a sample) that explains more than any effect is kept in the
diagnosis' fit as the logger's stamping (:meth:`Delay.stamping`), so that no effect stands in
for it, and reported in a note, not as a finding."""

from __future__ import annotations

import numpy as np

from .base import Atom, Effect, on_row

#: A delay must exceed half a sample interval by this fraction of it to be named.
HALF_SAMPLE_MARGIN = 0.1


class Delay(Effect):
    name = "delay"
    order = 80
    signature = "≈ −d·τ̇: in quadrature with the torque, grows with frequency"
    equation = "`τ_nom(t − d) − τ_nom(t)` (per joint or common)"
    unit = "s"
    suffix = "delay"
    wording = "delay"
    scope = "both"
    nonnegative = (0,)
    row_only = True

    def unphysical(self, atom, theta, resolution=None):
        why = super().unphysical(atom, theta, resolution)
        limit = 0.5 * (1 + HALF_SAMPLE_MARGIN) * resolution if resolution else 0.0
        if why is None and theta[0] < limit:
            return (f"its delay {1e3 * theta[0]:.3g} ms is within the time-stamp resolution "
                    f"(half a {1e3 * resolution:.3g} ms sample + {HALF_SAMPLE_MARGIN:.0%}): a "
                    "logger averaging over each interval shifts torques by half a sample; not "
                    "named a delay")
        return why

    def stamping(self, theta, resolution) -> bool:
        """A shift of either sign within half a sample (+ the margin): what a logger that
        averages each interval leaves when it stamps the interval's end (a lag) or start (a
        lead). The diagnosis keeps such a shift in its fit without naming it."""
        return bool(resolution) and abs(float(theta[0])) < 0.5 * (1 + HALF_SAMPLE_MARGIN) \
            * float(resolution)

    def atoms(self, library, tuning=None, residual=None) -> list[Atom]:
        return [Atom(self.name, None, ("delay",), ("s",)),
                *super().atoms(library, tuning, residual)]

    def columns(self, library, atom, data) -> np.ndarray:
        if atom.joint is None:
            return -data.tau_nom_derivatives[1][:, :, None]
        return on_row(data, atom.joint, self.row(library, atom, data))

    def row(self, library, atom, data) -> np.ndarray:
        return -data.tau_nom_derivatives[1][:, atom.joint]


EFFECT = Delay()

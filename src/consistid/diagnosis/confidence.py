r"""How much to trust one finding of a diagnosis: the evidence it carries and its label.

A finding (:class:`~consistid.diagnosis.diagnose.EffectFinding`) is labelled ``"high"``,
``"medium"`` or ``"low"`` from the evidence below, all of it read on the held-out data or from
the final fit (:class:`Evidence`):

* ``margin`` — ``1 − gain_runner_up / gain``: how much more of the held-out residual it explains
  than the best other candidate explaining the same residual (1: no rival);
* ``p_value`` — the held-out F-test when it entered the selection;
* ``z_min`` — its smallest per-joint parameter in standard deviations from zero (``inf`` for
  an arm-wide effect, whose base parameters are not judged one by one);
* ``worsened`` — it raised some joint's held-out RMS (arm-wide effects only: a per-joint atom
  that does is refused);
* ``excess_share`` — the fraction of what was above the noise floor on its joints that it
  removed, ``Σ(ρ_before² − ρ_after²) / Σ(ρ_before² − σ²)`` (held-out RMS ``ρ``, floor ``σ``);
* ``left_ratio`` — the largest held-out RMS over the floor left on its joints once every
  selected effect is in (the column the verdict judges): a joint still far above the floor
  holds something the effects do not describe, which may have lent the finding its gain;
* ``flagged`` — a joint of it is flagged or undetermined by the verdict.

The label rule and the table that argues it are in :func:`confidence_label` and
``benchmarks/diagnosis_confidence.py`` (calibrated on one half of a labelled simulation set,
reported on the other half).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

#: The labels, most trusted first.
LABELS = ("high", "medium", "low")
#: A runner-up within this fraction of the finding's held-out gain: both explain nearly as much.
CLOSE_MARGIN = 0.2
#: A parameter closer to zero than this many standard deviations is not determined by the data.
DETERMINED_Z = 2.0


@dataclass(frozen=True)
class Evidence:
    """What a finding's label is read from (see the module notes)."""

    name: str
    scope: str
    margin: float
    p_value: float
    z_min: float
    worsened: bool
    excess_share: float
    left_ratio: float
    flagged: bool
    total_shrink: float
    n_parameters: int

    @classmethod
    def of(cls, finding: Any, diag: Any) -> "Evidence":
        """The evidence of ``finding`` (an ``EffectFinding``) within its ``Diagnosis``."""
        names = list(diag.joint_names)
        idx = np.array([names.index(j) for j in finding.joints], dtype=int)
        floor = np.asarray(diag.noise_floor if diag.held_floor is None else diag.held_floor)
        z = [abs(p.value) / p.std for p in finding.parameters
             if finding.scope == "joint" and np.isfinite(p.std) and p.std > 0]
        before2 = np.asarray(finding.rms_before)[idx] ** 2
        after2 = np.asarray(finding.rms_after)[idx] ** 2
        excess = float(np.sum(np.maximum(before2 - floor[idx] ** 2, 0.0)))
        share = float(np.sum(before2 - after2)) / excess if excess > 0 else 0.0
        left = np.asarray(diag.left_to_noise)[idx]
        named = set(diag.remainder.flagged) | set(diag.remainder.undetermined) \
            if diag.remainder is not None else set()
        return cls(finding.name, finding.scope, float(finding.margin),
                   float(finding.p_value), float(min(z)) if z else float("inf"),
                   bool(finding.worsened), share,
                   float(np.max(left)) if left.size else float("nan"),
                   bool(named & set(finding.joints)), float(finding.total_shrink),
                   int(finding.n_parameters))

    def as_dict(self) -> dict:
        """Plain numbers (JSON: ``inf`` as a string)."""
        return {k: (str(v) if isinstance(v, float) and not np.isfinite(v) else v)
                for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, d: dict) -> "Evidence":
        """Back from :meth:`as_dict` (extra keys ignored)."""
        kw = {k: d[k] for k in cls.__dataclass_fields__}
        return cls(**{k: float(v) if isinstance(v, str) and k not in ("name", "scope") else v
                      for k, v in kw.items()})


def confidence_label(ev: Evidence) -> str:
    """``"high"`` (margin ≥ 0.5 over the runner-up, p < 1e-6 and its parameters determined),
    ``"low"`` (margin < 0.2: the runner-up explains nearly as much; or it makes some joint
    worse on the held-out data) or ``"medium"``."""
    if ev.margin < CLOSE_MARGIN or ev.worsened:
        return "low"
    return ("high" if ev.margin >= 0.5 and ev.p_value < 1e-6 and ev.z_min >= DETERMINED_Z
            else "medium")

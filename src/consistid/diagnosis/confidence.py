r"""How much to trust one finding of a diagnosis: the evidence it carries and its label.

A finding (:class:`~consistid.diagnosis.diagnose.EffectFinding`) is labelled ``"high"``,
``"medium"`` or ``"low"`` from the evidence below, all of it read on the held-out data or from
the final fit (:class:`Evidence`):

* ``margin`` — ``1 − gain_runner_up / gain``: how much more of the held-out residual it explains
  than the best other candidate explaining the same residual (1: no rival), both gains in the
  floors' units (``Σ_j ΔSSE_j / σ_j²``, whatever weights a rigid body was fitted with);
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
* ``flagged`` — a joint of it is flagged or undetermined by the verdict
  (``EffectFinding.unexplained``).

The label rule and the table that argues it are in :func:`confidence_label` and
``benchmarks/diagnosis_confidence.py`` (calibrated on one half of a labelled simulation set,
reported on the other half).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

#: The labels, most trusted first.
LABELS = ("high", "medium", "low")
#: "high" needs the runner-up to explain at most half as much of the held-out residual.
RIVAL_MARGIN = 0.5
#: "high" needs the held-out F-test at entry below this p-value.
HIGH_P = 1e-6
#: A parameter closer to zero than this many standard deviations is not determined by the data.
DETERMINED_Z = 2.0


@dataclass(frozen=True)
class Evidence:
    """What a finding's label is read from (see the module notes); ``excess_share``,
    ``left_ratio``, ``total_shrink`` and ``n_parameters`` are reported beside it for the
    calibration (``nan`` without the diagnosis)."""

    name: str
    scope: str
    margin: float
    p_value: float
    z_min: float
    worsened: bool
    flagged: bool
    excess_share: float = float("nan")
    left_ratio: float = float("nan")
    total_shrink: float = float("nan")
    n_parameters: int = 0

    @classmethod
    def of(cls, finding: Any, diag: Any = None) -> "Evidence":
        """The evidence of ``finding`` (an ``EffectFinding``), with the calibration's extra
        features when its ``Diagnosis`` is given."""
        z = [abs(p.value) / p.std for p in finding.parameters
             if finding.scope == "joint" and np.isfinite(p.std) and p.std > 0]
        core = cls(finding.name, finding.scope, float(finding.margin), float(finding.p_value),
                   float(min(z)) if z else float("inf"), bool(finding.worsened),
                   bool(finding.unexplained), total_shrink=float(finding.total_shrink),
                   n_parameters=int(finding.n_parameters))
        if diag is None:
            return core
        names = list(diag.joint_names)
        idx = np.array([names.index(j) for j in finding.joints], dtype=int)
        floor = np.asarray(diag.noise_floor if diag.held_floor is None else diag.held_floor)
        before2 = np.asarray(finding.rms_before)[idx] ** 2
        after2 = np.asarray(finding.rms_after)[idx] ** 2
        excess = float(np.sum(np.maximum(before2 - floor[idx] ** 2, 0.0)))
        left = np.asarray(diag.left_to_noise)[idx]
        return replace(core, excess_share=float(np.sum(before2 - after2)) / excess
                       if excess > 0 else 0.0,
                       left_ratio=float(np.max(left)) if left.size else float("nan"))

    def as_dict(self) -> dict:
        """Plain numbers (JSON: ``inf`` and ``nan`` as strings)."""
        return {k: (str(v) if isinstance(v, float) and not np.isfinite(v) else v)
                for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, d: dict) -> "Evidence":
        """Back from :meth:`as_dict` (extra keys ignored)."""
        kw = {k: d[k] for k in cls.__dataclass_fields__ if k in d}
        return cls(**{k: float(v) if isinstance(v, str) and k not in ("name", "scope") else v
                      for k, v in kw.items()})


def confidence_label(ev: Evidence) -> str:
    """The label of a finding from its evidence.

    * ``"low"`` — the data do not support it on their own: a per-joint parameter within
      :data:`DETERMINED_Z` σ of zero (the fit cannot tell it from no effect), a runner-up that
      explains more of the held-out residual but was refused (``margin < 0``), or it makes some
      joint worse on the held-out data (``worsened``).
    * ``"high"`` — none of that, the runner-up explains at most half as much
      (``margin ≥`` :data:`RIVAL_MARGIN`), the held-out F-test ``p <`` :data:`HIGH_P`, and
      the verdict leaves none of its joints flagged or undetermined (a joint still above its
      floor holds something the effects do not describe, which may have lent it its gain).
    * ``"medium"`` — otherwise (typically a rival that explains part of the same residual,
      such as viscous beside Coulomb friction on a joint that has both).

    Calibrated in ``benchmarks/diagnosis_confidence.py`` (the docs' calibration table): the
    old rule called a finding "low" for a close runner-up (margin < 0.2), which on friction
    present on every joint was nearly always right, while undetermined Stribeck humps
    (Δf within 1 σ of 0) were "medium".
    """
    if ev.worsened or ev.z_min < DETERMINED_Z or ev.margin < 0:
        return "low"
    if ev.margin >= RIVAL_MARGIN and ev.p_value < HIGH_P and not ev.flagged:
        return "high"
    return "medium"

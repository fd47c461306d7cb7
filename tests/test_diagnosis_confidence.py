"""The confidence label of a finding (issue 27) is read from its evidence: a parameter the data
cannot tell from zero, a refused rival that explains more, or a joint made worse make it "low"
whatever else it has; "high" needs a clear margin, a small p-value and none of its joints left
unexplained by the verdict (benchmarks/diagnosis_confidence.py calibrates the rule)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from consistid.diagnosis.confidence import (DETERMINED_Z, HIGH_P, RIVAL_MARGIN, Evidence,
                                            confidence_label)
from consistid.diagnosis.diagnose import EffectFinding
from consistid.diagnosis.effects import EffectParameter


def _finding(value: float, std: float, margin: float, p: float, worsened: bool = False,
             unexplained: tuple[str, ...] = ()) -> EffectFinding:
    before, after = np.array([1.0, 0.5]), np.array([0.2, 0.5])
    return EffectFinding(
        name="viscous", joints=("j1",), scope="joint", rms_before=before, rms_after=after,
        shrink=1 - after / before, total_shrink=0.5,
        parameters=(EffectParameter("j1.fv", value, std, "N·m·s/rad", "j1", "viscous"),),
        alternatives=(), n_parameters=1, delta_bic=-50.0, p_value=p, signature="",
        runner_up="offset (j1)" if margin < 1 else "", margin=margin,
        worsened=("j2",) if worsened else (), unexplained=unexplained)


@settings(max_examples=200, deadline=None)
@given(value=st.floats(-10, 10), std=st.floats(1e-3, 5), margin=st.floats(-1, 1),
       p=st.floats(0, 1), worsened=st.booleans(), unexplained=st.booleans())
def test_the_label_follows_its_evidence(value, std, margin, p, worsened, unexplained):
    """Over random evidence: "low" exactly when the parameter is within 2σ of zero, a refused
    rival explains more (margin < 0) or a joint is made worse; "high" exactly when none of that
    and margin ≥ 0.5, p < 1e-6 and no joint of it left unexplained; the finding's
    ``confidence`` is the label of its evidence."""
    f = _finding(value, std, margin, p, worsened, ("j1",) if unexplained else ())
    z = abs(value) / std
    low = z < DETERMINED_Z or margin < 0 or worsened
    high = not low and margin >= RIVAL_MARGIN and p < HIGH_P and not unexplained
    assert f.confidence == ("low" if low else "high" if high else "medium")
    ev = Evidence.of(f)
    assert ev.z_min == z and ev.flagged == unexplained
    assert confidence_label(Evidence.from_dict(ev.as_dict())) == f.confidence


def test_a_gain_of_one_sigma_is_low_whatever_its_margin():
    """The issue's example: a gain 1.81 ± 7.6 with no rival and p = 1e-30 is "low" (it was
    "medium" or, before the determined rule, "high"); the same gain at 1.81 ± 0.1 is high, and
    medium once the verdict leaves its joint above the floor or a close rival explains part."""
    assert _finding(1.81, 7.6, 1.0, 1e-30).confidence == "low"
    assert _finding(1.81, 0.1, 1.0, 1e-30).confidence == "high"
    assert _finding(1.81, 0.1, 1.0, 1e-30, unexplained=("j1",)).confidence == "medium"
    assert _finding(1.81, 0.1, 0.1, 1e-30).confidence == "medium"
    assert _finding(1.81, 0.1, -0.1, 1e-30).confidence == "low"

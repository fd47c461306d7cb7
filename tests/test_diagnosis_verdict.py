"""The verdict names every joint its held-out table leaves above the flag (issue 27): flagged or
undetermined, both when both occur, and "explained" only with none above it.

Constructed cases: remainders of a known RMS per joint (held-out ratio drawn by hypothesis,
floors unseen on some joints, relevance that tolerates some excesses) through
:func:`~consistid.diagnosis.remainder.analyse_remainder`, and end to end a 2R arm whose one
joint carries a torque outside the candidate list and whose other carries one within the signal
chain's tolerance (``diagnose``: the verdict against ``left_to_noise``)."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from consistid.data.dataset import Dataset
from consistid.diagnosis.candidates import GapData
from consistid.diagnosis.diagnose import diagnose
from consistid.diagnosis.remainder import REMAINDER_RATIO, analyse_remainder
from consistid.diagnosis.verdict import verdict_head

N = 2000
DT = 0.002


def _log(model) -> Dataset:
    t = np.arange(N) * DT
    w = np.array([1.3, 0.7])
    q = np.column_stack([np.sin(w[0] * t), 0.8 * np.cos(w[1] * t)])
    dq = np.column_stack([w[0] * np.cos(w[0] * t), -0.8 * w[1] * np.sin(w[1] * t)])
    ddq = np.column_stack([-w[0] ** 2 * np.sin(w[0] * t), -0.8 * w[1] ** 2 * np.cos(w[1] * t)])
    return Dataset(t, q, dq, ddq, model.rnea(q, dq, ddq))


def _named(verdict: str) -> tuple[set[str], set[str]]:
    """The joints the verdict's head names as a remainder and as undetermined."""
    head = verdict.split(":")[0]
    out = {"remainder": set(), "undetermined": set()}
    for part in head.split(";"):
        kind, _, joints = part.strip().partition(" on ")
        if kind in out:
            out[kind] |= set(re.findall(r"[\w.-]+", joints))
    return out["remainder"], out["undetermined"]


def check_verdict_agrees_with_the_table(verdict: str, names, judged, unseen=()) -> None:
    """Every joint above ``REMAINDER_RATIO`` in ``judged`` (the held-out column the verdict
    judges) or with an unseen floor is named once, and "explained" stands only with none."""
    flagged, undetermined = _named(verdict)
    above = {n for n, r in zip(names, judged) if r > REMAINDER_RATIO} | set(unseen)
    assert above <= flagged | undetermined, (verdict, judged)
    assert not flagged & undetermined, verdict
    assert (flagged | undetermined) <= set(names), verdict
    assert verdict.startswith("explained") == (not flagged | undetermined), (verdict, judged)


@settings(max_examples=60, deadline=None)
@given(ratios=st.lists(st.floats(0.6, 6.0), min_size=2, max_size=2),
       seen=st.lists(st.booleans(), min_size=2, max_size=2),
       relevance=st.sampled_from([1e-4, 1.0]), seed=st.integers(0, 2 ** 16))
def test_the_verdict_names_every_joint_the_held_out_table_leaves_above_the_flag(
        planar_2r, ratios, seen, relevance, seed):
    """A remainder of RMS ``ratio × floor`` per joint (held-out and judged alike), floors unseen
    on some joints, a relevance that tolerates every excess (1.0) or none (1e-4): every joint
    above 1.5 × its floor is named, as a remainder when relevant, undetermined when tolerated;
    the short verdict (``Diagnosis.verdict``) is the long one's head."""
    # exactly at the flag's ratio, round-off of ratio × floor / floor decides either way
    assume(all(abs(r - REMAINDER_RATIO) > 1e-9 for r in ratios))
    data = GapData(planar_2r, _log(planar_2r), planar_2r.prior_parameters)
    floor = np.array([0.02, 0.05])
    e = np.random.default_rng(seed).standard_normal((N, 2))
    e *= np.asarray(ratios) * floor / np.sqrt(np.mean(e ** 2, axis=0))
    held = np.asarray(ratios) * floor
    rem = analyse_remainder(data, e, floor, np.ones(2), np.array([0.0, 5.0, 50.0, 250.0]),
                            relevance=relevance, reliable=np.asarray(seen), held_out=held)
    names = planar_2r.joint_names
    judged = [j.held_ratio for j in rem.joints]
    np.testing.assert_allclose(judged, ratios)
    unseen = [n for n, s in zip(names, seen) if not s]
    check_verdict_agrees_with_the_table(rem.verdict, names, judged, unseen)
    assert rem.verdict.startswith(verdict_head(rem.flagged, rem.undetermined) + ":")
    flagged, undetermined = _named(rem.verdict)
    above = {n for n, r, s in zip(names, ratios, seen) if r > REMAINDER_RATIO and s}
    assert flagged == (above if relevance < 1 else set())
    if flagged and undetermined:                  # the case the old verdict got wrong
        assert "; undetermined on" in rem.verdict


def test_verdict_head_names_both_states():
    assert verdict_head((), ()) == "explained"
    assert verdict_head(("a",), ()) == "remainder on a"
    assert verdict_head((), ("b", "c")) == "undetermined on b, c"
    assert verdict_head(("a",), ("b",)) == "remainder on a; undetermined on b"


def test_flagged_and_undetermined_joints_both_in_diagnose_verdict(planar_2r):
    """End to end, σ given (1 mN·m): joint 1 carries a dead-zone-like torque outside the
    candidate list (0.5 N·m, flagged); joint 2 carries a slow torque 4× the floor yet below
    0.3 % of its torque RMS (undetermined). The verdict names both, and agrees with
    ``left_to_noise``; the check on the old wording (flagged joint only) fails."""
    ds = _log(planar_2r)
    rng = np.random.default_rng(3)
    sigma = 1e-3
    scale = np.sqrt(np.mean(ds.tau[:, 1] ** 2))
    extra = np.column_stack([0.5 * np.clip(np.sin(7 * ds.q[:, 0]), -0.3, 0.3) / 0.3,
                             0.002 * scale * np.sin(2 * np.pi * 0.13 * ds.t)])
    tau = ds.tau + extra + sigma * rng.standard_normal(ds.tau.shape)
    ds = Dataset(ds.t, ds.q, ds.dq, ds.ddq, tau)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        diag = diagnose(planar_2r, ds, sigma=sigma, effects=("viscous", "offset"))
    names = planar_2r.joint_names
    assert diag.remainder.flagged == (names[0],), diag.summary()
    assert diag.remainder.undetermined == (names[1],), diag.summary()
    assert diag.verdict == f"remainder on {names[0]}; undetermined on {names[1]}"
    check_verdict_agrees_with_the_table(diag.remainder.verdict, names, diag.left_to_noise)
    check_verdict_agrees_with_the_table(diag.verdict, names, diag.left_to_noise)
    with pytest.raises(AssertionError):
        check_verdict_agrees_with_the_table(f"remainder on {names[0]}", names,
                                            diag.left_to_noise)

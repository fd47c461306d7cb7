"""Dry friction at rest seen through the signal chain's low-pass (issue 13): the held torque is
set-valued (any ``f ∈ [−f_c, f_c]``), the torque channel holds it filtered. A joint whose
friction obeys that law is explained; stiction beyond the cone or a torque pulse as the joint
breaks away (not in the law) still leaves a remainder. Synthetic single-joint logs with a known
truth: the raw friction is built sample by sample and filtered with the chain's own
:func:`~consistid.data.signals.lowpass`, the dataset's velocity is the filtered one, as the
chain's."""

from __future__ import annotations

import numpy as np
import pytest

from consistid.data.dataset import Dataset
from consistid.data.signals import lowpass
from consistid.diagnosis.candidates import GapData
from consistid.diagnosis.remainder import (
    REMAINDER_RATIO,
    dry_friction_through_filter,
    standstill_mask,
)

RATE = 200.0
CUTOFF = 5.0          # the chain's low-pass on q and τ (Hz)
FC = 1.0              # Coulomb friction, N·m
NOISE = 0.02          # torque noise after the filter, N·m
N = 4000              # 20 s
EDGE = 200            # samples left out at each end (the filter's padding guesses there)


def _motion() -> tuple[np.ndarray, np.ndarray]:
    """Raw velocity that stops for ~0.6 s at each of its reversals (every 2.5 s), and where it
    is exactly at rest."""
    t = np.arange(N) / RATE
    s = np.sin(2 * np.pi * 0.2 * t)
    v = np.sign(s) * np.maximum(np.abs(s) - 0.3, 0.0)
    return v, v == 0


def _judge(planar_2r, raw_friction: np.ndarray, seed: int = 0, viscous: float | None = None
           ) -> tuple[float, float, float]:
    """The remainder's RMS over the noise after :func:`dry_friction_through_filter` (the fit
    having seen ``0.9 f_c sign(q̇)`` through a 3 × lower cut-off, as a tuned atom does), the cone
    it was judged against, and the RMS over the noise of the point-valued law with the true
    ``f_c`` through the true filter. ``viscous``: the fit also selected viscous friction
    ``f_v q̇`` with this ``f_v`` (on the filtered velocity), refitted beside the dry friction."""
    v, _ = _motion()
    t = np.arange(N) / RATE
    rng = np.random.default_rng(seed)
    tau = lowpass(raw_friction, CUTOFF, RATE) + NOISE * rng.standard_normal(N)
    dq = np.column_stack([lowpass(v, CUTOFF, RATE), np.zeros(N)])
    q = np.column_stack([np.cumsum(v) / RATE, np.zeros(N)])
    ds = Dataset(t, q, dq, np.zeros((N, 2)), np.column_stack([tau, np.zeros(N)]))
    data = GapData(planar_2r, ds, planar_2r.prior_parameters)
    law = np.sign(dq[:, 0])
    dry = lowpass(0.9 * FC * law, CUTOFF / 3, RATE)
    known = np.ones(N, dtype=bool)
    known[:EDGE] = known[-EDGE:] = False
    if viscous is None:
        left, cone = dry_friction_through_filter(data, 0, tau - dry, dry, [law], FC, CUTOFF,
                                                 known)
    else:
        fitted = dry + viscous * dq[:, 0]
        left, cone = dry_friction_through_filter(data, 0, tau - fitted, fitted, [law], FC,
                                                 CUTOFF, known, viscous=[dq[:, 0]])
    point = tau - lowpass(FC * law, CUTOFF, RATE)

    def ratio(e: np.ndarray) -> float:
        return float(np.sqrt(np.mean(e[known] ** 2)) / NOISE)

    return ratio(left), cone, ratio(point)


def test_rest_from_the_filtered_velocity_holds_every_sample_at_rest():
    """The velocity the chain filters like the torque marks every raw sample at rest."""
    v, rest = _motion()
    marked = standstill_mask(lowpass(v, CUTOFF, RATE)[:, None])[:, 0]
    assert rest.any() and not (rest & ~marked).any()


def test_filtered_set_valued_friction_is_explained(planar_2r):
    """Held torques drawn anywhere in the cone, sample by sample: the filtered log is explained
    to the noise (the held samples' freedom absorbs a little of it), and the cone is the true
    ``f_c`` (the moving amplitude fitted again, not the fit's 0.9 ``f_c``). The point-valued law
    with the true ``f_c`` through the true filter leaves many times the noise."""
    v, rest = _motion()
    held = np.random.default_rng(1).uniform(-FC, FC, N)
    ratio, cone, point = _judge(planar_2r, np.where(rest, held, FC * np.sign(v)))
    assert ratio < 1.1
    assert cone == pytest.approx(FC, rel=0.02)
    assert point > 5.0


@pytest.mark.parametrize("level", [0.9, 1.1, 1.4])
def test_a_held_torque_beyond_the_cone_is_flagged(planar_2r, level):
    """Stiction: the joint held with a constant ``level × f_c`` over each stop (sign alternating
    between stops). Within the cone (0.9) it is explained; beyond it (1.1, 1.4), no held torque
    within ±f_c gives what the filter shows in the middle of a stop: a remainder."""
    v, rest = _motion()
    stop = np.cumsum(np.r_[0, np.diff(rest.astype(int)) != 0])
    sign = np.where(stop // 2 % 2 == 0, 1.0, -1.0)
    ratio, _, _ = _judge(planar_2r, np.where(rest, level * FC * sign, FC * np.sign(v)))
    if level <= 1:
        assert ratio < 1.1
    else:
        assert ratio > REMAINDER_RATIO


def test_a_breakaway_pulse_near_standstill_is_flagged(planar_2r):
    """A torque pulse of 0.3 ``f_c`` for 0.1 s as the joint leaves each stop (moving samples,
    next to the held ones; not the Coulomb law): the held torques cannot take it up, and it
    stays a remainder."""
    v, rest = _motion()
    pulse = np.zeros(N)
    for k in np.flatnonzero(rest[:-1] & ~rest[1:]) + 1:
        pulse[k:k + 20] = 0.3 * FC * np.sign(v[min(k + 1, N - 1)])
    held = np.random.default_rng(1).uniform(-FC, FC, N)
    ratio, _, _ = _judge(planar_2r, np.where(rest, held, FC * np.sign(v)) + pulse)
    assert ratio > REMAINDER_RATIO


@pytest.mark.parametrize("growth", [1.5, 2.0])
def test_a_friction_grown_beyond_the_cone_is_flagged(planar_2r, growth):
    """The moving friction grew to 1.5 or 2 × the fitted static friction (held-out data against
    the fit): the refitted amplitude may not exceed the cone (dynamic friction ≤ static), so
    what it cannot take up stays a remainder."""
    v, rest = _motion()
    held = np.random.default_rng(1).uniform(-FC, FC, N)
    ratio, cone, _ = _judge(planar_2r, np.where(rest, held, growth * FC * np.sign(v)))
    assert ratio > REMAINDER_RATIO and cone <= FC


FV = 0.5              # viscous friction, N·m·s/rad


@pytest.mark.parametrize("fitted", [0.6 * FV, FV, 1.4 * FV])
def test_a_biased_viscous_fit_beside_set_valued_friction_is_explained(planar_2r, fitted):
    """Coulomb and viscous friction, held torques anywhere in the cone at rest: the point-valued
    fit (which saw the held torques) got ``f_v`` wrong by up to 40 %. Refitted beside the dry
    amplitude the law is explained to the noise and the cone is the true ``f_c``; the dry
    amplitude alone (a step, bounded by the cone) leaves the error in ``f_v q̇`` on every moving
    sample: 4.7 × the noise for 0.6 ``f_v``, 1.9 × (cone 0.90 ``f_c``) for 1.4 ``f_v``."""
    v, rest = _motion()
    held = np.random.default_rng(1).uniform(-FC, FC, N)
    raw = np.where(rest, held, FC * np.sign(v) + FV * v)
    ratio, cone, _ = _judge(planar_2r, raw, viscous=fitted)
    assert ratio < 1.1
    assert cone == pytest.approx(FC, rel=0.02)


@pytest.mark.parametrize("growth", [1.5, 2.0])
def test_a_friction_grown_beyond_the_cone_is_flagged_with_viscous_refitted(planar_2r, growth):
    """As above with viscous friction selected and refitted too: a line through the origin
    cannot take up a Coulomb step grown beyond the cone either, so it stays a remainder."""
    v, rest = _motion()
    held = np.random.default_rng(1).uniform(-FC, FC, N)
    raw = np.where(rest, held, growth * FC * np.sign(v) + FV * v)
    ratio, cone, _ = _judge(planar_2r, raw, viscous=FV)
    assert ratio > REMAINDER_RATIO and cone <= FC

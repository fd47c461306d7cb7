"""The diagnosis's fast paths give the numbers of the direct computations they replace: the
Butterworth design against ``scipy.signal.butter`` (bit for bit), filtering columns together
against one at a time (bit for bit), the angle-addition ripple periodogram against least squares
per order, the batched cut-off tuning against a known cut-off, the mass matrix of the RNEA
derivatives against ``pinocchio.crba``, and the segment plan against the segment labels."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import scipy.signal
from hypothesis import given, settings
from hypothesis import strategies as st

from consistid.data.dataset import Dataset
from consistid.data.signals import lowpass
from consistid.diagnosis.candidates import Atom, EffectLibrary, GapData
from consistid.diagnosis.effects.base import tune_cutoff, tune_cutoffs
from consistid.diagnosis.effects.coulomb import EFFECT as COULOMB
from consistid.diagnosis.effects.ripple import ripple_order
from consistid.diagnosis.gapdata import lowpass_segments, segments
from consistid.simulate import excitation_run

RATE = 500.0


@settings(max_examples=200, deadline=None)
@given(order=st.integers(1, 8), rate=st.floats(50.0, 5000.0), fraction=st.floats(1e-3, 0.499),
       n=st.integers(1, 400), columns=st.sampled_from([None, 1, 3]), seed=st.integers(0, 99))
def test_lowpass_is_scipys_sosfiltfilt_of_butter_bit_for_bit(order, rate, fraction, n, columns,
                                                             seed):
    """The chain's low-pass (its own Butterworth pairing and cached initial conditions) against
    ``scipy.signal.sosfiltfilt`` of ``scipy.signal.butter``'s sections with the same padding."""
    rng = np.random.default_rng(seed)
    x = rng.standard_normal(n if columns is None else (n, columns)).cumsum(axis=0)
    cutoff = fraction * rate
    pad = min(int(np.ceil(6.0 * rate / cutoff)), n - 1)
    sos = scipy.signal.butter(order, cutoff, fs=rate, output="sos")
    expected = scipy.signal.sosfiltfilt(sos, x, axis=0, padlen=pad)
    assert np.array_equal(lowpass(x, cutoff, rate, order), expected)


def _jittered(n_segments: int, n: int, jitter: bool, seed: int) -> Dataset:
    rng = np.random.default_rng(seed)
    parts = []
    for _ in range(n_segments):
        steps = np.full(n - 1, 1.0 / RATE)
        if jitter:
            steps *= rng.uniform(0.7, 1.3, n - 1)
        t = np.concatenate([[0.0], np.cumsum(steps)])
        q = rng.standard_normal((n, 7)).cumsum(axis=0) * 1e-3
        parts.append(Dataset(t=t, q=q, dq=rng.standard_normal((n, 7)),
                             ddq=np.zeros((n, 7)), tau=np.zeros((n, 7))))
    return Dataset.concatenate(parts)


@settings(max_examples=15, deadline=None)
@given(n_segments=st.integers(1, 3), jitter=st.booleans(), seed=st.integers(0, 1000),
       cutoff=st.floats(2.0, 240.0))
def test_filtering_columns_together_equals_one_at_a_time(n_segments, jitter, seed, cutoff):
    data = _jittered(n_segments, 600, jitter, seed)
    x = np.random.default_rng(seed).standard_normal((data.n_samples, 5))
    together = lowpass_segments(data, x, cutoff, segments(data))
    for k in range(5):
        assert np.array_equal(together[:, k], lowpass_segments(data, x[:, k], cutoff))
    # and on each segment it is the chain's low-pass at the segment's rate (uniform steps)
    if not jitter and cutoff < 0.45 * RATE:
        first = data.segment == 0
        rate = 1.0 / np.median(np.diff(data.t[first]))
        assert np.array_equal(together[first], lowpass(x[first], cutoff, rate))


def test_segment_plan_follows_the_labels():
    t = np.arange(10) / RATE
    data = Dataset(t=np.concatenate([t, t]), q=np.zeros((20, 7)), dq=np.zeros((20, 7)),
                   ddq=np.zeros((20, 7)), tau=np.zeros((20, 7)),
                   segment=np.array([1, 0] * 10))
    plan = segments(data)
    assert [np.asarray(s.index).tolist() for s in plan] == [list(range(1, 20, 2)),
                                                            list(range(0, 20, 2))]
    contiguous = _jittered(2, 50, True, 0)
    plan = segments(contiguous)
    assert [s.index for s in plan] == [slice(0, 50), slice(50, 100)]
    assert [s.uniform for s in plan] == [False, False]
    assert segments(_jittered(1, 50, False, 0))[0].uniform
    assert np.isclose(plan[0].step, np.median(np.diff(contiguous.t[:50])))


def test_ripple_periodogram_is_least_squares_per_order(panda):
    """The order the angle-addition periodogram picks explains as much as the best order found
    by ``numpy.linalg.lstsq`` on ``[sin kq, cos kq, 1]`` for every k, and is the true one."""
    rng = np.random.default_rng(3)
    n = 6000
    t = np.arange(n) / RATE
    q = np.zeros((n, 7))
    q[:, 2] = 2.5 * np.sin(2 * np.pi * 0.2 * t) + 0.3 * np.sin(2 * np.pi * 0.7 * t)
    dq = np.gradient(q, t, axis=0)
    data = Dataset(t=t, q=q, dq=dq, ddq=np.zeros_like(q), tau=np.zeros_like(q))
    gap = GapData(panda, data, panda.prior_parameters)
    k_true = 37
    r = 0.4 * np.sin(k_true * q[:, 2] + 0.3) + 0.2 * rng.standard_normal(n)
    k = ripple_order(gap, r, 2, (2, 200))
    assert k == k_true

    def explained(order: int) -> float:
        a = np.column_stack([np.sin(order * q[:, 2]), np.cos(order * q[:, 2]), np.ones(n)])
        coef = np.linalg.lstsq(a, r, rcond=None)[0]
        return float(np.sum((a @ coef - r.mean()) ** 2))

    speed = np.percentile(np.abs(dq[:, 2]), 99)
    k_hi = min(200, int(np.pi / (2 * speed / RATE)))
    k_lo = int(np.ceil(4 * np.pi / np.ptp(q[:, 2])))
    best = max(range(k_lo, k_hi + 1), key=explained)
    assert k == best


def test_batched_cutoff_tuning_finds_the_filter_and_equals_one_at_a_time(panda):
    """A Coulomb step seen through the chain's low-pass at 9 Hz (between the grid's 8 and 12 Hz):
    the tuning refines the cut-off to it; tuning several speeds together gives each the result
    of tuning it alone."""
    run = excitation_run(panda, duration=6.0, rate=RATE, torque_noise=0.0, seed=5).dataset
    gap = GapData(panda, run, panda.prior_parameters)
    lib = EffectLibrary(panda, ("coulomb",))
    j = 3
    step = np.sign(run.dq[:, j])
    r = 1.2 * lowpass(step, 9.0, RATE) + 0.01 * np.random.default_rng(0).standard_normal(
        run.n_samples)
    atoms = [Atom("coulomb", j, ("fc",), ("N·m",), setting=v) for v in (0.0, 0.01, 0.05)]
    together = tune_cutoffs(COULOMB, lib, gap, r, atoms)
    alone = [tune_cutoff(COULOMB, lib, gap, r, a) for a in atoms]
    assert [(a.cutoff, s) for a, s in together] == [(a.cutoff, s) for a, s in alone]
    assert abs(together[0][0].cutoff / 9.0 - 1) < 0.02
    assert together[0][1] > max(s for _, s in together[1:])   # the sign law fits best
    tuned = COULOMB.tune(lib, gap, r, atoms[0])
    assert tuned.setting == 0.0 and tuned.cutoff == together[0][0].cutoff


def test_rnea_derivatives_mass_matrix_is_crba(panda):
    run = excitation_run(panda, duration=0.2, rate=RATE, torque_noise=0.0, seed=2).dataset
    gap = GapData(panda, run, panda.prior_parameters)
    d_q, d_v, mass = gap.rnea_derivatives
    m = panda.with_parameters(panda.prior_parameters).pin_model
    m.armature[:] = 0.0
    data = m.createData()
    for k in (0, 17, run.n_samples - 1):
        full = pin.crba(m, data, run.q[k])
        full = np.triu(full) + np.triu(full, 1).T
        assert np.allclose(mass[k], full, rtol=0, atol=1e-12)
        assert np.array_equal(mass[k], mass[k].T)
        dq_ref, dv_ref, _ = pin.computeRNEADerivatives(m, data, run.q[k], run.dq[k], run.ddq[k])
        assert np.array_equal(d_q[k], dq_ref) and np.array_equal(d_v[k], dv_ref)


def test_gravity_torques_by_rnea_equal_the_regressor(panda):
    """``GapData.gravity``/``tilt_gravity`` (Pinocchio's RNEA at rest with the nominal inertias)
    against the regressor at rest times the nominal parameters; a nominal body without mass takes
    the regressor path itself."""
    from consistid.diagnosis.gapdata import tilt_directions
    from consistid.identification.regressor import rigid_body_regressor

    run = excitation_run(panda, duration=0.4, rate=RATE, torque_noise=0.0, seed=8).dataset
    zero = np.zeros_like(run.q)
    pi0 = panda.prior_parameters
    ref = rigid_body_regressor(panda, run.q, zero, zero) @ pi0
    gap = GapData(panda, run, pi0)
    assert np.allclose(gap.gravity, ref, rtol=0, atol=1e-10)
    for k, dg in enumerate(tilt_directions(panda.gravity)):
        tilted = rigid_body_regressor(panda.with_gravity(dg), run.q, zero, zero) @ pi0
        assert np.allclose(gap.tilt_gravity[..., k], tilted, rtol=0, atol=1e-10)
    massless = pi0.copy()
    massless[-10:] = 0.0
    ref = rigid_body_regressor(panda, run.q, zero, zero) @ massless
    assert np.all(np.isfinite(GapData(panda, run, massless).gravity))
    assert np.array_equal(GapData(panda, run, massless).gravity, ref)


def test_candidate_matrix_is_the_concatenated_columns(panda):
    """``EffectLibrary.matrix`` (row-only atoms written row by row) against the concatenation of
    every atom's full ``(N, nv, k)`` columns, bit for bit; a row-only effect's columns are zero off
    its joint's row."""
    from consistid.diagnosis.effects import REGISTRY

    run = excitation_run(panda, duration=1.0, rate=200.0, torque_noise=0.05, seed=9).dataset
    gap = GapData(panda, run, panda.prior_parameters)
    lib = EffectLibrary(panda)
    atoms = lib.atoms(gap, gap.residual)
    atoms = [a if a.effect not in ("coulomb", "ripple") else
             Atom(a.effect, a.joint, a.parameter_names, a.units, a.setting, 15.0, a.setting_name)
             for a in atoms]                                    # a filtered row too
    assert {a.effect for a in atoms} >= {"coulomb", "delay", "elasticity", "inertia", "position"}
    full = [lib.columns(a, gap) for a in atoms]
    assert np.array_equal(lib.matrix(atoms, gap), np.concatenate(full, axis=2))
    for a, cols in zip(atoms, full):
        if REGISTRY[a.effect].row_only and a.joint is not None:
            off = np.delete(cols, a.joint, axis=1)
            assert not off.any(), a

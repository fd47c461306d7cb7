"""The compressed least-squares problem (per-joint R factors) against the samples it came from."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

import consistid as ci
from consistid.identification.compression import compress
from consistid.identification.regressor import RegressorSpec, predict_torque


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**16))
def test_minus_is_the_problem_of_the_torque_a_known_robot_leaves(planar_2r, seed):
    rng = np.random.default_rng(seed)
    run = ci.simulate.excitation_run(planar_2r, duration=2.0, rate=100.0, seed=seed)
    spec = RegressorSpec.make(planar_2r, ("coulomb", "offset"))
    p = planar_2r.n_inertial + spec.n_joint_columns
    theta, v = rng.normal(size=p), rng.normal(size=p)
    shifted = compress(planar_2r, run.dataset, spec).minus(theta)
    left = run.dataset.with_torque(run.dataset.tau - predict_torque(planar_2r, run.dataset,
                                                                    spec, theta))
    direct = compress(planar_2r, left, spec)
    np.testing.assert_allclose(shifted.sum_squares(v), direct.sum_squares(v), rtol=1e-9)
    np.testing.assert_allclose(shifted.tau_sum_squares, np.sum(left.tau ** 2, axis=0),
                               rtol=1e-9)
    # the same normal equations from either: RᵀR and Rᵀz
    (r1, z1, _), (r2, z2, _) = shifted.stacked(), direct.stacked()
    np.testing.assert_allclose(r1.T @ r1, r2.T @ r2, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(r1.T @ z1, r2.T @ z2, rtol=1e-9, atol=1e-9)

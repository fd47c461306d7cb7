"""identify's data pass against the dense computation it replaces (issue 17).

The pass writes the rigid-body regressor into a reused buffer, folds each joint's block into its
factor with LAPACK's ``dtpqrt`` and, in ``identify``, runs each joint's QR on its supported
independent (base) columns only, the factor expanded by ``B`` afterwards. References here are
computed without any of that: the Gram matrix of the dense regressor ``[Y_j | τ_j]`` per joint,
and the dense per-joint QR (``accumulate`` on every column) fed to the same solvers.

OLS and WLS answers (estimate, covariance, σ, RMS) must equal the dense ones to 1e-9 (relative).
The SDP's only data are these factors, equal to round-off; its answer is equal to the interior
point solver's tolerance, not to 1e-9: the dense reference itself moves by ~1e-6 (standard
parameters) and ~5e-8 (base parameters) when only the chunk size of its QR changes (measured on
the Panda and the Kinova arm, 20 000 samples).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import consistid as ci
from consistid.identification.base import compute_base_parameters
from consistid.identification.compression import CompressedProblem, accumulate, compress
from consistid.identification.identify import least_squares, with_covariance
from consistid.identification.regressor import RegressorSpec, regressor
from consistid.identification.sdp import identify_sdp

SPECS = {"default": dict(friction=("coulomb", "viscous", "offset")),
         "position+armature": dict(friction=("coulomb", "position"), armature=True)}


@pytest.fixture(scope="module", params=["panda", "kinova", "ur5"])
def arm(request):
    model = ci.RobotModel.example(request.param)
    run = ci.simulate.excitation_run(model, duration=10.0, rate=100.0, torque_noise=0.1, seed=2)
    return model, run.dataset


def dense_gram(model, data, spec, weights=None):
    """``[Y_j | τ_j]ᵀ W_j [Y_j | τ_j]`` per joint, from the whole regressor (no QR)."""
    n = data.n_samples
    y = regressor(model, data.q, data.dq, data.ddq, spec).reshape(n, model.nv, -1)
    a = np.concatenate([y, data.tau[:, :, None]], axis=2)
    if weights is not None:
        a = a * np.sqrt(weights)[:, :, None]
    return np.einsum("nji,njk->jik", a, a)


def dense_problem(model, data, spec):
    """The compressed problem by a dense per-joint QR of every column (no structure used)."""
    p = model.n_inertial + spec.n_joint_columns
    factors = np.zeros((model.nv, p + 1, p + 1))
    y = regressor(model, data.q, data.dq, data.ddq, spec).reshape(data.n_samples, model.nv, p)
    accumulate(factors, y, data.tau)
    return CompressedProblem(factors, data.n_samples, np.sum(data.tau ** 2, axis=0))


def gram_of(problem):
    return np.einsum("jik,jil->jkl", problem.factors, problem.factors)


def close(a, b, rtol):
    scale = max(float(np.max(np.abs(b))), 1e-300)
    assert float(np.max(np.abs(a - b))) <= rtol * scale, float(np.max(np.abs(a - b))) / scale


@pytest.mark.parametrize("which", sorted(SPECS))
def test_base_column_factor_has_the_dense_gram(arm, which):
    model, data = arm
    spec = RegressorSpec.make(model, **SPECS[which])
    base = compute_base_parameters(model, spec)
    reference = dense_gram(model, data, spec)
    for kwargs in ({}, {"base": base}):
        problem = compress(model, data, spec, chunk=257, **kwargs)
        gram = gram_of(problem)
        assert np.allclose(np.tril(problem.factors, -1), 0.0)        # still upper triangular
        cols = np.append(base.independent, gram.shape[1] - 1)
        for j in range(model.nv):                                    # per joint, its own scale
            # independent columns and torque: the QR's round-off only
            close(gram[j][np.ix_(cols, cols)], reference[j][np.ix_(cols, cols)], 1e-12)
            # every column: plus B's round-off (Y_d = Y_b K to ~1e-12)
            close(gram[j], reference[j], 1e-10)


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**16), chunk=st.integers(1, 300), weighted=st.booleans())
def test_any_chunking_and_row_weights_give_the_dense_gram(planar_2r, seed, chunk, weighted):
    data = ci.simulate.excitation_run(planar_2r, duration=1.5, rate=100.0, torque_noise=0.05,
                                      seed=seed).dataset
    spec = RegressorSpec.make(planar_2r, ("coulomb", "viscous", "offset", "position"))
    base = compute_base_parameters(planar_2r, spec)
    weights = (np.random.default_rng(seed).uniform(0.0, 2.0, data.tau.shape) if weighted
               else None)
    problem = compress(planar_2r, data, spec, chunk=chunk, weights=weights, base=base)
    reference = dense_gram(planar_2r, data, spec, weights)
    for j in range(planar_2r.nv):
        close(gram_of(problem)[j], reference[j], 1e-10)
    assert problem.n_samples == data.n_samples


@pytest.mark.parametrize("method", ["ols", "wls"])
def test_least_squares_answers_equal_the_dense_ones(arm, method):
    model, data = arm
    spec = RegressorSpec.make(model)
    base = compute_base_parameters(model, spec)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")       # poorly excited short runs warn alike in both
        res = ci.identify(model, data, method=method)
        dense = least_squares(model, dense_problem(model, data, spec), base, spec,
                              weighted=method == "wls")
    dense = with_covariance(dense, dense_problem(model, data, spec), data, "coloured")
    for field in ("base_parameters", "base_covariance", "sigma", "train_rms", "parameters"):
        close(getattr(res, field), getattr(dense, field), 1e-9)
    np.testing.assert_allclose(res.details["autocorrelation_time"],
                               dense.details["autocorrelation_time"], rtol=1e-9)


def test_sdp_answer_equals_the_dense_one_to_the_solver_tolerance(arm):
    model, data = arm
    spec = RegressorSpec.make(model)
    base = compute_base_parameters(model, spec)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = ci.identify(model, data)
        dense = identify_sdp(model, dense_problem(model, data, spec), base, spec, dataset=data)
    assert res.solver.status == dense.solver.status == "optimal"
    # the data term's part of the answer; the directions only the prior decides move with
    # the interior point iterates (module docstring)
    close(res.base_parameters, dense.base_parameters, 1e-5)
    close(res.train_rms, dense.train_rms, 1e-6)
    close(res.sigma, dense.sigma, 1e-6)


#: Clarabel run far past its defaults: the interior point iterates then stop moving with the
#: round-off of their data, and the answers of two equal problems agree to ~1e-11.
TIGHT = {"tol_gap_abs": 1e-13, "tol_gap_rel": 1e-13, "tol_feas": 1e-13, "tol_ktratio": 1e-10,
         "max_iter": 400}


def test_sdp_answer_equals_the_dense_one_to_1e9_when_solved_tightly(arm):
    """Issue 17's equality for the SDP: with the solver converged far below its default
    tolerance, identify's data pass and the dense reference give the same base and standard
    parameters to 1e-9 (relative; measured 1e-11 to 1e-15 on the Panda, Kinova and UR5) — the
    1e-5 above is the default tolerance's, not the data pass's."""
    model, data = arm
    spec = RegressorSpec.make(model)
    base = compute_base_parameters(model, spec)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = ci.identify(model, data, solver_options=TIGHT)
        dense = identify_sdp(model, dense_problem(model, data, spec), base, spec, dataset=data,
                             solver_options=TIGHT)
    assert res.solver.status.startswith("optimal") and dense.solver.status.startswith("optimal")
    close(res.base_parameters, dense.base_parameters, 1e-9)
    close(res.parameters, dense.parameters, 1e-9)

"""The structural shortcuts of the data pass give the same numbers as the dense computation."""

from __future__ import annotations

import numpy as np
import pytest

import consistid as ci
from consistid.identification.compression import accumulate, compress
from consistid.identification.regressor import (RegressorSpec, column_support, iter_regressor,
                                                predict_torque, regressor)


@pytest.fixture(scope="module", params=["panda", "kinova", "ur5"])
def arm(request):
    model = ci.RobotModel.example(request.param)
    run = ci.simulate.excitation_run(model, duration=3.0, rate=200.0, torque_noise=0.1)
    return model, run.dataset


def test_support_covers_every_non_zero_entry_and_nothing_carried_is_left_out(arm):
    model, data = arm
    spec = RegressorSpec.make(model, armature=True)
    y = regressor(model, data.q, data.dq, data.ddq, spec).reshape(data.n_samples, model.nv, -1)
    support = column_support(model, spec)
    assert not np.any(y[:, ~support])                    # outside the support: exactly zero
    # inside it, every body column of a carried body is non-zero somewhere, except the
    # structurally unidentifiable ones (e.g. the mass moment along a joint's own axis)
    assert np.mean(np.any(y != 0, axis=0)[support]) > 0.6
    assert support[0].sum() > support[-1].sum()          # the first joint carries every body


def test_compressed_factor_is_the_dense_one(arm):
    model, data = arm
    spec = RegressorSpec.make(model)
    p = model.n_inertial + spec.n_joint_columns
    dense = np.zeros((model.nv, p + 1, p + 1))
    for s, y in iter_regressor(model, data, spec, chunk=97):
        accumulate(dense, y, data.tau[s])
    sparse = compress(model, data, spec, chunk=97).factors
    gram = np.einsum("jik,jil->jkl", dense, dense)
    np.testing.assert_allclose(np.einsum("jik,jil->jkl", sparse, sparse), gram,
                               atol=1e-12 * np.abs(gram).max())
    assert np.allclose(np.tril(sparse, -1), 0.0)         # still upper triangular


def test_prediction_by_rnea_equals_the_regressor_product(arm):
    model, data = arm
    spec = RegressorSpec.make(model, armature=True)
    rng = np.random.default_rng(1)
    theta = np.concatenate([model.prior_parameters * rng.uniform(0.5, 1.5, model.n_inertial),
                            rng.standard_normal(spec.n_joint_columns)])
    theta[0] = -abs(theta[0])                            # unphysical bodies predict all the same
    direct = np.vstack([y @ theta for _, y in iter_regressor(model, data, spec)])
    np.testing.assert_allclose(predict_torque(model, data, spec, theta), direct,
                               atol=1e-12 * np.abs(direct).max())
    theta[10] = 0.0                                      # a massless body: the regressor path
    direct = np.vstack([y @ theta for _, y in iter_regressor(model, data, spec)])
    np.testing.assert_allclose(predict_torque(model, data, spec, theta), direct, atol=1e-12)

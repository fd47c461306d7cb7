"""Base → consistent standard recovery: exact reproduction, nearest mode, diagnostics, statuses."""

import dataclasses

import numpy as np
import pytest

import consistid as ci
from consistid.cli import main
from consistid.errors import (InfeasibleError, JointCountError, ModelError, OptionError,
                              UnrealizableCoefficientsError)
from consistid.identification.identify import nearest_standard
from consistid.robot.inertia import (from_mass_com_inertia, is_physically_consistent, perturb,
                                     pseudo_inertia)
from consistid.estimation.recover import recover_standard
from consistid.identification.regressor import regressor

from .conftest import random_states


@pytest.fixture(scope="module")
def setup(panda):
    """Rigid-body coefficients (``friction=None`` below: the default is identify's friction)."""
    base = ci.compute_base_parameters(panda)
    truth = perturb(panda.prior_parameters, 0.2, np.random.default_rng(1))
    return base, truth


@pytest.fixture(scope="module")
def noisy_ols(panda, setup):
    """OLS coefficients from heavily noisy data (1 N·m): not realisable as they stand."""
    _, truth = setup
    run = ci.simulate.excitation_run(panda, truth, duration=10.0, rate=200.0, torque_noise=1.0,
                                     seed=1)
    return run.dataset, ci.identify(panda, run.dataset, method="ols", friction=None)


@pytest.mark.parametrize("prior", ["logdet", "euclidean"])
def test_exact_reproduces_truth_coefficients(panda, setup, prior):
    base, truth = setup
    beta = base.project(truth)
    rec = recover_standard(panda, beta, prior=prior, friction=None)
    assert [s.status for s in rec.solver] == ["optimal"]
    assert np.max(np.abs(rec.residual) / np.maximum(np.abs(beta), 1.0)) < 1e-6
    assert rec.check(tol=1e-6).ok
    # every body, including those most of whose columns vanish (panda_link1), is consistent
    assert np.all(rec.margins > 0) and is_physically_consistent(
        rec.inertial_parameters, body_names=panda.body_names).ok
    # same coefficients ⇒ same torques, checked on fresh states against the truth itself
    q, dq, ddq = random_states(panda, 20, seed=5)
    y = regressor(panda, q, dq, ddq)
    assert np.max(np.abs(y @ rec.parameters - y @ truth)) < 1e-5


def test_bodies_with_vanishing_columns_are_constrained(panda, setup):
    """A truth whose link 1 is a thin rod along z: the coefficient fixes link1.Izz (+ grouped
    terms) only, and the prior's other link-1 values with that Izz are not realisable. The
    recovered link 1 must be consistent anyway (FIGAROH left such bodies unconstrained)."""
    base, truth = setup
    rod = truth.copy()
    rod[0:10] = from_mass_com_inertia(4.0, [0.0, 0.0, -0.1], np.diag([0.05, 0.05, 2e-4]))
    beta = base.project(rod)
    naive = nearest_standard(base, beta, panda.prior_parameters)   # ignores consistency
    assert not is_physically_consistent(naive, body_names=panda.body_names).bodies[0].ok
    rec = recover_standard(panda, beta, prior="euclidean", friction=None)
    assert rec.consistency.bodies[0].ok and np.all(rec.margins > 0)
    assert np.max(np.abs(rec.residual)) < 1e-6


def test_nearest_on_noisy_ols_reports_moves(panda, noisy_ols):
    data, res = noisy_ols
    with pytest.raises(UnrealizableCoefficientsError) as info:
        recover_standard(panda, res)
    named = info.value.moves
    assert named and all(m.grouping in res.base.groupings for m in named)
    assert "β" in str(info.value) and "nearest" in str(info.value)
    rec = recover_standard(panda, res, mode="nearest")
    assert rec.is_consistent and rec.consistency.ok
    assert rec.moves and rec.moves[0].grouping in res.base.groupings
    recovered = rec.recovered_base
    for m in rec.moves:
        assert m.recovered == pytest.approx(recovered[m.index], abs=1e-12)
        assert m.given == res.base_parameters[m.index]
        assert abs(m.sigmas) >= 1e-3
    # nearest: it moves the coefficients by a fraction of their standard deviation only
    assert max(abs(m.sigmas) for m in rec.moves) < 1.0
    assert rec.distance == pytest.approx(
        float(np.sum((np.linalg.solve(np.linalg.cholesky(res.base_covariance),
                                      recovered - res.base_parameters)) ** 2)), rel=1e-6)
    check = rec.check(data)
    # the move changes the predicted torque by a tenth of the 1 N·m noise at most
    assert check.ok and np.max(check.torque_difference) < 0.1
    assert "moved" in rec.summary() and "panda_link2" in rec.summary()


def test_infeasibility_names_the_unrealisable_coefficient(panda, setup):
    """Izz about a body's origin is ≥ 0 for any mass distribution: a negative value alone can
    only be fixed by moving that coefficient."""
    base, truth = setup
    beta = base.project(truth)
    k = base.groupings.index("panda_link7.Izz")
    beta[k] = -0.01
    with pytest.raises(UnrealizableCoefficientsError) as info:
        recover_standard(panda, beta, friction=None)
    moves = {m.index: m for m in info.value.moves}
    assert k in moves and moves[k].change >= 0.01 - 1e-6
    assert "panda_link7.Izz" in str(info.value)


def test_sdp_result_with_unexcited_directions(planar_2r):
    """Static data leave the Izz groupings unexcited: the SDP's covariance gives them infinite
    variance. Recovery weights them with pseudo standard deviations (and says so) instead of
    refusing a non-finite covariance."""
    q, _, _ = random_states(planar_2r, 50, seed=2)
    still = np.zeros_like(q)
    data = ci.Dataset(t=0.1 * np.arange(50), q=q, dq=still, ddq=still,
                      tau=planar_2r.rnea(q, still, still))
    res = ci.identify(planar_2r, data, method="sdp", friction=None)
    free = ~np.isfinite(np.diag(res.base_covariance))
    assert free.any() and not free.all()
    rec = recover_standard(planar_2r, res)
    assert rec.details["pseudo_std"] == tuple(np.array(res.base.names)[free])
    np.testing.assert_allclose(rec.std[free], 0.01 * np.abs(res.base_parameters[free]) + 1e-6)
    np.testing.assert_allclose(rec.std[~free], res.base_std[~free])
    assert rec.check(tol=1e-6).ok and rec.is_consistent
    assert "undetermined (infinite variance: link1.Izz" in rec.summary()


def test_friction_coefficients_are_recovered_and_kept_nonnegative(panda, setup):
    _, truth = setup
    fr = ("coulomb", "viscous", "offset")
    theta = np.concatenate([truth, np.linspace(0.2, 0.8, 7), np.linspace(0.1, 0.4, 7),
                            np.zeros(7)])
    run = ci.simulate.excitation_run(panda, theta, duration=10.0, rate=200.0, torque_noise=0.05,
                                     friction=fr, seed=4)
    res = ci.identify(panda, run.dataset, method="ols", friction=fr)
    rec = recover_standard(panda, res, mode="nearest")
    friction = rec.parameters[panda.n_inertial:panda.n_inertial + 14]
    assert np.all(friction >= -1e-9)
    assert np.allclose(friction, theta[70:84], atol=0.05)
    # the bare vector of identify's default spec needs no friction= (both default alike), and a
    # friction= that describes the result's columns is accepted, another one refused
    bare = recover_standard(panda, res.base_parameters, mode="nearest",
                            covariance=res.base_covariance)
    np.testing.assert_allclose(bare.parameters, rec.parameters, rtol=1e-6, atol=1e-9)
    assert recover_standard(panda, res, mode="nearest", friction=fr).spec == res.spec
    with pytest.raises(OptionError, match="other per-joint columns.*taken from the result"):
        recover_standard(panda, res, friction=("coulomb",))
    with pytest.raises(OptionError, match=r"\['armature'\]"):
        recover_standard(panda, res, armature=True)


def test_status_and_input_errors(panda, setup):
    base, truth = setup
    beta = base.project(truth)
    kw = dict(friction=None)
    with pytest.raises(OptionError, match="solver='NOT_A_SOLVER'.*installed: .*CLARABEL"):
        recover_standard(panda, beta, solver="NOT_A_SOLVER", **kw)
    rec = recover_standard(panda, beta, solver="clarabel", **kw)  # names are case-insensitive
    assert rec.solver[0].name == "CLARABEL"
    with pytest.raises(InfeasibleError):              # J ⪰ 10·J₀ cannot match these masses
        recover_standard(panda, beta, margin=10.0, **kw)
    with pytest.raises(ModelError, match="42 base coefficients.*has 43"):
        recover_standard(panda, beta[:-1], **kw)
    with pytest.raises(OptionError):
        recover_standard(panda, beta, mode="closest", **kw)
    with pytest.raises(OptionError, match="positive definite"):
        recover_standard(panda, beta, covariance=-np.eye(beta.size), **kw)


def test_is_consistent_means_what_consistency_says(panda, setup):
    """One definition for both results: a body on the boundary (a point mass: J ⪰ 0 but I_c
    singular) is not consistent, whatever the solver's round-off."""
    base, truth = setup
    rec = recover_standard(panda, base.project(truth), friction=None)
    assert rec.is_consistent and rec.consistency.ok
    point = rec.parameters.copy()
    point[60:70] = from_mass_com_inertia(1.0, [0.0, 0.0, 0.1], np.zeros((3, 3)))
    margins = rec.margins.copy()
    margins[6] = np.linalg.eigvalsh(pseudo_inertia(point[60:70]))[0]
    assert margins[6] > -1e-12                       # ⪰ 0 to round-off
    boundary = dataclasses.replace(rec, parameters=point, margins=margins)
    assert not boundary.consistency.ok and not boundary.is_consistent
    assert not boundary.check().ok
    with pytest.raises(JointCountError):             # the dataset must match the model
        q = np.zeros((3, 6))
        rec.check(ci.Dataset(t=np.arange(3.0), q=q, dq=q, ddq=q, tau=q))


def test_bare_coefficients_default_to_identify_s_columns(panda, setup):
    """43 rigid-body coefficients under the default (identify's 64-coefficient friction spec):
    the error names the settings that would match, not just the count."""
    base, truth = setup
    with pytest.raises(ModelError, match=r"43 base coefficients.*has 64.*friction=None, "
                                         r"armature=False"):
        recover_standard(panda, base.project(truth))


def test_cli_recover_writes_a_consistent_urdf(panda, setup, tmp_path):
    base, truth = setup
    np.savez(tmp_path / "beta.npz", beta=base.project(truth))
    (tmp_path / "recover.toml").write_text(
        f'[model]\nurdf = "{panda.source}"\n'
        'locked_joints = ["panda_finger_joint1", "panda_finger_joint2"]\n'
        '[recover]\ncoefficients = "beta.npz"\nfriction = []\nprior = "euclidean"\n'
        'urdf = "out.urdf"\n')
    assert main(["recover", str(tmp_path / "recover.toml")]) == 0
    back = ci.RobotModel.from_urdf(tmp_path / "out.urdf", locked_joints=panda.locked_joints)
    assert np.max(np.abs(base.project(back.prior_parameters) - base.project(truth))) < 1e-6


def test_a_wrong_coefficient_count_names_the_settings_that_fit(planar_2r):
    # 2R arm with viscous friction: 6 rigid base coefficients + 2; recovered with the default
    # columns (Coulomb, viscous, offset: 12) it must say which settings give 8
    from consistid.identification.regressor import prior_vector

    spec = ci.RegressorSpec.make(planar_2r, ("viscous",))
    beta = ci.compute_base_parameters(planar_2r, spec).project(prior_vector(planar_2r, spec))
    with pytest.raises(ci.ModelError, match=r"8 base coefficients, but .* has 12\. Settings that "
                                            r"give that many: .*friction=\('viscous',\), "
                                            r"armature=False"):
        ci.recover_standard(planar_2r, beta, friction=("coulomb", "viscous", "offset"))


def test_wrongly_typed_inputs_are_named(planar_2r):
    spec = ci.RegressorSpec.make(planar_2r, None)
    from consistid.identification.regressor import prior_vector

    beta = ci.compute_base_parameters(planar_2r, spec).project(prior_vector(planar_2r, spec))
    kw = dict(friction=None)
    for options, error, message in (
            (dict(margin="x"), OptionError, "margin must be a finite number ≥ 0, got 'x'"),
            (dict(slack=[1]), OptionError, r"slack must be a finite number > 0, got \[1\]"),
            (dict(covariance="x"), OptionError, r"covariance must be numbers, shape \(6, 6\)")):
        with pytest.raises(error, match=message):
            ci.recover_standard(planar_2r, beta, **kw, **options)
    with pytest.raises(ModelError, match="base coefficients must be numbers"):
        ci.recover_standard(planar_2r, "abc", **kw)

"""The physically consistent SDP: recovery, consistency, priors, weighting, status contract.

Ground truth comes from the simulator (truth = URDF ±20 %); expected values are computed
independently: base parameters from the true vector, covariances and least-squares answers from
the full (uncompressed) regressor, realizability from eigenvalues of the pseudo-inertia built by
its defining formula.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.linalg

import consistid as ci
from consistid.identification.base import compute_base_parameters
from consistid.identification.compression import SIGMA_FLOOR, compress
from consistid.robot.shapes import Ellipsoid
from consistid.errors import (IdentificationError, InaccurateSolutionWarning,
                              InconsistentParametersError, InfeasibleError, ModelWarning,
                              OptionError, PoorExcitationWarning)
from consistid.excitation import FourierTrajectory
from consistid.robot.inertia import (from_pseudo_inertia, inertia_about_origin,
                                  is_physically_consistent, perturb, to_mass_com_inertia)
from consistid.identification.priors import Neighbourhood
from consistid.identification.regressor import RegressorSpec, dataset_regressor
from consistid.identification.sdp import default_prior_weight, identify_sdp

from .conftest import PLANAR_2R, PLANAR_2R_VALUES, random_states

SIGMA = 0.1
FRICTION = ("coulomb", "viscous")


def j_matrix(p: np.ndarray) -> np.ndarray:
    """Pseudo-inertia by its definition (not via the library)."""
    i = np.array([[p[4], p[5], p[7]], [p[5], p[6], p[8]], [p[7], p[8], p[9]]])
    out = np.empty((4, 4))
    out[:3, :3] = 0.5 * np.trace(i) * np.eye(3) - i
    out[:3, 3] = out[3, :3] = p[1:4]
    out[3, 3] = p[0]
    return out


def min_eigs(theta: np.ndarray, nb: int) -> np.ndarray:
    return np.array([np.linalg.eigvalsh(j_matrix(theta[10 * i:10 * i + 10]))[0]
                     for i in range(nb)])


def held_rms(res, data) -> float:
    return float(np.sqrt(np.mean(res.rms(data) ** 2)) / SIGMA)


@pytest.fixture(scope="module")
def truth(panda):
    inertial = perturb(panda.prior_parameters, 0.2, np.random.default_rng(3))
    friction = np.random.default_rng(4).uniform(0.05, 0.5, 2 * panda.nv)
    return np.concatenate([inertial, friction])


@pytest.fixture(scope="module")
def sets(panda, truth):
    """Friction-free sets follow the issue's protocol (truth = URDF ±20 %, no friction): a
    poorly exciting 2 s small-amplitude run and a held-out one; the others carry friction."""
    def run(duration, rate, seed, noise=SIGMA, trajectory=None, friction=FRICTION):
        params = truth if friction else truth[:panda.n_inertial]
        return ci.simulate.excitation_run(panda, params, duration, rate, torque_noise=noise,
                                          friction=friction, seed=seed,
                                          trajectory=trajectory).dataset

    small = FourierTrajectory.random(panda, 5, 10.0, np.random.default_rng(12), amplitude=0.2)
    return {"train": run(10.0, 100.0, 1), "held": run(5.0, 100.0, 2),
            "poor": run(2.0, 250.0, 3, trajectory=small, friction=None),
            "poor_held": run(5.0, 100.0, 2, friction=None), "clean": run(5.0, 100.0, 5, 0.0)}


@pytest.fixture(scope="module")
def well(panda, sets):
    return ci.identify(panda, sets["train"], method="sdp", friction=FRICTION)


def test_noise_free_data_recover_the_base_parameters(panda, truth, sets):
    for prior in ("logdet", "euclidean"):
        res = ci.identify(panda, sets["clean"], method="sdp", friction=FRICTION, prior=prior)
        expected = res.base.project(truth)
        assert np.max(np.abs(res.base_parameters - expected)) <= 1e-6 * np.max(np.abs(expected))
        assert res.is_consistent


def test_position_terms_have_no_sign_constraint(panda, truth):
    # sin q_j, cos q_j per joint (joint 2's pair is regrouped with link 2's first moments)
    friction = FRICTION + ("position",)
    params = np.concatenate([truth, np.tile([-0.3, 0.2], panda.nv)])
    data = ci.simulate.excitation_run(panda, params, 5.0, 100.0, torque_noise=0.0,
                                      friction=friction, seed=5).dataset
    res = ci.identify(panda, data, method="sdp", friction=friction)
    expected = res.base.project(params)
    assert np.max(np.abs(res.base_parameters - expected)) <= 1e-6 * np.max(np.abs(expected))
    assert res.parameters[res.parameter_names.index("panda_joint7.ps1")] == pytest.approx(-0.3)
    assert res.is_consistent


def test_well_excited_fit_matches_ols_and_every_body_is_realizable(panda, sets, well):
    ols = ci.identify(panda, sets["train"], method="ols", friction=FRICTION)
    assert held_rms(well, sets["held"]) <= 1.01 * held_rms(ols, sets["held"])
    assert np.all(min_eigs(well.parameters, panda.n_bodies) > 0)
    assert well.solver.status == "optimal" and well.solver.name.startswith("CLARABEL")
    np.testing.assert_allclose(well.base_parameters, well.base.matrix @ well.parameters)
    d = well.details
    np.testing.assert_allclose(list(d["min_eigenvalues"].values()),
                               min_eigs(well.parameters, panda.n_bodies), rtol=1e-9, atol=1e-15)
    assert list(d["min_eigenvalues"]) == panda.body_names
    assert all(v > 0 for v in d["relative_margins"].values())
    assert d["prior"] == "logdet" and d["prior_weight"] == default_prior_weight()
    assert d["fit"]["default_prior_weight"] == default_prior_weight()
    assert d["timing"]["solve"] == well.solver.solve_time > 0 and d["timing"]["compile"] > 0
    assert d["sigma_source"] == "ols" and d["constraints"] == "pseudo-inertia; active: none"
    assert np.all(np.abs(well.sigma / SIGMA - 1) < 0.1)
    assert "physical consistency: all 7 bodies consistent" in well.summary()


def test_base_covariance_is_that_of_the_weighted_fit(panda, sets):
    """``(W_bᵀ Σ⁻¹ W_b)⁻¹`` from the full regressor, with the σ the SDP used (rows counted as
    independent: ``covariance="iid"``)."""
    well = ci.identify(panda, sets["train"], method="sdp", friction=FRICTION, covariance="iid")
    y = dataset_regressor(panda, sets["train"], well.spec)
    w = y[:, well.base.independent] / np.tile(well.sigma, sets["train"].n_samples)[:, None]
    np.testing.assert_allclose(well.base_covariance, np.linalg.inv(w.T @ w), rtol=1e-6)


def test_unconstrained_sdp_equals_weighted_least_squares(panda, sets):
    wls = ci.identify(panda, sets["train"], method="wls", friction=FRICTION)
    res = ci.identify(panda, sets["train"], method="sdp", friction=FRICTION, constraints="none",
                      prior=None, friction_nonnegative=False, sigma=wls.sigma)
    np.testing.assert_allclose(res.base_parameters, wls.base_parameters,
                               atol=1e-6 * np.abs(wls.base_parameters).max())
    assert res.details["sigma_source"] == "given" and res.details["active_constraints"] == ()


def test_poorly_excited_data_use_the_prior_without_failing(panda, sets):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PoorExcitationWarning)
        ols = ci.identify(panda, sets["poor"], method="ols", friction=None)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sdp = ci.identify(panda, sets["poor"], method="sdp", friction=None)
    # no inaccuracy and no uninformed direction: only the weakly informed ones the prior decides
    assert sdp.weakly_informed and not sdp.uninformed
    assert all(w.category is PoorExcitationWarning and "barely inform" in str(w.message)
               for w in caught), [str(w.message) for w in caught]
    assert sdp.condition_number > 1e3
    assert held_rms(sdp, sets["poor_held"]) <= 1.2 < held_rms(ols, sets["poor_held"]) / 2
    assert sdp.is_consistent and np.all(min_eigs(sdp.parameters, panda.n_bodies) > 0)


def test_prior_weight_sweep_never_fails(panda, sets):
    default = default_prior_weight()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        # the poor data's weakly informed directions are said; no solver trouble is
        warnings.filterwarnings("ignore", "the data barely inform", PoorExcitationWarning)
        for friction, data in ((None, sets["poor"]), (FRICTION, sets["train"])):
            for factor in (1e-6, 1e-3, 1.0, 1e2):
                res = ci.identify(panda, data, method="sdp", friction=friction,
                                  prior_weight=factor * default)
                assert res.solver.status == "optimal" and res.is_consistent, factor
                assert res.details["prior_weight_rule"] == "given"


def test_euclidean_prior_has_the_log_det_curvature(panda, sets):
    """The default Euclidean metric is the log-det one at the prior, so at the default weight
    the answers are close; with a huge weight the answer is the prior."""
    kw = dict(method="sdp", friction=None)
    logdet = ci.identify(panda, sets["poor"], **kw)
    euclid = ci.identify(panda, sets["poor"], prior="euclidean", **kw)
    assert held_rms(euclid, sets["poor_held"]) == pytest.approx(
        held_rms(logdet, sets["poor_held"]), rel=0.1)
    pinned = ci.identify(panda, sets["poor"], prior="euclidean", prior_weight=1e9, **kw)
    np.testing.assert_allclose(pinned.inertial_parameters, panda.prior_parameters,
                               atol=1e-4 * np.abs(panda.prior_parameters).max())


def test_levels_hold_on_the_answer(panda, sets):
    """A weak Euclidean prior does not imply realizability (unlike log-det), so each level's
    constraint is what holds the answer: "mass-inertia" gives m > 0, I_c ⪰ 0 only."""
    kw = dict(method="sdp", friction=None, prior="euclidean",
              prior_weight=1e-4 * default_prior_weight())
    free = ci.identify(panda, sets["poor"], constraints="none", **kw)
    assert not free.is_consistent  # otherwise the levels below would not be tested
    mi = ci.identify(panda, sets["poor"], constraints="mass-inertia", **kw)
    tri = ci.identify(panda, sets["poor"], constraints="triangle", **kw)
    assert is_physically_consistent(mi.parameters, "mass-inertia", panda.body_names, tol=1e-9)
    assert any(a.endswith("mass-inertia LMI") for a in mi.details["active_constraints"])
    assert is_physically_consistent(tri.parameters, "triangle", panda.body_names, tol=1e-12)
    assert np.all(min_eigs(tri.parameters, panda.n_bodies) > 0)
    mixed = {"panda_link1": "none", "panda_link2": "mass-inertia"}
    res = ci.identify(panda, sets["poor"], constraints=mixed, **kw)
    assert res.details["constraints"].startswith("panda_link1=none, panda_link2=mass-inertia, "
                                                 "panda_link3=pseudo-inertia")
    fr = ci.identify(panda, sets["train"], method="sdp", friction=FRICTION)
    assert np.all(fr.parameters[panda.n_inertial:] >= 0)  # Coulomb and viscous ≥ 0


def test_margin_is_relative_to_the_prior_body(panda, sets):
    """``margin`` means ``J ⪰ margin·J₀`` (as in recover_standard): every generalised eigenvalue
    of ``(J, J₀)`` is ≥ margin, and bodies the weak prior lets go sit on that bound."""
    margin = 0.05
    res = ci.identify(panda, sets["poor"], method="sdp", friction=None, prior="euclidean",
                      prior_weight=1e-4 * default_prior_weight(), margin=margin)
    prior = panda.prior_parameters
    lowest = np.array([scipy.linalg.eigh(j_matrix(res.parameters[10 * i:10 * i + 10]),
                                         j_matrix(prior[10 * i:10 * i + 10]),
                                         eigvals_only=True)[0] for i in range(panda.n_bodies)])
    assert np.all(lowest >= margin * (1 - 1e-5))
    assert np.any(lowest <= margin * (1 + 1e-4))
    np.testing.assert_allclose(list(res.details["relative_margins"].values()), lowest,
                               rtol=1e-6)


def test_bounds_are_enforced_and_reported_active(panda, truth, sets):
    m2 = truth[10]
    com3 = truth[21:24] / truth[20]
    box_hi = com3.copy()
    box_hi[2] -= 0.02  # exclude the true CoM height of link 3
    res = ci.identify(panda, sets["train"], method="sdp", friction=FRICTION,
                      mass_bounds={"panda_link2": (None, 0.9 * m2)},
                      com_boxes={"panda_link3": (com3 - 0.5, box_hi)},
                      total_mass=(None, 0.99 * truth[0:70:10].sum()))
    theta = res.parameters
    assert theta[10] <= 0.9 * m2 * (1 + 1e-6)
    assert theta[23] / theta[20] <= box_hi[2] + 1e-6
    assert theta[0:70:10].sum() <= 0.99 * truth[0:70:10].sum() * (1 + 1e-6)
    active = res.details["active_constraints"]
    assert f"panda_link2: m ≤ {0.9 * m2:g}" in active
    assert f"panda_link3: cz ≤ {box_hi[2]:g}" in active
    assert res.is_consistent


def test_neighbourhood_and_ellipsoid_bounds_hold(panda, sets):
    prior = panda.prior_parameters
    nbh = Neighbourhood(mass=0.05, com=0.01, inertia=0.1)
    res = ci.identify(panda, sets["train"], method="sdp", friction=FRICTION, neighbourhood=nbh)
    for i in range(panda.n_bodies):
        x, x0 = res.parameters[10 * i:10 * i + 10], prior[10 * i:10 * i + 10]
        assert abs(x[0] / x0[0] - 1) <= 0.05 + 1e-6
        assert np.linalg.norm(x[1:4] / x[0] - x0[1:4] / x0[0]) <= 0.01 + 1e-6
        i0 = inertia_about_origin(x0)
        assert np.linalg.norm(inertia_about_origin(x) - i0) <= (0.1 + 1e-6) * np.linalg.norm(i0)
    assert any("neighbourhood" in a for a in res.details["active_constraints"])
    # every body's mass inside a sphere around its prior CoM: tr(J Q) ≥ 0
    ells = {}
    for i, body in enumerate(panda.body_names):
        _, c0, _ = to_mass_com_inertia(prior[10 * i:10 * i + 10])
        ells[body] = Ellipsoid.from_semi_axes(c0, [0.12, 0.12, 0.12])
    res = ci.identify(panda, sets["train"], method="sdp", friction=FRICTION,
                      constraints="ellipsoid", ellipsoids=ells)
    for i, body in enumerate(panda.body_names):
        q = ells[body].q_matrix()
        j = j_matrix(res.parameters[10 * i:10 * i + 10])
        assert np.trace(j @ q) >= -1e-8 * np.linalg.norm(j) * np.linalg.norm(q)
    assert res.is_consistent


def test_sigma_is_reweighted_per_joint(panda, truth):
    """Heteroscedastic noise: IRLS re-estimates each joint's σ from the SDP residuals."""
    clean = ci.simulate.excitation_run(panda, truth, 10.0, 100.0, torque_noise=0.0,
                                       friction=FRICTION, seed=7).dataset
    sig = np.array([0.05, 0.4, 0.1, 0.2, 0.05, 0.1, 0.02])
    noisy = clean.__class__(t=clean.t, q=clean.q, dq=clean.dq, ddq=clean.ddq,
                            tau=clean.tau + sig * np.random.default_rng(8).normal(
                                size=clean.tau.shape))
    res = ci.identify(panda, noisy, method="sdp", friction=FRICTION, reweight=2)
    assert res.details["sigma_source"] == "irls" and res.details["passes"]["reweighting"] >= 2
    np.testing.assert_allclose(res.sigma, sig, rtol=0.1)


def test_huber_loss_resists_outliers(panda, truth):
    clean = ci.simulate.excitation_run(panda, truth, 10.0, 100.0, torque_noise=SIGMA,
                                       friction=FRICTION, seed=9).dataset
    rng = np.random.default_rng(10)
    tau = clean.tau.copy()
    hit = rng.random(tau.shape) < 0.03
    tau[hit] += rng.choice([-1, 1], hit.sum()) * rng.uniform(5.0, 20.0, hit.sum())
    data = clean.__class__(t=clean.t, q=clean.q, dq=clean.dq, ddq=clean.ddq, tau=tau)
    base = compute_base_parameters(panda, RegressorSpec.make(panda, FRICTION))
    expected = base.project(truth)

    def error(res):
        return np.linalg.norm((res.base_parameters - expected) / np.abs(expected).clip(0.05))

    squared = ci.identify(panda, data, method="sdp", friction=FRICTION)
    huber = ci.identify(panda, data, method="sdp", friction=FRICTION, loss="huber")
    assert huber.details["sigma_source"] == "huber"
    assert error(huber) < 0.5 * error(squared)
    assert np.all(np.abs(huber.sigma / SIGMA - 1) < 0.2)


def _rest_heavy_data(tmp_path):
    """A planar 2R arm with gravity along its joint axes, at rest in 60 % of the samples: there
    the torque and the regressor rows are exactly 0, so noise-free residuals have MAD = 0."""
    path = tmp_path / "planar2r.urdf"
    path.write_text(PLANAR_2R.format(**PLANAR_2R_VALUES))
    model = ci.RobotModel.from_urdf(path, gravity=(0.0, 0.0, -9.81))
    q, dq, ddq = random_states(model, 200, seed=0)
    dq[:120] = ddq[:120] = 0.0
    tau = model.rnea(q, dq, ddq)
    assert np.all(tau[:120] == 0.0)
    return model, ci.Dataset(t=0.01 * np.arange(200), q=q, dq=dq, ddq=ddq, tau=tau)


def test_huber_loss_on_noise_free_data_floors_the_scale(tmp_path):
    """MAD = 0 used to give σ = 1e-300 and infinite weights (scipy ValueError)."""
    model, data = _rest_heavy_data(tmp_path)
    res = ci.identify(model, data, method="sdp", friction=None, loss="huber")
    expected = res.base.project(model.prior_parameters)
    assert np.max(np.abs(res.base_parameters - expected)) <= 1e-9 * np.max(np.abs(expected))
    rms = np.sqrt(np.mean(data.tau ** 2, axis=0))
    np.testing.assert_allclose(res.sigma, SIGMA_FLOOR * rms)
    assert res.details["sigma_source"] == "huber"


def test_status_is_propagated(panda, sets):
    kw = dict(method="sdp", friction=FRICTION)
    with pytest.raises(IdentificationError, match="user_limit"):
        ci.identify(panda, sets["train"], solver_options={"max_iter": 2}, **kw)
    loose = {"max_iter": 8, "reduced_tol_gap_abs": 1e3, "reduced_tol_gap_rel": 1e3,
             "reduced_tol_feas": 1e3, "reduced_tol_ktratio": 1e3}
    with pytest.warns(InaccurateSolutionWarning):
        res = ci.identify(panda, sets["train"], solver_options=loose, **kw)
    assert res.solver.status == "optimal_inaccurate"
    with pytest.raises(InfeasibleError, match="infeasible.*Hint"):
        ci.identify(panda, sets["train"], mass_bounds={"panda_link1": (5.0, 4.0)}, **kw)


def test_options_are_validated(panda, sets):
    kw = dict(method="sdp", friction=FRICTION)
    with pytest.raises(OptionError, match="unknown bodies.*'forearm'"):
        ci.identify(panda, sets["train"], constraints={"forearm": "none"}, **kw)
    with pytest.raises(OptionError, match="panda_link1.*no ellipsoids"):
        ci.identify(panda, sets["train"], constraints={"panda_link1": "ellipsoid"}, **kw)
    with pytest.raises(OptionError, match="solver='FOO'"):
        ci.identify(panda, sets["train"], solver="FOO", **kw)
    with pytest.raises(OptionError, match="prior='gaussian'"):
        ci.identify(panda, sets["train"], prior="gaussian", **kw)
    with pytest.raises(OptionError, match="sigma must be 7"):
        ci.identify(panda, sets["train"], sigma=[0.1, 0.1], **kw)
    spec = RegressorSpec.make(panda, FRICTION)
    problem = compress(panda, sets["train"], spec)
    with pytest.raises(OptionError, match="pass dataset="):
        identify_sdp(panda, problem, compute_base_parameters(panda, spec), spec, loss="huber")


@pytest.mark.parametrize("options, message", [
    (dict(prior=None, prior_weight=1.0), r"\['prior_weight'\] weight a prior"),
    (dict(prior=None, prior_uncertainty=0.1), r"\['prior_uncertainty'\] weight a prior"),
    (dict(prior_weight=1.0, prior_uncertainty=0.1), "not both"),
    (dict(prior_weights=np.ones(70)), "prior='logdet'"),
    (dict(huber_threshold=2.0), "loss='squared'"),
    (dict(loss="huber", reweight=0), "reweight ≥ 1"),
    (dict(ellipsoids={"panda_link3": Ellipsoid.from_semi_axes([0, 0, 0], [1, 1, 1])}),
     r"ellipsoids given for bodies \['panda_link3'\]"),
])
def test_meaningless_option_combinations_are_refused(panda, sets, options, message):
    """Options that the other options make meaningless raise instead of being ignored."""
    with pytest.raises(OptionError, match=message):
        ci.identify(panda, sets["clean"], method="sdp", friction=FRICTION, **options)


@pytest.mark.parametrize("options, message", [
    (dict(prior_weight="big"), "prior_weight must be a finite number ≥ 0, got 'big'"),
    (dict(prior_uncertainty=-1), "prior_uncertainty must be a finite number > 0"),
    (dict(margin=[1]), r"margin must be a finite number ≥ 0, got \[1\]"),
    (dict(reweight=1.5), "reweight must be an integer ≥ 0, got 1.5"),
    (dict(reweight=True), "reweight must be an integer"),
    (dict(sigma="x"), "sigma must be 7 finite values > 0 .* got 'x'"),
    (dict(constraints=5), "constraints must be a level name"),
    (dict(total_mass=5), "total_mass must be a pair"),
    (dict(mass_bounds={"panda_link1": [1]}), r"mass_bounds\['panda_link1'\] must be a pair"),
    (dict(mass_bounds={"panda_link1": (0.1, "x")}), r"mass_bounds\['panda_link1'\] bound"),
    (dict(com_boxes={"panda_link1": 1}), r"com_boxes\['panda_link1'\] must be \(lower, upper\)"),
    (dict(solver_options={"max_iter": "a"}), "solver CLARABEL could not run with the options"),
])
def test_options_of_the_wrong_type_are_named(panda, sets, options, message):
    """A wrongly typed option raises OptionError naming it (it used to end in a traceback)."""
    with pytest.raises(OptionError, match=message):
        ci.identify(panda, sets["clean"], method="sdp", friction=FRICTION, **options)


def test_warnings_of_a_failed_first_solve_are_kept(panda, sets, monkeypatch):
    """A solve that warns, then raises: the warning reaches the caller with the error."""
    import consistid.identification.sdp as sdp

    def warn_then_fail(*args, **kwargs):
        warnings.warn("reduced accuracy before failing", InaccurateSolutionWarning)
        raise IdentificationError("solver failed")

    monkeypatch.setattr(sdp, "_solve", warn_then_fail)
    with pytest.warns(InaccurateSolutionWarning, match="before failing"):
        with pytest.raises(IdentificationError, match="solver failed"):
            ci.identify(panda, sets["clean"], method="sdp", friction=FRICTION)


def test_log_det_prior_needs_realizable_prior_bodies(panda, sets):
    bad = panda.prior_parameters.copy()
    bad[10 * 3 + 9] = 5.0  # panda_link4: Izz far beyond Ixx + Iyy
    model = panda.with_parameters(bad)
    with pytest.raises(InconsistentParametersError, match="panda_link4.*: no physical body"):
        ci.identify(model, sets["train"], method="sdp", friction=FRICTION, prior="logdet")
    res = ci.identify(model, sets["train"], method="sdp", friction=FRICTION, prior="euclidean")
    assert res.is_consistent
    # the default prior says why it is not the log-det one, and gives the Euclidean answer
    with pytest.warns(ModelWarning, match="panda_link4.*prior='euclidean'"):
        auto = ci.identify(model, sets["train"], method="sdp", friction=FRICTION)
    np.testing.assert_allclose(auto.parameters, res.parameters, rtol=1e-9, atol=1e-12)


def flattened(body: np.ndarray, ratio: float = 1e-12) -> np.ndarray:
    """``body`` with its pseudo-inertia's smallest eigenvalue set to ``ratio`` × its largest: a
    body with no extent along one direction up to round-off (as the Tiago URDF's arm_1_link,
    ratio 5e-13)."""
    lam, vec = np.linalg.eigh(j_matrix(body))
    lam[0] = ratio * lam[-1]
    return from_pseudo_inertia(vec @ np.diag(lam) @ vec.T)


def test_log_det_prior_refuses_a_body_singular_to_working_precision(panda, sets):
    """A URDF body whose pseudo-inertia is positive definite only by round-off (λ_min = 1e-12
    λ_max) is no centre for a log-det prior (its divergence weighs the flat direction by
    1/λ_min; on Tiago's arm_1_link the solve stalled, InsufficientProgress, or came back
    inaccurate): refused by name as a non-positive one is, and the Euclidean prior works."""
    bad = panda.prior_parameters.copy()
    bad[30:40] = flattened(bad[30:40])
    assert np.linalg.eigvalsh(j_matrix(bad[30:40]))[0] > 0
    model = panda.with_parameters(bad)
    with pytest.raises(InconsistentParametersError,
                       match="panda_link4.*working precision.*: a body with no extent"):
        ci.identify(model, sets["train"], method="sdp", friction=FRICTION, prior="logdet")
    res = ci.identify(model, sets["train"], method="sdp", friction=FRICTION, prior="euclidean")
    assert res.is_consistent
    with pytest.warns(ModelWarning, match="panda_link4.*working precision"):
        ci.identify(model, sets["train"], method="sdp", friction=FRICTION)


def test_a_nonlinear_friction_law_falls_back_to_the_euclidean_prior_too(planar_2r):
    """prior='auto' with a URDF body singular to working precision: the linear laws fall back
    to the Euclidean prior with a warning; a Stribeck law (its own SDP per search step) was
    refused instead, as if the user had asked for prior='logdet'."""
    nominal = planar_2r.prior_parameters.copy()
    nominal[10:20] = flattened(nominal[10:20])                              # link2
    model = planar_2r.with_parameters(nominal)
    d = ci.simulate.excitation_run(model, duration=10.0, rate=100.0, seed=3, torque_noise=0.05,
                                   friction=("coulomb", "viscous")).dataset
    with pytest.raises(InconsistentParametersError, match="link2"):
        ci.identify(model, d, friction="stribeck", prior="logdet")
    with pytest.warns(ModelWarning, match="link2.*prior='euclidean'"):
        auto = ci.identify(model, d, friction="stribeck")
    euclidean = ci.identify(model, d, friction="stribeck", prior="euclidean")
    np.testing.assert_allclose(auto.parameters, euclidean.parameters, rtol=1e-9, atol=1e-12)


def test_program_size_does_not_depend_on_the_number_of_samples(panda, sets):
    spec = RegressorSpec.make(panda, FRICTION)
    base = compute_base_parameters(panda, spec)
    sizes = []
    for data in (sets["poor"], sets["train"]):
        res = identify_sdp(panda, compress(panda, data, spec), base, spec)
        sizes.append((res.n_samples, res.details["program_size"]))
    assert sizes[0][0] != sizes[1][0] and sizes[0][1] == sizes[1][1]

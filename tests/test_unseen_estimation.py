"""Payload estimation on arms other than the Panda (UR5, xarm7), against the simulated truth,
and with bounds that exclude it: a bound that decides the answer must say so."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import consistid as ci
from consistid.errors import BoundActiveWarning
from consistid.estimation.payload import frame_transform
from consistid.robot.inertia import from_mass_com_inertia, perturb

MASS, COM = 1.2, np.array([0.02, -0.01, 0.06])


@pytest.fixture(scope="module", params=[("ur5", "tool0"), ("xarm7", "link_eef")])
def loaded_run(request):
    name, frame = request.param
    model = ci.RobotModel.example(name)
    nb = model.nv
    truth = perturb(model.prior_parameters, 0.1, np.random.default_rng(1))
    box = from_mass_com_inertia(MASS, COM, MASS / 12 * np.diag([0.01, 0.0136, 0.0164]))
    placement = model.pin_model.frames[model.pin_model.getFrameId(frame)].placement
    loaded = truth.copy()
    loaded[10 * (nb - 1):10 * nb] += frame_transform(placement.rotation,
                                                    placement.translation) @ box
    runs = [ci.simulate.excitation_run(model, p, duration=8.0, rate=200.0, torque_noise=0.2,
                                       seed=s).dataset for p, s in ((truth, 3), (loaded, 4))]
    robot = ci.identify(model, runs[0], method="ols", friction=None)
    return model, frame, robot, runs[1]


def test_payload_matches_the_simulated_one(loaded_run):
    model, frame, robot, loaded = loaded_run
    pay = ci.estimate_payload(model, loaded, robot=robot, frame=frame)
    assert pay.found
    assert abs(pay.mass - MASS) < 5 * pay.mass_std + 1e-3
    assert np.linalg.norm(pay.com - COM) < 3e-3


def test_a_mass_range_that_excludes_the_payload_warns(loaded_run):
    """Before: mass 0.5 kg on the bound, CoM 25 cm off, no word that the bound decided it."""
    model, frame, robot, loaded = loaded_run
    with pytest.warns(BoundActiveWarning, match="mass_range") as record:
        pay = ci.estimate_payload(model, loaded, robot=robot, frame=frame, mass_range=(0, 0.5))
    assert pay.mass == pytest.approx(0.5, abs=1e-3)
    named = float(str(record[0].message).split("give ")[1].split(" kg")[0])
    assert named == pytest.approx(MASS, abs=0.01)           # the unbounded estimate is named
    assert any("mass_range" in note for note in pay.notes)  # and the summary keeps it


def test_com_bounds_that_exclude_the_payload_warn_on_the_base_change_route(loaded_run):
    model, frame, robot, loaded = loaded_run
    loaded_res = ci.identify(model, loaded, method="ols", friction=None)
    with pytest.warns(BoundActiveWarning, match="com_bounds"):
        ci.payload_from_base_change(model, robot, loaded_res, frame=frame,
                                    com_bounds=([-0.1, -0.1, -0.1], [0.1, 0.1, 0.02]))


def test_bounds_that_contain_the_payload_stay_silent(loaded_run):
    model, frame, robot, loaded = loaded_run
    with warnings.catch_warnings():
        warnings.simplefilter("error", BoundActiveWarning)
        pay = ci.estimate_payload(model, loaded, robot=robot, frame=frame, mass_range=(0.5, 3.0),
                                  com_bounds=([-0.1, -0.1, -0.1], [0.1, 0.1, 0.2]))
    assert abs(pay.mass - MASS) < 0.02


def test_recovery_never_returns_an_inconsistent_set_silently():
    """Kinova, nearest mode, coefficients whose last body is ~5× its mass too light with a
    small identity covariance. Before: 'optimal', is_consistent False (a triangle inequality
    short by 1.7e-7 on a link the recovery made 3327 kg), and no warning."""
    from consistid.errors import InaccurateSolutionWarning
    from consistid.robot.inertia import perturb

    model = ci.RobotModel.example("kinova")
    base = ci.compute_base_parameters(model)
    truth = perturb(model.prior_parameters, 0.2, np.random.default_rng(0))
    last = 10 * (model.nv - 1)
    truth[last] -= 5.0 * (truth[last] + 1.0)
    beta = base.project(truth)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        rec = ci.recover_standard(model, beta, mode="nearest",
                                  covariance=np.eye(beta.size) * 1e-4, friction=None)
    warned = [w for w in record if issubclass(w.category, InaccurateSolutionWarning)
              and "not physically consistent" in str(w.message)]
    assert rec.is_consistent or warned


def test_an_undetermined_mass_is_not_reported_as_no_payload(planar_2r):
    """A payload on link1 of the planar 2R arm (gravity in the plane): its mass has σ = inf.
    Before: 'no payload found: the mass 0.623 ± inf kg is within 3 σ of 0'."""
    from consistid.errors import NothingFoundWarning

    truth = planar_2r.prior_parameters.copy()
    loaded = truth.copy()
    loaded[:10] += from_mass_com_inertia(0.7, [0.1, 0.02, 0.0], 0.7 / 12 * np.eye(3) * 0.01)
    runs = [ci.simulate.excitation_run(planar_2r, p, duration=8.0, rate=200.0, torque_noise=0.05,
                                       seed=s).dataset for p, s in ((truth, 3), (loaded, 4))]
    robot = ci.identify(planar_2r, runs[0], method="ols", friction=None)
    with pytest.warns(NothingFoundWarning, match="not determined") as record:
        pay = ci.estimate_payload(planar_2r, runs[1], robot=robot, body="link1")
    assert not np.isfinite(pay.mass_std) and not pay.found
    assert not any("no payload found" in str(w.message) for w in record)
    assert "cannot tell" in pay.summary()


def test_planar_com_std_is_finite_where_the_data_fix_it(planar_2r):
    """Planar 2R, payload on link2: m, m·c_x, m·c_y are determined, m·c_z is not. Before: the
    delta method multiplied 0 × inf and reported c_x, c_y as undetermined (σ = inf) too."""
    truth = planar_2r.prior_parameters.copy()
    loaded = truth.copy()
    loaded[10:20] += from_mass_com_inertia(0.7, [0.1, 0.02, 0.0], 0.7 / 12 * np.eye(3) * 0.01)
    runs = [ci.simulate.excitation_run(planar_2r, p, duration=8.0, rate=200.0, torque_noise=0.05,
                                       seed=s).dataset for p, s in ((truth, 3), (loaded, 4))]
    robot = ci.identify(planar_2r, runs[0], method="ols", friction=None)
    pay = ci.estimate_payload(planar_2r, runs[1], robot=robot)
    std = pay.com_std
    assert np.isinf(std[2]) and np.all(np.isfinite(std[:2]))
    m, h, cov = pay.mass, pay.parameters[1:3], pay.covariance
    for i in range(2):                       # c_i = h_i / m, by hand on the (m, h_i) block
        g = np.array([-h[i] / m ** 2, 1.0 / m])
        block = cov[np.ix_([0, i + 1], [0, i + 1])]
        assert std[i] == pytest.approx(np.sqrt(g @ block @ g), rel=1e-9)
    assert np.all(np.abs(pay.com[:2] - [0.1, 0.02]) < 5 * std[:2] + 1e-3)


@pytest.mark.parametrize("name", ["ur5", "xarm7"])
def test_a_ceiling_mounted_robot_is_found_upside_down(name):
    """Gravity turned by 180° (a robot hung from the ceiling, URDF level). Before: the search
    from the level mounting stopped in a local basin: xarm7 'tilt 0.59° ± 0.6°'."""
    import math

    from consistid.estimation.mounting import estimate_mounting, gravity_from_tilt

    model = ci.RobotModel.example(name)
    hung = model.with_gravity(gravity_from_tilt(model.gravity, (math.pi, math.radians(3.0))))
    data = ci.simulate.excitation_run(hung, model.prior_parameters, duration=10.0, rate=200.0,
                                      torque_noise=0.1, friction=None, seed=1).dataset
    est = estimate_mounting(model, data, friction=None)
    assert np.allclose(est.gravity, hung.gravity, atol=0.01 * 9.81)
    assert np.all(np.isfinite(est.std)) and est.relative_error[1] < est.relative_error[0]


def test_a_payload_no_motor_could_carry_is_flagged(loaded_run):
    """200 kg on the flange: the simulated torques reach 8× the URDF's efforts. Before: 'mass
    201 kg, found' without a word; now the data checks identify() runs say so."""
    from consistid.errors import DataQualityWarning

    model, frame, robot, _ = loaded_run
    heavy = robot.parameters[: model.n_inertial].copy()
    placement = model.pin_model.frames[model.pin_model.getFrameId(frame)].placement
    heavy[-10:] += frame_transform(placement.rotation, placement.translation) @ \
        from_mass_com_inertia(200.0, [0, 0, 0.05], 200.0 / 12 * 0.01 * np.eye(3))
    data = ci.simulate.excitation_run(model, heavy, duration=4.0, rate=200.0, torque_noise=0.2,
                                      seed=5).dataset
    with pytest.warns(DataQualityWarning, match="effort"):
        ci.estimate_payload(model, data, robot=robot, frame=frame)


def test_a_wall_mounted_robot_is_not_called_undetermined():
    """Gravity turned by 90° about x: the two-angle chart is singular there (the pitch turns
    nothing). Before: 'the data do not determine the mounting tilt … the model's gravity is kept
    there' although the data fixed gravity to 0.01°."""
    import math

    from consistid.errors import PoorExcitationWarning
    from consistid.estimation.mounting import estimate_mounting, gravity_from_tilt

    model = ci.RobotModel.example("ur5")
    wall = model.with_gravity(gravity_from_tilt(model.gravity, (math.pi / 2, 0.0)))
    data = ci.simulate.excitation_run(wall, model.prior_parameters, duration=10.0, rate=200.0,
                                      torque_noise=0.1, friction=None, seed=1).dataset
    with pytest.warns(PoorExcitationWarning, match="singular") as record:
        est = estimate_mounting(model, data, friction=None)
    assert not any("do not determine" in str(w.message) for w in record)
    assert np.allclose(est.gravity, wall.gravity, atol=0.005 * 9.81)


def test_a_failed_logdet_stage_points_to_the_euclidean_prior(planar_2r):
    """Planar 2R, coefficients whose link2 is ~4× its mass too light, σ = 0.01: Clarabel fails
    on the log-det stage of the nearest recovery. The error now says stage 1 succeeded and that
    prior='euclidean' solves — and it does (checked here)."""
    from consistid.errors import SolverError
    from consistid.robot.inertia import perturb

    base = ci.compute_base_parameters(planar_2r)
    truth = perturb(planar_2r.prior_parameters, 0.2, np.random.default_rng(0))
    truth[10] -= 5.0 * (truth[10] + 1.0)
    beta = base.project(truth)
    cov = np.eye(beta.size) * 1e-4
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rec = ci.recover_standard(planar_2r, beta, mode="nearest", covariance=cov,
                                      friction=None)
    except SolverError as exc:
        assert "prior='euclidean'" in str(exc)
    else:                               # a solver that copes must still give a consistent set
        assert rec.is_consistent
    rec = ci.recover_standard(planar_2r, beta, mode="nearest", covariance=cov, friction=None,
                              prior="euclidean")
    assert rec.is_consistent

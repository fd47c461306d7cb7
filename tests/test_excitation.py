"""Excitation trajectories, criteria, limits and the optimal design."""

from __future__ import annotations

import warnings

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import consistid as ci
from consistid.cli import main
from consistid.errors import (ExcitationError, InfeasibleExcitationError,
                             PoorExcitationWarning)
from consistid.excitation import (BoundaryConditions, BSplineParameterisation, CartesianBox,
                                  ExcitationLimits, FloorPlane, FourierPolynomial, KeepOutSphere,
                                  assess_excitation, design_excitation, end_effector_frame,
                                  random_excitation)
from consistid.excitation.criteria import criterion_and_gradient, regressor_sensitivity
from consistid.excitation.design import _DesignProblem
from consistid.excitation.limits import ConstraintSet
from consistid.excitation.trajectory import _polynomial_basis

PANDA_ACC = [15, 7.5, 10, 12.5, 15, 20, 20]          # Franka datasheet, rad/s²


@pytest.fixture(scope="module")
def panda_limits(panda):
    return ExcitationLimits.from_model(panda, acceleration=PANDA_ACC, floor=FloorPlane(0.2),
                                       sphere=KeepOutSphere(0.3))


# ------------------------------------------------------------------------------ trajectories
@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 10_000), free=st.booleans(), harmonics=st.integers(1, 6))
def test_fourier_polynomial_meets_boundary_and_matches_its_formula(seed, free, harmonics):
    rng = np.random.default_rng(seed)
    nv, T = 3, float(rng.uniform(2.0, 20.0))
    bc = BoundaryConditions(
        q_start=None if free else rng.standard_normal(nv),
        q_end=None if free else rng.standard_normal(nv),
        dq_start=rng.standard_normal(nv), dq_end=rng.standard_normal(nv),
        ddq_start=rng.standard_normal(nv), ddq_end=rng.standard_normal(nv))
    fp = FourierPolynomial(nv, harmonics, T, bc)
    x = rng.standard_normal((nv, fp.n_coefficients))
    q, dq, ddq = fp.evaluate(x, np.array([0.0, T]))
    if not free:
        np.testing.assert_allclose(q, [bc.q_start, bc.q_end], atol=1e-9)
    else:
        np.testing.assert_allclose(q[0], q[1], atol=1e-9)
    np.testing.assert_allclose(dq, [bc.dq_start, bc.dq_end], atol=1e-9)
    np.testing.assert_allclose(ddq, [bc.ddq_start, bc.ddq_end], atol=1e-8)
    # Independent evaluation of q0 + Σ a/(ωl) sin − b/(ωl) cos + Σ c_k (t/T)^k.
    parts = fp.unpack(x)
    t = rng.uniform(0.0, T, 7)
    w = 2 * np.pi / T * np.arange(1, harmonics + 1)
    expected = (parts["q0"] + (np.sin(np.outer(t, w)) / w) @ parts["a"].T
                - (np.cos(np.outer(t, w)) / w) @ parts["b"].T
                + np.vander(t / T, 6, increasing=True) @ parts["polynomial"].T)
    got = fp.evaluate(x, t)
    np.testing.assert_allclose(got[0], expected, atol=1e-9)
    h = 1e-5                                             # derivatives: central differences
    qp, dqp, _ = fp.evaluate(x, t + h)
    qm, dqm, _ = fp.evaluate(x, t - h)
    np.testing.assert_allclose((qp - qm) / (2 * h), got[1], rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose((dqp - dqm) / (2 * h), got[2], rtol=1e-5, atol=1e-4)


def test_polynomial_basis_derivatives():
    t = np.linspace(0, 3, 5)
    p = _polynomial_basis(t, 3.0)
    np.testing.assert_allclose(p[1][:, 3], 3 * (t / 3) ** 2 / 3)
    np.testing.assert_allclose(p[2][:, 5], 20 * (t / 3) ** 3 / 9)


def test_free_fourier_polynomial_repeats_smoothly():
    fp = FourierPolynomial(2, 3, 4.0)
    traj = fp.trajectory(np.random.default_rng(0).standard_normal((2, fp.n_coefficients)))
    assert fp.periodic
    eps = 1e-7
    before, after = traj.evaluate([4.0 - eps]), traj.evaluate([4.0 + eps])
    for a, b in zip(before, after):
        np.testing.assert_allclose(a, b, atol=1e-4)
    assert traj.sample(50.0, duration=12.0).n_samples == 600


def test_open_trajectory_cannot_be_sampled_beyond_its_end():
    fp = FourierPolynomial(2, 2, 4.0, BoundaryConditions(q_start=[0.0, 0.1], q_end=[0.5, 0.2]))
    traj = fp.trajectory(np.ones((2, fp.n_coefficients)))
    data = traj.sample(10.0)
    np.testing.assert_allclose(data.q[[0, -1]], [[0.0, 0.1], [0.5, 0.2]], atol=1e-12)
    assert data.t[-1] == pytest.approx(4.0)
    with pytest.raises(ExcitationError, match="non-periodic"):
        traj.sample(10.0, duration=8.0)


@pytest.mark.parametrize("degree", [4, 5])
@pytest.mark.parametrize("free", [True, False])
def test_bspline_interpolates_via_points_with_boundary_derivatives(degree, free):
    rng = np.random.default_rng(degree)
    times = np.array([0.0, 0.7, 1.5, 2.0, 3.1, 4.0])
    bc = BoundaryConditions(q_start=None if free else [0.3, -0.2],
                            dq_start=[0.5, -1.0], dq_end=[0.2, 0.0], ddq_end=[1.0, -2.0])
    bs = BSplineParameterisation(2, times, degree=degree, boundary=bc)
    x = rng.standard_normal((2, bs.n_coefficients))
    q, dq, ddq = bs.evaluate(x, times)
    vias = x if free else np.hstack([[[0.3], [-0.2]], x])
    np.testing.assert_allclose(q[:-1], vias.T, atol=1e-10)
    np.testing.assert_allclose(q[-1], vias[:, 0], atol=1e-10)     # closed: q_end = q_start
    np.testing.assert_allclose(dq[[0, -1]], [[0.5, -1.0], [0.2, 0.0]], atol=1e-9)
    np.testing.assert_allclose(ddq[[0, -1]], [[0.0, 0.0], [1.0, -2.0]], atol=1e-8)
    spline = bs.spline(x)                                           # scipy's own evaluation
    t = np.linspace(0, 4, 33)
    np.testing.assert_allclose(spline(t, nu=2), bs.evaluate(x, t)[2], atol=1e-9)
    inner = bs.knots[degree + 1:-degree - 1]
    jerk = spline.derivative(3)
    np.testing.assert_allclose(jerk(inner - 1e-9), jerk(inner + 1e-9), atol=1e-5)  # C³


def test_bspline_rejects_bad_times():
    with pytest.raises(ExcitationError, match="increasing"):
        BSplineParameterisation(2, [0.0, 2.0, 1.0, 3.0])


# ------------------------------------------------------------------------------ criteria
@pytest.mark.parametrize("criterion", ["cond", "d-opt", "e-opt"])
def test_criterion_gradient_matches_finite_differences(criterion):
    rng = np.random.default_rng(1)
    a = rng.standard_normal((30, 5))
    value, grad = criterion_and_gradient(a, criterion, 10)
    s = np.linalg.svd(a, compute_uv=False)
    closed = {"cond": s[0] / s[-1],
              "d-opt": -np.linalg.slogdet(a.T @ a / 10)[1],
              "e-opt": -np.log(np.linalg.eigvalsh(a.T @ a / 10)[0])}[criterion]
    assert value == pytest.approx(closed, rel=1e-10)
    h, fd = 1e-6, np.zeros_like(a)
    for i, j in [(0, 0), (3, 2), (17, 4), (29, 1)]:
        e = np.zeros_like(a)
        e[i, j] = h
        fd[i, j] = (criterion_and_gradient(a + e, criterion, 10)[0]
                    - criterion_and_gradient(a - e, criterion, 10)[0]) / (2 * h)
        assert grad[i, j] == pytest.approx(fd[i, j], rel=1e-5, abs=1e-7)


def test_regressor_sensitivity_matches_central_differences(panda):
    spec = ci.RegressorSpec.make(panda, ("viscous", "offset", "position"), armature=True)
    rng = np.random.default_rng(2)
    q, dq, ddq = rng.uniform(-1, 1, (3, 2, 7))
    y, dy = regressor_sensitivity(panda, q, dq, ddq, spec)
    np.testing.assert_allclose(y.reshape(-1, y.shape[-1]), ci.regressor(panda, q, dq, ddq, spec))
    h = 1e-5
    for which, k in [(0, 1), (0, 5), (1, 2), (2, 6)]:
        e = np.zeros((2, 7))
        e[:, k] = h
        args_p = [q, dq, ddq]
        args_m = [q, dq, ddq]
        args_p[which], args_m[which] = args_p[which] + e, args_m[which] - e
        fd = (ci.regressor(panda, *args_p, spec) - ci.regressor(panda, *args_m, spec)) / (2 * h)
        np.testing.assert_allclose(dy[:, which * 7 + k].reshape(fd.shape), fd, atol=2e-4)


def test_design_problem_gradients_match_finite_differences(panda):
    limits = ExcitationLimits.from_model(
        panda, acceleration=PANDA_ACC, floor=FloorPlane(0.1), sphere=KeepOutSphere(0.25),
        workspace=CartesianBox([-1, -1, 0], [1, 1, 1.4], frames=("panda_link7", "panda_hand_tcp")))
    spec = ci.RegressorSpec.make(panda, ("viscous",))
    base = ci.compute_base_parameters(panda, spec)
    param = FourierPolynomial(7, 2, 6.0)
    problem = _DesignProblem(panda, param, spec, base, ConstraintSet(panda, limits), "cond",
                             np.ones(7), np.linspace(1, 2, base.n_base), 5.0, 25, 0.01)
    rng = np.random.default_rng(3)
    x = param.rest(np.array([0, 0.3, 0, -1.5, 0, 1.5, 0])).ravel()
    x = x + 0.05 * rng.standard_normal(x.size)
    g, jac = problem.gradient(x), problem.nonlinear_jacobian(x)
    h = 1e-6
    for i in rng.choice(x.size, 6, replace=False):
        e = np.zeros_like(x)
        e[i] = h
        fd = (problem.objective(x + e) - problem.objective(x - e)) / (2 * h)
        assert g[i] == pytest.approx(fd, rel=1e-3, abs=1e-4)
        fd_c = (problem.nonlinear_margins(x + e) - problem.nonlinear_margins(x - e)) / (2 * h)
        np.testing.assert_allclose(jac[:, i], fd_c, atol=1e-5)


# ------------------------------------------------------------------------------ limits
def test_zero_velocity_limit_raises_named_error(panda):
    limits = ExcitationLimits.from_model(panda, velocity=[2.0, 2.0, 0.0, 2.0, 2.0, 2.0, 2.0])
    with pytest.raises(InfeasibleExcitationError, match="velocity limit of joint 'panda_joint3'"):
        design_excitation(panda, harmonics=1, n_starts=1, max_iter=1, limits=limits)


def test_empty_position_range_and_unreachable_floor_raise(panda):
    lim = ExcitationLimits.from_model(panda, lower=0.5, upper=0.5)
    with pytest.raises(InfeasibleExcitationError, match="no range"):
        design_excitation(panda, harmonics=1, n_starts=1, max_iter=1, limits=lim)
    lim = ExcitationLimits.from_model(panda, floor=FloorPlane(3.0))
    with pytest.raises(InfeasibleExcitationError, match="no feasible rest pose"):
        design_excitation(panda, harmonics=1, n_starts=1, max_iter=1, limits=lim, n_grid=20)


@pytest.mark.parametrize("name, frame", [("panda", "panda_hand_tcp"), ("ur5", "tool0"),
                                         ("kinova", "j2s6s200_end_effector")])
def test_end_effector_is_the_outermost_frame_of_the_last_joint(name, frame):
    """Not the last body frame of the URDF: on the Kinova that is a finger tip, 5 mm nearer
    the wrist than the end-effector frame."""
    model = ci.RobotModel.example(name)
    assert end_effector_frame(model) == frame
    pm = model.pin_model
    data = pm.createData()
    pin.framesForwardKinematics(pm, data, pin.randomConfiguration(pm))
    wrist = data.oMi[pm.njoints - 1].translation
    reach = {f.name: np.linalg.norm(data.oMf[k].translation - wrist)
             for k, f in enumerate(pm.frames) if f.parentJoint == pm.njoints - 1}
    assert reach[frame] >= max(reach.values()) - 1e-9
    tool = pin.Frame("tool_tip", pm.njoints - 1, pm.frames[pm.getFrameId(frame)].parentFrame,
                     pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.3])), pin.FrameType.OP_FRAME)
    pm.addFrame(tool)
    assert end_effector_frame(model) == "tool_tip"


# ------------------------------------------------------------------------------ the design
@pytest.fixture(scope="module")
def small_design(panda, panda_limits):
    return design_excitation(panda, harmonics=3, period=8.0, seed=1, friction=None, n_starts=2,
                             max_iter=25, n_grid=80, n_check=800, limits=panda_limits)


def test_design_improves_and_respects_limits_on_a_dense_grid(panda, panda_limits, small_design):
    d = small_design
    assert len(d.starts) == 2 and d.cond < 100
    assert all(s.value < s.initial_value for s in d.starts)
    assert d.value == min(s.value for s in d.starts if s.feasible)
    # Independent dense check: limits by hand, torque from RNEA, floor/sphere from Pinocchio FK.
    data = d.sample(500.0)
    lim = panda_limits
    assert np.all((data.q >= lim.lower) & (data.q <= lim.upper))
    assert np.all(np.abs(data.dq) <= lim.velocity) and np.all(np.abs(data.ddq) <= lim.acceleration)
    assert np.all(np.abs(panda.rnea(data.q, data.dq, data.ddq)) <= lim.torque)
    m, pdata = panda.pin_model, panda.pin_model.createData()
    fid = m.getFrameId("panda_hand_tcp")
    for q in data.q[::5]:
        pin.framesForwardKinematics(m, pdata, q)
        p = pdata.oMf[fid].translation
        assert p[2] >= 0.2 and np.linalg.norm(p) >= 0.3
    assert d.constraints.feasible and d.constraints["floor"].value >= 0
    # The reported cond is the unscaled base regressor's, as identify() computes it.
    yb = d.base.base_columns(ci.regressor(panda, data.q, data.dq, data.ddq))
    assert d.cond == pytest.approx(np.linalg.cond(yb), rel=0.02)


def test_design_is_deterministic_and_reports_progress(panda, panda_limits):
    seen = []
    kw = dict(harmonics=2, period=6.0, seed=7, friction=None, n_starts=1, max_iter=4, n_grid=40,
              n_check=200, limits=panda_limits)
    a = design_excitation(panda, progress=seen.append, **kw)
    b = design_excitation(panda, **kw)
    np.testing.assert_array_equal(a.trajectory.coefficients, b.trajectory.coefficients)
    assert [s.index for s in seen] == [0]


def test_optimised_trajectory_gives_smaller_standard_deviations(panda, panda_limits,
                                                                small_design):
    random = random_excitation(panda, harmonics=3, period=8.0, seed=3, limits=panda_limits)
    assert assess_excitation(panda, random, panda_limits, friction=None).cond > small_design.cond
    std = {}
    for name, traj in (("optimised", small_design.trajectory), ("random", random)):
        run = ci.simulate.excitation_run(panda, duration=16.0, rate=100.0, torque_noise=0.2,
                                         trajectory=traj, seed=11)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", PoorExcitationWarning)   # the random one may warn
            res = ci.identify(panda, run.dataset, method="ols", friction=None)
        std[name] = res.base_std
        if name == "optimised":
            assert res.condition_number == pytest.approx(small_design.cond, rel=0.02)
    assert np.median(std["optimised"]) < np.median(std["random"])
    assert std["optimised"].max() < std["random"].max()


def test_csv_round_trip(small_design, tmp_path):
    path = small_design.save_csv(tmp_path / "traj.csv", 50.0)
    loaded = ci.Dataset.load(path)
    sampled = small_design.sample(50.0)
    assert loaded.tau is None
    np.testing.assert_allclose(loaded.q, sampled.q, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(loaded.ddq, sampled.ddq, rtol=1e-9, atol=1e-12)


def test_bspline_design_with_imposed_start(planar_2r):
    q_start = [0.2, -0.4]
    d = design_excitation(planar_2r, period=4.0, trajectory="bspline", via_points=5,
                          boundary=BoundaryConditions(q_start=q_start), friction=("viscous",),
                          n_starts=1, max_iter=15, n_grid=60, n_check=400)
    data = d.sample(100.0)
    np.testing.assert_allclose(data.q[0], q_start, atol=1e-12)
    np.testing.assert_allclose(data.dq[0], 0.0, atol=1e-12)
    assert d.constraints.feasible and np.isfinite(d.cond)


@pytest.mark.parametrize("method, criterion", [("SLSQP", "e-opt"), ("trust-constr", "d-opt")])
def test_methods_and_criteria_improve_the_design(planar_2r, method, criterion):
    d = design_excitation(planar_2r, harmonics=2, period=4.0, criterion=criterion,
                          friction=None, method=method, n_starts=1, max_iter=10, n_grid=40,
                          n_check=400, seed=2)
    start = d.starts[0]
    assert start.value < start.initial_value and d.constraints.feasible
    assert d.value == pytest.approx(d.quality.criteria[criterion], rel=0.05)


def test_cli_excite_writes_a_csv(planar_2r, tmp_path):
    cfg = tmp_path / "excite.toml"
    cfg.write_text(f"""
[model]
urdf = "{planar_2r.source}"
gravity = [0.0, -9.81, 0.0]

[excite]
harmonics = 2
period = 4.0
friction = []
n_starts = 1
max_iter = 5
n_grid = 40
rate = 50.0
output = "out.csv"

[excite.limits]
acceleration = 20.0
sphere = {{ radius = 0.2 }}
""")
    assert main(["excite", str(cfg)]) == 0
    data = ci.Dataset.load(tmp_path / "out.csv")
    assert data.nv == 2 and data.n_samples == 200
    cfg.write_text(cfg.read_text().replace("max_iter = 5", "max_iters = 5"))
    assert main(["excite", str(cfg)]) == 2


# ------------------------------------------------------------------------------ unset limits
def test_urdf_without_efforts_designs_with_torque_unchecked():
    """The double pendulum's URDF sets no effort (read as inf): no torque columns, no NaN."""
    model = ci.RobotModel.example("double_pendulum")
    assert np.all(np.isinf(model.limits.effort))
    limits = ExcitationLimits.from_model(model)
    assert limits.torque is None
    d = design_excitation(model, harmonics=2, period=4.0, friction=None, n_starts=1,
                          max_iter=5, n_grid=30, n_check=200)
    assert d.constraints.feasible
    assert {m.kind for m in d.constraints.margins} == {"acceleration"}


def test_torque_columns_only_for_joints_with_a_finite_limit(planar_2r):
    limits = ExcitationLimits.from_model(planar_2r, torque=[np.inf, 5.0])
    q, dq, ddq = np.array([[0.3, -0.2]]), np.array([[0.5, 1.0]]), np.array([[2.0, -1.0]])
    (block,) = ConstraintSet(planar_2r, limits).blocks(q, dq, ddq, derivatives=True,
                                                       linear=False)
    assert block.labels == ("joint2 lower", "joint2 upper")
    tau = planar_2r.rnea(q, dq, ddq)[0, 1]
    np.testing.assert_allclose(block.values[0], [tau + 5.0, 5.0 - tau])
    np.testing.assert_allclose(block.scale, [5.0, 5.0])
    _, _, mass = pin.computeRNEADerivatives(planar_2r.pin_model, planar_2r.pin_model.createData(),
                                            q[0], dq[0], ddq[0])
    np.testing.assert_allclose(block.derivative[0, 0, 2], mass[1])     # ∂τ_2/∂q̈
    np.testing.assert_allclose(block.derivative[0, 1, 2], -mass[1])


def test_constraint_report_refuses_nan():
    from consistid.excitation.limits import ConstraintReport, Margin
    with pytest.raises(ExcitationError, match="'joint1 upper'"):
        ConstraintReport((Margin("torque", np.nan, np.nan, "joint1 upper", 0.5),), 10)


def test_one_sided_position_limit_is_feasible(planar_2r):
    """A joint bounded below only: its margin is scaled by one turn (2π), not by inf."""
    limits = ExcitationLimits.from_model(planar_2r, lower=[-1.0, -1.0], upper=[np.inf, 3.0],
                                         acceleration=20.0)
    q = np.array([[0.0, 0.0], [1.0, 2.0]])
    (pos,) = [b for b in ConstraintSet(planar_2r, limits).blocks(q, q, q, linear=True)
              if b.kind == "position"]
    assert pos.labels == ("joint1 lower", "joint2 lower", "joint2 upper")
    np.testing.assert_allclose(pos.scale, [2 * np.pi, 4.0, 4.0])
    np.testing.assert_allclose(pos.values[1], [2.0, 3.0, 1.0])
    d = design_excitation(planar_2r, harmonics=2, period=4.0, friction=None, n_starts=1,
                          max_iter=5, n_grid=30, n_check=200, limits=limits)
    margin = d.constraints["position"]
    assert d.constraints.feasible and 0 < margin.relative < 1


def test_limit_vectors_accept_inf_and_refuse_nan(planar_2r):
    lim = ExcitationLimits.from_model(planar_2r, velocity=[np.inf, 2.0], upper=np.inf,
                                      torque=np.inf)
    np.testing.assert_array_equal(lim.velocity, [np.inf, 2.0])
    np.testing.assert_array_equal(lim.upper, [np.inf, np.inf])
    assert lim.torque is None
    for kw in (dict(velocity=np.nan), dict(lower=[0.0, np.nan]), dict(torque=np.nan)):
        with pytest.raises(ExcitationError, match="NaN"):
            ExcitationLimits.from_model(planar_2r, **kw)
    with pytest.raises(ExcitationError, match="not finite"):
        ExcitationLimits.from_model(planar_2r, acceleration=np.nan)      # scalar path too
    with pytest.raises(ExcitationError, match="not finite"):
        BoundaryConditions(q_start=[0.0, np.inf]).resolved(2)


# ------------------------------------------------------------------------------ options
def test_torque_weight_needs_the_cond_criterion(planar_2r):
    with pytest.raises(ci.errors.OptionError, match="torque_weight.*'d-opt'"):
        design_excitation(planar_2r, criterion="d-opt", torque_weight=1.0, n_starts=1)
    with pytest.raises(ci.errors.OptionError, match="torque_weight"):
        design_excitation(planar_2r, torque_weight=-1.0, n_starts=1)


def test_random_excitation_needs_no_base_parameters(planar_2r, monkeypatch):
    import consistid.excitation.design as design

    def fail(*args, **kwargs):
        raise AssertionError("random_excitation computed base parameters")

    monkeypatch.setattr(design, "compute_base_parameters", fail)
    limits = ExcitationLimits.from_model(planar_2r, acceleration=20.0)
    traj = random_excitation(planar_2r, harmonics=2, period=4.0, seed=1, limits=limits,
                             n_grid=40)
    data = traj.sample(100.0)
    assert np.all(np.abs(data.ddq) <= 20.0 * (1 + 1e-6))
    assert np.all((data.q >= limits.lower) & (data.q <= limits.upper))


def test_config_friction_string_is_one_term(planar_2r, tmp_path):
    from consistid.cli.excite import load_excitation_config
    cfg = tmp_path / "excite.toml"
    cfg.write_text(f'[model]\nurdf = "{planar_2r.source}"\n\n[excite]\nfriction = "viscous"\n')
    assert load_excitation_config(cfg).options["friction"] == ("viscous",)
    cfg.write_text(cfg.read_text().replace('"viscous"', '["viscous", "coulomb"]'))
    assert load_excitation_config(cfg).options["friction"] == ("viscous", "coulomb")
    cfg.write_text(cfg.read_text().replace('["viscous", "coulomb"]', "[]"))
    assert load_excitation_config(cfg).options["friction"] is None


def test_fourier_trajectory_validates_its_fields():
    from consistid.excitation import FourierTrajectory
    from consistid.errors import JointCountError
    a = np.array([[0.1, 0.2], [0.3, -0.1]])
    traj = FourierTrajectory(a.tolist(), (-a).tolist(), [0.0, 0.5], 2)
    assert traj.harmonics == 2 and traj.period == 2.0
    q, dq, _ = traj.evaluate([0.25])                 # the formula, by hand
    w = np.pi * np.arange(1, 3)
    np.testing.assert_allclose(q[0], [0.0, 0.5] + (a * np.sin(w / 4) / w).sum(1)
                               + (a * np.cos(w / 4) / w).sum(1))
    np.testing.assert_allclose(dq[0], (a * np.cos(w / 4)).sum(1) - (a * np.sin(w / 4)).sum(1))
    for args, match in [((a, a[:, :1], [0, 0], 2.0), "a .* and b"),
                        ((a[0], a[0], [0, 0], 2.0), "a .* and b"),
                        ((a[:, :0], a[:, :0], [0, 0], 2.0), "H ≥ 1"),
                        ((a, a, [0, 0], 0.0), "period"),
                        ((a, a, [0, 0], np.nan), "period"),
                        ((a, a * np.nan, [0, 0], 2.0), "Fourier b")]:
        with pytest.raises(ExcitationError, match=match):
            FourierTrajectory(*args)
    with pytest.raises(JointCountError, match="q0"):
        FourierTrajectory(a, a, [0.0], 2.0)
    for rate, duration in [(0.0, None), (-5.0, None), (10.0, -1.0)]:
        with pytest.raises(ExcitationError, match="rate|duration"):
            traj.sample(rate, duration)
    assert traj.sample(10.0).n_samples == 20


def test_array_holding_values_compare_by_identity_instead_of_raising(planar_2r):
    """A field-wise ``==`` on ndarray fields raises ('truth value of an array is ambiguous')."""
    import dataclasses
    from consistid.excitation import FourierTrajectory
    fourier = FourierTrajectory.random(planar_2r, 2, 2.0, seed=0)
    fp = FourierPolynomial(2, 2, 2.0)
    limits = ExcitationLimits.from_model(planar_2r)
    for value in (fourier, fp.trajectory(0.1 * np.ones((2, fp.n_coefficients))), limits,
                  BoundaryConditions(q_start=np.zeros(2))):
        twin = dataclasses.replace(value)
        assert value == value and value != twin and len({value, twin}) == 2


def test_cartesian_shapes_compare_and_check_their_inputs():
    # arrays or lists, the same shape: equal (they used to raise on ==)
    assert CartesianBox(np.array([-1, -1, 0]), np.array([1, 1, 1.4])) == \
        CartesianBox([-1, -1, 0], [1, 1, 1.4])
    assert KeepOutSphere(0.3, np.zeros(3), frames="panda_hand") == \
        KeepOutSphere(0.3, (0, 0, 0), frames=("panda_hand",))
    for make, message in ((lambda: CartesianBox([0, 0], [1, 1, 1]), "lower must be 3 finite"),
                          (lambda: CartesianBox([0, 0, 2], [1, 1, 1]), "lower ≤ upper"),
                          (lambda: KeepOutSphere(-0.1), "radius must be a finite number > 0"),
                          (lambda: KeepOutSphere(0.2, centre=[0, np.nan, 0]), "centre must be"),
                          (lambda: FloorPlane("low"), "z_min must be a finite number")):
        with pytest.raises(ci.ExcitationError, match=message):
            make()


def test_design_options_of_the_wrong_type_are_named(panda):
    for options, message in ((dict(harmonics="5"), "harmonics must be an integer"),
                             (dict(n_starts=1.5), "n_starts must be an integer, got 1.5"),
                             (dict(seed="x"), "seed must be an integer"),
                             (dict(period="10"), "period must be a finite number")):
        with pytest.raises(ci.OptionError, match=message):
            design_excitation(panda, **{**dict(harmonics=2, period=2.0, n_starts=1), **options})
    with pytest.raises(ci.ModelError, match="model must be a consistid.RobotModel"):
        design_excitation("panda", harmonics=2, period=2.0, n_starts=1)

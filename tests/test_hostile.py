"""Hostile and degenerate inputs to the public API (issue 14): every case ends in a named
consistid error whose message names the cause (field, index, joint, option, body, file), or in
an answer whose numbers are finite and whose warnings say what the data do not inform.

Fast by construction: the planar 2R arm of ``conftest.py`` and a few hundred samples. The CLI's
cases are in ``test_hostile_cli.py``.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import consistid as ci
from consistid.data.checks import MAX_ABS
from consistid.errors import (DataQualityWarning, NothingFoundWarning, OptionError,
                              PoorExcitationWarning, SolverError)
from consistid.estimation import recover as recover_module
from consistid.identification.solver import solve
from consistid.identification.regressor import regressor
from consistid.robot import inertia
from consistid.robot.shapes import Ellipsoid

from .conftest import PLANAR_2R, PLANAR_2R_VALUES, random_states

N = 300


@pytest.fixture(scope="module")
def arm(planar_2r):
    return planar_2r


@pytest.fixture(scope="module")
def states(arm):
    q, dq, ddq = random_states(arm, N, 0)
    rng = np.random.default_rng(1)
    tau = arm.rnea(q, dq, ddq) + 0.01 * rng.standard_normal((N, 2))
    return {"t": np.arange(N) * 0.01, "q": q, "dq": dq, "ddq": ddq, "tau": tau}


def dataset(states, **changes):
    fields = {k: np.array(v, copy=True) for k, v in states.items()}
    for k, v in changes.items():
        fields[k] = v
    return ci.Dataset(**fields)


@pytest.fixture(scope="module")
def data(states):
    return dataset(states)


@pytest.fixture(scope="module")
def ols(arm, data):
    return ci.identify(arm, data, method="ols", friction=None)


def poke(a, index, value):
    a = np.array(a, dtype=float, copy=True)
    a[index] = value
    return a


# ================================================================= 1. Dataset construction
NONFINITE = [(f, idx, v) for f in ("t", "q", "dq", "ddq", "tau")
             for idx, v in (((0, 0), np.nan), ((17, 1), np.inf), ((N - 1, 0), -np.inf))]


@pytest.mark.parametrize("field,index,value", NONFINITE,
                         ids=[f"{f}-{i}-{v}" for f, i, v in NONFINITE])
def test_non_finite_values_name_field_and_index(states, field, index, value):
    idx = index[0] if field == "t" else index
    first = idx if field == "t" else idx[0]
    with pytest.raises(ci.DatasetError, match=rf"dataset\.{field}\[{first}"):
        dataset(states, **{field: poke(states[field], idx, value)})


SHAPES = [
    ("t", np.zeros((N, 2)), "must be 1-D"),
    ("t", np.zeros(0), "empty"),
    ("q", np.zeros((N - 1, 2)), r"dataset\.q has shape"),
    ("dq", np.zeros((N, 3)), r"dataset\.dq has 3 joints"),
    ("ddq", np.zeros((N, 2, 2)), r"dataset\.ddq has shape"),
    ("tau", np.zeros((N + 1, 2)), r"dataset\.tau has shape"),
    ("q", None, r"dataset\.q is missing"),
    ("t", np.r_[0.0, np.zeros(N - 1)], r"t\[\d+\].*strictly increasing"),
    ("t", np.arange(N)[::-1] * 0.01, r"t\[1\].*strictly increasing"),
]


@pytest.mark.parametrize("field,value,message", SHAPES,
                         ids=[f"{f}-{m[:12]}" for f, _, m in SHAPES])
def test_malformed_fields_name_the_field(states, field, value, message):
    with pytest.raises(ci.DatasetError, match=message):
        dataset(states, **{field: value})


def test_segment_and_joint_names_are_checked(states):
    with pytest.raises(ci.DatasetError, match=r"segment\[3\] = 0.5"):
        dataset(states, segment=poke(np.zeros(N), 3, 0.5))
    with pytest.raises(ci.DatasetError, match="segment has shape"):
        dataset(states, segment=np.zeros(N - 2))
    with pytest.raises(ci.DatasetError, match="3 names for 2 joints"):
        dataset(states, joint_names=("a", "b", "c"))


def test_text_in_arrays_is_a_named_error_not_a_numpy_traceback(states):
    with pytest.raises((ci.DatasetError, ValueError)) as err:
        dataset(states, q=np.full((N, 2), "x"))
    assert isinstance(err.value, ci.ConsistidError) or "could not convert" in str(err.value)


# ================================================================= 2. checks before numerics
@pytest.mark.parametrize("method", ["ols", "wls", "sdp"])
@pytest.mark.parametrize("field", ["q", "dq", "ddq", "tau"])
def test_values_of_1e300_are_refused_before_the_linear_algebra(arm, states, method, field):
    bad = dataset(states, **{field: poke(states[field], (41, 1), 1e300)})
    with pytest.raises(ci.DatasetError, match=rf"dataset\.{field}\[41, 'joint2'\] = 1e\+300"):
        ci.identify(arm, bad, method=method, friction=None)


@pytest.mark.parametrize("method", ["ols", "wls", "sdp"])
def test_all_zero_torque_is_a_dead_channel(arm, states, method):
    with pytest.raises(ci.DatasetError, match=r"tau\[:, 'joint1'\] is 0 in all 300 samples"):
        ci.identify(arm, dataset(states, tau=np.zeros((N, 2))), method=method, friction=None)


def test_one_dead_torque_channel_is_named_and_left_out(arm, states):
    """Issue 26: a dead channel among live ones is warned and excluded, not fatal."""
    tau = states["tau"].copy()
    tau[:, 1] = 0.0
    with pytest.warns(ci.errors.DataQualityWarning, match=r"\['joint2'\] read one value"):
        res = ci.identify(arm, dataset(states, tau=tau), method="sdp", friction=None)
    assert res.excluded_joints == ("joint2",) and np.isnan(res.sigma[1])


@pytest.mark.parametrize("method", ["ols", "wls", "sdp"])
def test_no_motion_at_all_is_an_error(arm, states, method):
    q = np.tile([0.3, -0.2], (N, 1))
    still = dataset(states, q=q, dq=0 * q, ddq=0 * q, tau=arm.rnea(q, 0 * q, 0 * q))
    with pytest.raises(ci.PoorExcitationError, match="no motion at all"):
        ci.identify(arm, still, method=method, friction=None)


@pytest.mark.parametrize("method", ["ols", "sdp"])
@pytest.mark.parametrize("field", ["dq", "ddq", "tau"])
def test_a_single_glitch_warns_with_its_sample_and_joint(arm, states, method, field):
    value = poke(states[field], (123, 0), 1e5)
    with pytest.warns(DataQualityWarning, match=rf"{field}\[123, 'joint1'\] = 1e\+05"):
        res = ci.identify(arm, dataset(states, **{field: value}), method=method, friction=None)
    assert np.all(np.isfinite(res.parameters))


def test_clean_simulated_data_raise_no_glitch_warning(arm, data):
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataQualityWarning)
        ci.identify(arm, data, method="ols", friction=None)


def test_wrong_joint_count_and_missing_torque(arm, states):
    three = {k: (v if v.ndim == 1 else np.column_stack([v, v[:, :1]])) for k, v in states.items()}
    with pytest.raises(ci.JointCountError, match="dataset has 3 joints but the model has 2"):
        ci.identify(arm, ci.Dataset(**three))
    with pytest.raises(ci.DatasetError, match="tau is missing"):
        ci.identify(arm, dataset(states, tau=None))


@pytest.mark.parametrize("value,message", [
    ("run.csv", "must be a Dataset"), (42, "must be a Dataset"), ([], "empty list"),
    ([1, 2], r"dataset\[0\] is a int"), (None, "must be a Dataset")])
def test_what_is_not_a_dataset_is_named(arm, value, message):
    with pytest.raises(ci.DatasetError, match=message):
        ci.identify(arm, value, method="ols")


@pytest.mark.parametrize("model", [None, "panda", 3.0])
def test_what_is_not_a_model_is_named(data, model):
    with pytest.raises(ci.ModelError, match="must be a consistid.RobotModel"):
        ci.identify(model, data)


# ================================================================= 3. uninformed directions
def one_sample(states):
    return dataset({k: v[:1] for k, v in states.items()})


def repeated(states):
    return dataset({k: (np.repeat(v[:1], N, axis=0) if v.ndim == 2 else v)
                    for k, v in states.items()})


def frozen_joint2(arm, states):
    q, dq, ddq = (np.column_stack([states[k][:, 0], 0 * states[k][:, 1]])
                  for k in ("q", "dq", "ddq"))
    # joint 2 never moves and its torque channel only sees gravity and coupling
    return dataset(states, q=q, dq=dq, ddq=ddq, tau=arm.rnea(q, dq, ddq) + 0.01)


UNINFORMATIVE = {"one sample": one_sample, "one state repeated": repeated}


@pytest.mark.parametrize("prior", ["logdet", "euclidean"])
@pytest.mark.parametrize("case", sorted(UNINFORMATIVE))
def test_sdp_names_what_the_data_leave_to_the_prior(arm, states, case, prior):
    data = UNINFORMATIVE[case](states)
    with pytest.warns(PoorExcitationWarning, match=rf"do not inform \d of 6 .*{prior} prior alone"):
        res = ci.identify(arm, data, method="sdp", prior=prior, friction=None)
    assert res.uninformed and all("β" in u for u in res.uninformed)
    assert "Not informed by the data" in res.summary() and "the prior alone" in res.summary()
    assert np.all(np.isfinite(res.parameters))
    # what is not informed has infinite σ; what is informed does not
    assert np.sum(~np.isfinite(res.base_std)) >= 1
    assert not np.any(np.isnan(res.relative_std)) and not np.any(np.isnan(res.conf_int()))


@pytest.mark.parametrize("case", sorted(UNINFORMATIVE))
@pytest.mark.parametrize("method", ["ols", "wls"])
def test_least_squares_refuses_and_names_groupings(arm, states, case, method):
    with pytest.raises(ci.PoorExcitationError, match=r"equations for 6|β\d+ = |β\d"):
        ci.identify(arm, UNINFORMATIVE[case](states), method=method, friction=None)


def test_without_prior_the_constraints_decide_and_the_result_says_so(arm, states):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            res = ci.identify(arm, repeated(states), method="sdp", prior=None, friction=None)
        except ci.IdentificationError as exc:     # unbounded free directions: named
            assert "prior" in str(exc)
            return
    assert res.uninformed
    assert any("constraints alone" in str(w.message) for w in caught)


def test_informative_data_leave_nothing_uninformed(arm, data):
    with warnings.catch_warnings():
        warnings.simplefilter("error", PoorExcitationWarning)
        res = ci.identify(arm, data, method="sdp", friction=None)
    assert res.uninformed == () and "Not informed" not in res.summary()
    assert np.all(np.isfinite(res.base_std))


def test_uninformed_groupings_read_as_base_parameters(arm, states):
    """One sample of a 2R arm: the rows of R_b are 2, the base parameters 6, so 4 directions
    are uninformed; each names a base parameter and its regrouping (like
    compute_base_parameters)."""
    with pytest.warns(PoorExcitationWarning):
        res = ci.identify(arm, one_sample(states), method="sdp", friction=None)
    assert len(res.uninformed) == 4
    groupings = ci.compute_base_parameters(arm).groupings
    assert all(any(g in u for g in groupings) for u in res.uninformed)


@pytest.mark.parametrize("robot", ["ur5", "xarm7", "kinova"])
def test_a_first_joint_that_never_moves_on_other_arms(robot):
    """Not tuned on: joint 1 frozen leaves the base parameters it alone drives (its link's
    Izz grouping, inertia products of link 2) to the prior; the SDP names them, OLS refuses."""
    model = ci.RobotModel.example(robot)
    q, dq, ddq = random_states(model, 150, 3)
    for a in (q, dq, ddq):
        a[:, 0] = 0.0
    tau = model.rnea(q, dq, ddq) + 0.01 * np.random.default_rng(4).standard_normal(q.shape)
    data = ci.Dataset(t=np.arange(150) * 0.01, q=q, dq=dq, ddq=ddq, tau=tau)
    with pytest.warns(PoorExcitationWarning, match="do not inform") as caught:
        res = ci.identify(model, data, friction=None)
    assert len(res.uninformed) >= 3
    second = model.body_names[1]
    assert any(second in u for u in res.uninformed)
    assert all(u.split(" = ")[0].startswith("β") for u in res.uninformed)
    assert any(str(len(res.uninformed)) in str(w.message) for w in caught)
    with pytest.raises(ci.PoorExcitationError, match=rf"do not excite {len(res.uninformed)} of"):
        ci.identify(model, data, method="ols", friction=None)


def test_null_directions_of_a_known_factor():
    from consistid.identification.uninformed import null_directions

    r = np.array([[1.0, 1.0, 0.0], [0.0, 0.0, 2.0]])      # β1 + β2 informed, β3 informed
    rows = null_directions(r)
    assert rows.shape == (1, 3)
    np.testing.assert_allclose(rows[0] / rows[0][np.argmax(np.abs(rows[0]))],
                               [1.0, -1.0, 0.0] if rows[0][0] > 0 else [-1.0, 1.0, 0.0],
                               atol=1e-12)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(b=st.integers(2, 12), rank=st.integers(0, 12), seed=st.integers(0, 1000))
def test_null_directions_span_the_null_space(b, rank, seed):
    """Rows are in the null space of r_b, independent, and as many as b − rank (numpy's rank,
    an independent computation)."""
    from consistid.identification.uninformed import null_directions

    rank = min(rank, b)
    rng = np.random.default_rng(seed)
    r = rng.normal(size=(b, rank)) @ rng.normal(size=(rank, b))
    rows = null_directions(r)
    tol = 1e-11 * max(1e-300, np.linalg.norm(r, 2))
    assert rows.shape == (b - np.linalg.matrix_rank(r, tol=tol), b)
    if rows.size:
        assert np.max(np.abs(r @ rows.T)) <= 1e-8 * max(1.0, np.linalg.norm(r, 2)) \
            * np.max(np.abs(rows))
        assert np.linalg.matrix_rank(rows) == rows.shape[0]


# ================================================================= 4. options
OPTIONS = [
    (dict(method="lsq"), "method='lsq'"),
    (dict(covariance="white"), "covariance='white'"),
    (dict(prior="gauss"), "prior='gauss'"),
    (dict(constraints="solid"), "constraints='solid'"),
    (dict(constraints={"nobody": "triangle"}), "unknown bodies"),
    (dict(prior_weight=-1.0), "prior_weight must be"),
    (dict(prior_weight=float("nan")), "prior_weight must be"),
    (dict(prior_weight="heavy"), "prior_weight must be"),
    (dict(prior_uncertainty=0.0), "prior_uncertainty must be"),
    (dict(prior_weight=1.0, prior_uncertainty=0.3), "not both"),
    (dict(prior=None, prior_weight=1.0), "prior=None has none"),
    (dict(sigma=[1.0]), "sigma must be 2 finite values"),
    (dict(sigma=[1.0, -1.0]), "sigma must be 2 finite values"),
    (dict(sigma=[1.0, float("nan")]), "sigma must be 2 finite values"),
    (dict(margin=-1e-3), "margin must be"),
    (dict(reweight=-1), "reweight must be"),
    (dict(reweight=1.5), "reweight must be"),
    (dict(loss="l1"), "loss='l1'"),
    (dict(loss="huber", covariance="coloured"), "not with loss='huber'"),
    (dict(huber_threshold=1.0), "huber_threshold applies to loss='huber'"),
    (dict(solver="GUROBI_NOT_HERE"), "solver='GUROBI_NOT_HERE'"),
    (dict(mass_bounds={"link1": (1.0,)}), r"mass_bounds\['link1'\]"),
    (dict(mass_bounds={"link1": (None, "x")}), r"mass_bounds\['link1'\] bound"),
    (dict(mass_bounds=[1, 2]), "mass_bounds must be a mapping"),
    (dict(com_boxes={"link1": ([0, 0], [1, 1])}), r"com_boxes\['link1'\]"),
    (dict(com_boxes={"link1": ([1, 0, 0], [0, 1, 1])}), r"com_boxes\['link1'\]"),
    (dict(total_mass=(float("inf"), None)), "total_mass bound"),
    (dict(total_mass=5.0), "total_mass must be a pair"),
    (dict(constraints="ellipsoid"), r"bodies \['link1', 'link2'\] have constraints='ellipsoid'"),
    (dict(ellipsoids={"link1": Ellipsoid.from_semi_axes([0, 0, 0], [1, 1, 1])}),
     "whose constraints level is not 'ellipsoid'"),
    (dict(prior_weights=np.ones(3), prior="euclidean"), "prior_weights must be finite"),
    (dict(prior_weights=np.ones(20)), "prior_weights are the Euclidean prior's metric"),
    (dict(friction=("coulomb", "stiction")), "stiction"),
    (dict(armature=["joint9"]), "joint9"),
    (dict(margin=1.0), "margin ≥ 1 excludes the prior itself"),
    (dict(prior_uncertainty=1e-300), "gives the prior weight 2/r² = inf"),
    (dict(scale="yes"), "scale must be True or False"),
    (dict(friction_nonnegative=3), "friction_nonnegative must be True or False"),
    (dict(solver_options=5), "solver_options must be a mapping"),
    (dict(solver_options={"max_iter": "x"}), "could not run with the options"),
    (dict(neighbourhood=ci.identification.priors.Neighbourhood(mass=0.1), prior=None,
          prior_weight=2.0), "prior=None has none"),
    (dict(method="ols", prior="logdet"), "apply to method='sdp' only"),
    (dict(method="wls", margin=0.1), "apply to method='sdp' only"),
]


@pytest.mark.parametrize("options,message", OPTIONS, ids=[m[:30] for _, m in OPTIONS])
def test_bad_options_name_the_option(arm, data, options, message):
    with pytest.raises(ci.ConsistidError, match=message):
        ci.identify(arm, data, **{"friction": None, **options})


# ================================================================= 5. the solver contract
class PanicException(BaseException):
    """Stands for pyo3's PanicException, which derives from BaseException."""


def test_a_rust_panic_becomes_a_solver_error(arm, data, monkeypatch):
    import cvxpy as cp

    def panic(self, *args, **kwargs):
        raise PanicException("called `Result::unwrap()` on an `Err` value")

    monkeypatch.setattr(cp.Problem, "solve", panic)
    # the scaled Clarabel program is solved directly (consistid.identification.program)
    from consistid.identification import program

    monkeypatch.setattr(program, "run_clarabel", panic)
    with pytest.raises(SolverError, match="crashed .*PanicException") as err:
        ci.identify(arm, data, method="sdp", friction=None)
    assert isinstance(err.value, Exception)       # caught by `except Exception`


@pytest.mark.parametrize("weight", [1e300, 1e-300])
def test_an_extreme_prior_weight_is_named_as_the_cause(arm, data, weight):
    """A weight 10^±300 breaks the solver (a Rust panic at 1e300): the error names the weight
    and the range that solves, not only 'another solver may help'."""
    try:
        res = ci.identify(arm, data, friction=None, prior_weight=weight)
    except SolverError as exc:
        assert f"prior_weight = {weight:.3g} is" in str(exc) and "× the default" in str(exc)
    else:
        assert res.solver.status == "optimal" and res.is_consistent


def test_keyboard_interrupt_is_not_swallowed(monkeypatch):
    import cvxpy as cp

    x = cp.Variable(2)
    problem = cp.Problem(cp.Minimize(cp.sum_squares(x)))
    monkeypatch.setattr(cp.Problem, "solve", lambda *a, **k: (_ for _ in ()).throw(
        KeyboardInterrupt()))
    with pytest.raises(KeyboardInterrupt):
        solve(problem, "test")


def test_a_real_clarabel_panic_is_a_solver_error(arm, ols, monkeypatch):
    """Coefficients of 1e300 made Clarabel panic in its PSD cone (Rust "Eigval error"); with the
    up-front magnitude check lifted, the wrapper still names it."""
    monkeypatch.setattr(recover_module, "MAX_COEFFICIENT", np.inf)
    with pytest.raises(ci.IdentificationError) as err:
        ci.recover_standard(arm, ols.base_parameters * 1e300, mode="exact", friction=None)
    assert "CLARABEL" in str(err.value)


def test_cvxpy_refusing_the_data_is_a_solver_error():
    import cvxpy as cp

    x = cp.Variable(2)
    problem = cp.Problem(cp.Minimize(cp.sum_squares(np.array([[np.nan, 1], [0, 1]]) @ x)))
    with pytest.raises(SolverError, match="cvxpy refused the problem"):
        solve(problem, "test")


# ================================================================= 6. prediction
def test_predict_checks_its_input(arm, ols, states):
    with pytest.raises(ci.DatasetError, match=r"dataset\.dq\[5, 'joint1'\] = 1e\+300"):
        ols.predict(dataset(states, dq=poke(states["dq"], (5, 0), 1e300)))
    with pytest.raises(ci.JointCountError, match="3 joints"):
        ols.predict(ci.Dataset(t=np.arange(3.0), q=np.zeros((3, 3)), dq=np.zeros((3, 3)),
                               ddq=np.zeros((3, 3))))
    with pytest.raises(ci.DatasetError, match="not a Dataset"):
        ols.predict(np.zeros((3, 2)))
    assert np.all(np.isfinite(ols.predict(dataset(states, q=states["q"] * 0 + MAX_ABS))))


# ================================================================= 7. models and URDFs
URDF = PLANAR_2R.format(**PLANAR_2R_VALUES)
MIMIC = URDF.replace('<limit lower="-3" upper="3" velocity="5" effort="100"/></joint>\n</robot>',
                     '<limit lower="-3" upper="3" velocity="5" effort="100"/>'
                     '<mimic joint="joint1" multiplier="2"/></joint>\n</robot>')
URDFS = [
    ("negative mass", URDF.replace('<mass value="2.0"/>', '<mass value="-2.0"/>'),
     r"link 'link1' has <mass value='-2.0'>"),
    ("NaN mass", URDF.replace('<mass value="1.5"/>', '<mass value="nan"/>'),
     r"link 'link2' has <mass value='nan'>"),
    ("text mass", URDF.replace('<mass value="1.5"/>', '<mass value="heavy"/>'),
     r"link 'link2' has <mass value='heavy'>"),
    ("inf inertia", URDF.replace('izz="0.05"', 'izz="inf"'), r"<inertia izz='inf'>"),
    ("zero axis", URDF.replace('<axis xyz="0 0 1"/>', '<axis xyz="0 0 0"/>', 1),
     r"joint 'joint1' has <axis xyz='0 0 0'>"),
    ("NaN axis", URDF.replace('<axis xyz="0 0 1"/>', '<axis xyz="0 nan 1"/>', 1),
     r"joint 'joint1' has <axis xyz='0 nan 1'>"),
    ("short axis", URDF.replace('<axis xyz="0 0 1"/>', '<axis xyz="0 1"/>', 1),
     r"joint 'joint1' has <axis xyz='0 1'>"),
    ("mimic", MIMIC, r"joint 'joint2' mimics joint 'joint1' \(multiplier 2"),
    ("no joints", '<robot name="r"><link name="base"/></robot>', "no moving joint"),
    ("not XML", "<robot", "not well-formed XML|could not read"),
]


@pytest.mark.parametrize("name,text,message", URDFS, ids=[u[0] for u in URDFS])
def test_bad_urdfs_are_refused_by_name(tmp_path, name, text, message):
    path = tmp_path / "bad.urdf"
    path.write_text(text)
    with pytest.raises(ci.ModelError, match=message):
        ci.RobotModel.from_urdf(path)


def test_a_locked_mimic_joint_is_fine(tmp_path):
    path = tmp_path / "mimic.urdf"
    path.write_text(MIMIC)
    assert ci.RobotModel.from_urdf(path, locked_joints=["joint2"]).nv == 1


def test_locking_a_joint_named_like_its_parent_link_is_named(tmp_path):
    """The SO-100 arm's URDF names its gripper joint like the link it hangs from ('gripper'):
    Pinocchio's buildReducedModel then fails on an ambiguous frame name (a bare ValueError);
    the error names the joint and what to do."""
    path = tmp_path / "clash.urdf"
    path.write_text(PLANAR_2R.format(**PLANAR_2R_VALUES).replace("link1", "joint2"))
    with pytest.raises(ci.ModelError, match=r"clash.urdf: cannot lock \['joint2'\].*share"
                                            r".*rename the joint"):
        ci.RobotModel.from_urdf(path, locked_joints=["joint2"])


@pytest.mark.parametrize("kwargs,message", [
    (dict(locked_joints=["joint1", "joint2"]), r"no moving joint \(locked: \['joint1', 'joint2'\]"),
    (dict(locked_joints="joint1"), "must be a list of joint names"),
    (dict(locked_joints=[1]), r"joint names \(strings\), got \[1\]"),
    (dict(locked_joints=["elbow"]), r"unknown joint\(s\) \['elbow'\]"),
    (dict(gravity=(0.0, float("nan"), 0.0)), "gravity must be 3 finite numbers"),
    (dict(gravity=(0.0, -9.81)), "gravity must be 3 finite numbers"),
    (dict(gravity="down"), "gravity must be 3 finite numbers"),
    (dict(locked_configuration={"joint1": 0.1}), "not in locked_joints"),
])
def test_bad_model_options_are_named(tmp_path, kwargs, message):
    path = tmp_path / "arm.urdf"
    path.write_text(URDF)
    with pytest.raises(ci.ModelError, match=message):
        ci.RobotModel.from_urdf(path, **kwargs)


@pytest.mark.parametrize("parameters,message", [
    (np.full(20, np.nan), r"parameters\[0\] \(link1.m\) is nan"),
    (poke(np.ones(20), 13, np.inf), r"parameters\[13\] \(link2.mz\) is inf"),
    (np.ones(5), r"shape \(5,\)"),
    (np.ones((2, 20)), r"shape \(2, 20\)"),
    (["a"] * 20, "vector of numbers"),
    (poke(np.ones(20), 0, 0.0), r"bodies \['link1'\] have mass 0"),
])
def test_with_parameters_refuses_what_pinocchio_would_turn_into_nan(arm, parameters, message):
    with pytest.raises(ci.ModelError, match=message):
        arm.with_parameters(parameters)


@pytest.mark.parametrize("gravity", [(np.nan, 0, 0), (0, 0), "g", (np.inf, 0, 0)])
def test_with_gravity_refuses_non_finite(arm, gravity):
    with pytest.raises(ci.ModelError, match="gravity must be 3 finite numbers"):
        arm.with_gravity(gravity)


@pytest.mark.parametrize("field", ["q", "dq", "ddq"])
def test_rnea_names_a_nan_input(arm, field):
    args = {k: np.zeros((4, 2)) for k in ("q", "dq", "ddq")}
    args[field] = poke(args[field], (2, 1), np.nan)
    with pytest.raises(ci.DatasetError, match=rf"{field}\[2, 'joint2'\] is nan"):
        arm.rnea(**args)
    with pytest.raises(ci.JointCountError, match=f"{field} has 3 joints"):
        arm.rnea(**{**args, field: np.zeros((4, 3))})


@pytest.mark.parametrize("center,axes,rotation,message", [
    ([0, 0, 0], [0.1, -0.1, 0.1], None, r"semi_axes\[1\] = -0.1 must be > 0"),
    ([0, 0, 0], [0.1, 0.0, 0.1], None, r"semi_axes\[1\] = 0 must be > 0"),
    ([0, 0, 0], [0.1, np.nan, 0.1], None, "semi_axes must be 3 finite numbers"),
    ([0, 0, 0], [0.1, 0.1], None, "semi_axes must be 3 finite numbers"),
    ([0, np.inf, 0], [0.1, 0.1, 0.1], None, "center must be 3 finite numbers"),
    ([0, 0, 0], [0.1, 0.1, 0.1], 2 * np.eye(3), "rotation must be a 3×3 rotation"),
])
def test_ellipsoids_refuse_degenerate_shapes(center, axes, rotation, message):
    with pytest.raises(OptionError, match=message):
        Ellipsoid.from_semi_axes(center, axes, rotation)


@pytest.mark.parametrize("value", ["x", -1.0, float("nan"), True])
def test_neighbourhood_bounds_are_numbers(value):
    from consistid.identification.priors import Neighbourhood

    with pytest.raises(OptionError, match="Neighbourhood.com must be a finite number ≥ 0"):
        Neighbourhood(com=value)


def test_ellipsoid_shape_must_be_positive_definite():
    with pytest.raises(OptionError, match="positive definite"):
        Ellipsoid(np.zeros(3), np.diag([1.0, 0.0, 1.0]))
    with pytest.raises(OptionError, match="symmetric 3×3"):
        Ellipsoid(np.zeros(3), np.arange(9.0).reshape(3, 3))


# ================================================================= 8. recovery
def test_recovery_refuses_non_finite_and_absurd_coefficients(arm, ols):
    beta = ols.base_parameters
    with pytest.raises(ci.ModelError, match=r"β\[2\] .* is nan"):
        ci.recover_standard(arm, poke(beta, 2, np.nan), friction=None)
    with pytest.raises(ci.ModelError, match=r"β\[0\] \(link1.mx \+ 0.8·link2.m\) = 1e\+300"):
        ci.recover_standard(arm, poke(beta, 0, 1e300), friction=None)
    with pytest.raises(ci.ModelError, match="4 base coefficients, but 'planar2r' .* has 6"):
        ci.recover_standard(arm, beta[:4], friction=None)


@pytest.mark.parametrize("index", [3, 4, 5])
def test_unrealisable_coefficients_are_blamed_not_the_solver(arm, ols, index):
    bad = poke(ols.base_parameters, index, -1.0 if index == 5 else 1e3)
    with pytest.raises(ci.UnrealizableCoefficientsError, match="Smallest changes") as err:
        ci.recover_standard(arm, bad, mode="exact", friction=None)
    assert err.value.moves and err.value.moves[0].index == index


def test_extreme_but_valid_coefficients_name_the_coefficient(arm, ols):
    bad = poke(ols.base_parameters, 1, 1e3)                    # link1.my: 1000 kg·m
    try:
        rec = ci.recover_standard(arm, bad, mode="exact", friction=None)
    except ci.IdentificationError as exc:
        assert "far from the prior" in str(exc) and "β[1] (link1.my)" in str(exc)
    else:
        assert rec.is_consistent


@pytest.mark.parametrize("scale", [1e-4, 1e6])
def test_recovery_of_a_robot_far_from_the_kilogram_scale(tmp_path, scale):
    """The same 2R arm with every mass and inertia × scale: recovered and consistent, or an
    error that blames the scale (never 'try another solver' alone)."""
    v = dict(PLANAR_2R_VALUES)
    v.update(m1=v["m1"] * scale, m2=v["m2"] * scale, i1=v["i1"] * scale, i2=v["i2"] * scale)
    text = (PLANAR_2R.format(**v).replace('ixx="0.01"', f'ixx="{0.01 * scale}"')
            .replace('iyy="0.045"', f'iyy="{0.045 * scale}"')
            .replace('iyy="0.03"', f'iyy="{0.03 * scale}"'))
    (tmp_path / "big.urdf").write_text(text)
    model = ci.RobotModel.from_urdf(tmp_path / "big.urdf", gravity=(0.0, -9.81, 0.0))
    q, dq, ddq = random_states(model, 300, 0)
    data = ci.Dataset(t=np.arange(300) * 0.01, q=q, dq=dq, ddq=ddq,
                      tau=model.rnea(q, dq, ddq) * (1 + 1e-3))
    res = ci.identify(model, data, friction=None)
    assert res.solver.status == "optimal" and res.is_consistent
    try:
        rec = ci.recover_standard(model, ci.identify(model, data, method="ols", friction=None))
    except ci.IdentificationError as exc:
        assert f"weigh up to {2 * scale:.3g} kg" in str(exc)
    else:
        assert rec.is_consistent


@pytest.mark.parametrize("kwargs,message", [
    (dict(mode="closest"), "mode='closest'"), (dict(prior=None), "prior=None"),
    (dict(margin=-1.0), "margin must be"), (dict(slack=0.0), "slack must be"),
    (dict(prior_parameters=np.full(20, np.nan)), "prior_parameters must be 20 finite"),
])
def test_recovery_options_are_named(arm, ols, kwargs, message):
    with pytest.raises(ci.ConsistidError, match=message):
        ci.recover_standard(arm, ols.base_parameters, friction=None, **kwargs)


# ================================================================= 9. payload
@pytest.mark.parametrize("kwargs,message", [
    (dict(mass_range=(6.0, 5.0)), "lower bound above the upper"),
    (dict(mass_range=(None, -1.0)), "a payload mass is ≥ 0"),
    (dict(mass_range=(np.nan, 5.0)), "mass_range bound must be a finite number"),
    (dict(mass_range=5.0), "mass_range must be a pair"),
    (dict(frame=3), "frame must be a frame/body name"),
    (dict(ellipsoid=(0, 0, 0)), "ellipsoid must be a consistid.Ellipsoid"),
    (dict(com_bounds=([0, 0, 0], [1, 1])), "com_bounds must be"),
])
def test_payload_options_are_named(arm, data, ols, kwargs, message):
    with pytest.raises(ci.OptionError, match=message):
        ci.estimate_payload(arm, data, robot=ols, **kwargs)


def test_infeasible_mass_range_is_named(arm, data, ols):
    with pytest.raises(ci.InfeasibleError, match=r"mass_range = \(5.0, 6.0\) is what admits no"):
        ci.estimate_payload(arm, data, robot=ols, mass_range=(5.0, 6.0))


def test_payload_on_unloaded_data_says_nothing_was_found(arm, data, ols):
    with pytest.warns(NothingFoundWarning, match="no payload found"):
        pay = ci.estimate_payload(arm, data, robot=ols)
    assert not pay.found and "no payload found" in pay.summary()
    assert np.all(np.isnan(pay.com)) and abs(pay.mass) < 3 * pay.mass_std


def test_a_real_payload_is_found(arm, states, ols):
    # a 0.8 kg solid sphere (radius 5 cm) at 0.2 m on link2: the loaded robot's torques
    payload = ci.robot.inertia.from_mass_com_inertia(0.8, [0.2, 0, 0], 0.0008 * np.eye(3))
    loaded = arm.with_parameters(ols.parameters[:20] + np.r_[np.zeros(10), payload])
    tau = loaded.rnea(states["q"], states["dq"], states["ddq"])
    with warnings.catch_warnings():
        warnings.simplefilter("error", NothingFoundWarning)
        pay = ci.estimate_payload(arm, dataset(states, tau=tau), robot=ols)
    assert pay.found and pay.mass == pytest.approx(0.8, abs=0.05)


def test_payload_loaded_must_be_data(arm, ols):
    with pytest.raises(ci.ConsistidError, match="not a Dataset|must be a Dataset"):
        ci.estimate_payload(arm, np.zeros((3, 2)), robot=ols)


# ================================================================= 10. NaN in, NaN out
def _nan_body(k):
    body = np.array([2.0, 0.8, 0, 0, 0.01, 0, 0.365, 0, 0, 0.37])
    return poke(body, k, np.nan)


NAN_IN = [
    ("regressor q", lambda m: regressor(m, np.full((3, 2), np.nan), np.zeros((3, 2)),
                                        np.zeros((3, 2))), r"q\[0, 'joint1'\] = nan"),
    ("regressor dq 1e300", lambda m: regressor(m, np.zeros((3, 2)), poke(np.zeros((3, 2)),
                                                                          (2, 1), 1e300),
                                               np.zeros((3, 2))), r"dq\[2, 'joint2'\] = 1e\+300"),
    ("regressor ddq inf", lambda m: regressor(m, np.zeros((3, 2)), np.zeros((3, 2)),
                                              poke(np.zeros((3, 2)), (1, 0), -np.inf)),
     r"ddq\[1, 'joint1'\] = -inf"),
    ("regressor shapes", lambda m: regressor(m, np.zeros((3, 2)), np.zeros((2, 2)),
                                             np.zeros((3, 2))), "dq has shape"),
    ("pseudo_inertia", lambda m: inertia.pseudo_inertia(_nan_body(3)), "mz = nan"),
    ("check_body", lambda m: inertia.check_body(_nan_body(9)), "Izz = nan"),
    ("is_physically_consistent", lambda m: inertia.is_physically_consistent(
        np.r_[_nan_body(0), _nan_body(1)]), "m = nan"),
    ("to_mass_com_inertia", lambda m: inertia.to_mass_com_inertia(_nan_body(5)), "Ixy = nan"),
    ("from_mass_com_inertia",
     lambda m: inertia.from_mass_com_inertia(1.0, [0, np.nan, 0], np.eye(3)), "must be finite"),
    ("perturb", lambda m: inertia.perturb(_nan_body(2), 0.1, np.random.default_rng(0)),
     "my = nan"),
    ("inertias_from_vector", lambda m: inertia.inertias_from_vector(_nan_body(4)),
     "Ixx = nan|finite"),
]


@pytest.mark.parametrize("name,call,message", NAN_IN, ids=[n for n, _, _ in NAN_IN])
def test_nan_in_is_an_error_not_nan_out(arm, name, call, message):
    with pytest.raises(ci.ConsistidError, match=message):
        call(arm)


# ================================================================= 11. other entry points
def still_data(arm, states):
    q = np.tile([0.3, -0.2], (N, 1))
    return dataset(states, q=q, dq=0 * q, ddq=0 * q, tau=arm.rnea(q, 0 * q, 0 * q))


@pytest.mark.parametrize("entry", ["estimate_mounting", "diagnose"])
def test_mounting_and_diagnosis_check_the_data_first(arm, states, entry):
    call = getattr(ci, entry)
    with pytest.raises(ci.PoorExcitationError, match="no motion at all"):
        call(arm, still_data(arm, states))
    with pytest.raises(ci.DatasetError, match="dead torque channel"):
        call(arm, dataset(states, tau=np.zeros((N, 2))))
    with pytest.raises(ci.DatasetError, match=r"tau\[7, 'joint2'\] = 1e\+300"):
        call(arm, dataset(states, tau=poke(states["tau"], (7, 1), 1e300)))


@pytest.mark.parametrize("kwargs,message", [
    (dict(n_samples=0), "n_samples must be an integer ≥ 1"),
    (dict(n_samples=2.5), "n_samples must be an integer"),
    (dict(rtol=-1.0), "rtol must be a finite number > 0"),
    (dict(rtol=2.0), r"rtol is a relative rank tolerance in \(0, 1\)"),
])
def test_base_parameter_options(arm, kwargs, message):
    with pytest.raises(ci.OptionError, match=message):
        ci.compute_base_parameters(arm, **kwargs)


@pytest.mark.parametrize("kwargs,message", [
    (dict(harmonics=-1), "harmonics must be an integer ≥ 1"),
    (dict(harmonics=0), "harmonics must be an integer ≥ 1"),
    (dict(period=0.0), "period must be a finite number > 0"),
    (dict(period=float("inf")), "period must be a finite number"),
    (dict(amplitude=-0.5), "amplitude must be a finite number > 0"),
])
def test_random_fourier_trajectory_options(arm, kwargs, message):
    with pytest.raises(ci.OptionError, match=message):
        ci.FourierTrajectory.random(arm, **kwargs)


FILES = [
    ("ragged.csv", "t,q1,dq1,ddq1\n0,1,2\n", "header names 4 columns, the rows have 3"),
    ("text.csv", "t,q1,dq1,ddq1\n0,1,x,3\n", "rows below the header are not all numbers"),
    ("nocols.csv", "a,b\n1,2\n", "no q1..qn columns"),
    ("lacks.csv", "t,q1,dq1\n0,1,2\n", r"lacks columns \['ddq1'\]"),
    ("text.npz", "not a zip", "bad.npz is not a readable .npz archive|not a readable .npz"),
    ("run.txt", "t\n0\n", "unknown dataset format '.txt'|format"),
]


@pytest.mark.parametrize("name,text,message", FILES, ids=[f[0] for f in FILES])
def test_dataset_files_that_are_not_datasets(tmp_path, name, text, message):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(ci.DatasetError, match=message.replace("bad.npz", name)):
        ci.Dataset.load(path)


def test_npz_holding_one_array_or_garbage_for_load_recording(tmp_path):
    np.save(tmp_path / "one.npy", np.zeros(3))
    (tmp_path / "one.npy").rename(tmp_path / "one.npz")
    with pytest.raises(ci.DatasetError, match="one.npz holds a single array"):
        ci.Dataset.load(tmp_path / "one.npz")
    (tmp_path / "junk.npz").write_bytes(b"PK\x03\x04 truncated")
    with pytest.raises(ci.DatasetError, match="junk.npz is not a readable .npz"):
        ci.load_recording(tmp_path / "junk.npz")


@pytest.mark.parametrize("fraction", [0.0, 1.0, 1.5, float("nan"), -0.2])
def test_split_fractions(data, fraction):
    with pytest.raises(ci.DatasetError, match="split fraction must lie in"):
        data.split(fraction)


# ================================================================= 12. fuzz
FLOATS = st.one_of(st.floats(-10, 10, allow_nan=False),
                   st.sampled_from([0.0, 1e-300, -1e9, 1e12, 1e300, np.nan, np.inf]))


@st.composite
def hostile_arrays(draw):
    n = draw(st.integers(1, 30))
    nv = draw(st.sampled_from([2] * 8 + [1, 3]))
    kind = draw(st.sampled_from(["random"] * 3 + ["constant", "zeros", "sprinkled"] * 2))
    rng = np.random.default_rng(draw(st.integers(0, 2 ** 16)))
    fields = {}
    for name in ("q", "dq", "ddq", "tau"):
        if kind == "random":
            a = rng.normal(size=(n, nv))
        elif kind == "constant":
            a = np.full((n, nv), draw(FLOATS))
        elif kind == "zeros":
            a = np.zeros((n, nv))
        else:
            a = rng.normal(size=(n, nv))
            a[draw(st.integers(0, n - 1)), draw(st.integers(0, nv - 1))] = draw(FLOATS)
        fields[name] = a
    steps = draw(st.sampled_from(["ok"] * 6 + ["repeat", "backwards"]))
    t = np.arange(n) * 0.01 if steps == "ok" else (
        np.zeros(n) if steps == "repeat" else -np.arange(n) * 0.01)
    return t, fields


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow],
          derandomize=True)
@given(arrays=hostile_arrays(), method=st.sampled_from(["ols", "wls", "sdp"]))
def test_fuzz_dataset_identify_predict(planar_2r, arrays, method):
    """Named error, or finite numbers with warnings naming what is missing."""
    t, fields = arrays
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            data = ci.Dataset(t=t, **fields)
            res = ci.identify(planar_2r, data, method=method, friction=None)
            pred = res.predict(data)
        except ci.ConsistidError as exc:
            assert len(str(exc)) > 20            # a message that says something
            event(f"named error {type(exc).__name__}")
            return
    event("result" + (" with uninformed directions" if res.uninformed else ""))
    assert np.all(np.isfinite(res.parameters)) and np.all(np.isfinite(pred))
    assert np.all(np.isfinite(res.base_parameters)) and np.all(np.isfinite(res.train_rms))
    if not np.all(np.isfinite(res.base_std)):
        assert res.uninformed, "infinite σ without naming the uninformed directions"
    if res.uninformed:
        assert any(issubclass(w.category, PoorExcitationWarning)
                   and "do not inform" in str(w.message) for w in caught)
    for w in caught:    # no numpy RuntimeWarning (overflow, invalid value) leaks out
        assert not issubclass(w.category, RuntimeWarning), str(w.message)


@pytest.mark.parametrize("effects", [0.5, {"coulomb": 1.0}, "coulomb"])
def test_effects_that_are_not_an_effects_value_are_named(panda, effects):
    with pytest.raises(ci.ModelError, match="effects must be a consistid.simulate.Effects"):
        ci.estimate_breakaway(panda, effects=effects)


def test_mimic_tag_on_a_fixed_joint_is_harmless():
    """Talos's fixed gripper joints carry <mimic> tags: nothing moves, nothing is refused."""
    from consistid.robot.model import example_robot_data_dir

    path = example_robot_data_dir() / "talos_data" / "robots" / "talos_reduced.urdf"
    if not path.exists():
        pytest.skip(f"{path} is not in this example-robot-data")
    assert "<mimic" in path.read_text()
    assert ci.RobotModel.from_urdf(path).nv == 32


def test_positions_in_degrees_read_as_radians_are_flagged(panda):
    """A log whose angles are in degrees, with no unit to say so, leaves the joint limits by
    far: identify says so (and names the joints) instead of fitting nonsense silently."""
    run = ci.simulate.excitation_run(panda, duration=3.0, rate=100.0, torque_noise=0.05, seed=1)
    d = run.dataset
    in_degrees = ci.Dataset(t=d.t, q=np.degrees(d.q), dq=d.dq, ddq=d.ddq, tau=d.tau)
    with pytest.warns(ci.DataQualityWarning, match=r"beyond the joint limits: 'panda_joint1'"):
        ci.identify(panda, in_degrees, method="ols")
    with warnings.catch_warnings():
        warnings.simplefilter("error", ci.DataQualityWarning)
        ci.identify(panda, d, method="ols")             # the same log in radians: silent

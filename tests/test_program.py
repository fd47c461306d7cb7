"""The SDP compiled once per model and options (identification/program.py) against the program
built afresh by cvxpy each time (the path every other solver and ``scale=False`` still take):
same optimum to the solver's tolerance, re-used across calls and passes, the status contract kept.
"""

from __future__ import annotations

import numpy as np
import pytest

import consistid as ci
from consistid.errors import SolverError
from consistid.identification import program, sdp
from consistid.identification.base import compute_base_parameters
from consistid.identification.compression import compress
from consistid.identification.regressor import RegressorSpec


def fresh_build(monkeypatch):
    """Make sdp build every program afresh through cvxpy (today's path before the cache)."""
    original = sdp._build

    def build(*args, **kwargs):
        kwargs["solver"] = "fresh"        # anything but CLARABEL: the cvxpy program
        return original(*args, **kwargs)

    monkeypatch.setattr(sdp, "_build", build)


def problem_of(model, seconds, seed, friction=("coulomb", "viscous", "offset")):
    data = ci.simulate.excitation_run(model, duration=seconds, rate=200.0, torque_noise=0.1,
                                      seed=seed).dataset
    spec = RegressorSpec.make(model, friction)
    return data, spec, compute_base_parameters(model, spec), compress(model, data, spec)


def relative(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


@pytest.fixture(scope="module")
def ur5():
    return ci.RobotModel.example("ur5")


@pytest.mark.parametrize("name,seconds,options", [
    ("planar_2r", 10.0, {}),
    ("ur5", 12.0, {}),
    ("ur5", 12.0, dict(prior="euclidean")),
    ("ur5", 12.0, dict(reweight=2, mass_bounds={"wrist_3_link": (0.05, None)})),
    ("ur5", 12.0, dict(prior=None, com_boxes={"forearm_link": ((-0.5,) * 3, (0.5,) * 3)},
                       neighbourhood=ci.identification.priors.Neighbourhood(mass=0.5))),
])
def test_compiled_program_equals_a_fresh_build(request, monkeypatch, name, seconds, options):
    model = request.getfixturevalue(name)
    data, spec, base, prob = problem_of(model, seconds, seed=3)
    program.clear_cache()
    cached = [sdp.identify_sdp(model, prob, base, spec, dataset=data, **options)
              for _ in range(2)]                      # the second reuses the first's compile
    info = program.cache_info()
    assert info["programs"] == 1 and info["solves"] >= 2
    with monkeypatch.context() as m:
        fresh_build(m)
        fresh = sdp.identify_sdp(model, prob, base, spec, dataset=data, **options)
    assert fresh.solver.status == "optimal"
    for res in cached:
        assert res.solver.status == "optimal"
        assert relative(res.base_parameters, fresh.base_parameters) <= 1e-7
        if options.get("prior", "logdet") is not None:
            # standard parameters: where only the prior decides, to the SDP's own tolerance
            # (measured ≤ 4e-6 on these arms); without a prior they are not unique (the
            # first link's mass of a fixed base: any value the constraints admit)
            assert relative(res.parameters, fresh.parameters) <= 1e-4
        assert res.details["passes"] == fresh.details["passes"]
        assert res.is_consistent
    assert np.array_equal(cached[0].base_parameters, cached[1].base_parameters)


def test_prior_weight_and_sigma_change_without_a_new_compile(ur5):
    """γ and σ are data of the compiled program, not its structure; a weight change gives the
    answer a fresh build gives for that weight."""
    data, spec, base, prob = problem_of(ur5, 12.0, seed=5)
    program.clear_cache()
    weights = (sdp.default_prior_weight() * 0.1, sdp.default_prior_weight() * 10)
    answers = [sdp.identify_sdp(ur5, prob, base, spec, prior_weight=w) for w in weights]
    answers.append(sdp.identify_sdp(ur5, prob, base, spec, sigma=np.full(ur5.nv, 0.3)))
    # one compiled structure served every solve (a pass that ends optimal_inaccurate is
    # refined by one more solve of the same structure: which passes do depends on round-off)
    refinements = sum(a.details["passes"]["refinements"] for a in answers)
    assert program.cache_info() == {"programs": 1, "solves": 3 + refinements}
    # a larger weight pulls the answer towards the prior: the divergence falls
    assert (answers[1].details["fit"]["prior_divergence"]
            < answers[0].details["fit"]["prior_divergence"])


def test_structure_changes_compile_anew(ur5):
    data, spec, base, prob = problem_of(ur5, 12.0, seed=6)
    program.clear_cache()
    sdp.identify_sdp(ur5, prob, base, spec)
    sdp.identify_sdp(ur5, prob, base, spec, constraints="mass-inertia")
    sdp.identify_sdp(ur5, prob, base, spec, margin=1e-3)
    assert program.cache_info()["programs"] == 3


def test_identify_reuses_the_compile_across_model_objects(ur5):
    """Through the public entry: repeated calls share one compiled program, also through a
    model rebuilt with the same inertias (the cache is keyed by content)."""
    data = ci.simulate.excitation_run(ur5, duration=12.0, rate=200.0, torque_noise=0.1,
                                      seed=8).dataset
    program.clear_cache()
    first = ci.identify(ur5, data)
    second = ci.identify(ur5.with_parameters(ur5.prior_parameters), data)  # a rebuilt model
    assert program.cache_info() == {"programs": 1, "solves": 2}
    assert np.array_equal(first.base_parameters, second.base_parameters)
    assert second.details["timing"]["compile"] < first.details["timing"]["compile"]


def test_a_clarabel_panic_in_the_compiled_path_is_a_solver_error(ur5, monkeypatch):
    class PanicException(BaseException):
        pass

    def panic(*args, **kwargs):
        raise PanicException("called `Result::unwrap()` on an `Err` value")

    data, spec, base, prob = problem_of(ur5, 12.0, seed=9)
    monkeypatch.setattr(program, "run_clarabel", panic)
    with pytest.raises(SolverError, match="crashed .*PanicException"):
        sdp.identify_sdp(ur5, prob, base, spec)


def test_unknown_solver_option_is_named(ur5):
    data, spec, base, prob = problem_of(ur5, 12.0, seed=9)
    with pytest.raises(ci.OptionError, match="could not run with the options"):
        sdp.identify_sdp(ur5, prob, base, spec, solver_options={"no_such_setting": 1})

"""SDPOptions: one validated value for the SDP's options, shared by the API and the TOML schema."""

from __future__ import annotations

from dataclasses import fields

import numpy as np
import pytest

import consistid as ci
from consistid.cli.config import identify_keys


@pytest.fixture(scope="module")
def run(planar_2r):
    return ci.simulate.excitation_run(planar_2r, duration=4.0, rate=100.0, torque_noise=0.05,
                                      seed=2).dataset


def test_options_value_and_keywords_give_the_same_answer(planar_2r, run):
    by_keywords = ci.identify(planar_2r, run, prior="euclidean", prior_weight=3.0, margin=1e-5)
    by_value = ci.identify(planar_2r, run, options=ci.SDPOptions(
        prior="euclidean", prior_weight=3.0, margin=1e-5))
    np.testing.assert_array_equal(by_value.parameters, by_keywords.parameters)
    assert by_value.details["prior_weight"] == pytest.approx(3.0)


@pytest.mark.parametrize("bad, match", [
    (dict(prior="bogus"), "prior"), (dict(loss="l1"), "loss"), (dict(margin=1.5), "margin"),
    (dict(margin=-1e-3), "margin"), (dict(scale="yes"), "scale"),
    (dict(friction_nonnegative=1), "friction_nonnegative"), (dict(solver="NO_SUCH"), "solver"),
    (dict(solver_options=[("max_iter", 3)]), "solver_options"),
    (dict(prior=None, prior_weight=2.0), "prior_weight"),
    (dict(huber_threshold=2.0), "huber_threshold"), (dict(reweight=-1), "reweight"),
    (dict(prior_uncertainty=0.0), "prior_uncertainty"),
])
def test_bad_options_are_named_on_construction(bad, match):
    with pytest.raises(ci.OptionError, match=match):
        ci.SDPOptions(**bad)


def test_unknown_keyword_and_mixed_forms_are_named(planar_2r, run):
    with pytest.raises(ci.OptionError, match="unknown SDP option.*'bogus'"):
        ci.identify(planar_2r, run, bogus=1.0)
    with pytest.raises(ci.OptionError, match="either"):
        ci.identify(planar_2r, run, options=ci.SDPOptions(), prior_weight=2.0)


def test_derived_values():
    assert ci.SDPOptions(prior=None).weight == 0.0
    assert ci.SDPOptions().weight == pytest.approx(ci.default_prior_weight())
    assert ci.SDPOptions(loss="huber").passes == 5 and ci.SDPOptions(reweight=2).passes == 2
    assert ci.SDPOptions(solver="clarabel").solver == "CLARABEL"


def test_the_toml_schema_is_the_options_fields():
    keys = set(identify_keys())
    assert {f.name for f in fields(ci.SDPOptions)} <= keys
    assert {"method", "friction", "armature", "covariance"} <= keys

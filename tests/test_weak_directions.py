"""Weakly informed directions, the training envelope and the SDP's joint prior (issue 26).

Truth comes from the MuJoCo "real robot" (its friction and the nominal model's residual) or from
regressor-built torques with known parameters, never from the identification under test."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import consistid as ci
from consistid.errors import ExtrapolationWarning, PoorExcitationWarning
from consistid.identification.envelope import TrainingEnvelope
from consistid.identification.regressor import RegressorSpec, regressor
from consistid.simulate import Effects, TrackingController, record
from consistid.simulate.experiments import nominal_residual

FRICTION = ("coulomb", "viscous", "offset")


class OneWay:
    """A Fourier excitation whose first joint moves at ``speed · (1 ± 0.4 cos ωt)``: one way."""

    def __init__(self, base, speed: float, centre: float, duration: float) -> None:
        self.base, self.speed, self.centre, self.duration = base, speed, centre, duration

    def evaluate(self, t):
        q, dq, ddq = (np.array(a) for a in self.base.evaluate(t))
        w, v = 2 * np.pi / 7.0, self.speed
        a = 0.4 * abs(v) / w
        q[:, 0] = self.centre + v * (t - self.duration / 2) + np.sign(v) * a * np.sin(w * t)
        dq[:, 0] = v + np.sign(v) * a * w * np.cos(w * t)
        ddq[:, 0] = -np.sign(v) * a * w * w * np.sin(w * t)
        return q, dq, ddq


@pytest.fixture(scope="module", params=["panda", "ur5"])
def one_way(request):
    """(model, train, held, coulomb): the first joint moves one way in train, the other way in
    held (another excitation), with MuJoCo Coulomb + viscous friction on every joint."""
    model = ci.RobotModel.example(request.param)
    rng = np.random.default_rng(3)
    eff = Effects(coulomb=rng.uniform(0.5, 2.0, model.nv),
                  viscous=rng.uniform(0.1, 0.5, model.nv), torque_noise=0.1)
    centre = float(0.5 * (np.clip(model.limits.lower, -3, 3)
                          + np.clip(model.limits.upper, -3, 3))[0])
    logs = []
    for k, speed in enumerate((0.15, -0.15)):
        traj = ci.FourierTrajectory.random(model, harmonics=5, period=10.0, seed=7 + k)
        logs.append(record(model, OneWay(traj, speed, centre, 12.0), eff, duration=12.0,
                           rate=250.0, seed=k, controller=TrackingController(bandwidth=100.0)
                           ).true_dataset())
    return model, logs[0], logs[1], eff.coulomb


@pytest.fixture(scope="module")
def fitted(one_way):
    model, train, _, _ = one_way
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = ci.identify(model, train, method="sdp")
    return res, caught


def test_a_one_way_joint_is_named_and_warned(one_way, fitted):
    model, train, _, _ = one_way
    res, caught = fitted
    joint = model.joint_names[0]
    assert np.all(train.dq[:, 0] > 0)                       # the simulation moved it one way
    said = [str(w.message) for w in caught if w.category is PoorExcitationWarning
            and "barely inform" in str(w.message)]
    assert said and f"{joint}'s Coulomb and offset: {joint} moves one way only" in said[0]
    assert res.weakly_informed[0].startswith(f"{joint}'s Coulomb and offset")
    assert "Weakly informed by the data" in res.summary() and joint in res.summary()
    assert "only weakly informed by the data" in res._repr_html_()


def test_reversed_motion_warns_and_is_no_worse_than_nominal(one_way, fitted):
    """The issue's case: on held-out data where the joint reverses, predict warns naming the
    joint and the sign, and the default SDP predicts no worse than the nominal (CAD) model,
    judged by the simulation's own residual of the nominal model."""
    model, _, held, coulomb = one_way
    res, _ = fitted
    with pytest.warns(ExtrapolationWarning, match=f"{model.joint_names[0]} moves with q̇ < 0"):
        rms = res.rms(held)
    nominal = np.sqrt(np.mean(nominal_residual(model, held) ** 2, axis=0))
    assert np.all(rms <= nominal), (rms, nominal)
    fc, fo = (res.parameters[res.parameter_names.index(f"{model.joint_names[0]}.{c}")]
              for c in ("fc", "fo"))
    assert abs(fc) < 10 * coulomb[0] and abs(fo) < 10 * coulomb[0]     # not ±859 N·m


def test_a_stream_gets_the_same_envelope_and_weak_directions_as_its_dataset(one_way, fitted):
    """The one-way training log read as a stream of three parts (identify's DataStream, the
    coloured covariance reading it twice): the envelope is the whole dataset's (computed here
    on the stacked arrays), the one-way joint is named and warned as in the batch fit, and
    prediction on reversed motion warns. Before, a stream kept neither ("not assessed")."""
    model, train, held, _ = one_way
    res, _ = fitted
    edges = np.linspace(0, train.n_samples, 4).astype(int)
    parts = [train.select(np.arange(a, b)) for a, b in zip(edges[:-1], edges[1:])]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        streamed = ci.identify(model, ci.identification.streaming.DataStream(parts),
                               method="sdp")
    whole = TrainingEnvelope.of(train, model.joint_names)
    for field in ("q_min", "q_max", "dq_max", "ddq_max", "positive", "negative"):
        np.testing.assert_array_equal(getattr(streamed.envelope, field), getattr(whole, field))
    assert streamed.envelope.n_samples == train.n_samples
    joint = model.joint_names[0]
    said = [str(w.message) for w in caught if w.category is PoorExcitationWarning
            and "barely inform" in str(w.message)]
    assert said and f"{joint} moves one way only" in said[0]
    assert streamed.weakly_informed[0] == res.weakly_informed[0]
    with pytest.warns(ExtrapolationWarning, match=f"{joint} moves with q̇ < 0"):
        streamed.rms(held)


def test_the_envelope_survives_save_and_load_and_old_files_load_without_it(one_way, fitted,
                                                                           tmp_path):
    model, _, held, _ = one_way
    res, _ = fitted
    path = res.save(tmp_path / "res.json")
    back = ci.IdentificationResult.load(path, model=model)
    assert back.weakly_informed == res.weakly_informed
    with pytest.warns(ExtrapolationWarning, match="q̇ < 0"):
        np.testing.assert_array_equal(back.predict(held), res.predict(held))
    doc = json.loads(path.read_text())
    for key in ("envelope", "weakly_informed"):
        del doc[key]
    (tmp_path / "old.json").write_text(json.dumps(doc))
    old = ci.IdentificationResult.load(tmp_path / "old.json", model=model)
    assert old.envelope is None and old.weakly_informed == ()
    with warnings.catch_warnings():
        warnings.simplefilter("error", ExtrapolationWarning)
        old.predict(held)


def synthetic(model, seed: int, one_way: bool, noise: float = 0.05):
    """Regressor-built torques with friction ``fc = 1, fv = 0.3, fo = 0.2`` per joint (true
    parameters known exactly); ``one_way``: joint 1's velocity made positive throughout."""
    traj = ci.FourierTrajectory.random(model, harmonics=5, period=10.0, seed=seed)
    data = traj.sample(100.0, 20.0)
    dq = data.dq.copy()
    if one_way:
        dq[:, 0] = np.abs(dq[:, 0]) + 0.05
    spec = RegressorSpec.make(model, FRICTION)
    truth = np.concatenate([model.prior_parameters,
                            np.tile([1.0, 0.3, 0.2], model.nv)])
    names = spec.joint_column_names(model.joint_names)
    truth[model.n_inertial:] = [{"fc": 1.0, "fv": 0.3, "fo": 0.2}[n.rsplit(".", 1)[1]]
                                for n in names]
    rng = np.random.default_rng(seed)
    tau = (regressor(model, data.q, dq, data.ddq, spec) @ truth).reshape(-1, model.nv)
    return ci.Dataset(t=data.t, q=data.q, dq=dq, ddq=data.ddq,
                      tau=tau + noise * rng.standard_normal(tau.shape))


def test_least_squares_refuses_a_one_way_joint_and_says_why():
    model = ci.RobotModel.example("ur5")
    with pytest.raises(ci.errors.PoorExcitationError,
                       match=r"shoulder_pan_joint moves one way only in these data \(q̇ > 0; "
                             r"0 of 2000 moving samples with q̇ < 0\)"):
        ci.identify(model, synthetic(model, 1, one_way=True), method="ols")


def test_the_joint_prior_splits_a_one_way_constant_equally():
    """Closed form: the data fix f_c + f_o = 1.2 and nothing else of the pair; the prior, equal
    σ on both, puts f_c = f_o = 0.6 (the minimum of f_c² + f_o² on that line)."""
    model = ci.RobotModel.example("ur5")
    with pytest.warns(PoorExcitationWarning):
        res = ci.identify(model, synthetic(model, 1, one_way=True), method="sdp")
    j = model.joint_names[0]
    fc, fo = (res.parameters[res.parameter_names.index(f"{j}.{c}")] for c in ("fc", "fo"))
    assert fc + fo == pytest.approx(1.2, abs=0.02)
    assert fc == pytest.approx(fo, abs=5e-3)   # the solver's tolerance on a flat direction
    assert "σ = the effort limit" in res.details["joint_prior"]


@pytest.mark.parametrize("arm", ["panda", "ur5", "xarm7"])
def test_two_way_data_have_no_weak_direction_and_the_joint_prior_does_not_move_them(arm):
    model = ci.RobotModel.example(arm)
    data = synthetic(model, 2, one_way=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error", PoorExcitationWarning)
        res = ci.identify(model, data, method="sdp")
        off = ci.identify(model, data, method="sdp", joint_prior=False)
    assert res.weakly_informed == ()
    moved = np.abs(res.base_parameters - off.base_parameters) / res.base_std
    assert np.max(moved) < 0.05


@settings(max_examples=25, deadline=None)
@given(st.integers(2, 40), st.integers(1, 4), st.integers(0, 2**31 - 1))
def test_data_never_leave_their_own_envelope(n, nv, seed):
    rng = np.random.default_rng(seed)
    q, dq, ddq = (rng.standard_normal((n, nv)) * rng.uniform(0, 3, nv) for _ in range(3))
    ds = ci.Dataset(t=np.arange(n) * 0.01, q=q, dq=dq, ddq=ddq)
    env = TrainingEnvelope.of(ds)
    assert env.departures(ds) == []
    back = TrainingEnvelope.from_dict(json.loads(json.dumps(env.to_dict())))
    assert back.departures(ds) == [] and back.one_way() == env.one_way()


def test_a_sign_never_seen_and_a_range_exceeded_are_named():
    t = np.arange(500) * 0.01
    q = np.column_stack([np.sin(t), 0.1 * t])
    dq = np.column_stack([np.cos(t), np.full_like(t, 0.1)])
    env = TrainingEnvelope.of(ci.Dataset(t=t, q=q, dq=dq, ddq=np.zeros_like(q),
                                         joint_names=("a", "b")))
    assert env.one_way() == [(1, "q̇ > 0")]
    away = env.departures(ci.Dataset(t=t, q=2 * q, dq=-dq, ddq=np.zeros_like(q),
                                     joint_names=("a", "b")))
    assert any(s.startswith("b moves with q̇ < 0 in 500 samples") for s in away)
    assert any(s.startswith("a goes to q ∈") for s in away)
    assert not any(s.startswith("a moves with") for s in away)

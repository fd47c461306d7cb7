"""Rollout validation and simulator calibration (consistid.simulator).

The logs here are made by a plain ``mj_step`` loop of MuJoCo on the MJCF of
:func:`consistid.robot.mjcf.mjcf_spec` (not by the code under test): a PD plus gravity
compensation tracks a Fourier trajectory, and the applied torque is logged with each state.
The truth (inertias, armature, damping) is what that simulation was given.
"""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import mujoco
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

import consistid as ci
from consistid.robot.mjcf import mjcf_spec, write_mjcf
from consistid.simulate.mujoco_logs import PD_STEP as H
from consistid.simulate.mujoco_logs import pd_log
from consistid.simulator import (ComputedTorque, PDGains, RolloutOptions, calibrate_simulator,
                                 validate_rollout)



def _terms(model: ci.RobotModel, armature: np.ndarray, damping: np.ndarray):
    names = [f"{j}.{s}" for s in ("Ia", "fv") for j in model.joint_names]
    return np.concatenate([armature, damping]), names


def _computed_torque_log(model: ci.RobotModel, parameters: np.ndarray, names, duration: float,
                         seed: int, noise: float = 0.0) -> ci.Dataset:
    """A log of MuJoCo at step H, implicitfast, under computed torque with the true model
    (its own ``mj_inverse``, discrete-time) tracking a Fourier trajectory."""
    spec = mjcf_spec(model, parameters, names)
    spec.option.timestep = H
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.enableflags |= int(mujoco.mjtEnableBit.mjENBL_INVDISCRETE)
    mj = spec.compile()
    data = mujoco.MjData(mj)
    rng = np.random.default_rng(seed)
    des = ci.FourierTrajectory.random(model, 4, 4.0, rng).sample(1.0 / H, duration + 2 * H)
    steps = int(round(duration / H))
    data.qpos[:], data.qvel[:] = des.q[0], des.dq[0]
    q, dq, tau = (np.empty((steps + 1, model.nv)) for _ in range(3))
    for k in range(steps + 1):
        data.qacc[:] = des.ddq[k] + 40.0 * (des.dq[k] - data.qvel) + 400.0 * (des.q[k]
                                                                               - data.qpos)
        mujoco.mj_inverse(mj, data)
        q[k], dq[k], tau[k] = data.qpos, data.qvel, data.qfrc_inverse
        data.qfrc_applied[:] = data.qfrc_inverse
        mujoco.mj_step(mj, data)
    ddq = np.diff(dq, axis=0) / H
    tau = tau + noise * rng.standard_normal(tau.shape)
    return ci.Dataset(t=H * np.arange(steps), q=q[:-1], dq=dq[:-1], ddq=ddq, tau=tau[:-1],
                      joint_names=tuple(model.joint_names))


@pytest.fixture(scope="module")
def truth(panda):
    rng = np.random.default_rng(3)
    inertial = panda.prior_parameters * np.repeat(1 + 0.2 * rng.uniform(-1, 1, panda.n_bodies),
                                                  10)
    armature = np.linspace(0.12, 0.04, panda.nv)
    damping = np.linspace(0.8, 0.3, panda.nv)
    extra, names = _terms(panda, armature, damping)
    return (panda.with_parameters(inertial), np.concatenate([inertial, extra]),
            list(panda.parameter_names) + names, armature, damping)


class _Fixed:
    """A model with given parameters, as validate_rollout reads an identification result."""

    def __init__(self, model, parameters, names):
        self.model, self.parameters, self.parameter_names = model, parameters, names


def test_the_true_model_replays_its_own_log(panda, truth):
    true_model, params, names, *_ = truth
    log = pd_log(panda, params, names, 2.0, seed=0)
    v = validate_rollout(log, {"nominal": panda, "truth": _Fixed(panda, params, names)})
    nominal, exact = v.replays
    assert np.all(exact.q_error < 1e-9) and np.all(exact.tau_error < 1e-6)
    assert np.all(exact.drift < 1e-9)                              # open loop too
    assert np.max(nominal.q_error) > 1e-4 and np.max(nominal.drift) > 1e-3
    assert v.shrink["q_error_mrad"] < 1e-4


def test_the_true_model_replays_through_the_users_mjcf(panda, truth, tmp_path):
    """The user's MJCF (written with the nominal inertias) gets the true ones in memory."""
    _, params, names, *_ = truth
    log = pd_log(panda, params, names, 1.0, seed=1)
    path = write_mjcf(panda, tmp_path / "robot.xml")
    before = path.read_bytes()
    v = validate_rollout(log, {"nominal": panda, "truth": _Fixed(panda, params, names)},
                         mjcf=path)
    assert path.read_bytes() == before
    assert np.all(v.replays[1].q_error < 1e-8)
    assert np.max(v.replays[0].q_error) > 1e-4


def test_noise_only_leaves_a_small_closed_loop_error(panda, truth):
    _, params, names, *_ = truth
    log = pd_log(panda, params, names, 2.0, seed=2, noise=0.1)
    v = validate_rollout(log, {"truth": _Fixed(panda, params, names)},
                         options=RolloutOptions(controller=PDGains(bandwidth=30.0)))
    r = v.replays[0]
    assert not r.diverged
    # τ noise of 0.1 N·m through a 30 rad/s PD: sub-mrad tracking, correction below the noise
    assert np.all(r.q_error < 1e-3) and np.all(r.tau_error < 0.1)


def test_calibration_recovers_armature_and_damping(panda, truth):
    _, params, names, armature, damping = truth
    log = pd_log(panda, params, names, 4.0, seed=4, noise=0.02)
    res = ci.identify(panda, log, method="sdp", friction=("viscous",), armature=True)
    start = res.parameters.copy()
    for k, n in enumerate(res.parameter_names):
        if n.endswith((".Ia", ".fv")):
            start[k] = 0.0                    # the simulator terms start from nothing
    cal = calibrate_simulator(dataclasses.replace(res, parameters=start), log)
    assert cal.cost < cal.cost_start
    assert np.all(np.isfinite(cal.std)) and np.all(cal.std > 0)
    got_a, got_d = cal.term("armature"), cal.term("damping")
    # joints 1-2: the armature trades with link 1's Izz in the identification; from joint 3 on
    # each armature is its own
    assert np.allclose(got_a[2:], armature[2:], rtol=0.1, atol=4e-3), (got_a, armature)
    assert np.allclose(got_d, damping, rtol=0.1, atol=0.03), (got_d, damping)
    assert np.all(np.abs(cal.term("frictionloss")) < 0.05)     # none was simulated
    # σ cover the truth (the inertias' uncertainty in them, joints 3… as above)
    assert np.all(np.abs(got_a[2:] - armature[2:]) < 3 * cal.term_std("armature")[2:])
    assert np.all(np.abs(got_d - damping) < 3 * cal.term_std("damping"))


def test_results_save_and_report(panda, truth, tmp_path):
    _, params, names, *_ = truth
    log = pd_log(panda, params, names, 1.0, seed=5)
    v = validate_rollout(log, {"nominal": panda, "truth": _Fixed(panda, params, names)})
    back = type(v).load(v.save(tmp_path / "rollout.json"))
    assert np.array_equal(back.replays[0].q_error, v.replays[0].q_error)
    assert "nominal" in v.summary() and v.report(tmp_path / "r.html").read_text().count("<table")
    with pytest.raises(ci.OptionError, match="json"):
        v.save(tmp_path / "rollout.txt")


@pytest.mark.parametrize("edit, match", [
    (lambda d: d.pop("kp"), "field 'kp' is missing"),
    (lambda d: d.update(format="other"), "not a saved rollout validation"),
    (lambda d: d.update(timestep=-0.002), "field 'timestep'"),
    (lambda d: d.update(integrator="semi"), "field 'integrator'"),
    (lambda d: d["replays"][0].update(q_error=[0.1, 0.2]), "field 'q_error' must hold 7"),
    (lambda d: d["replays"][0].update(tau_error=[-1.0] * 7), "field 'tau_error'"),
    (lambda d: d.update(kd=[{"__float__": "nan"}] * 7), "field 'kd'"),
    (lambda d: d["replays"][1].update(diverged="no"), r"replays\[1\]: field 'diverged'"),
    (lambda d: d.update(replays=[]), "'replays' is empty"),
])
def test_a_tampered_rollout_file_is_refused(panda, truth, tmp_path, edit, match):
    import json

    _, params, names, *_ = truth
    log = pd_log(panda, params, names, 0.5, seed=8)
    path = validate_rollout(log, {"nominal": panda, "truth": _Fixed(panda, params, names)}
                            ).save(tmp_path / "rollout.json")
    doc = json.loads(path.read_text())
    edit(doc)
    path.write_text(json.dumps(doc))
    with pytest.raises(ci.ResultFileError, match=match):
        ci.RolloutValidation.load(path)


def test_a_rollout_file_that_is_not_json_is_refused(tmp_path):
    path = tmp_path / "rollout.json"
    path.write_bytes(b"\xff\xfe not json")
    with pytest.raises(ci.ResultFileError, match="not a JSON file"):
        ci.RolloutValidation.load(path)
    with pytest.raises(ci.ResultFileError, match="does not exist"):
        ci.RolloutValidation.load(tmp_path / "missing.json")


def test_a_failed_save_leaves_the_old_file(panda, truth, tmp_path, monkeypatch):
    _, params, names, *_ = truth
    log = pd_log(panda, params, names, 0.5, seed=9)
    v = validate_rollout(log, {"truth": _Fixed(panda, params, names)})
    path = v.save(tmp_path / "rollout.json")
    before = path.read_bytes()

    def broken(self, *args, **kwargs):
        Path.write_bytes(self, b'{"format": "consistid.rollout", "jo')    # half-written
        raise OSError("disk full")

    monkeypatch.setattr(Path, "write_text", broken)
    with pytest.raises(OSError, match="disk full"):
        v.save(path)
    monkeypatch.undo()
    assert path.read_bytes() == before and [p.name for p in tmp_path.iterdir()] == [path.name]


@pytest.mark.parametrize("kwargs, match", [
    (dict(timestep=0.0), "RolloutOptions.timestep"),
    (dict(integrator="semi"), "RolloutOptions.integrator"),
    (dict(window=-1.0), "RolloutOptions.window"),
    (dict(controller=PDGains(kp=100.0, kd=10.0), threads=0), "RolloutOptions.threads"),
])
def test_bad_options_name_the_keyword(kwargs, match):
    with pytest.raises(ci.OptionError, match=match):
        RolloutOptions(**kwargs)


def test_gains_need_both_or_neither():
    with pytest.raises(ci.OptionError, match="both kp and kd"):
        PDGains(kp=10.0)
    with pytest.raises(ci.OptionError, match="1 or 7"):
        PDGains(kp=(1.0, 2.0), kd=(1.0, 2.0)).resolve(np.ones(7))


def _config(tmp_path, rollout: str) -> str:
    data = Path(__file__).resolve().parents[1] / "examples" / "panda" / "data"
    path = tmp_path / "rollout.toml"
    path.write_text(f"""
[model]
example = "panda"
[data]
dir = "{data.as_posix()}"
train = ["panda_train.csv"]
held_out = ["panda_held_out.csv"]
trim_start = 0.5
[identify]
method = "sdp"
friction = ["coulomb", "viscous"]
[rollout]
{rollout}
""")
    return str(path)


def test_cli_rollout_writes_its_report(tmp_path, capsys):
    from consistid.cli.commands import main

    out = tmp_path / "rollout.html"
    assert main(["rollout", _config(tmp_path, 'window = 0.5'), "--output", str(out)]) == 0
    text = capsys.readouterr().out
    assert "nominal" in text and "identified" in text and out.read_text().count("<table") >= 2


def test_cli_rollout_under_computed_torque(tmp_path, capsys):
    from consistid.cli.commands import main

    config = _config(tmp_path, 'controller = "computed_torque"\nbandwidth = 10.0')
    assert main(["rollout", config]) == 0
    assert "closed loop under computed torque (mean K_p 100)" in capsys.readouterr().out
    assert main(["rollout", _config(tmp_path, 'controller = "lqr"')]) == 2
    assert "[rollout] controller = 'lqr'" in capsys.readouterr().err
    assert main(["rollout", _config(tmp_path, 'calibrate = true\nterms = ["mass"]')]) == 2
    assert "[rollout] terms = ['mass']" in capsys.readouterr().err


def test_cli_rollout_names_a_bad_key_in_toml(tmp_path, capsys):
    from consistid.cli.commands import main

    assert main(["rollout", _config(tmp_path, 'integrator = "semi"')]) == 2
    assert "RolloutOptions.integrator" in capsys.readouterr().err
    assert main(["rollout", _config(tmp_path, 'stepsize = 0.001')]) == 2
    assert "[rollout]" in capsys.readouterr().err


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-3.0, 3.0), min_size=10, max_size=10))
def test_every_log_cholesky_vector_is_a_consistent_body_and_round_trips(u):
    from consistid.simulator.logcholesky import (from_log_cholesky, pseudo_inertia,
                                                 to_log_cholesky)

    pi = from_log_cholesky(np.array(u))
    assert ci.is_physically_consistent(pi, "pseudo-inertia").ok
    j = pseudo_inertia(pi)
    # near the boundary (J almost singular) to_log_cholesky first moves the body inside
    assume(np.linalg.eigvalsh(j)[0] > 1e-6 * np.trace(j))
    assert np.allclose(to_log_cholesky(pi), u, atol=1e-6 * (1 + np.abs(u).max()))


def test_a_calibration_warns_in_another_simulator(panda, truth):
    _, params, names, *_ = truth
    log = pd_log(panda, params, names, 1.0, seed=6)
    res = ci.identify(panda, log, method="sdp", friction=("viscous",), armature=True)
    cal = calibrate_simulator(res, log, max_iterations=1)
    with pytest.warns(ci.ModelMisfitWarning, match="calibrated at 0.002 s implicitfast"):
        cal.simulator(timestep=0.001, integrator="RK4")
    assert cal.simulator(timestep=0.002, integrator="implicitfast").nv == panda.nv


def test_a_diagnosis_carries_the_rollout(panda, truth, tmp_path):
    _, params, names, *_ = truth
    log = pd_log(panda, params, names, 4.0, seed=7, noise=0.05)
    diag = ci.diagnose(panda, log, effects=("inertia", "viscous", "armature"))
    v = validate_rollout(log, {"nominal": panda, "truth": _Fixed(panda, params, names)})
    carried = diag.with_rollout(v)
    assert diag.rollout is None and carried.rollout is v
    text = carried.summary()
    assert "How far the gap shrinks in your simulator" in text and v.summary() in text
    assert 'id="rollout"' in carried.report(tmp_path / "d.html").read_text()
    back = ci.Diagnosis.load(carried.save(tmp_path / "d.json"))      # the rollout travels too
    assert back.rollout is not None and back.summary() == text
    for a, b in zip(back.rollout.replays, v.replays):
        np.testing.assert_array_equal(a.q_error, b.q_error)


def test_computed_torque_replays_with_the_model_under_test(panda, truth, tmp_path):
    """Under computed torque every model follows the log (its own inverse dynamics linearises
    it exactly); the model shows in the torque it commands: none beyond the log for the truth,
    the identification's between the truth's and the nominal's."""
    _, params, names, *_ = truth
    train = _computed_torque_log(panda, params, names, 4.0, seed=11, noise=0.05)
    held = _computed_torque_log(panda, params, names, 2.0, seed=12)
    res = ci.identify(panda, train, method="sdp", friction=("viscous",), armature=True)
    v = validate_rollout(held, {"nominal": panda, "identified": res,
                                "truth": _Fixed(panda, params, names)},
                         options=RolloutOptions(controller=ComputedTorque(bandwidth=15.0)))
    nominal, identified, exact = v.replays
    assert v.controller == "computed torque" and "computed torque" in v.summary()
    assert np.allclose(v.kp, 15.0 ** 2) and np.allclose(v.kd, 30.0)
    assert all(np.all(r.q_error < 1e-9) for r in v.replays)
    assert np.all(exact.tau_error < 1e-9)
    tau = [np.sqrt(np.mean(r.tau_error ** 2)) for r in v.replays]
    assert tau[2] < tau[1] < 0.1 * tau[0], tau
    # a PD replay of the same log sees the same ordering in its tracking error
    pd = validate_rollout(held, {"nominal": panda, "identified": res,
                                 "truth": _Fixed(panda, params, names)})
    q = [r.row()["q_error_mrad"] for r in pd.replays]
    assert q[2] < 1e-6 < q[1] < q[0]
    # through the user's MJCF (nominal inertias in the file, the truth's put in memory)
    path = write_mjcf(panda, tmp_path / "robot.xml")
    own = validate_rollout(held, {"truth": _Fixed(panda, params, names)}, mjcf=path,
                           options=RolloutOptions(controller=ComputedTorque()))
    assert np.all(own.replays[0].tau_error < 1e-9) and np.all(own.replays[0].q_error < 1e-9)


def test_calibration_under_computed_torque_recovers_damping(panda, truth):
    _, params, names, armature, damping = truth
    log = _computed_torque_log(panda, params, names, 1.2, seed=13, noise=0.02)
    res = ci.identify(panda, log, method="sdp", friction=("viscous",), armature=True)
    start = res.parameters.copy()
    for k, n in enumerate(res.parameter_names):
        if n.endswith(".fv"):
            start[k] = 0.0
    cal = calibrate_simulator(dataclasses.replace(res, parameters=start), log,
                              controller=ComputedTorque(), max_iterations=3)
    assert cal.controller == "computed torque" and cal.cost < 0.1 * cal.cost_start
    assert np.allclose(cal.term("damping"), damping, rtol=0.1, atol=0.03)
    assert np.allclose(cal.term("armature")[2:], armature[2:], rtol=0.1, atol=4e-3)


@pytest.mark.parametrize("kwargs, match", [
    (dict(bandwidth=0.0), "ComputedTorque.bandwidth"),
    (dict(kp=100.0), "both kp and kd"),
    (dict(kp=-1.0, kd=1.0), "kp must be > 0"),
])
def test_bad_computed_torque_gains_name_the_keyword(kwargs, match):
    with pytest.raises(ci.OptionError, match=match):
        ComputedTorque(**kwargs)


def test_calibration_recovers_a_planted_gain_and_delay(panda, truth):
    """Drive gains off by up to 15 % and a 4 ms delay, planted in MuJoCo's "real" robot: the
    calibration finds each within 3σ, or says it cannot (held at its start, warned, listed)."""
    _, params, names, armature, damping = truth
    gain = np.array([1.1, 0.9, 1.15, 0.85, 1.05, 0.95, 1.1])
    # the physical parameters from the drives as they were (no gain error, no delay)
    res = ci.identify(panda, pd_log(panda, params, names, 3.0, seed=20, noise=0.02),
                      method="sdp", friction=("viscous",), armature=True)
    log = pd_log(panda, params, names, 3.0, seed=21, noise=0.02, gain=gain, lag=2,
                 gains=(100.0, 10.0))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        cal = calibrate_simulator(res, log, terms=("armature", "damping", "gain", "delay"))
    assert cal.names[-1] == "delay" and cal.layout.terms[-2:] == ("gain", "delay")
    z = np.abs(cal.values - np.concatenate([armature, damping, gain, [2 * H]])) / cal.std
    held = np.isin(cal.names, cal.uninformed)
    assert np.all(np.isfinite(cal.std)) and np.all(z[~held] < 3.0), dict(zip(cal.names, z))
    assert np.array_equal(cal.values[held], cal.start[held])
    assert "delay" not in cal.uninformed and all(f"panda_joint{j}.gain" not in cal.uninformed
                                                 for j in (1, 2, 4))
    said = [str(w.message) for w in caught if issubclass(w.category, ci.PoorExcitationWarning)]
    assert all(any(n in m for m in said) for n in cal.uninformed)
    # the calibrated simulator replays with its gain and delay: it beats the physical model
    v = validate_rollout(log, {"identified": res, "calibrated": cal})
    assert v.shrink["q_error_mrad"] < 0.5


def test_gain_and_delay_are_refused_under_computed_torque(panda, truth):
    _, params, names, *_ = truth
    log = pd_log(panda, params, names, 0.5, seed=22)
    res = ci.identify(panda, log, method="sdp", friction=("viscous",), armature=True)
    with pytest.raises(ci.OptionError, match="PD replay"):
        calibrate_simulator(res, log, controller=ComputedTorque(), terms=("armature", "gain"))
    with pytest.raises(ci.OptionError, match="terms="):
        calibrate_simulator(res, log, terms=("armature", "mass"))


def test_the_actuation_applies_gain_and_delay(panda, truth):
    """``actuated`` is a shift by whole steps and a scaling (closed form); under computed
    torque through a drive of gain 2 the model commands half the logged torque and still
    tracks; a 4 ms delay in it is followed by the lagged command."""
    from consistid.simulator.engine import build_simulator
    from consistid.simulator.replay import LogGrid, actuated, computed_torque

    tau = np.arange(12.0).reshape(6, 2)
    got = actuated(tau, 0.002, np.array([2.0, 0.5]), 0.004)
    want = np.vstack([tau[:1], tau[:1], tau[:4]]) * [2.0, 0.5]
    np.testing.assert_allclose(got, want)
    _, params, names, *_ = truth
    log = LogGrid.from_dataset(_computed_torque_log(panda, params, names, 0.4, seed=14), H)
    sim = build_simulator(panda, params, names, timestep=H, integrator="implicitfast")
    kp, kd = ComputedTorque().resolve(np.ones(panda.nv))
    doubled = dataclasses.replace(sim, gain=np.full(panda.nv, 2.0))
    run = computed_torque(doubled, [doubled.mj_model], log, kp, kd)
    assert np.nanmax(np.abs(run.error)) < 1e-9
    np.testing.assert_allclose(run.correction[0], -0.5 * log.tau[:-1], atol=1e-8)
    late = dataclasses.replace(sim, delay=2 * H)
    run = computed_torque(late, [late.mj_model], log, kp, kd)
    assert not run.diverged[0] and np.nanmax(np.abs(run.error)) > 1e-6   # the lag is felt


_JSON = st.recursive(st.none() | st.booleans() | st.integers(-10, 10) | st.floats()
                     | st.text(max_size=5),
                     lambda inner: st.lists(inner, max_size=8)
                     | st.dictionaries(st.text(max_size=5), inner, max_size=3), max_leaves=12)


@settings(max_examples=80, deadline=None)
@given(key=st.sampled_from(["format", "joint_names", "timestep", "integrator", "window", "kp",
                            "kd", "duration", "controller", "replays", "replays.0.q_error",
                            "replays.0.label", "replays.1.diverged", "replays.1.drift_max"]),
       value=_JSON)
def test_a_fuzzed_rollout_file_loads_or_is_refused_by_name(key, value):
    """Any JSON value in any field: a RolloutValidation or a ResultFileError, nothing else."""
    import json
    import tempfile

    from consistid.simulator.rollout import Replay, RolloutValidation

    nv = 2
    replays = tuple(Replay(label, np.full(nv, 1e-3), np.full(nv, 0.1), np.full(nv, 2e-3),
                           np.full(nv, 3e-3), False) for label in ("nominal", "identified"))
    v = RolloutValidation(replays, ("j1", "j2"), 0.002, "implicitfast", 1.0, np.ones(nv),
                          np.ones(nv), 2.0)
    with tempfile.TemporaryDirectory() as folder:
        path = v.save(Path(folder) / "rollout.json")
        doc = json.loads(path.read_text())
        *parents, last = key.split(".")
        target = doc
        for p in parents:
            target = target[int(p)] if p.isdigit() else target[p]
        target[int(last) if last.isdigit() else last] = value
        path.write_text(json.dumps(doc))
        try:
            back = RolloutValidation.load(path)
        except ci.ResultFileError:
            return
        assert isinstance(back, RolloutValidation) and len(back.replays) >= 1
        assert all(r.q_error.shape == (len(back.joint_names),) for r in back.replays)


def _short_calibration(panda, truth, monkeypatch, step: float):
    """Calibrate on a 0.3 s log (the σ's inertia share dominates), recording whether each
    inertia vector the simulator was given is physically consistent."""
    from consistid.robot.inertia import is_physically_consistent
    from consistid.simulator import calibrate as calibrate_module

    _, params, names, *_ = truth
    log = pd_log(panda, params, names, 0.3, seed=4, noise=0.02)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ci.PoorExcitationWarning)
        res = ci.identify(panda, log, method="sdp", friction=("viscous",), armature=True)
    given = []
    write = calibrate_module.write_inertias

    def spy(sim, mj, inertial):
        given.append(is_physically_consistent(inertial, "pseudo-inertia", panda.body_names).ok)
        return write(sim, mj, inertial)

    monkeypatch.setattr(calibrate_module, "write_inertias", spy)
    monkeypatch.setattr(calibrate_module, "INERTIA_STEP", step)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ci.PoorExcitationWarning)
        return calibrate_simulator(res, log), given


def test_the_inertia_share_of_sigma_is_physical_and_does_not_depend_on_the_step(
        panda, truth, monkeypatch):
    """The inertias' share of σ is a derivative: every perturbed body the simulator gets is
    consistent (none clipped), and σ is the same at steps of 0.1, 0.01 and 0.001 σ. Figures
    (panda, 0.3 s): joint-1 armature σ 0.895 / 0.895 / 0.894 kg·m², 0 of 42 perturbed
    inertia vectors inconsistent; before (steps in π itself, negative moments clipped) 37, 28,
    17 of 44 inconsistent and σ 5.46 / 1.03 / 0.914 with the step."""
    stds = []
    for step in (0.1, 0.01, 0.001):
        cal, given = _short_calibration(panda, truth, monkeypatch, step)
        assert given and all(given), f"{given.count(False)} of {len(given)} inconsistent"
        stds.append(cal.std)
    assert np.all(np.isfinite(stds))
    np.testing.assert_allclose(stds[0], stds[2], rtol=0.02)
    np.testing.assert_allclose(stds[1], stds[2], rtol=0.02)


def test_an_inconsistent_body_is_not_clipped_silently(panda, truth):
    """A perturbed candidate with a negative moment reaches the simulator only with a warning."""
    from consistid.simulator.engine import build_simulator, write_inertias

    _, params, names, *_ = truth
    sim = build_simulator(panda, params, names, timestep=H, integrator="implicitfast")
    bad = params[:panda.n_inertial].copy()
    bad[4] = -1.0                                # body 1's Ixx: a negative moment
    with pytest.warns(ci.ModelMisfitWarning, match="panda_link1.*negative"):
        write_inertias(sim, sim.mj_model, bad)


@pytest.mark.parametrize("term, value, std, floor, informed", [
    ("armature", 5.0, 0.5, 0.01, True),        # an industrial arm's, to 10 %: informed
    ("damping", 40.0, 2.0, 0.05, True),
    ("damping", 0.01, 0.08, 0.001, False),     # a small arm's, σ 800 %: not informed
    ("armature", 0.002, 0.004, 1e-4, False),
    ("frictionloss", 0.0, 0.004, 0.02, True),  # ≈ 0 and known to be below the noise
    ("frictionloss", 0.0, 0.3, 5.0, False),    # a joint that hardly moves: no floor of 5 N·m
    ("gain", 1.0, 0.05, np.inf, True),
    ("gain", 1.0, 0.3, np.inf, False),
])
def test_informed_is_relative_to_the_terms_magnitude(term, value, std, floor, informed):
    """σ against the term's own magnitude (a large arm's terms are not held for being large,
    a small arm's not passed for being small), a noise floor near zero."""
    from consistid.simulator.terms import TermLayout, informed_threshold

    layout = TermLayout((term,), 1)
    threshold = informed_threshold(layout, np.array([value]), np.array([value]),
                                   np.array([floor]))
    assert bool(std <= threshold[0]) is informed, threshold


def test_a_term_reported_informed_has_its_final_sigma_below_the_threshold(panda, truth,
                                                                          monkeypatch):
    """Which terms are informed is decided on the σ reported (the inertias' share included):
    on a 0.3 s log that share dominates, so terms must be held, and none reported informed may
    carry a σ above its threshold (at most half its magnitude or its typical scale,
    :func:`~consistid.simulator.terms.informed_threshold`)."""
    from consistid.simulator.terms import RELATIVE, TYPICAL

    cal, _ = _short_calibration(panda, truth, monkeypatch, 0.01)
    assert cal.uninformed
    for name, std, value, start in zip(cal.names, cal.std, cal.values, cal.start):
        if name not in cal.uninformed:
            bound = max(RELATIVE * max(abs(value), abs(start)), TYPICAL[name.rpartition(".")[2]])
            assert std <= bound, (name, std, bound)


@pytest.fixture(scope="module")
def saved_calibration(panda, truth, tmp_path_factory):
    """An identification and the JSON document of a calibration made on it (0.3 s log)."""
    import json

    _, params, names, *_ = truth
    log = pd_log(panda, params, names, 0.3, seed=4, noise=0.02)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ci.PoorExcitationWarning)
        res = ci.identify(panda, log, method="sdp", friction=("viscous",), armature=True)
        cal = calibrate_simulator(res, log, max_iterations=1)
    path = cal.save(tmp_path_factory.mktemp("cal") / "calibration.json")
    return res, cal, json.loads(path.read_text())


def test_a_calibration_round_trips(saved_calibration, tmp_path):
    from consistid.simulator import SimulatorCalibration

    res, cal, _ = saved_calibration
    back = SimulatorCalibration.load(cal.save(tmp_path / "c.json"), res)
    for key in ("start", "values", "std", "kp", "kd", "inertial", "base_parameters",
                "base_std"):
        np.testing.assert_array_equal(getattr(back, key), getattr(cal, key))
    assert (back.names, back.uninformed, back.controller) == (cal.names, cal.uninformed,
                                                              cal.controller)


@pytest.mark.parametrize("edit, match", [
    (lambda d: d["names"].__setitem__(0, "panda_joint1.mass"), "field 'names'"),
    (lambda d: d["names"].__setitem__(0, "panda_joint2.armature"), "field 'names'"),
    (lambda d: d.update(values=d["values"][:-1]), "field 'values' must hold 21"),
    (lambda d: d.update(std=[-1.0] * 21), "field 'std'"),
    (lambda d: d.update(kind="other"), "not a saved SimulatorCalibration"),
    (lambda d: d.pop("kp"), "field 'kp' is missing"),
    (lambda d: d.update(controller="LQR"), "field 'controller'"),
    (lambda d: d.update(uninformed=["panda_joint1.gain"]), "field 'uninformed'"),
    (lambda d: d.update(integrator="semi"), "field 'integrator'"),
    (lambda d: d.update(inertial=d["inertial"][:10]), "field 'inertial' must hold 70"),
    (lambda d: d.update(refined="no"), "field 'refined'"),
    (lambda d: d.update(timestep=0), "field 'timestep'"),
])
def test_a_tampered_calibration_file_is_refused(saved_calibration, tmp_path, edit, match):
    import json

    from consistid.simulator import SimulatorCalibration

    res, _, doc = saved_calibration
    doc = json.loads(json.dumps(doc))
    edit(doc)
    path = tmp_path / "c.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(ci.ResultFileError, match=match):
        SimulatorCalibration.load(path, res)


def test_gain_under_computed_torque_is_refused_in_a_calibration_file(saved_calibration,
                                                                     tmp_path):
    import json

    from consistid.simulator import SimulatorCalibration

    res, _, doc = saved_calibration
    names = doc["names"][:7] + [n.replace("armature", "gain") for n in doc["names"][:7]]
    doc = dict(doc, names=names, start=doc["start"][:14], values=doc["values"][:14],
               std=doc["std"][:14], uninformed=[])
    (tmp_path / "c.json").write_text(json.dumps(doc))
    assert SimulatorCalibration.load(tmp_path / "c.json", res).layout.terms == ("armature",
                                                                               "gain")
    (tmp_path / "c.json").write_text(json.dumps(dict(doc, controller="computed torque")))
    with pytest.raises(ci.ResultFileError, match="gain or delay.*'computed torque'"):
        SimulatorCalibration.load(tmp_path / "c.json", res)


@settings(max_examples=60, deadline=None)
@given(key=st.sampled_from(["kind", "names", "names.0", "names.20", "start", "values",
                            "values.3", "std", "std.0", "timestep", "integrator", "kp", "kd.2",
                            "cost", "evaluations", "message", "inertial", "inertial.5",
                            "base_parameters", "base_std", "refined", "controller",
                            "uninformed"]),
       value=_JSON)
def test_a_fuzzed_calibration_file_loads_or_is_refused_by_name(saved_calibration, key, value):
    """Any JSON value in any field: a SimulatorCalibration or a ResultFileError, nothing else."""
    import json
    import tempfile

    from consistid.simulator import SimulatorCalibration

    res, _, saved = saved_calibration
    doc = json.loads(json.dumps(saved))
    *parents, last = key.split(".")
    target = doc
    for p in parents:
        target = target[p]
    target[int(last) if last.isdigit() else last] = value
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "c.json"
        path.write_text(json.dumps(doc))
        try:
            back = SimulatorCalibration.load(path, res)
        except ci.ResultFileError:
            return
    n = len(back.names)
    assert back.values.shape == back.std.shape == back.start.shape == (n,)
    assert back.layout.size == n and set(back.uninformed) <= set(back.names)


@pytest.mark.parametrize("rollout, match", [
    ('controller = "computed_torque"\ncalibrate = true\nterms = ["damping", "gain"]',
     r'controller = "computed_torque".*set controller = "pd" in \[rollout\]'),
    ('terms = ["armature"]', r"\[rollout\] terms set.*add calibrate = true"),
    ('calibrate = false\nrefine_inertia = true', r"refine_inertia set.*add calibrate = true"),
    ('calibrate = true\nterms = ["damping", "damping"]', r"\[rollout\] terms = \['damping', "),
])
def test_cli_rollout_refuses_calibration_keys_before_identifying(tmp_path, capsys, monkeypatch,
                                                                 rollout, match):
    """Contradictory or ignored calibration keys are named in TOML terms before any work (the
    identification is replaced by one that fails the test if reached)."""
    import re

    from consistid.cli import rollout as cli_rollout
    from consistid.cli.commands import main

    def reached(*args, **kwargs):
        raise AssertionError("the identification ran before the keys were checked")

    monkeypatch.setattr(cli_rollout, "identify", reached)
    assert main(["rollout", _config(tmp_path, rollout)]) == 2
    err = capsys.readouterr().err
    assert re.search(match, err), err
    assert "PDGains" not in err


@pytest.mark.parametrize("case", ["better", "worse on j2", "diverged"])
def test_rollout_report_opens_with_its_worst_finding(case):
    """The rollout page's first box (issue 31): "ok" when the last model replays closer on
    every joint, "warn" naming a joint it replays worse, "bad" headed by a diverged replay."""
    from consistid.simulator.rollout import Replay, RolloutValidation

    before = Replay("nominal", np.array([4e-3, 2e-3]), np.array([1.0, 0.5]),
                    np.array([0.1, 0.05]), np.array([0.2, 0.1]), False)
    q_after = np.array([1e-3, 3e-3 if case == "worse on j2" else 1e-3])
    after = Replay("identified", np.full(2, np.nan) if case == "diverged" else q_after,
                   np.full(2, np.nan) if case == "diverged" else np.array([0.1, 0.1]),
                   np.full(2, np.nan) if case == "diverged" else np.array([0.01, 0.02]),
                   np.full(2, np.nan) if case == "diverged" else np.array([0.02, 0.03]),
                   case == "diverged")
    v = RolloutValidation((before, after), ("j1", "j2"), 0.002, "implicitfast", 1.0,
                          np.ones(2), np.ones(2), 2.0)
    page = v.page().render()
    box = page.split('<div class="verdict ', 1)[1].split("</div>", 1)[0]
    level, headline = box.split('"', 1)[0], box.split('<p class="headline">', 1)[1]
    if case == "better":
        ratio = np.sqrt(np.mean(q_after ** 2) / np.mean(before.q_error ** 2))   # RMS over joints
        assert level == "ok" and f"closed-loop q error ×{ratio:.3g}" in headline
        assert "j2, 20 mrad RMS" in box                 # the joint drifting most, named
    elif case == "worse on j2":
        assert level == "warn" and "worse than nominal on j2" in headline
    else:
        assert level == "bad" and headline.startswith("identified diverged")


def test_a_rollout_whose_open_loop_diverged_is_not_ok():
    """The last model's open loop diverged in every window (drift NaN) while its closed loop
    held: its first-box line is "bad", with the joints named, not "ok" read off NaN ratios
    (the review)."""
    from consistid.simulator.rollout import Replay, RolloutValidation

    nan = np.full(2, np.nan)
    urdf = Replay("URDF", np.array([0.01, 0.02]), np.array([1.0, 1.0]),
                  np.array([0.01, 0.01]), np.array([0.02, 0.02]), False)
    found = Replay("identified", np.array([0.005, 0.01]), np.array([0.5, 0.5]), nan, nan, False)
    v = RolloutValidation((urdf, found), ("j1", "j2"), 0.001, "implicitfast", 0.5,
                          np.ones(2), np.ones(2), 10.0)
    level, text = v.findings()[0]
    assert level == "bad" and "worse than URDF on j1, j2" in text
    # the other way round (the URDF's open loop diverged, the identified model's did not) is
    # an improvement, not "bad" (the second review)
    urdf_lost = dataclasses.replace(urdf, drift=nan)
    held = dataclasses.replace(found, drift=np.array([0.01, 0.01]))
    back = RolloutValidation((urdf_lost, held), ("j1", "j2"), 0.001, "implicitfast", 0.5,
                             np.ones(2), np.ones(2), 10.0)
    assert back.findings()[0][0] == "ok"

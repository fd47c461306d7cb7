"""Drives: transmission algebra, the coupled motor's columns against MuJoCo, drive gains from
currents with a known load and a coupled wrist, each against the simulation's truth."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import consistid as ci
from consistid.drives.motor_terms import motor_column_names, motor_columns
from consistid.excitation import FourierTrajectory
from consistid.simulate import Effects, MountedPayload
from consistid.simulate.drives import SimulatedDrives, record_drives
from consistid.simulate.mujoco_robot import MujocoRobot

KT = np.array([0.13, 0.13, 0.13, 0.1, 0.1, 0.1])
NOISE = 0.01                                                         # A
LOAD = MountedPayload(2.5, com=[0.02, -0.03, 0.08], inertia=np.diag([0.01, 0.012, 0.008]))


@pytest.fixture(scope="module")
def ur5() -> ci.RobotModel:
    return ci.RobotModel.example("ur5")


def wrist_coupling(c: float = 1.0) -> np.ndarray:
    """Motor 6 turns with joints 5 and 6 (``q_m6 = r (c q5 + q6)``), as on a TX40 wrist."""
    g = np.eye(6)
    g[5, 4] = c
    return g


def run(model, drives, seed, payload=None, duration=10.0) -> ci.Dataset:
    """A simulated log, exact joint states (from the motor encoders) and noisy currents."""
    traj = FourierTrajectory.random(model, 5, 10.0, np.random.default_rng(seed))
    rec = record_drives(model, traj, drives, Effects(payload=payload), seed=seed,
                        duration=duration, rate=500.0)
    q = drives.transmission.joint_positions(rec.motor_q)
    assert np.allclose(q, rec.truth.true_q, atol=1e-12)
    return ci.Dataset(t=rec.t, q=q, dq=rec.truth.true_dq, ddq=rec.truth.true_ddq,
                      tau=rec.currents, joint_names=tuple(model.joint_names))


# ----------------------------------------------------------------------------- transmission
@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(0.5, 200.0), min_size=3, max_size=3),
       st.lists(st.sampled_from([-1.0, 1.0]), min_size=3, max_size=3),
       st.floats(-2.0, 2.0), st.integers(0, 2 ** 31))
def test_transmission_round_trip_and_power(ratios, signs, c, seed):
    """Motor angles → joint angles inverts the forward map, and the torque map conserves
    power: ``τᵀ q̇ = τ_mᵀ q̇_m`` (independent of how the maps are written)."""
    g = np.eye(3)
    g[2, 1] = c
    tr = ci.Transmission(np.array(ratios) * signs, coupling=g)
    rng = np.random.default_rng(seed)
    q, tau_m = rng.standard_normal((5, 3)), rng.standard_normal((5, 3))
    np.testing.assert_allclose(tr.joint_positions(tr.motor_positions(q)), q, atol=1e-9)
    np.testing.assert_allclose(np.sum(tr.joint_torque(tau_m) * q, axis=1),
                               np.sum(tau_m * tr.motor_positions(q), axis=1),
                               rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(tr.motor_torque(tr.joint_torque(tau_m)), tau_m, atol=1e-9)


@pytest.mark.parametrize("kwargs, match", [
    (dict(ratios=[100, 0, 50]), r"ratios\[1\] = 0"),
    (dict(ratios=[100, 50, 50], coupling=[[1, 0, 0], [1, 0, 0], [0, 0, 1]]), "singular"),
    (dict(ratios=[100, 50, 50], coupling=np.eye(2)), "3×3"),
    (dict(ratios=[100, 50, 50], torque_constants=[0.1, 0.1]), "torque_constants has 2"),
    (dict(ratios=[100, np.nan, 50]), r"ratios\[1\]"),
])
def test_bad_transmission_is_named(kwargs, match):
    with pytest.raises(ci.OptionError, match=match):
        ci.Transmission(**kwargs)


def test_ratios_of_the_wrong_length_are_named(ur5):
    tr = ci.Transmission([100.0] * 5, torque_constants=[0.1] * 5)
    with pytest.raises(ci.JointCountError, match="ratios has 5 entries but the robot has 6"):
        record_drives(ur5, FourierTrajectory.random(ur5, 3, 5.0, np.random.default_rng(0)),
                      SimulatedDrives(tr), duration=1.0)


# ----------------------------------------------------------------------------- motor columns
def test_coupled_motor_columns_match_mujoco(ur5):
    """MuJoCo's inverse dynamics with the coupled motor (a tendon with armature and damping)
    minus without it equals the motor columns times the true motor-side terms."""
    ia, fv = 3e-5, 4e-4
    tr = ci.Transmission([101.0, 101, 101, 101, 80, -60], coupling=wrist_coupling(0.7),
                         torque_constants=KT)
    drives = SimulatedDrives(tr, rotor_inertia=[0, 0, 0, 0, 0, ia], viscous=[0] * 5 + [fv])
    rng = np.random.default_rng(3)
    q, dq, ddq = (rng.standard_normal((20, 6)) for _ in range(3))
    with_motor = MujocoRobot(ur5, tendons=drives.tendons(ur5, 1e-3)).inverse(q, dq, ddq)
    without = MujocoRobot(ur5).inverse(q, dq, ddq)
    assert motor_column_names(tr) == ["drives.Iam6", "drives.fvm6", "drives.fsm6"]
    predicted = motor_columns(tr, dq, ddq) @ np.array([ia, fv, 0.0])
    np.testing.assert_allclose(with_motor - without, predicted, rtol=1e-8, atol=1e-9)
    assert np.abs(predicted[:, 4]).max() > 0.1            # the cross term on joint 5 is there


# ----------------------------------------------------------------------------- drive gains
@pytest.fixture(scope="module")
def current_runs(ur5):
    tr = ci.Transmission([101.0, 101, 101, 101, -101, 101], torque_constants=KT)
    drives = SimulatedDrives(tr, viscous=2e-4, current_noise=NOISE)
    return (tr, run(ur5, drives, 1), run(ur5, drives, 2, payload=LOAD), run(ur5, drives, 3),
            drives)


@pytest.mark.parametrize("method", ["wls", "sdp"])
def test_drive_gains_from_currents_and_a_known_load(ur5, current_runs, method, tmp_path):
    tr, unloaded, loaded, held_out, _ = current_runs
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ci.ModelMisfitWarning)
        found = ci.identify_drive_gains(ur5, unloaded, loaded, payload_mass=LOAD.mass,
                                        method=method, friction=("viscous",))
    truth = tr.gains
    error = found.gains - truth
    assert np.all(np.abs(error) <= 0.01 * np.abs(truth)), error / truth
    assert np.all(np.abs(error) <= 3.0 * found.std), error / found.std
    floor = np.abs(truth) * NOISE
    rms = found.result.rms(found.to_torque(held_out))
    assert np.all(rms <= 1.1 * floor), rms / floor
    assert ci.is_physically_consistent(found.result.parameters[:ur5.n_inertial])
    assert found.load[0] == LOAD.mass
    assert "drive gains" in found.summary() and "wrist_3_joint" in found._repr_html_()
    saved = ci.IdentificationResult.load(found.result.save(tmp_path / "result.json"))
    np.testing.assert_allclose(saved.details["drive_gain_values"], found.gains)
    frame = found.conf_int()                  # labelled by joint, as res.conf_int() is
    assert list(frame.index) == list(found.joint_names)
    lo, hi = frame["lower"].to_numpy(), frame["upper"].to_numpy()
    assert np.all(lo < found.gains) and np.all(found.gains < hi)
    np.testing.assert_allclose(found.conf_int(labelled=False), frame.to_numpy())
    if method == "sdp":     # the report: its first box names the least certain gain
        page = found.report(tmp_path / "gains.html", held_out=held_out).read_text()
        box = page.split('<div class="verdict ', 1)[1].split("</div>", 1)[0]
        worst = found.joint_names[int(np.argmax(found.std / np.abs(found.gains)))]
        assert f"Least certain gain: {worst}," in box and "consistent" in box
        assert page.count('<div class="verdict ') == 1       # one first box, not one per part
        assert "Measured vs predicted torque" in page and "data:image/png;base64" in page


def test_currents_without_a_loaded_run_are_refused(ur5, current_runs):
    _, unloaded, _, _, _ = current_runs
    with pytest.raises(ci.OptionError, match="needs loaded="):
        ci.identify_drive_gains(ur5, unloaded, payload_mass=2.5)


def test_a_load_too_light_to_inform_a_gain_is_named(ur5, current_runs):
    _, unloaded, _, _, drives = current_runs
    feather = run(ur5, drives, 2, payload=MountedPayload(0.005, com=[0.0, 0.0, 0.05]))
    with pytest.raises(ci.UninformedGainError, match="does not inform the drive gain of"
                       ) as err:
        ci.identify_drive_gains(ur5, unloaded, feather, payload_mass=0.005, method="wls",
                                friction=("viscous",))
    assert "'wrist_3_joint'" in str(err.value) and "heavier load" in str(err.value)


# ----------------------------------------------------------------------------- coupled wrist
def test_coupled_wrist_needs_its_motor_terms(ur5):
    """Held-out RMS at the noise floor on every joint with the coupled motor's terms, and a
    measurable failure without them."""
    tr = ci.Transmission([101.0] * 6, coupling=wrist_coupling(), torque_constants=KT)
    drives = SimulatedDrives(tr, rotor_inertia=[6e-5] * 4 + [2e-5, 4e-5],
                             viscous=[2e-4] * 5 + [4e-4], coulomb=[0.0] * 5 + [5e-3],
                             current_noise=NOISE)

    def joint_side(data):
        return data.with_torque(tr.current_torque(data.tau))

    train, test = joint_side(run(ur5, drives, 1)), joint_side(run(ur5, drives, 2))
    floor = np.sqrt((tr.coupling ** 2).T @ (tr.gains * NOISE) ** 2)
    terms = dict(armature=True, friction=("viscous", "coulomb"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ci.ModelMisfitWarning)
        coupled = ci.identify_coupled(ur5, train, tr, **terms)
        plain = ci.identify(ur5, train, **terms)
    assert np.all(coupled.rms(test) <= 1.1 * floor), coupled.rms(test) / floor
    assert np.all(plain.rms(test)[4:] > 3.0 * floor[4:]), plain.rms(test) / floor
    truth = np.array([4e-5, 4e-4, 5e-3])
    assert np.all(np.abs(coupled.motor_terms - truth) <= 0.05 * truth)
    assert "drives.Iam6" in coupled.summary()


# ----------------------------------------------------------------------------- datasheet path
@pytest.mark.parametrize("coupling", [None, wrist_coupling(-0.5)])
def test_load_recording_converts_a_motor_side_log(ur5, tmp_path, coupling):
    """Motor angles and currents in, the simulation's joint states and drive torques out, the
    conversion in the recording's steps."""
    tr = ci.Transmission([101.0, 101, 101, -101, 80, 60], coupling=coupling,
                         torque_constants=KT)
    traj = FourierTrajectory.random(ur5, 4, 8.0, np.random.default_rng(4))
    rec = record_drives(ur5, traj, SimulatedDrives(tr, viscous=1e-4), seed=4, duration=4.0,
                        rate=500.0)
    path = tmp_path / "motor_log.npz"
    np.savez(path, time=rec.t, motor_angle=rec.motor_q, current=rec.currents)
    loaded = ci.load_recording(path, keys={"t": "time", "q": "motor_angle", "tau": "current"},
                               model=ur5, drives=tr)
    data = loaded.dataset
    assert any("motor side to joint side (drives=)" in s for s in loaded.steps)
    at = np.searchsorted(rec.t, data.t)                 # the chain trims its filter's edges
    assert np.allclose(rec.t[at], data.t, atol=1e-9)
    truth = rec.truth
    scale = np.abs(truth.tau).max(axis=0)
    # the chain low-passes the currents (zero phase): the smooth torque passes unchanged
    assert np.all(np.abs(data.tau - truth.tau[at]).max(axis=0) < 0.02 * scale)
    np.testing.assert_allclose(data.q, truth.true_q[at], atol=1e-4)
    assert np.abs(data.dq - truth.true_dq[at]).max() < 0.02


def test_currents_kept_in_amperes_are_not_read_for_degrees(tmp_path):
    """Without torque constants the currents stay in A: the degrees check by the URDF's torque
    does not read them as N·m (it warned "read as degrees" on radians motor logs; the review),
    the steps say the currents were kept, and angles in degrees are still caught by the
    joint limits (the second review: skipping the whole check had lost them)."""
    panda = ci.RobotModel.example("panda")
    ratios = [100.0, 100, 100, -100, 80, 80, 50]
    tr = ci.Transmission(ratios)
    traj = FourierTrajectory.random(panda, 4, 8.0, np.random.default_rng(6), amplitude=0.02)
    drives = SimulatedDrives(ci.Transmission(ratios, torque_constants=[0.1] * 7), viscous=1e-4)
    rec = record_drives(panda, traj, drives, seed=6, duration=4.0, rate=500.0)
    path = tmp_path / "motor_log.npz"
    np.savez(path, time=rec.t, motor_angle=rec.motor_q, current=rec.currents)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        loaded = ci.load_recording(path, keys={"t": "time", "q": "motor_angle", "tau": "current"},
                                   model=panda, drives=tr)
    assert not [w for w in caught if "degrees" in str(w.message)]
    assert any("motor currents (A)" in s for s in loaded.steps)
    # the same log with its motor angles in degrees is still caught, by the joint limits
    np.savez(path, time=rec.t, motor_angle=np.degrees(rec.motor_q), current=rec.currents)
    with pytest.warns(ci.DataQualityWarning, match="look like degrees"):
        ci.load_recording(path, keys={"t": "time", "q": "motor_angle", "tau": "current"},
                          model=panda, drives=tr)


# ----------------------------------------------------------------------------- TOML [drives]
EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "ur5_drives"


def with_drives(tmp_path, drives: str | None = None) -> Path:
    """The UR5 drives example (its root pointing at the example) with its ``[drives]`` table's
    body replaced by ``drives`` (``None``: kept)."""
    text = (EXAMPLE / "identify.toml").read_text().replace('root = "."', f'root = "{EXAMPLE}"')
    if drives is not None:
        head, rest = text.split("\n[drives]", 1)
        text = (head + "\n[drives]\n" + drives + "\n\n[identify]"
                + rest.split("\n[identify]", 1)[1])
    config = tmp_path / "identify.toml"
    config.write_text(text)
    return config


@pytest.mark.parametrize("drives, match", [
    ("ratios = [101, 101, 0, 101, 101, 101]\ntorque_constants = [0.1, 0.1, 0.1, 0.1, 0.1, 0.1]",
     r"\[drives\] ratios\[2\] = 0"),
    ("ratios = [101, 101, 101, 101, 101]\ntorque_constants = [0.1, 0.1, 0.1, 0.1, 0.1]",
     r"\[drives\] ratios has 5 entries but ur5 has 6 joints"),
    ("ratios = [101, 101, 101, 101, 101, 101]", r"\[drives\] needs torque_constants"),
    ("ratios = [101, 101]\ntorque_constants = [0.1, 0.1]\ncoupling = [[1, 1], [2, 2]]",
     r"\[drives\] coupling is singular"),
    ("ratios = [101, 101]\ntorque_constants = [0.1, 0.1]\ngear = 3", r"unknown key.*\[drives\]"),
    ('ratios = [101, 101, 101, 101, 101, 101]\ngains = "identify"\npayload_mass = 2.5',
     r'\[drives\] gains = "identify" needs loaded = \["file.npz"'),
    ('ratios = [101, 101, 101, 101, 101, 101]\ngains = "identify"\nloaded = ["l.npz"]',
     r'\[drives\] gains = "identify" needs payload_mass = <kg>'),
    ('ratios = [101, 101, 101, 101, 101, 101]\ngains = "datasheet"',
     r'\[drives\] gains = "datasheet": the one value is gains = "identify"'),
    ('ratios = [101, 101, 101, 101, 101, 101]\ntorque_constants = [0.1, 0.1, 0.1, 0.1, 0.1, 0.1]'
     '\ngains = "identify"\nloaded = ["l.npz"]\npayload_mass = 2.5',
     r"torque_constants both given"),
    ('ratios = [101, 101, 101, 101, 101, 101]\ngains = "identify"\nloaded = ["l.npz"]\n'
     'payload_mass = "2.5 kg"', r"\[drives\] payload_mass"),
])
def test_bad_drives_table_is_named_in_toml_terms(tmp_path, ur5, drives, match):
    from consistid.cli.config import config_recordings, load_config

    with pytest.raises(ci.ConfigError, match=match):
        config_recordings(load_config(with_drives(tmp_path, drives)), ur5)


@pytest.mark.slow
def test_the_drives_example_identifies_the_ur5(tmp_path, ur5):
    """The example's motor-side logs, converted by ``[drives]``, give a consistent UR5 whose
    held-out residual is at the example's current noise (0.02 A × κ)."""
    import json

    from consistid.cli import main

    out = tmp_path / "out"
    config = with_drives(tmp_path)
    assert main(["-q", "identify", str(config), "--output", str(out)]) == 0
    result = ci.IdentificationResult.load(out / "result.json")
    assert ci.is_physically_consistent(result.parameters[:ur5.n_inertial])
    assert (out / "robot.urdf").exists() and json.loads((out / "result.json").read_text())


def test_drive_gains_through_a_coupled_wrist(ur5):
    """Unknown gains behind a coupled wrist whose motor has inertia and friction: the gains
    within 1 % and 3σ, and the coupled motor's terms found with them."""
    tr = ci.Transmission([101.0] * 6, coupling=wrist_coupling(), torque_constants=KT)
    drives = SimulatedDrives(tr, rotor_inertia=[0.0] * 5 + [4e-5],
                             viscous=[2e-4] * 5 + [4e-4], current_noise=NOISE)
    unloaded, loaded = run(ur5, drives, 1), run(ur5, drives, 2, payload=LOAD)
    ratios_only = ci.Transmission([101.0] * 6, coupling=wrist_coupling())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ci.ModelMisfitWarning)
        found = ci.identify_drive_gains(ur5, unloaded, loaded, payload_mass=LOAD.mass,
                                        method="wls", friction=("viscous",),
                                        transmission=ratios_only)
    error = found.gains - tr.gains
    assert np.all(np.abs(error) <= 0.01 * np.abs(tr.gains)), error / tr.gains
    assert np.all(np.abs(error) <= 3.0 * found.std), error / found.std
    terms = found.details["motor_terms"]
    assert abs(terms["drives.Iam6"] / 4e-5 - 1) < 0.05
    assert abs(terms["drives.fvm6"] / 4e-4 - 1) < 0.05
    assert found.coupled is not None and found.coupled.result is found.result


def test_the_gains_warnings_are_kept_with_the_result(ur5, tmp_path):
    """Random gains and reversed sensors (UR5, seed from the review): the consistency
    constraints move the elbow's gain 2.5 σ, which is warned, and that warning is in the
    result's details, its summary and the report's first box ("warn"), not only on stderr."""
    rng = np.random.default_rng(105)
    ratios = rng.choice([-1, 1], 6) * rng.uniform(50, 120, 6)
    kappa = rng.choice([-1, 1], 6) * np.exp(rng.uniform(np.log(0.1), np.log(10), 6))
    drives = SimulatedDrives(ci.Transmission(ratios, torque_constants=kappa / ratios),
                             viscous=2e-4, current_noise=0.01)
    unloaded, loaded = run(ur5, drives, 51), run(ur5, drives, 52, payload=LOAD)
    with pytest.warns(ci.BoundActiveWarning, match="consistency constraints move") as caught:
        found = ci.identify_drive_gains(ur5, unloaded, loaded, payload_mass=LOAD.mass)
    said = str(next(w.message for w in caught if w.category is ci.BoundActiveWarning))
    kept = [v for k, v in found.result.details.items() if k.startswith("warning")]
    assert any(said in v for v in kept) and said in found.summary()
    assert found.findings()[0][0] == "warn"
    page = found.report(tmp_path / "gains.html").read_text()
    box = page.split('<div class="verdict ', 1)[1].split("</div>", 1)[0]
    assert box.startswith("warn") and "consistency constraints move" in box


def test_the_gains_warnings_reach_the_caller_when_the_estimate_fails(ur5, current_runs,
                                                                    monkeypatch):
    """A warning raised before the consistent program fails reaches the caller with the
    error (the second review: recording the warnings for the result had swallowed it)."""
    from consistid.errors import InfeasibleError, PoorExcitationWarning

    def failing(*args, **kwargs):
        warnings.warn("barely excited", PoorExcitationWarning, stacklevel=2)
        raise InfeasibleError("the consistent program failed")

    monkeypatch.setattr("consistid.drives.gains._consistent", failing)
    _, unloaded, loaded, _, _ = current_runs
    with pytest.warns(PoorExcitationWarning, match="barely excited"):
        with pytest.raises(InfeasibleError):
            ci.identify_drive_gains(ur5, unloaded, loaded, payload_mass=LOAD.mass)


# ----------------------------------------------------------------------------- what real logs do
def test_gains_across_magnitudes_signs_offsets_and_quantisation(ur5):
    """Gains from 0.08 to 13 N·m/A on one arm, two reversed current sensors (negative torque
    constants), a constant offset on every current and 5 mA quantisation: the consistent gains
    within 1 % and 3σ of the simulation's (the whitened program; unscaled, Clarabel had
    stopped 'optimal' 46 % off)."""
    ratios = np.array([101.0, -101, 80, 121, -60, 101])
    kappa = np.array([0.08, -2.0, -0.15, 12.7, 13.4, -3.6])
    tr = ci.Transmission(ratios, torque_constants=kappa / ratios)
    drives = SimulatedDrives(tr, viscous=2e-4, current_noise=NOISE, current_step=0.005,
                             current_offset=[0.02, -0.05, 0.1, -0.01, 0.03, 0.015])
    unloaded, loaded = run(ur5, drives, 1), run(ur5, drives, 2, payload=LOAD)
    assert np.any(np.abs(np.diff(unloaded.tau[:, 3])) == 0.005)      # the logger rounds
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ci.ModelMisfitWarning)
        found = ci.identify_drive_gains(ur5, unloaded, loaded, payload_mass=LOAD.mass)
    error = found.gains - tr.gains
    assert np.all(np.abs(error) <= 0.01 * np.abs(tr.gains)), error / tr.gains
    assert np.all(np.abs(error) <= 3.0 * found.std), error / found.std
    assert np.all(np.sign(found.gains) == np.sign(kappa))


def test_gains_with_dry_friction_on_every_motor(ur5):
    """Coulomb friction on every motor (1–3 % of the UR5's effort limits, MuJoCo's soft
    frictionloss) with viscous friction: the rows at rest are left out, so the current noise
    read from the residual is the simulated one (it was up to 1.46 × with them in) and the
    gains stay within 3σ of the simulation's."""
    ratios = np.array([101.0, 101, -101, 101, 101, -101])
    effort = np.minimum(ur5.limits.effort, 200.0)
    tr = ci.Transmission(ratios, torque_constants=KT)
    drives = SimulatedDrives(tr, viscous=0.01 * effort / ratios ** 2,
                             coulomb=np.array([0.01, 0.03, 0.02, 0.03, 0.01, 0.02]) * effort
                             / np.abs(ratios), current_noise=NOISE)
    unloaded, loaded = run(ur5, drives, 3), run(ur5, drives, 4, payload=LOAD)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ci.ModelMisfitWarning)
        found = ci.identify_drive_gains(ur5, unloaded, loaded, payload_mass=LOAD.mass)
    np.testing.assert_allclose(found.details["current_sigma"], NOISE, rtol=0.1)
    error = found.gains - tr.gains
    assert np.all(np.abs(error) <= 3.0 * found.std), error / found.std
    assert np.all(np.abs(error) <= 0.015 * np.abs(tr.gains)), error / tr.gains


def test_an_unmodelled_current_offset_is_named(ur5, current_runs):
    """Currents with a constant sensor offset, fitted with friction= that has no offset column:
    an OptionError naming the joints and the keyword, not gains that absorb it."""
    tr, _, _, _, _ = current_runs
    drives = SimulatedDrives(tr, viscous=2e-4, current_noise=NOISE,
                             current_offset=[0.05, 0.0, 0.0, 0.0, 0.0, 0.0])
    unloaded, loaded = run(ur5, drives, 1), run(ur5, drives, 2, payload=LOAD)
    with pytest.raises(ci.OptionError, match="constant offset that friction= leaves out"
                       ) as err:
        ci.identify_drive_gains(ur5, unloaded, loaded, payload_mass=LOAD.mass,
                                friction=("viscous",))
    assert "'shoulder_pan_joint' (≈ 0.05" in str(err.value)
    assert "Add 'offset' to friction=" in str(err.value)


@pytest.mark.slow
def test_the_drive_gains_example_identifies_the_gains(tmp_path):
    """``[drives] gains = "identify"`` through the CLI on the example's logs (unloaded, loaded
    with 2.5 kg, held out): the gains in result.json within 1 % and 3σ of the simulated
    ``r ⊙ k_t``, and the held-out logs scored in N·m through them."""
    import json

    from consistid.cli import main

    text = (EXAMPLE / "identify_gains.toml").read_text().replace('root = "."',
                                                                   f'root = "{EXAMPLE}"')
    config = tmp_path / "identify_gains.toml"
    config.write_text(text)
    out = tmp_path / "out"
    assert main(["-q", "identify", str(config), "--output", str(out)]) == 0
    result = ci.IdentificationResult.load(out / "result.json")
    truth = np.array([101.0, 101, 101, 101, -101, 101]) * KT
    gains, std = result.details["drive_gain_values"], result.details["drive_gain_std"]
    assert np.all(np.abs(gains - truth) <= 0.01 * np.abs(truth)), gains / truth
    assert np.all(np.abs(gains - truth) <= 3.0 * std), (gains - truth) / std
    # the loaded log is an input too: hashed in the provenance (and never an output)
    inputs = json.loads((out / "result.json").read_text())["provenance"]["inputs"]
    assert any(Path(r["path"]).name == "ur5_motor_loaded.npz" and r.get("sha256")
               for r in inputs), inputs

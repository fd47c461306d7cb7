"""Drive gains from motor currents, and a coupled wrist: accuracy against MuJoCo's truth.

Gains: a simulated arm logs motor currents (per-motor torque constants, gear ratios, motor-side
viscous friction) and motor-encoder angles; the same kind of excitation runs unloaded and with a
known load. ``identify_drive_gains`` from the exact joint states ("exact") and from the
encoders through the default signal chain (``Dataset.from_recording``: filtered currents,
differentiated angles; "chain"). Printed per robot and seed: the worst gain error (%), the worst
``|error|/σ``, the held-out torque RMS over the noise floor ``|κ| σ_i`` (worst joint) and whether
every body is consistent. Arms: the UR5 (the acceptance case) and arms it was not tuned on
(Panda, UR10, xArm7), with drawn ratios, constants and loads.

Coupled wrist: motor 6 turns with joints 5 and 6 (``q_m6 = r (c q5 + q6)``); held-out RMS over
the floor per joint with ``identify_coupled`` and with plain ``identify``.

Unseen set (``--unseen``): what real current logs do, each on seeds 1–3 with drawn ratios
(±50–160), gains, loads and excitations, simulated at 2 kHz and logged at 500 Hz: a constant
current-sensor offset per motor (±0.1–0.2 A), 10 mA current quantisation, reversed current
sensors (negative torque constants), gains log-uniform in 0.05–20 N·m/A, Coulomb (1–3 % of the
effort limit, MuJoCo's soft frictionloss) and viscous friction on every motor, other arms
(Panda, xArm7, Kinova, UR10, with that friction), 1 kHz logs stamped in bursts (jitter) through
the signal chain, and 12-bit motor encoders through the chain. Printed per case and seed: the
worst gain error (%) and |error|/σ, the held-out RMS over the floor ``|κ| √(σ_i² + step²/12)``
(``*``: through the chain, whose low-pass removes most of the noise), consistency and the named
warnings; then per case the share of gains within 2σ and 3σ over the seeds. Also the current
offset left out of ``friction=`` (a named error expected).

Run: ``python benchmarks/drives.py`` (seeded; about two minutes on one core);
``python benchmarks/drives.py --unseen`` (about fifteen minutes).
"""

from __future__ import annotations

import sys
import time
import warnings

import numpy as np

import consistid as ci
from consistid.excitation import FourierTrajectory
from consistid.simulate import Effects, MountedPayload, burst_stamps
from consistid.simulate.drives import SimulatedDrives, record_drives
from consistid.simulate.experiments import TrackingController

NOISE = 0.01                                                         # A


def log(model, drives, seed, payload=None, chain=False, physics_rate=1000.0):
    traj = FourierTrajectory.random(model, 5, 10.0, np.random.default_rng(seed))
    rec = record_drives(model, traj, drives, Effects(payload=payload), seed=seed,
                        duration=10.0, rate=500.0, physics_rate=physics_rate)
    q = drives.transmission.joint_positions(rec.motor_q)
    names = tuple(model.joint_names)
    if chain:
        return ci.Dataset.from_recording(rec.t, q, rec.currents, joint_names=names)
    return ci.Dataset(t=rec.t, q=q, dq=rec.truth.true_dq, ddq=rec.truth.true_ddq,
                      tau=rec.currents, joint_names=names)


def gains_case(name, seed, chain, physics_rate=1000.0, viscous=(1e-4, 3e-4)):
    """``viscous``: the range of the motor-side viscous friction (N·m·s/rad at the motor); the
    joint sees ``r² f_v``."""
    model = ci.RobotModel.example(name)
    rng = np.random.default_rng(seed)
    n = model.nv
    ratios = rng.uniform(50, 160, n) * rng.choice([-1, 1], n)
    constants = rng.uniform(0.05, 0.2, n)
    tr = ci.Transmission(ratios, torque_constants=constants)
    drives = SimulatedDrives(tr, viscous=rng.uniform(*viscous, n), current_noise=NOISE,
                             encoder_counts=2 ** 17)
    load = MountedPayload(float(rng.uniform(2.0, 3.0)), com=rng.uniform(-0.05, 0.05, 3) +
                          [0, 0, 0.05], inertia=np.diag(rng.uniform(0.004, 0.01, 3)))
    runs = [log(model, drives, 10 * seed + k, payload=load if k == 1 else None, chain=chain,
                physics_rate=physics_rate) for k in range(3)]
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        found = ci.identify_drive_gains(model, runs[0], runs[1], payload_mass=load.mass,
                                        friction=("viscous",))
    spent = time.perf_counter() - start
    truth = tr.gains
    err = (found.gains - truth) / np.abs(truth)
    ratio = np.abs(found.gains - truth) / found.std
    floor = np.abs(truth) * NOISE
    rms = found.result.rms(found.to_torque(runs[2])) / floor
    consistent = bool(ci.is_physically_consistent(found.result.parameters[:model.n_inertial]))
    print(f"{name:6s} seed {seed} {'chain' if chain else 'exact'}  load {load.mass:.2f} kg  "
          f"max |gain err| {np.max(np.abs(err)):.3%}  max |err|/σ {ratio.max():.2f}  "
          f"held-out RMS/floor max {rms.max():.3f}{'*' if chain else ''}  "
          f"consistent {consistent}  {spent:.1f} s")


def coupled_case(c, seed):
    model = ci.RobotModel.example("ur5")
    g = np.eye(6)
    g[5, 4] = c
    tr = ci.Transmission([101.0] * 6, coupling=g,
                         torque_constants=[0.13, 0.13, 0.13, 0.1, 0.1, 0.1])
    drives = SimulatedDrives(tr, rotor_inertia=[6e-5] * 4 + [2e-5, 4e-5],
                             viscous=[2e-4] * 5 + [4e-4], coulomb=[0.0] * 5 + [5e-3],
                             current_noise=NOISE)
    train, test = (d.with_torque(tr.current_torque(d.tau))
                   for d in (log(model, drives, seed), log(model, drives, seed + 1)))
    floor = np.sqrt((g ** 2).T @ (tr.gains * NOISE) ** 2)
    terms = dict(armature=True, friction=("viscous", "coulomb"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with_terms = ci.identify_coupled(model, train, tr, **terms)
        without = ci.identify(model, train, **terms)
    fmt = " ".join
    print(f"coupled c={c:+.1f} seed {seed}: RMS/floor with    "
          f"{fmt(f'{v:.3f}' for v in with_terms.rms(test) / floor)}")
    print(f"{'':27s}without {fmt(f'{v:.3f}' for v in without.rms(test) / floor)}")
    print(f"{'':27s}Iam6, fvm6, fsm6 = {fmt(f'{v:.4g}' for v in with_terms.motor_terms)} "
          "(truth 4e-05 0.0004 0.005)")


def main() -> None:
    print("drive gains from currents (unknown gains, one known load)")
    for chain in (False, True):
        for seed in (1, 2, 3):
            gains_case("ur5", seed, chain)
    # light wrists take r² f_v ≲ 0.5 N·m·s/rad of damping at a 2 kHz Euler step (r ≤ 160)
    for name in ("panda", "ur10", "xarm7"):
        gains_case(name, 1, False, 2000.0, viscous=(4e-6, 2e-5))
        gains_case(name, 1, True, 2000.0, viscous=(4e-6, 2e-5))
    print("* the floor is the raw current noise; the chain's zero-phase low-pass removes most "
          "of it from the held-out currents too")
    print("\ncoupled wrist (motor-side logs, known torque constants)")
    for c, seed in ((1.0, 1), (-0.5, 5)):
        coupled_case(c, seed)


def unseen_drives(model, rng, gain_range=None, current_sign=False, coulomb=0.0,
                  viscous=0.01, offset=0.0, step=0.0, counts=2 ** 17):
    """Drawn drives: ratios ±50–160, gains (torque constants 0.05–0.2, or κ log-uniform in
    ``gain_range``), friction as fractions of the effort limit (joint side)."""
    n = model.nv
    ratios = rng.uniform(50, 160, n) * rng.choice([-1, 1], n)
    if gain_range is None:
        kt = rng.uniform(0.05, 0.2, n)
    else:
        kt = np.exp(rng.uniform(*np.log(gain_range), n)) / np.abs(ratios)
    if current_sign:
        kt = kt * rng.choice([-1, 1], n)
    effort = np.minimum(model.limits.effort, 200.0)
    tr = ci.Transmission(ratios, torque_constants=kt)
    return tr, SimulatedDrives(
        tr, viscous=viscous * rng.uniform(0.5, 1.5, n) * effort / ratios ** 2,
        coulomb=coulomb * rng.uniform(0.5, 1.5, n) * effort / np.abs(ratios),
        current_noise=NOISE, encoder_counts=counts, current_step=step,
        current_offset=offset * rng.uniform(0.5, 1.0, n) * rng.choice([-1, 1], n))


def unseen_log(model, drives, seed, payload, chain, jitter, rate):
    traj = FourierTrajectory.random(model, 5, 10.0, np.random.default_rng(seed))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = record_drives(model, traj, drives, Effects(payload=payload), seed=seed,
                            duration=10.0, rate=rate, physics_rate=2000.0,
                            controller=TrackingController(bandwidth=100.0))
        q = drives.transmission.joint_positions(rec.motor_q)
        names = tuple(model.joint_names)
        if not chain:
            return ci.Dataset(t=rec.t, q=q, dq=rec.truth.true_dq, ddq=rec.truth.true_ddq,
                              tau=rec.currents, joint_names=names)
        t = burst_stamps(rec.t.size, np.random.default_rng([seed, 5]), rate)[1] if jitter \
            else rec.t
        return ci.Dataset.from_recording(t, q, rec.currents, joint_names=names)


def unseen_case(label, arm, seed, chain=False, jitter=False, rate=500.0, friction=None,
                **drawn):
    """One case and seed: prints its line, returns ``(error / |κ|, error / σ)`` or ``None``
    when the library refused (the error is printed)."""
    model = ci.RobotModel.example(arm)
    rng = np.random.default_rng([seed, 2828])
    tr, drives = unseen_drives(model, rng, **drawn)
    load = MountedPayload(float(rng.uniform(2.0, 3.0)), com=rng.uniform(-0.05, 0.05, 3) +
                          [0, 0, 0.05], inertia=np.diag(rng.uniform(0.004, 0.01, 3)))
    runs = [unseen_log(model, drives, 100 * seed + k, load if k == 1 else None, chain, jitter,
                       rate) for k in range(3)]
    options = {} if friction is None else {"friction": friction}
    head = f"{label:16s} {arm:6s} seed {seed}"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            found = ci.identify_drive_gains(model, runs[0], runs[1], payload_mass=load.mass,
                                            **options)
        except ci.ConsistidError as exc:
            print(f"{head}  refused: {type(exc).__name__}: {str(exc)[:110]}…")
            return None
        named = sorted({w.category.__name__ for w in caught
                        if w.category.__module__ == "consistid.errors"})
        floor = np.abs(tr.gains) * np.hypot(NOISE, drives.current_step / np.sqrt(12))
        rms = found.result.rms(found.to_torque(runs[2])) / floor
    err = (found.gains - tr.gains) / np.abs(tr.gains)
    z = (found.gains - tr.gains) / found.std
    consistent = bool(ci.is_physically_consistent(found.result.parameters[:model.n_inertial]))
    print(f"{head}  max |gain err| {np.max(np.abs(err)):.3%}  max |err|/σ "
          f"{np.max(np.abs(z)):.2f}  held-out RMS/floor max {rms.max():.3f}"
          f"{'*' if chain else ''}  consistent {consistent}  warnings {named or '-'}",
          flush=True)
    return err, z


UNSEEN = {
    "current offset": dict(offset=0.2),
    "10 mA steps": dict(step=0.01),
    "reversed sensors": dict(current_sign=True),
    "gains 0.05-20": dict(gain_range=(0.05, 20.0)),
    "friction": dict(coulomb=0.02),
    "1 kHz jitter": dict(chain=True, jitter=True, rate=1000.0, coulomb=0.02),
    "12-bit encoders": dict(chain=True, counts=2 ** 12, coulomb=0.02),
}


def unseen() -> None:
    print("unseen set: what real current logs do (default friction= and method='sdp')")
    cases = [(label, "ur5", kw) for label, kw in UNSEEN.items()]
    cases += [("friction", arm, UNSEEN["friction"]) for arm in ("panda", "xarm7", "kinova",
                                                                 "ur10")]
    for label, arm, kw in cases:
        found = [f for f in (unseen_case(label, arm, s, **kw) for s in (1, 2, 3)) if f]
        if found:
            z = np.abs(np.concatenate([f[1] for f in found]))
            err = np.abs(np.concatenate([f[0] for f in found]))
            print(f"{label:16s} {arm:6s} over {len(found)} seeds: |err| ≤ 1 % "
                  f"{np.mean(err <= 0.01):.0%}, within 2σ {np.mean(z <= 2):.0%}, "
                  f"within 3σ {np.mean(z <= 3):.0%} of {z.size} gains")
    print("current offset left out of friction= (a named error expected):")
    unseen_case("offset, no col.", "ur5", 1, friction=("coulomb", "viscous"), offset=0.02)


if __name__ == "__main__":
    if "--unseen" in sys.argv[1:]:
        unseen()
    else:
        main()

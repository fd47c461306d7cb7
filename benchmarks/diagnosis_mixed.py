"""Mixed mismatches: every body's inertia off AND friction on every joint — does ``diagnose``
reach what ``identify`` reaches on the same logs?

The commonest real situation: the CAD inertias are off on every body (each body's mass, CoM
coordinates and inertia about the CoM scaled by independent factors in 0.88–1.12,
:func:`consistid.robot.inertia.perturb`) and every joint has Coulomb friction (MuJoCo's
``frictionloss``, 0.8–2 N·m) and viscous friction (0.3–1.5 N·m·s/rad). Torque noise
σ = 0.1 N·m, 30 s of training (three periods of a Fourier excitation) and 10 s held out on
another excitation, at 500 Hz, default signal chain (``Dataset.from_recording``).

Per arm and seed it prints, per joint, the held-out RMS of the nominal model, of ``diagnose``'s
final model and of ``identify(method="sdp")`` (with its default friction columns) on the same
logs, ``diagnose``'s ratio to identify's, its noise floor, the held-out RMS over the floor
point-valued (``/floor``) and as the verdict judges it (``judged``: dry friction set-valued at
rest), whether the joint is flagged, and the effects named; then a summary table (the
acceptance: inertia and friction named, held-out RMS per joint ≤ 1.2 × identify's, every joint
whose judged held-out RMS is above 1.5 × its floor flagged or undetermined).

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/diagnosis_mixed.py [--arms ur5,panda,xarm7,kinova]
[--seeds 0,1,2] [--inertia 0.12]``.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

import consistid as ci
from consistid.errors import TrackingWarning
from consistid.excitation import FourierTrajectory
from consistid.robot.inertia import perturb
from consistid.simulate import Effects, record

NOISE = 0.1
RATE = 500.0
PERIOD = 10.0
#: Acceptance: diagnose's held-out RMS per joint within this factor of identify's.
IDENTIFY_FACTOR = 1.2
#: Acceptance: every joint above this multiple of its floor is flagged.
FLAG_RATIO = 1.5


def mixed_case(arm: str, seed: int, train_s: float = 30.0, held_s: float = 10.0,
               rate: float = RATE, noise: float = NOISE, inertia: float = 0.12):
    """``(model, train, held, truth)``: the seeded mixed-mismatch logs of ``arm`` (every body's
    inertial parameters scaled by factors within ``1 ± inertia``).

    ``truth`` holds the simulated inertial parameters, Coulomb and viscous friction per joint.
    """
    model = ci.RobotModel.example(arm)
    rng = np.random.default_rng(seed)
    params = perturb(model.prior_parameters, inertia, rng)
    coulomb = rng.uniform(0.8, 2.0, model.nv)
    viscous = rng.uniform(0.3, 1.5, model.nv)
    eff = Effects(coulomb=coulomb, viscous=viscous, torque_noise=noise)
    logs = []
    for k, duration in enumerate((train_s, held_s)):
        traj = FourierTrajectory.random(model, 5, PERIOD, seed=int(rng.integers(2 ** 31)))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", TrackingWarning)
            rec = record(model, traj, eff, true_parameters=params, duration=duration, rate=rate,
                         physics_rate=1000.0 if rate <= 1000 else rate, seed=10 * seed + k)
        logs.append(ci.Dataset.from_recording(rec.t, rec.q, rec.tau))
    truth = dict(inertial=params, coulomb=coulomb, viscous=viscous)
    return model, logs[0], logs[1], truth


def held_rms(predicted: np.ndarray, held: ci.Dataset) -> np.ndarray:
    return np.sqrt(np.mean((held.tau - predicted) ** 2, axis=0))


def compare(arm: str, seed: int, inertia: float = 0.12) -> dict:
    """Diagnose and identify(sdp) on one mixed case; held-out RMS per joint of each."""
    model, train, held, _ = mixed_case(arm, seed, inertia=inertia)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        diag = ci.diagnose(model, train, held_out=held)
    elapsed = time.perf_counter() - t0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = ci.identify(model, train, method="sdp")
    rms_id = held_rms(res.predict(held), held)
    ratio = diag.left_to_noise     # held-out, as the verdict judges it
    flagged = set(diag.remainder.flagged) | set(diag.remainder.undetermined)
    missed = [n for n, r in zip(model.joint_names, ratio) if r > FLAG_RATIO and n not in flagged]
    names = {e.name for e in diag.effects}
    return dict(arm=arm, seed=seed, diag=diag, rms_id=rms_id, elapsed=elapsed, missed=missed,
                named=names, worst=float(np.max(diag.rms_final / rms_id)),
                ok=("inertia" in names and bool(names & {"coulomb", "viscous", "stribeck"})
                    and float(np.max(diag.rms_final / rms_id)) <= IDENTIFY_FACTOR
                    and not missed))


def print_case(out: dict) -> None:
    diag = out["diag"]
    print(f"\n{out['arm']} seed {out['seed']}: {diag.verdict}  ({out['elapsed']:.1f} s)")
    print("  effects: " + "; ".join(f"{e.name}({', '.join(e.joints)}) {e.confidence}"
                                    for e in diag.effects))
    print(f"  {'joint':<22}{'nominal':>9}{'diagnose':>10}{'identify':>10}{'ratio':>7}"
          f"{'floor':>8}{'/floor':>8}{'judged':>8}  flag")
    for j, name in enumerate(diag.joint_names):
        flag = ("REMAINDER" if name in diag.remainder.flagged else
                "undetermined" if name in diag.remainder.undetermined else "")
        print(f"  {name:<22}{diag.rms_nominal[j]:9.3f}{diag.rms_final[j]:10.3f}"
              f"{out['rms_id'][j]:10.3f}{diag.rms_final[j] / out['rms_id'][j]:7.2f}"
              f"{diag.noise_floor[j]:8.3f}{diag.rms_final[j] / diag.noise_floor[j]:8.2f}"
              f"{diag.left_to_noise[j]:8.2f}  {flag}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--arms", default="ur5,panda,xarm7,kinova")
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--inertia", type=float, default=0.12,
                        help="every body's inertial parameters scaled within 1 ± this")
    args = parser.parse_args()
    rows = []
    for arm in args.arms.split(","):
        for seed in (int(s) for s in args.seeds.split(",")):
            out = compare(arm, seed, args.inertia)
            print_case(out)
            rows.append(out)
    print("\n| arm | seed | effects named | worst diagnose / identify | joints > 1.5 × floor "
          "not flagged | accepted | time (s) |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        print(f"| {r['arm']} | {r['seed']} | {', '.join(sorted(r['named']))} | "
              f"{r['worst']:.2f} | {', '.join(r['missed']) or 'none'} | "
              f"{'yes' if r['ok'] else 'no'} | {r['elapsed']:.1f} |")
    print(f"\naccepted {sum(r['ok'] for r in rows)}/{len(rows)}")


if __name__ == "__main__":
    main()

"""Is a Stribeck hump beside Coulomb friction named, and is plain Coulomb friction left without
one?

MuJoCo, one joint (the arm's 2nd, 3rd or 4th, by seed) with Coulomb friction 0.5 N·m and a
Stribeck excess ``Δf`` = 5 × the torque noise (0.02 N·m) at ``v_s`` = 0.05 rad/s, or plain
Coulomb friction (``Δf`` = 0); a random Fourier excitation, 20 s at 500 Hz, the true signals
(no filter), the last 30 % held out; ``diagnose`` with its defaults. Printed per case: the
effects named, the hump's ``Δf ± σ`` against the simulation's, and the verdict; then per arm,
humps named out of humps simulated and humps named on plain Coulomb friction.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/diagnosis_stribeck.py [--arms ur5,xarm7]
[--seeds 3,4,5,6]``.
"""

from __future__ import annotations

import argparse
import logging
import warnings

import consistid as ci
from consistid.errors import ConsistidError
from consistid.simulate import Effects, record

NOISE = 0.02
COULOMB = 0.5
SPEED = 0.05


def case(arm: str, seed: int, excess: float) -> tuple[str, ci.Diagnosis]:
    """The joint and the diagnosis of one seeded case (``excess`` 0: plain Coulomb)."""
    model = ci.RobotModel.example(arm)
    joint = model.joint_names[1 + seed % 3]
    traj = ci.FourierTrajectory.random(model, harmonics=5, period=10.0, seed=seed)
    eff = Effects(coulomb={joint: COULOMB}, torque_noise=NOISE)
    if excess > 0:
        eff = Effects(coulomb={joint: COULOMB}, static_friction={joint: COULOMB + excess},
                      stribeck_speed=SPEED, torque_noise=NOISE)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        data = record(model, traj, eff, duration=20.0, rate=500.0).true_dataset()
        return joint, ci.diagnose(model, data)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--arms", default="ur5,xarm7,panda,kinova")
    parser.add_argument("--seeds", default="3,4,5,6")
    args = parser.parse_args()
    logging.disable(logging.WARNING)
    totals = {}
    for arm in args.arms.split(","):
        named = simulated = spurious = plain = 0
        for seed in map(int, args.seeds.split(",")):
            for excess in (5 * NOISE, 0.0):
                try:
                    joint, diag = case(arm, seed, excess)
                except ConsistidError as exc:
                    print(f"{arm:7} {seed} Δf={excess:.2f}: not simulated ({str(exc)[:60]})")
                    continue
                humps = [p for e in diag.effects if e.name == "stribeck"
                         for p in e.parameters]
                here = [p for p in humps if p.joint == joint]
                if excess > 0:
                    simulated += 1
                    named += bool(here)
                else:
                    plain += 1
                    spurious += bool(humps)
                shown = ", ".join(f"{p.joint} Δf {p.value:.3f} ± {p.std:.3f} ({p.note[:13]})"
                                  for p in humps) or "-"
                print(f"{arm:7} {seed} {joint:18} Δf={excess:.2f}: "
                      f"{', '.join(e.name for e in diag.effects):30} hump: {shown}; "
                      f"{diag.verdict}", flush=True)
        totals[arm] = (named, simulated, spurious, plain)
    print("\narm      humps named (5 × noise)   humps on plain Coulomb")
    for arm, (n, s, f, p) in totals.items():
        print(f"{arm:8} {n}/{s:<24} {f}/{p}")


if __name__ == "__main__":
    main()

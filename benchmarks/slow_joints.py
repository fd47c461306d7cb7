"""How often ``identify`` warns a joint "too slow to check its friction law": false alarms where
the law holds, catches where it does not.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/slow_joints.py [--runs 20] [--seeds 8]``.

Protocol (seeded):

* **False alarms**: 2 s at 200 Hz of a random Fourier trajectory at 5 % amplitude (every joint
  below ~0.16 rad/s, speed bands of a few dozen samples), torques from ``pin.rnea`` of the URDF
  plus ``f_c sign(q̇) + f_v q̇`` exactly (``f_c`` 0.5–2 N·m, ``f_v`` 0.2–1 N·m·s/rad) and white
  noise σ = 0.1 N·m; ``identify(method="sdp")`` with Coulomb, viscous and offset terms. The law
  holds: every "never moved faster" warning is false. Runs least squares cannot identify are
  skipped and counted.
* **Catches**: :func:`consistid.simulate.mujoco_logs.friction_run` (MuJoCo's soft
  ``frictionloss``, 30 s at 500 Hz, OLS) on the Kinova and the xArm7, whose slowest joints never
  exceed 0.32 rad/s, inside the band where the soft dry friction is not
  ``f_c sign(q̇) + f_v q̇``: each such joint should be warned.

Measured (20 runs, 8 seeds): false alarms 0 of 20 on each of UR5, Panda, xArm7 and Kinova
(before ``SLOPE_Z`` and the band test's Bonferroni factor: 2, 1, 1 and 0 of 20 — a noise slope
``f̂_v`` 0.12 ± 8.5·10⁵ read as smoothed dry friction, and the extreme pair of four band
variances of ~25 samples tested as if it were the only one); catches 13 of 13 slow Kinova
joints and 6 of 6 xArm7 ones, before and after.
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np

import consistid as ci
from consistid.simulate.mujoco_logs import friction_run

FRICTION = ("coulomb", "viscous", "offset")
#: A joint whose fastest speed is below this (rad/s; the top speed band's lower edge) is slow.
SLOW_SPEED = 0.32


def warned(model: ci.RobotModel, data: ci.Dataset, method: str) -> list[str]:
    """The joints ``identify`` warns as too slow to check their friction law."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ci.identify(model, data, method=method, friction=FRICTION)
    text = " ".join(str(w.message) for w in caught if "never moved faster" in str(w.message))
    return [j for j in model.joint_names if f"{j} (rows" in text]


def false_alarms(arm: str, runs: int) -> tuple[int, int, int, list]:
    """``(runs made, runs skipped, runs warned, [(seed, joints)])`` on data whose law holds."""
    model = ci.RobotModel.example(arm)
    made = skipped = 0
    hits = []
    for seed in range(runs):
        rng = np.random.default_rng(seed)
        data = ci.FourierTrajectory.random(model, 5, 10.0, rng, amplitude=0.05).sample(200.0,
                                                                                       2.0)
        fc, fv = rng.uniform(0.5, 2.0, model.nv), rng.uniform(0.2, 1.0, model.nv)
        tau = (model.rnea(data.q, data.dq, data.ddq) + fc * np.sign(data.dq) + fv * data.dq
               + 0.1 * rng.standard_normal(data.q.shape))
        try:
            joints = warned(model, data.with_torque(tau), "sdp")
        except ci.ConsistidError:
            skipped += 1
            continue
        made += 1
        if joints:
            hits.append((seed, joints))
    return made, skipped, len(hits), hits


def catches(arm: str, seeds: int) -> tuple[int, int, list]:
    """``(slow joints, warned, [(seed, missed joint)])`` on MuJoCo's soft dry friction."""
    model = ci.RobotModel.example(arm)
    slow = caught = 0
    missed = []
    for seed in range(seeds):
        data = friction_run(model, seed, duration=30.0, rate=500.0).dataset
        joints = [model.joint_names[j]
                  for j in np.flatnonzero(np.abs(data.dq).max(axis=0) < SLOW_SPEED)]
        found = warned(model, data, "ols")
        slow += len(joints)
        caught += sum(j in found for j in joints)
        missed += [(seed, j) for j in joints if j not in found]
    return slow, caught, missed


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20, help="false-alarm runs per arm")
    ap.add_argument("--seeds", type=int, default=8, help="MuJoCo seeds per arm (catches)")
    ap.add_argument("--arms", nargs="+", default=["ur5", "panda", "xarm7", "kinova"])
    args = ap.parse_args()
    print("false alarms (law holds, 2 s below ~0.16 rad/s, SDP):")
    for arm in args.arms:
        made, skipped, n, hits = false_alarms(arm, args.runs)
        print(f"  {arm:7s} {n} of {made} runs warned ({skipped} not identifiable) {hits}")
    print(f"catches (MuJoCo soft frictionloss, joints below {SLOW_SPEED} rad/s, OLS):")
    for arm in ("kinova", "xarm7"):
        slow, caught, missed = catches(arm, args.seeds)
        print(f"  {arm:7s} {caught} of {slow} slow joints warned; missed {missed}")


if __name__ == "__main__":
    main()

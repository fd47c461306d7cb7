"""Nonlinear and break-away friction (issue 20): accuracy against a MuJoCo truth, and which law
the real KUKA LWR4+ logs prefer.

Run from the repository: ``OPENBLAS_NUM_THREADS=1 python benchmarks/friction.py [--seeds 3]``.

Prints (1) Stribeck and Gaz-sigmoid friction simulated on the Panda (MuJoCo, 30 s at 500 Hz,
torque noise 0.02 N·m, seeds 1..S): the largest |estimate − truth|/σ over the friction
parameters, and the held-out RMS at low speed (0.02 ≤ |q̇| < 0.1 rad/s, and |q̇| < 0.1 with the
standstill samples: point residual, and judged against the friction cone at rest) over the
noise floor for the fitted law and for the linear Coulomb + viscous model, with fit times;
(2) break-away torques from the simulated ramp experiment (known frictionloss per joint):
relative error per joint, experiment length and wall time; (3) on
``../shared/data/kuka_lwr4`` (train measurements_2 + 3, held-out measurements_1, as
benchmarks/real_kuka.py), the held-out RMS of every law per joint and the law each joint
prefers.
"""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

import numpy as np

import consistid as ci
from consistid.data.recordings import load_recording
from consistid.friction import compare_friction_models, estimate_breakaway
from consistid.friction.fit import identify_nonlinear
from consistid.identification.summary import table
from consistid.simulate import Effects, record

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "kuka_lwr4"
NOISE, MIN_SPEED = 0.02, 0.02
FC = np.array([0.5, 0.5, 0.4, 0.4, 0.25, 0.2, 0.15])
GAZ = dict(sigmoid_amplitude=[0.55, 0.87, 0.64, 1.28, 0.84, 0.30, 0.56],
           sigmoid_steepness=[5.1, 9.1, 10.1, 5.6, 8.3, 17.1, 10.3],
           sigmoid_shift=[0.04, 0.026, -0.046, 0.036, 0.026, -0.021, 0.0036])
TRUTH = {"stribeck": dict(fc=FC, fs=2 * FC, vs=np.full(7, 0.15), delta=np.full(7, 2.0)),
         "sigmoid": dict(phi1=np.array(GAZ["sigmoid_amplitude"]),
                         phi2=np.array(GAZ["sigmoid_steepness"]),
                         phi3=np.array(GAZ["sigmoid_shift"]))}
FS = np.array([1.5, 1.8, 1.2, 1.4, 0.8, 0.6, 0.5])


def z_max(res, truth) -> float:
    row = {res.base.standard_names[c]: r for r, c in enumerate(res.base.independent)}
    joints = res.model.joint_names
    z = [(res.base_parameters[row[n]] - truth[n.split(".")[1]][joints.index(n.split(".")[0])])
         / res.base_std[row[n]] for n in res.amplitude_names]
    z += [(v - truth[n.split(".")[1]][joints.index(n.split(".")[0])]) / s
          for n, v, s in zip(res.shape_names, res.shape_parameters, res.shape_std)]
    return float(np.max(np.abs(z)))


def low_ratio(res, held, floor: float = MIN_SPEED, at_rest: str = "point") -> np.ndarray:
    e = res.residual(held, at_rest=at_rest)
    low = (np.abs(held.dq) < 0.1) & (np.abs(held.dq) >= floor)
    return np.array([np.sqrt(np.mean(e[low[:, j], j] ** 2)) for j in range(7)]) / NOISE


def simulated_fits(model: ci.RobotModel, seeds: int) -> None:
    rows = []
    for law in ("stribeck", "sigmoid"):
        for seed in range(1, seeds + 1):
            eff = (Effects(coulomb=FC, static_friction=2 * FC, stribeck_speed=0.15,
                           stribeck_exponent=2.0, viscous=0.3, torque_noise=NOISE)
                   if law == "stribeck" else Effects(torque_noise=NOISE, **GAZ))
            traj = ci.FourierTrajectory.random(model, harmonics=5, period=10.0, seed=seed)
            train, held = record(model, traj, eff, duration=30.0,
                                 rate=500.0).true_dataset().split(0.7)
            t0 = time.perf_counter()
            res = ci.identify(model, train, method="sdp", friction=law, min_speed=MIN_SPEED)
            t_fit = time.perf_counter() - t0
            linear = identify_nonlinear(model, train, "ols", {j: "coulomb" for j in range(7)},
                                        min_speed=MIN_SPEED)
            r, rl = low_ratio(res, held), low_ratio(linear, held)
            r0, rl0 = low_ratio(res, held, 0.0), low_ratio(linear, held, 0.0)
            rc, rlc = low_ratio(res, held, 0.0, "cone"), low_ratio(linear, held, 0.0, "cone")
            rows.append([law, seed, z_max(res, TRUTH[law]), r.min(), r.max(), rl.min(), rl.max(),
                         r0.max(), rl0.min(), rc.max(), rlc.min(),
                         "yes" if res.is_consistent else "no", t_fit])
    print("== (1) MuJoCo Panda, simulated nonlinear friction: SDP + law vs truth ==")
    print("held-out RMS/σ per joint (min, max over joints) for 0.02 ≤ |q̇| < 0.1 rad/s; then "
          "|q̇| < 0.1 with the standstill samples, where stiction holds the joint: residual of "
          "the point prediction, and (cone) each joint at rest judged against its friction "
          "cone ±f_s, residual(held, at_rest='cone')")
    print(table(["law", "seed", "max |z|", "low RMS/σ min", "max", "linear min", "linear max",
                 "with standstill: law max", "linear min", "cone: law max", "linear min",
                 "consistent", "fit [s]"], rows, floatfmt=".3g"))


def breakaway(model: ci.RobotModel, seeds: int) -> None:
    rows = []
    arms = [("panda", model, FS, {})] + [
        (name, ci.RobotModel.example(name), None, opts)
        for name, opts in (("ur5", {}), ("xarm7", {}), ("kinova", {}),
                           ("kinova", dict(threshold=0.04, abort_speed=0.12)))]
    for name, arm, fs, opts in arms:
        fs = np.linspace(2.0, 0.4, arm.nv) if fs is None else fs
        for seed in range(seeds):
            t0 = time.perf_counter()
            est = estimate_breakaway(arm, effects=Effects(coulomb=fs, torque_noise=0.01),
                                     seed=seed, **opts)
            wall = time.perf_counter() - t0
            err = 100 * (est.torque - fs) / fs
            rows.append([name + (" (v_th 0.04)" if opts else ""), seed,
                         *np.pad(err, (0, 7 - err.size), constant_values=np.nan),
                         float(np.max(np.abs(err))), est.duration, wall])
    print("\n== (2) break-away from simulated torque ramps (known frictionloss, torque noise "
          "0.01 N·m), error % ==")
    print(table(["arm", "seed", *(f"j{j + 1}" for j in range(7)), "max |%|", "experiment [s]",
                 "wall [s]"], rows, floatfmt=".3g"))


def kuka() -> None:
    if not (DATA / "measurements_1.npz").is_file():
        print(f"\n(3) skipped: no KUKA data in {DATA}")
        return
    joints = [f"lwr_{i}_joint" for i in range(7)]
    model = ci.RobotModel.from_urdf(DATA / "kuka_lwr4.urdf")

    def load(numbers):
        return ci.Dataset.concatenate([
            load_recording(DATA / f"measurements_{i}.npz", "flobaroid", joint_names=joints,
                           model=model, trim_start=2.0).dataset for i in numbers])

    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ci.errors.PoorExcitationWarning)
        cmp = compare_friction_models(model, load((2, 3)), load((1,)))
    print(f"\n== (3) real KUKA LWR4+: train measurements_2+3, held-out measurements_1 "
          f"({time.perf_counter() - t0:.1f} s) ==")
    print(cmp)
    for law, res in cmp.results.items():
        if law != "coulomb":
            print(f"{law}: shapes at the search bounds: {res.details['shapes_at_bounds']}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    args = ap.parse_args()
    model = ci.RobotModel.example("panda")
    simulated_fits(model, args.seeds)
    breakaway(model, args.seeds)
    kuka()


if __name__ == "__main__":
    main()

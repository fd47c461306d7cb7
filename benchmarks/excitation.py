"""Optimal excitation for the Panda: optimised cond(Y_b) versus random feasible trajectories.

Acceptance of issue 7: Panda 7-DoF, Fourier series (+ quintic boundary polynomial) with 5
harmonics and a 10 s period; the optimised trajectory's condition number against 50 random
feasible trajectories of the same class (Rackl et al. 2012 report ~23 optimised vs ~120 random
for the DLR LWR; Gaz et al. 2019 report 48.9 for the Panda). Target: cond ≤ 50 with every
constraint satisfied on the dense grid.

The condition number reported is that of the *unscaled, unweighted* base regressor ``Y_b`` over one
period (SI units, base parameters of ``compute_base_parameters``) — what
``IdentificationResult.condition_number`` reports for OLS on data along the trajectory. It depends
on the units and on the regressor columns (rigid body only: 43 base parameters; with Coulomb,
viscous and offset friction: 64).

Limits: URDF position, velocity and effort limits, Franka datasheet accelerations
(15, 7.5, 10, 12.5, 15, 20, 20 rad/s²), end effector (``panda_hand_tcp``) above a floor at
z = 0.2 m, outside a 0.3 m sphere around the base and inside a workspace box.

Run: ``python benchmarks/excitation.py [--quick]`` (seeded; about 5 min on a loaded 2-core machine,
``--quick`` about 1 min).
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import time  # noqa: E402

import numpy as np  # noqa: E402

import consistid as ci  # noqa: E402
from consistid.excitation import (CartesianBox, ExcitationLimits, FloorPlane,  # noqa: E402
                                  KeepOutSphere, assess_excitation, random_excitation)

PANDA_ACCELERATION = [15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0]


def panda_limits(model: ci.RobotModel) -> ExcitationLimits:
    return ExcitationLimits.from_model(
        model, acceleration=PANDA_ACCELERATION, floor=FloorPlane(0.2),
        sphere=KeepOutSphere(0.3), workspace=CartesianBox([-0.9, -0.9, 0.0], [0.9, 0.9, 1.25]))


def run_variant(model, limits, label, n_random, n_starts, max_iter, **kw):
    t0 = time.perf_counter()
    design = ci.design_excitation(model, harmonics=5, period=10.0, seed=0, limits=limits,
                                  n_starts=n_starts, max_iter=max_iter, **kw)
    seconds = time.perf_counter() - t0
    shape = {k: kw[k] for k in ("trajectory", "via_points") if k in kw}
    rng = np.random.default_rng(1)
    conds = []
    for _ in range(n_random):
        traj = random_excitation(model, harmonics=5, period=10.0, seed=rng, limits=limits,
                                 **shape)
        quality = assess_excitation(model, traj, limits, friction=kw.get("friction"),
                                    base=design.base)
        if not quality.constraints.feasible:
            raise RuntimeError(f"random trajectory violates {quality.constraints}")
        conds.append(quality.cond)
    conds = np.array(conds)
    return dict(label=label, n_base=design.base.n_base, cond=design.cond,
                d_opt=design.quality.criteria["d-opt"], best=conds.min(),
                median=np.median(conds), worst=conds.max(),
                margin=design.constraints.min_relative_margin,
                feasible=design.constraints.feasible, per_start=seconds / n_starts,
                design=design)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer starts, iterations, variants")
    args = parser.parse_args()
    model = ci.RobotModel.example("panda")
    limits = panda_limits(model)
    n_random = 50
    n_starts, max_iter = (2, 60) if args.quick else (4, 150)
    variants = [("fourier H=5, cond, rigid body", dict(criterion="cond", friction=None))]
    if not args.quick:
        variants += [
            ("fourier H=5, cond, + friction", dict(criterion="cond",
                                                    friction=("coulomb", "viscous", "offset"))),
            ("fourier H=5, d-opt, rigid body", dict(criterion="d-opt", friction=None)),
            ("B-spline 10 intervals, cond, rigid", dict(criterion="cond", friction=None,
                                                       trajectory="bspline", via_points=10)),
        ]
    rows = [run_variant(model, limits, label, n_random, n_starts, max_iter, **kw)
            for label, kw in variants]
    print(f"Panda, 10 s, {n_starts} starts × ≤ {max_iter} SLSQP iterations, optimiser grid 150 "
          f"samples, dense check 2000 samples; random: {n_random} feasible trajectories of the "
          "same class.\ncond = unscaled base-regressor condition number over one period.\n")
    head = (f"{'variant':<36}{'b':>4}{'cond opt':>10}{'rand best':>11}{'rand med':>10}"
            f"{'rand worst':>12}{'med/opt':>9}{'min margin':>12}{'feasible':>10}{'s/start':>9}")
    print(head)
    print("-" * len(head))
    for r in rows:
        print(f"{r['label']:<36}{r['n_base']:>4}{r['cond']:>10.1f}{r['best']:>11.1f}"
              f"{r['median']:>10.1f}{r['worst']:>12.3g}{r['median'] / r['cond']:>9.1f}"
              f"{r['margin'] * 100:>11.2f}%{str(r['feasible']):>10}{r['per_start']:>9.1f}")
    first = rows[0]
    verdict = "met" if first["cond"] <= 50 and first["feasible"] else "NOT met"
    print(f"\nacceptance (rigid body, Fourier H=5): cond {first['cond']:.1f} ≤ 50 and feasible: "
          f"{verdict}\n")
    print(first["design"])


if __name__ == "__main__":
    main()

"""Bounding ellipsoids from collision geometry: sizes, prior consistency, build and SDP times.

For the Panda: per body, the minimum-volume ellipsoid's volume against the collision hull's,
whether the URDF CoM lies inside and whether the URDF body satisfies the ellipsoid LMI
``tr(J Q) ≥ 0``; then the SDP on simulated data (truth = URDF ±20 %) with the default
``"pseudo-inertia"`` level and with ``constraints="ellipsoid", ellipsoids="collision"``
(median of 3 runs each). Build times for other example-robot-data arms (STL, COLLADA through
coal, primitives).

Run: ``python benchmarks/collision_ellipsoids.py``.
"""

from __future__ import annotations

import time
import warnings

import numpy as np
from scipy.spatial import ConvexHull

import consistid as ci
from consistid.robot.inertia import perturb, pseudo_inertia
from consistid.robot.shapes import collision_ellipsoids, collision_points, volume


def main() -> None:
    panda = ci.RobotModel.example("panda")
    start = time.perf_counter()
    ellipsoids = collision_ellipsoids(panda)
    build = time.perf_counter() - start
    points = collision_points(panda)
    print(f"Panda: collision ellipsoids built in {build:.2f} s\n")
    print(f"{'body':12s} {'hull pts':>8s} {'V_ell (l)':>9s} {'V_hull (l)':>10s} {'ratio':>6s} "
          f"{'CoM in':>6s} {'tr(JQ)':>9s}")
    inside = lmi = 0
    for body, x in zip(panda.body_names, panda.prior_parameters.reshape(-1, 10)):
        e, hull = ellipsoids[body], ConvexHull(points[body])
        com = e.contains(x[1:4] / x[0])
        trjq = float(np.trace(pseudo_inertia(x) @ e.q_matrix()))
        inside += com
        lmi += trjq >= 0
        print(f"{body:12s} {len(hull.vertices):8d} {1e3 * volume(e):9.3f} "
              f"{1e3 * hull.volume:10.3f} {volume(e) / hull.volume:6.2f} {str(com):>6s} "
              f"{trjq:9.3g}")
    n = panda.n_bodies
    print(f"\nURDF prior: {inside}/{n} CoMs inside, {lmi}/{n} bodies satisfy tr(J Q) ≥ 0\n")

    truth = perturb(panda.prior_parameters, 0.2, np.random.default_rng(3))
    data = ci.simulate.excitation_run(panda, truth, 10.0, 100.0, torque_noise=0.1,
                                      friction=None, seed=1).dataset
    print(f"{'SDP (1000 samples)':34s} {'total s':>8s} {'solve s':>8s} {'status':>8s}")
    for label, kw in (("pseudo-inertia", {}),
                      ("ellipsoid, ellipsoids='collision'",
                       dict(constraints="ellipsoid", ellipsoids="collision"))):
        runs = []
        for _ in range(3):
            t0 = time.perf_counter()
            res = ci.identify(panda, data, friction=(), **kw)
            runs.append((time.perf_counter() - t0, res.solver.solve_time))
        total, solve = np.median(np.array(runs), axis=0)
        print(f"{label:34s} {total:8.2f} {solve:8.3f} {res.solver.status:>8s}")

    print(f"\n{'robot':8s} {'bodies':>6s} {'with ellipsoid':>14s} {'build s':>8s}")
    for name in ("ur5", "z1", "kinova", "xarm7"):
        model = ci.RobotModel.example(name)
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                found = len(collision_ellipsoids(model))
            except ci.errors.ModelError as exc:
                print(f"{name:8s} {model.n_bodies:6d} {'error':>14s}  {exc}")
                continue
        print(f"{name:8s} {model.n_bodies:6d} {found:14d} {time.perf_counter() - t0:8.2f}")


if __name__ == "__main__":
    main()

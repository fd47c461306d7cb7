"""Online identification and Slotine–Li adaptive control: the figures of issue 19.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/online.py [--quick]``.

1. Update cost of :class:`consistid.RecursiveEstimator` (Panda, Coulomb + viscous + offset, the
   regressor row included), as µs and as a ratio to ``pinocchio.rnea`` timed in the same run
   (target ≤ 50 µs); medians of repetitions.
   The cost of ``predict`` on one sample (the training-envelope check included) as a ratio to
   the same call without the check (an estimator with no samples yet, the same ``β̂``) timed in
   the same run, called alone and after each update (as in a control loop).
2. Consistent projection time (target ≤ 20 ms): the closed form when the unconstrained optimum
   is consistent, and the solver path (an estimate pushed out of the consistent set).
3. Detection delay and payload mass versus time after a 1.5 kg payload at t = 20 s (σ = 0.1 N·m,
   σ estimated online), over several seeds; false flags over 60 s of unchanged motion.
4. Slotine–Li on the MuJoCo robot (nominal bodies ±30 % off): first/last period RMS, and the
   recovery after a payload grasped mid-run, on the Panda and on arms the defaults were not
   chosen on (UR5, xArm7, Kinova).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
import pinocchio as pin

import consistid as ci
from consistid.identification.base import random_states
from consistid.online.adaptive_run import adaptive_run
from consistid.online.projection import ConsistencyProjector
from consistid.online.scenario import payload_change_run


def update_cost(model: ci.RobotModel, n: int, repeat: int) -> None:
    q, dq, ddq = random_states(model, n, np.random.default_rng(0))
    tau = np.random.default_rng(1).normal(size=q.shape)
    m, d = model.pin_model, model.pin_model.createData()
    rnea, upd, growth, cpu, cpu_rnea = [], [], [], [], []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for k in range(n):
            pin.rnea(m, d, q[k], dq[k], ddq[k])
        rnea.append((time.perf_counter() - t0) / n)
        est = ci.RecursiveEstimator(model, noise_std=1.0, detector="chi2")
        tenth = max(n // 10, 1)
        marks = []
        t0 = time.perf_counter()
        for k in range(n):
            if k % tenth == 0:
                marks.append(time.perf_counter())
            est.update(q[k], dq[k], ddq[k], tau[k])
        end = time.perf_counter()
        upd.append((end - t0) / n)
        c0 = time.process_time()
        for k in range(n):
            est.update(q[k], dq[k], ddq[k], tau[k])
        cpu.append((time.process_time() - c0) / n)
        c0 = time.process_time()
        for k in range(n):
            pin.rnea(m, d, q[k], dq[k], ddq[k])
        cpu_rnea.append((time.process_time() - c0) / n)
        growth.append((end - marks[-1]) / (marks[1] - marks[0]))
    r, u = statistics.median(rnea), statistics.median(upd)
    print(f"update cost ({model.name}, {est.base.n_base} base parameters, friction, regressor "
          f"row included, {n} samples × {repeat}): {u * 1e6:.1f} µs per sample; pin.rnea "
          f"{r * 1e6:.2f} µs; ratio {u / r:.1f} (target ≤ 50 µs); last tenth / first tenth of "
          f"the updates {statistics.median(growth):.2f} (independent of time: 1); CPU time "
          f"{statistics.median(cpu) * 1e6:.1f} µs vs rnea {statistics.median(cpu_rnea) * 1e6:.2f}"
          f" µs")


def predict_cost(model: ci.RobotModel, n: int, repeat: int) -> None:
    q, dq, ddq = random_states(model, 2 * n, np.random.default_rng(0))
    tau = np.random.default_rng(1).normal(size=q.shape)
    est = ci.RecursiveEstimator(model, noise_std=1.0, detector=None)
    est.update_batch(q[:n], dq[:n], ddq[:n], tau[:n], record=False)
    bare, alone, looped = [], [], []
    for _ in range(repeat):
        fresh = ci.RecursiveEstimator(model, noise_std=1.0, detector=None,
                                      initial=est.base_parameters)     # no envelope yet
        t0 = time.perf_counter()
        for k in range(n):
            fresh.predict(q[k], dq[k], ddq[k])
        bare.append((time.perf_counter() - t0) / n)
        t0 = time.perf_counter()
        for k in range(n):
            est.predict(q[k], dq[k], ddq[k])
        alone.append((time.perf_counter() - t0) / n)
        spent = 0.0
        for k in range(n, 2 * n):
            est.update(q[k], dq[k], ddq[k], tau[k])
            t0 = time.perf_counter()
            est.predict(q[k], dq[k], ddq[k])
            spent += time.perf_counter() - t0
        looped.append(spent / n)
    b, a, lo = (statistics.median(x) for x in (bare, alone, looped))
    print(f"predict on one sample ({model.name}, envelope check included, {n} calls × "
          f"{repeat}): {a * 1e6:.1f} µs, {lo * 1e6:.1f} µs after each update; without the "
          f"check {b * 1e6:.1f} µs; ratios {a / b:.2f} and {lo / b:.2f}")


def projection_time(model: ci.RobotModel, repeat: int) -> None:
    run = payload_change_run(model, duration=10.0, change_time=1e9, seed=4)
    d = run.dataset
    est = ci.RecursiveEstimator(model, noise_std=0.1, detector=None)
    est.update_batch(d.q, d.dq, d.ddq, d.tau, record=False)
    projector = ConsistencyProjector(model, est.base, est.spec)
    first = projector.project(est.base_parameters, est.covariance)
    closed = [projector.project(est.base_parameters, est.covariance).seconds
              for _ in range(repeat)]
    rng = np.random.default_rng(0)
    solved, cpu, statuses = [], [], []
    for _ in range(repeat):
        body = rng.integers(model.n_bodies)
        pushed = est.base_parameters - 5.0 * est.base.matrix[:, 10 * body]
        c0 = time.process_time()
        out = projector.project(pushed, est.covariance)
        if out.solver.name == "closed form":
            continue
        cpu.append(time.process_time() - c0)
        solved.append(out.seconds)
        statuses.append(f"{out.solver.name} {out.solver.status}")
    print(f"consistent projection ({model.name}, {est.base.n_standard} standard parameters): "
          f"first call {first.seconds * 1e3:.1f} ms ({first.solver.name}); closed form "
          f"{statistics.median(closed) * 1e3:.2f} ms; solver path ({len(solved)} calls) wall "
          f"median {statistics.median(solved) * 1e3:.1f} ms, max {max(solved) * 1e3:.1f} ms; "
          f"CPU median {statistics.median(cpu) * 1e3:.1f} ms "
          f"({', '.join(sorted(set(statuses)))}) (target ≤ 20 ms; wall time grows with the "
          f"machine's load, CPU time much less)")


def detection(model: ci.RobotModel, seeds: int) -> None:
    print("payload 1.5 kg at t = 20 s, σ = 0.1 N·m (estimated online), λ = 0.9999:")
    print("  seed   flags   delay [ms]   mass after 0.5 s   1 s      5 s      (truth 1.5 kg)")
    for seed in range(seeds):
        run = payload_change_run(model, duration=25.5, change_time=20.0, seed=10 + seed)
        d, k0 = run.dataset, run.change_index
        est = ci.RecursiveEstimator(model, forgetting=0.9999)
        masses, done = [], 0
        for stop in (k0 + 500, k0 + 1000, k0 + 5000):
            est.update_batch(d.q[done:stop], d.dq[done:stop], d.ddq[done:stop],
                             d.tau[done:stop], t=d.t[done:stop], record=False)
            done = stop
            masses.append(est.payload().mass if est.changes else float("nan"))
        delay = (est.changes[0].index - k0) if est.changes else float("nan")
        print(f"  {seed:4d}   {len(est.changes):5d}   {delay:10.0f}   {masses[0]:16.4f}   "
              f"{masses[1]:.4f}   {masses[2]:.4f}")
    flags = []
    for seed in range(seeds):
        run = payload_change_run(model, duration=60.0, change_time=1e9, seed=100 + seed)
        d = run.dataset
        est = ci.RecursiveEstimator(model, forgetting=0.9999)
        est.update_batch(d.q, d.dq, d.ddq, d.tau, record=False)
        flags.append(len(est.changes))
    print(f"  false flags over 60 s of unchanged motion, {seeds} runs: {flags}")


def slotine_li(robots: list[str], periods: int) -> None:
    print(f"Slotine–Li on MuJoCo, nominal bodies ±30 % off, {periods} periods of 4 s, defaults "
          "(Λ = 5, K = 50·M̂(q₀), γ = 10, payload capacity 3 kg):")
    print("  robot    first [mrad]  last/first (no payload)  pre-grasp  after grasp (periods "
          "k, k+1, k+2, relative to pre-grasp)  projections clipped  s")
    for name in robots:
        model = ci.RobotModel.example(name)
        t0 = time.perf_counter()
        plain = adaptive_run(model, periods=periods, payload=None, seed=0)
        loaded = adaptive_run(model, periods=periods, seed=0)
        seconds = time.perf_counter() - t0
        rms, rl = plain.period_rms(), loaded.period_rms()
        k = loaded.payload_period
        after = ", ".join(f"{x:.2f}" for x in rl[k:k + 3] / rl[k - 1])
        consistent = np.all(loaded.projected_minimum >= loaded.controller.margin * (1 - 1e-6))
        print(f"  {name:7s}  {rms[0] * 1e3:12.2f}  {rms[-1] / rms[0]:23.3f}  "
              f"{rl[k - 1] * 1e3:9.2f}  {after:>50s}  {loaded.clips:8d} "
              f"(consistent at every projection: {consistent})  {seconds:.0f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="fewer repetitions, seeds and arms")
    args = ap.parse_args()
    model = ci.RobotModel.example("panda")
    update_cost(model, 2000 if args.quick else 10_000, 3 if args.quick else 5)
    predict_cost(model, 1000 if args.quick else 5000, 3 if args.quick else 5)
    projection_time(model, 5 if args.quick else 20)
    detection(model, 2 if args.quick else 5)
    slotine_li(["panda"] if args.quick else ["panda", "ur5", "xarm7", "kinova"], 8)


if __name__ == "__main__":
    main()

"""``consistid online``: the online-identification and adaptive-control demo.

Part 1, recursive least squares (:class:`consistid.RecursiveEstimator`) on a simulated run of the
robot's own equations (σ = ``--noise`` N·m) with a 1.5 kg payload attached at ``--change`` s:
the estimate's error versus time (base parameters in units of their reported σ, the payload's
mass read from the estimate), the flagged change and the consistent projection's time.
Part 2, the Slotine–Li adaptive controller on the MuJoCo robot (nominal bodies ±30 % off, the
payload grasped mid-run): the RMS tracking error per period and the estimate's torque error.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import consistid as ci
from consistid.errors import OptionError, check_number, check_seed
from consistid.excitation.trajectory import sample_count
from consistid.robot.model import EXAMPLE_ROBOTS


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", default="panda", help="example-robot-data arm (default panda)")
    parser.add_argument("--duration", type=float, default=30.0,
                        help="seconds of the recursive-estimation run at 1 kHz")
    parser.add_argument("--change", type=float, default=None,
                        help="when the payload is attached in that run (s; default 20, or "
                             "0.8 × --duration when that is sooner)")
    parser.add_argument("--noise", type=float, default=0.1, help="torque noise σ in N·m")
    parser.add_argument("--forgetting", type=float, default=0.9999, help="RLS forgetting λ")
    parser.add_argument("--periods", type=int, default=8,
                        help="periods (4 s each) of the adaptive-control run")
    parser.add_argument("--seed", type=int, default=0)


def run(args: argparse.Namespace) -> int:
    from consistid.online.adaptive_run import adaptive_run
    from consistid.online.scenario import payload_change_run

    if args.robot not in EXAMPLE_ROBOTS:
        raise OptionError(f"--robot {args.robot} is not an example robot; they are "
                          f"{', '.join(EXAMPLE_ROBOTS)}")
    model = ci.RobotModel.example(args.robot)
    check_number("--periods", args.periods, 1, integer=True)       # every option before the work
    check_seed("--seed", args.seed)
    sample_count(1000.0, 4.0 * args.periods, model.nv)  # the adaptive run: 4 s periods at 1 kHz
    est = ci.RecursiveEstimator(model, forgetting=args.forgetting)
    check_number("--duration", args.duration, 0, strict=True)
    if args.change is None:
        change_time = min(20.0, 0.8 * args.duration)
    else:
        change_time = check_number("--change", args.change, 0, strict=True)
        if change_time >= args.duration:
            raise OptionError(f"--change {change_time:g} s is not within the run of --duration "
                              f"{args.duration:g} s: the payload would never be attached; give "
                              "a --change below --duration (or leave it out)")
    sim = payload_change_run(model, duration=args.duration, change_time=change_time,
                             torque_noise=args.noise, seed=args.seed)
    d = sim.dataset
    print(f"recursive least squares on {model.name}: {d.n_samples} samples at 1 kHz, "
          f"σ = {args.noise:g} N·m, {sim.payload.mass:g} kg payload at t = {change_time:g} s, "
          f"{est.base.n_base} base parameters, λ = {args.forgetting:g}")
    print("    t [s]   max |β̂ − β| / σ̂   payload mass [kg]   µs/sample")
    step = int(round(2.0 / (d.t[1] - d.t[0])))
    for start in range(0, d.n_samples, step):
        s = slice(start, min(start + step, d.n_samples))
        t0 = time.perf_counter()
        est.update_batch(d.q[s], d.dq[s], d.ddq[s], d.tau[s], t=d.t[s], record=False)
        cost = (time.perf_counter() - t0) / (s.stop - s.start) * 1e6
        truth = est.base.project(sim.truth(s.stop - 1))
        z = np.max(np.abs(est.base_parameters - truth) / est.std)
        mass = f"{est.payload().mass:.4f}" if est.changes else "—"
        print(f"  {d.t[s.stop - 1]:7.2f}   {z:16.2f}   {mass:>17}   {cost:9.1f}")
    for c in est.changes:
        print(f"  {c} (true change at {sim.change_time:g} s)")
    proj = est.consistent_parameters()
    print(f"  {proj}")
    print()
    runs = adaptive_run(model, periods=args.periods, seed=args.seed)
    print(runs.summary())
    return 0

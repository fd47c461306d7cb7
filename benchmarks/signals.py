"""Velocity/acceleration estimates of the signal chain versus MuJoCo's true states.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/signals.py [--duration 30] [--robot panda]
[--physics-rate 10000]``.

A MuJoCo Panda (no dynamic effects, inertias the URDF's ±20 %) tracks a 5-harmonic Fourier
excitation of period 10 s, logged at 1 kHz, under three sensor scenarios (clean; a 19-bit encoder;
Gaussian noise on q and τ). For
each, four ways to get ``q̇, q̈`` from the logged positions:

``raw``      central differences of the unfiltered log, torque unfiltered;
``central``  the default chain: zero-phase Butterworth (cut-off 10 × bandwidth) + central
             differences (``Dataset.from_recording``);
``savgol``   Savitzky–Golay (order 5, window from the same cut-off);
``fourier``  whole periods averaged, harmonics below the cut-off, differentiated in the
             frequency domain (compared against the true states of every period).

Printed per joint: RMS error of ``q̇`` (rad/s) and ``q̈`` (rad/s²) on the samples each method
keeps; then the relative error ``‖β̂ − β‖/‖β‖`` of OLS base parameters identified from each
dataset, and the processing time (median of 3).

The simulator's own floor: semi-implicit Euler logs positions whose central difference is
``q̇ + h q̈ / 2`` with ``h`` the *physics* step (see :mod:`consistid.simulate.mujoco_robot`), ~1e-3
rad/s
at 1 kHz physics; the default 10 kHz physics (and control) brings it to ~1e-4 rad/s so that the
table shows the signal chain rather than the integrator.
"""

from __future__ import annotations

import argparse
import statistics
import time
import warnings

import numpy as np

import consistid as ci
from consistid.data import signals
from consistid.errors import PoorExcitationWarning
from consistid.excitation import FourierTrajectory
from consistid.robot.inertia import perturb
from consistid.identification.summary import table
from consistid.simulate import Effects, record

PERIOD, HARMONICS = 10.0, 5
SCENARIOS = {
    "clean": Effects(),
    "19-bit encoder": Effects(quantisation=2 * np.pi / 2 ** 19),
    "σq=1e-4, στ=0.1": Effects(position_noise=1e-4, torque_noise=0.1),
}
METHODS = ("raw", "central", "savgol", "fourier")


def process(method: str, rec) -> tuple[ci.Dataset, np.ndarray]:
    """The dataset and, per dataset sample, the indices of the log samples it stands for
    (several for the period-averaged ``fourier`` estimate)."""
    if method == "raw":
        dq, ddq = signals.central_difference(rec.q, rec.rate)
        data = ci.Dataset(t=rec.t[1:-1], q=rec.q[1:-1], dq=dq[1:-1], ddq=ddq[1:-1],
                          tau=rec.tau[1:-1])
        return data, np.arange(1, rec.n_samples - 1)[:, None]
    bandwidth = HARMONICS / PERIOD
    data = signals.preprocess(rec.t, rec.q, rec.tau, derivative=method, period=PERIOD,
                              bandwidth=bandwidth).dataset
    first = np.rint(data.t * rec.rate).astype(int)
    if method != "fourier":
        return data, first[:, None]
    p = data.n_samples
    periods = rec.n_samples // p
    return data, first[:, None] + p * np.arange(periods)[None, :]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="panda")
    parser.add_argument("--duration", type=float, default=30.0, help="seconds logged")
    parser.add_argument("--physics-rate", type=float, default=10000.0, help="Hz")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    warnings.simplefilter("ignore", PoorExcitationWarning)

    model = ci.RobotModel.example(args.robot)
    traj = FourierTrajectory.random(model, HARMONICS, PERIOD, seed=args.seed)
    rng = np.random.default_rng(args.seed)
    truth = perturb(model.prior_parameters, 0.2, rng)
    joints = [f"j{j + 1}" for j in range(model.nv)]
    print(f"{model.name}: {args.duration:g} s logged at 1 kHz (physics {args.physics_rate:g} Hz), "
          f"Fourier excitation ({HARMONICS} harmonics of {PERIOD:g} s), cut-off "
          f"{10 * HARMONICS / PERIOD:g} Hz\n")
    for scenario, effects in SCENARIOS.items():
        rec = record(model, traj, effects, true_parameters=truth, duration=args.duration,
                     physics_rate=args.physics_rate, seed=args.seed)
        rows_dq, rows_ddq, rows_id = [], [], []
        for method in METHODS:
            times = []
            for _ in range(3):
                t0 = time.perf_counter()
                data, idx = process(method, rec)
                times.append(time.perf_counter() - t0)
            err_dq = data.dq[:, None, :] - rec.true_dq[idx]
            err_ddq = data.ddq[:, None, :] - rec.true_ddq[idx]
            rows_dq.append([method, *np.sqrt(np.mean(err_dq ** 2, axis=(0, 1)))])
            rows_ddq.append([method, *np.sqrt(np.mean(err_ddq ** 2, axis=(0, 1)))])
            res = ci.identify(model, data, method="ols", friction=None)
            beta = res.base.project(truth)
            rows_id.append([method, data.n_samples,
                            np.linalg.norm(res.base_parameters - beta) / np.linalg.norm(beta),
                            statistics.median(times) * 1e3])
        print(f"== {scenario}")
        print("RMS error of dq (rad/s)")
        print(table(["method", *joints], rows_dq, ".2e"))
        print("RMS error of ddq (rad/s²)")
        print(table(["method", *joints], rows_ddq, ".2e"))
        print(table(["method", "samples", "‖β̂−β‖/‖β‖", "processing ms"], rows_id, ".3g"))
        print()


if __name__ == "__main__":
    main()

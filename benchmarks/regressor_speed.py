"""Regressor build time versus pinocchio.rnea over the same samples (target: ratio ≤ 3).

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/regressor_speed.py [--samples 100000]``.
Prints medians of several repetitions. The full regressor of 10⁵ Panda samples with friction is
(700 000 × 91) doubles ≈ 510 MB, so its build time includes first-touch page faults; the streamed
build (a reused 4096-sample buffer, what ``identify`` does) shows the cost of the regressor alone.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
import pinocchio as pin

import consistid as ci
from consistid.identification.base import random_states
from consistid.identification.regressor import RegressorSpec, iter_regressor, regressor


def timed(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--samples", type=int, default=100_000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    model = ci.RobotModel.example("panda")
    q, dq, ddq = random_states(model, args.samples, np.random.default_rng(0))
    m, d = model.pin_model, model.pin_model.createData()

    def rnea_loop():
        out = np.empty_like(q)
        for k in range(q.shape[0]):
            out[k] = pin.rnea(m, d, q[k], dq[k], ddq[k])
        return out

    spec = RegressorSpec.make(model, ("coulomb", "viscous", "offset"))
    data = ci.Dataset(t=np.arange(args.samples) * 1e-3, q=q, dq=dq, ddq=ddq)

    def streamed():
        for _ in iter_regressor(model, data, spec):
            pass
    t_rnea = timed(rnea_loop, args.repeat)
    t_rigid = timed(lambda: regressor(model, q, dq, ddq), args.repeat)
    t_full = timed(lambda: regressor(model, q, dq, ddq, spec), args.repeat)
    t_stream = timed(streamed, args.repeat)
    print(f"Panda, {args.samples} samples, median of {args.repeat}")
    print(f"{'what':38s} {'time [s]':>9s} {'µs/sample':>10s} {'× rnea':>7s}")
    for name, t in [("pinocchio.rnea loop", t_rnea), ("regressor, rigid body", t_rigid),
                    ("regressor + coulomb/viscous/offset", t_full),
                    ("same, streamed in 4096-sample chunks", t_stream)]:
        print(f"{name:38s} {t:9.3f} {t / args.samples * 1e6:10.2f} {t / t_rnea:7.2f}")


if __name__ == "__main__":
    main()

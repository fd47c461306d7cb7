"""What the validation layer of issue 14 costs: the checks before the numerics
(:func:`consistid.data.checks.check_for_identification`: magnitudes, motion, dead torque
channels, glitches) and the naming of uninformed directions
(:func:`consistid.identification.uninformed.uninformed_directions`), against the ``identify``
call they guard, measured in the same run.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/hostile_checks.py [--quick]``. Prints medians of
5 repetitions; simulated excitation runs (seeded), OLS and the default SDP.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import consistid as ci
from consistid.data.checks import check_for_identification
from consistid.identification.uninformed import uninformed_directions


def median_time(call, repeat: int = 5) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="10⁴ samples only")
    args = parser.parse_args()
    sizes = (10_000,) if args.quick else (10_000, 100_000)
    print(f"{'robot':8s} {'N':>7s} {'checks [ms]':>12s} {'OLS [ms]':>10s} {'ratio':>7s} "
          f"{'SDP [ms]':>10s} {'ratio':>7s} {'uninformed [ms]':>16s}")
    for robot in ("panda", "ur5"):
        model = ci.RobotModel.example(robot)
        for n in sizes:
            run = ci.simulate.excitation_run(model, duration=n / 1000.0, rate=1000.0,
                                             torque_noise=0.1, seed=0)
            data = run.dataset
            t_check = median_time(lambda: check_for_identification(data, model.joint_names))
            t_ols = median_time(lambda: ci.identify(model, data, method="ols", friction=None), 3)
            res = ci.identify(model, data, friction=None)
            t_sdp = median_time(lambda: ci.identify(model, data, friction=None), 3)
            r_b = np.linalg.cholesky(np.linalg.inv(res.base_covariance)).T
            t_unin = median_time(lambda: uninformed_directions(r_b, res.base))
            print(f"{robot:8s} {n:7d} {1e3 * t_check:12.1f} {1e3 * t_ols:10.0f} "
                  f"{t_check / t_ols:7.3f} {1e3 * t_sdp:10.0f} {t_check / t_sdp:7.3f} "
                  f"{1e3 * t_unin:16.2f}")


if __name__ == "__main__":
    main()

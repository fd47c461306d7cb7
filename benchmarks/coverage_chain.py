"""Coverage of the weighted fits' 95 % intervals on friction logs through the signal chain.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/coverage_chain.py [--robots ur5 panda xarm7]
[--seeds 0 1000 2000 3000] [--methods ols wls sdp] [--duration 30] [--rate 500]``.

Protocol (seeded, that of ``coverage_friction.py --chain``): per arm and seed, the URDF's
bodies perturbed by ±12 % (:func:`consistid.robot.inertia.perturb`), MuJoCo Coulomb
(``frictionloss``) 0.5–2 N·m and viscous 0.2–1 N·m·s/rad friction on every joint, torque noise
σ = 0.1 N·m, a random Fourier trajectory; the measured log (positions, torques) through the
default signal chain (:func:`consistid.data.signals.preprocess`), identified with parallel
filtering (``parallel``) and without (``10×``), ``friction=("coulomb", "viscous", "offset")``.
Truth: the inertias of the compiled MuJoCo model and the simulated friction (offset 0), on the
base parameters. A parameter is covered when ``|β̂ − β| ≤ 1.96 σ̂``.

Columns: coverage and median ``|β̂ − β|/σ̂`` (0.67 when honest) with the reported σ, the same
without the weighting term (``details["weighting_error"]``,
:mod:`consistid.identification.weighting_error`: the interval as it was before that term), and
the median ratio of the two half-widths; ``gate`` is the share of runs whose test of the
weights rejected. The weighted fits (WLS, SDP) missed on the UR5 (0.88) because the residual
through the chain is mostly model error, which their ``1/σ_j²`` weights follow.
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np

import consistid as ci
from consistid.simulate.mujoco_logs import friction_run

FRICTION = ("coulomb", "viscous", "offset")


def one_run(name: str, seed: int, duration: float, rate: float,
            methods: list[str]) -> list[dict]:
    """Every method on the chain's dataset of one simulated log, parallel filtering on and
    off: per fit the errors, σ with and without the weighting term, and whether it opened."""
    from consistid.data.signals import preprocess

    model = ci.RobotModel.example(name)
    run = friction_run(model, seed, duration, rate)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        data = preprocess(run.dataset.t, run.dataset.q, run.dataset.tau).dataset
    rows = []
    for method in methods:
        for parallel in (True, False):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = ci.identify(model, data, method=method, friction=FRICTION,
                                  parallel_filter=parallel)
            theta = run.truth(model, list(res.parameter_names))
            var = np.clip(np.diag(res.base_covariance), 0, None)
            extra = res.details["weighting_error"] ** 2
            rows.append(dict(robot=name, method=method, parallel=parallel,
                             error=np.abs(res.base_parameters - res.base.project(theta)),
                             sd=np.sqrt(var), sd_before=np.sqrt(np.clip(var - extra, 0, None)),
                             opened=bool(np.any(extra > 0))))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", nargs="+", default=["ur5", "panda", "xarm7"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1000, 2000, 3000])
    ap.add_argument("--methods", nargs="+", default=["ols", "wls", "sdp"])
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--rate", type=float, default=500.0)
    args = ap.parse_args()
    rows = [r for name in args.robots for seed in args.seeds
            for r in one_run(name, seed, args.duration, args.rate, args.methods)]
    print(f"coverage of 95 % intervals through the signal chain, seeds {args.seeds}, "
          f"{args.duration:g} s at {args.rate:g} Hz (median |error|/σ in brackets)")
    print(f"{'arm':8s}{'method':7s}{'filter':10s}{'reported':>16s}{'no weighting term':>20s}"
          f"{'width ratio':>13s}{'gate':>7s}")
    for name in args.robots:
        for method in args.methods:
            for parallel in (True, False):
                sel = [r for r in rows if (r["robot"], r["method"], r["parallel"])
                       == (name, method, parallel)]
                err = np.concatenate([r["error"] for r in sel])
                sd = np.concatenate([r["sd"] for r in sel])
                before = np.concatenate([r["sd_before"] for r in sel])
                z, z0 = err / sd, err / before
                print(f"{name:8s}{method:7s}{'parallel' if parallel else '10×':10s}"
                      f"{f'{np.mean(z <= 1.96):.3f} ({np.median(z):.2f})':>16s}"
                      f"{f'{np.mean(z0 <= 1.96):.3f} ({np.median(z0):.2f})':>20s}"
                      f"{np.median(sd / before):>13.3f}"
                      f"{np.mean([r['opened'] for r in sel]):>7.2f}")


if __name__ == "__main__":
    main()

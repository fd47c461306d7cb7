"""The SDP prior's weight chosen from the data (the default) against the fixed ``2/r²``.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/prior_weight.py [--seeds 0 1 2 3]
[--robots panda ur5 xarm7] [--off 0.2 0.7] [--friction]``.

Protocol (that of ``sdp_accuracy.py``, on more arms and a URDF further off): the simulated
bodies are the URDF's perturbed by ``±off`` (:func:`consistid.robot.inertia.perturb`), torque
noise σ = 0.1 N·m, rigid body only; training 30 s at 500 Hz (well excited) or 2 s of 20 %-
amplitude motion (poor), held out a different 10 s trajectory. Per arm, ``off`` and seed: held-out
RMS/σ of OLS (well-excited only; on poor data it is 7–19), of the SDP with the fixed weight
(``prior_uncertainty=0.3``) and with the weight from the data (the default,
:mod:`consistid.identification.prior_weight`), and that weight over ``2/r²``. ``--friction``
fits Coulomb, viscous and offset terms too (the simulated robot has none), under the SDP's
joint prior (:mod:`consistid.identification.joint_prior`), which the weight's evidence counts.
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np

import consistid as ci
from consistid.excitation import FourierTrajectory
from consistid.identification.summary import table
from consistid.robot.inertia import perturb

SIGMA = 0.1


def data_sets(model: ci.RobotModel, off: float, seed: int) -> dict[str, ci.Dataset]:
    truth = perturb(model.prior_parameters, off, np.random.default_rng(seed))

    def run(duration, s, trajectory=None):
        return ci.simulate.excitation_run(model, truth, duration, 500.0, torque_noise=SIGMA,
                                          seed=s, trajectory=trajectory).dataset

    small = FourierTrajectory.random(model, 5, 10.0, np.random.default_rng(seed + 3),
                                     amplitude=0.2)
    return {"well": run(30.0, seed + 1), "held": run(10.0, seed + 2),
            "poor": run(2.0, seed + 3, small)}


def held_rms(res: ci.IdentificationResult, data: ci.Dataset) -> float:
    return float(np.sqrt(np.mean(res.rms(data) ** 2)) / SIGMA)


def rows_of(name: str, off: float, seed: int, friction=None) -> list[tuple]:
    model = ci.RobotModel.example(name)
    sets = data_sets(model, off, seed)
    rows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for case in ("well", "poor"):
            ols = ci.identify(model, sets[case], method="ols", friction=friction,
                              covariance="iid") if case == "well" else None
            fixed = ci.identify(model, sets[case], method="sdp", friction=friction,
                                covariance="iid", prior_uncertainty=0.3)
            chosen = ci.identify(model, sets[case], method="sdp", friction=friction,
                                 covariance="iid")
            rows.append((name, f"±{off:g}", seed, case,
                         "—" if ols is None else f"{held_rms(ols, sets['held']):.4f}",
                         f"{held_rms(fixed, sets['held']):.4f}",
                         f"{held_rms(chosen, sets['held']):.4f}",
                         f"{chosen.details['prior_weight'] / fixed.details['prior_weight']:.3g}"))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3])
    ap.add_argument("--robots", nargs="+", default=["panda", "ur5", "xarm7"])
    ap.add_argument("--off", type=float, nargs="+", default=[0.2, 0.7])
    ap.add_argument("--friction", action="store_true",
                    help="fit Coulomb, viscous and offset terms too")
    args = ap.parse_args()
    friction = ("coulomb", "viscous", "offset") if args.friction else None
    rows = [r for name in args.robots for off in args.off for seed in args.seeds
            for r in rows_of(name, off, seed, friction)]
    print(f"held-out RMS/σ (σ = {SIGMA} N·m; 1 is the floor); weight = chosen / 2/r² (r = 0.3)")
    print(table(["arm", "URDF off", "seed", "data", "OLS", "SDP fixed 2/r²", "SDP from data",
                 "weight"], rows))


if __name__ == "__main__":
    main()

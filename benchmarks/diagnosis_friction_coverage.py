"""Do the diagnosis's friction σ cover the truth? Coulomb and viscous friction as ``diagnose``
reports them (the set-valued refit where the verdict made it, else the point-valued fit), over
seeds of the Panda example's simulated robot.

Each seed simulates, as ``examples/panda/make_example_data.py`` does (inertias 10 % off,
Coulomb 1.2–0.6 N·m and viscous 0.8–0.3 N·m·s/rad over the joints, a 0.3 N·m offset, σ = 0.05
N·m, 19-bit encoders, 100 Hz), a 20 s training and a 10 s held-out log on new trajectories,
through the default signal chain, and diagnoses them. Printed per parameter: value ± σ, the
simulated truth and ``z = (value − truth) / σ``; then per kind (Coulomb or viscous, set-valued
or point-valued) the mean and RMS of ``z`` (RMS ≈ 1 when σ covers) and how many lie beyond 3.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/diagnosis_friction_coverage.py [--seeds 1-6]``.
"""

from __future__ import annotations

import argparse
import logging
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples" / "panda"))

import consistid as ci  # noqa: E402
from consistid.robot.inertia import perturb  # noqa: E402

import make_example_data as example  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="1-6", help="first-last seed")
    args = parser.parse_args()
    first, last = map(int, args.seeds.split("-"))
    logging.disable(logging.WARNING)
    warnings.simplefilter("ignore")
    model = ci.RobotModel.example("panda")
    truth = perturb(model.prior_parameters, 0.1, np.random.default_rng(7))
    friction = {"coulomb": np.linspace(1.2, 0.6, model.nv),
                "viscous": np.linspace(0.8, 0.3, model.nv)}
    zs = []
    for s in range(first, last + 1):
        logs = [example.simulate(model, truth, seed=10 * s + k, duration=d)
                for k, d in ((1, 20.0), (2, 10.0))]
        train, held = (ci.Dataset.from_recording(r.t, r.q, r.tau) for r in logs)
        diag = ci.diagnose(model, train, held_out=held)
        for e in diag.effects:
            for p in e.parameters if e.name in friction else ():
                true = friction[e.name][model.joint_names.index(p.joint)]
                kind = "set-valued" if "set-valued" in p.note else "point-valued"
                zs.append((e.name, kind, (p.value - true) / p.std))
                print(f"{s} {e.name:8} {p.joint:12} {p.value:.3f} ± {p.std:.3f}  truth "
                      f"{true:.3f}  z {zs[-1][2]:+.1f}  {kind}", flush=True)
    print("\nparameter       fit           n  mean z  RMS z  |z| > 3")
    for name in friction:
        for kind in ("set-valued", "point-valued"):
            z = np.array([v for n, k, v in zs if n == name and k == kind])
            if z.size:
                print(f"{name:15} {kind:12} {z.size:3} {z.mean():+7.2f} "
                      f"{np.sqrt(np.mean(z ** 2)):6.2f} {int(np.sum(abs(z) > 3)):4}")


if __name__ == "__main__":
    main()

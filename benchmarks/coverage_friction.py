"""Coverage of the reported 95 % intervals when the robot has dry (MuJoCo) and viscous friction.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/coverage_friction.py [--seeds 4] [--duration 30]
[--rate 500] [--robots ur5 panda] [--covariance auto iid coloured] [--chain]``.

Protocol (seeded): per arm and seed, the simulated robot's bodies are the URDF's perturbed by
±12 % (:func:`consistid.robot.inertia.perturb`), with Coulomb friction 0.5–2 N·m (MuJoCo's
``frictionloss``, a soft constraint: no single number at low speed) and viscous friction
0.2–1 N·m·s/rad on every joint, torque noise σ = 0.1 N·m; a random Fourier trajectory, exact
states (:meth:`SimulatedRecording.true_dataset`). Truth: the inertias read back from the MuJoCo
model the simulation ran (mass, ``body_ipos``, ``body_iquat``, ``body_inertia``: the body frame is
the joint frame), mapped to the base parameters by the base map, and the simulation's friction
values (offset 0). ``identify(..., friction=("coulomb", "viscous", "offset"))`` with OLS and the
SDP; a parameter is covered when ``|β̂ − β| ≤ 1.96 σ̂``. The table gives the share covered per
group of base parameters (rigid body / viscous / Coulomb / offset), pooled over seeds, and the
median ``|β̂ − β| / σ̂`` of the group (0.67 for honest Gaussian intervals). Rows ``<cov>-noise``
are the same intervals without the model-error term of the rows at rest
(:mod:`consistid.identification.model_error`): the noise-only sandwich. ``--chain``: the
measured log (positions, torques) through the default signal chain instead of the exact states,
identified with parallel filtering (``+parallel``: τ and Y low-passed alike at 3 × the band) and
without (``+10×``: the samples at the derivative cut-off, 10 × the band).
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np

import consistid as ci
from consistid.simulate.mujoco_logs import friction_run

GROUPS = ("rigid body", "viscous", "Coulomb", "offset")


def one_run(name: str, seed: int, duration: float, rate: float, covariances: list[str],
            methods: list[str], chain: bool = False) -> list[dict]:
    model = ci.RobotModel.example(name)
    run = friction_run(model, seed, duration, rate)
    friction = ("coulomb", "viscous", "offset")
    rows = []
    if chain:       # the measured log through the signal chain, parallel filtering on and off
        from consistid.data.signals import preprocess

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            data = preprocess(run.dataset.t, run.dataset.q, run.dataset.tau).dataset
        variants = [(data, True, "+parallel"), (data, False, "+10×")]
    else:
        variants = [(run.dataset, True, "")]
    for method in methods:
        for cov, (dataset, parallel, label) in ((c, v) for c in covariances for v in variants):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = ci.identify(model, dataset, method=method, friction=friction,
                                  covariance=cov, parallel_filter=parallel)
            cov = cov + label
            beta = res.base.project(run.truth(model, list(res.parameter_names)))
            var = np.clip(np.diag(res.base_covariance), 0, None)
            error = np.abs(res.base_parameters - beta)
            rows.append(dict(robot=name, seed=seed, method=method, covariance=cov,
                             z=error / np.sqrt(var), group=groups(res)))
            if "model_error" in res.details:         # the same without the model-error term
                noise = var - res.details["model_error"] ** 2
                rows.append(dict(robot=name, seed=seed, method=method,
                                 covariance=f"{cov}-noise", z=error / np.sqrt(noise),
                                 group=groups(res)))
    return rows


def groups(res) -> np.ndarray:
    """The group of each base parameter: a base column that is a joint term (its own column)
    is in that term's group, every other one is rigid body."""
    names = [res.parameter_names[c] for c in res.base.independent]
    out = []
    for n in names:
        out.append("viscous" if n.endswith(".fv") else "Coulomb" if n.endswith(".fc")
                   else "offset" if n.endswith(".fo") else "rigid body")
    return np.array(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--rate", type=float, default=500.0)
    ap.add_argument("--robots", nargs="+", default=["ur5", "panda"])
    ap.add_argument("--methods", nargs="+", default=["ols", "sdp"])
    ap.add_argument("--covariance", nargs="+", default=["auto"])
    ap.add_argument("--chain", action="store_true",
                    help="identify from the measured log through the signal chain (positions "
                         "differentiated, torques filtered), with parallel filtering on and off")
    args = ap.parse_args()
    rows = []
    for i, name in enumerate(args.robots):
        for k in range(args.seeds):
            rows += one_run(name, 1000 * k + 17 * i, args.duration, args.rate, args.covariance,
                            args.methods, args.chain)
    print(f"coverage of 95 % intervals, {args.seeds} seeds, {args.duration:g} s at "
          f"{args.rate:g} Hz (median |error|/σ in brackets; 0.67 when honest)")
    print(f"{'arm':8s}{'method':6s}{'covariance':12s}" + "".join(f"{g:>18s}" for g in GROUPS)
          + f"{'all':>18s}")
    for name in args.robots:
        for method in args.methods:
            shown = dict.fromkeys(r["covariance"] for r in rows)
            for cov in shown:
                sel = [r for r in rows if (r["robot"], r["method"], r["covariance"])
                       == (name, method, cov)]
                z = np.concatenate([r["z"] for r in sel])
                g = np.concatenate([r["group"] for r in sel])
                cells = []
                for group in (*GROUPS, None):
                    m = np.ones(z.size, bool) if group is None else g == group
                    cells.append(f"{np.mean(z[m] <= 1.96):.3f} ({np.median(z[m]):.2f})"
                                 if m.any() else "—")
                print(f"{name:8s}{method:6s}{cov:12s}" + "".join(f"{c:>18s}" for c in cells))


if __name__ == "__main__":
    main()

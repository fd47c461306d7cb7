"""Real KUKA LWR4+ torque-sensor logs: consistid's OLS and consistent SDP against the a-priori URDF
and FloBaRoID's identified model, on a held-out recording.

Run from the repository:
``OPENBLAS_NUM_THREADS=1 python benchmarks/real_kuka.py [--position] [--diagnose]``.

Data: ``../shared/data/kuka_lwr4`` beside the checkout (FloBaRoID project, LGPL-3.0; never copied
into consistid), or ``--data DIR``. The upstream recipe: identify on measurements_2 +
measurements_3 (stacked as two segments), validate on measurements_1 (the same trajectory as
measurements_2, recorded 29 min earlier). Every recording loses its first 2 s (run-in from rest:
see docs/tutorials/real_kuka.md for the measurement behind the rule).

Prints: (1) what the loader did; (2) the held-out table — per-joint and total relative error (%),
RMS (N·m) — for every model; (3) physical consistency (minimum pseudo-inertia eigenvalue per
body); (4) friction/offset estimates ± standard deviation and base-parameter uncertainty; (5) the
acceptance checks; (6) a cross-trajectory check (training and validation on *different*
trajectories). OLS and SDP are fitted twice: with the URDF's gravity, and with the base tilt
(gravity direction) estimated from the training files alone (:func:`consistid.estimate_mounting`).
With ``--position``, (7) the per-joint position term (``sin q_j, cos q_j``):
which joints get it, chosen on the training files alone, and the held-out and cross-trajectory
figures with and without it; with ``--diagnose``, (8) the diagnosis of the a-priori URDF.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

import consistid as ci
from consistid.identification.compression import compress
from consistid.identification.identify import with_covariance
from consistid.estimation.mounting import estimate_mounting
from consistid.data.recordings import Recording, load_recording
from consistid.identification.summary import table
from consistid.robot.model import model_without_dynamics
from consistid.robot.urdf import joint_dynamics
from consistid.identification.scoring import (refit_joint_terms, rigid_model, score, scores_table,
                                  with_urdf_friction)

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "kuka_lwr4"
JOINTS = [f"lwr_{i}_joint" for i in range(7)]
TRIM_START = 2.0
#: Torque noise σ for the diagnosis (N·m). The logged torques are low-pass filtered upstream, so
#: the spectral noise-floor estimate sees only what the filter left (0.002–0.02 N·m) and would
#: weight joints by it; 0.2 N·m is the per-joint RMS that the 64-parameter least-squares fit
#: leaves on the training data (0.16–0.22 N·m): a floor no candidate effect can be asked to beat.
SIGMA = 0.2
FRICTION = ("coulomb", "viscous", "offset")


def load(data: Path, model: ci.RobotModel, numbers: tuple[int, ...]) -> Recording:
    recs = [load_recording(data / f"measurements_{i}.npz", "flobaroid", joint_names=JOINTS,
                           model=model, trim_start=TRIM_START) for i in numbers]
    return recs[0] if len(recs) == 1 else Recording.concatenate(recs)


def joint_terms_table(results: dict[str, object], names: list[str]) -> str:
    """fc, fv, fo ± std per joint for identification results and refit baselines."""
    rows = []
    for label, res in results.items():
        if isinstance(res, ci.IdentificationResult):
            standard = list(res.base.standard_names)
            base_of = {standard[c]: r for r, c in enumerate(res.base.independent)}
            values = [(res.base_parameters[base_of[n]], res.base_std[base_of[n]]) for n in names]
        else:
            idx = {n: i for i, n in enumerate(res.parameter_names)}
            values = [(res.joint_parameters[idx[n]], res.joint_std[idx[n]]) for n in names]
        rows.append([label, *(f"{v:+.3f}±{s:.3f}" for v, s in values)])
    short = [f"j{k + 1}" for k in range(len(names))]      # joint k + 1 = lwr_k_joint
    return table(["model", *short], rows)


def _errors(prior: ci.RobotModel, train: ci.Dataset, held: ci.Dataset,
            friction: object) -> tuple[float, float, bool]:
    """Held-out total relative error of OLS and the SDP, and the SDP's consistency."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ci.errors.PoorExcitationWarning)
        ols = ci.identify(prior, train, method="ols", friction=friction)
        sdp = ci.identify(prior, train, method="sdp", friction=friction)
    return (score(ols, held).total_relative_error, score(sdp, held).total_relative_error,
            sdp.is_consistent)


def position_joints(prior: ci.RobotModel, data: Path) -> tuple[list[int], str]:
    """Joints that get the position term, chosen on the training recordings only.

    Folds: train on measurements_2, score measurements_3, and the reverse (two different
    trajectories, so the score is that of a new motion). Greedy forward selection: add the joint
    whose term lowers the SDP's mean total relative error over both folds most; stop when no
    joint lowers it. measurements_1 is never read. Returns the chosen joints and the table.
    """
    recs = {i: load(data, prior, (i,)).dataset for i in (2, 3)}

    def cv(joints: list[int]) -> tuple[float, float]:
        friction = {t: True for t in FRICTION} | {"position": joints}
        e = [_errors(prior, recs[a], recs[b], friction) for a, b in ((2, 3), (3, 2))]
        return float(np.mean([x[0] for x in e])), float(np.mean([x[1] for x in e]))

    chosen: list[int] = []
    e_ols, e_sdp = cv(chosen)
    rows = [["none", 100 * e_ols, 100 * e_sdp, ""]]
    while len(chosen) < prior.nv:
        trials = {j: cv(sorted(chosen + [j])) for j in range(prior.nv) if j not in chosen}
        for j, (o, sd) in trials.items():
            rows.append([f"{'+'.join(f'j{k + 1}' for k in sorted(chosen + [j]))}", 100 * o,
                         100 * sd, ""])
        best = min(trials, key=lambda j: trials[j][1])
        if trials[best][1] >= e_sdp:
            break
        chosen.append(best)
        e_sdp = trials[best][1]
        rows[-len(trials) + list(trials).index(best)][3] = "chosen"
    return sorted(chosen), table(["position term on", "OLS e% (mean of 2→3, 3→2)", "SDP e%",
                                  ""], rows, floatfmt=".3g")


def position_table(prior: ci.RobotModel, data: Path, chosen: list[int]) -> str:
    """Held-out figures without the position term, with it on every joint, and on ``chosen``."""
    variants = {"c,v,o": FRICTION, "+ position, all joints": (*FRICTION, "position"),
                f"+ position, {','.join(f'j{j + 1}' for j in chosen)}":
                    {t: True for t in FRICTION} | {"position": chosen}}
    rows = []
    for trn, val in (((2, 3), 1), ((1, 2), 3), ((3,), 1), ((1, 3), 2)):
        tr, va = load(data, prior, trn).dataset, load(data, prior, (val,)).dataset
        e_plain = None
        for label, friction in variants.items():
            e_ols, e_sdp, ok = _errors(prior, tr, va, friction)
            e_plain = e_ols if e_plain is None else e_plain
            rows.append([f"{'+'.join(map(str, trn))} → {val}", label, 100 * e_ols, 100 * e_sdp,
                         e_sdp / e_ols, e_sdp / e_plain, "yes" if ok else "no"])
    return table(["train → held-out", "joint terms", "OLS e%", "SDP e%", "SDP/OLS",
                  "SDP/OLS(c,v,o)", "SDP ⪰ 0"], rows, floatfmt=".3g")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DATA)
    ap.add_argument("--position", action="store_true",
                    help="also measure the per-joint position term (sin q, cos q)")
    ap.add_argument("--diagnose", action="store_true", help="also diagnose the a-priori URDF")
    args = ap.parse_args()
    if not (args.data / "measurements_1.npz").is_file():
        print(f"KUKA LWR4+ data not found in {args.data}; pass --data DIR", file=sys.stderr)
        return 1
    prior = ci.RobotModel.from_urdf(args.data / "kuka_lwr4.urdf")
    flobaroid, flo_dyn = model_without_dynamics(args.data / "kuka_lwr4_identified.urdf")
    train = load(args.data, prior, (2, 3))
    held = load(args.data, prior, (1,))
    print("== Loading (what was done to measurements_1) ==")
    print(held)
    print(f"training: {train.source} ({train.dataset.n_samples} samples in "
          f"{len(np.unique(train.dataset.segment))} segments)\n")

    t0 = time.perf_counter()
    mounting = estimate_mounting(prior, train.dataset, friction=FRICTION)
    print(f"== Mounting, estimated on the training files ({time.perf_counter() - t0:.1f} s) ==")
    print(mounting)
    print("residual autocorrelation time τ_j (samples): " + ", ".join(
        f"{t:.0f}" for t in mounting.autocorrelation_time) + "\n")

    timings = {}
    fits = {}
    for robot, suffix in ((prior, ""), (mounting.model, "+tilt")):
        for method in ("ols", "sdp"):
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ci.errors.PoorExcitationWarning)
                fits[method + suffix] = ci.identify(robot, train.dataset, method=method,
                                                    friction=FRICTION, covariance="iid")
            timings[method + suffix] = time.perf_counter() - t0
    ols, sdp = fits["ols"], fits["sdp"]
    models = {
        "consistid OLS": ols,
        "consistid SDP (pseudo-inertia, log-det prior)": sdp,
        "consistid OLS, estimated tilt": fits["ols+tilt"],
        "consistid SDP, estimated tilt": fits["sdp+tilt"],
        "a-priori URDF, rigid": rigid_model(prior),
        "a-priori URDF + its <dynamics> friction": with_urdf_friction(
            prior, joint_dynamics(args.data / "kuka_lwr4.urdf")),
        "a-priori URDF + fc,fv,fo refit on training": refit_joint_terms(prior, train.dataset),
        "FloBaRoID URDF, rigid": rigid_model(flobaroid),
        "FloBaRoID URDF + its <dynamics> friction": with_urdf_friction(flobaroid, flo_dyn),
        "FloBaRoID URDF + fc,fv,fo refit on training": refit_joint_terms(flobaroid,
                                                                         train.dataset),
    }
    held_scores = {k: score(m, held.dataset, k) for k, m in models.items()}
    train_scores = {k: score(m, train.dataset, k) for k, m in models.items()}
    print("== Held-out measurements_1: relative error e (%) and RMS (N·m) per joint ==")
    print(scores_table(list(held_scores.values())))
    print("\ntotal relative error on the training data (%): " + ", ".join(
        f"{k.split(' (')[0]} {100 * s.total_relative_error:.2f}"
        for k, s in train_scores.items()))
    print(f"identification time: OLS {timings['ols']:.2f} s, SDP {timings['sdp']:.2f} s "
          f"({sdp.solver})")

    print("\n== Physical consistency: minimum eigenvalue of each body's pseudo-inertia "
          "(kg·m², ≥ 0 is realizable) ==")
    cons = {"consistid OLS (standard vector nearest the prior)": ols.consistency,
            "consistid SDP": sdp.consistency,
            "consistid SDP, estimated tilt": fits["sdp+tilt"].consistency,
            "a-priori URDF": models["a-priori URDF, rigid"].consistency,
            "FloBaRoID URDF": models["FloBaRoID URDF, rigid"].consistency}
    bodies = [b.replace("lwr_", "").replace("_link", "") for b in prior.body_names]
    print(table(["model", *(f"body {b}" for b in bodies), "all ⪰ 0"],
                [[k, *c.min_eigenvalues, "yes" if c.ok else "no"] for k, c in cons.items()],
                floatfmt=".2e"))

    # Residuals of the filtered logs are correlated over tens of samples: the same fits with
    # each joint's rows counted as N/τ_j independent ones (identify's default, "coloured"),
    # against counting every row as independent ("iid", the fits above).
    problem = compress(prior, train.dataset, ols.spec)
    ols_c, sdp_c = (with_covariance(r, problem, train.dataset, "coloured") for r in (ols, sdp))
    print("\n== Friction and offset per joint (estimate ± standard deviation; 'coloured': rows "
          "counted as N/τ_j independent samples) ==")
    print("residual autocorrelation time τ_j (samples), OLS: " + ", ".join(
        f"{t:.0f}" for t in ols_c.details["autocorrelation_time"]) + "; SDP: " + ", ".join(
        f"{t:.0f}" for t in sdp_c.details["autocorrelation_time"]))
    for term, unit in (("fc", "N·m"), ("fv", "N·m·s/rad"), ("fo", "N·m")):
        names = [f"{j}.{term}" for j in JOINTS]
        print(f"-- {term} [{unit}]")
        print(joint_terms_table({"OLS iid": ols, "SDP iid": sdp, "OLS coloured": ols_c,
                                 "SDP coloured": sdp_c,
                                 "a-priori + refit": models[
                                     "a-priori URDF + fc,fv,fo refit on training"],
                                 "FloBaRoID + refit": models[
                                     "FloBaRoID URDF + fc,fv,fo refit on training"]}, names))
    print("\nbase-parameter relative standard deviation (%, Pressé & Gautier): "
          + "; ".join(f"{k} median {np.median(r.relative_std):.1f}, "
                      f"{int(np.sum(r.relative_std < 10))}/{r.base.n_base} below 10 %"
                      for k, r in (("OLS iid", ols), ("SDP iid", sdp), ("OLS coloured", ols_c),
                                   ("SDP coloured", sdp_c))))
    print(f"cond(W_b) = {ols.condition_number:.4g}; {ols.base.n_base} base parameters "
          f"(rigid {ols.base.n_base - 21} + 21 friction/offset)")

    e = {k: s.total_relative_error for k, s in held_scores.items()}
    best_ref = min(v for k, v in e.items() if k.startswith(("a-priori", "FloBaRoID")))
    print("\n== Acceptance (OLS and SDP fitted on the same model and columns) ==")
    for label, o, s in (("URDF gravity", "consistid OLS",
                         "consistid SDP (pseudo-inertia, log-det prior)"),
                        ("estimated tilt", "consistid OLS, estimated tilt",
                         "consistid SDP, estimated tilt")):
        ratio = e[s] / e[o]
        res = models[s]
        print(f"{label}: SDP / OLS held-out total relative error {100 * e[s]:.2f} / "
              f"{100 * e[o]:.2f} = {ratio:.3f} (target ≤ 1.05) "
              f"{'PASS' if ratio <= 1.05 else 'FAIL'}; every body's pseudo-inertia ⪰ 0: "
              f"{res.is_consistent} (min eigenvalue {res.consistency.min_eigenvalues.min():.3g}); "
              f"vs best a-priori/FloBaRoID variant {100 * best_ref:.2f} %: "
              f"{'beats both' if e[s] < best_ref else 'does not beat both'}")

    print("\n== Cross-trajectory check (measurements_1 and _2 share one trajectory, _3 is "
          "another) ==")
    print("(tilt: estimated on the training files of the row; one trajectory alone determines "
          "it poorly)")
    rows = []
    for trn, val, seen in (((2, 3), 1, "yes (as 2)"), ((1, 2), 3, "no"), ((3,), 1, "no"),
                           ((1, 3), 2, "yes (as 1)")):
        tr = load(args.data, prior, trn).dataset
        va = load(args.data, prior, (val,)).dataset
        tilt = estimate_mounting(prior, tr, friction=FRICTION)
        row = [f"{'+'.join(map(str, trn))} → {val}", seen]
        for robot in (prior, tilt.model):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ci.errors.PoorExcitationWarning)
                o = ci.identify(robot, tr, method="ols", friction=FRICTION)
                s = ci.identify(robot, tr, method="sdp", friction=FRICTION)
            so, ss = score(o, va).total_relative_error, score(s, va).total_relative_error
            row += [100 * so, 100 * ss, ss / so]
        (r, p), (sr, sp) = np.degrees(tilt.angles), np.degrees(tilt.std)
        rows.append(row + [f"{r:+.2f} ± {sr:.2f}, {p:+.2f} ± {sp:.2f}"])
    print(table(["train → held-out", "trajectory seen", "OLS e%", "SDP e%", "SDP/OLS",
                 "OLS e% (tilt)", "SDP e% (tilt)", "SDP/OLS (tilt)", "tilt x, y (°)"], rows,
                floatfmt=".3g"))

    if args.position:
        print("\n== Position term sin q_j, cos q_j per joint: joints chosen on the training "
              "files only (train 2 → score 3, train 3 → score 2; greedy on the SDP's error) ==")
        chosen, cv_table = position_joints(prior, args.data)
        print(cv_table)
        print("\n== Position term: held-out total relative error (SDP/OLS: same joint terms; "
              "SDP/OLS(c,v,o): against OLS without the position term) ==")
        print(position_table(prior, args.data, chosen))
        pos = {"all joints": (*FRICTION, "position"),
               ",".join(f"j{j + 1}" for j in chosen): {t: True for t in FRICTION}
               | {"position": chosen}}
        pos_fits = {}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ci.errors.PoorExcitationWarning)
            for label, friction in pos.items():
                for method in ("ols", "sdp"):
                    pos_fits[f"consistid {method.upper()} + position ({label})"] = ci.identify(
                        prior, train.dataset, method=method, friction=friction)
        print("\n-- held-out measurements_1 per joint (train 2+3):")
        print(scores_table([held_scores["consistid OLS"],
                            held_scores["consistid SDP (pseudo-inertia, log-det prior)"]]
                           + [score(r, held.dataset, k) for k, r in pos_fits.items()]))
        rows = []
        for label, res in pos_fits.items():
            names = list(res.parameter_names)
            cells = []
            for j in chosen:
                a, b = (res.parameters[names.index(f"{JOINTS[j]}.{c}")] for c in ("ps1", "pc1"))
                cells.append(f"{a:+.3f}, {b:+.3f} (amplitude {np.hypot(a, b):.2f})")
            r7 = res.residual(held.dataset)[:, 6]
            rows.append([label, *cells, np.corrcoef(r7, np.sin(held.dataset.q[:, 6]))[0, 1],
                         res.consistency.min_eigenvalues.min()])
        r7 = sdp.residual(held.dataset)[:, 6]
        rows.append(["consistid SDP (no position term)", *(["-"] * len(chosen)),
                     np.corrcoef(r7, np.sin(held.dataset.q[:, 6]))[0, 1],
                     sdp.consistency.min_eigenvalues.min()])
        print("\n-- position terms p_s, p_c (N·m) of the chosen joints; joint 7's held-out "
              "residual vs sin q7; smallest pseudo-inertia eigenvalue:")
        print(table(["model", *(f"j{j + 1}: ps1, pc1" for j in chosen), "corr(r7, sin q7)",
                     "min λ(J)"], rows, floatfmt=".3g"))

    if args.diagnose:
        print(f"\n== Diagnosis of the a-priori URDF (train 2+3, held-out 1, σ = {SIGMA} N·m) ==")
        t0 = time.perf_counter()
        diag = ci.diagnose(prior, train.dataset, held_out=held.dataset, sigma=SIGMA)
        print(diag.summary())
        print(f"(diagnosis took {time.perf_counter() - t0:.1f} s)")
        norm = np.linalg.norm(np.sqrt(np.mean(held.dataset.tau ** 2, axis=0)))
        rows = [["a-priori URDF", *diag.rms_nominal,
                 100 * np.linalg.norm(diag.rms_nominal) / norm]]
        rows += [[f"+ {f.name} ({', '.join(str(JOINTS.index(j) + 1) for j in f.joints)})",
                  *f.rms_after, 100 * np.linalg.norm(f.rms_after) / norm] for f in diag.effects]
        rows += [[k, *held_scores[k].rms, 100 * held_scores[k].total_relative_error]
                 for k in ("consistid OLS", "consistid SDP (pseudo-inertia, log-det prior)")]
        print("\nHeld-out RMS per joint (N·m) and total relative error e (%) as the effects are "
              "added in rank order (joints 1–7 = lwr_0…lwr_6), and the identified models:")
        print(table(["model", *(f"rms{j + 1}" for j in range(7)), "e%"], rows, floatfmt=".3g"))
    return 0


if __name__ == "__main__":
    sys.exit(main())

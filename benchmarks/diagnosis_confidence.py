"""Calibration of ``diagnose``'s confidence labels on a labelled simulation set: how often is a
finding labelled "high", "medium" or "low" right?

The set (seeded; MuJoCo Panda, UR5, xArm7 and Kinova, torque noise 0.05 N·m through the default
signal chain, 200 Hz), case kinds cycling over each arm's seeds:

* **in-list** — :func:`diagnosis_blind.run_scenario`: one or two effects of the candidate list
  injected (random joints and magnitudes). Right: its effect is an injected one and, for a
  per-joint effect, every joint it names is an injected joint.
* **nuisance** — the same with one injected effect on top of Coulomb (0.2–1 N·m) and viscous
  (0.1–0.5 N·m·s/rad) friction on *every* joint. Right: as in-list, or Coulomb / viscous
  friction on any joint (it is there).
* **out-of-list** — :func:`diagnosis_out_of_list.run_case`: one effect that is *not* a
  candidate (friction varying with the angle, drifting, load-dependent, quadratic drag, a
  dead zone, crosstalk, backlash). No finding names the truth; one counts as right only when it
  acts on the disturbed joint *and* the diagnosis flags a remainder there (it says the effect
  is not the whole story); otherwise it is wrong.
* **mixed** — :func:`diagnosis_mixed.mixed_case`: every body's inertia off by up to 12 % and
  Coulomb plus viscous friction on every joint. Right: ``inertia``, ``coulomb``, ``viscous``.

The labels are :func:`consistid.diagnosis.confidence.confidence_label` of the features each
finding carries (:class:`consistid.diagnosis.confidence.Evidence`). **Calibration** uses the
cases of even seeds only; the **table** is printed per half, and the held-out half (odd seeds)
is the one to quote. ``--out`` writes every finding's features and label as JSON lines;
``--from`` reads them back (no simulation) to print the tables again.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/diagnosis_confidence.py [--per-arm 16]
[--arms panda,ur5] [--out findings.jsonl] [--from findings.jsonl]``.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import consistid as ci  # noqa: E402
from consistid.diagnosis.candidates import EffectLibrary  # noqa: E402
from consistid.diagnosis.confidence import LABELS, Evidence, confidence_label  # noqa: E402
from consistid.simulate.effects import Effects  # noqa: E402

import diagnosis_blind as blind  # noqa: E402
import diagnosis_mixed as mixed  # noqa: E402
import diagnosis_out_of_list as outside  # noqa: E402

ARMS = ("panda", "ur5", "xarm7", "kinova")
KINDS = ("in-list", "in-list-2", "nuisance", "out-of-list", "in-list", "out-of-list",
         "nuisance", "mixed", "weak", "weak")
#: Magnitudes of the "weak" cases' in-list effects relative to the blind benchmark's: near the
#: noise, where wrong findings are commoner.
WEAK = 0.25
OUT_KINDS = ("position_friction", "drifting_friction", "load_friction", "quadratic_drag",
             "dead_zone", "crosstalk", "backlash")
FRICTION = {"coulomb", "viscous"}
MIXED_RIGHT = {"inertia", "coulomb", "viscous"}
FIRST_SEED = 7000


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson score interval of a proportion ``k / n`` (Wilson 1927, JASA 22(158), 209–212)."""
    if n == 0:
        return float("nan"), float("nan")
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return centre - half, centre + half


def rows_of(diag, right_of, case: dict) -> list[dict]:
    """One row per finding: the case, whether it is right, its features and label."""
    out = []
    for e in diag.effects:
        ev = Evidence.of(e, diag)
        out.append(dict(case, effect=e.name, joints=list(e.joints), right=bool(right_of(e)),
                        label=confidence_label(ev), **ev.as_dict()))
    return out


def in_list_case(arm: str, seed: int, n_effects: int, nuisance: bool, scale: float = 1.0
                 ) -> list[dict]:
    model = ci.RobotModel.example(arm)
    base = None
    if nuisance:
        rng = np.random.default_rng(seed + 77)
        base = Effects(coulomb=dict(enumerate(rng.uniform(0.2, 1.0, model.nv))),
                       viscous=dict(enumerate(rng.uniform(0.1, 0.5, model.nv))),
                       torque_noise=blind.NOISE)
    out = blind.run_scenario(model, EffectLibrary(model), seed, n_effects, base=base,
                             scale=scale)
    if out["failed"]:
        return []
    names = model.joint_names
    truth = out["truth"]

    def right(e) -> bool:
        if nuisance and e.name in FRICTION:
            return True
        injected = [t for t in truth if t.name == e.name]
        joints = {names[t.joint] for t in injected if t.joint is not None}
        return bool(injected) and (e.scope != "joint" or not joints or set(e.joints) <= joints)

    kind = "nuisance" if nuisance else "in-list"
    return rows_of(out["diag"], right, dict(set=kind, arm=arm, seed=seed,
                                            truth=[blind.describe(t) for t in truth]))


def out_of_list_case(arm: str, seed: int) -> list[dict]:
    model = ci.RobotModel.example(arm)
    kind = OUT_KINDS[seed % len(OUT_KINDS)]
    out = outside.run_case(model, kind, seed)
    if out["failed"]:
        return []
    right_joints = set(out["right_joints"])
    flagged = set(out["diag"].remainder.flagged)

    def right(e) -> bool:
        on = set(e.joints) & right_joints
        return bool(on and on <= flagged)

    return rows_of(out["diag"], right, dict(set="out-of-list", arm=arm, seed=seed,
                                            truth=[f"{kind}@j{out['dist'].joint + 1}"]))


def mixed_case(arm: str, seed: int) -> list[dict]:
    model, train, held, _ = mixed.mixed_case(arm, seed, train_s=20.0)
    diag = ci.diagnose(model, train, held_out=held)
    return rows_of(diag, lambda e: e.name in MIXED_RIGHT,
                   dict(set="mixed", arm=arm, seed=seed, truth=["inertia+friction"]))


def run_case(arm: str, k: int) -> list[dict]:
    seed = FIRST_SEED + k
    kind = KINDS[(k // 2) % len(KINDS)]     # both halves see every kind
    if kind == "out-of-list":
        return out_of_list_case(arm, seed)
    if kind == "mixed":
        return mixed_case(arm, seed)
    return in_list_case(arm, seed, 2 if kind == "in-list-2" else 1, kind == "nuisance",
                        WEAK if kind == "weak" else 1.0)


def table(rows: list[dict], title: str) -> None:
    print(f"\n{title}\n\n| set | label | findings | right | fraction right (Wilson 95 %) |")
    print("| --- | --- | --- | --- | --- |")
    for which in ("all", "in-list", "nuisance", "out-of-list", "mixed"):
        for label in LABELS:
            sel = [r for r in rows if r["label"] == label and which in ("all", r["set"])]
            if which != "all" and not sel:
                continue
            k = sum(r["right"] for r in sel)
            lo, hi = wilson(k, len(sel))
            lo = max(lo, 0.0)
            frac = f"{k / len(sel):.0%} ({lo:.0%}–{hi:.0%})" if sel else "-"
            print(f"| {which} | {label} | {len(sel)} | {k} | {frac} |")


def relabel(rows: list[dict]) -> list[dict]:
    """Rows read back: their labels from the current rule (the features are stored)."""
    return [dict(r, label=confidence_label(Evidence.from_dict(r))) for r in rows]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--per-arm", type=int, default=20, help="cases per arm")
    parser.add_argument("--start", type=int, default=0,
                        help="first case index (to run a set in parts)")
    parser.add_argument("--arms", default=",".join(ARMS))
    parser.add_argument("--out", type=Path, help="write the findings (JSON lines)")
    parser.add_argument("--from", dest="source", type=Path,
                        help="read findings written by --out instead of simulating")
    args = parser.parse_args()
    logging.disable(logging.WARNING)
    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    if args.source is not None:
        rows = relabel([json.loads(line) for line in args.source.read_text().splitlines()])
    else:
        rows = []
        for arm in args.arms.split(","):
            for k in range(args.start, args.per_arm):
                new = run_case(arm, k)
                rows += new
                print(f"  {arm} {FIRST_SEED + k}: {len(new)} findings "
                      f"({time.perf_counter() - t0:.0f} s)", flush=True)
                if args.out is not None:
                    with args.out.open("a") as fh:
                        fh.writelines(json.dumps(r) + "\n" for r in new)
    print("\nwrong findings:")
    for r in rows:
        if not r["right"]:
            print(f"  [{r['set']}] {r['arm']} {r['seed']} {'+'.join(r['truth'])}: "
                  f"{r['effect']}({','.join(r['joints'])}) — {r['label']}")
    calib = [r for r in rows if r["seed"] % 2 == 0]
    test = [r for r in rows if r["seed"] % 2 == 1]
    table(calib, f"calibration half (even seeds): {len(calib)} findings")
    table(test, f"held-out half (odd seeds): {len(test)} findings")
    print(f"\n{len(rows)} findings in {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()

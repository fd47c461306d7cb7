"""Calibration of ``diagnose``'s confidence labels on a labelled simulation set: how often is a
finding labelled "high", "medium" or "low" right?

The set (seeded; about 26 cases, ≈ 5 minutes on one core):

* **in-list** — :func:`diagnosis_blind.run_scenario`: one or two effects of the candidate list
  injected into the MuJoCo Panda and UR5 (random joints and magnitudes; the signal chain's
  low-pass, torque noise 0.05 N·m). A finding is right when its effect is an injected one
  and, for a per-joint effect, every joint it names is an injected joint.
* **out-of-list** — :func:`diagnosis_out_of_list.run_case`: one effect that is *not* a
  candidate (friction varying with the angle, drifting, load-dependent, quadratic drag, a
  dead zone, crosstalk, backlash) on the Panda and UR5. No finding names the truth; one counts
  as right only when it acts on the disturbed joint *and* the diagnosis flags a remainder
  there (it says the effect is not the whole story); otherwise it is wrong.
* **mixed** — :func:`diagnosis_mixed.mixed_case`: every body's inertia off by up to 12 % and
  Coulomb plus viscous friction on every joint (UR5, Panda, Kinova). Right: ``inertia``,
  ``coulomb``, ``viscous``; anything else is wrong.

Printed: per label, findings, right, the fraction right with a Wilson 95 % interval, and per
set. The target is "high" right in at least 95 % of its findings.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/diagnosis_confidence.py [--quick]``.
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import consistid as ci  # noqa: E402
from consistid.diagnosis.candidates import EffectLibrary  # noqa: E402

import diagnosis_blind as blind  # noqa: E402
import diagnosis_mixed as mixed  # noqa: E402
import diagnosis_out_of_list as outside  # noqa: E402

LABELS = ("high", "medium", "low")
OUT_KINDS = ("position_friction", "drifting_friction", "load_friction", "quadratic_drag",
             "dead_zone", "crosstalk", "backlash")
MIXED_RIGHT = {"inertia", "coulomb", "viscous"}


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson score interval of a proportion ``k / n`` (Wilson 1927, JASA 22(158), 209–212)."""
    if n == 0:
        return float("nan"), float("nan")
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return centre - half, centre + half


def in_list(arm: str, seeds: list[int], double: bool) -> list[tuple[str, str, bool, str]]:
    model = ci.RobotModel.example(arm)
    library = EffectLibrary(model)
    rows = []
    for seed in seeds:
        out = blind.run_scenario(model, library, seed, 2 if double else 1)
        if out["failed"]:
            continue
        truth = {t.name: t.joint for t in out["truth"]}
        for e in out["diag"].effects:
            joints_ok = (e.scope != "joint" or e.name not in truth or truth[e.name] is None
                         or set(e.joints) <= {model.joint_names[t.joint] for t in out["truth"]
                                              if t.name == e.name and t.joint is not None})
            rows.append(("in-list", e.confidence, e.name in truth and joints_ok,
                         f"{arm} {seed}: {e.name}({','.join(e.joints)})"))
    return rows


def out_of_list(arm: str, seeds: list[int]) -> list[tuple[str, str, bool, str]]:
    model = ci.RobotModel.example(arm)
    rows = []
    for k, seed in enumerate(seeds):
        kind = OUT_KINDS[k % len(OUT_KINDS)]
        out = outside.run_case(model, kind, seed)
        if out["failed"]:
            continue
        right = set(out["right_joints"])
        flagged = set(out["diag"].remainder.flagged)
        for e in out["diag"].effects:
            on = set(e.joints) & right
            rows.append(("out-of-list", e.confidence, bool(on and on <= flagged),
                         f"{arm} {seed} {kind}: {e.name}({','.join(e.joints)})"))
    return rows


def mixed_set(arms: list[str], seed: int) -> list[tuple[str, str, bool, str]]:
    rows = []
    for arm in arms:
        model, train, held, _ = mixed.mixed_case(arm, seed)
        diag = ci.diagnose(model, train, held_out=held)
        for e in diag.effects:
            rows.append(("mixed", e.confidence, e.name in MIXED_RIGHT,
                         f"{arm} {seed}: {e.name}"))
    return rows


def table(rows: list[tuple[str, str, bool, str]]) -> None:
    print("\n| set | label | findings | right | fraction right (Wilson 95 %) |")
    print("| --- | --- | --- | --- | --- |")
    for which in ("all", "in-list", "out-of-list", "mixed"):
        for label in LABELS:
            sel = [r for r in rows if r[1] == label and which in ("all", r[0])]
            k = sum(r[2] for r in sel)
            lo, hi = wilson(k, len(sel))
            frac = f"{k / len(sel):.0%} ({lo:.0%}–{hi:.0%})" if sel else "-"
            print(f"| {which} | {label} | {len(sel)} | {k} | {frac} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="a third of the set")
    args = parser.parse_args()
    logging.disable(logging.WARNING)
    warnings.simplefilter("ignore")
    n = 2 if args.quick else 6
    t0 = time.perf_counter()
    rows = []
    for arm in ("panda", "ur5"):
        rows += in_list(arm, list(range(3000, 3000 + n)), double=False)
        rows += in_list(arm, list(range(4000, 4000 + n // 2)), double=True)
        rows += out_of_list(arm, list(range(5000, 5000 + n // 2 + 1)))
    rows += mixed_set(["ur5"] if args.quick else ["ur5", "panda", "kinova"], 7)
    print("wrong findings:")
    for r in rows:
        if not r[2]:
            print(f"  [{r[0]}] {r[3]} — {r[1]}")
    table(rows)
    print(f"\n{len(rows)} findings in {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()

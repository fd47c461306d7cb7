"""MJCF both ways on random chains: reading (``RobotModel.from_mjcf`` and, for comparison,
``pinocchio.buildModelFromMJCF``) against MuJoCo's ``mj_inverse``, and writing identified
values into the file (``consistid.robot.mjcf_edit.write_mjcf_into``) read back by MuJoCo.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/mjcf_roundtrip.py [--chains 50] [--seed 0]``.
Each chain has 2–6 bodies with random placements, orientations, inertials (``iquat``),
joint anchors and reference positions (``ref``), oblique hinge/slide axes, armature, a tilted
gravity and, on half of them, a body
whose inertia MuJoCo derives from a box geom. Prints the largest relative torque error over
20 random states per chain, and the largest relative error of the written file's inverse
dynamics against ``pinocchio.rnea`` with the written parameters (armature included).
"""

from __future__ import annotations

import argparse
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin

import consistid as ci
from consistid.errors import ExportWarning
from consistid.identification.summary import table
from consistid.robot.mjcf_edit import write_mjcf_into


def chain(rng: np.random.Generator, n: int, geom_body: int | None) -> str:
    """MJCF text of a random n-body chain."""
    g = rng.normal(0, 1, 3) + [0, 0, -9.81]
    text = [f'<mujoco><option gravity="{g[0]:.4f} {g[1]:.4f} {g[2]:.4f}"/><worldbody>']
    for k in range(n):
        r = rng.uniform(-1, 1, 16)
        kind = "slide" if r[15] > 0.6 else "hinge"
        body = (f'<body name="b{k}" pos="{r[0]:.3f} {r[1]:.3f} {r[2]:.3f}" '
                f'quat="{r[3]:.3f} {r[4]:.3f} {r[5]:.3f} {r[6]:.3f}">'
                f'<joint name="j{k}" type="{kind}" pos="{r[7]:.3f} {r[8]:.3f} 0" ref="{r[0]:.2f}" '
                f'axis="{r[9]:.3f} {r[10]:.3f} 1" armature="{abs(r[11]) / 10:.4f}"/>')
        if k == geom_body:
            body += f'<geom type="box" size="0.05 0.03 {0.02 + abs(r[12]) / 10:.3f}"/>'
        else:
            d = np.sort(rng.uniform(0.01, 0.05, 3))
            d[2] = min(d[2], 0.95 * (d[0] + d[1]))
            body += (f'<inertial pos="{r[12]:.3f} {r[13]:.3f} {r[14]:.3f}" '
                     f'quat="{r[4]:.3f} {r[3]:.3f} 0.3 {r[5]:.3f}" mass="{1 + abs(r[6]):.3f}" '
                     f'diaginertia="{d[0]:.4f} {d[1]:.4f} {d[2]:.4f}"/>')
        text.append(body)
    return "".join(text + ["</body>"] * n + ["</worldbody></mujoco>"])


def mj_inverse(path: Path, states: tuple[np.ndarray, ...]) -> np.ndarray:
    import mujoco

    mm = mujoco.MjModel.from_xml_path(str(path))
    mm.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    d = mujoco.MjData(mm)
    out = []
    for q, dq, ddq in zip(*states):
        d.qpos[:], d.qvel[:], d.qacc[:] = q, dq, ddq
        mujoco.mj_inverse(mm, d)
        out.append(d.qfrc_inverse.copy())
    return np.array(out)


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def one(rng: np.random.Generator, folder: Path, index: int) -> tuple[float, float, float]:
    n = int(rng.integers(2, 7))
    path = folder / f"chain{index}.xml"
    path.write_text(chain(rng, n, int(rng.integers(n)) if index % 2 else None))
    states = tuple(rng.normal(size=(20, n)) for _ in range(3))
    truth = mj_inverse(path, states)
    model = ci.RobotModel.from_mjcf(path)
    ours = rel(model.rnea(*states), truth)
    pm = pin.buildModelFromMJCF(str(path))
    data = pm.createData()
    theirs = rel(np.array([pin.rnea(pm, data, *s) for s in zip(*states)]), truth)
    theta = model.prior_parameters * rng.uniform(0.8, 1.3, model.n_bodies).repeat(10)
    names = [*model.parameter_names, *(f"{j}.Ia" for j in model.joint_names)]
    ia = rng.uniform(0.0, 0.1, n)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExportWarning)
        out = write_mjcf_into(model, folder / f"chain{index}_out.xml", path,
                              np.concatenate([theta, ia]), names)
    written = model.with_parameters(theta).pin_model
    written.armature = ia
    data = written.createData()
    expected = np.array([pin.rnea(written, data, *s) for s in zip(*states)])
    return ours, theirs, rel(mj_inverse(out, states), expected)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--chains", type=int, default=50)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    with tempfile.TemporaryDirectory() as tmp:
        rows = np.array([one(rng, Path(tmp), k) for k in range(args.chains)])
    print(table(["reader / writer", "median rel. error", "max rel. error"], [
        ["RobotModel.from_mjcf vs mj_inverse", f"{np.median(rows[:, 0]):.1e}",
         f"{rows[:, 0].max():.1e}"],
        ["pin.buildModelFromMJCF vs mj_inverse", f"{np.median(rows[:, 1]):.1e}",
         f"{rows[:, 1].max():.1e}"],
        ["written file (mj_inverse) vs pin.rnea", f"{np.median(rows[:, 2]):.1e}",
         f"{rows[:, 2].max():.1e}"]]))
    print(f"{args.chains} chains of 2–6 bodies (seed {args.seed}); half with a body's inertia "
          "derived from a geom")


if __name__ == "__main__":
    main()

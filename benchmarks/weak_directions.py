"""A joint that moves one way only (issue 26): what identify names, what predict warns, and what
the SDP's default joint prior buys on reversed motion.

Run from the repository:
``OPENBLAS_NUM_THREADS=1 python benchmarks/weak_directions.py [--seeds 2]``.

For the Panda and the UR5 (MuJoCo "real robot", Coulomb + viscous friction drawn per joint,
σ = 0.1 N·m, 20 s at 500 Hz per log, seeded): training on a random Fourier excitation in which
joint 1 moves one way only (q̇ > 0 throughout), held-out on another excitation in which it
moves the other way. Prints the held-out RMS of that joint for the nominal model (CAD, no
friction), OLS (when the data determine it), the SDP with ``joint_prior=False`` and the SDP as
by default, with its f_c, f_o against the simulated truth, and whether identify and predict
warned. Second table: the largest weak-direction ratio (:mod:`consistid.identification.weak`)
on ordinary two-way excitations of four arms, against ``WEAK_RATIO``.
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np

import consistid as ci
from consistid.errors import ExtrapolationWarning, PoorExcitationError, PoorExcitationWarning
from consistid.identification.envelope import TrainingEnvelope
from consistid.identification.streaming import compress_data
from consistid.identification.summary import table
from consistid.identification.weak import WEAK_RATIO, weak_directions
from consistid.simulate import Effects, TrackingController, record
from consistid.simulate.experiments import nominal_residual

DURATION, RATE, NOISE = 20.0, 500.0, 0.1


class OneWay:
    """A Fourier excitation whose joint ``joint`` moves at ``speed · (1 ± 0.4 cos ωt)``: one
    way only, never slower than 0.6 × ``speed``."""

    def __init__(self, base, joint: int, speed: float, centre: float) -> None:
        self.base, self.joint, self.speed, self.centre = base, joint, speed, centre

    def evaluate(self, t: np.ndarray):
        q, dq, ddq = (np.array(a) for a in self.base.evaluate(t))
        w, v = 2 * np.pi / 7.0, self.speed
        a = 0.4 * abs(v) / w
        s = np.sign(v)
        q[:, self.joint] = self.centre + v * (t - DURATION / 2) + s * a * np.sin(w * t)
        dq[:, self.joint] = v + s * a * w * np.cos(w * t)
        ddq[:, self.joint] = -s * a * w * w * np.sin(w * t)
        return q, dq, ddq


def one_way_logs(model: ci.RobotModel, seed: int, joint: int = 0):
    """(train, reversed held-out, effects): joint ``joint`` moves one way in train, the other
    way in held-out (module docstring)."""
    rng = np.random.default_rng(seed)
    eff = Effects(coulomb=rng.uniform(0.5, 2.0, model.nv), viscous=rng.uniform(0.1, 0.5, model.nv),
                  torque_noise=NOISE)
    lim = model.limits
    centre = float(0.5 * (np.clip(lim.lower, -3, 3) + np.clip(lim.upper, -3, 3))[joint])
    ctrl = TrackingController(bandwidth=100.0)
    logs = []
    for k, speed in enumerate((0.15, -0.15)):
        traj = ci.FourierTrajectory.random(model, harmonics=5, period=10.0, seed=seed + 100 * k)
        logs.append(record(model, OneWay(traj, joint, speed, centre), eff, duration=DURATION,
                           rate=RATE, seed=seed + k, controller=ctrl).true_dataset())
    return logs[0], logs[1], eff


def fit(model, train, held, joint, **kw):
    """(held-out RMS of ``joint``, f_c, f_o, warned at identify, warned at predict) or None."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            res = ci.identify(model, train, **kw)
        except PoorExcitationError:
            return None
        rms = res.rms(held)[joint]
    kinds = {w.category for w in caught}
    names = res.parameter_names
    j = model.joint_names[joint]
    return (rms, res.parameters[names.index(f"{j}.fc")], res.parameters[names.index(f"{j}.fo")],
            PoorExcitationWarning in kinds, ExtrapolationWarning in kinds)


def one_way_table(seeds: int) -> None:
    rows = []
    for arm in ("panda", "ur5"):
        model = ci.RobotModel.example(arm)
        for seed in range(1, seeds + 1):
            train, held, eff = one_way_logs(model, seed)
            nominal = float(np.sqrt(np.mean(nominal_residual(model, held)[:, 0] ** 2)))
            fc_true = float(eff.coulomb[0])
            for label, kw in (("ols", dict(method="ols")),
                              ("sdp, joint_prior=False", dict(method="sdp", joint_prior=False)),
                              ("sdp (default)", dict(method="sdp"))):
                out = fit(model, train, held, 0, **kw)
                if out is None:
                    rows.append((arm, seed, label, nominal, "refused", "", "", fc_true, "", ""))
                    continue
                rms, fc, fo, w_id, w_pred = out
                rows.append((arm, seed, label, nominal, rms, rms / nominal, f"{fc:.4g}",
                             f"{fo:.4g}", f"{fc_true:.3g}", f"{'yes' if w_id else 'no'}/"
                             f"{'yes' if w_pred else 'no'}"))
    print("Joint 1 moves one way in training, the other way in the held-out log "
          f"({DURATION:g} s at {RATE:g} Hz each, σ = {NOISE} N·m):")
    print(table(["arm", "seed", "fit", "nominal RMS", "held-out RMS", "/ nominal", "f_c", "f_o",
                 "true f_c", "warned identify/predict"], rows))


def ratio_table(seeds: int) -> None:
    rows = []
    for arm in ("panda", "ur5", "xarm7", "kinova"):
        model = ci.RobotModel.example(arm)
        for seed in range(1, seeds + 1):
            rng = np.random.default_rng(seed)
            eff = Effects(coulomb=rng.uniform(0.5, 2.0, model.nv),
                          viscous=rng.uniform(0.1, 0.5, model.nv), torque_noise=NOISE)
            traj = ci.FourierTrajectory.random(model, harmonics=5, period=10.0, seed=seed)
            train = record(model, traj, eff, duration=30.0, rate=RATE, seed=seed).true_dataset()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = ci.identify(model, train, method="sdp")
            prob = compress_data(model, train, res.spec, res.base)
            r_b = prob.stacked(sigma=res.sigma, columns=res.base.independent)[0]
            found = weak_directions(model, res.spec, res.base, r_b, TrainingEnvelope.of(train),
                                    np.sqrt(prob.tau_sum_squares / prob.n_samples), ratio=0.0)
            rows.append((arm, seed, found[0][1], len(res.weakly_informed)))
    print(f"\nTwo-way random Fourier excitations (30 s): largest ratio (WEAK_RATIO = "
          f"{WEAK_RATIO}):")
    print(table(["arm", "seed", "largest ratio", "weakly informed"], rows))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=2)
    args = parser.parse_args()
    one_way_table(args.seeds)
    ratio_table(args.seeds)


if __name__ == "__main__":
    main()

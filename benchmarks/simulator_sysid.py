"""``mujoco.sysid`` (MuJoCo 4.0) on the runs of ``simulator.py``, for its table: run once per run
type with one seed (a fit takes minutes and hundreds of MB to GBs).

How it is run (its integration tests and README): the robot's MJCF at 2 ms ``implicitfast`` with
a ``motor`` per joint and a ``jointpos`` sensor per joint; the training log cut into 1 s
sequences (``ModelSequences``, each from its logged state: an open-loop rollout of an arm under
gravity diverges over longer spans), the logged torques as controls, the positions as sensors;
parameters per body ``body_inertia_param(..., InertiaType.MassIpos, scale_rot_inertia=True)``
and per joint ``armature``, ``damping``, ``frictionloss`` in ``[0, 0.5 | 2]``; the default
``optimizer="mujoco"``. Known 4.0.0 bugs worked around: ``InertiaType.Pseudo`` does not compile
(NaN ``iquat``), so ``MassIpos``; ``damping`` is a 3-vector (the README's scalar recipe raises
``TypeError``), so its first entry is set; a diverging candidate raises out of ``optimize``,
caught and reported. Needs ``pip install "mujoco[sysid]"`` (the ``bench-sysid`` extra).

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/simulator_sysid.py poor`` (or ``rich``).
"""

from __future__ import annotations

import argparse
import resource
import time
import warnings

import mujoco
import numpy as np
import pinocchio as pin
from simulator import RUNS, SIGMA, Truth, _Fixed, log, make_truth, truth_rms

import consistid as ci
from consistid.robot.mjcf import mjcf_spec
from consistid.simulator import validate_rollout

H, WINDOW = 0.002, 1.0


def user_spec(model: ci.RobotModel):
    spec = mjcf_spec(model)
    spec.option.timestep = H
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    return spec


def parameters(sysid, spec, model: ci.RobotModel):
    mj = spec.compile()
    params = sysid.ParameterDict()
    for b in model.body_names:
        params.add(sysid.body_inertia_param(spec, mj, b, sysid.InertiaType.MassIpos,
                                            scale_rot_inertia=True))
    for j in model.joint_names:
        for attr, hi in (("armature", 0.5), ("damping", 2.0), ("frictionloss", 2.0)):
            def modify(s, p, j=j, attr=attr):
                value = getattr(s.joint(j), attr)
                if np.ndim(value):
                    value = np.array(value, dtype=float)
                    value[0] = p.value[0]
                    setattr(s.joint(j), attr, value)
                else:
                    setattr(s.joint(j), attr, float(p.value[0]))
            params.add(sysid.Parameter(f"{j}_{attr}", nominal=0.0, min_value=0.0,
                                       max_value=hi, modifier=modify))
    return params


def sequences(sysid, spec, model: ci.RobotModel, data: ci.Dataset):
    for j in model.joint_names:
        spec.add_sensor(name=f"{j}_pos", type=mujoco.mjtSensor.mjSENS_JOINTPOS, objname=j,
                        objtype=mujoco.mjtObj.mjOBJ_JOINT)
    mj = spec.compile()
    t = np.arange(data.t[0], data.t[-1], H)
    q = np.column_stack([np.interp(t, data.t, c) for c in data.q.T])
    dq = np.column_stack([np.interp(t, data.t, c) for c in data.dq.T])
    tau = data.tau[np.clip(np.searchsorted(data.t, t, "right") - 1, 0, None)]
    w = int(round(WINDOW / H))
    parts = [slice(s, s + w) for s in range(0, t.size - w + 1, w)]
    return sysid.ModelSequences(
        "panda", spec, [f"w{k}" for k in range(len(parts))],
        [sysid.create_initial_state(mj, q[p.start], dq[p.start]) for p in parts],
        [sysid.TimeSeries(t[p] - t[p.start], tau[p]) for p in parts],
        [sysid.TimeSeries.from_names(t[p] - t[p.start], q[p], mj) for p in parts])


def identified(model: ci.RobotModel, mj) -> Truth:
    """The fitted MuJoCo model as standard parameters and joint terms."""
    inertial, terms = [], []
    for i, (b, j) in enumerate(zip(model.body_names, model.joint_names)):
        bid = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, b)
        dof = mj.jnt_dofadr[mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, j)]
        rot = pin.Quaternion(*mj.body_iquat[bid]).toRotationMatrix()
        inertia = rot @ np.diag(mj.body_inertia[bid]) @ rot.T
        inertial.append(pin.Inertia(float(mj.body_mass[bid]), mj.body_ipos[bid].copy(),
                                    inertia).toDynamicParameters())
        terms.append((mj.dof_armature[dof] - model.pin_model.armature[i], mj.dof_damping[dof],
                      mj.dof_frictionloss[dof]))
    a, d, f = np.array(terms).T
    return Truth(model, np.concatenate(inertial), a, d, f)


def main() -> None:
    from mujoco import sysid  # the optional comparison (the bench-sysid extra)

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", choices=list(RUNS))
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    model = ci.RobotModel.example("panda")
    truth = make_truth(model, np.random.default_rng(args.seed))
    train = log(truth, seed=100 * args.seed + 1, **RUNS[args.run])
    held = log(truth, 10.0, 5, seed=100 * args.seed + 2)
    t0 = time.process_time()
    res = ci.identify(model, train, method="sdp", friction=("coulomb", "viscous"),
                      armature=True)
    t_sdp = time.process_time() - t0
    spec = user_spec(model)
    params = parameters(sysid, spec, model)
    residual_fn = sysid.build_residual_fn(models_sequences=[sequences(sysid, spec, model,
                                                                      train)])
    t0 = time.process_time()
    try:
        fitted, _ = sysid.optimize(initial_params=params, residual_fn=residual_fn,
                                   optimizer="mujoco", verbose=False)
    except Exception as exc:                 # a diverging candidate aborts a fit in 4.0.0
        print(f"mujoco.sysid failed: {exc!r}")
        return
    t_sysid = time.process_time() - t0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
    fit = identified(model, sysid.apply_param_modifiers(fitted, user_spec(model)))
    models = {"truth": _Fixed(model, truth.vector(res.parameter_names), res.parameter_names),
              "consistid SDP": res,
              "mujoco.sysid": _Fixed(model, fit.vector(res.parameter_names),
                                     res.parameter_names)}
    v = validate_rollout(held, models)
    print(f"{args.run}, seed {args.seed}: mujoco.sysid CPU {t_sysid:.0f} s = "
          f"{t_sysid / t_sdp:.0f} × the SDP's; peak RSS {peak:.2f} GB; held-out τ RMS/σ (max) "
          f"{np.max(truth_rms(fit, res, held)) / SIGMA:.3g} (SDP "
          f"{np.max(res.rms(held)) / SIGMA:.3g}); consistent "
          f"{ci.is_physically_consistent(fit.inertial, 'pseudo-inertia').ok}")
    print(v.summary())


if __name__ == "__main__":
    main()

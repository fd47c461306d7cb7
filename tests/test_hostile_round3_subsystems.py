"""Hostile input, round three (issue 30): the newer subsystems and resources.

The online estimator refuses a sample that is text or beyond any joint's range (the estimate
unchanged, not moved to 1e199); a negative break-away torque warns as non-physical; an
excitation of 2·10⁸ samples is refused with its size before anything is allocated; the
remaining entries of the earlier harness (text in ``q``, ``neighbourhood={…}``,
``effects=[]``, a NaN nominal vector) are named.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import consistid as ci
from consistid.errors import DatasetError, ExcitationError, ModelError, ModelMisfitWarning, \
    OptionError
from consistid.online.rls import RecursiveEstimator

from .conftest import random_states


@pytest.fixture(scope="module")
def arm():
    return ci.RobotModel.example("ur5")


@pytest.fixture(scope="module")
def states(arm):
    q, dq, ddq = random_states(arm, 120, 5)
    return q, dq, ddq, arm.rnea(q, dq, ddq)


def _warm(arm, states, n=40):
    est = RecursiveEstimator(arm)
    q, dq, ddq, tau = states
    for k in range(n):
        est.update(q[k], dq[k], ddq[k], tau[k])
    return est


@pytest.mark.parametrize("field, value", [("tau", 1e100), ("q", -1e100), ("ddq", 3e7)])
def test_an_implausible_sample_is_refused_and_the_estimate_kept(arm, states, field, value):
    est = _warm(arm, states)
    before = est.base_parameters.copy()
    q, dq, ddq, tau = (a[40].copy() for a in states)
    sample = dict(q=q, dq=dq, ddq=ddq, tau=tau)
    sample[field][1] = value
    with pytest.raises(DatasetError, match=f"{field}\\['shoulder_lift_joint'\\].*SI units"):
        est.update(**sample)
    assert est.n_updates == 40 and np.array_equal(est.base_parameters, before)
    batch = {k: np.asarray(v)[40:45].copy() for k, v in zip(("q", "dq", "ddq", "tau"), states)}
    batch[field][2, 1] = value
    with pytest.raises(DatasetError, match="update_batch: sample 42"):
        est.update_batch(**batch)
    assert est.n_updates == 40


def test_a_text_sample_is_named(arm, states):
    est = _warm(arm, states, 5)
    q, dq, ddq, _ = (a[5] for a in states)
    with pytest.raises(DatasetError, match="update: tau is not numbers"):
        est.update(q, dq, ddq, ["a"] * arm.nv)
    with pytest.raises(DatasetError, match="update_batch: q is not numbers"):
        est.update_batch([["x"] * arm.nv], dq[None], ddq[None], dq[None])


def test_text_and_ragged_dataset_fields_are_named(states):
    q, dq, ddq, tau = states
    t = 0.01 * np.arange(len(q))
    with pytest.raises(DatasetError, match="dataset.q holds"):
        ci.Dataset(t=t, q=np.full(q.shape, "a"), dq=dq, ddq=ddq, tau=tau)
    with pytest.raises(DatasetError, match="dataset.t"):
        ci.Dataset(t=["0", "x"] * (len(q) // 2), q=q, dq=dq, ddq=ddq, tau=tau)
    with pytest.raises(DatasetError, match="dataset.tau is not an array"):
        ci.Dataset(t=t, q=q, dq=dq, ddq=ddq, tau=[[1.0], [1.0, 2.0]] * (len(q) // 2))


def test_a_neighbourhood_that_is_not_one_is_named(arm, states):
    q, dq, ddq, tau = states
    data = ci.Dataset(t=0.01 * np.arange(len(q)), q=q, dq=dq, ddq=ddq, tau=tau)
    with pytest.raises(OptionError, match="neighbourhood must be"):
        ci.identify(arm, data, neighbourhood={"mass": 0.1})


def test_diagnose_without_effects_or_with_a_nan_nominal_is_named(arm, states):
    q, dq, ddq, tau = states
    data = ci.Dataset(t=0.01 * np.arange(len(q)), q=q, dq=dq, ddq=ddq, tau=tau)
    with pytest.raises(OptionError, match="effects=\\[\\] names no effect"):
        ci.diagnose(arm, data, effects=[])
    nominal = arm.prior_parameters.copy()
    nominal[13] = np.nan
    with pytest.raises(ModelError, match=f"nominal\\[13\\] \\({arm.parameter_names[13]}\\)"):
        ci.diagnose(arm, data, nominal=nominal)
    with pytest.raises(ModelError, match="nominal must be"):
        ci.diagnose(arm, data, nominal=["a"] * arm.n_inertial)


def test_a_negative_breakaway_torque_warns_as_non_physical(arm):
    """Torques logged with the opposite sign, read with a model whose gravity is flipped to
    match: every event's friction reads negative (−f_s), which no static friction is."""
    from consistid.friction import estimate_breakaway, ramp_plan, simulate_ramps
    from consistid.simulate import Effects
    fs = np.linspace(2.0, 0.4, arm.nv)
    run = simulate_ramps(arm, ramp_plan(arm, joints=[2], repeats=1), Effects(coulomb=fs))
    flipped = dataclasses.replace(run.dataset, tau=-run.dataset.tau)
    upside_down = ci.RobotModel.from_urdf(arm.source, gravity=(0.0, 0.0, 9.81))
    with pytest.warns(ModelMisfitWarning, match="elbow_joint: break-away torque -.* not "
                                                "physical"):
        est = estimate_breakaway(upside_down, flipped, joints=[2])
    assert est.torque[2] < 0 and any("not physical" in n for n in est.notes)


def test_an_excitation_of_2e8_samples_is_refused_with_its_size(arm, monkeypatch):
    from consistid.excitation.trajectory import FourierTrajectory
    traj = FourierTrajectory.random(arm)
    allocated = []
    monkeypatch.setattr(np, "arange", lambda *a, **k: allocated.append(a) or pytest.fail(
        "allocated before refusing"))
    with pytest.raises(ExcitationError, match=r"2e\+08 samples .* 28.3 GiB"):
        traj.sample(2e4, 1e4)
    assert not allocated
    monkeypatch.undo()
    assert traj.sample(100.0).n_samples == int(round(100.0 * traj.period))


class _DyingClient:
    """A ``distributed.Client`` stand-in whose reduction fails as a killed worker does."""

    class scheduler:                                     # noqa: N801 (mirrors the attribute)
        address = "tcp://fake:0"

    def __init__(self, task):
        self.task = task

    def compute(self, item):
        distributed = pytest.importorskip("distributed")
        task = self.task

        class Future:
            def result(self):
                worker = type("WorkerState", (), {"address": "tcp://worker:1"})()
                raise distributed.scheduler.KilledWorker(task, worker, 3)
        return Future()


def test_a_killed_dask_worker_names_the_partition_and_its_files(tmp_path, planar_2r):
    pytest.importorskip("dask.bag")
    from consistid.identification.distributed import on_dask
    paths = [str(tmp_path / f"log{k}.npz") for k in range(4)]
    data = on_dask(paths, client=_DyingClient(("compress_partition-part-abc", 1)),
                   npartitions=2)
    with pytest.raises(ci.IdentificationError,
                       match=r"died .*partition 1: '.*log2.npz', '.*log3.npz'"):
        ci.identify(planar_2r, data, method="ols")


@pytest.mark.slow
def test_a_worker_killed_for_real_is_named(tmp_path, planar_2r):
    """A LocalCluster of worker processes; the loader of one file kills its worker (as an
    out-of-memory kill would): the error names that file's partition. The scheduler sends the
    single worker one task at a time (worker-saturation 1.0): with the default 1.1 it holds both
    partitions when it dies, Dask marks both as the killers, and either may be named."""
    distributed = pytest.importorskip("distributed")
    import dask
    from consistid.identification.distributed import on_dask
    paths = []
    for k in range(2):
        q, dq, ddq = random_states(planar_2r, 50, k)
        ci.Dataset(t=0.01 * np.arange(50), q=q, dq=dq, ddq=ddq,
                   tau=planar_2r.rnea(q, dq, ddq)).save(tmp_path / f"log{k}.npz")
        paths.append(str(tmp_path / f"log{k}.npz"))
    with dask.config.set({"distributed.scheduler.worker-saturation": 1.0}), \
            distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as cluster, \
            distributed.Client(cluster) as client, \
            pytest.raises(ci.IdentificationError, match=r"partition 1: '.*log1.npz'"):
        data = on_dask(paths, client=client, npartitions=2, loader=_dies_on_log1)
        ci.identify(planar_2r, data, method="ols")


def _dies_on_log1(path):
    import os
    if path.name == "log1.npz":
        os._exit(1)
    return ci.Dataset.load(path)


def _tool_poses(model, q, turn=None):
    import pinocchio as pin
    pm = model.pin_model
    data, fid = pm.createData(), pm.getFrameId("tool0")
    out = []
    for k, qk in enumerate(q):
        pin.framesForwardKinematics(pm, data, model.configuration(qk))
        m = data.oMf[fid]
        rot = np.array(m.rotation) if turn is None else np.array(m.rotation) @ turn[k]
        out.append(np.block([[rot, np.array(m.translation)[:, None]],
                             [np.zeros((1, 3)), 1.0]]))
    return np.array(out)


def test_a_calibration_its_offsets_cannot_explain_warns(arm):
    """Orientations off by up to ~0.6 rad (what degrees read as radians, or another measured
    frame, look like): no offset explains them, and the result says so; clean poses of the
    same configurations do not warn."""
    import warnings

    from scipy.spatial.transform import Rotation

    from consistid.kinematics.parameters import random_configurations
    rng = np.random.default_rng(4)
    q = random_configurations(arm, 30, rng)
    turn = Rotation.from_rotvec(rng.normal(0.0, 0.35, (30, 3))).as_matrix()
    with pytest.warns(ModelMisfitWarning, match="orientation error is still .* degrees"):
        ci.calibrate_kinematics(arm, q, _tool_poses(arm, q, turn), frame="tool0")
    with warnings.catch_warnings():
        warnings.simplefilter("error", ModelMisfitWarning)
        ci.calibrate_kinematics(arm, q, _tool_poses(arm, q), frame="tool0")


def test_a_500_link_urdf_is_refused_up_front(tmp_path):
    """Pinocchio's createData for 500 joints takes ~30 s at every call (and cannot be
    interrupted): the model is refused when built, naming the count and what to do."""
    n = 500
    links = ['<link name="base"/>'] + [
        f'<link name="l{k}"><inertial><origin xyz="0.1 0 0"/><mass value="1"/><inertia '
        'ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>'
        for k in range(n)]
    parents = ["base"] + [f"l{k}" for k in range(n - 1)]
    joints = [f'<joint name="j{k}" type="revolute"><parent link="{parents[k]}"/>'
              f'<child link="l{k}"/><origin xyz="0.1 0 0"/><axis xyz="0 0 1"/>'
              '<limit lower="-3" upper="3" velocity="5" effort="100"/></joint>' for k in range(n)]
    path = tmp_path / "chain.urdf"
    path.write_text('<?xml version="1.0"?><robot name="chain">' + "".join(links + joints)
                    + "</robot>")
    with pytest.raises(ModelError, match="500 moving joints, more than the 256.*locked_joints"):
        ci.RobotModel.from_urdf(path)

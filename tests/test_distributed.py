"""The compressed problem reduced on Dask equals the single-machine one (4-worker LocalCluster)."""

from __future__ import annotations

import re

import numpy as np
import pytest

import consistid as ci
from consistid.errors import DatasetError, JointCountError, OptionError
from consistid.identification.compression import compress
from consistid.identification.identify import base_parameters_of
from consistid.identification.regressor import RegressorSpec

distributed = pytest.importorskip("distributed")
pytest.importorskip("dask.bag")

from consistid.identification.distributed import DaskData, compress_on_dask, on_dask  # noqa: E402


def runs(model, n, duration=2.0, rate=200.0):
    return [ci.simulate.excitation_run(model, duration=duration, rate=rate, seed=s,
                                       torque_noise=0.05).dataset for s in range(n)]


@pytest.fixture(scope="module")
def ur5():
    return ci.RobotModel.example("ur5")


def test_without_a_client_the_threaded_scheduler_runs_and_says_so(planar_2r):
    """(First in the file: no Client exists yet, so none is current.)"""
    data = runs(planar_2r, 3)
    dask_data = on_dask(data)
    res = ci.identify(planar_2r, dask_data, method="ols")
    assert "threads" in dask_data.scheduler
    ref = ci.identify(planar_2r, data, method="ols")
    np.testing.assert_allclose(res.base_parameters, ref.base_parameters, rtol=1e-10,
                               atol=1e-12 * np.max(np.abs(ref.base_parameters)))


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=4, threads_per_worker=1, processes=False,
                                       dashboard_address=":0")
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


def normal_equations(problem):
    r, z, _ = problem.stacked()
    return r.T @ r, r.T @ z


def test_compressed_problem_equals_the_local_one(client, ur5):
    data = runs(ur5, 9)
    spec = RegressorSpec.make(ur5)
    assert len(client.scheduler_info()["workers"]) == 4
    remote = compress_on_dask(ur5, data, spec, client=client, split_every=2)  # a 4-level tree
    local = compress(ur5, ci.Dataset.concatenate(data), spec)
    assert remote.n_samples == local.n_samples
    for got, want in zip(normal_equations(remote), normal_equations(local)):
        np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-10 * np.max(np.abs(want)))
    # each joint's QR on its independent columns only, as identify runs it, on the workers too
    base = base_parameters_of(ur5, spec)
    remote_b = on_dask(data, client=client, split_every=2).compress(ur5, spec, base)
    local_b = compress(ur5, ci.Dataset.concatenate(data), spec, base=base)
    for got, want in zip(normal_equations(remote_b), normal_equations(local_b)):
        np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-10 * np.max(np.abs(want)))


@pytest.mark.parametrize("method", ["ols", "wls", "sdp"])
def test_identify_on_dask_equals_the_local_answer(client, ur5, tmp_path, method):
    """Files read on the workers; OLS/WLS and both covariances to 1e-10; the SDP solves the same
    program, to its solver's tolerance."""
    data = runs(ur5, 6)
    paths = []
    for k, d in enumerate(data):
        paths.append(tmp_path / f"run{k}.npz")
        d.save(paths[-1])
    dask_data = on_dask(paths, client=client, npartitions=4)
    remote = ci.identify(ur5, dask_data, method=method)
    local = ci.identify(ur5, data, method=method)
    assert dask_data.scheduler.startswith("distributed.Client")
    tol = 1e-10 if method != "sdp" else 1e-6
    np.testing.assert_allclose(remote.base_parameters, local.base_parameters,
                               atol=tol * np.max(np.abs(local.base_parameters)))
    np.testing.assert_allclose(remote.base_covariance, local.base_covariance,
                               rtol=tol, atol=tol * np.max(np.abs(local.base_covariance)))
    np.testing.assert_allclose(remote.details["autocorrelation_time"],
                               local.details["autocorrelation_time"], rtol=1e-10)


def test_the_current_client_is_used_when_none_is_given(client, planar_2r):
    data = on_dask(runs(planar_2r, 2))
    ci.identify(planar_2r, data, method="ols", covariance="iid")
    assert data.scheduler == f"distributed.Client {client.scheduler.address}"
    assert re.match(r"DaskData\(2 partitions", repr(data))


def test_bad_collections_are_named(client, planar_2r, ur5, tmp_path):
    with pytest.raises(DatasetError, match="empty"):
        on_dask([])
    with pytest.raises(DatasetError, match="item 1 is a int"):
        on_dask([runs(planar_2r, 1)[0], 3])
    with pytest.raises(DatasetError, match="pass \\[it\\]"):
        on_dask(runs(planar_2r, 1)[0])
    with pytest.raises(OptionError, match="split_every"):
        on_dask(runs(planar_2r, 1), split_every=1)
    runs(ur5, 1, duration=0.5)[0].save(tmp_path / "ur5.npz")
    with pytest.raises(JointCountError, match="ur5.npz"):
        ci.identify(planar_2r, on_dask([tmp_path / "ur5.npz"], client=client), method="ols")
    assert isinstance(on_dask(runs(planar_2r, 1)), DaskData)
    import dask.bag as db

    with pytest.raises(OptionError, match="on_dask"):   # not computed here by iteration
        ci.identify(planar_2r, db.from_sequence(runs(planar_2r, 2)), method="ols")


def test_excitation_starts_go_to_the_cluster_through_joblib(client, planar_2r):
    """design_excitation(n_jobs=…) under joblib's Dask backend: the starts run as tasks on the
    cluster, and the design is the one made start after start here."""
    import joblib

    kw = dict(harmonics=2, period=4.0, seed=3, n_starts=2, friction=None, n_grid=60,
              n_check=400, max_iter=30)
    here = ci.design_excitation(planar_2r, **kw)
    with distributed.get_task_stream(client) as tasks, joblib.parallel_config(backend="dask"):
        remote = ci.design_excitation(planar_2r, n_jobs=2, **kw)
    assert len(tasks.data) >= 1
    assert [s.value for s in remote.starts] == [s.value for s in here.starts]
    assert remote.best_start == here.best_start
    np.testing.assert_array_equal(remote.starts[remote.best_start].coefficients,
                                  here.starts[here.best_start].coefficients)

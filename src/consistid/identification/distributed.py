r"""The compressed least-squares problem as a reduction on Dask: logs identified where they lie.

A fleet's recordings need not be moved to one machine. Each Dask partition (a few files or
Datasets) is compressed where it is read (per-joint R factors of ``[Y_j | τ_j]``,
:func:`consistid.identification.compression.compress`), and the partial factors are merged up a
tree by QR of the stacked factors (:func:`consistid.identification.streaming.merge`):

.. math::  \bar R_{j} = \operatorname{qr}\begin{bmatrix} \bar R_{j,1} \\ \vdots \\
           \bar R_{j,k} \end{bmatrix}

(the tall-skinny QR reduction of Demmel, Grigori, Hoemmen, Langou 2012, "Communication-optimal
parallel and sequential QR and LU factorizations", SIAM J. Sci. Comput. 34(1),
doi:10.1137/080731992). Only ``nv (p + 1)²`` numbers per partition travel (≈ 60 kB for a Panda
with friction), whatever the length of the logs. The solve (OLS, WLS or the SDP) then runs on
the client as for one machine, and the coloured covariance's residual pass is a second
reduction (autocovariance sums, residual sums of squares and counts add up).

>>> from distributed import Client
>>> client = Client("tcp://scheduler:8786")                     # an existing cluster
>>> res = ci.identify(model, on_dask(paths, client=client, loader=my_s3_loader))

``client``: a ``distributed.Client``; default the current one (``distributed.get_client()``,
e.g. inside ``with Client(...):``), else Dask's configured scheduler, else its threaded one.
:attr:`DaskData.scheduler` records which ran.

Dask is an optional dependency (``pip install "dask[bag]" distributed``), imported when a
reduction first runs.
"""

from __future__ import annotations

import os
from functools import partial
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from ..data.dataset import Dataset
from ..errors import DatasetError, IdentificationError, OptionError
from ..robot.model import RobotModel
from .base import BaseParameters
from .compression import CompressedProblem, compress
from .regressor import RegressorSpec
from .streaming import DataStream, Part, ResidualStatistics, merge_all

#: Default fan-in of the tree reduction (partials merged per node).
SPLIT_EVERY = 8


def _load(part: Part, k: int, model: RobotModel, loader: Callable[[Path], Dataset]) -> Dataset:
    label = f"file {str(part)!r}" if isinstance(part, (str, os.PathLike)) else f"item {k}"
    try:
        data = loader(Path(part)) if isinstance(part, (str, os.PathLike)) else part
        if not isinstance(data, Dataset):
            raise DatasetError(f"is a {type(data).__name__}, not a Dataset or a file")
        data.check_joints(model.nv, model.joint_names)
        data.require_torque()
    except DatasetError as exc:
        raise type(exc)(f"{label} of the Dask collection: {exc}") from exc
    return data


def compress_partition(items: Iterable[Part], model: RobotModel, spec: RegressorSpec,
                       loader: Callable[[Path], Dataset], base: BaseParameters | None = None
                       ) -> CompressedProblem | None:
    """The compressed problem of one partition's files or Datasets (``None`` if empty);
    ``base`` as in :func:`~consistid.identification.compression.compress`."""
    parts = [compress(model, _load(p, k, model, loader), spec, base=base)
             for k, p in enumerate(items)]
    return merge_all(parts) if parts else None


def merge_partials(partials: Iterable[CompressedProblem | None]) -> CompressedProblem | None:
    """One node of the tree: :func:`~consistid.identification.streaming.merge` of the partials
    that hold data."""
    kept = [p for p in partials if p is not None]
    return merge_all(kept) if kept else None


def residual_partition(items: Iterable[Part], model: RobotModel, spec: RegressorSpec,
                       theta: np.ndarray, loader: Callable[[Path], Dataset],
                       base: BaseParameters | None = None,
                       viscous_std: np.ndarray | None = None) -> ResidualStatistics | None:
    """:class:`ResidualStatistics` of ``τ − Y θ`` on one partition (``None`` if empty;
    ``base``: also its rows at rest, ``viscous_std``: σ of the fitted ``f_v``;
    :meth:`ResidualStatistics.of`)."""
    out = None
    for k, p in enumerate(items):
        stats = ResidualStatistics.of(model, spec, theta, _load(p, k, model, loader), base=base,
                                      viscous_std=viscous_std)
        out = stats if out is None else out + stats
    return out


def add_partials(partials: Iterable[ResidualStatistics | None]) -> ResidualStatistics | None:
    kept = [p for p in partials if p is not None]
    if not kept:
        return None
    out = kept[0]
    for p in kept[1:]:
        out = out + p
    return out


class DaskData(DataStream):
    """A Dask collection of recordings for :func:`consistid.identify` (module docstring).

    Build it with :func:`on_dask`. It is re-readable: the coloured covariance runs a second
    reduction. ``scheduler`` names what ran the last reduction.
    """

    def __init__(self, bag: Any, client: Any = None,
                 loader: Callable[[Path], Dataset] | None = None,
                 split_every: int = SPLIT_EVERY) -> None:
        if loader is not None and not callable(loader):
            raise OptionError(f"loader must be a function path → Dataset, got {loader!r:.60}")
        if isinstance(split_every, bool) or not isinstance(split_every, int) or split_every < 2:
            raise OptionError(f"split_every must be an integer ≥ 2, got {split_every!r}")
        self.source = bag
        self.bag = bag
        self.client = client
        self.loader = loader or Dataset.load
        self.split_every = split_every
        self.scheduler = "not run yet"
        self._read = False

    @property
    def rereadable(self) -> bool:
        return True

    def __repr__(self) -> str:
        return (f"DaskData({self.bag.npartitions} partitions, split_every={self.split_every}, "
                f"scheduler: {self.scheduler})")

    def _compute(self, item: Any) -> Any:
        import dask

        client = self.client
        if client is None:
            try:
                from distributed import get_client

                client = get_client()
            except (ImportError, ValueError):
                client = None
        if client is not None:
            self.scheduler = f"distributed.Client {client.scheduler.address}"
            try:
                return client.compute(item).result()
            except Exception as exc:
                if type(exc).__name__ != "KilledWorker":
                    raise
                raise self._killed(exc) from exc
        configured = dask.config.get("scheduler", None)
        self.scheduler = f"dask {configured or 'threads'} scheduler (no distributed.Client)"
        return dask.compute(item, scheduler=configured or "threads")[0]

    def _killed(self, exc: Exception) -> IdentificationError:
        """A ``distributed.KilledWorker`` as an error naming the partition and its files (a
        partition task's key is ``(name, index)``; the partition's items are read back from
        the source bag, which holds the paths, not the data)."""
        task = getattr(exc, "task", exc.args[0] if exc.args else None)
        index = task[1] if isinstance(task, tuple) and len(task) > 1 \
            and isinstance(task[1], int) else None
        items = ""
        if index is not None and index < self.bag.npartitions:
            try:
                held = self.bag.to_delayed()[index].compute(scheduler="sync")
                items = ": " + ", ".join(repr(str(p)) if isinstance(p, (str, os.PathLike))
                                         else type(p).__name__ for p in list(held)[:8])
            except Exception:           # the partition itself cannot be rebuilt here
                items = ""
        where = f"partition {index}{items}" if index is not None else f"task {task!r}"
        worker = getattr(getattr(exc, "last_worker", None), "address", "?")
        tries = getattr(exc, "allowed_failures", "?")
        return IdentificationError(
            f"a Dask worker died while reducing {where} (KilledWorker: last on {worker}, "
            f"{tries} allowed failures; a worker holding several partitions when it died "
            "shares the blame among them, and Dask names one); a file that exhausts a worker's "
            "memory or crashes its reader is the usual cause: read it alone "
            "(consistid.Dataset.load) or give the workers more memory")

    def compress(self, model: RobotModel, spec: RegressorSpec,
                 base: BaseParameters | None = None) -> CompressedProblem:
        """The compressed problem of every partition, merged up a tree of fan-in
        ``split_every`` (``base``: each joint's QR on its independent columns only)."""
        per = partial(compress_partition, model=model, spec=spec, loader=self.loader, base=base)
        problem = self._compute(self.bag.reduction(per, merge_partials,
                                                   split_every=self.split_every))
        if problem is None:
            raise DatasetError("the Dask collection is empty: it holds no Dataset or file")
        return problem

    def residual_statistics(self, model: RobotModel, spec: RegressorSpec,
                            theta: np.ndarray, base: BaseParameters | None = None,
                            viscous_std: np.ndarray | None = None) -> ResidualStatistics:
        per = partial(residual_partition, model=model, spec=spec,
                      theta=np.asarray(theta, dtype=float), loader=self.loader, base=base,
                      viscous_std=viscous_std)
        stats = self._compute(self.bag.reduction(per, add_partials,
                                                 split_every=self.split_every))
        if stats is None:
            raise DatasetError("the Dask collection is empty: it holds no Dataset or file")
        return stats


def on_dask(source: Sequence[Part] | Any, client: Any = None,
            loader: Callable[[Path], Dataset] | None = None,
            partition_size: int | None = None, npartitions: int | None = None,
            split_every: int = SPLIT_EVERY) -> DaskData:
    """Recordings as a Dask collection, for :func:`consistid.identify` and
    :func:`compress_on_dask`.

    Parameters
    ----------
    source : a list of files (read on the workers by ``loader``) and/or Datasets, or a
        ``dask.bag.Bag`` of them (e.g. ``dask.bag.from_delayed`` of your own readers).
    client : a ``distributed.Client``; default the current one, if any (module docstring).
    loader : path → Dataset, run on the workers; default :meth:`Dataset.load`. For object
        storage, e.g. ``lambda p: Dataset.load(fsspec.open_local(f"simplecache::s3://{p}"))``.
    partition_size, npartitions : how a list is cut into partitions (``dask.bag.from_sequence``;
        default one item per partition, so that files are read in parallel).
    split_every : fan-in of the tree reduction.

    Raises
    ------
    DatasetError : an empty list, or one that holds something other than files and Datasets.
    """
    import dask.bag as db

    if isinstance(source, db.Bag):
        bag = source
    else:
        if isinstance(source, (Dataset, str, bytes, os.PathLike)):
            raise DatasetError(f"on_dask takes a list of files or Datasets, got one "
                               f"{type(source).__name__}: pass [it]")
        try:
            items = list(source)
        except TypeError:
            raise DatasetError(f"on_dask takes a list of files or Datasets or a dask.bag.Bag, "
                               f"got {type(source).__name__}") from None
        if not items:
            raise DatasetError("on_dask: the list of files or Datasets is empty")
        for k, item in enumerate(items):
            if not isinstance(item, (Dataset, str, os.PathLike)):
                raise DatasetError(f"on_dask: item {k} is a {type(item).__name__}, not a Dataset "
                                   "or a file")
        if partition_size is None and npartitions is None:
            partition_size = 1
        bag = db.from_sequence(items, partition_size=partition_size, npartitions=npartitions)
    return DaskData(bag, client=client, loader=loader, split_every=split_every)


def compress_on_dask(model: RobotModel, data: DaskData | Sequence[Part],
                     spec: RegressorSpec | None = None, **options: Any) -> CompressedProblem:
    """The compressed problem of a Dask collection (:func:`on_dask` takes ``options``); what
    :func:`consistid.identify` solves. ``spec`` default: :func:`consistid.identify`'s columns
    (Coulomb, viscous, offset)."""
    spec = spec or RegressorSpec.make(model)
    data = data if isinstance(data, DaskData) else on_dask(data, **options)
    return data.compress(model, spec)


__all__ = ["DaskData", "SPLIT_EVERY", "add_partials", "compress_on_dask", "compress_partition",
           "merge_partials", "on_dask", "residual_partition"]

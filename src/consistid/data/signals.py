r"""The signal chain's public face: :func:`preprocess` (a robot log to a
:class:`~consistid.data.dataset.Dataset` and the record of how), and its building blocks.

The blocks live in :mod:`consistid.data.filters` (filters, differentiators, outliers, bandwidth),
:mod:`consistid.data.timestamps` (units, duplicates, gaps, interval-averaged stamps) and
:mod:`consistid.data.resample` (the one resampler); the chain itself, which returns arrays, is
:mod:`consistid.data.chain` (its docstring lists the steps in order). They are re-exported here,
the signal chain's one public face.
:meth:`Dataset.from_recording` is :func:`preprocess` without the record.
"""

from __future__ import annotations

import html
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .chain import DERIVATIVES, TRIM_PERIODS, ChainResult, PreprocessOptions, Step, run_chain
from .dataset import Dataset
from .filters import (
    CUTOFF_FACTOR,
    MAX_CUTOFF_FRACTION,
    PAD_PERIODS,
    central_difference,
    default_cutoff,
    estimate_bandwidth,
    fourier_derivatives,
    hampel,
    low_speed_mask,
    lowpass,
    period_average,
    samples_per_period,
    savgol_cutoff,
    savgol_derivatives,
    savgol_window,
    stuck_samples,
)
from .resample import resample, supported_rate, to_uniform, uniform_grid
from .timestamps import duplicate_groups, group_mean, interval_centres, long_steps

__all__ = [
    "CUTOFF_FACTOR", "DERIVATIVES", "MAX_CUTOFF_FRACTION", "PAD_PERIODS", "TRIM_PERIODS",
    "ChainResult", "PreprocessOptions", "Preprocessed", "Step", "central_difference",
    "default_cutoff", "duplicate_groups", "estimate_bandwidth", "fourier_derivatives",
    "group_mean", "hampel", "interval_centres", "long_steps", "low_speed_mask", "lowpass",
    "period_average", "preprocess", "resample", "samples_per_period", "savgol_cutoff",
    "savgol_derivatives", "savgol_window", "stuck_samples", "supported_rate", "to_uniform",
    "uniform_grid",
]


@dataclass(frozen=True)
class Preprocessed:
    """The dataset made from a recording, and the record of how.

    Attributes
    ----------
    dataset : the :class:`Dataset` (one segment per gap-free stretch of the log).
    steps : the :class:`Step` s applied, in order.
    rate : sampling rate of the dataset (Hz), after resampling/decimation.
    cutoff : the cut-off identification sees (Hz): where ``τ`` and every column of ``Y`` are
        low-passed alike (``dataset.identification_filter``, parallel filtering), or, when
        there is none, :attr:`derivative_cutoff`.
    bandwidth : excitation bandwidth used to choose it (Hz; given or estimated), or ``None``
        when the cut-off was given.
    options : the :class:`PreprocessOptions` used.
    derivative_cutoff : the cut-off of the low-pass on ``q`` (then differentiated) and ``τ``
        (Hz; ``dataset.torque_filter``); default :attr:`cutoff`.
    """

    dataset: Dataset
    steps: tuple[Step, ...]
    rate: float
    cutoff: float
    bandwidth: float | None
    options: PreprocessOptions
    derivative_cutoff: float | None = None

    def __post_init__(self) -> None:
        if self.derivative_cutoff is None:
            object.__setattr__(self, "derivative_cutoff", self.cutoff)

    def __str__(self) -> str:
        return self.summary()

    def summary(self) -> str:
        """The result's size and rate, and one numbered line per step applied."""
        lines = [f"{len(self.steps)} steps → {self.dataset.n_samples} samples, "
                 f"{len(np.unique(self.dataset.segment))} segment(s) at {self.rate:.6g} Hz"]
        lines += [f"  {i + 1}. {s}" for i, s in enumerate(self.steps)]
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        items = "".join(f"<li><b>{html.escape(s.name)}</b>: {html.escape(s.detail)}</li>"
                        for s in self.steps)
        return (f"<p>{self.dataset.n_samples} samples, "
                f"{len(np.unique(self.dataset.segment))} segment(s) at {self.rate:.6g} Hz</p>"
                f"<ol>{items}</ol>")


def preprocess(t: np.ndarray, q: np.ndarray, tau: np.ndarray, *,
               joint_names: Sequence[str] | None = None, **options: object) -> Preprocessed:
    """Turn a log ``(t, q, τ)`` into a :class:`Dataset` by the chain of
    :mod:`consistid.data.chain`; ``options`` are the fields of :class:`PreprocessOptions`
    (``derivative``, ``cutoff``, ``bandwidth``, ``rate``, ``gap``, ``timestamp``,
    ``time_unit``, …; an unknown name raises :class:`~consistid.errors.OptionError`).

    Returns
    -------
    Preprocessed
        ``.dataset``, and ``.steps``: what was done (also logged at INFO level on the
        ``consistid.data.chain`` logger).
    """
    res = run_chain(t, q, tau, PreprocessOptions.from_kwargs(options))
    return Preprocessed(Dataset.from_chain(res, joint_names), res.steps, res.rate, res.cutoff,
                        res.bandwidth, res.options, res.derivative_cutoff)

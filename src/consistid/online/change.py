r"""Change detection on the whitened innovation of a recursive estimator.

Before sample ``k`` updates the estimate, its innovation ``e_k = τ_k − W_k β̂_{k−1}`` has, while
the robot does not change, zero mean and covariance ``S_k = W_k P_{k−1} W_kᵀ + Σ`` (the Kalman
innovation, :mod:`consistid.online.rls`), so

.. math::  \chi^2_k = e_k^\top S_k^{-1} e_k \;\sim\; \chi^2(n_v)

independently from sample to sample (the innovations of a correctly specified recursive least
squares are white: Ljung & Söderström, *Theory and Practice of Recursive Identification*, MIT
Press 1983, §2.2; the whiteness test of Mehra & Peschon 1971, Automatica 7(5),
doi:10.1016/0005-1098(71)90028-8). A step change of the dynamics (a payload grasped) makes the
innovation's mean non-zero and ``χ²_k`` large. Two tests, both ``O(1)`` per sample:

:class:`WindowedChiSquare`
    ``Σ_{i=k−w+1}^{k} χ²_i ~ χ²(n_v w)``; flags when it exceeds the ``1 − α`` quantile. With
    ``α`` the false-alarm probability of one test, ``n`` tests flag falsely with probability at
    most ``n α`` (Bonferroni): the default ``α = 10⁻⁹`` gives ≤ 6·10⁻⁵ over a minute at 1 kHz.
:class:`Cusum`
    Page's cumulative sum (Page 1954, "Continuous inspection schemes", Biometrika 41,
    doi:10.1093/biomet/41.1-2.100) of the standardised excess
    ``g_k = max(0, g_{k−1} + (χ²_k − n_v)/√(2 n_v) − ν)``, flagging when ``g_k > h``;
    Basseville & Nikiforov, *Detection of Abrupt Changes*, Prentice Hall 1993, §2.2.

After a flag a detector starts afresh (its window or sum is emptied) and tests again once it has
seen ``window`` (CUSUM: ``refractory``) new samples, so one change is flagged once while the
estimator adapts to it.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
import scipy.stats

from ..errors import OptionError, check_number

#: Default window (samples) of :class:`WindowedChiSquare`.
DEFAULT_WINDOW = 50
#: Default false-alarm probability of one windowed test.
DEFAULT_FALSE_ALARM = 1e-9


class ChangeDetector(Protocol):
    """What :class:`~consistid.online.rls.RecursiveEstimator` needs from a detector."""

    threshold: float

    def step(self, chi2: float, dof: int) -> tuple[bool, float]:
        """Take one sample's ``χ²`` (with ``dof`` degrees of freedom); return ``(flag,
        statistic)``."""
        ...

    def reset(self) -> None:
        """Forget the samples seen (after a flag, or when the estimate was reset)."""
        ...


class WindowedChiSquare:
    """Sum of the last ``window`` per-sample ``χ²`` against its ``1 − false_alarm`` quantile.

    Parameters
    ----------
    window : samples per test (≥ 1).
    false_alarm : probability that one test flags while nothing changed (0 < α < 1).

    Attributes
    ----------
    threshold : the quantile for the degrees of freedom of the last test (computed once per
        ``dof``; ``nan`` before the first sample).
    """

    def __init__(self, window: int = DEFAULT_WINDOW,
                 false_alarm: float = DEFAULT_FALSE_ALARM) -> None:
        self.window = check_number("window", window, 1, integer=True)
        self.false_alarm = check_number("false_alarm", false_alarm, 0, strict=True)
        if self.false_alarm >= 1:
            raise OptionError(f"false_alarm must lie in (0, 1), got {false_alarm!r}")
        self._buffer = np.zeros(self.window)
        self._quantiles: dict[int, float] = {}
        self.threshold = float("nan")
        self.reset()

    def reset(self) -> None:
        self._buffer[:] = 0.0
        self._sum = 0.0
        self._count = 0

    def _quantile(self, dof: int) -> float:
        if dof not in self._quantiles:
            self._quantiles[dof] = float(scipy.stats.chi2.isf(self.false_alarm,
                                                              dof * self.window))
        return self._quantiles[dof]

    def step(self, chi2: float, dof: int) -> tuple[bool, float]:
        slot = self._count % self.window
        self._sum += chi2 - self._buffer[slot]
        self._buffer[slot] = chi2
        self._count += 1
        if self._count % 4096 == 0:          # no drift of the running sum
            self._sum = float(np.sum(self._buffer))
        self.threshold = self._quantile(dof)
        if self._count < self.window:
            return False, self._sum
        return self._sum > self.threshold, self._sum

    def __repr__(self) -> str:
        return f"WindowedChiSquare(window={self.window}, false_alarm={self.false_alarm:g})"


class Cusum:
    r"""Page's CUSUM of the standardised ``χ²`` excess (module docstring).

    Parameters
    ----------
    drift : ``ν``, subtracted per sample (standard deviations of ``χ²``); smaller reacts to
        smaller changes and flags falsely more often.
    threshold : ``h``.
    refractory : samples after a flag (or a reset) before the next test.
    """

    def __init__(self, drift: float = 1.0, threshold: float = 40.0,
                 refractory: int = DEFAULT_WINDOW) -> None:
        self.drift = check_number("drift", drift, 0, strict=True)
        self.threshold = check_number("threshold", threshold, 0, strict=True)
        self.refractory = check_number("refractory", refractory, 0, integer=True)
        self.reset()

    def reset(self) -> None:
        self._g = 0.0
        self._count = 0

    def step(self, chi2: float, dof: int) -> tuple[bool, float]:
        self._g = max(0.0, self._g + (chi2 - dof) / np.sqrt(2.0 * dof) - self.drift)
        self._count += 1
        return self._count > self.refractory and self._g > self.threshold, self._g

    def __repr__(self) -> str:
        return (f"Cusum(drift={self.drift:g}, threshold={self.threshold:g}, "
                f"refractory={self.refractory})")

"""Logs as real loggers write them: stamps that jitter, joints that barely move, coloured
position noise and encoder counts, for checking the signal chain (:mod:`consistid.data.chain`)
on what it meets on real robots.

:func:`burst_stamps`
    a logger that writes in bursts: samples taken every ``1 / rate`` s, stamped on arrival after
    a delay drawn uniformly from ``[0, max_delay]`` and at least ``min_step`` after the stamp
    before (at 1 kHz with the defaults: steps from 0.5 to ~5 ms).
:func:`jittered_log`
    the positions of a trajectory so stamped, its last joint's motion scaled about its mean to
    ``slow`` (default 2 %) of its own amplitude — not of the joint's range: a joint that barely
    moves — with position noise (white or AR(1) with φ = 0.95) and encoder counts.
"""

from __future__ import annotations

import numpy as np
import scipy.signal

from ..errors import OptionError, check_number
from .experiments import DesiredMotion

#: AR(1) coefficient of the coloured position noise of :func:`jittered_log`.
AR1_PHI = 0.95


def burst_stamps(n: int, rng: np.random.Generator, rate: float = 1000.0,
                 max_delay: float = 4e-3, min_step: float = 0.5e-3
                 ) -> tuple[np.ndarray, np.ndarray]:
    """``(true sample times, stamps)`` of ``n`` samples taken every ``1 / rate`` s and stamped
    on arrival, ``max(stamp_{k−1} + min_step, t_k + U(0, max_delay))``."""
    t = np.arange(n) / rate
    arrival = t + rng.uniform(0.0, max_delay, n)
    stamps = np.empty(n)
    stamps[0] = arrival[0]
    for k in range(1, n):
        stamps[k] = max(stamps[k - 1] + min_step, arrival[k])
    return t, stamps


def jittered_log(motion: DesiredMotion, rng: np.random.Generator, noise: str = "white",
                 n: int = 30000, noise_std: float = 2e-4, counts: int = 2 ** 17,
                 slow: float = 0.02) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(true times, stamps, positions)`` of ``motion`` sampled at 1 kHz and stamped in bursts
    (:func:`burst_stamps`), with position noise of ``noise_std`` rad (``"white"``, or
    ``"ar1"``: white noise through ``√(1 − φ²) / (1 − φ z⁻¹)``, φ = :data:`AR1_PHI`, started
    at rest) and rounded to ``2π / counts``. The true motion of the last joint is the motion's
    own scaled about its mean, ``q̄ + slow (q − q̄)`` (``q̄`` its mean over the log; ``slow ≥ 0``;
    1: unchanged); ``n ≥ 1`` samples.

    Raises :class:`~consistid.errors.OptionError` naming ``noise``, ``n`` or ``slow`` when
    out of range."""
    if noise not in ("white", "ar1"):
        raise OptionError(f"noise = {noise!r}; it is 'white' or 'ar1'")
    n = check_number("n", n, 1, integer=True)
    slow = check_number("slow", slow, 0)
    t, stamps = burst_stamps(n, rng)
    q = motion.evaluate(t)[0]
    q[:, -1] = q[:, -1].mean() + slow * (q[:, -1] - q[:, -1].mean())
    e = noise_std * rng.standard_normal(q.shape)
    if noise == "ar1":
        e = scipy.signal.lfilter([np.sqrt(1 - AR1_PHI ** 2)], [1.0, -AR1_PHI], e, axis=0)
    step = 2 * np.pi / counts
    return t, stamps, np.round((q + e) / step) * step

r"""Excitation trajectories.

Finite Fourier series per joint (Swevers, Ganseman, Tükel, De Schutter, Van Brussel 1997,
"Optimal robot excitation and identification", IEEE T-RA 13(5), doi:10.1109/70.631234):

.. math::

    q_j(t) = q_{0,j} + \sum_{l=1}^{H} \frac{a_{jl}}{\omega_f l}\sin(\omega_f l t)
                                    - \frac{b_{jl}}{\omega_f l}\cos(\omega_f l t)

with analytic velocity and acceleration; the trajectory is periodic with period ``2π/ω_f``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .dataset import Dataset
from .model import RobotModel

#: Default acceleration bound (rad/s²) when a model has none: URDFs carry no acceleration limits.
DEFAULT_ACCELERATION_LIMIT = 10.0


@dataclass(frozen=True)
class FourierTrajectory:
    """A periodic joint trajectory ``q(t)`` as a finite Fourier series.

    Attributes
    ----------
    a, b : (nv, H) sine and cosine coefficients (rad/s).
    q0 : (nv,) offsets (rad).
    period : seconds, ``2π/ω_f``.
    """

    a: np.ndarray
    b: np.ndarray
    q0: np.ndarray
    period: float

    @property
    def omega(self) -> float:
        return 2.0 * np.pi / self.period

    @property
    def harmonics(self) -> int:
        return int(self.a.shape[1])

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(q, dq, ddq)`` at times ``t`` (s), each (len(t), nv)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        w = self.omega * np.arange(1, self.harmonics + 1)          # (H,)
        s, c = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))       # (N, H)
        q = self.q0 + (s / w) @ self.a.T - (c / w) @ self.b.T
        dq = c @ self.a.T + s @ self.b.T
        ddq = -(s * w) @ self.a.T + (c * w) @ self.b.T
        return q, dq, ddq

    def sample(self, rate: float, duration: float | None = None, t0: float = 0.0) -> Dataset:
        """The trajectory sampled at ``rate`` Hz over ``duration`` s (default one period)."""
        duration = self.period if duration is None else duration
        t = t0 + np.arange(int(round(duration * rate))) / rate
        q, dq, ddq = self.evaluate(t)
        return Dataset(t=t, q=q, dq=dq, ddq=ddq)

    @classmethod
    def random(cls, model: RobotModel, harmonics: int = 5, period: float = 10.0,
               seed: int | np.random.Generator = 0, amplitude: float = 0.8,
               acceleration_limit: float | np.ndarray = DEFAULT_ACCELERATION_LIMIT
               ) -> "FourierTrajectory":
        """Random coefficients, scaled per joint to use ``amplitude`` of the position range,
        velocity limit and acceleration limit (whichever binds first), centred in the range.

        Unbounded joints are treated as having the range ±π.
        """
        rng = np.random.default_rng(seed)
        lim = model.limits
        lo = np.where(np.isfinite(lim.lower), lim.lower, -np.pi)
        hi = np.where(np.isfinite(lim.upper), lim.upper, np.pi)
        a = rng.standard_normal((model.nv, harmonics))
        b = rng.standard_normal((model.nv, harmonics))
        q0 = 0.5 * (lo + hi)
        trial = cls(a, b, np.zeros(model.nv), period)
        q, dq, ddq = trial.evaluate(np.linspace(0.0, period, 50 * harmonics * 4, endpoint=False))
        vel = np.where(lim.velocity > 0, lim.velocity, np.inf)
        acc = np.broadcast_to(np.asarray(acceleration_limit, dtype=float), (model.nv,))
        scale = amplitude * np.minimum.reduce([
            0.5 * (hi - lo) / np.max(np.abs(q), axis=0),
            vel / np.max(np.abs(dq), axis=0),
            acc / np.max(np.abs(ddq), axis=0)])
        return cls(a * scale[:, None], b * scale[:, None], q0, period)

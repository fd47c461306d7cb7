r"""Where the training data went: the per-joint envelope a result remembers, and the departures
of new data from it.

An identified model is a fit over the states it saw. Outside them it extrapolates, and how well
depends on directions the training data may not inform at all: a joint that moved one way only
cannot tell its Coulomb friction ``f_c sign(q̇)`` from its offset ``f_o`` (the two columns are
equal on every training sample), so its prediction for the other direction is whatever the
prior or the solver left in ``f_c − f_o``. The envelope records, per joint, the position range,
the velocity signs seen with enough samples (:func:`sign_seen`), and the largest ``|q̇|`` and
``|q̈|``; :meth:`TrainingEnvelope.departures` names where new data leave it (a sign never seen,
a range exceeded by more than :data:`RANGE_MARGIN` of its width, in at least
:func:`enough` samples), which ``predict`` turns into an
:class:`~consistid.errors.ExtrapolationWarning`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from ..data.dataset import Dataset
from ..robot.joint_terms import STANDSTILL_SPEED

__all__ = ["TrainingEnvelope", "enough", "sign_seen"]

#: A velocity sign counts as seen when at least this share of the joint's moving samples have
#: it (and at least :data:`MIN_SAMPLES`): a few samples decide nothing when the residual near a
#: reversal is dominated by stiction, which ``f_c sign(q̇)`` does not model.
MIN_SIGN_SHARE = 0.01
#: ... and at least this many samples (one stroke of a few ms at 1 kHz is not a reversal).
MIN_SAMPLES = 10
#: New data leave a range (position, |q̇|, |q̈|) when they exceed it by more than this share of
#: its width (position) or of its bound (|q̇|, |q̈|): noise on the edges is not extrapolation.
RANGE_MARGIN = 0.1


def enough(count: np.ndarray, total: np.ndarray | int) -> np.ndarray:
    """``count ≥ max(MIN_SAMPLES, MIN_SIGN_SHARE · total)``, elementwise."""
    return np.asarray(count) >= np.maximum(MIN_SAMPLES, MIN_SIGN_SHARE * np.asarray(total))


def sign_seen(positive: np.ndarray, negative: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per joint: did the data move it with ``q̇ > 0``, with ``q̇ < 0``, in enough of its moving
    samples (:func:`enough`; moving: ``|q̇| ≥ STANDSTILL_SPEED``,
    :data:`consistid.robot.joint_terms.STANDSTILL_SPEED`)?"""
    moving = np.asarray(positive) + np.asarray(negative)
    return enough(positive, moving), enough(negative, moving)


def _counts(dq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return (np.sum(dq >= STANDSTILL_SPEED, axis=0), np.sum(dq <= -STANDSTILL_SPEED, axis=0))


@dataclass(frozen=True, eq=False)
class TrainingEnvelope:
    """Per joint (arrays of length ``nv``, named by ``joint_names``): position range
    ``[q_min, q_max]`` (rad/m), the samples moving with ``q̇ > 0`` (``positive``) and
    ``q̇ < 0`` (``negative``), and the largest ``|q̇|``, ``|q̈|``; ``n_samples`` in all."""

    joint_names: tuple[str, ...]
    q_min: np.ndarray
    q_max: np.ndarray
    dq_max: np.ndarray
    ddq_max: np.ndarray
    positive: np.ndarray
    negative: np.ndarray
    n_samples: int

    @classmethod
    def of(cls, dataset: Dataset, joint_names: Sequence[str] | None = None
           ) -> "TrainingEnvelope":
        """The envelope of a dataset (one pass over its arrays); ``joint_names`` (the model's)
        name the joints, else the dataset's own names or ``joint 1..n``."""
        names = joint_names or dataset.joint_names or tuple(f"joint {j + 1}"
                                                            for j in range(dataset.nv))
        return cls.of_states(dataset.q, dataset.dq, dataset.ddq, names)

    @classmethod
    def of_states(cls, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray,
                  joint_names: Sequence[str]) -> "TrainingEnvelope":
        """The envelope of ``(N, nv)`` state arrays (an online estimator's samples)."""
        pos, neg = _counts(dq)
        return cls(tuple(joint_names), q.min(axis=0), q.max(axis=0), np.abs(dq).max(axis=0),
                   np.abs(ddq).max(axis=0), pos, neg, int(q.shape[0]))

    def __add__(self, other: "TrainingEnvelope") -> "TrainingEnvelope":
        """The envelope of two data sets together (ranges joined, sign counts summed): a
        stream's, part by part."""
        return TrainingEnvelope(
            self.joint_names, np.minimum(self.q_min, other.q_min),
            np.maximum(self.q_max, other.q_max), np.maximum(self.dq_max, other.dq_max),
            np.maximum(self.ddq_max, other.ddq_max), self.positive + other.positive,
            self.negative + other.negative, self.n_samples + other.n_samples)

    def one_way(self) -> list[tuple[int, str]]:
        """``(joint, "q̇ > 0" | "q̇ < 0")`` for each joint that moved, but one way only: the
        other sign not :func:`sign_seen`."""
        pos, neg = sign_seen(self.positive, self.negative)
        return [(j, "q̇ > 0" if pos[j] else "q̇ < 0") for j in range(self.q_min.size)
                if pos[j] != neg[j]]

    def describe_one_way(self, joint: int) -> str:
        """``"<joint> moves one way only in these data (q̇ > 0; 3 of 14000 moving samples
        with q̇ < 0)"``."""
        pos, neg = int(self.positive[joint]), int(self.negative[joint])
        up = pos >= neg
        return (f"{self.joint_names[joint]} moves one way only in these data "
                f"({'q̇ > 0' if up else 'q̇ < 0'}; {neg if up else pos} of {pos + neg} moving "
                f"samples with {'q̇ < 0' if up else 'q̇ > 0'})")

    def departures(self, dataset: Dataset) -> list[str]:
        """Where ``dataset`` goes that the training data never went (module docstring), one
        sentence per joint and kind; empty when it stays inside."""
        out = []
        seen_pos, seen_neg = sign_seen(self.positive, self.negative)
        pos, neg = _counts(dataset.dq)
        moving = pos + neg
        width = self.q_max - self.q_min
        for j, name in enumerate(self.joint_names):
            for count, seen, sign in ((pos[j], seen_pos[j], "q̇ > 0"),
                                      (neg[j], seen_neg[j], "q̇ < 0")):
                if not seen and enough(count, moving[j]):
                    trained = self.positive[j] if sign == "q̇ > 0" else self.negative[j]
                    out.append(f"{name} moves with {sign} in {int(count)} samples; the training "
                               f"data moved it that way in {int(trained)}")
            q = dataset.q[:, j]
            low = q < self.q_min[j] - RANGE_MARGIN * width[j]
            high = q > self.q_max[j] + RANGE_MARGIN * width[j]
            if enough(np.sum(low | high), q.size):
                out.append(f"{name} goes to q ∈ [{q.min():.3g}, {q.max():.3g}] beyond the "
                           f"trained [{self.q_min[j]:.3g}, {self.q_max[j]:.3g}] in "
                           f"{int(np.sum(low | high))} samples")
            for field, bound, unit in (("dq", self.dq_max[j], "|q̇|"),
                                       ("ddq", self.ddq_max[j], "|q̈|")):
                v = np.abs(getattr(dataset, field)[:, j])
                over = v > (1 + RANGE_MARGIN) * bound
                if enough(np.sum(over), v.size):
                    out.append(f"{name} reaches {unit} = {v.max():.3g} beyond the trained "
                               f"{bound:.3g} in {int(np.sum(over))} samples")
        return out

    def to_dict(self) -> dict[str, Any]:
        """Plain lists and numbers (for the result file)."""
        return {"joint_names": list(self.joint_names), "n_samples": self.n_samples,
                **{k: np.asarray(getattr(self, k)).tolist() for k in
                   ("q_min", "q_max", "dq_max", "ddq_max", "positive", "negative")}}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "TrainingEnvelope":
        """The inverse of :meth:`to_dict`."""
        arrays = {k: np.asarray(d[k], dtype=float) for k in ("q_min", "q_max", "dq_max",
                                                              "ddq_max")}
        counts = {k: np.asarray(d[k], dtype=int) for k in ("positive", "negative")}
        return cls(tuple(d["joint_names"]), **arrays, **counts, n_samples=int(d["n_samples"]))

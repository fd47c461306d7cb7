r"""Held-out scoring of torque models, and fixed (not identified) models as baselines.

Scores of a prediction ``τ̂`` against measured torques ``τ`` (``N`` samples, ``n`` joints):

.. math::

    e_j = \frac{\|\tau_{:,j} - \hat\tau_{:,j}\|}{\|\tau_{:,j}\|}, \qquad
    e = \frac{\|\tau - \hat\tau\|_F}{\|\tau\|_F}, \qquad
    \mathrm{RMS}_j = \sqrt{\tfrac1N \textstyle\sum_k (\tau_{kj} - \hat\tau_{kj})^2}

(relative errors as in Bethge et al.'s FloBaRoID and Jovic et al. 2016; the total relative error
weighs joints by their torque, so the large gravity-loaded joints dominate it, and the per-joint
figures are needed to see the small ones).

A :class:`FixedModel` predicts with given parameters: the rigid-body torque of a
:class:`~consistid.RobotModel`'s own inertias (``pinocchio.rnea``) plus per-joint terms
(:mod:`consistid.regressor` columns: Coulomb, viscous, offset, armature). It is how a URDF — a
CAD model, or another tool's identified model — is evaluated the same way as an identification
result. :func:`refit_joint_terms` fits only the per-joint terms by least squares on training data,
keeping the rigid body fixed: the fair way to compare a rigid model whose friction and offsets
were not exported.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Protocol, Sequence

import numpy as np

from ..data.dataset import Dataset
from ..errors import DatasetError, ModelError
from ..robot.model import RobotModel
from ..robot.inertia import ConsistencyReport, is_physically_consistent
from .regressor import DEFAULT_FRICTION, TERM_COLUMNS, FrictionArg, RegressorSpec, joint_columns
from .summary import table
from ..robot.urdf import JointDynamics


class Predictor(Protocol):
    """Anything that predicts joint torques for a dataset (results, fixed models)."""

    def predict(self, dataset: Dataset) -> np.ndarray: ...


@dataclass(frozen=True, eq=False)
class TorqueScores:
    """How well a prediction matches measured torques (module docstring for the formulas).

    Attributes
    ----------
    label : what was scored.
    joint_names : (n,) names.
    relative_error : (n,) per-joint relative error ``e_j`` (fraction, not %).
    total_relative_error : ``e`` over all joints.
    rms : (n,) per-joint residual RMS (N·m).
    total_rms : RMS over all joints and samples (N·m).
    n_samples : ``N``.
    """

    label: str
    joint_names: tuple[str, ...]
    relative_error: np.ndarray
    total_relative_error: float
    rms: np.ndarray
    total_rms: float
    n_samples: int


def score_prediction(predicted: np.ndarray, dataset: Dataset, label: str = "",
                     joint_names: Sequence[str] | None = None) -> TorqueScores:
    """Scores of predicted torques ``(N, n)`` against ``dataset.tau``."""
    tau = dataset.require_torque()
    predicted = np.asarray(predicted, dtype=float)
    if predicted.shape != tau.shape:
        raise DatasetError(f"prediction has shape {predicted.shape}; the dataset's torques have "
                           f"{tau.shape}")
    r = tau - predicted
    names = tuple(joint_names or dataset.joint_names or
                  (f"joint{j + 1}" for j in range(dataset.nv)))
    norms = np.linalg.norm(tau, axis=0)
    return TorqueScores(label, names,
                        np.linalg.norm(r, axis=0) / np.where(norms > 0, norms, np.nan),
                        float(np.linalg.norm(r) / np.linalg.norm(tau)),
                        np.sqrt(np.mean(r ** 2, axis=0)), float(np.sqrt(np.mean(r ** 2))),
                        dataset.n_samples)


def score(predictor: Predictor, dataset: Dataset, label: str = "") -> TorqueScores:
    """Scores of ``predictor.predict(dataset)`` (an identification result or a fixed model)."""
    names = getattr(getattr(predictor, "model", None), "joint_names", None)
    return score_prediction(predictor.predict(dataset), dataset,
                            label or getattr(predictor, "label", "") or type(predictor).__name__,
                            joint_names=names)


def scores_table(scores: Sequence[TorqueScores], percent: bool = True) -> str:
    """One row per scored model: per-joint and total relative error (%), then per-joint and
    total RMS (N·m)."""
    if not scores:
        return ""
    nv = len(scores[0].joint_names)
    f = 100.0 if percent else 1.0
    unit = "%" if percent else ""
    header = (["model"] + [f"e{j + 1}{unit}" for j in range(nv)] + [f"e{unit}"]
              + [f"rms{j + 1}" for j in range(nv)] + ["rms"])
    rows = [[s.label, *(f * s.relative_error), f * s.total_relative_error, *s.rms, s.total_rms]
            for s in scores]
    return table(header, rows, floatfmt=".3g")


@dataclass(frozen=True, eq=False)
class FixedModel:
    """A torque model with given parameters: ``τ̂ = rnea(q, q̇, q̈) + C(q̇, q̈) φ``.

    Attributes
    ----------
    model : the robot, whose own inertias give the rigid-body torque.
    spec : which per-joint columns ``C`` (:class:`~consistid.RegressorSpec`) carry ``φ``.
    joint_parameters : (spec.n_joint_columns,) ``φ``, named by :attr:`parameter_names`.
    label : a name for tables.
    joint_std : (spec.n_joint_columns,) standard deviations of ``φ`` when it was fitted.
    """

    model: RobotModel
    spec: RegressorSpec
    joint_parameters: np.ndarray
    label: str = ""
    joint_std: np.ndarray | None = None

    @property
    def parameter_names(self) -> list[str]:
        return self.spec.joint_column_names(self.model.joint_names)

    @property
    def consistency(self) -> ConsistencyReport:
        """Physical consistency of the model's own inertias (pseudo-inertia level)."""
        return is_physically_consistent(self.model.prior_parameters, "pseudo-inertia",
                                        self.model.body_names)

    def predict(self, dataset: Dataset) -> np.ndarray:
        """Predicted joint torques, (N, n)."""
        dataset.check_joints(self.model.nv, self.model.joint_names)
        tau = self.model.rnea(dataset.q, dataset.dq, dataset.ddq)
        if self.spec.n_joint_columns:
            tau = tau + joint_columns(dataset.q, dataset.dq, dataset.ddq,
                                      self.spec) @ self.joint_parameters
        return tau


def rigid_model(model: RobotModel, label: str = "") -> FixedModel:
    """The model's rigid-body dynamics alone (no friction, no offset)."""
    return FixedModel(model, RegressorSpec.make(model, friction=None), np.zeros(0),
                      label or f"{model.name} (rigid)")


def with_urdf_friction(model: RobotModel, dynamics: Mapping[str, JointDynamics],
                       label: str = "") -> FixedModel:
    """The rigid model plus the URDF's ``<dynamics>`` friction: ``f_c = friction``,
    ``f_v = damping`` (:mod:`consistid.robot.urdf`); every joint of the model needs a tag."""
    missing = [j for j in model.joint_names if j not in dynamics]
    if missing:
        raise ModelError(f"joints {missing} of {model.name} have no <dynamics> tag; tags exist "
                         f"for {list(dynamics)}")
    spec = RegressorSpec.make(model, friction=("coulomb", "viscous"))
    phi = np.concatenate([[dynamics[j].friction for j in model.joint_names],
                          [dynamics[j].damping for j in model.joint_names]])
    return FixedModel(model, spec, phi, label or f"{model.name} + URDF friction")


def refit_joint_terms(model: RobotModel, dataset: Dataset,
                      friction: FrictionArg = DEFAULT_FRICTION,
                      armature: bool | Sequence[int | str] = False,
                      label: str = "") -> FixedModel:
    r"""Fit only the per-joint terms, keeping the model's rigid body fixed.

    Joint ``j``'s columns act on joint ``j`` alone, so each joint is an independent least-squares
    problem ``min ‖C_j φ_j − (τ_j − rnea_j)‖²`` with standard deviations from
    ``σ_j² (C_jᵀC_j)⁻¹``, ``σ_j² = ‖ρ_j‖² / (N − c_j)`` (Gautier & Khalil 1990).

    Raises :class:`ModelError` when a joint's columns are rank deficient on the data (e.g. a
    joint that never moves cannot separate Coulomb friction from offset).
    """
    spec = RegressorSpec.make(model, friction, armature)
    tau = dataset.require_torque() - model.rnea(dataset.q, dataset.dq, dataset.ddq)
    cols = joint_columns(dataset.q, dataset.dq, dataset.ddq, spec)
    phi = np.zeros(spec.n_joint_columns)
    std = np.zeros(spec.n_joint_columns)
    names = spec.joint_column_names(model.joint_names)
    for j in range(model.nv):
        own = np.array([c for c, (_, joint, _) in enumerate(spec.columns) if joint == j],
                       dtype=int)
        if own.size == 0:
            continue
        a = cols[:, j, own]
        coef, _, rank, _ = np.linalg.lstsq(a, tau[:, j], rcond=None)
        if rank < own.size:
            raise ModelError(f"joint {model.joint_names[j]!r}: the data cannot separate "
                             f"{[names[c] for c in own]} (rank {rank} of {own.size})")
        rho = tau[:, j] - a @ coef
        sigma2 = float(rho @ rho) / max(dataset.n_samples - own.size, 1)
        phi[own] = coef
        std[own] = np.sqrt(np.diag(sigma2 * np.linalg.inv(a.T @ a)))
    terms = ",".join(",".join(TERM_COLUMNS[t]) for t, m in spec.masks if any(m))
    return FixedModel(model, spec, phi, label or f"{model.name} + refit {terms}", std)

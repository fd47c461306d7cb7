r"""Identification with the motor-side terms of a coupled transmission.

The torque model is the rigid-body and per-joint model of
:mod:`consistid.identification.regressor` plus the coupled motors' columns ``C ζ``
(:mod:`consistid.drives.motor_terms`: rotor inertia, viscous and Coulomb friction of each
motor that drives several joints, e.g. ``Iam6, fvm6, fsm6`` of a TX40 wrist):

.. math::  τ = W_b β + C ζ + ε .

``ζ`` is estimated with ``β`` by weighted least squares on ``[W_b | C]`` (Gautier 1997, per-joint
weights from the OLS residual), with its covariance; then the dynamic parameters are identified
by :func:`consistid.identify` (the consistent SDP by default) on ``τ − C ζ̂``: the SDP's
estimate is conditional on ``ζ̂`` (the coupled terms have no consistency constraint of their own
beyond their sign, which the result reports). Without ``C``, a coupled motor's inertia and
friction are absorbed by the joints' own armature and friction columns, which cannot carry the
cross terms: the residual stays above the noise floor on the coupled joints.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ..data.dataset import Dataset, as_dataset
from ..errors import OptionError, PoorExcitationError
from ..identification.base import RANK_RTOL
from ..identification.identify import base_parameters_of, identify
from ..identification.regressor import DEFAULT_FRICTION, FrictionArg, RegressorSpec, regressor
from ..identification.result import IdentificationResult
from ..robot.model import RobotModel, require_model
from .motor_terms import motor_column_names, motor_columns
from .transmission import Transmission


@dataclass(frozen=True, eq=False)
class CoupledResult:
    """A robot identified with its coupled motors' terms.

    Attributes
    ----------
    result : the :class:`~consistid.identification.result.IdentificationResult` of
        ``τ − C ζ̂`` (the rigid-body and per-joint model).
    motor_terms : (c,) ``ζ̂`` in motor-side units, named by ``motor_names``.
    motor_std : (c,) their standard deviations (WLS, rows counted as independent).
    transmission : the :class:`Transmission` whose coupled motors they are.
    """

    result: IdentificationResult
    motor_terms: np.ndarray
    motor_std: np.ndarray
    motor_names: tuple[str, ...]
    transmission: Transmission

    def predict(self, dataset: Dataset) -> np.ndarray:
        """Predicted joint torques ``W β + C ζ̂``, (N, nv)."""
        dataset = as_dataset(dataset)
        return self.result.predict(dataset) + _motor_torque(self.transmission, dataset,
                                                            self.motor_terms)

    def rms(self, dataset: Dataset) -> np.ndarray:
        """Per-joint RMS of the measured minus predicted torque, (nv,)."""
        dataset = as_dataset(dataset)
        return np.sqrt(np.mean((dataset.require_torque() - self.predict(dataset)) ** 2, axis=0))

    def summary(self) -> str:
        rows = [f"{n:>24s}  {v:12.6g}  ± {s:.3g}"
                for n, v, s in zip(self.motor_names, self.motor_terms, self.motor_std)]
        return "\n".join(["coupled motor terms (motor side)", *rows, "",
                          self.result.summary()])


def _motor_torque(transmission: Transmission, dataset: Dataset, zeta: np.ndarray) -> np.ndarray:
    return motor_columns(transmission, dataset.dq, dataset.ddq) @ zeta


def identify_coupled(model: RobotModel, dataset: Dataset, transmission: Transmission,
                     method: str = "sdp", friction: FrictionArg = DEFAULT_FRICTION,
                     armature: bool | Sequence[int | str] = False,
                     **identify_options: Any) -> CoupledResult:
    """Identify a robot whose transmission couples joints, with the coupled motors' terms.

    Parameters
    ----------
    model : the robot.
    dataset : joint-side :class:`Dataset` with joint torques (convert motor-side logs with
        :meth:`Transmission.joint_positions` and :meth:`Transmission.current_torque`).
    transmission : its ratios and coupling (the columns are those of its coupled motors).
    method, friction, armature, identify_options : as in :func:`consistid.identify`.

    Raises
    ------
    OptionError when the transmission couples no joints (use :func:`consistid.identify`);
    JointCountError for a transmission or data of another joint count; PoorExcitationError when
    the data cannot separate the coupled terms from the rest.
    """
    require_model(model)
    if not isinstance(transmission, Transmission):
        raise OptionError(f"identify_coupled: transmission must be a Transmission(ratios=..., "
                          f"coupling=...), got {type(transmission).__name__}")
    transmission.check_joints(model.nv, model.joint_names)
    if not transmission.coupled_motors.size:
        raise OptionError("transmission couples no joints (coupling is diagonal): its motor "
                          "terms are the joints' own armature and friction columns; use "
                          "consistid.identify(..., armature=True)")
    dataset = as_dataset(dataset)
    dataset.check_joints(model.nv, model.joint_names)
    spec = RegressorSpec.make(model, friction, armature)
    zeta, std = _motor_terms(model, dataset, spec, transmission)
    corrected = dataset.with_torque(
        dataset.require_torque() - _motor_torque(transmission, dataset, zeta), keep_filter=True)
    result = identify(model, corrected, method=method, friction=friction, armature=armature,
                      **identify_options)
    return CoupledResult(result, zeta, std, tuple(motor_column_names(transmission)),
                         transmission)


def _motor_terms(model: RobotModel, dataset: Dataset, spec: RegressorSpec,
                 transmission: Transmission) -> tuple[np.ndarray, np.ndarray]:
    """``(ζ̂, σ_ζ)`` of WLS on ``[W_b | C]`` (module docstring)."""
    base = base_parameters_of(model, spec)
    n, nv = dataset.n_samples, model.nv
    wb = regressor(model, dataset.q, dataset.dq, dataset.ddq, spec, dq_sign=dataset.dq_sign
                   ).reshape(n, nv, -1)[:, :, base.independent]
    a = np.concatenate([wb, motor_columns(transmission, dataset.dq, dataset.ddq)], axis=2)
    tau = dataset.require_torque()
    factors = [np.linalg.qr(np.column_stack([a[:, j], tau[:, j]]), mode="r") for j in range(nv)]
    p = a.shape[2]
    sigma = np.ones(nv)
    for _ in range(2):                                   # OLS, then per-joint weights
        r = np.linalg.qr(np.concatenate([f / s for f, s in zip(factors, sigma)]), mode="r")
        sv = np.linalg.svd(r[:p, :p], compute_uv=False)
        if sv[-1] < RANK_RTOL * sv[0]:
            raise PoorExcitationError(
                "the data do not separate the coupled motors' terms "
                f"({', '.join(motor_column_names(transmission))}) from the joints' own "
                "columns: excite the coupled joints with different, independent motions")
        x = np.linalg.solve(r[:p, :p], r[:p, p])
        sse = np.array([np.sum((f @ np.append(x, -1.0)) ** 2) for f in factors])
        sigma = np.sqrt(sse / max(n - p / nv, 1.0))
        sigma = np.where(sigma > 0, sigma, 1.0)
    r = np.linalg.qr(np.concatenate([f / s for f, s in zip(factors, sigma)]), mode="r")
    r_inv = np.linalg.inv(r[:p, :p])
    cov = r_inv @ r_inv.T
    c = slice(base.n_base, p)
    return x[c], np.sqrt(np.diag(cov)[c])

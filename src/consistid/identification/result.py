"""The result of an identification: estimates, uncertainty, solver report, prediction."""

from __future__ import annotations

import dataclasses
import importlib
import warnings
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, ClassVar, Mapping, Sequence

import numpy as np

from . import persistence
from .intervals import interval_frame
from .base import BaseParameters
from .envelope import TrainingEnvelope
from ..data.checks import check_magnitudes
from ..data.dataset import Dataset, as_dataset
from ..errors import ExtrapolationWarning, ResultFileError, check_number, check_option
from ..report.result import normal_intervals
from ..filesafety import replacing
from ..robot.export import check_not_source, write_urdf
from ..robot.mjcf import write_mjcf
from ..robot.mjcf_edit import write_mjcf_into
from ..robot.model import RobotModel
from ..robot.inertia import ConsistencyReport, is_physically_consistent
from ..robot.joint_terms import STANDSTILL_SPEED, joint_terms_of
from .regressor import RegressorSpec, predict_torque
from .solver import SolverReport
from .report import identification_page, standard_set_page
from .summary import identification_summary


class StandardParameterSet:
    """What any answer carrying a full standard vector offers: its consistency, its model and
    its URDF. Subclasses (dataclasses) define ``model``, ``parameters`` (10 per body, then the
    per-joint terms) and ``parameter_names``."""

    model: RobotModel
    parameters: np.ndarray
    parameter_names: tuple[str, ...]

    @property
    def inertial_parameters(self) -> np.ndarray:
        """The ``10·nbodies`` inertial entries of ``parameters``."""
        return self.parameters[: self.model.n_inertial]

    @cached_property
    def consistency(self) -> ConsistencyReport:
        """Per-body physical consistency at the pseudo-inertia level
        (:func:`consistid.robot.inertia.is_physically_consistent`, its tolerance)."""
        return is_physically_consistent(self.inertial_parameters, "pseudo-inertia",
                                        self.model.body_names)

    @property
    def is_consistent(self) -> bool:
        """``consistency.ok``: every body realizable."""
        return self.consistency.ok

    def identified_model(self) -> RobotModel:
        """The robot model carrying these inertial parameters."""
        return self.model.with_parameters(self.inertial_parameters)

    def exported_terms(self) -> tuple[np.ndarray, tuple[str, ...]]:
        """The standard vector and its names as the URDF and MJCF writers take them (10 per
        body, then per-joint terms those formats hold); a subclass with terms they cannot hold
        maps or drops them, and says so."""
        return self.parameters, self.parameter_names

    def to_urdf(self, path: str | Path, merged: str = "auto") -> Path:
        """Write the model's URDF with these inertias and Coulomb/viscous friction
        (:func:`consistid.robot.export.write_urdf`); refuses an inconsistent body."""
        return write_urdf(self.model, path, *self.exported_terms(), merged)

    def _repr_html_(self) -> str:
        """Jupyter: each body's consistency and margin, the per-joint terms, the summary."""
        return standard_set_page(self, f"{type(self).__name__}: {self.model.name}").fragment()

    def to_mjcf(self, path: str | Path, source: str | Path | None = None, *,
                absolute_assets: bool = False) -> Path:
        """Write an MJCF of the model with these inertias, Coulomb friction (``frictionloss``),
        viscous friction (``damping``) and armature; refuses an inconsistent body.

        ``source=None``: a new file built through MuJoCo's ``MjSpec``, without geometry
        (:func:`consistid.robot.mjcf.write_mjcf`). ``source=`` the user's MJCF (e.g.
        ``self.model.source`` of a model read by ``RobotModel.from_mjcf``): a copy of it with
        these values written in and every other byte unchanged (meshes, actuators, sensors;
        :func:`consistid.robot.mjcf_edit.write_mjcf_into`). ``absolute_assets=True``: a copy
        written outside the source's folder names the source's mesh and texture folders by
        absolute path (its ``<compiler meshdir/texturedir>``), so that its assets resolve."""
        if source is not None:
            return write_mjcf_into(self.model, path, source, *self.exported_terms(),
                                   absolute_assets=absolute_assets)
        return write_mjcf(self.model, path, *self.exported_terms())


#: Result classes by the ``kind`` their saved files carry (filled as each class is defined).
RESULT_KINDS: dict[str, type] = {}
#: Where the kinds defined above this package live: :meth:`IdentificationResult.load` imports
#: the module of a kind not yet defined in this session (a plug-in registry, not an import
#: of the layer above).
KIND_MODULES = {"nonlinear_friction": "consistid.friction"}


@dataclass(frozen=True, eq=False)
class IdentificationResult(StandardParameterSet):
    """Identified parameters of a robot, with the numbers needed to trust them.

    Attributes
    ----------
    method : ``"ols"``, ``"wls"`` or ``"sdp"``.
    parameters : (p,) standard parameters (10 per body) then friction/armature, named by
        ``parameter_names``. For OLS/WLS, which determine only base parameters, this is the
        standard vector nearest to the prior (Euclidean) that has the identified base parameters.
    base_parameters : (b,) identified base parameters ``β = B π``, named by ``base.names``.
    base_covariance : (b, b) covariance ``σ² (W_bᵀ W_b)⁻¹`` (OLS) or ``(W_bᵀ Σ⁻¹ W_b)⁻¹`` (WLS,
        SDP), Gautier & Khalil; for the SDP it is that of the unconstrained fit at the answer.
    sigma : (nv,) per-joint torque-noise standard deviation used for weighting / estimated.
    condition_number : of the (weighted) base regressor.
    train_rms : (nv,) residual RMS on the training data.
    solver : :class:`SolverReport`.
    details : extra method-specific figures (SDP: margins, active constraints, prior weight …).
    provenance : what computed it (package versions, input files and their SHA-256, the run
        configuration; :func:`consistid.identification.persistence.make_provenance`), filled
        by :meth:`with_provenance`, :meth:`save` and :meth:`load`.
    uninformed : the base-parameter directions the data do not inform, as readable groupings
        (:func:`consistid.identification.uninformed.uninformed_directions`); their values come
        from the prior (or the constraints) alone, their ``base_std`` is ``inf``. Empty when
        the data inform every direction. Shown by :meth:`summary`; a
        :class:`~consistid.errors.PoorExcitationWarning` names them when the result is made.
    weakly_informed : the directions the data inform so weakly that one σ along them moves
        predictions by more than :data:`~consistid.identification.weak.WEAK_RATIO` of the
        torque on the trained motions run with either velocity sign, and each joint that moved
        one way only (its Coulomb and offset), in words
        (:func:`consistid.identification.weak.weakly_informed`); warned when the result is made.
    envelope : where the training data went, per joint
        (:class:`~consistid.identification.envelope.TrainingEnvelope`); :meth:`predict` warns
        (:class:`~consistid.errors.ExtrapolationWarning`) on data that leave it (a stream's:
        its parts' joined). ``None`` for data compressed where they lie (Dask) or a result file
        written without it.
    excluded_joints : joints whose torque rows were left out (``exclude_joints=``, or a dead
        channel): their ``sigma`` and ``train_rms`` are NaN, and ``details["excluded_joints"]``
        names what cannot be identified without them (:mod:`consistid.identification.subset`).
    """

    method: str
    model: RobotModel
    spec: RegressorSpec
    base: BaseParameters
    parameters: np.ndarray
    parameter_names: tuple[str, ...]
    prior: np.ndarray
    base_parameters: np.ndarray
    base_covariance: np.ndarray
    sigma: np.ndarray
    condition_number: float
    train_rms: np.ndarray
    n_samples: int
    solver: SolverReport
    details: dict[str, Any] = field(default_factory=dict)
    provenance: dict[str, Any] = field(default_factory=dict)
    uninformed: tuple[str, ...] = ()
    weakly_informed: tuple[str, ...] = ()
    envelope: TrainingEnvelope | None = None
    excluded_joints: tuple[str, ...] = ()

    #: What a saved file calls this kind of result (``"kind"`` in its JSON); each subclass names
    #: its own and :meth:`load` gives back that class.
    kind: ClassVar[str] = "identification"

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        RESULT_KINDS[cls.kind] = cls

    def persisted_fields(self) -> dict[str, Any]:
        """The fields a subclass adds, as :meth:`save` writes them (``"extra"`` in the JSON);
        its constructor takes them back."""
        return {}

    def shape_rows(self) -> list[tuple[str, float, float, str]]:
        """``(name, value, std, unit)`` of each parameter outside the linear model (a friction
        law's shape; none here), for :meth:`to_csv`."""
        return []

    # ----------------------------------------------------------------------------- uncertainty
    @cached_property
    def base_std(self) -> np.ndarray:
        """Standard deviation of each base parameter, ``sqrt(diag(cov))``."""
        return np.sqrt(np.clip(np.diag(self.base_covariance), 0.0, None))

    @cached_property
    def relative_std(self) -> np.ndarray:
        """Relative standard deviation in % (Pressé & Gautier 1991; Rackl et al. 2012 eq. 13):
        ``100 · σ_β / |β|``; ``inf`` where ``β = 0`` (``0`` where ``σ_β`` is 0 too, never NaN)."""
        std, beta = self.base_std, np.abs(self.base_parameters)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(std == 0, 0.0, 100.0 * std / beta)

    @cached_property
    def at_bound(self) -> np.ndarray:
        """(n_base,) ``True`` where the base parameter is a standard one (no ``*``) that a
        non-negativity bound of the SDP holds active (``panda_joint1.fc ≥ 0`` in
        ``details["active_constraints"]``): its estimate is the bound, 0 to the solver's
        tolerance, so its :attr:`relative_std` (σ over a value like 1e-12) says nothing."""
        active = set(self.details.get("active_constraints", ()))
        return np.array([f"{name} ≥ 0" in active for name in self.base.names], dtype=bool)

    @property
    def estimate(self) -> np.ndarray:
        """The estimated vector whose ``std``, ``covariance`` and ``conf_int`` are reported: the
        base parameters (the identifiable combinations; :attr:`parameters` is the standard
        vector they come from, with the prior deciding what the data do not)."""
        return self.base_parameters

    @property
    def std(self) -> np.ndarray:
        """Standard deviations of :attr:`estimate` (the base parameters), as on every result."""
        return self.base_std

    @property
    def covariance(self) -> np.ndarray:
        """Covariance of :attr:`estimate` (the base parameters), as on every result."""
        return self.base_covariance

    def conf_int(self, alpha: float = 0.05, *, labelled: bool = True) -> Any:
        """Two-sided ``1 − alpha`` confidence intervals of the base parameters, as statsmodels
        gives them: a pandas ``DataFrame`` indexed by base-parameter name, columns ``lower``
        and ``upper`` (:mod:`consistid.identification.intervals`); ``labelled=False``: the
        bare ``(b, 2)`` array (no pandas needed)."""
        if not labelled:
            return normal_intervals(self.base_parameters, self.base_std, alpha)
        return interval_frame(self.base_parameters, self.base_std, self.base.names, alpha)

    # ----------------------------------------------------------------------------- prediction
    def predict(self, dataset: Dataset) -> np.ndarray:
        """Predicted joint torques ``Y(q, q̇, q̈) π`` for a dataset's samples, shape (N, nv).

        Raises :class:`~consistid.errors.DatasetError` for a dataset that is not one, has
        another joint count, or values beyond :data:`consistid.data.checks.MAX_ABS`."""
        dataset = as_dataset(dataset)
        dataset.check_joints(self.model.nv, self.model.joint_names)
        check_magnitudes(dataset, ("q", "dq", "ddq"), self.model.joint_names)
        self._warn_extrapolation(dataset)
        return predict_torque(self.model, dataset, self.spec, self.parameters)

    def _warn_extrapolation(self, dataset: Dataset) -> None:
        """An :class:`~consistid.errors.ExtrapolationWarning` naming where ``dataset`` leaves
        the training :attr:`envelope` (nothing without one)."""
        envelope = getattr(self, "envelope", None)
        if envelope is None or envelope.joint_names and len(envelope.joint_names) != dataset.nv:
            return
        away = envelope.departures(dataset)
        if away:
            weak = ("; the data barely informed " + "; ".join(self.weakly_informed[:2])
                    if self.weakly_informed else "")
            warnings.warn(f"these data go where the training data never went: "
                          f"{'; '.join(away[:4])}{' …' if len(away) > 4 else ''}. The "
                          f"prediction there extrapolates{weak}. Train on motions that cover "
                          "them (res.envelope holds the trained ranges)", ExtrapolationWarning,
                          stacklevel=3)

    def residual(self, dataset: Dataset, *, at_rest: str = "point",
                 rest_speed: float = STANDSTILL_SPEED) -> np.ndarray:
        r"""Measured minus predicted torque, (N, nv).

        ``at_rest="cone"``: at samples where a joint stands still (``|q̇_j| < rest_speed``,
        rad/s), its dry friction is any torque in ``[−f_s, f_s]`` (:attr:`static_friction`; the
        set-valued Coulomb law, Olsson et al., *Friction models and friction compensation*,
        Eur. J. Control 4, 1998), which no law of ``q̇`` predicts: the residual there is the
        distance of ``e_0 = τ − (τ̂ − τ_dry(q̇))`` to that interval,
        ``e_0 − clip(e_0, −f_s, f_s)`` (:meth:`dry_friction`). ``"point"`` (default): the
        single-valued prediction everywhere."""
        check_option("at_rest", at_rest, ("point", "cone"))
        rest_speed = check_number("rest_speed", rest_speed, 0)
        dataset = as_dataset(dataset)
        e = dataset.require_torque() - self.predict(dataset)
        if at_rest == "point":
            return e
        cone = self.static_friction
        rest = (np.abs(dataset.dq) < rest_speed) & (cone > 0)
        e0 = e + self.dry_friction(dataset.dq, dataset.dq_sign)
        e[rest] = (e0 - np.clip(e0, -cone, cone))[rest]
        return e

    @property
    def static_friction(self) -> np.ndarray:
        """(nv,) N·m: the largest torque dry friction holds a joint at rest with — the
        Coulomb ``f_c`` of the ``coulomb`` column here (0 without one; a negative ``f_c`` counts
        as 0), the friction laws' limit as ``q̇ → 0`` in a nonlinear-friction result."""
        return np.maximum(self._coulomb(), 0.0)

    def dry_friction(self, dq: np.ndarray, sign: np.ndarray | None = None) -> np.ndarray:
        """The dry (velocity-sign) friction the prediction holds at velocities ``dq`` (N, nv):
        ``f_c sign(q̇)`` (``sign``: the Coulomb signal the prediction used instead, a dataset's
        ``dq_sign``)."""
        return self._coulomb() * (np.sign(np.atleast_2d(dq)) if sign is None
                                  else np.atleast_2d(sign))

    def _coulomb(self) -> np.ndarray:
        """(nv,) the ``coulomb`` column's ``f_c`` per joint (0 without one)."""
        p = self.model.n_inertial + self.spec.n_joint_columns
        terms = joint_terms_of(self.model, self.parameters[:p], self.parameter_names[:p])
        return np.array([terms.get(j, {}).get("fc", 0.0) for j in self.model.joint_names])

    def rms(self, dataset: Dataset) -> np.ndarray:
        """Per-joint RMS of the residual on a dataset, (nv,); ``nan`` at the
        :attr:`excluded_joints` (their torque channel was left out of the fit, e.g. a dead
        sensor: its readings judge nothing)."""
        rms = np.sqrt(np.mean(self.residual(dataset) ** 2, axis=0))
        return np.where(self._kept_joints(), rms, np.nan)

    def relative_error(self, dataset: Dataset) -> tuple[np.ndarray, float]:
        """Per-joint and total relative error ``‖τ − τ̂‖ / ‖τ‖`` on a dataset; ``nan`` at the
        :attr:`excluded_joints`, whose channels the total leaves out too."""
        dataset = as_dataset(dataset)
        kept = self._kept_joints()
        r, tau = self.residual(dataset)[:, kept], dataset.require_torque()[:, kept]
        per_joint = np.full(self.model.nv, np.nan)
        per_joint[kept] = np.linalg.norm(r, axis=0) / np.linalg.norm(tau, axis=0)
        return per_joint, float(np.linalg.norm(r) / np.linalg.norm(tau))

    def _kept_joints(self) -> np.ndarray:
        """(nv,) bool: the joints whose torque rows the fit used (not :attr:`excluded_joints`)."""
        excluded = set(self.excluded_joints or ())
        return np.array([name not in excluded for name in self.model.joint_names])

    # ----------------------------------------------------------------------------- reporting
    def summary(self, max_rows: int | None = None) -> str:
        """A readable table: one row per base parameter, then per-joint figures and notes."""
        return identification_summary(self, max_rows=max_rows)

    def report(self, path: str | Path | None = None, *, data: Dataset | None = None,
               held_out: Dataset | None = None, max_rows: int | None = None):
        """Write the report, as :meth:`consistid.diagnosis.diagnose.Diagnosis.report` does:
        ``*.html`` one self-contained page (plots embedded), ``*.txt`` the text
        :meth:`summary`, any other path a folder holding ``report.html``, ``report.txt`` and
        the plots as PNG files. Returns the path written (with ``path=None``: the text).

        ``data`` (the training data) and ``held_out`` add the measured-vs-predicted torque per
        joint, residual histograms and spectra (:mod:`consistid.identification.report`).
        """
        text = self.summary(max_rows=max_rows)
        if path is None:
            return text
        path = check_not_source(self.model, path, "report")
        if path.suffix.lower() == ".txt":
            with replacing(path) as tmp:
                tmp.write_text(text + "\n", encoding="utf-8")
            return path
        page = identification_page(self, data, held_out, max_rows=max_rows)
        out = page.write(path, text + "\n")
        return out if path.suffix.lower() in (".html", ".htm") else path

    def _repr_html_(self) -> str:
        """Jupyter: the report without plots."""
        return identification_page(self, figures=False, max_rows=20).fragment()

    # ----------------------------------------------------------------------------- files
    def with_provenance(self, inputs: Sequence[str | Path] = (),
                        config: Mapping[str, Any] | None = None) -> "IdentificationResult":
        """A copy whose :attr:`provenance` records package versions, the ``inputs`` files
        (path, size, SHA-256) and the run ``config`` (a mapping, e.g. the TOML tables)."""
        return dataclasses.replace(self, provenance=persistence.make_provenance(
            self.provenance, inputs, config))

    def save(self, path: str | Path, *, inputs: Sequence[str | Path] = (),
             config: Mapping[str, Any] | None = None) -> Path:
        """Write this result as JSON (:mod:`consistid.identification.persistence`): names,
        values, σ, covariance, solver report, consistency margins, the model (URDF text
        included) and provenance (with ``inputs`` and ``config`` added).
        :meth:`load` gives back an equal result. Returns the path."""
        res = self.with_provenance(inputs, config) if (inputs or config is not None) else self
        return persistence.write_result(res, path)

    @classmethod
    def load(cls, path: str | Path, model: RobotModel | None = None,
             urdf: str | Path | None = None, *,
             follow_source: bool = False) -> "IdentificationResult":
        """Read a result written by :meth:`save`.

        The robot is rebuilt from the URDF text stored in the file; give ``model`` (same joints
        and bodies) or ``urdf`` to use your own, or ``follow_source=True`` to use the URDF at
        the path the file names when its SHA-256 still matches (a result file is data: no
        path it names is opened unless you ask). The whole file is checked first. Raises
        :class:`~consistid.errors.ResultFileError` naming the file and the field that is
        missing or wrong.
        """
        fields = persistence.read_result_fields(path, model, urdf, follow_source)
        kind, extra = fields.pop("kind"), fields.pop("extra")
        if kind not in RESULT_KINDS and kind in KIND_MODULES:
            importlib.import_module(KIND_MODULES[kind])   # defines (and registers) the class
        target = RESULT_KINDS.get(kind)
        if target is None:
            raise ResultFileError(f"{path}: it holds a {kind!r} result, a kind this consistid "
                                  f"does not know (known: {', '.join(sorted(RESULT_KINDS))}); "
                                  "was it written by a newer version?")
        if not issubclass(target, cls):
            raise ResultFileError(f"{path}: it holds a {kind!r} result; {cls.__name__}.load "
                                  f"reads {cls.kind!r} results: use {target.__name__}.load "
                                  "(or IdentificationResult.load, which reads every kind)")
        known = {f.name for f in dataclasses.fields(target)}
        return target(**{k: v for k, v in {**fields, **extra}.items() if k in known})

    def to_csv(self, path: str | Path) -> Path:
        """The parameter table as CSV: base parameters ± σ with their groupings, then every
        standard parameter (:func:`consistid.identification.persistence.write_csv`)."""
        return persistence.write_csv(self, path)

    def __str__(self) -> str:
        return self.summary(max_rows=20)


RESULT_KINDS[IdentificationResult.kind] = IdentificationResult

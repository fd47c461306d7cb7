r"""Simulator calibration: the terms only a simulator has, fitted by batched rollouts.

An identification gives the *physical* parameters: inertias (consistent), armature ``I_a``,
viscous ``f_v`` and Coulomb ``f_c`` friction, from the inverse-dynamics equation error. A
simulator at step ``h`` does not reproduce that physics exactly: ``implicitfast`` integrates
the joint damping ``d`` and the servo's velocity gain ``K_d`` implicitly, which acts as an added
inertia of about ``h (K_d + d)`` on the joint, and MuJoCo's dry friction (``frictionloss``) is a
soft constraint, not ``f_c sign q̇``. :func:`calibrate_simulator` keeps the physical inertias
(the convex, consistent estimate) and fits per joint the simulator's

* ``armature`` (``dof_armature``; its offset from the physical ``I_a`` is the integrator's share
  for joint damping, ``≈ −h d``, and what else the step and the friction model change; the
  replay's own PD adds no inertia, :mod:`.replay`, so for a servo of velocity gain ``k_v`` in
  the user's MJCF subtract ``h k_v`` more),
* ``damping`` (``dof_damping``), ``frictionloss`` (``dof_frictionloss``),

by output error in closed loop (the direct-and-inverse-dynamics identification, DIDIM:
Gautier, Janot, Vandanjon 2013, doi:10.1109/TCST.2012.2185697): the log is replayed under the
PD of :mod:`.options` with the logged torque as feed-forward, and the correction torque
``c_k(θ)`` the simulated robot needs to follow the log is minimised,

.. math:: \min_{\theta \ge 0} \sum_{k,j} \big(c_{kj}(\theta) / s_j\big)^2,

``s_j`` the identification's residual RMS of joint ``j`` on the same data, by bounded
Gauss–Newton (:func:`gauss_newton`: Levenberg–Marquardt damping, the bounds as an active set,
a line search over a few step lengths run as one batch) with the Jacobian from forward
differences, all ``p + 1`` rollouts of one Jacobian in one ``mujoco.rollout`` call. The
positions the simulated robot reaches (not the logged accelerations) carry the information.
A candidate whose rollout diverges
gets a large finite residual and the step is rejected; it does not abort the fit.

Uncertainty: ``Cov θ = ŝ² τ (JᵀJ)⁻¹`` with ``ŝ²`` the residual's mean square at the answer and
``τ`` its integrated autocorrelation time (:func:`consistid.identification.statistics.
autocorrelation_time`; closed-loop residuals are strongly correlated, so counting samples as
independent would make σ far too small); with ``refine_inertia`` the prior's rows add their
information. The σ of the simulator terms are conditional on the physical inertias unless they
were refined.
"""

from __future__ import annotations

import json
import time
import warnings
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from ..data.dataset import Dataset
from ..filesafety import replacing
from ..errors import (DatasetError, ModelMisfitWarning, OptionError, PoorExcitationWarning,
                      ResultFileError, check_number)
from ..identification.resultschema import read_document
from ..identification.statistics import autocorrelation_time
from ..report.html import Page
from ..robot.inertia import is_physically_consistent
from ..report.result import Reported
from ..identification.regressor import RegressorSpec, regressor
from .engine import Simulator, build_simulator, integrator_name, write_inertias
from .logcholesky import from_log_cholesky, to_log_cholesky
from .terms import LOWER, TERMS, TYPICAL, TermLayout, check_terms, informed_threshold
from .fields import field, number, vector
from .options import INTEGRATORS, ComputedTorque, Controller, PDGains, RolloutOptions
from .replay import LogGrid, closed_loop_under

#: Typical magnitude of a log-Cholesky entry (sets its finite-difference step).
TYPICAL_LOG_CHOLESKY = 0.1
#: Relative finite-difference step.
FD_STEP = 1e-3
#: Whitened residual given to a diverged rollout's samples.
DIVERGED_RESIDUAL = 1e3
#: Step (in σ) of the central differences of the inertias' share of σ (:func:`_inertia_share`).
INERTIA_STEP = 1e-2
#: Largest move of one log-Cholesky coordinate in those differences.
MAX_LOG_CHOLESKY_STEP = 0.05


@dataclass(frozen=True, eq=False)
class SimulatorCalibration(Reported):
    """Simulator-only terms calibrated by rollouts on top of an identification.

    Attributes
    ----------
    result : the identification (its physical parameters, base σ: ``result.std``).
    names : ``"<joint>.<term>"`` of each simulator parameter (``term`` in
        :data:`~.terms.ALL_TERMS`), and ``"delay"``.
    start, values, std : (p,) the physical starting values, the calibrated values and their σ.
    timestep, integrator : the simulator they were calibrated for.
    kp, kd : (nv,) the gains of the closed-loop replay (its ``controller``: ``"PD"`` or
        ``"computed torque"``, :mod:`.options`).
    cost_start, cost : mean square whitened correction torque before and after.
    evaluations : rollouts of the residual; seconds : wall time.
    message : the optimiser's.
    inertial : (10·nbodies,) the physical inertias simulated: the identification's, or refined.
    base_parameters, base_std : the physical base parameters ``β = B π`` and their σ (the
        identification's unless refined; then propagated from the refinement, and given the
        closed-loop rows' whitening).
    refined : whether the inertias were refined (``refine_inertia=True``).
    controller : the closed-loop replay's, ``"PD"`` or ``"computed torque"``.
    uninformed : the simulator parameters the data did not inform, held at their start.

    The σ of the simulator terms are those of the output-error fit given the physical
    parameters (conditional on them unless ``refined``).
    """

    result: Any
    names: tuple[str, ...]
    start: np.ndarray
    values: np.ndarray
    std: np.ndarray
    timestep: float
    integrator: str
    kp: np.ndarray
    kd: np.ndarray
    cost_start: float
    cost: float
    evaluations: int
    seconds: float
    message: str
    inertial: np.ndarray
    base_parameters: np.ndarray
    base_std: np.ndarray
    refined: bool
    controller: str = "PD"
    uninformed: tuple[str, ...] = ()

    @property
    def parameters(self) -> np.ndarray:
        """The identification's parameter vector with these inertias and the calibrated terms
        as its ``Ia`` (minus the model's own rotor inertia), ``fv``, ``fc``."""
        r = self.result
        out = np.asarray(r.parameters, dtype=float).copy()
        out[:r.model.n_inertial] = self.inertial
        key = {"Ia": "armature", "fv": "damping", "fc": "frictionloss"}
        for k, name in enumerate(r.parameter_names[r.model.n_inertial:], r.model.n_inertial):
            joint, _, term = name.rpartition(".")
            if term in key and key[term] in self.layout.terms and joint in r.model.joint_names:
                j = r.model.joint_names.index(joint)
                own = float(r.model.pin_model.armature[j]) if term == "Ia" else 0.0
                out[k] = self.term(key[term])[j] - own
        return out

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return tuple(self.result.parameter_names)

    @property
    def model(self) -> Any:
        return self.result.model

    @property
    def is_consistent(self) -> bool:
        """Every simulated body physically consistent (pseudo-inertia)."""
        return is_physically_consistent(self.inertial, "pseudo-inertia",
                                        self.result.model.body_names).ok

    def as_result(self) -> Any:
        """The identification with :attr:`parameters` (its ``predict``/``rms`` then use the
        calibrated terms and inertias; its base parameters and σ stay the identification's)."""
        return replace(self.result, parameters=self.parameters)

    @property
    def estimate(self) -> np.ndarray:
        """The calibrated simulator parameters (``std`` are theirs)."""
        return self.values

    @property
    def layout(self) -> TermLayout:
        """Where each calibrated term sits in :attr:`values`."""
        return TermLayout.of_names(self.names, self.result.model.joint_names)

    def term(self, name: str) -> np.ndarray:
        """The calibrated values of one term: (nv,), or (1,) for ``"delay"``."""
        return self.values[self.layout.slice(name)]

    def term_std(self, name: str) -> np.ndarray:
        """σ of :meth:`term`."""
        return self.std[self.layout.slice(name)]

    @property
    def armature_offset(self) -> np.ndarray:
        """(nv,) calibrated minus physical armature: the integrator's share."""
        k = self.layout.slice("armature")
        return self.values[k] - self.start[k]

    def simulator(self, *, mjcf: str | Path | None = None, timestep: float | None = None,
                  integrator: str | None = None) -> Simulator:
        """The identified robot in the simulator with the calibrated terms; warns
        (:class:`~consistid.errors.ModelMisfitWarning`) at another step or integrator than the
        calibration's, for which they were not fitted."""
        if (timestep is not None and not np.isclose(timestep, self.timestep)) or (
                integrator is not None and integrator != self.integrator):
            warnings.warn(f"the simulator terms were calibrated at {self.timestep:g} s "
                          f"{self.integrator}, not at {timestep} s {integrator}: the armature "
                          "offset and damping are the integrator's; calibrate again for this "
                          "simulator", ModelMisfitWarning, stacklevel=2)
        r = self.result
        params = np.asarray(r.parameters, dtype=float).copy()
        params[:r.model.n_inertial] = self.inertial
        sim = build_simulator(r.model, params, r.parameter_names, mjcf=mjcf,
                              timestep=timestep, integrator=integrator)
        layout = self.layout
        for attr, term in (("dof_armature", "armature"), ("dof_damping", "damping"),
                           ("dof_frictionloss", "frictionloss")):
            if term in layout.terms:
                getattr(sim.mj_model, attr)[sim.dofs] = self.term(term)
        gain = self.term("gain") if "gain" in layout.terms else None
        delay = float(self.term("delay")[0]) if "delay" in layout.terms else 0.0
        return replace(sim, gain=gain, delay=delay)

    def table(self) -> list[dict[str, Any]]:
        """One row per simulator parameter: physical start (gain 1, delay 0), calibrated value,
        σ (given the inertias' uncertainty unless refined, :func:`_inertia_share`)."""
        return [{"parameter": n, "physical": s, "simulator": v, "std": d}
                for n, s, v, d in zip(self.names, self.start, self.values, self.std)]

    def summary(self) -> str:
        lines = [f"Simulator calibration at {self.timestep:g} s {self.integrator}: "
                 f"{self.evaluations} rollouts, {self.seconds:.2f} s ({self.message})",
                 f"closed-loop correction cost {self.cost_start:.4g} → {self.cost:.4g} "
                 "(mean square, in units of the identification's residual RMS)",
                 f"physical parameters: {self.result.method} identification"
                 f"{', refined by output error' if self.refined else ''}, "
                 f"{len(self.base_parameters)} base parameters (base_parameters ± base_std), "
                 f"consistent: {self.is_consistent}",
                 f"{'simulator parameter':<30}{'physical':>12}{'simulator':>12}{'± σ':>12}"]
        if self.uninformed:
            lines.insert(3, "not informed by the data, held at their start: "
                            + ", ".join(self.uninformed))
        lines += [f"{r['parameter']:<30}{r['physical']:>12.4g}{r['simulator']:>12.4g}"
                  f"{r['std']:>12.3g}" for r in self.table()]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def page(self) -> Page:
        page = Page("consistid simulator calibration", self.summary().splitlines()[0])
        page.paragraph(self.summary().splitlines()[1])
        page.table(["parameter", "physical", "simulator", "σ"],
                   [tuple(r.values()) for r in self.table()])
        page.heading("Physical base parameters")
        page.table(["base parameter", "value", "σ"],
                   list(zip(self.result.base.names, self.base_parameters, self.base_std)))
        return page

    def save(self, path: str | Path) -> Path:
        """The calibrated terms as JSON (``*.json``; the identification is saved on its own,
        ``result.save``), written atomically."""
        path = Path(path)
        if path.suffix.lower() != ".json":
            raise OptionError(f"save path {str(path)!r}: give a .json file")
        doc = {"kind": "simulator_calibration", "names": list(self.names),
               "start": self.start.tolist(), "values": self.values.tolist(),
               "std": self.std.tolist(), "timestep": self.timestep,
               "integrator": self.integrator, "kp": self.kp.tolist(), "kd": self.kd.tolist(),
               "cost_start": self.cost_start, "cost": self.cost,
               "evaluations": self.evaluations, "seconds": self.seconds,
               "message": self.message, "inertial": self.inertial.tolist(),
               "base_parameters": self.base_parameters.tolist(),
               "base_std": self.base_std.tolist(), "refined": self.refined,
               "controller": self.controller, "uninformed": list(self.uninformed)}
        text = json.dumps(doc, indent=1)
        with replacing(path) as tmp:                # never a half-written file
            tmp.write_text(text, encoding="utf-8")
        return path

    @classmethod
    def load(cls, path: str | Path, result: Any) -> "SimulatorCalibration":
        """Read :meth:`save`'s file back, with the identification ``result`` it was made on;
        :class:`~consistid.errors.ResultFileError` naming the file and the field for one that
        is not (not JSON, beyond a result file's limits, a field missing or of another type,
        length or sign, names not ``result``'s joints' terms in their order, an uninformed
        term not among them, gain or delay under computed torque)."""
        path = Path(path)
        doc = read_document(path, path.name)
        if not isinstance(doc, dict) or doc.get("kind") != "simulator_calibration":
            raise ResultFileError(f"{path.name} is not a saved SimulatorCalibration (kind "
                                  "'simulator_calibration' missing)")
        return cls(result, *_calibration_fields(doc, path.name, result))


def _calibration_fields(doc: dict, where: str, result: Any) -> tuple[Any, ...]:
    """:class:`SimulatorCalibration`'s fields after ``result`` from a saved document, each
    checked (:mod:`.fields`)."""
    model = result.model
    names = field(doc, "names", list, where)
    if not all(isinstance(n, str) for n in names):
        raise ResultFileError(f"{where}: field 'names' must list the terms' names")
    try:
        layout = TermLayout.of_names(names, model.joint_names)
    except OptionError as exc:
        raise ResultFileError(f"{where}: field 'names' {str(names)[:60]} are not the "
                              f"'<joint>.<term>' of {model.name}'s joints in order: "
                              f"{exc}") from exc
    controller = field(doc, "controller", str, where)
    if controller not in ("PD", "computed torque"):
        raise ResultFileError(f"{where}: field 'controller' is {controller!r:.40}, not 'PD' "
                              "or 'computed torque'")
    if controller == "computed torque" and {"gain", "delay"} & set(layout.terms):
        raise ResultFileError(f"{where}: field 'names' holds gain or delay, calibrated under "
                              "the PD replay only, but field 'controller' is 'computed torque'")
    integrator = field(doc, "integrator", str, where)
    if integrator not in INTEGRATORS:
        raise ResultFileError(f"{where}: field 'integrator' is {integrator!r:.40}, not one of "
                              f"{INTEGRATORS}")
    uninformed = field(doc, "uninformed", list, where)
    if not all(isinstance(u, str) and u in names for u in uninformed):
        raise ResultFileError(f"{where}: field 'uninformed' must list names of field "
                              f"'names', got {str(uninformed):.60}")
    p, nv, nb = layout.size, model.nv, len(result.base_parameters)
    terms = [vector(doc, k, p, where, inf=k == "std", what="one per term")
             for k in ("start", "values", "std")]
    gains = [vector(doc, k, nv, where) for k in ("kp", "kd")]
    costs = [number(doc, k, where, positive=False) for k in ("cost_start", "cost")]
    evaluations = field(doc, "evaluations", int, where)
    if evaluations < 0:
        raise ResultFileError(f"{where}: field 'evaluations' is {evaluations}, expected ≥ 0")
    inertial = vector(doc, "inertial", model.n_inertial, where, signed=True,
                      what="10 per body")
    base = [vector(doc, "base_parameters", nb, where, signed=True, what="one per base "
                   "parameter"), vector(doc, "base_std", nb, where, inf=True,
                                        what="one per base parameter")]
    return (tuple(names), *terms, number(doc, "timestep", where), integrator, *gains, *costs,
            evaluations, number(doc, "seconds", where, positive=False),
            field(doc, "message", str, where), inertial, *base,
            field(doc, "refined", bool, where), controller, tuple(uninformed))


@dataclass(frozen=True)
class InertiaPrior:
    r"""What the identification knows of the inertias, as Gauss–Newton rows: with ``R`` the
    triangular factor of the whitened inertial regressor ``Y/σ`` on the training data, the
    inverse-dynamics cost of moving the inertias from the estimate ``π̂`` is
    ``‖R (π − π̂)‖²`` (the unconstrained least-squares cost to second order; Gautier &
    Khalil's covariance is its inverse). The refinement may move ``π`` where the
    identification is uncertain and pays for moving it where it is sure."""

    r: np.ndarray
    estimate: np.ndarray

    @classmethod
    def of(cls, result: Any, data: Dataset) -> "InertiaPrior":
        model = result.model
        spec = RegressorSpec.make(model, friction=None, armature=False)
        y = regressor(model, data.q, data.dq, data.ddq, spec)
        sigma = np.asarray(result.sigma, dtype=float)
        # an excluded joint (exclude_joints=, a dead channel: σ NaN) had no rows in the fit
        weight = np.where(np.isfinite(sigma), 1.0 / np.maximum(sigma, 1e-9), 0.0)
        y = y * np.tile(weight, data.q.shape[0])[:, None]
        return cls(np.linalg.qr(y, mode="r"), np.asarray(result.inertial_parameters, float))

    def rows(self, inertial: np.ndarray) -> np.ndarray:
        return self.r @ (inertial - self.estimate)


class _Problem:
    """The whitened closed-loop correction as a function of the simulator terms and, when
    refined, the log-Cholesky parameters of the bodies (then with the inertia prior's rows)."""

    def __init__(self, sim: Simulator, log: LogGrid, controller: Controller, kp: np.ndarray,
                 kd: np.ndarray, scale: np.ndarray, threads: int,
                 prior: InertiaPrior | None, layout: TermLayout) -> None:
        self.sim, self.log, self.kp, self.kd = sim, log, kp, kd
        self.controller, self.layout = controller, layout
        self.scale, self.threads, self.prior = scale, threads, prior
        self.evaluations = 0
        n_bodies = 0 if prior is None else prior.estimate.size // 10
        self.typical = np.concatenate([layout.per_entry(TYPICAL),
                                       np.full(10 * n_bodies, TYPICAL_LOG_CHOLESKY)])
        self.lower = np.concatenate([layout.per_entry(LOWER), np.full(10 * n_bodies, -np.inf)])
        self.weight = 1.0             # 1/√τ of the closed-loop rows, set once τ is known

    def start(self) -> np.ndarray:
        """The terms' starting values: the simulator's own joint terms, gain 1, delay 0."""
        own = self.sim.joint_terms()
        return np.concatenate([own[t] if t in own else np.full(self.layout.size_of(t),
                                                                 float(t == "gain"))
                               for t in self.layout.terms])

    def inertial(self, x: np.ndarray) -> np.ndarray:
        u = x[self.layout.size:]
        return np.concatenate([from_log_cholesky(u[10 * b:10 * b + 10])
                               for b in range(u.size // 10)])

    def models(self, xs: list[np.ndarray], inertials: list[np.ndarray] | None = None
               ) -> list[Any]:
        """The candidate ``MjModel`` of each ``x`` (with ``inertials``, these inertias)."""
        out, lay = [], self.layout
        for k, x in enumerate(xs):
            terms = {t: x[lay.slice(t)] for t in TERMS if t in lay.terms}
            m = self.sim.variant(*(terms.get(t) for t in TERMS))
            inertial = (inertials[k] if inertials is not None
                        else self.inertial(x) if self.prior is not None else None)
            if inertial is not None:
                write_inertias(self.sim, m, inertial)
                mujoco.mj_setConst(m, mujoco.MjData(m))
            out.append(m)
        return out

    def actuation(self, x: np.ndarray) -> tuple[np.ndarray | None, float]:
        lay = self.layout
        return (x[lay.slice("gain")] if "gain" in lay.terms else None,
                float(x[lay.slice("delay")][0]) if "delay" in lay.terms else 0.0)

    def residuals(self, xs: list[np.ndarray], inertials: list[np.ndarray] | None = None
                  ) -> np.ndarray:
        """(len(xs), rows) whitened corrections (and prior rows), one rollout batch."""
        run = closed_loop_under(self.controller, self.sim, self.models(xs, inertials),
                                self.log, self.kp, self.kd, self.threads,
                                [self.actuation(x) for x in xs])
        self.evaluations += len(xs)
        r = run.correction / self.scale
        r[run.diverged] = DIVERGED_RESIDUAL
        r = self.weight * np.nan_to_num(r, nan=DIVERGED_RESIDUAL).reshape(len(xs), -1)
        if self.prior is None:
            return r
        return np.hstack([r, np.stack([self.prior.rows(self.inertial(x)) for x in xs])])

    def noise_floor(self) -> np.ndarray:
        """(size,) per term the σ whose torque on this log equals the identification's
        residual RMS ``s_j`` of its joint: ``s_j / RMS(q̈_j)`` (armature), ``s_j / RMS(q̇_j)``
        (damping), ``s_j / RMS(sign q̇_j)`` (frictionloss); ``inf`` for the others (unused,
        :func:`~.terms.informed_threshold`)."""
        ddq = np.gradient(self.log.dq, self.log.t, axis=0)
        column = {"armature": ddq, "damping": self.log.dq, "frictionloss": np.sign(self.log.dq)}
        return np.concatenate([
            self.scale / np.maximum(np.sqrt(np.mean(column[t] ** 2, axis=0)), 1e-300)
            if t in column else np.full(self.layout.size_of(t), np.inf)
            for t in self.layout.terms])

    def jac_and_fun(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Forward-difference Jacobian and the residual at ``x``, one batch of ``p + 1``."""
        steps = FD_STEP * (np.abs(x) + self.typical)
        xs = [x] + [x + np.eye(x.size)[i] * steps[i] for i in range(x.size)]
        r = self.residuals(xs)
        return ((r[1:] - r[0]) / steps[:, None]).T, r[0]


def calibrate_simulator(result: Any, data: Dataset, mjcf: str | Path | None = None,
                        timestep: float = 0.002, integrator: str = "implicitfast",
                        controller: Controller | None = None, *, refine_inertia: bool = False,
                        terms: tuple[str, ...] = TERMS, max_iterations: int = 10,
                        threads: int = 1) -> SimulatorCalibration:
    """Calibrate the simulator-only terms (module docstring) on top of ``result``.

    Parameters
    ----------
    result : an :class:`~consistid.IdentificationResult`; its inertias are kept (or refined),
        its ``Ia``, ``fv``, ``fc``, where identified, are the starting values, else 0.
    data : one continuous recording with torques (the training data of ``result``, or more).
    mjcf : the user's MJCF file (loaded as is, not changed); default the robot's
        dynamics-only MJCF.
    timestep, integrator : the user's simulator (``RolloutOptions`` explains them).
    controller : the closed-loop replay's :class:`PDGains` (default ω = 20 rad/s, ζ = 1) or
        :class:`ComputedTorque` (then the correction minimised is the computed torque minus
        the logged one; one ``mj_step`` loop per candidate, slower than the PD's batch).
    refine_inertia : also refine the inertias by output error, through each body's
        log-Cholesky parameters (consistent by construction, :mod:`.logcholesky`), paying the
        inverse-dynamics cost of moving them (:class:`InertiaPrior`): for short or poorly
        exciting runs, where the positions the robot reached tell more than the torques. Ten
        more rollouts per body and Jacobian.
    terms : the simulator terms fitted (:mod:`.terms`): ``"armature"``, ``"damping"``,
        ``"frictionloss"`` (default), ``"gain"`` (per joint) and ``"delay"`` (one; both under
        the PD replay only). A term the data do not inform (its σ at the answer above half
        its magnitude and above its noise floor, :func:`~.terms.informed_threshold`; for
        gain and delay above 0.1 and 5 ms) is held at its start, the others fitted
        again, and named in a :class:`~consistid.errors.PoorExcitationWarning` and in
        ``uninformed``.
    max_iterations : Gauss–Newton iterations (Jacobians), ≥ 1.
    threads : threads of ``mujoco.rollout``.

    Returns
    -------
    SimulatorCalibration
    """
    options = RolloutOptions(timestep=timestep, integrator=integrator,
                             controller=controller or PDGains(), threads=threads)
    check_number("max_iterations", max_iterations, 1, integer=True)
    if not all(hasattr(result, a) for a in ("model", "parameters", "parameter_names", "rms",
                                            "sigma", "base")):
        raise OptionError(f"calibrate_simulator: result must be an IdentificationResult, got "
                          f"{type(result).__name__}")
    terms = check_terms(terms)
    if isinstance(options.controller, ComputedTorque) and {"gain", "delay"} & set(terms):
        raise OptionError(f"terms={terms!r}: gain and delay act on the logged torque and are "
                          "calibrated under the PD replay; give controller=PDGains(...) or "
                          "leave them out of terms")
    if not isinstance(data, Dataset) or data.nv != result.model.nv:
        raise DatasetError(f"calibrate_simulator: data must be a Dataset of the result's "
                           f"{result.model.nv} joints (one recording with torques), got "
                           f"{type(data).__name__}"
                           + (f" of {data.nv} joints" if isinstance(data, Dataset) else ""))
    started = time.perf_counter()
    sim = build_simulator(result.model, result.parameters, result.parameter_names, mjcf=mjcf,
                          timestep=options.timestep, integrator=options.integrator)
    log = LogGrid.from_dataset(data, float(sim.mj_model.opt.timestep))
    kp, kd = options.controller.resolve(sim.mass_diagonal(log.q[::max(1, log.t.size // 50)]))
    scale = np.maximum(np.asarray(result.rms(data), dtype=float), 1e-6)
    prior = InertiaPrior.of(result, data) if refine_inertia else None
    layout = TermLayout(terms, sim.nv)
    problem = _Problem(sim, log, options.controller, kp, kd, scale, options.threads, prior,
                       layout)
    start = problem.start()
    x0 = start if prior is None else np.concatenate(
        [start, *(to_log_cholesky(prior.estimate[10 * b:10 * b + 10])
                  for b in range(prior.estimate.size // 10))])
    n_out = (log.t.size - 1) * sim.nv
    r0 = problem.residuals([x0])[0][:n_out]
    problem.weight, tau = _row_weight(r0, log, sim.nv)
    n = layout.size
    names = layout.names(sim.joint_names)
    fit = gauss_newton(problem, x0, max_iterations)
    held = np.empty(0, dtype=int)
    cov = _final_covariance(result, problem, fit, n_out, tau, held)
    std = np.sqrt(np.diag(cov))[:n]
    # hold the uninformed terms at their start and fit the others again, until every term
    # left free is informed by its final σ (held only grows: at most n rounds); a held term
    # keeps the σ it was judged by (held, it has no inertia share, and its conditional σ
    # would read as informed)
    while (more := np.setdiff1d(_uninformed(std, layout, fit.x, start, problem), held)).size:
        judged = std[more]
        held = np.union1d(held, more)
        x1 = fit.x.copy()
        x1[held] = x0[held]
        fit = gauss_newton(problem, x1, max_iterations, np.isin(np.arange(x0.size), held))
        cov = _final_covariance(result, problem, fit, n_out, tau, held)
        kept = std[held].copy()
        std = np.sqrt(np.diag(cov))[:n]
        std[held] = kept
        std[more] = judged
    _warn_uninformed(std, layout, fit.x, start, problem, names, held)
    inertial = problem.inertial(fit.x) if prior is not None else result.inertial_parameters
    base, base_std = _physical(result, problem, fit.x, cov)
    return SimulatorCalibration(result, names, start, fit.x[:n], std,
                                float(sim.mj_model.opt.timestep),
                                integrator_name(int(sim.mj_model.opt.integrator)), kp, kd,
                                float(np.mean(r0 ** 2)),
                                float(np.mean(fit.fun[:n_out] ** 2)) / problem.weight ** 2,
                                problem.evaluations, time.perf_counter() - started, fit.message,
                                inertial, base, base_std, prior is not None,
                                "computed torque" if isinstance(options.controller,
                                                                ComputedTorque) else "PD",
                                tuple(names[k] for k in held))


def _final_covariance(result: Any, problem: _Problem, fit: "Fit", n_out: int, tau: float,
                      held: np.ndarray) -> np.ndarray:
    """The covariance reported: the output-error fit's (:func:`_covariance`, ``ŝ²`` its mean
    square × ``τ``) plus, unless the inertias were refined, their uncertainty's share
    (:func:`_inertia_share`). Which terms are informed is decided on this one, the σ the user
    reads."""
    cov = _covariance(fit.jac, n_out, float(np.mean(fit.fun[:n_out] ** 2)) * tau)
    if problem.prior is None:
        n = problem.layout.size
        cov[:n, :n] += _inertia_share(result, problem, fit, n_out, held)
    return cov


def _uninformed(std: np.ndarray, layout: TermLayout, x: np.ndarray, start: np.ndarray,
                problem: _Problem) -> np.ndarray:
    """Indices of the simulator terms the data do not inform: σ (with the inertias' share,
    :func:`_final_covariance`) above its threshold (:func:`~.terms.informed_threshold`: a
    fraction of the term's own magnitude, or a noise floor for a term near zero)."""
    threshold = informed_threshold(layout, x[:layout.size], start, problem.noise_floor())
    return np.flatnonzero(~(std <= threshold))


def _warn_uninformed(std: np.ndarray, layout: TermLayout, x: np.ndarray, start: np.ndarray,
                     problem: _Problem, names: tuple[str, ...], held: np.ndarray) -> None:
    """Name the ``held`` terms, their σ and threshold, in a :class:`PoorExcitationWarning`."""
    n = layout.size
    threshold = informed_threshold(layout, x[:n], start, problem.noise_floor())
    if held.size:
        listed = ", ".join(f"{names[k]} (σ {std[k]:.3g} > {threshold[k]:.3g})" for k in held)
        warnings.warn(f"calibrate_simulator: the data do not inform {listed}; held at their "
                      "start values (the identification's, gain 1, delay 0) and listed in "
                      ".uninformed: record a run that moves these joints (velocity reversals "
                      "for frictionloss, changing torques for gain and delay) or leave them "
                      "out of terms=", PoorExcitationWarning, stacklevel=3)


def _inertia_share(result: Any, problem: _Problem, fit: "Fit", n_out: int,
                   held: np.ndarray) -> np.ndarray:
    r"""The simulator terms' covariance due to the physical inertias' uncertainty.

    The terms are fitted with the inertias ``π`` held at the identification's ``π̂``; their
    answer moves with ``π`` as ``∂θ̂/∂π = −(J_θᵀJ_θ)⁻¹ J_θᵀ ∂r/∂π`` (implicit function
    theorem at the minimum), so ``Cov θ ⊇ G Cov_π Gᵀ``. ``Cov_π = K⁺ Cov_β K⁺ᵀ`` is the
    identified base covariance mapped to the inertial columns of the base map ``K`` (a
    direction the data do not inform moves no torque and no rollout).

    The derivative is taken in each body's log-Cholesky coordinates ``u`` (:mod:`.logcholesky`),
    where every point is a physically consistent body: ``Cov_u = L⁻¹ Cov_π L⁻ᵀ`` with
    ``L = ∂π/∂u`` at ``û`` (:func:`_log_cholesky_jacobian`; ``L Cov_u Lᵀ = Cov_π``, the same
    first-order propagation), and ``∂r/∂u`` along each principal direction ``d`` of ``Cov_u``
    (one σ long) by central differences ``(r(û + s d) − r(û − s d)) / 2s`` with
    ``s =`` :data:`INERTIA_STEP`, shortened so that no coordinate moves by more than
    :data:`MAX_LOG_CHOLESKY_STEP` (a logarithm's step is a relative one). Every perturbed
    body is consistent by construction, so none is clipped by :func:`~.engine.write_inertias`
    (a step of a tenth of σ in ``π`` itself left most perturbed bodies inconsistent, their
    negative moments clipped, and σ ten times that of a small step). Added to the conditional
    covariance as independent (the calibration data and the identification's are often the
    same: then this errs on the wide side).
    """
    p = result.model.n_inertial
    cov_beta = np.asarray(result.base_covariance, dtype=float)
    k_inertial = np.linalg.pinv(np.asarray(result.base.matrix, dtype=float)[:, :p])
    if not np.all(np.isfinite(cov_beta)):
        warnings.warn("calibrate_simulator: the identification's base covariance is not finite "
                      "(a direction its data did not inform); the σ of the simulator terms are "
                      "conditional on the inertias (refine_inertia=True fits them jointly)",
                      PoorExcitationWarning, stacklevel=4)
        return np.zeros((problem.layout.size,) * 2)
    cov_pi = k_inertial @ cov_beta @ k_inertial.T
    u0 = np.concatenate([to_log_cholesky(b) for b in
                         np.asarray(result.inertial_parameters, float).reshape(-1, 10)])
    jac_u = _log_cholesky_jacobian(u0)
    cov_u = np.linalg.solve(jac_u, np.linalg.solve(jac_u, cov_pi).T)
    w, v = np.linalg.eigh(0.5 * (cov_u + cov_u.T))
    keep = w > 1e-12 * max(w.max(), 1e-300)
    directions = (v[:, keep] * np.sqrt(w[keep])).T            # one σ along each
    steps = np.minimum(INERTIA_STEP,
                       MAX_LOG_CHOLESKY_STEP / np.max(np.abs(directions), axis=1))
    moved = [u0 + sign * s * d for s, d in zip(steps, directions) for sign in (1.0, -1.0)]
    rs = problem.residuals([fit.x] * len(moved),
                           [_inertial_of(u) for u in moved])[:, :n_out]
    sens = ((rs[0::2] - rs[1::2]) / (2.0 * steps[:, None])).T  # (rows, directions)
    n = problem.layout.size
    free = np.setdiff1d(np.arange(n), held)
    jac = fit.jac[:n_out][:, free]
    g = np.zeros((n, len(directions)))
    g[free] = -np.linalg.lstsq(jac, sens, rcond=None)[0]
    return g @ g.T


def _inertial_of(u: np.ndarray) -> np.ndarray:
    """The standard inertial vector of stacked log-Cholesky vectors (10 per body)."""
    return np.concatenate([from_log_cholesky(b) for b in u.reshape(-1, 10)])


def _log_cholesky_jacobian(u: np.ndarray) -> np.ndarray:
    """``∂π/∂u`` (block diagonal, one 10 × 10 block per body) by central differences of
    :func:`~.logcholesky.from_log_cholesky` (a polynomial in ``exp u₀…₃`` and ``u₄…₉``, step
    1e-6: error ~1e-12 relative)."""
    out = np.zeros((u.size, u.size))
    for b in range(u.size // 10):
        blk = slice(10 * b, 10 * b + 10)
        for i in range(10):
            du = np.zeros(10)
            du[i] = 1e-6 * max(1.0, abs(u[blk][i]))
            out[blk, 10 * b + i] = (from_log_cholesky(u[blk] + du)
                                    - from_log_cholesky(u[blk] - du)) / (2.0 * du[i])
    return out


def _row_weight(r: np.ndarray, log: LogGrid, nv: int) -> tuple[float, float]:
    """``(1/√(v τ), τ)`` for the closed-loop rows ``r`` at the start: ``v`` their mean square,
    ``τ`` their integrated autocorrelation time (samples), so that ``S·nv`` correlated rows
    count as the ``S·nv/τ`` independent ones they are worth, each of unit variance beside the
    inertia prior's rows."""
    grid = Dataset(t=log.t[:-1], q=log.q[:-1], dq=log.dq[:-1], ddq=np.zeros_like(log.q[:-1]),
                   tau=log.tau[:-1])
    tau = max(1.0, float(np.max(autocorrelation_time(grid, r.reshape(-1, nv)))))
    return 1.0 / np.sqrt(max(float(np.mean(r ** 2)), 1e-12) * tau), tau


def _covariance(jac: np.ndarray, n_out: int, s2: float) -> np.ndarray:
    """``(J_oᵀJ_o / ŝ² + J_pᵀJ_p)⁻¹``: the closed-loop rows ``J_o`` (the first ``n_out``) with
    their variance ``ŝ²`` at the answer (mean square × τ: correlated rows, the sandwich's
    leading term), the inertia prior's rows ``J_p`` with unit variance; ``inf`` on the diagonal
    of a parameter in a direction neither informs (an eigenvalue below 1e-12 of the largest)."""
    j_out, j_prior = jac[:n_out], jac[n_out:]
    w, v = np.linalg.eigh(j_out.T @ j_out / max(s2, 1e-300) + j_prior.T @ j_prior)
    informed = w > 1e-12 * max(w.max(), np.finfo(float).tiny)
    cov = (v[:, informed] / w[informed]) @ v[:, informed].T
    blind = np.any(np.abs(v[:, ~informed]) > 1e-3, axis=1)
    cov[blind, blind] = np.inf
    return cov


def _physical(result: Any, problem: _Problem, x: np.ndarray, cov: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """The base parameters and their σ: the identification's, or, refined, ``β = K π(u)``
    with ``Cov β = K G Cov_u Gᵀ Kᵀ`` (``G = ∂π/∂u``, forward differences)."""
    if problem.prior is None:
        return np.asarray(result.base_parameters, float), np.asarray(result.std, float)
    n, p = problem.layout.size, result.model.n_inertial
    params = np.asarray(result.parameters, float).copy()
    params[:p] = problem.inertial(x)
    k = np.asarray(result.base.matrix, float)[:, :p]
    g = np.empty((p, x.size - n))
    for i in range(x.size - n):
        dx = np.zeros_like(x)
        dx[n + i] = 1e-7 * (1.0 + abs(x[n + i]))
        g[:, i] = (problem.inertial(x + dx) - params[:p]) / dx[n + i]
    cov_u = cov[n:, n:]
    with np.errstate(invalid="ignore"):
        var = np.einsum("ij,jk,ik->i", k @ g, np.nan_to_num(cov_u, posinf=0.0), k @ g)
    return result.base.project(params), np.sqrt(np.clip(var, 0.0, None))


@dataclass(frozen=True, eq=False)
class Fit:
    """What :func:`gauss_newton` found: ``x``, the residual ``fun`` and Jacobian ``jac`` there,
    and why it stopped."""

    x: np.ndarray
    fun: np.ndarray
    jac: np.ndarray
    message: str


#: Step lengths tried at each Gauss–Newton iteration (one batch of rollouts).
STEP_LENGTHS = (1.0, 0.3, 0.1, 0.03)
#: Stop when an iteration lowers the cost by less than this fraction.
RELATIVE_DECREASE = 1e-4


def gauss_newton(problem: _Problem, x0: np.ndarray, max_iterations: int,
                 fixed: np.ndarray | None = None) -> Fit:
    r"""Bounded Gauss–Newton (``x ≥ problem.lower``) on ``problem``'s residual, the variables
    ``fixed`` (a mask) held at ``x0``.

    Each iteration solves ``(JᵀJ + λ diag JᵀJ) δ = −Jᵀr`` over the free variables (a variable
    at its bound whose step points out of the box is held there, and the system solved again
    without it), tries the step lengths :data:`STEP_LENGTHS` in one batch, keeps the best if it
    lowers the cost (``λ`` ÷ 10) or raises ``λ`` × 10; it stops when the cost falls by less
    than :data:`RELATIVE_DECREASE` or after ``max_iterations`` Jacobians (Nocedal & Wright,
    *Numerical Optimization*, 2nd ed., §10.3, doi:10.1007/978-0-387-40065-5).
    """
    lower = problem.lower
    fixed = np.zeros(x0.size, dtype=bool) if fixed is None else fixed
    x, lam = np.maximum(x0, lower), 1e-2
    jac, r = problem.jac_and_fun(x)
    cost = float(r @ r)
    message = f"stopped after {max_iterations} iterations (max_iterations)"
    for _ in range(max_iterations):
        step = _step(jac, r, x <= lower, lam, fixed)
        xs = [np.maximum(x + a * step, lower) for a in STEP_LENGTHS]
        rs = problem.residuals(xs)
        costs = np.einsum("ij,ij->i", rs, rs)
        best = int(np.argmin(costs))
        if costs[best] >= cost:
            lam *= 10.0
            if lam > 1e6:
                message = "no step lowers the cost (converged)"
                break
            continue
        decrease = (cost - costs[best]) / cost
        x, lam = xs[best], max(lam / 10.0, 1e-9)
        jac, r = problem.jac_and_fun(x)
        cost = float(r @ r)
        if decrease < RELATIVE_DECREASE:
            message = f"cost decrease below {RELATIVE_DECREASE:g} (converged)"
            break
    return Fit(x, r, jac, message)


def _step(jac: np.ndarray, r: np.ndarray, at_bound: np.ndarray, lam: float,
          fixed: np.ndarray) -> np.ndarray:
    """The damped Gauss–Newton step with the lower bounds as an active set (``at_bound``: the
    variables on theirs), zero for the ``fixed`` ones."""
    a, g = jac.T @ jac, jac.T @ r
    free = ~fixed
    step = np.zeros(at_bound.size)
    for _ in range(2):
        sub = a[np.ix_(free, free)]
        damped = sub + lam * np.diag(np.diag(sub)) + 1e-12 * np.trace(sub) * np.eye(free.sum())
        step[:] = 0.0
        step[free] = np.linalg.solve(damped, -g[free])
        blocked = at_bound & (step < 0.0)
        if not blocked.any():
            break
        free &= ~blocked
    return step

"""An identification fitted on joint angles that look like degrees read as radians: said.

The same numbers in degrees are 57.3 × larger positions and speeds; a fit of the robot's
torques to them is poorly conditioned (velocity products 3 300 × larger) and often ends
``optimal_inaccurate``, yet every body may still read "consistent". :func:`flag_degrees` makes
such an answer loud: when the data look like degrees (:func:`consistid.data.units.
degree_suspects`) *and* the fit shows it — a solver status other than ``optimal`` or
``cond(W_b) >`` :data:`~consistid.identification.base.COND_WARN` — it warns
:class:`~consistid.errors.ModelMisfitWarning` and records the sentence in the result's
``details["angle unit"]`` (shown by ``summary()``, the report and the saved file).
"""

from __future__ import annotations

import dataclasses
import warnings

from ..data.dataset import Dataset
from ..data.units import degree_suspects, model_limits, revolute_joints
from ..errors import ModelMisfitWarning
from .base import COND_WARN
from .result import IdentificationResult


def flag_degrees(res: IdentificationResult, dataset: object,
                 stacklevel: int = 3) -> IdentificationResult:
    """``res`` as it is, or with ``details["angle unit"]`` and a
    :class:`ModelMisfitWarning` when ``dataset`` (a :class:`Dataset`; streams are not
    checked) looks like degrees and the fit is inaccurate or poorly conditioned."""
    if not isinstance(dataset, Dataset):
        return res
    model = res.model
    found = degree_suspects(dataset.q, dataset.dq, model.joint_names, revolute_joints(model),
                            model_limits(model))
    status = getattr(res.solver, "status", None)
    shows = [f"the solver ended {status!r}"] if status not in (None, "optimal") else []
    if res.condition_number > COND_WARN:
        shows.append(f"cond(W_b) = {res.condition_number:.3g}")
    if not (found and shows):
        return res
    text = (f"{' and '.join(shows)} on joint positions that look like degrees read as "
            f"radians ({'; '.join(found[:4])}{' …' if len(found) > 4 else ''}): these "
            "parameters, their σ and the consistency verdict describe data in other units, not "
            "the robot. Load the log with angle_unit=\"deg\" ([data] angle_unit = \"deg\") and "
            "identify again")
    warnings.warn(text, ModelMisfitWarning, stacklevel=stacklevel)
    return dataclasses.replace(res, details={**res.details, "angle unit": text})

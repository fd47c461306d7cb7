"""Confidence intervals labelled by parameter, as statsmodels gives them.

``IdentificationResult.conf_int()`` returns a pandas ``DataFrame``: one row per base
parameter, indexed by its name (``*`` marks a regrouped one, :mod:`.base`), columns ``lower``
and ``upper`` — the normal interval ``β̂ ∓ z_{1−α/2} σ_β`` — and the level in ``attrs``.
pandas is imported here, where it is first needed (the ``[io]`` extra); without it a
:class:`~consistid.errors.MissingDependencyError` says how to install it, and
``conf_int(labelled=False)`` gives the bare ``(b, 2)`` array.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from ..errors import MissingDependencyError
from ..report.result import normal_intervals


def interval_frame(estimate: np.ndarray, std: np.ndarray, names: Sequence[str],
                   alpha: float = 0.05) -> Any:
    """The ``1 − alpha`` normal intervals of ``estimate`` (σ ``std``) as a ``DataFrame``
    indexed by ``names`` (index name ``"parameter"``), columns ``lower``, ``upper``;
    ``frame.attrs["alpha"]`` is ``alpha``."""
    intervals = normal_intervals(estimate, std, alpha)
    try:
        import pandas as pd
    except ImportError:
        raise MissingDependencyError(
            "conf_int() labels the intervals in a pandas DataFrame: pip install "
            "'consistid[io]' (or pandas); conf_int(labelled=False) gives the (n, 2) array "
            "without it") from None
    frame = pd.DataFrame(intervals, index=pd.Index([str(n) for n in names], name="parameter"),
                         columns=["lower", "upper"])
    frame.attrs["alpha"] = float(alpha)
    return frame

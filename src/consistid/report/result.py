"""What every result object offers, whatever it estimates.

The same words mean the same thing on every result of consistid:

============== =========================================================================
``std``        standard deviations of the result's *estimate vector* (the base parameters
               of an identification, the tilt angles of a mounting estimate, the ten
               payload parameters …), in its units; ``inf`` for a direction the data did
               not inform
``covariance`` the covariance of that vector (same order as ``std``)
``conf_int``   ``(n, 2)`` two-sided normal intervals of that vector at level ``1 − alpha``
``summary()``  the text report (what ``print(result)`` shows)
``report(p)``  one self-contained HTML page at ``p`` (``*.html``), returns its path
``_repr_html_`` the same page's body, for notebooks
============== =========================================================================

:class:`Reported` supplies ``report``, ``_repr_html_`` and ``conf_int`` from a result's
:meth:`~Reported.page` and its ``estimate``/``std``; each result builds its own page from real
tables (:mod:`consistid.report.html`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.stats import norm

from ..errors import OptionError
from .html import Page


def normal_intervals(estimate: np.ndarray, std: np.ndarray, alpha: float = 0.05) -> np.ndarray:
    """``estimate ∓ z_{1−α/2} σ`` as an ``(n, 2)`` array; ``alpha`` in (0, 1)."""
    if not 0.0 < float(alpha) < 1.0:
        raise OptionError(f"alpha = {alpha!r}: the interval level 1 − alpha needs 0 < alpha < 1")
    z = norm.ppf(1.0 - float(alpha) / 2.0)
    estimate, std = np.asarray(estimate, dtype=float), np.asarray(std, dtype=float)
    return np.column_stack([estimate - z * std, estimate + z * std])


class Reported:
    """Mixin: ``report(path)``, ``_repr_html_`` and ``conf_int`` from :meth:`page`,
    ``estimate`` and ``std`` (module docstring)."""

    def summary(self) -> str:  # pragma: no cover - every subclass defines it
        raise NotImplementedError

    def page(self) -> Page:  # pragma: no cover - every subclass defines it
        raise NotImplementedError

    @property
    def estimate(self) -> np.ndarray:  # pragma: no cover - every subclass defines it
        raise NotImplementedError

    def conf_int(self, alpha: float = 0.05) -> np.ndarray:
        """``(n, 2)`` normal confidence intervals of :attr:`estimate` at level ``1 − alpha``."""
        return normal_intervals(self.estimate, self.std, alpha)

    def report(self, path: str | Path) -> Path:
        """Write the HTML report (``*.html``) and return its path."""
        path = Path(path)
        if path.suffix.lower() not in (".html", ".htm"):
            raise OptionError(f"report path {str(path)!r}: give an .html file")
        return self.page().write(path)

    def _repr_html_(self) -> str:
        return self.page().fragment()

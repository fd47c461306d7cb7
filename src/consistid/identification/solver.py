"""Solving a cvxpy problem under consistid's status contract.

:func:`solve` calls cvxpy and turns the status into: optimal → a
:class:`SolverReport`; ``optimal_inaccurate`` → the same plus an
:class:`~consistid.errors.InaccurateSolutionWarning`; infeasible → :class:`InfeasibleError`;
anything else (or no values) → :class:`IdentificationError`. Never a silent ``None`` (the cvxpy
behaviour the style guide warns about). An unknown or uninstalled solver name is an
:class:`~consistid.errors.OptionError` (:func:`check_solver`), never a substitution. Used by
:mod:`consistid.identification.sdp`, :mod:`consistid.estimation.recover` and
:mod:`consistid.estimation.payload`.
"""

from __future__ import annotations

import functools
import time
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ..errors import (IdentificationError, InaccurateSolutionWarning, InfeasibleError,
                      OptionError, SolverError)

if TYPE_CHECKING:
    import cvxpy as cp

#: Default solver: interior point, accurate on the semidefinite cone (SCS is not; stack notes).
DEFAULT_SOLVER = "CLARABEL"


@dataclass(frozen=True)
class SolverReport:
    """What ran and how it ended: never a bare success flag."""

    name: str
    status: str
    solve_time: float
    compile_time: float = 0.0
    iterations: int | None = None

    def __str__(self) -> str:
        it = f", {self.iterations} iterations" if self.iterations is not None else ""
        return (f"{self.name}: {self.status} (solve {self.solve_time * 1e3:.1f} ms, "
                f"setup {self.compile_time * 1e3:.1f} ms{it})")


@functools.lru_cache(maxsize=1)
def _installed_solvers() -> tuple[str, ...]:
    """``cvxpy.installed_solvers()``, asked once per process: it imports every solver interface
    and took ~4 ms (14 ms on a loaded machine) per call, i.e. per :func:`solve` of a re-solved
    parametrised program (:mod:`consistid.online.projection`)."""
    import cvxpy as cp  # heavy: loaded with the first conic solve

    return tuple(cp.installed_solvers())


def check_solver(solver: str) -> str:
    """The cvxpy name of ``solver`` (case-insensitive, returned upper-case).

    Raises :class:`OptionError` naming the installed solvers unless ``solver`` is one of them.
    """
    installed = _installed_solvers()
    name = str(solver).upper()
    if name not in installed:
        raise OptionError(f"solver={solver!r} is not supported (not a cvxpy solver, or not "
                          f"installed); installed: {', '.join(installed)}")
    return name


def solve(problem: cp.Problem, what: str, solver: str = DEFAULT_SOLVER,
          options: dict[str, Any] | None = None) -> SolverReport:
    """Solve ``problem`` and map its status to a report, a warning or an exception.

    Parameters
    ----------
    problem : the cvxpy problem.
    what : a short description used in messages, e.g. ``"exact recovery"``.
    solver : a cvxpy solver name (any case); an unknown or uninstalled one raises
        :class:`OptionError` (no substitution).
    options : keyword options passed to the solver.

    Raises
    ------
    OptionError : ``solver`` is not an installed cvxpy solver, or it refused ``options``.
    InfeasibleError : the solver proved (or nearly proved) infeasibility.
    SolverError : the solver crashed (a Rust ``PanicException`` from Clarabel, a cvxpy
        ``SolverError``) or cvxpy refused the problem data.
    IdentificationError : the solver returned no solution (status named).
    """
    import cvxpy as cp  # heavy: loaded with the first conic solve

    solver = check_solver(solver)
    start = time.perf_counter()
    try:
        with warnings.catch_warnings():
            # cvxpy's own "Solution may be inaccurate" would duplicate the warning issued below.
            warnings.filterwarnings("ignore", message="Solution may be inaccurate")
            problem.solve(solver=solver, **(options or {}))
    except cp.error.SolverError as exc:
        raise SolverError(f"{what}: solver {solver} failed ({exc}). Hint: check the data for "
                          "extreme magnitudes (|values| ≫ 1e8 or ≪ 1e-8 of the others); "
                          "another solver may help") from exc
    except (TypeError, ValueError) as exc:
        if not options:
            raise SolverError(f"{what}: cvxpy refused the problem before solver {solver} ran: "
                              f"{exc}") from exc
        raise OptionError(f"{what}: solver {solver} could not run with the options "
                          f"{options}: {exc}") from exc
    except (KeyboardInterrupt, SystemExit, GeneratorExit):
        raise
    except BaseException as exc:  # noqa: BLE001 - Clarabel's Rust panic is a BaseException
        # pyo3's PanicException derives from BaseException so that `except Exception` does not
        # swallow it; a crashed solve is a named SolverError here, which callers do catch.
        raise SolverError(f"{what}: solver {solver} crashed ({type(exc).__name__}: {exc}). "
                          "This is a solver bug, usually triggered by extreme or degenerate "
                          "data; check the inputs' magnitudes, or pass solver='SCS' to try "
                          "another solver") from exc
    wall = time.perf_counter() - start
    stats = problem.solver_stats
    status = problem.status
    solve_time = float(stats.solve_time) if stats and stats.solve_time is not None else wall
    report = SolverReport(solver, status, solve_time, max(wall - solve_time, 0.0),
                          None if stats is None else stats.num_iters)
    if status in (cp.INFEASIBLE, cp.INFEASIBLE_INACCURATE):
        raise InfeasibleError(f"{what}: the constraints admit no solution (solver {solver} "
                              f"status {status!r})")
    if status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) or any(
            v.value is None for v in problem.variables()):
        raise IdentificationError(f"{what}: solver {solver} returned status {status!r}")
    if status == cp.OPTIMAL_INACCURATE:
        warnings.warn(f"{what}: solver {solver} stopped at reduced accuracy ({status}); check "
                      "the reported residuals and margins", InaccurateSolutionWarning,
                      stacklevel=3)
    return report

r"""The consistent SDP canonicalised once per structure and re-solved with Clarabel directly.

:mod:`consistid.identification.sdp` solves, in whitened variables ``w``,

.. math::  \min_w \|G w - h\|^2 + \gamma f(\theta) \quad\text{s.t.}\quad \theta \in \mathcal K,
           \qquad \theta = \theta_c + \Phi w,\; G = R\Phi,\; h = z - R\theta_c,

where the prior term ``f`` and the constraint set ``𝒦`` (LMIs, boxes, bounds, neighbourhoods)
depend only on the model, the regressor columns and the options, while ``(θ_c, Φ, G, h, γ)``
change with the data, ``σ`` and every re-weighting or refinement pass. So the part that does not
change is handed to cvxpy once, in prior-normalised variables ``y`` (``θ = T y``, ``T`` the
per-body congruence of :class:`~consistid.identification.constraints.BodyScaling`), and its
canonical conic form (Clarabel's standard form, O'Donoghue et al. / Goulart & Chen 2024,
"Clarabel: an interior-point solver for conic programs with quadratic objectives",
arXiv:2405.12762)

.. math::  \min_x \tfrac12 x^\top P x + c^\top x \quad\text{s.t.}\quad A x + s = b,\; s \in K,
           \qquad x = (y, u),

is stored (``u``: cvxpy's auxiliary variables, e.g. the log-det epigraph). Each solve substitutes
``y = T⁻¹θ_c + T⁻¹Φ w`` (dense matrix products of size ``rows × p × p``), scales the prior's
``P`` and ``c`` by ``γ``, adds the data term ``2 GᵀG`` and ``−2 Gᵀh`` to the ``w`` block, and calls
Clarabel: no cvxpy canonicalisation per solve. Rows of the non-negative cone are normalised to unit
length after the substitution (a positive row scaling: the feasible set is unchanged), which for
the friction bounds is the unit scale :mod:`~consistid.identification.sdp` used before.

Mathematically the program is the one :func:`consistid.identification.sdp.identify_sdp` builds
afresh with ``scale=True``; the answers agree to the solver's tolerance (tests/test_program.py).
Compiled programs are cached by content (``consistid.identification.sdp``'s structure key: the
prior, the names, the regressor columns and every option that shapes the program, not the model
object, so that a model rebuilt with the same inertias, e.g. by ``model.with_parameters`` in a
diagnosis refit, reuses it), the :data:`CACHE_SIZE` most recently used.
"""

from __future__ import annotations

import threading
import time
import warnings
from collections import OrderedDict
from typing import Any, Callable, Hashable, Sequence

import cvxpy as cp
import numpy as np
import scipy.sparse as sp
from cvxpy.reductions.solvers.conic_solvers.clarabel_conif import CLARABEL, dims_to_solver_cones

from ..errors import (
    IdentificationError,
    InaccurateSolutionWarning,
    InfeasibleError,
    OptionError,
    SolverError,
)

#: Compiled structures kept (least recently used dropped first).
CACHE_SIZE = 16

_CACHE: "OrderedDict[Hashable, CompiledProgram]" = OrderedDict()
_CACHE_LOCK = threading.Lock()

Labelled = Sequence[tuple[cp.Constraint, tuple[str, ...]]]



def constraint_slacks(con: cp.Constraint, labels: Sequence[str], value: np.ndarray
                      ) -> list[tuple[str, float]]:
    """``(label, slack)`` of one constraint whose expression has ``value``: ``−expr`` per entry
    for inequalities; for an LMI its smallest eigenvalue over ``max(1, largest)`` (relative to
    the matrix's size: interior-point accuracy is relative)."""
    if isinstance(con, cp.constraints.PSD):
        lam = np.linalg.eigvalsh(0.5 * (value + value.T))
        return [(labels[0], float(lam[0] / max(1.0, abs(lam[-1]))))]
    return list(zip(labels, (-value).ravel().tolist()))

class CompiledProgram:
    """A program structure in variables ``y`` (``θ = T y``), canonicalised once (module
    docstring).

    Parameters
    ----------
    problem : the cvxpy problem over ``y``: every constraint, and the prior term at ``γ = 1``
        as objective (``cp.Minimize(0)`` without a prior).
    y : its (p,) variable.
    t_map : (p, p) ``T``.
    labelled : ``(constraint, labels)`` pairs of ``problem`` (labels name each row).
    unit_rows : ``(k, columns)``: ``labelled[k]`` is ``θ[columns] ≥ 0``, whose slacks are
        reported in the unit scale of the whitening (``θ_i / ‖Φ_i‖``), as the fresh program's.
    euclidean : ``(W, π₀)`` of a Euclidean prior ``‖W (θ[:len(π₀)] − π₀)‖²`` (unit weight),
        added by :meth:`BoundProgram.standard_form` straight to the ``w`` block as a quadratic
        (as cvxpy does for the fresh program), not through cvxpy's auxiliary variables, whose
        weight ``γ`` alone left the solve inaccurate at small weights.
    """

    def __init__(self, problem: cp.Problem, y: cp.Variable, t_map: np.ndarray,
                 labelled: Labelled, unit_rows: tuple[int, np.ndarray] | None = None,
                 euclidean: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        start = time.perf_counter()
        p = y.size
        if any(v.id == y.id for v in problem.variables()):
            data, _, _ = problem.get_problem_data(cp.CLARABEL)
            offset = data[cp.settings.PARAM_PROB].var_id_to_col[y.id]
            dims = data[cp.settings.DIMS]
        else:   # no constraint and no prior: nothing for cvxpy to canonicalise
            data, offset, dims = {"A": sp.csc_array((0, p)), "b": np.zeros(0),
                                  "c": np.zeros(p), "P": None}, 0, None
        a = sp.csc_array(data["A"])
        n = a.shape[1]
        ycols = np.arange(offset, offset + p)
        ucols = np.setdiff1d(np.arange(n), ycols)
        pmat = sp.csc_array(data["P"]) if data.get("P") is not None else sp.csc_array((n, n))
        pmat = (pmat + pmat.T) / 2 if (abs(pmat - pmat.T) > 0).nnz else pmat
        self.problem, self.y, self.labelled = problem, y, tuple(labelled)
        self.unit_rows, self.euclidean = unit_rows, euclidean
        self.t_map, self.t_inv = t_map, np.linalg.inv(t_map)
        self.a_y = a[:, ycols].toarray()
        self.a_u = sp.csc_array(a[:, ucols])
        self.b = np.asarray(data["b"], dtype=float)
        c = np.asarray(data["c"], dtype=float)
        self.c_y, self.c_u = c[ycols], c[ucols]
        self.p_yy = pmat[ycols][:, ycols].toarray()
        self.p_yu = sp.csc_array(pmat[ycols][:, ucols])
        self.p_uu = sp.csc_array(pmat[ucols][:, ucols])
        self.cones = [] if dims is None else dims_to_solver_cones(dims)
        self.nonneg = (slice(0, 0) if dims is None
                       else slice(int(dims.zero), int(dims.zero) + int(dims.nonneg)))
        self.n_u = ucols.size
        self.lock = threading.Lock()
        self.compile_time = time.perf_counter() - start
        self.solves = 0

    def bind(self, theta_c: np.ndarray, phi: np.ndarray, r: np.ndarray, z: np.ndarray,
             gamma: float) -> "BoundProgram":
        """This structure with the data of one pass (module docstring)."""
        return BoundProgram(self, theta_c, phi, r, z, gamma)


class _Value:
    """A stand-in for a cvxpy variable's ``value`` (the whitened ``w``)."""

    value: np.ndarray | None = None


class BoundProgram:
    """A :class:`CompiledProgram` with ``θ_c, Φ, R, z, γ``: the interface of
    :mod:`~consistid.identification.sdp`'s built programs (``problem``, ``w``, ``theta_c``,
    ``phi``, ``labelled``, :meth:`theta`, :meth:`slacks`) plus :meth:`solve`."""

    def __init__(self, compiled: CompiledProgram, theta_c: np.ndarray, phi: np.ndarray,
                 r: np.ndarray, z: np.ndarray, gamma: float) -> None:
        self.compiled, self.theta_c, self.phi = compiled, theta_c, phi
        self.r, self.z, self.gamma = r, z, float(gamma)
        self.problem, self.labelled = compiled.problem, compiled.labelled
        self.w = _Value()

    def theta(self) -> np.ndarray:
        return self.theta_c + self.phi @ self.w.value

    def slacks(self) -> list[tuple[str, float]]:
        """``(label, slack)`` of every constraint at ``w.value`` (as the fresh program's)."""
        with self.compiled.lock:
            self.compiled.y.value = self.compiled.t_inv @ self.theta()
            out = []
            for k, (con, labels) in enumerate(self.labelled):
                value = np.asarray(con.expr.value, dtype=float)
                if self.compiled.unit_rows is not None and k == self.compiled.unit_rows[0]:
                    cols = self.compiled.unit_rows[1]
                    value = value / np.maximum(np.linalg.norm(self.phi[cols], axis=1), 1e-300)
                out += constraint_slacks(con, labels, value)
            return out

    def standard_form(self) -> tuple[sp.csc_array, np.ndarray, sp.csc_array, np.ndarray,
                                     list]:
        """Clarabel's ``(P (upper triangle), q, A, b, cones)`` of this pass over
        ``x = (w, u, t, e)``.

        As cvxpy states a sum of squares, the data term is ``‖t‖²`` with ``t = G w − h`` (and a
        Euclidean prior ``γ‖e‖²`` with ``e = W(θ − π₀)``) as equality rows, not ``wᵀ 2GᵀG w``:
        the objective then keeps its value (χ²), on which Clarabel's relative gap is measured
        (with the constant dropped the gap was absolute, and small prior weights ended
        ``optimal_inaccurate``)."""
        c, g = self.compiled, self.gamma
        psi = c.t_inv @ self.phi
        y_c = c.t_inv @ self.theta_c
        a_w = c.a_y @ psi
        b = c.b - c.a_y @ y_c
        gm = self.r @ self.phi
        h = self.z - self.r @ self.theta_c
        eq_w, eq_b, aux_diag = [-gm], [-h], [np.full(gm.shape[0], 2.0)]
        if c.euclidean is not None and g > 0:
            w_mat, prior = c.euclidean
            eq_w.append(-(w_mat @ self.phi[:prior.size]))
            eq_b.append(w_mat @ (self.theta_c[:prior.size] - prior))
            aux_diag.append(np.full(prior.size, 2.0 * g))
        n_aux = sum(e.shape[0] for e in eq_w)
        a = sp.hstack([sp.csc_array(a_w), c.a_u], format="csr")
        rows = np.arange(c.nonneg.start, c.nonneg.stop)
        if rows.size:
            norms = np.sqrt(np.asarray(a[rows].multiply(a[rows]).sum(axis=1)).ravel())
            scale = np.ones(a.shape[0])
            scale[rows] = 1.0 / np.where(norms > 0, norms, 1.0)
            a = sp.csr_array(sp.diags_array(scale) @ a)
            b = b * scale
        a_eq = sp.hstack([sp.csc_array(np.vstack(eq_w)), sp.csc_array((n_aux, c.n_u)),
                          sp.identity(n_aux, format="csc")], format="csc")
        a_all = sp.vstack([a_eq, sp.hstack([a, sp.csc_array((a.shape[0], n_aux))])],
                          format="csc")
        p_ww = g * (psi.T @ c.p_yy @ psi)
        pmat = sp.block_array([[sp.csc_array(0.5 * (p_ww + p_ww.T)),
                                sp.csc_array(g * (psi.T @ c.p_yu)), None],
                               [None, sp.csc_array(g * c.p_uu), None],
                               [None, None, sp.diags_array(np.concatenate(aux_diag))]],
                              format="csc")
        q = np.concatenate([g * (psi.T @ (c.c_y + c.p_yy @ y_c)),
                            g * (c.c_u + c.p_yu.T @ y_c), np.zeros(n_aux)])
        import clarabel  # heavy: loaded with the first conic solve (as cvxpy does)

        cones = [clarabel.ZeroConeT(n_aux), *c.cones]
        return (sp.csc_array(sp.triu(pmat)), q, sp.csc_array(a_all),
                np.concatenate([*eq_b, b]), cones)

    def solve(self, what: str, options: dict[str, Any] | None = None) -> tuple[str, float, float,
                                                                               int]:
        """Solve with Clarabel under :mod:`consistid.identification.solver`'s contract.

        Returns ``(status, solve_time, setup_time, iterations)`` (cvxpy status names; the
        setup time of the structure's first solve includes its one-off canonicalisation); sets
        ``w.value``. Raises as :func:`consistid.identification.solver.solve` does.
        """
        start = time.perf_counter()
        pmat, q, a, b, cones = self.standard_form()
        if not (np.all(np.isfinite(pmat.data)) and np.all(np.isfinite(q))
                and np.all(np.isfinite(a.data)) and np.all(np.isfinite(b))):
            raise SolverError(f"{what}: the problem data hold NaN or inf before solver "
                              "CLARABEL ran (cvxpy refused the problem)")
        try:
            settings = CLARABEL.parse_solver_opts(False, dict(options or {}))
        except (TypeError, ValueError, AttributeError) as exc:
            raise OptionError(f"{what}: solver CLARABEL could not run with the options "
                              f"{options}: {exc}") from exc
        try:
            solution, setup = run_clarabel(pmat, q, a, b, cones, settings)
            setup -= start
        except (KeyboardInterrupt, SystemExit, GeneratorExit):
            raise
        except (TypeError, ValueError) as exc:
            raise OptionError(f"{what}: solver CLARABEL could not run with the options "
                              f"{options}: {exc}") from exc
        except BaseException as exc:  # noqa: BLE001 - Clarabel's Rust panic is a BaseException
            raise SolverError(f"{what}: solver CLARABEL crashed ({type(exc).__name__}: {exc}). "
                              "This is a solver bug, usually triggered by extreme or degenerate "
                              "data; check the inputs' magnitudes, or pass solver='SCS' to try "
                              "another solver") from exc
        status = CLARABEL.STATUS_MAP.get(str(solution.status), cp.SOLVER_ERROR)
        if self.compiled.solves == 0:        # the first solve carries the canonicalisation
            setup += self.compiled.compile_time
        self.compiled.solves += 1
        if status in (cp.INFEASIBLE, cp.INFEASIBLE_INACCURATE):
            raise InfeasibleError(f"{what}: the constraints admit no solution (solver CLARABEL "
                                  f"status {status!r})")
        if status == cp.SOLVER_ERROR:     # what cvxpy raises as its SolverError
            raise SolverError(f"{what}: solver CLARABEL failed (status {solution.status}). "
                              "Hint: check the data for extreme magnitudes (|values| ≫ 1e8 or "
                              "≪ 1e-8 of the others); another solver may help")
        x = np.asarray(solution.x, dtype=float)
        if status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) or not np.all(np.isfinite(x)):
            raise IdentificationError(f"{what}: solver CLARABEL returned status {status!r}")
        if status == cp.OPTIMAL_INACCURATE:
            warnings.warn(f"{what}: solver CLARABEL stopped at reduced accuracy ({status}); "
                          "check the reported residuals and margins", InaccurateSolutionWarning,
                          stacklevel=4)
        self.w.value = x[:self.phi.shape[1]]
        return status, float(solution.solve_time), setup, int(solution.iterations)


def run_clarabel(pmat: sp.csc_array, q: np.ndarray, a: sp.csc_array, b: np.ndarray,
                 cones: list, settings: Any) -> tuple[Any, float]:
    """Clarabel's solution of ``min ½xᵀPx + qᵀx, Ax + s = b, s ∈ cones`` and the clock
    (``time.perf_counter``) when its setup ended."""
    import clarabel

    solver = clarabel.DefaultSolver(pmat, q, a, b, cones, settings)
    ready = time.perf_counter()
    return solver.solve(), ready


def compiled(key: Hashable, build: Callable[[], CompiledProgram]) -> CompiledProgram:
    """The compiled program of ``key``: from the cache, or ``build()`` (then cached).

    Shared between threads: a solve keeps its data in its own :class:`BoundProgram` and Clarabel
    solver; only :meth:`BoundProgram.slacks` writes the shared variable's value, under a lock."""
    with _CACHE_LOCK:
        found = _CACHE.get(key)
        if found is not None:
            _CACHE.move_to_end(key)
            return found
    program = build()
    with _CACHE_LOCK:
        _CACHE[key] = program
        while len(_CACHE) > CACHE_SIZE:
            _CACHE.popitem(last=False)
    return program


def cache_info() -> dict[str, int]:
    """``{"programs": compiled structures cached, "solves": solves they served}``."""
    with _CACHE_LOCK:
        programs = list(_CACHE.values())
    return {"programs": len(programs), "solves": sum(p.solves for p in programs)}


def clear_cache() -> None:
    """Drop every compiled program (e.g. to measure a fresh compile)."""
    with _CACHE_LOCK:
        _CACHE.clear()


def array_key(a: object) -> Hashable:
    """A hashable stand-in for an array-valued option (shape and bytes)."""
    if a is None:
        return None
    arr = np.ascontiguousarray(np.asarray(a, dtype=float))
    return (arr.shape, arr.tobytes())


__all__ = ["CACHE_SIZE", "BoundProgram", "CompiledProgram", "array_key", "cache_info",
           "clear_cache", "compiled", "run_clarabel"]

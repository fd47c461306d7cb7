"""The package's shape: no import cycles, no private names across modules, heavy dependencies
loaded only when first used (``docs/architecture.md``).

The import graph is read from the source with :mod:`ast` (module-level and function-level
imports; imports under ``if TYPE_CHECKING:`` are for type checkers and do not run).
"""

from __future__ import annotations

import ast
import concurrent.futures
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "consistid"

#: Third-party packages slow to import or optional: a function may import these (or a module of
#: ours that imports one at module level) where they are first needed.
HEAVY = ("pinocchio", "scipy", "cvxpy", "clarabel", "mujoco", "matplotlib", "pyarrow",
         "pandas", "rosbags", "dask", "distributed", "joblib", "tqdm", "coal", "threadpoolctl")


def _name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _imports(name: str) -> list[tuple[str, str, bool]]:
    """``(module imported, name imported or "", inside a function)`` for each import of ``name``'s
    source, skipping ``if TYPE_CHECKING:`` blocks."""
    path = MODULES[name]
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    out: list[tuple[str, str, bool]] = []

    def visit(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                continue
            inner = in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef))
            if isinstance(child, ast.Import):
                out.extend((a.name, "", inner) for a in child.names)
            elif isinstance(child, ast.ImportFrom):
                if child.level:
                    base = package[:len(package) - child.level + 1]
                    module = ".".join(base + ([child.module] if child.module else []))
                else:
                    module = child.module or ""
                for alias in child.names:
                    sub = f"{module}.{alias.name}"
                    out.append((sub, "", inner) if sub in MODULES else
                               (module, alias.name, inner))
            visit(child, inner)

    visit(ast.parse(path.read_text()), False)
    return out


GRAPH = {m: _imports(m) for m in MODULES}


def _edges(module: str) -> set[str]:
    return {target for target, _, _ in GRAPH[module] if target in MODULES and target != module}


def _heavy(module: str, seen: set[str] | None = None) -> bool:
    """Whether importing ``module`` loads a heavy dependency (module-level imports,
    transitively)."""
    seen = set() if seen is None else seen
    if module in seen:
        return False
    seen.add(module)
    if module not in MODULES:
        return module.startswith(HEAVY)
    return any(not inner and _heavy(target, seen) for target, _, inner in GRAPH[module])


def test_graph_was_read():
    assert {"consistid.robot.model", "consistid.identification.sdp",
            "consistid.diagnosis.diagnose"} <= set(MODULES)
    assert "consistid.robot.model" in _edges("consistid.identification.regressor")


def test_no_import_cycles():
    """Tarjan's strongly connected components of the module graph; every one must be a single
    module. Function-level imports count: a cycle hidden in a function is still a cycle."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles: list[list[str]] = []

    def strong(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in _edges(v):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10 * len(MODULES)))
    for v in MODULES:
        if v not in index:
            strong(v)
    assert not cycles, f"import cycles: {cycles}"


def test_no_private_names_across_modules():
    crossing = [(m, target, name) for m in MODULES for target, name, _ in GRAPH[m]
                if name.startswith("_") and target.startswith("consistid")]
    assert not crossing, f"private names imported from another module: {crossing}"


def test_function_level_imports_only_for_heavy_dependencies():
    """A function may import a heavy dependency (or one of our modules that loads one) where it
    is first needed; anything else belongs at the top of the module."""
    light = [(m, target) for m in MODULES for target, _, inner in GRAPH[m]
             if inner and not _heavy(target) and target not in sys.stdlib_module_names
             and target.split(".")[0] not in sys.stdlib_module_names]
    assert not light, f"function-level imports of light modules (move them to the top): {light}"


def test_import_consistid_loads_no_heavy_dependency():
    """``import consistid`` is fast because the public names load on first use (PEP 562)."""
    code = ("import sys, consistid; heavy = ('cvxpy', 'mujoco', 'matplotlib', 'pinocchio', "
            "'scipy'); print([m for m in heavy if m in sys.modules])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


@pytest.mark.parametrize("name", ["identify", "RobotModel", "Dataset", "diagnose", "simulate",
                                  "SolverError", "estimate_payload", "design_excitation"])
def test_public_names_resolve(name):
    import consistid

    assert getattr(consistid, name) is not None
    assert name in dir(consistid)


def test_every_raised_exception_is_exported():
    import consistid
    from consistid import errors

    trees = [ast.parse(p.read_text()) for p in PACKAGE.rglob("*.py")]
    raised = {n.exc.func.id for tree in trees for n in ast.walk(tree)
              if isinstance(n, ast.Raise) and isinstance(n.exc, ast.Call)
              and isinstance(n.exc.func, ast.Name) and hasattr(errors, n.exc.func.id)}
    missing = sorted(e for e in raised if e not in consistid.__all__)
    assert not missing, f"raised but not exported from consistid: {missing}"


def test_architecture_page_lists_every_module():
    """``docs/architecture.md`` has one line per module; a new module must be added there."""
    page = (PACKAGE.parents[1] / "docs" / "architecture.md").read_text()
    folders: dict[str, set[str]] = {}
    current = None
    for line in page.splitlines():
        if line.startswith("### `"):
            current = line.split("`")[1].rstrip("/")
            current = "" if current == "consistid" else current
        elif current is not None and line.startswith("| `"):
            folders.setdefault(current, set()).add(line.split("`")[1])
    missing = [str(p.relative_to(PACKAGE)) for p in sorted(PACKAGE.rglob("*.py"))
               if p.name not in folders.get(str(p.parent.relative_to(PACKAGE)).replace(".", ""),
                                            set())]
    assert not missing, f"modules missing from docs/architecture.md: {missing}"


@pytest.mark.slow
def test_every_module_imports_first_in_a_fresh_interpreter():
    """Whatever module a user imports first, it loads: a cycle through a package's
    ``__init__`` (``friction/__init__`` → ``selection`` → ``diagnosis.noise`` → … →
    ``diagnosis.effects.stribeck`` → ``friction.models``) passes the graph test above, which
    does not see the implicit import of a parent package, yet raised ImportError when a user's
    first import was ``consistid.diagnosis.candidates``."""
    def first(name: str) -> tuple[str, str]:
        out = subprocess.run([sys.executable, "-c", f"import {name}"], capture_output=True,
                             text=True)
        return name, (out.stderr.strip().splitlines() or [""])[-1] if out.returncode else ""

    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
        failed = [(n, err) for n, err in pool.map(first, sorted(MODULES)) if err]
    assert not failed, f"modules that fail to import first: {failed}"

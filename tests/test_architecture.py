"""The package's import graph: no cycles, dependencies pointing one way, the math free of IO,
Dask and plotting. Every import counts, including those inside functions (kept there only to make
``import shapelib`` light), so the graph read here is the real one."""

import ast
from collections import defaultdict
from pathlib import Path

import pytest

from tests.conftest import ROOT

PKG = ROOT / "shapelib"

#: rank of each area: a module may import from its own area or from an area of lower rank
RANK = {
    "_validate": 0, "_files": 0, "_version": 0,
    "_executor": 0.5,  # where work runs (Dask imported inside its functions): the engine and the statistics
    "geometry": 1,
    "solver": 2,
    "comparison": 3,
    "pointsets": 3.5,  # beside the comparison: the registry of metrics (distances) holds its registration distance
    "distances": 4, "statistics": 4, "retrieval": 5, "rerank": 5,
    "io": 5, "pairwise": 5, "plotting": 5,
    "_warmup": 5,  # calls the registration and the geodesic once each, to compile the kernels
    "datasets": 6,
    "study": 7,
    "cli": 8,
    "__init__": 9, "__main__": 10,
}
#: areas that hold the mathematics: they never import the study, IO, Dask, zarr or plotting
MATH = {"_validate", "geometry", "solver", "comparison", "distances", "statistics", "pointsets", "retrieval", "rerank"}
FORBIDDEN_IN_MATH = {"dask", "distributed", "zarr", "matplotlib", "tqdm", "pooch", "papermill"}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _area(module: str) -> str:
    parts = module.split(".")
    return "__init__" if len(parts) == 1 else parts[1]


def _imports():
    """{module: {(imported module, tuple of names)}} for every module of the package."""
    modules = {_module_name(p): p for p in PKG.rglob("*.py")}
    found = defaultdict(set)
    for mod, path in modules.items():
        package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")
                    base = base[:len(base) - (node.level - 1)]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module
                names = tuple(a.name for a in node.names)
                # "from . import io": the names may be submodules, imported as modules
                subs = {n for n in names if f"{target}.{n}" in modules}
                found[mod].update((f"{target}.{n}", ()) for n in subs)
                if len(subs) < len(names):
                    found[mod].add((target, tuple(n for n in names if n not in subs)))
            elif isinstance(node, ast.Import):
                for a in node.names:
                    found[mod].add((a.name, ()))
    return modules, found


MODULES, IMPORTS = _imports()


def _internal_edges():
    edges = defaultdict(set)
    for mod, targets in IMPORTS.items():
        for target, _ in targets:
            if target == "shapelib" or target.startswith("shapelib."):
                while target not in MODULES and "." in target:
                    target = target.rpartition(".")[0]
                if target != mod:
                    edges[mod].add(target)
    return edges


def test_every_module_has_an_area_with_a_rank():
    assert {_area(m) for m in MODULES} <= set(RANK), {_area(m) for m in MODULES} - set(RANK)


def test_no_import_cycle():
    edges = _internal_edges()
    state, stack, cycles = {}, [], []

    def visit(m):
        state[m] = 1
        stack.append(m)
        for n in sorted(edges.get(m, ())):
            if n == "shapelib" or (n.startswith("shapelib.") and _area(n) == "__init__"):
                continue  # the package's __init__ re-exports; checked by the rank test
            if state.get(n) == 1:
                cycles.append(stack[stack.index(n):] + [n])
            elif n not in state:
                visit(n)
        stack.pop()
        state[m] = 2

    for m in sorted(MODULES):
        if m not in state:
            visit(m)
    assert not cycles, "import cycles: " + "; ".join(" -> ".join(c) for c in cycles)


def test_dependencies_point_one_way():
    wrong = []
    for mod, targets in _internal_edges().items():
        a = _area(mod)
        for t in targets:
            b = _area(t)
            if a != b and RANK[b] >= RANK[a]:
                wrong.append(f"{mod} imports {t} ({a} rank {RANK[a]} -> {b} rank {RANK[b]})")
    assert not wrong, "\n".join(sorted(wrong))


def test_no_private_name_crosses_an_area():
    """A module may use another area's public names only (private modules such as ``_validate``
    and ``_files`` are shared helpers and count as public)."""
    wrong = []
    for mod, targets in IMPORTS.items():
        for target, names in targets:
            if not target.startswith("shapelib") or _area(target) == _area(mod):
                continue
            wrong += [f"{mod} imports {target}.{n}" for n in names if n.startswith("_") and n != "__version__"
                      and f"{target}.{n}" not in MODULES]
    assert not wrong, "\n".join(sorted(wrong))


@pytest.mark.parametrize("area", sorted(MATH))
def test_the_mathematics_imports_no_io_dask_or_plotting(area):
    wrong = [f"{mod} imports {t}" for mod, targets in IMPORTS.items() if _area(mod) == area
             for t, _ in targets if t.split(".")[0] in FORBIDDEN_IN_MATH
             or (t.startswith("shapelib") and _area(t) in {"io", "pairwise", "plotting", "study", "cli", "datasets"})]
    assert not wrong, "\n".join(wrong)


#: the compiled kernels (numba), long by nature
LONG_MODULES_ALLOWED = {"shapelib.geometry._kernels": "compiled kernels"}
#: the most lines a module of the package may have
MAX_MODULE_LINES = 700


def _code_lines(source: str) -> int:
    """Lines of a module less its docstrings (module, class and function): the API pages' formulas,
    references and examples live in the docstrings by design and do not make a room cramped."""
    tree = ast.parse(source)
    doc = 0
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and body and \
                isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) and \
                isinstance(body[0].value.value, str):
            doc += body[0].end_lineno - body[0].lineno + 1
    return len(source.splitlines()) - doc


def test_every_module_is_a_small_room():
    """No module over ~700 lines of code (docstrings apart): a module with several jobs is a package
    of small private ones (as :mod:`shapelib.pairwise` is)."""
    long = {m: _code_lines(p.read_text()) for m, p in MODULES.items()}
    over = {m: n for m, n in long.items() if n > MAX_MODULE_LINES and m not in LONG_MODULES_ALLOWED}
    assert not over, over
    assert len(MODULES["shapelib.pairwise"].read_text().splitlines()) < 200  # the package's door, not its rooms


def test_the_statistics_reach_the_engine_through_the_executor_module_only():
    """The statistics take n_jobs / client / scheduler themselves through :mod:`shapelib._executor`
    (Dask imported inside its functions), never through the pairwise engine."""
    for mod, targets in IMPORTS.items():
        if _area(mod) == "statistics":
            assert not {t for t, _ in targets if t.startswith("shapelib.pairwise")}, mod
    executor = {t for t, _ in IMPORTS["shapelib._executor"]}
    assert not {t for t in executor if t.startswith("shapelib.") and t not in ("shapelib._validate",)}, executor

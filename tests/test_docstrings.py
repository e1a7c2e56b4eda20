"""The API docstrings of the mathematics, the datasets and the plot helpers: every public function
and class has a numpydoc docstring with an Example that runs (the docstring examples are doctests,
run here), a References section whose citations the text cites, and the rendered formula of the
equation it implements."""
import doctest
import importlib
import inspect
import re

import pytest

from tests.conftest import requires_data

#: the modules whose public names (``__all__``, defined there) are documented POT- and scikit-learn-style
MATH_MODULES = (
    "shapelib.geometry.gmm", "shapelib.geometry.metrics", "shapelib.geometry.procrustes",
    "shapelib.geometry.quadrature", "shapelib.geometry.scale", "shapelib.geometry.sigma2",
    "shapelib.geometry.bound_matrices",
    "shapelib.solver.result", "shapelib.solver.path_metric", "shapelib.solver.geodesic", "shapelib.solver.bracket",
    "shapelib.solver.logexp", "shapelib.solver.energy", "shapelib.solver.minimise", "shapelib.solver.linalg",
    "shapelib.comparison.diffeomorphism", "shapelib.comparison.hausdorff", "shapelib.comparison.splines",
    "shapelib.comparison.warp", "shapelib.comparison.missing", "shapelib.geometry.semilandmarks",
    "shapelib.distances",
    "shapelib.solver.batched",
    "shapelib.pointsets.checks", "shapelib.pointsets.density", "shapelib.pointsets.pose", "shapelib.pointsets.em",
    "shapelib.pointsets.registration", "shapelib.pointsets._batch", "shapelib.pointsets.invariant",
    "shapelib.pointsets.outline",
    "shapelib.retrieval", "shapelib.statistics.linear_model", "shapelib.statistics.allometry",
    "shapelib.solver.transport", "shapelib.statistics.disparity", "shapelib.statistics.pls",
    "shapelib.statistics.modularity",
    "shapelib.statistics.symmetry", "shapelib.statistics.trajectory", "shapelib.statistics.integration",
)
MODULES = MATH_MODULES + ("shapelib.datasets", "shapelib.plotting")

#: names whose docstring states a formula of the paper: their page renders it (``.. math::``)
RENDERED_EQUATIONS = {
    "shapelib.geometry.gmm": ("gmm_density", "gmm_log_density", "l2_distance", "l2_inner", "gaussian_overlap"),
    "shapelib.geometry.metrics": ("alpha_metric", "alpha_quadratic_form", "fisher_rao_metric",
                                  "fisher_rao_quadratic_form"),
    "shapelib.geometry.bound_matrices": ("alpha_bound_matrix", "fisher_rao_bound_matrix", "bound_matrix_sweep"),
    "shapelib.solver.geodesic": ("geodesic", "fisher_rao_lower_bound", "path_length", "shoot",
                                 "geodesic_acceleration"),
    "shapelib.solver.bracket": ("distance_bracket", "DistanceBracket"),
    "shapelib.solver.logexp": ("log_map", "exp_map"),
    "shapelib.solver.energy": ("path_energy",),
    "shapelib.comparison.diffeomorphism": ("landmark_diffeomorphism", "diffeomorphism_warp"),
    "shapelib.comparison.warp": ("extrinsic_warp", "likelihood_flow"),
    "shapelib.comparison.splines": ("tps_bending_energy", "wendland_bending_energy"),
}


def public_objects(module_name):
    """``(name, object)`` of the functions and classes of ``module.__all__`` defined in that module."""
    module = importlib.import_module(module_name)
    return [(name, obj) for name in module.__all__
            for obj in [getattr(module, name)]
            if (inspect.isfunction(obj) or inspect.isclass(obj)) and obj.__module__ == module_name]


def sections(doc):
    """The numpydoc section titles of a (cleaned) docstring."""
    lines = doc.splitlines()
    return {lines[i].strip() for i in range(len(lines) - 1)
            if lines[i].strip() and re.fullmatch(r"-{3,}", lines[i + 1].strip())
            and len(lines[i + 1].strip()) == len(lines[i].strip())}


def test_the_modules_cover_the_mathematics():
    """Every public name of ``shapelib`` that the mathematics defines is in one of these modules."""
    import shapelib

    floors = ("shapelib.geometry.", "shapelib.solver.", "shapelib.comparison.", "shapelib.distances", "shapelib.pointsets.")
    defined = {getattr(shapelib, n).__module__ for n in shapelib.__all__ if hasattr(getattr(shapelib, n), "__module__")}
    missing = sorted(m for m in defined if m.startswith(floors) and m not in MODULES)
    assert not missing, f"add these modules to MODULES: {missing}"


@pytest.mark.parametrize("module_name", MODULES)
def test_every_public_name_has_a_numpydoc_docstring_with_an_example(module_name):
    problems = []
    for name, obj in public_objects(module_name):
        doc = inspect.getdoc(obj) or ""
        found = sections(doc)
        need = {"Examples", "See Also"} | ({"Returns"} if inspect.isfunction(obj) else set())
        if inspect.isfunction(obj) and [p for p in inspect.signature(obj).parameters if p != "self"]:
            need.add("Parameters")
        if not inspect.isclass(obj) or not issubclass(obj, Warning):
            need.add("References")
        if missing := sorted(need - found):
            problems.append(f"{name}: no {', '.join(missing)}")
        if ">>> " not in doc:
            problems.append(f"{name}: its Examples section has no runnable example")
        cited = set(re.findall(r"^\.\. \[(\w+)\]", doc, flags=re.M))
        text = re.sub(r"^\.\. math::\n(?:\n|    .*\n)*", "", doc + "\n", flags=re.M)  # citations in math do not count
        if uncited := sorted(c for c in cited if f"[{c}]_" not in text):
            problems.append(f"{name}: references {uncited} are not cited in the text")
    assert not problems, f"{module_name}:\n" + "\n".join(problems)


@pytest.mark.parametrize("module_name", sorted(RENDERED_EQUATIONS))
def test_the_paper_s_equations_are_rendered_with_their_numbers(module_name):
    module = importlib.import_module(module_name)
    for name in RENDERED_EQUATIONS[module_name]:
        doc = inspect.getdoc(getattr(module, name))
        assert ".. math::" in doc, f"{module_name}.{name}: no rendered formula"
        assert re.search(r"eqs?\. \(?\d", doc), f"{module_name}.{name}: no equation number of the paper"


def run_doctests(module_name):
    module = importlib.import_module(module_name)
    tests = [t for t in doctest.DocTestFinder().find(module, module_name) if t.examples]
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    out = []
    for test in tests:
        runner.run(test, out=out.append)
    assert runner.failures == 0, f"{module_name}: {runner.failures} failing docstring examples\n" + "".join(out)
    return len(tests)


@pytest.fixture
def metric_registry():
    """The metric registry as the other tests know it, restored after examples that register a metric."""
    from shapelib import distances

    saved = dict(distances._REGISTRY)
    yield
    distances._REGISTRY.clear()
    distances._REGISTRY.update(saved)


@pytest.mark.parametrize("module_name", MATH_MODULES)
def test_the_docstring_examples_run(module_name, metric_registry):
    assert run_doctests(module_name) >= len(public_objects(module_name))


def _other_modules():
    """Every module of the package whose docstring examples the tests above do not run (the engine,
    IO, the statistics, the command line): each example runs once, here."""
    import pkgutil

    import shapelib

    done = set(MATH_MODULES) | {"shapelib.datasets", "shapelib.plotting"}
    names = [m.name for m in pkgutil.walk_packages(shapelib.__path__, "shapelib.")]
    return [n for n in sorted(names) if n not in done and not n.endswith("__main__") and ".study" not in n]


@pytest.mark.parametrize("module_name", _other_modules())
def test_the_other_modules_examples_run(module_name, metric_registry):
    run_doctests(module_name)


@requires_data
def test_the_dataset_examples_run():
    run_doctests("shapelib.datasets")


def test_the_plotting_examples_run():
    import matplotlib

    matplotlib.use("Agg")
    run_doctests("shapelib.plotting")

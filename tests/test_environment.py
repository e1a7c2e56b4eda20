"""The environment: environment.yml (conda) and pyproject.toml (pip) list the same packages; what `import shapelib` loads."""
import re
import tomllib

from tests.conftest import ROOT


def _name(req: str) -> str:
    return re.split(r"[<>=!~\[ ]", req.strip(), maxsplit=1)[0].lower()


def test_environment_yml_in_sync_with_pyproject():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    pip_names = {_name(r) for r in project["dependencies"]}
    for extra in project["optional-dependencies"].values():
        pip_names |= {_name(r) for r in extra}
    conda_names, in_deps = set(), False
    for line in (ROOT / "environment.yml").read_text().splitlines():
        if re.match(r"^\S", line):
            in_deps = line.startswith("dependencies:")
        m = re.match(r"^(?:\s{2}|\s{6})- ([A-Za-z0-9_.][A-Za-z0-9_.-]*)", line)  # conda's list, its pip: list
        if in_deps and m:
            conda_names.add(_name(m.group(1)))
    conda_names -= {"python", "pip"}  # conda-only conveniences
    conda_names = {{"python-build": "build"}.get(n, n) for n in conda_names}  # conda-forge's name for pypa/build
    assert pip_names == conda_names


def test_import_shapelib_is_light_and_its_other_modules_load_on_use():
    """`import shapelib` loads no module of the package beyond its door (neither the compiled kernels
    and SciPy nor IO and Dask); each public name, `shapelib.register` as `from shapelib import geodesic`,
    and the documentation's `shapelib.io.read_landmarks(...)` and `shapelib.pairwise.open_store(...)`,
    loads its module on first use."""
    import subprocess
    import sys

    code = ("import sys, shapelib\n"
            "heavy = [m for m in ('dask', 'distributed', 'zarr', 'numba', 'scipy', 'shapelib.io', 'shapelib.pairwise',"
            " 'shapelib.statistics.distance_based', 'shapelib.solver.geodesic', 'shapelib.pointsets') if m in sys.modules]\n"
            "assert not heavy, heavy\n"
            "assert callable(shapelib.register) and 'shapelib.pointsets.registration' in sys.modules\n"
            "from shapelib import geodesic, rerank, TangentPCA\n"
            "assert geodesic.__module__ == 'shapelib.solver.geodesic' and callable(rerank) and callable(shapelib.rerank)\n"
            "assert callable(shapelib.io.read_landmarks) and callable(shapelib.pairwise.open_store)\n"
            "assert callable(shapelib.statistics.distance_based.permanova) and 'io' in dir(shapelib)\n"
            "try:\n    shapelib.no_such_thing\nexcept AttributeError as e:\n    print(e)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "has no attribute 'no_such_thing'" in proc.stdout


def test_the_dataset_registry_ships_inside_the_package():
    """The loaders read the registry as a package resource, so a wheel carries it: it is a file under
    the package, setuptools' package-data names it, and it is the repository's only copy."""
    import importlib.resources

    from shapelib import datasets

    resource = importlib.resources.files("shapelib") / "data" / "registry.csv"
    assert resource.is_file() and str(datasets.REGISTRY_PATH) == str(resource)
    assert resource.read_text().splitlines()[0] == "path,url,sha256"
    package_data = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    assert "registry.csv" in package_data["shapelib.data"]
    assert not (ROOT / "data" / "registry.csv").exists()  # its old place beside the package: one copy


def test_the_statistics_need_no_optional_extra():
    """scikit-learn is a core dependency (TangentPCA is a scikit-learn transformer; knn_loo_accuracy and
    classical_mds use its estimators), so the statistics a wheel installs need no extra; build is in dev."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert "scikit-learn" in {_name(r) for r in project["dependencies"]}
    assert "build" in {_name(r) for r in project["optional-dependencies"]["dev"]}


def test_every_public_name_is_served_from_the_module_its_table_names():
    """The package's table of lazily loaded names covers ``shapelib.__all__``, and each name is the
    object its module defines (what an eager ``from .module import name`` gave)."""
    import importlib

    import shapelib

    table = {name: module for module, names in shapelib._PUBLIC.items() for name in names}
    assert set(shapelib.__all__) - set(table) == {"InputError"}
    assert set(table) - set(shapelib.__all__) == set()
    for name, module in table.items():
        assert getattr(shapelib, name) is getattr(importlib.import_module(f"shapelib.{module}"), name), name
    assert set(shapelib.__all__) <= set(dir(shapelib))

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
    assert pip_names == conda_names


def test_import_shapelib_is_light_and_its_other_modules_load_on_use():
    """`import shapelib` brings the mathematics only (the math never imports IO or Dask); the
    documentation's `shapelib.io.read_landmarks(...)` and `shapelib.pairwise.open_store(...)` work after
    it, loading those modules on first use."""
    import subprocess
    import sys

    code = ("import sys, shapelib\n"
            "heavy = [m for m in ('dask', 'distributed', 'zarr', 'shapelib.io', 'shapelib.pairwise', 'shapelib.statistics.distance_based')"
            " if m in sys.modules]\n"
            "assert not heavy, heavy\n"
            "assert callable(shapelib.io.read_landmarks) and callable(shapelib.pairwise.open_store)\n"
            "assert callable(shapelib.statistics.distance_based.permanova) and 'io' in dir(shapelib)\n"
            "try:\n    shapelib.no_such_thing\nexcept AttributeError as e:\n    print(e)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "has no attribute 'no_such_thing'" in proc.stdout

"""environment.yml (conda) and pyproject.toml (pip) list the same packages."""
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
        m = re.match(r"^\s{2}- ([A-Za-z0-9_.-]+)", line)
        if in_deps and m:
            conda_names.add(_name(m.group(1)))
    conda_names -= {"python", "pip"}  # conda-only conveniences
    assert pip_names == conda_names

"""Every study notebook runs with its quick parameters and records what the report needs."""
import json

import pandas as pd
import pytest

import run_all
from tests.conftest import ROOT, requires_data

REFERENCE_KEYS = set(pd.read_csv(ROOT / "data" / "reference" / "table1.csv", comment="#")["key"])


#: quick runs of 35–60 s each on 2 cores: in `make test-all` (and run in full by `make results`),
#: so that the default suite stays within its five minutes
SLOW_QUICK_RUNS = {"intrinsic_statistics", "table1_pairwise", "adhd200_population"}


@requires_data
@pytest.mark.notebooks
@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW_QUICK_RUNS else n
                                  for n in run_all.NOTEBOOKS])
def test_notebook_runs_quick_and_records_expected_values(name, tmp_path):
    _, status, _, msg = run_all.run_one(name, quick=True, force=True, results_dir=tmp_path)
    assert status == "ok", msg
    data = json.loads((tmp_path / name / "values.json").read_text())
    keys = set(data["values"])
    for prefix, count in run_all.NOTEBOOKS[name]["expects"].items():
        got = {k for k in keys if k.startswith(prefix)}
        assert len(got) == count, (prefix, sorted(got))
        if prefix.startswith("table1/"):
            assert got <= REFERENCE_KEYS
    pngs = list(tmp_path.glob(f"{name}/*.png"))
    assert pngs or name.startswith("table")
    # figures are saved as files and shown inline in the executed notebook
    nb = json.loads((tmp_path / name / f"{name}.ipynb").read_text())
    shown = [o for c in nb["cells"] for o in c.get("outputs", []) if "image/png" in o.get("data", {})]
    assert len(shown) >= len(pngs), f"{len(pngs)} PNG files, {len(shown)} figures shown in the notebook"
    assert data["meta"]["parameters"] == json.loads((tmp_path / name / ".inputs.json").read_text())["params"]

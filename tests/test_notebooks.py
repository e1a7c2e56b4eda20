"""Every study notebook runs with its quick parameters and records what the report needs.

The runner checks each run's outputs itself (:func:`shapelib.study.runner.check_outputs`: the
values under each ``expects`` prefix, Table I keys the paper has, the figures saved and shown), so
a run that comes back ``ok`` has them; ``tests/test_pipeline.py`` shows that the check fails a run
that lacks them. The quick runs take 3–60 s each on 2 cores and are in ``make test-all``: ``make
docs`` (which CI runs before the tests) executes every study notebook through the same runner and
fails on any of them, and ``tests/test_docs.py`` runs one (``fig04_line_bending``) in ``make test``.
"""
import json

import pytest

import run_all
from tests.conftest import requires_data


@requires_data
@pytest.mark.slow
@pytest.mark.notebooks
@pytest.mark.parametrize("name", list(run_all.NOTEBOOKS))
def test_notebook_runs_quick_and_records_expected_values(name, tmp_path):
    _, status, _, msg = run_all.run_one(name, quick=True, force=True, results_dir=tmp_path)
    assert status == "ok", msg
    data = json.loads((tmp_path / name / "values.json").read_text())
    assert data["meta"]["parameters"] == json.loads((tmp_path / name / ".inputs.json").read_text())["params"]
    assert len(list(tmp_path.glob(f"{name}/*.png"))) >= run_all.NOTEBOOKS[name]["figures"] >= 1

import json

import numpy as np
import pandas as pd
import pytest

from shapelib.report import compare, load_reference, render_report, write_report
from shapelib.study import record_values


@pytest.fixture
def reference(tmp_path):
    d = tmp_path / "ref"
    d.mkdir()
    (d / "t.csv").write_text(
        "# comment\nkey,item,row,column,printed,scale,decimals,value,source\n"
        "t/c/1-2,t,1 vs. 2,c,11.73,0.01,2,0.1173,x\n"
        "t/c/1-3,t,1 vs. 3,c,7.74,0.01,2,0.0774,x\n"
        "t/c/1-4,t,1 vs. 4,c,5.00,0.01,2,0.05,x\n"
        "t/c/1-5,t,1 vs. 5,c,2.00,0.01,2,0.02,x\n"
    )
    return d


def test_statuses(reference):
    values = {"t/c/1-2": (0.117349, "nb"), "t/c/1-3": (0.0776, "nb"), "t/c/1-4": (0.06, "nb")}
    table = compare(load_reference(reference), values).set_index("key")
    assert table.loc["t/c/1-2", "status"] == "match"  # 11.7349 prints as 11.73
    assert table.loc["t/c/1-3", "status"] == "close"  # 0.26 % off
    assert table.loc["t/c/1-4", "status"] == "differs"
    assert table.loc["t/c/1-5", "status"] == "not computed"
    assert table.loc["t/c/1-4", "ratio"] == pytest.approx(1.2)
    assert table.loc["t/c/1-3", "rel_err"] == pytest.approx(0.0002 / 0.0774)


def test_print_precision_boundary(reference):
    ref = load_reference(reference)
    just_out = compare(ref, {"t/c/1-2": (0.11735 + 1e-9, "nb")}).set_index("key")
    assert just_out.loc["t/c/1-2", "status"] == "close"


def test_report_written_from_results(tmp_path, reference):
    results = tmp_path / "results"
    record_values(results / "nb1", {"t/c/1-2": 0.1173, "t/c/1-3": 0.08}, notes={"t/c": "convention X"})
    path = write_report(results, reference)
    text = path.read_text()
    assert "| t | c | 2 | 1 | 0 | 1 | 2 |" in text and "ratio CV" in text
    assert "convention X" in text and "1 vs. 3" in text
    assert (results / "comparison.csv").exists()


def test_duplicate_values_across_notebooks_are_an_error(tmp_path, reference):
    results = tmp_path / "results"
    record_values(results / "a", {"t/c/1-2": 0.1})
    record_values(results / "b", {"t/c/1-2": 0.1})
    with pytest.raises(ValueError, match="recorded by two notebooks"):
        write_report(results, reference)


import numpy as np
import pytest

from shapelib.study.report import compare, fit_constant, load_reference, load_regression, write_report
from shapelib.study.report import SECTION_FILE
from shapelib.study import record_values, record_verdict


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
    # compared 2: one match, one differs, 2 not computed
    assert "| t | c | 2 | 1 | 0 | 0 | 1 | 2 |" in text and "ratio CV" in text
    assert "convention X" in text and "1 vs. 3" in text
    assert (results / "comparison.csv").exists()


def test_duplicate_values_across_notebooks_are_an_error(tmp_path, reference):
    results = tmp_path / "results"
    record_values(results / "a", {"t/c/1-2": 0.1})
    record_values(results / "b", {"t/c/1-2": 0.1})
    with pytest.raises(ValueError, match="recorded by two notebooks"):
        write_report(results, reference)


def test_proportional_status_uses_the_recorded_constant(reference):
    ref = load_reference(reference)
    # ours = paper / 3.5 (to 0.3 %) except 1-4, which is off by 5 % after scaling
    values = {"t/c/1-2": (0.1173 / 3.5 * 1.003, "nb"), "t/c/1-3": (0.0774 / 3.5, "nb"), "t/c/1-4": (0.05 / 3.5 * 1.05, "nb"),
              "constant/t/c": (3.5, "nb")}
    table = compare(ref, values).set_index("key")
    assert table.loc["t/c/1-2", "status"] == "proportional"  # 0.3 % after k: within rel_tol
    assert table.loc["t/c/1-3", "status"] == "proportional"
    assert table.loc["t/c/1-4", "status"] == "differs"
    assert table.loc["t/c/1-2", "ratio"] == pytest.approx(1.003 / 3.5)  # the ratio stays that of ours itself
    # without a constant the same values differ: the status needs the recorded constant
    bare = compare(ref, {k: v for k, v in values.items() if not k.startswith("constant/")}).set_index("key")
    assert (bare.loc[["t/c/1-2", "t/c/1-3"], "status"] == "differs").all()
    # the boundary: k × ours 1.1 % off (print tolerance 0.25 % for "2.00") is outside max(abs_tol, 1 %)
    assert compare(ref, {"t/c/1-5": (0.02 / 3.5 * 1.011, "nb"), "constant/t/c": (3.5, "nb")}).set_index("key").loc[
        "t/c/1-5", "status"] == "differs"
    assert compare(ref, {"t/c/1-5": (0.02 / 3.5 * 1.009, "nb"), "constant/t/c": (3.5, "nb")}).set_index("key").loc[
        "t/c/1-5", "status"] == "proportional"


def test_constants_must_be_well_formed(reference):
    with pytest.raises(ValueError, match="constant/t"):
        compare(load_reference(reference), {"constant/t": (3.0, "nb")})
    with pytest.raises(ValueError, match="positive"):
        compare(load_reference(reference), {"constant/t/c": (-1.0, "nb")})


def test_fit_constant_closed_forms():
    ours = np.array([1.0, 2.0, 5.0])
    f = fit_constant(3 * ours, ours)
    assert f["k"] == pytest.approx(3.0) and f["cv"] == pytest.approx(0.0, abs=1e-15) and f["max_min"] == pytest.approx(0.0)
    f = fit_constant(np.array([1.0, 2.0, 4.0]), np.ones(3))  # ratios 1, 2, 4: geometric mean 2
    assert f["k"] == pytest.approx(2.0) and f["median"] == 2.0 and f["max_min"] == pytest.approx(3.0)
    assert f["cv"] == pytest.approx(np.std([1, 2, 4]) / np.mean([1, 2, 4]))
    with pytest.raises(ValueError, match="positive"):
        fit_constant([1.0, 0.0], [1.0, 1.0])
    with pytest.raises(ValueError, match="shape"):
        fit_constant([1.0], [1.0, 2.0])


def test_fit_constant_spread_beyond_print_rounding():
    rng = np.random.default_rng(3)
    ours = rng.uniform(0.02, 0.5, 15)  # printed 0.07–1.8: rounding is up to 7 %
    printed = np.round(3.55 * ours, 2)  # a column printed to 2 decimals: k · ours to its last digit
    f = fit_constant(printed, ours, abs_tol=0.005)
    assert f["cv"] > 0.005  # rounding alone spreads the raw ratios
    assert f["cv_beyond_rounding"] == pytest.approx(0.0, abs=1e-9)
    assert np.all(np.abs(f["k_rounding"] * ours - printed) <= 0.005 + 1e-12)  # the constant reproduces every digit
    # no rounding interval: the spread is the raw CV whatever the constant
    f0 = fit_constant(printed, ours, abs_tol=0.0)
    assert f0["cv_beyond_rounding"] == pytest.approx(f0["cv"], rel=1e-12)
    # a real deviation larger than the rounding stays, but less of it than the raw CV
    off = printed.copy()
    off[0] *= 1.2
    g = fit_constant(off, ours, abs_tol=0.005)
    assert 0.0 < g["cv_beyond_rounding"] < g["cv"]
    # independent check: brute force over constants
    lo, hi = (off - 0.005) / ours, (off + 0.005) / ours
    moved = np.clip(np.linspace(lo.min(), hi.max(), 200001)[:, None], lo, hi)
    brute = (moved.std(axis=1) / moved.mean(axis=1)).min()
    assert g["cv_beyond_rounding"] == pytest.approx(brute, rel=1e-6)
    with pytest.raises(ValueError, match="abs_tol"):
        fit_constant(printed, ours, abs_tol=-0.1)
    with pytest.raises(ValueError, match="abs_tol"):
        fit_constant(printed, ours, abs_tol=np.ones(3))


def test_verdicts_are_validated_and_tabulated(tmp_path, reference):
    results = tmp_path / "results"
    with pytest.raises(ValueError, match="must be one of"):
        record_verdict(results / "fig", "fig04", "mostly", "x")
    with pytest.raises(ValueError, match="measured"):
        record_verdict(results / "fig", "fig04", "reproduced", " ")
    record_verdict(results / "fig", "fig04", "reproduced with a difference", "turning 12° vs 3°")
    record_verdict(results / "fig", "fig06", "not reproduced", "α max turning 8.7° < Fisher–Rao 10.7°")
    text = write_report(results, reference).read_text()
    assert "## Figures" in text and "1 reproduced with a difference, 1 not reproduced" in text
    assert "| fig06 | not reproduced | α max turning 8.7° < Fisher–Rao 10.7° |" in text


def test_sections_failures_and_conventions(tmp_path, reference):
    results = tmp_path / "results"
    record_values(results / "paper_nb", {"t/c/1-2": 0.1173, "fit/t/c/straight_line/k": 3.5,
                                         "fit/t/c/straight_line/cv_15": 0.004, "fit/t/c/straight_line/cv_21": 0.015,
                                         "fit/t/c/geodesic/cv_15": 0.03},
                  notes={"convention/t/c": {"column": "c", "convention": "straight_line", "k": 3.5,
                                            "sentence": "generated sentence"}})
    (results / "paper_nb" / SECTION_FILE).write_text("paper notebook extra")
    record_values(results / "population", {"adhd/n": 10})
    (results / "population" / SECTION_FILE).write_text("PERMANOVA p = 0.04")
    text = write_report(results, reference, failures=[("broken_nb", "broken_nb: cell 3 raised ValueError: bad")]).read_text()
    assert "## Failed notebooks" in text and "| broken_nb | broken_nb: cell 3 raised ValueError: bad |" in text
    beyond = text.split("## Beyond the paper", 1)[1]
    assert "### population" in beyond and "PERMANOVA p = 0.04" in beyond and "paper notebook extra" not in beyond
    assert "## Notes from paper_nb" in text and "paper notebook extra" in text
    conv = text.split("## Fitted conventions", 1)[1]
    assert "| **straight_line** (fitted) | 3.5 |" in conv and "0.40%" in conv and "generated sentence" in conv
    assert "| geodesic | — |" in conv
    assert "## Failed notebooks" not in write_report(results, reference).read_text()


def test_regression_checks_are_separate_from_the_paper(tmp_path, reference):
    (reference / "regression_nb.csv").write_text(
        "key,item,row,column,printed,scale,decimals,value,source,rel_tol\n"
        "fit/t/c/k,fit,c,k,3.5,1,4,3.5,ours,0.001\n"
        "fit/t/c/cv_15,fit,c,cv,0.004,1,4,0.004,ours,0.1\n"
        "fit/t/c/cv_21,fit,c,cv,0.015,1,4,0.015,ours,0.1\n")
    assert "fit/t/c/k" not in load_reference(reference).index and len(load_regression(reference)) == 3
    results = tmp_path / "results"
    record_values(results / "nb", {"fit/t/c/k": 3.5001, "fit/t/c/cv_15": 0.006})
    text = write_report(results, reference).read_text()
    reg = text.split("## Regression checks", 1)[1]
    assert "| fit/t/c/k | 3.5 | 3.5001 |" in reg and "| ok |" in reg
    assert "| fit/t/c/cv_15 |" in reg and "regressed" in reg and "not computed" in reg
    # never counted as paper comparisons
    assert "fit/t/c/k" not in text.split("## Regression checks", 1)[0]
    (results / "nb" / ".inputs.json").write_text('{"mode": "quick"}')
    assert "quick run" in write_report(results, reference).read_text().split("## Regression checks", 1)[1]
    (reference / "regression_bad.csv").write_text("key,item,row,column,printed,scale,decimals,value,source\nx,a,b,c,1,1,0,1,s\n")
    with pytest.raises(ValueError, match="regression_bad.csv"):
        load_regression(reference)

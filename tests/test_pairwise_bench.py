"""benchmarks/bench_pairwise.py keeps running (quick mode: tiny subsets, one worker, seconds)."""

import importlib.util

import pytest

from tests.conftest import ROOT, requires_data


@requires_data
def test_bench_pairwise_quick_run_reports_rates_and_projection(tmp_path):
    spec = importlib.util.spec_from_file_location("bench_pairwise", ROOT / "benchmarks" / "bench_pairwise.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    out = tmp_path / "out.json"
    report = bench.main(["--quick", "--workers", "1", "--metrics", "procrustes", "tps", "alpha",
                         "--json", str(out)])
    assert out.is_file()
    n = bench.QUICK_SIZES
    assert report["metrics"]["procrustes"][1]["pairs"] == n["procrustes"] * (n["procrustes"] - 1) // 2
    assert report["metrics"]["tps"][1]["pairs"] == n["tps"] * (n["tps"] - 1)  # both directions
    for metric in ("procrustes", "tps", "alpha"):
        r = report["metrics"][metric][1]
        assert r["pairs_per_second"] > 0 and r["efficiency"] == pytest.approx(1.0)
    proj = report["projection"]["alpha"]
    per_pair = report["metrics"]["alpha"][1]["mean_seconds_per_pair"]
    assert proj["hours"][1] == pytest.approx(647 * 646 / 2 * per_pair / 3600)
    assert proj["hours"][8] == pytest.approx(proj["hours"][1] / 8)
    b = report["bound_matrices"]
    assert b["n_shapes"] == 40 and b["alpha_bound"]["max_rel_diff_per_pair"] < 1e-12
    assert b["fisher_rao_bound"]["max_rel_diff_per_pair"] < 1e-7
    assert b["alpha_bound"]["gaussians"] == 40 * 39 // 2 * 50 * 50 and b["alpha_bound"]["bare_exp_seconds"] > 0
    assert len(b["sweep"]["sigma2"]) == 3 and b["sweep"]["both_seconds"] > 0

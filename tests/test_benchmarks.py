"""The solver comparison in benchmarks/ keeps running and its methods do what they claim.

Quick mode only (n_steps = 4, 3 iterations each); the measurements themselves come from the full
run, which takes minutes, and are shown on the documentation's performance page
(docs/_data/benchmarks/).
"""

import importlib.util

import numpy as np
import pytest

from tests.conftest import ROOT, requires_data


def _load_bench_solvers():
    spec = importlib.util.spec_from_file_location("bench_solvers", ROOT / "benchmarks" / "bench_solvers.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@requires_data
def test_bench_solvers_quick_run_decreases_the_energy_and_respects_the_bound(tmp_path):
    bench = _load_bench_solvers()
    report = bench.main(["--quick", "--json", str(tmp_path / "out.json")])
    assert (tmp_path / "out.json").is_file()
    assert set(report["methods"]) == set(bench.METHODS)
    from shapelib.datasets import load_corpus_callosum
    from shapelib.solver.energy import path_energy
    from shapelib.solver.path_metric import AlphaPathMetric
    from shapelib import to_centroid_size

    shapes, ids = load_corpus_callosum()
    x = to_centroid_size(shapes)
    u, v = x[list(ids).index(1)], x[list(ids).index(2)]
    start = path_energy(AlphaPathMetric(0.5), bench.straight_line(u, v, report["n_steps"]), gradient=False)[0]
    for name, out in report["methods"].items():
        assert out["iterations"] >= 1, name
        # every method decreased the straight-line energy and stayed above the squared lower bound
        assert report["lower_bound_squared"] < out["energy"] < start, name
    poly = report["methods"]["polynomial"]
    assert poly["energy_with_4x_time_nodes"] == pytest.approx(poly["energy"], rel=1e-5)


def test_polynomial_basis_is_a_lagrange_basis_with_exact_derivative():
    bench = _load_bench_solvers()
    s, phi, dphi, w = bench.polynomial_basis(4, 12)
    # nodal basis: reproduces any polynomial of degree <= 4 from its values at the nodes
    coef = np.array([0.3, -1.0, 2.0, 0.5, -0.7])
    f = np.polynomial.polynomial.Polynomial(coef)
    x, _ = np.polynomial.legendre.leggauss(12)
    t = 0.5 * (x + 1)
    np.testing.assert_allclose(phi @ f(s), f(t), atol=1e-12)
    np.testing.assert_allclose(dphi @ f(s), f.deriv()(t), atol=1e-10)
    assert w.sum() == pytest.approx(1.0)
    assert s[0] == 0.0 and s[-1] == pytest.approx(1.0)


def test_dense_hessian_matches_the_block_product(rng):
    bench = _load_bench_solvers()
    from shapelib.solver.linalg import hess_vec

    diag = rng.normal(size=(3, 4, 4))
    diag = diag + diag.transpose(0, 2, 1)
    upper = rng.normal(size=(2, 4, 4))
    xv = rng.normal(size=(3, 4))
    np.testing.assert_allclose(bench.dense_hessian(diag, upper) @ xv.ravel(), hess_vec(diag, upper, xv).ravel(),
                               atol=1e-12)


def _load_bench(name):
    spec = importlib.util.spec_from_file_location(name, ROOT / "benchmarks" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@requires_data
def test_bench_bracket_quick_run_reports_certified_brackets(tmp_path):
    bench = _load_bench("bench_bracket")
    report = bench.main(["--quick", "--json", str(tmp_path / "out.json")])
    assert (tmp_path / "out.json").is_file()
    assert set(report["cases"]) == {c[0] for c in bench.CASES}
    for name, case in report["cases"].items():
        assert case["pairs_per_second"] > 0 and case["lower_le_upper"], name
        for b in case["brackets"]:
            assert b["lower"] <= b["upper"]
            assert (b["rel_gap"] <= report["rtol"]) == b["converged"], name
    # at sigma2 = 0.5 both metrics close the bracket on these pairs
    assert report["cases"]["alpha_s2_0.5"]["converged"] == report["cases"]["alpha_s2_0.5"]["pairs"]


@requires_data
def test_bench_registration_runs_every_method_on_the_same_case_and_refuses_a_partial_record(tmp_path):
    spec = importlib.util.spec_from_file_location("bench_registration", ROOT / "benchmarks" / "bench_registration.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    with pytest.raises(SystemExit):  # a partial run is not the benchmark
        bench.main(["--levels", "fish_def_2", "--record"])
    report = bench.main(["--levels", "fish_def_2", "--json", str(tmp_path / "r.json")])
    row = report["levels"]["fish_def_2"]
    assert set(row) == set(report["methods"]) and len(report["methods"]) == 6
    # a clean deformation level: shapelib and CPD register the fish to within a few thousandths of its unit size
    assert row["shapelib"]["error"] < 0.005 and row["cpd"]["error"] < 0.005
    assert report["summary"]["1-1"]["levels"] == 1 and (tmp_path / "r.json").is_file()


def test_the_shortlist_order_has_every_shortlist_as_a_prefix():
    """bench_retrieval.shortlist_order: every pair once; the pairs of rank below k are exactly the
    engine's symmetric shortlist of k (one set among the other's k nearest), for every k."""
    from shapelib.pairwise._pointsets import shortlist_mask, shortlist_neighbours

    bench = _load_bench("bench_retrieval")
    rng = np.random.default_rng(5)
    x = rng.normal(size=(30, 3))
    rigid = np.linalg.norm(x[:, None] - x[None], axis=2)
    pairs, rank = bench.shortlist_order(rigid)
    assert len(pairs) == 30 * 29 // 2 and len({tuple(p) for p in pairs}) == len(pairs)
    assert np.all(pairs[:, 0] < pairs[:, 1]) and np.all(np.diff(rank) >= 0)
    for k in (1, 2, 5, 29):
        mask = shortlist_mask(shortlist_neighbours(rigid, k))
        want = {(i, j) for i, j in zip(*np.nonzero(np.triu(mask, 1)))}
        assert {tuple(map(int, p)) for p in pairs[rank < k]} == want


def test_the_outline_splits_at_its_concave_corners():
    """bench_articulation.split_at_concavities: the arcs cover the outline once, each contiguous, and
    on a plus sign (12 corners, 4 of them concave) the cuts are the 4 concave corners, whichever way
    the outline runs."""
    bench = _load_bench("bench_articulation")
    corners = np.array([[1, 3], [-1, 3], [-1, 1], [-3, 1], [-3, -1], [-1, -1], [-1, -3], [1, -3], [1, -1],
                        [3, -1], [3, 1], [1, 1]], float)
    # 8 points per edge, the corners among them (every 8th point)
    plus = np.concatenate([a + (b - a) * t for a, b in zip(corners, np.roll(corners, -1, axis=0))
                           for t in [np.linspace(0, 1, 8, endpoint=False)[:, None]]])
    concave = {i * 8 for i in (2, 5, 8, 11)}  # the inner corners (±1, ±1)
    for x, index in ((plus, lambda i: i), (plus[::-1], lambda i: len(plus) - 1 - i)):
        arcs = bench.split_at_concavities(x, 4)
        assert sorted(np.concatenate(arcs).tolist()) == list(range(len(x)))
        assert {index(int(a[0])) for a in arcs} == concave
        for a in arcs:  # consecutive along the outline
            assert np.all(np.isin((np.diff(a) % len(x)), (1, len(x) - 1)))


def test_the_device_run_resumes_where_it_stopped_and_equals_one_by_one(tmp_path):
    """bench_retrieval_device.py (on JAX's CPU backend here): a run stopped after some pairs, continued
    with --resume, holds the misfits of one uninterrupted pass, each equal to the numpy backend's
    registration one pair at a time; a resume from another run's pairs is refused."""
    from tests.conftest import import_or_missing

    import_or_missing("jax", "JAX (the dev or jax extra) is not installed")
    from shapelib.pointsets.registration_distance import registration_misfits_many

    prepare, device = _load_bench("bench_retrieval"), _load_bench("bench_retrieval_device")
    t = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    sets = np.stack([np.c_[np.cos(t), (0.5 + 0.1 * k) * np.sin(t) + 0.05 * k * np.cos(2 * t)] for k in range(5)])
    rigid = np.linalg.norm(sets[:, None] - sets[None], axis=(2, 3))
    pairs, rank = prepare.shortlist_order(rigid)
    data = tmp_path / "data"
    data.mkdir()
    np.save(data / "outlines.npy", sets)
    np.save(data / "pairs.npy", pairs)
    first, second = tmp_path / "first", tmp_path / "second"
    opts = ["--data", str(data), "--batch-size", "4", "--check", "1"]
    assert device.main([*opts, "--out", str(first), "--limit", "4"]) == 0
    assert int(np.load(first / "progress.npz")["done"]) == 4
    assert device.main([*opts, "--out", str(second), "--resume", str(first)]) == 0
    state = np.load(second / "progress.npz")
    misfits = np.load(second / "misfits.npy")
    assert int(state["done"]) == len(pairs) == 10 and misfits.shape == (10, 2)
    ref = registration_misfits_many([(sets[i], sets[j]) for i, j in pairs], max_iter=150)
    np.testing.assert_allclose(misfits, [(a, b) for a, b, _, _ in ref], rtol=1e-6, atol=1e-12)
    assert list(state["ok"]) == [c for _, _, c, _ in ref]
    np.save(data / "pairs.npy", pairs[::-1])  # other pairs: the first run's files are not theirs
    with pytest.raises(ValueError, match="not this run's"):
        device.main([*opts, "--out", str(tmp_path / "third"), "--resume", str(first)])

"""The registration distance of point sets (:func:`shapelib.pointsets.registration_distance.registration_distance`) and its
matrix through the pairwise engine (``metric="registration"``): symmetry, invariances, the engine
in process, in a resumed zarr store and on a LocalCluster against the direct loop, the shortlist."""

import numpy as np
import pytest

import shapelib as sl
from shapelib.pointsets.registration_distance import registration_distance, registration_misfits
from shapelib.pairwise import open_store

T = np.linspace(0, 2 * np.pi, 20, endpoint=False)
ELLIPSE = np.c_[np.cos(T), 0.6 * np.sin(T)]
# no symmetry: a symmetric shape has several equally good poses, and which one the registration
# takes can turn on the last bit of the input
STAR = np.c_[np.cos(T), np.sin(T)] * (1 + 0.3 * np.cos(2 * T) + 0.15 * np.sin(5 * T + 0.4))[:, None]
TRIFOIL = np.c_[np.cos(T), np.sin(T)] * (1 + 0.25 * np.cos(3 * T) + 0.1 * np.cos(T + 1))[:, None]
OPTS = {"max_iter": 60}
# a few EMs stop at max_iter = 60 (recorded per pair, and warned): the tests compare values, not convergence
pytestmark = pytest.mark.filterwarnings("ignore:.*an EM stopped at max_iter")


def _similar(x, angle, scale, shift):
    c, s = np.cos(angle), np.sin(angle)
    return scale * x @ np.array([[c, -s], [s, c]]).T + shift


def _sets():
    rng = np.random.default_rng(7)
    out = [ELLIPSE, _similar(ELLIPSE + rng.normal(scale=0.02, size=ELLIPSE.shape), 2.0, 0.5, 3.0),
           STAR, _similar(STAR, -1.0, 4.0, -2.0)[:17], TRIFOIL]  # sizes differ
    return [np.asarray(x) for x in out]


SETS = _sets()


@pytest.fixture(scope="module")
def direct():
    n = len(SETS)
    d = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1, n):
            d[i, j] = d[j, i] = registration_distance(SETS[i], SETS[j], **OPTS)
    return d


def test_zero_for_a_similar_copy_and_positive_for_other_shapes():
    copy = _similar(ELLIPSE, 1.0, 3.0, np.array([2.0, -1.0]))
    same = registration_distance(ELLIPSE, copy)
    assert same < 1e-4
    for other in (STAR, TRIFOIL):
        assert registration_distance(ELLIPSE, other) > 50 * max(same, 1e-6)


def test_symmetric_and_scale_free():
    m_uv, m_vu, converged, n_iter = registration_misfits(STAR, TRIFOIL)
    d = registration_distance(STAR, TRIFOIL)
    assert d == pytest.approx(0.5 * (m_uv + m_vu), rel=1e-12)
    assert registration_distance(TRIFOIL, STAR) == pytest.approx(d, rel=1e-9)
    assert registration_distance(STAR, TRIFOIL, combine="max") == pytest.approx(max(m_uv, m_vu), rel=1e-12)
    # the misfit is a fraction of the target's size: scaling either set changes nothing
    assert registration_distance(7.0 * STAR + 3, 0.2 * TRIFOIL - 1) == pytest.approx(d, rel=1e-6)


def test_invariant_to_the_order_of_the_points():
    rng = np.random.default_rng(1)
    d = registration_distance(STAR, TRIFOIL)
    assert registration_distance(STAR[rng.permutation(20)], TRIFOIL[rng.permutation(20)]) == pytest.approx(d, rel=1e-6)


def test_engine_in_process_equals_the_direct_loop(direct):
    r = sl.pairwise_distances(SETS, metric="registration", n_jobs=1, block_size=2, progress=False,
                              return_result=True, **OPTS)
    np.testing.assert_allclose(r.matrix, direct, rtol=1e-12, atol=1e-15)
    assert np.array_equal(r.matrix, r.matrix.T)
    off = ~np.eye(len(SETS), dtype=bool)
    assert np.all(r.lower[off] <= r.matrix[off]) and np.all(r.matrix[off] <= r.upper[off])
    # the class-mates (0, 1) and (2, 3) are each other's nearest
    assert np.argsort(r.matrix[0])[1] == 1 and np.argsort(r.matrix[2])[1] == 3


def test_the_energy_weight_reaches_the_engine(direct):
    """``energy_weight=0`` (σ² alone) through the engine equals the direct loop with it, and is below the
    default's matrix off the diagonal (the default multiplies each misfit by exp(κ E/m) > 1)."""
    sets = SETS[2:]
    r = sl.pairwise_distances(sets, metric="registration", n_jobs=1, progress=False, energy_weight=0.0, **OPTS)
    for i in range(len(sets)):
        for j in range(i + 1, len(sets)):
            assert r[i, j] == pytest.approx(registration_distance(sets[i], sets[j], energy_weight=0.0, **OPTS),
                                            rel=1e-12)
            assert r[i, j] < direct[2 + i, 2 + j]


def test_store_resumes_and_checks_its_options(tmp_path, direct):
    store = tmp_path / "reg.zarr"
    calls = []
    part = sl.pairwise_distances(SETS, metric="registration", n_jobs=1, block_size=2, store=store, progress=False,
                                 return_result=True, callback=lambda p: calls.append(p) or len(calls) == 2, **OPTS)
    assert not part.complete
    full = sl.pairwise_distances(SETS, metric="registration", n_jobs=1, store=store, progress=False,
                                 return_result=True, **OPTS)
    assert full.complete and full.log["blocks_found_done"] == 2
    np.testing.assert_allclose(full.matrix, direct, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(open_store(store).matrix, direct, rtol=1e-12, atol=1e-15)
    with pytest.raises(ValueError, match="param"):
        sl.pairwise_distances(SETS, metric="registration", n_jobs=1, store=store, progress=False, max_iter=61)


@pytest.mark.processes
def test_local_cluster_equals_the_direct_loop(direct):
    D = sl.pairwise_distances(SETS, metric="registration", n_jobs=2, block_size=2, progress=False, **OPTS)
    np.testing.assert_allclose(D, direct, rtol=1e-12, atol=1e-15)


def test_shortlist_registers_only_the_rigid_neighbours(direct):
    k = 1
    r = sl.pairwise_distances(SETS, metric="registration", n_jobs=1, progress=False, return_result=True,
                              shortlist=k, **OPTS)
    rigid = sl.invariant_distance_matrix(SETS, metric="fisher_rao_bound", sigma2=0.01)
    near = np.argsort(rigid + np.diag(np.full(len(SETS), np.inf)), axis=1, kind="stable")[:, :k]
    mask = np.zeros_like(rigid, dtype=bool)
    mask[np.arange(len(SETS))[:, None], near] = True
    mask |= mask.T
    np.testing.assert_allclose(r.matrix[mask], direct[mask], rtol=1e-12)  # registered: the registration distance
    off = ~mask & ~np.eye(len(SETS), dtype=bool)
    assert off.any()
    # the rest: the rigid bound, shifted above every registered value (each row ranks its shortlist first)
    assert r.matrix[off].min() > r.matrix[mask].max()
    np.testing.assert_allclose(r.matrix[off] - rigid[off], r.log["shortlist"]["shift"], rtol=1e-9)
    assert r.log["shortlist"]["pairs_registered"] == int(mask.sum()) // 2
    assert "registered only each query's 1 nearest" in r.summary()


def test_bad_input_names_the_parameter():
    with pytest.raises(ValueError, match="^combine "):
        registration_distance(STAR, TRIFOIL, combine="min")
    with pytest.raises(ValueError, match="^shortlist "):
        sl.pairwise_distances(SETS, metric="registration", shortlist=len(SETS), progress=False)
    with pytest.raises(ValueError, match="^shortlist_metric "):
        sl.pairwise_distances(SETS, metric="registration", shortlist=2, shortlist_metric="procrustes", progress=False)
    with pytest.raises(ValueError, match="lam_x"):
        sl.pairwise_distances(SETS, metric="registration", lam_x=2, progress=False)
    with pytest.raises(ValueError, match="rtol"):
        sl.pairwise_distances(SETS, metric="registration", rtol=1e-3, progress=False)
    assert sl.metric_info("registration").point_sets and "registration" in sl.distances.METRICS


def test_cli_writes_the_library_matrix_and_says_the_shortlist(tmp_path, capsys, direct):
    import pandas as pd

    from shapelib.cli import main

    f = tmp_path / "sets.npz"
    np.savez(f, **{f"s{i}": x for i, x in enumerate(SETS)})
    out = tmp_path / "reg.csv"
    assert main(["distances", str(f), "--metric", "registration", "--param", "max_iter=60", "-o", str(out),
                 "--no-progress", "--jobs", "1"]) == 0
    d = pd.read_csv(out, index_col=0)
    assert list(d.index) == [f"s{i}" for i in range(len(SETS))]
    np.testing.assert_allclose(d.to_numpy(), direct, rtol=1e-12, atol=1e-15)
    capsys.readouterr()
    assert main(["distances", str(f), "--metric", "registration", "--param", "max_iter=60", "--param", "shortlist=1",
                 "-o", str(out), "--no-progress", "--jobs", "1"]) == 0
    assert "registered only each query's 1 nearest" in capsys.readouterr().err
    assert main(["distances", str(f), "--metric", "registration", "--sigma2", "0.1", "-o", str(out)]) != 0
    assert "--sigma2" in capsys.readouterr().err


def test_the_engine_batches_a_block_on_jax_and_equals_the_numpy_matrix(direct):
    """backend="jax": every pair of a block (both directions) goes to the device in one batch
    (JAX's CPU backend here); the matrix equals the one-by-one registrations."""
    from tests.conftest import import_or_missing

    import_or_missing("jax", "JAX (the dev or jax extra) is not installed")
    r = sl.pairwise_distances(SETS[:4], metric="registration", n_jobs=1, progress=False, return_result=True,
                              backend="jax", **OPTS)
    np.testing.assert_allclose(r.matrix, direct[:4, :4], rtol=1e-6, atol=1e-9)
    with pytest.raises(ValueError, match="backend"):
        registration_distance(STAR, TRIFOIL, backend="cuda")


def test_registrations_on_jax_run_in_this_process_in_blocks_that_fill_the_device(direct, tmp_path):
    """backend="jax" with n_jobs left to the engine: one process feeds the one device (worker processes
    would each claim it), in blocks of about 32 × 32 registered pairs: with a shortlist that registers a
    fraction f of the pairs, a block's side grows as 1/√f; the matrix still equals one by one."""
    from tests.conftest import import_or_missing

    import_or_missing("jax", "JAX (the dev or jax extra) is not installed")
    r = sl.pairwise_distances(SETS[:4], metric="registration", progress=False, return_result=True,
                              backend="jax", store=str(tmp_path / "r.zarr"), **OPTS)
    assert r.log["mode"] == "in-process"
    np.testing.assert_allclose(r.matrix, direct[:4, :4], rtol=1e-6, atol=1e-9)
    from shapelib.pairwise._store import _Store

    # 20 sets, each registered with its 1 rigid nearest: at most 20 of the 190 pairs (f ≤ 0.105), so a block
    # is at least 32 / √0.105 ≈ 99 sets a side: all 20 in one block, one device call
    many = [_similar(SETS[k % len(SETS)], 0.3 * k, 1 + 0.05 * k, 0.1 * k) for k in range(20)]
    store = tmp_path / "s.zarr"
    sl.pairwise_distances(many, metric="registration", shortlist=1, store=str(store), progress=False,
                          backend="jax", max_iter=3)
    assert _Store.open(str(store)).b == 20


def test_the_registration_metric_is_known_after_import_shapelib_alone():
    # in a fresh interpreter, as a user's script starts: the metric is shapelib's own, whatever module
    # was imported first (it was registered only once shapelib.retrieval had been imported)
    import subprocess
    import sys

    code = ("import numpy as np, shapelib as sl\n"
            "from shapelib.distances import is_builtin\n"
            "info = sl.metric_info('registration')\n"
            "assert info.point_sets and is_builtin(info), info\n"
            "t = np.linspace(0, 2 * np.pi, 12, endpoint=False)\n"
            "x = np.c_[np.cos(t), 0.6 * np.sin(t)]\n"
            "d = sl.pairwise_distances([x, 2 * x[::-1] + 1], metric='registration', max_iter=60, progress=False)\n"
            "assert d.shape == (2, 2) and d[0, 1] < 1e-3, d\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr

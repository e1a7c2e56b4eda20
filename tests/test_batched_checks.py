"""Checks of the host-side parts of shapelib.solver.batched (no JAX program is compiled here; the device
solves are tests/test_jax_backend.py's): the bucket sizes against the set {1..4} ∪ {c·2^j, c = 4..7}
searched by brute force, the padded grids against the grids' own integrals, the Laplacian inverse against
np.linalg.inv of the tridiagonal matrix, grid coverage against a node-by-node set inclusion, the device
checks' errors, and a batch of identical pairs (solved without a device program) against what a trivial
geodesic is: a constant path of length 0."""

import numpy as np
import pytest

from shapelib.geometry.quadrature import make_grid
from shapelib.solver import batched
from shapelib.solver.batched import (GRID_PAD, _auto_batch, _covers, _entries_per_pair, _solve_grid,
                                     batched_geodesics, bucket, check_backend, jax_device, laplacian_inverse,
                                     stack_grids)
from shapelib.solver.path_metric import path_metric
from shapelib.solver.result import StopReason


def _smallest_bucket(m):
    sizes = {1, 2, 3, 4} | {c * 2 ** j for c in (4, 5, 6, 7) for j in range(30)}
    return min(s for s in sizes if s >= max(m, 1))


def test_bucket_is_the_smallest_allowed_size_at_or_above():
    for m in list(range(-2, 300)) + [1000, 1023, 1024, 1025, 5000, 7 * 2 ** 20 + 1]:
        assert bucket(m) == _smallest_bucket(m), m
    assert bucket(np.int64(9)) == 10 and type(bucket(np.int64(9))) is int


def test_padding_by_bucket_is_at_most_a_quarter():
    for m in range(5, 2000):
        assert m <= bucket(m) <= 1.25 * m


def test_stacked_grids_are_padded_with_weightless_copies_of_the_first_node():
    pts = [np.array([[0.0, 0.0], [1.0, 0.5]]), np.array([[0.0, 0.0]]), np.array([[2.0, -1.0], [3.0, 0.0]])]
    grids = [make_grid(p, sigma2=0.4, grid_spacing=0.5, grid_margin=3.0) for p in pts]
    nodes, weights = stack_grids(grids, 2)
    size = _smallest_bucket(max(len(g.nodes) for g in grids))
    assert nodes.shape == (3, size, 2) and weights.shape == (3, size)
    f = lambda x: np.exp(-0.5 * (x ** 2).sum(-1)) * (1 + x[..., 0])  # noqa: E731
    for i, g in enumerate(grids):
        m = len(g.nodes)
        np.testing.assert_array_equal(nodes[i, :m], g.nodes)
        np.testing.assert_array_equal(nodes[i, m:], np.broadcast_to(g.nodes[0], (size - m, 2)))
        assert np.all(weights[i, :m] == g.weight) and np.all(weights[i, m:] == 0)
        assert np.sum(weights[i] * f(nodes[i])) == pytest.approx(g.integrate(f(g.nodes)), rel=1e-13)


@pytest.mark.parametrize("m", [1, 2, 3, 7])
def test_laplacian_inverse_inverts_the_second_difference_matrix(m):
    lap = 2 * np.eye(m) - np.eye(m, k=1) - np.eye(m, k=-1)
    np.testing.assert_allclose(laplacian_inverse(m), np.linalg.inv(lap), rtol=1e-12, atol=1e-14)


def _node_set(grid, h):
    return {tuple(np.round(n / h).astype(int)) for n in grid.nodes}


def test_the_solve_grid_is_the_cpu_grid_with_grid_pad_more_margin_and_covers_it():
    rng = np.random.default_rng(0)
    path = rng.normal(size=(5, 4, 2))
    s2, spacing, margin = 0.5, 0.45, 5.0
    h, sigma = spacing * np.sqrt(s2), np.sqrt(s2)
    solve = _solve_grid(path, s2, spacing, margin)
    cpu = make_grid(path, sigma2=s2, grid_spacing=spacing, grid_margin=margin)
    assert _node_set(cpu, h) <= _node_set(solve, h)
    flat = path.reshape(-1, 2)
    for i, ax in enumerate(solve.axes):
        np.testing.assert_allclose(np.diff(ax), h, rtol=1e-12)  # the step asked for
        assert ax[0] <= flat[:, i].min() - (margin + GRID_PAD) * sigma + 1e-12
        assert ax[0] > flat[:, i].min() - (margin + GRID_PAD) * sigma - h
        assert ax[-1] >= flat[:, i].max() + (margin + GRID_PAD) * sigma - 1e-12
    assert _covers(solve, path, s2, spacing, margin) and _covers(cpu, path, s2, spacing, margin)


@pytest.mark.parametrize("shift", [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0), (3.0, 3.0)])
def test_a_path_that_moved_past_its_grid_is_not_covered(shift):
    """Coverage is set inclusion of the path's CPU grid in the given grid, node by node."""
    rng = np.random.default_rng(1)
    path = rng.normal(size=(3, 3, 2))
    s2, spacing, margin = 0.5, 0.35, 6.0
    h = spacing * np.sqrt(s2)
    grid = make_grid(path, sigma2=s2, grid_spacing=spacing, grid_margin=margin)
    moved = path + np.array(shift) * np.sqrt(s2)
    need = make_grid(moved, sigma2=s2, grid_spacing=spacing, grid_margin=margin)
    inside = _node_set(need, h) <= _node_set(grid, h)
    assert _covers(grid, moved, s2, spacing, margin) == inside
    assert not inside


@pytest.mark.parametrize("axis", [0, 1])
@pytest.mark.parametrize("nodes", [-1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5])
def test_coverage_is_node_set_inclusion_for_shifts_of_about_one_node(axis, nodes):
    # a non-default step and margin, and shifts of the path by fractions of one node h along one axis
    rng = np.random.default_rng(4)
    path = rng.normal(size=(3, 3, 2))
    s2, spacing, margin = 0.7, 0.5, 3.0
    h = spacing * np.sqrt(s2)
    grid = make_grid(path, sigma2=s2, grid_spacing=spacing, grid_margin=margin)
    moved = path.copy()
    moved[..., axis] += nodes * h
    need = make_grid(moved, sigma2=s2, grid_spacing=spacing, grid_margin=margin)
    assert _covers(grid, moved, s2, spacing, margin) == (_node_set(need, h) <= _node_set(grid, h))


def test_the_auto_batch_is_between_1_and_1024_and_shrinks_with_the_problem():
    small = _auto_batch("alpha", 2, 3, 1, "cpu")
    assert small == 1024
    assert _auto_batch("fisher_rao", 64, 200, 10 ** 6, "cpu") == 1
    sizes = [_auto_batch("fisher_rao", n, 20, 4000, "cpu") for n in (4, 8, 16, 32, 64)]
    assert all(1 <= s <= 1024 for s in sizes) and sizes == sorted(sizes, reverse=True) and sizes[0] > sizes[-1]
    # a pair's largest arrays: 3 n time nodes x K landmarks x (grid nodes or K) float64 entries
    assert _entries_per_pair("fisher_rao", 4, 5, 100) * 2 == _entries_per_pair("fisher_rao", 8, 5, 100)
    assert _entries_per_pair("fisher_rao", 4, 5, 100) * 3 == _entries_per_pair("fisher_rao", 4, 5, 300)
    assert _entries_per_pair("alpha", 4, 5, 10 ** 6) * 2 == _entries_per_pair("alpha", 4, 10, 10 ** 6) / 2
    # the default budget, 2 GiB where the device does not report its memory: a pair of 2 GiB / 8 entries fits once
    entries = _entries_per_pair("fisher_rao", 4, 5, 100)
    assert _auto_batch("fisher_rao", 4, 5, 100, "cpu") == min(1024, (2 * 2 ** 30) // (8 * entries))


def test_backend_and_device_are_checked():
    assert check_backend("cpu") == ("cpu", None) and check_backend("cpu", "cpu") == ("cpu", "cpu")
    assert check_backend("jax", "cpu") == ("jax", "cpu") and check_backend("jax") == ("jax", None)
    with pytest.raises(ValueError, match=r"^backend must be one of \('cpu', 'jax'\); got 'gpu'$"):
        check_backend("gpu")
    with pytest.raises(ValueError, match=r"^device must be None, 'cpu' or 'gpu'; got 'tpu'$"):
        check_backend("jax", "tpu")
    with pytest.raises(ValueError, match=r'^device="gpu" needs backend="jax" \(the CPU backend runs on the CPU only\)$'):
        check_backend("cpu", "gpu")
    import jax

    try:
        has_gpu = bool(jax.devices("gpu"))
    except RuntimeError:
        has_gpu = False
    if not has_gpu:  # the device is looked up before any work
        with pytest.raises(RuntimeError, match='device="gpu" but JAX sees no GPU'):
            check_backend("jax", "gpu")


def test_the_devices_are_jaxs():
    import jax

    assert jax_device() == jax.devices()[0]
    assert jax_device("cpu") == jax.devices("cpu")[0]
    try:
        gpus = jax.devices("gpu")
    except RuntimeError:
        gpus = []
    if gpus:
        assert jax_device("gpu") == gpus[0]
    else:
        with pytest.raises(RuntimeError, match=r'^device="gpu" but JAX sees no GPU \(JAX .*, devices: .*\); on a '
                                               r'CUDA 12 machine: pip install "shapelib\[gpu\]"$'):
            jax_device("gpu")


U = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 1.5]])


def test_identical_pairs_are_trivial_constant_paths_of_length_zero():
    us = np.stack([U, U + 1.0])
    res = batched_geodesics(us, us.copy(), metric="alpha", sigma2=0.5, n_steps=3, device="cpu", tol=1e-5)
    assert len(res) == 2
    import jax

    for u, r in zip(us, res):
        np.testing.assert_array_equal(r.path, np.broadcast_to(u, (4, 3, 2)))
        assert r.length == 0.0 and r.energy == 0.0 and r.lower_bound == 0.0 and r.grad_norm == 0.0
        assert r.converged and r.stop_reason is StopReason.TRIVIAL and r.n_iter == 0
        assert r.max_step_over_sigma == 0.0 and r.metric == "alpha" and r.sigma2 == 0.5
        assert r.log["solver"] == "lbfgs" and r.log["backend"] == "jax" and r.log["hessian"] is None
        assert r.log["device"] == str(jax.devices("cpu")[0]) and r.log["regrids"] == 0
        assert r.log["n_steps"] == 3 and r.log["tol"] == 1e-5 and r.log["energy"] == [0.0]
        assert r.log["stopped_by"] == "trivial" and r.log["newton_decrement"] is None and r.log["damping"] == []
        assert r.rel_energy_change == 0.0


def test_given_lower_bounds_and_init_ends_are_used():
    us = np.stack([U, U])
    init = np.full((2, 3, 3, 2), 5)  # integers, read as floats: the ends are replaced by the pairs' (1.5 kept)
    res = batched_geodesics(us, us, metric="fisher_rao", sigma2=0.5, n_steps=2, init=init, lower_bounds=[0.25, 0.5],
                            device="cpu")
    assert [r.lower_bound for r in res] == [0.25, 0.5]
    for r in res:
        np.testing.assert_array_equal(r.path[0], U)
        np.testing.assert_array_equal(r.path[-1], U)
        np.testing.assert_array_equal(r.path[1], np.full((3, 2), 5.0))
        assert r.max_step_over_sigma == pytest.approx(np.linalg.norm(U - 5.0, axis=1).max() / np.sqrt(0.5))
    model = path_metric("fisher_rao", 0.5)
    res = batched_geodesics(us, us, metric="fisher_rao", sigma2=0.5, n_steps=2, device="cpu")
    assert res[0].lower_bound == model.lower_bound(U, U)


@pytest.mark.parametrize("kwargs, match", [
    (dict(metric="euclid"), r"^metric must be one of"),
    (dict(n_steps=0), "^n_steps must be"), (dict(tol=0.0), "^tol must be"), (dict(max_iter=-1), "^max_iter must be"),
    (dict(window=0), "^window must be"), (dict(batch_size=0), "^batch_size must be"),
    (dict(init=np.zeros((2, 3, 3, 2))), r"^init must have shape \(2, 5, 3, 2\); got \(2, 3, 3, 2\)$"),
    (dict(init=np.full((2, 5, 3, 2), np.nan)), "^init contains non-finite values$"),
])
def test_arguments_are_checked_before_any_solve(kwargs, match):
    kw = dict(metric="alpha", sigma2=0.5, n_steps=4, device="cpu")
    kw.update(kwargs)
    with pytest.raises(ValueError, match=match):
        batched_geodesics(np.stack([U, U]), np.stack([U, U + 0.1]), **kw)


def test_pairs_of_different_shapes_are_refused():
    with pytest.raises(ValueError, match="us and vs"):
        batched_geodesics(np.stack([U, U]), U[None], metric="alpha", sigma2=0.5, device="cpu")


def test_the_constants_are_the_documented_ones():
    assert batched.BACKENDS == ("cpu", "jax") and batched.DEVICES == (None, "cpu", "gpu")
    assert batched.GRID_PAD == 2.0 and batched.MAX_REGRIDS == 3 and batched.LBFGS_HISTORY == 10


def test_the_defaults_are_the_cpu_solvers():
    """batched_geodesics solves what shapelib.geodesic does for one pair: the same settings by default."""
    import inspect

    import shapelib

    ours, cpu = (inspect.signature(f).parameters for f in (batched_geodesics, shapelib.geodesic))
    for name in ("metric", "n_steps", "tol", "max_iter", "window", "init", "grid_spacing", "grid_margin", "device",
                 "warn"):
        assert ours[name].default == cpu[name].default, name


def test_the_device_solvers_defaults_are_the_cpu_solvers():
    """lbfgs_solve stops as shapelib.geodesic does by default (tolerance, iterations, window)."""
    import inspect

    import shapelib

    ours, cpu = (inspect.signature(f).parameters for f in (batched.lbfgs_solve, shapelib.geodesic))
    for name in ("tol", "max_iter", "window"):
        assert ours[name].default == cpu[name].default, name


# -------------------------------------------------------------------------------------------------
# The automatic batch size and the device lookups, with stand-in devices (no JAX program is compiled)
# -------------------------------------------------------------------------------------------------


class _Device:
    """A stand-in JAX device: a name and what its ``memory_stats()`` reports (None: nothing, as JAX's CPU)."""

    def __init__(self, name, stats=None, fails=False):
        self.name, self.stats, self.fails = name, stats, fails

    def memory_stats(self):
        if self.fails:
            raise RuntimeError("memory_stats is not implemented for this platform")
        return self.stats

    def __str__(self):
        return self.name


def _largest_fitting(budget, per_pair):
    """The most pairs of ``per_pair`` bytes each within ``budget`` bytes, clipped to [1, 1024], by counting."""
    b = 1
    while b < 1024 and (b + 1) * per_pair <= budget:
        b += 1
    return b


def _use_devices(monkeypatch, devices):
    """batched.jax_device looks ``device`` up in ``devices``; the lookups are recorded."""
    asked = []

    def lookup(device=None):
        asked.append(device)
        return devices[device]

    monkeypatch.setattr(batched, "jax_device", lookup)
    return asked


GIB = 2 ** 30


def test_the_auto_batch_is_the_most_pairs_that_fit_40_percent_of_the_memory_the_device_reports(monkeypatch):
    """A device that reports its memory gets 40 % of it; one that does not (JAX's CPU: None, an empty report, a
    report without the limit, or an error) 2 GiB; a pair's arrays take 8 bytes an entry."""
    devices = {"gpu": _Device("gpu:0", {"bytes_limit": 80 * GIB, "bytes_in_use": 10 * GIB}),
               "cpu": _Device("cpu:0", None), None: _Device("other:0", {"bytes_limit": 16 * GIB}),
               "empty": _Device("e:0", {}), "nolimit": _Device("n:0", {"bytes_in_use": 5 * GIB}),
               "fails": _Device("f:0", fails=True)}
    asked = _use_devices(monkeypatch, devices)
    problems = [("fisher_rao", 16, 20, 4000), ("fisher_rao", 32, 12, 9000), ("fisher_rao", 8, 40, 2500),
                ("alpha", 16, 100, 1)]
    for metric, n, k, grid in problems:
        per_pair = 8 * _entries_per_pair(metric, n, k, grid)
        assert 1 < _largest_fitting(2 * GIB, per_pair) < 1024  # problems between the floor and the cap
        for device, budget in (("gpu", 0.4 * 80 * GIB), (None, 0.4 * 16 * GIB), ("cpu", 2 * GIB),
                               ("empty", 2 * GIB), ("nolimit", 2 * GIB), ("fails", 2 * GIB)):
            asked.clear()
            assert _auto_batch(metric, n, k, grid, device) == _largest_fitting(budget, per_pair), (metric, device)
            assert asked == [device]  # the memory of the device asked for
    # the 80 GiB device's batches are not the 2 GiB default's (the report is read)
    per_pair = 8 * _entries_per_pair("fisher_rao", 16, 20, 4000)
    assert _largest_fitting(0.4 * 80 * GIB, per_pair) != _largest_fitting(2 * GIB, per_pair)


def _spy_solves(monkeypatch):
    """batched.lbfgs_solve replaced by a spy that records its first call and stops the solve there."""
    calls = []

    class Stop(Exception):
        pass

    def spy(paths, **kwargs):
        calls.append(dict(kwargs, paths=np.array(paths)))
        raise Stop

    monkeypatch.setattr(batched, "lbfgs_solve", spy)
    return calls, Stop


def test_with_no_options_the_device_solve_stops_as_shapelib_geodesic_does(monkeypatch):
    """batched_geodesics called with its defaults hands the device loop shapelib.geodesic's defaults: its metric
    and steps (the path's shape), tolerance, iterations and window."""
    import inspect

    import shapelib

    cpu = {name: p.default for name, p in inspect.signature(shapelib.geodesic).parameters.items()}
    calls, stop = _spy_solves(monkeypatch)
    v = U[[1, 2, 0]] * 0.9
    with pytest.raises(stop):
        batched_geodesics(np.stack([U, U]), np.stack([v, U + 0.2]), sigma2=0.5, device="cpu")
    (call,) = calls
    assert call["metric"] == cpu["metric"] and call["paths"].shape == (2, cpu["n_steps"] + 1, 3, 2)
    assert (call["tol"], call["max_iter"], call["window"]) == (cpu["tol"], cpu["max_iter"], cpu["window"])
    np.testing.assert_allclose(call["paths"][0], np.linspace(U, v, cpu["n_steps"] + 1), rtol=0, atol=1e-15)


def _fr_pairs(scales):
    """Fisher–Rao pairs whose solve grids grow with ``scale`` (the shapes' spread)."""
    rng = np.random.default_rng(3)
    base = rng.normal(size=(4, 2))
    return np.stack([base * s for s in scales]), np.stack([(base + 0.3 * rng.normal(size=base.shape)) * s
                                                           for s in scales])


def test_the_auto_batch_fits_the_largest_solve_grid_and_batches_go_smallest_grid_first(monkeypatch):
    """Fisher–Rao pairs of three grid sizes on a device that reports its memory: the device calls take the pairs
    by the size of their solve grid, smallest first (so each call pads its grids least), as many a call as fit
    40 % of the memory with the largest grid's arrays."""
    s2, n, kw = 0.5, 4, dict(grid_spacing=0.6, grid_margin=4.0)
    us, vs = _fr_pairs([3.0, 1.0, 2.0, 1.5, 2.5])
    straight = np.linspace(us, vs, n + 1, axis=1)
    sizes = [len(_solve_grid(p, s2, kw["grid_spacing"], kw["grid_margin"]).nodes) for p in straight]
    assert len(set(sizes)) == 5
    per_pair = 8 * _entries_per_pair("fisher_rao", n, 4, max(sizes))
    memory = 3.5 * per_pair / 0.4  # room for 3 pairs of the largest grid (and more of the smallest)
    assert 8 * _entries_per_pair("fisher_rao", n, 4, min(sizes)) * 4 <= 0.4 * memory
    _use_devices(monkeypatch, {"gpu": _Device("gpu:0", {"bytes_limit": memory})})
    calls, stop = _spy_solves(monkeypatch)
    with pytest.raises(stop):
        batched_geodesics(us, vs, metric="fisher_rao", sigma2=s2, n_steps=n, device="gpu", **kw)
    first = np.argsort(sizes)[:3]
    np.testing.assert_allclose(calls[0]["paths"], straight[first], rtol=0, atol=1e-14)
    assert calls[0]["metric"] == "fisher_rao" and calls[0]["nodes"].shape[:2] == (3, bucket(sizes[first[-1]]))
    # two pairs, the larger grid first, one a call: the smaller one goes first
    calls.clear()
    with pytest.raises(stop):
        batched_geodesics(us[[0, 1]], vs[[0, 1]], metric="fisher_rao", sigma2=s2, n_steps=n, device="gpu",
                          batch_size=1, **kw)
    np.testing.assert_allclose(calls[0]["paths"], straight[[1]], rtol=0, atol=1e-14)


class _Jax:
    """What jax.devices answers on a machine with ``gpus`` GPUs and ``cpus`` CPU devices (JAX's platform names are
    lower case; an unknown or absent one raises RuntimeError)."""

    def __init__(self, gpus, cpus):
        self.by = {"gpu": [_Device(f"cuda:{i}") for i in range(gpus)], "cpu": [_Device(f"TFRT_CPU_{i}")
                                                                               for i in range(cpus)]}

    def devices(self, backend=None):
        if backend is None:
            return self.by["gpu"] or self.by["cpu"]  # JAX's default: the GPUs where there are some
        if not self.by.get(backend):
            raise RuntimeError(f"Unknown backend {backend}")
        return self.by[backend]


def test_the_device_lookups_pick_jaxs_default_its_first_cpu_and_its_first_gpu(monkeypatch):
    import jax

    two_gpus = _Jax(gpus=2, cpus=1)
    monkeypatch.setattr(jax, "devices", two_gpus.devices)
    assert jax_device() is two_gpus.by["gpu"][0] and jax_device(None) is two_gpus.by["gpu"][0]
    assert jax_device("cpu") is two_gpus.by["cpu"][0]
    assert jax_device("gpu") is two_gpus.by["gpu"][0]
    no_gpu = _Jax(gpus=0, cpus=2)
    monkeypatch.setattr(jax, "devices", no_gpu.devices)
    assert jax_device() is no_gpu.by["cpu"][0] and jax_device("cpu") is no_gpu.by["cpu"][0]
    with pytest.raises(RuntimeError) as err:
        jax_device("gpu")
    assert str(err.value).startswith(f'device="gpu" but JAX sees no GPU (JAX {jax.__version__}, devices: '
                                     f'TFRT_CPU_0, TFRT_CPU_1); on a CUDA 12 machine: ')

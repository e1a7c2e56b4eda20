"""Checks of shapelib.statistics.population_logs against a loop over the shapes one at a time: the chunked
results in the order of the shapes, each task's base, shapes and warm starts the slice the loop would
give, the chunk sizes by the documented rule (N / DEFAULT_CHUNKS rounded up), the warm starts of
shifted_paths against their definition point by point (start moved by the change of base, the move
tapered linearly to zero at the end), and one real log map against shapelib.solver.logexp.log_maps."""

import math
from concurrent.futures import Future
from types import SimpleNamespace

import numpy as np
import pytest

from shapelib.solver.logexp import GeodesicOptions, log_maps
from shapelib.statistics import population_logs as module
from shapelib.statistics.population_logs import DEFAULT_CHUNKS, population_logs, shifted_paths


class Recorder:
    """A synchronous executor that records the size of each task."""

    def __init__(self):
        self.sizes = []

    def submit(self, fn, *args, **kwargs):
        self.sizes.append(len(args[1]))
        fut = Future()
        fut.set_result(fn(*args, **kwargs))
        return fut


def fake_log_maps(base, shapes, *, options, inits=None):
    """One record per shape: its own base, shape, warm start and options (what the loop would pass)."""
    base = np.asarray(base)
    out = []
    for i, s in enumerate(shapes):
        b = base if base.ndim == 2 else base[i]
        out.append(SimpleNamespace(base=np.array(b), shape=np.array(s), init=inits[i], options=options))
    return out


def _data(n, per_shape_base):
    rng = np.random.default_rng(n)
    shapes = rng.normal(size=(n, 3, 2))
    base = rng.normal(size=(n, 3, 2)) if per_shape_base else rng.normal(size=(3, 2))
    inits = [f"init{i}" for i in range(n)]
    return base, shapes, inits


def _check_in_order(out, base, shapes, inits, options):
    assert len(out) == len(shapes)
    for i, r in enumerate(out):
        np.testing.assert_array_equal(r.base, base if np.ndim(base) == 2 else base[i])
        np.testing.assert_array_equal(r.shape, shapes[i])
        assert r.init == inits[i] and r.options is options


@pytest.mark.parametrize("n, chunk, sizes", [(5, 2, [2, 2, 1]), (6, 3, [3, 3]), (4, 10, [4]), (3, 1, [1, 1, 1])])
@pytest.mark.parametrize("per_shape_base", [False, True])
def test_chunks_in_order_each_with_its_slice(monkeypatch, n, chunk, sizes, per_shape_base):
    monkeypatch.setattr(module, "log_maps", fake_log_maps)
    base, shapes, inits = _data(n, per_shape_base)
    ex = Recorder()
    options = object()
    out = population_logs(base, shapes, options=options, inits=inits, executor=ex, chunk_size=chunk)
    assert ex.sizes == sizes
    _check_in_order(out, base, shapes, inits, options)


@pytest.mark.parametrize("n", [1, 15, 16, 17, 33, 40])
def test_the_default_chunk_is_n_over_default_chunks_rounded_up(monkeypatch, n):
    monkeypatch.setattr(module, "log_maps", fake_log_maps)
    base, shapes, inits = _data(n, False)
    ex = Recorder()
    out = population_logs(base, shapes, options=None, inits=inits, executor=ex)
    size = math.ceil(n / 16)
    assert DEFAULT_CHUNKS == 16
    assert ex.sizes == [min(size, n - a) for a in range(0, n, size)]
    _check_in_order(out, base, shapes, inits, None)


def test_without_an_executor_one_call_in_process_and_no_warm_starts_are_nones(monkeypatch):
    calls = []

    def counted(*args, **kw):
        calls.append(len(args[1]))
        return fake_log_maps(*args, **kw)

    monkeypatch.setattr(module, "log_maps", counted)
    base, shapes, _ = _data(5, False)
    options = object()
    out = population_logs(base, shapes, options=options)
    assert calls == [5] and [r.init for r in out] == [None] * 5 and all(r.options is options for r in out)
    ex = Recorder()
    out = population_logs(base, shapes, options=None, executor=ex, chunk_size=2)
    assert ex.sizes == [2, 2, 1] and [r.init for r in out] == [None] * 5
    assert population_logs(base, shapes[:0], options=None, executor=ex) == [] and ex.sizes == [2, 2, 1]


def test_a_real_population_on_an_executor_is_the_log_maps_one_by_one():
    rng = np.random.default_rng(0)
    base = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    shapes = base + 0.1 * rng.normal(size=(3, 4, 2))
    opts = GeodesicOptions("alpha", 0.5, n_steps=2)
    out = population_logs(base, shapes, options=opts, executor=Recorder(), chunk_size=2)
    for s, r in zip(shapes, out):
        one = log_maps(base, s[None], options=opts)[0]
        np.testing.assert_allclose(r.vector, one.vector, rtol=1e-10, atol=1e-12)


def _paths(n_results, n_steps, seed=1):
    rng = np.random.default_rng(seed)
    return [SimpleNamespace(path=rng.normal(size=(n_steps + 1, 3, 2))) for _ in range(n_results)]


@pytest.mark.parametrize("per_result", [False, True])
@pytest.mark.parametrize("n_steps", [1, 4])
def test_shifted_paths_move_the_start_and_taper_to_the_fixed_end(per_result, n_steps):
    results = _paths(3, n_steps)
    rng = np.random.default_rng(2)
    shape = (3, 3, 2) if per_result else (3, 2)
    old, new = rng.normal(size=shape), rng.normal(size=shape)
    out = shifted_paths(results, old, new)
    assert len(out) == 3
    for i, (r, p) in enumerate(zip(results, out)):
        delta = (new - old) if not per_result else (new[i] - old[i])
        assert p.shape == r.path.shape
        for k in range(n_steps + 1):
            t = k / n_steps
            np.testing.assert_allclose(p[k], r.path[k] + (1 - t) * delta, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(p[0] - r.path[0], delta, atol=1e-12)   # start moved with the base
        np.testing.assert_array_equal(p[-1], r.path[-1])                    # end fixed


def test_one_result_is_shifted_too():
    (r,) = _paths(1, 2)
    (p,) = shifted_paths([r], np.zeros((3, 2)), np.ones((3, 2)))
    np.testing.assert_allclose(p, r.path + np.array([1.0, 0.5, 0.0])[:, None, None], atol=1e-15)


def test_shifted_paths_of_nothing_is_nothing():
    assert shifted_paths([], np.zeros((3, 2)), np.ones((3, 2))) == []

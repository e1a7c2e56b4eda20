"""Checks of shapelib.statistics._run against independent values: the projected serial time from a scripted
clock (the faster of two timed log maps times N times the rounds, one only when the first is long), the
chunk size against its rule counted with math.ceil, and where_logs_run's choice (a given executor, in this
process for tiny work, timing otherwise) against the engine_executor call it makes, recorded by a stand-in."""

import contextlib
import math
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from shapelib.geometry.scale import ScaleWarning
from shapelib.statistics import _run
from shapelib.statistics._run import MEAN_ROUNDS, Where, _chunk_size, projected_seconds, where_logs_run


def _clock(monkeypatch, ticks):
    ticks = iter(ticks)
    monkeypatch.setattr(_run, "time", SimpleNamespace(perf_counter=lambda: next(ticks)))


def _log_maps(calls):
    def fake(base, shapes, *, options):
        calls.append((np.array(base), np.array(shapes), options))
        warnings.warn("tiny", ScaleWarning)
        return []
    return fake


@pytest.mark.parametrize("ticks, expected_unit", [((0.0, 3.0, 3.0, 4.0), 1.0), ((0.0, 0.5, 1.0, 3.0), 0.5),
                                                  ((0.0, 10.0, 10.0, 10.25), 0.25)])
def test_projected_seconds_is_the_faster_of_two_calls_times_n_times_rounds(monkeypatch, ticks, expected_unit):
    calls = []
    monkeypatch.setattr(_run, "log_maps", _log_maps(calls))
    _clock(monkeypatch, ticks)
    x = np.arange(5 * 3 * 2, dtype=float).reshape(5, 3, 2)
    base = np.ones((3, 2))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the ScaleWarning of the timed log map is silenced
        assert projected_seconds(x, base, "opts", rounds=3.0) == pytest.approx(expected_unit * 5 * 3.0)
    assert len(calls) == 2
    for b, s, o in calls:  # one shape, the first, at the base
        np.testing.assert_array_equal(b, base)
        np.testing.assert_array_equal(s, x[:1])
        assert o == "opts"


def test_only_the_scale_warning_of_the_timed_log_map_is_silenced(monkeypatch):
    def fake(base, shapes, *, options):
        warnings.warn("tiny", ScaleWarning)
        warnings.warn("something else", RuntimeWarning)
        return []

    monkeypatch.setattr(_run, "log_maps", fake)
    _clock(monkeypatch, (0.0, 1.0, 1.0, 2.0))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        projected_seconds(np.zeros((3, 3, 2)), np.zeros((3, 2)), None)
    assert [w.category for w in caught] == [RuntimeWarning, RuntimeWarning]


def test_projected_seconds_times_once_when_the_first_call_is_long_and_defaults_to_mean_rounds(monkeypatch):
    calls = []
    monkeypatch.setattr(_run, "log_maps", _log_maps(calls))
    _clock(monkeypatch, (0.0, 10.5))
    x = np.zeros((4, 3, 2))
    assert projected_seconds(x, np.zeros((3, 2)), None) == pytest.approx(10.5 * 4 * MEAN_ROUNDS)
    assert len(calls) == 1 and MEAN_ROUNDS == 2.0


@pytest.mark.parametrize("n", [1, 3, 4, 5, 8, 9, 100])
@pytest.mark.parametrize("workers", [0, 1, 2, 3])
def test_four_tasks_per_worker(n, workers):
    assert _chunk_size(n, workers) == max(1, math.ceil(n / (4 * max(1, workers))))


def test_where_passes_on_its_executor_or_one_job_and_records_its_mode():
    ex = object()
    assert Where(ex, 3, "cluster", 7).passed_on == {"executor": ex, "chunk_size": 7}
    assert Where(None, 1, "in-process", 2).passed_on == {"n_jobs": 1, "chunk_size": 2}
    history = [{"a": 1}, {"b": 2}, {"c": 3}]
    Where(None, 1, "in-process", 2).record(history)
    assert history == [{"a": 1}, {"b": 2}, {"c": 3, "mode": "in-process", "n_workers": 1}]
    history = [{"b": 2}]
    Where(ex, None, "executor", 2).record(history)
    assert history == [{"b": 2}]
    empty = []
    Where(None, 1, "in-process", 2).record(empty)
    assert empty == []


@pytest.fixture
def engine(monkeypatch):
    """A stand-in engine_executor that records its keywords and yields (executor, workers, mode)."""
    seen = {}

    @contextlib.contextmanager
    def fake(*, n_jobs=None, client=None, scheduler=None, serial_seconds=None):
        seen.update(n_jobs=n_jobs, client=client, scheduler=scheduler, serial_seconds=serial_seconds)
        yield seen.get("yield", (None, 1, "in-process"))

    monkeypatch.setattr(_run, "engine_executor", fake)
    return seen


def test_a_given_executor_is_used_as_it_is(engine):
    ex = object()
    with where_logs_run(np.zeros((9, 3, 2)), None, base=None, rounds=2, executor=ex, chunk_size=4) as w:
        assert w == Where(ex, None, "executor", 4)
    assert engine == {}
    for kw in (dict(n_jobs=2), dict(client=object()), dict(scheduler="tcp://x")):
        with pytest.raises(ValueError, match="give executor, or n_jobs / client / scheduler, not both"):
            with where_logs_run(np.zeros((9, 3, 2)), None, base=None, rounds=2, executor=ex, **kw):
                pass


@pytest.mark.parametrize("n, rounds", [(1, 2.0), (2, 2.0), (5, 0.0), (5, -1.0)])
def test_tiny_work_stays_in_process_without_timing(monkeypatch, engine, n, rounds):
    monkeypatch.setattr(_run, "projected_seconds", lambda *a, **k: pytest.fail("timed"))
    with where_logs_run(np.zeros((n, 3, 2)), None, base=lambda: pytest.fail("base built"), rounds=rounds) as w:
        assert w.executor is None and w.chunk_size == _chunk_size(n, 1)
    assert engine["n_jobs"] == 1 and engine["serial_seconds"] is None


@pytest.mark.parametrize("n_jobs", [None, -1])
@pytest.mark.parametrize("callable_base", [False, True])
def test_otherwise_one_log_map_is_timed_at_the_base(monkeypatch, engine, n_jobs, callable_base):
    seen = {}

    def projected(x, base, options, *, rounds):
        seen.update(n=len(x), base=base, options=options, rounds=rounds)
        return 42.0

    monkeypatch.setattr(_run, "projected_seconds", projected)
    b = np.full((3, 2), 7.0)
    engine["yield"] = ("EX", 3, "LocalCluster(3 processes)")
    with where_logs_run(np.zeros((13, 3, 2)), "opts", base=(lambda: b) if callable_base else b, rounds=1.5,
                        n_jobs=n_jobs) as w:
        assert w == Where("EX", 3, "LocalCluster(3 processes)", _chunk_size(13, 3)) and w.chunk_size == 2
    assert seen["n"] == 13 and seen["base"] is b and seen["options"] == "opts" and seen["rounds"] == 1.5
    assert engine["serial_seconds"] == 42.0 and engine["n_jobs"] == n_jobs


def test_a_fixed_engine_is_not_timed_and_a_given_chunk_size_wins(monkeypatch, engine):
    monkeypatch.setattr(_run, "projected_seconds", lambda *a, **k: pytest.fail("timed"))
    for kw in (dict(n_jobs=2), dict(client="C"), dict(scheduler="tcp://x")):
        engine.clear()
        with where_logs_run(np.zeros((13, 3, 2)), None, base=None, rounds=2.0, chunk_size=5, **kw) as w:
            assert w.chunk_size == 5
        expected = dict(n_jobs=None, client=None, scheduler=None, serial_seconds=None)
        expected.update(kw)
        assert engine == expected


def test_where_it_runs_is_checked():
    with pytest.raises(ValueError, match="n_jobs"):
        with where_logs_run(np.zeros((3, 3, 2)), None, base=None, rounds=2.0, n_jobs=0):
            pass

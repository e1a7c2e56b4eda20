"""Checks of shapelib.solver.result against values the records are built from, independently of the solver:
a hand-made GeodesicResult whose path is a known function of time, its times, velocities and interpolation
against NumPy's (np.interp per coordinate, the exact derivative of the path), its summary against the
fields it was given, and the stop reasons' convergence as their docstrings list it."""

import numpy as np
import pytest

from shapelib.solver.result import BracketStopReason, GeodesicResult, GeodesicWarning, StopReason


def _result(n_steps=4, **fields):
    """A record whose path is θ(t) = a + b t + c t² sampled at t = k / n (K = 3 landmarks in 2-D)."""
    rng = np.random.default_rng(3)
    a, b, c = rng.normal(size=(3, 3, 2))
    t = np.arange(n_steps + 1) / n_steps
    path = a + b * t[:, None, None] + c * t[:, None, None] ** 2
    kw = dict(path=path, length=1.25, energy=1.75, lower_bound=0.875, converged=True, n_iter=7, grad_norm=1e-9,
              rel_energy_change=1e-10, max_step_over_sigma=0.3, metric="alpha", sigma2=0.5,
              log={"stopped_by": "newton_decrement"})
    kw.update(fields)
    return GeodesicResult(**kw), (a, b, c, t)


@pytest.mark.parametrize("n_steps", [1, 3, 5])
def test_times_and_steps_are_the_sample_times_of_the_path(n_steps):
    r, (_, _, _, t) = _result(n_steps)
    assert r.n_steps == n_steps
    np.testing.assert_allclose(r.times, t, rtol=0, atol=1e-15)


def test_velocities_are_the_chord_slopes_of_the_path():
    r, (a, b, c, t) = _result(5)
    # θ(t1) − θ(t0) over t1 − t0 of the quadratic: b + c (t0 + t1)
    expected = b + c * (t[:-1] + t[1:])[:, None, None]
    np.testing.assert_allclose(r.velocities, expected, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("tq", [0.0, 0.1, 0.25, 0.5, 0.61, 0.99, 1.0])
def test_shape_at_is_linear_interpolation_of_the_path(tq):
    r, (_, _, _, t) = _result(4)
    expected = np.stack([[np.interp(tq, t, r.path[:, k, j]) for j in range(2)] for k in range(3)])
    np.testing.assert_allclose(r.shape_at(tq), expected, rtol=1e-12, atol=1e-12)


def test_shape_at_hits_the_path_points():
    r, _ = _result(4)
    for k in range(5):
        np.testing.assert_allclose(r.shape_at(k / 4), r.path[k], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("tq", [-1e-9, 1.0 + 1e-9, -0.5, 2.0, float("nan")])
def test_shape_at_outside_the_unit_interval_is_a_value_error_naming_t(tq):
    r, _ = _result(4)
    with pytest.raises(ValueError, match="t must lie in"):
        r.shape_at(tq)


def test_value_lower_upper_are_the_fields():
    r, _ = _result(length=2.5, lower_bound=1.5)
    assert r.value == 2.5 and r.upper == 2.5 and r.lower == 1.5


def test_summary_reports_the_fields_it_was_built_from():
    r, _ = _result(length=1.234567891, lower_bound=0.987654321, converged=False, n_iter=13, metric="fisher_rao",
                   log={"stopped_by": "max_iter"})
    assert r.summary() == ("fisher_rao: length 1.23457 (lower bound 0.987654), converged False in 13 iterations "
                           "(max_iter)")
    r2, _ = _result(log={})
    assert r2.summary().endswith("converged True in 7 iterations (?)")


def test_stop_reason_reads_the_log():
    for reason in StopReason:
        r, _ = _result(log={"stopped_by": reason.value})
        assert r.stop_reason is reason


def test_stop_reasons_converged_as_documented():
    # the docstrings: max_iter and underflow are the only stops that are not converged
    not_converged = {"max_iter", "underflow"}
    assert {s.value for s in StopReason} == {"trivial", "newton_decrement", "energy_window", "no_decrease",
                                            "target_energy", "max_iter", "underflow"}
    for s in StopReason:
        assert s.converged is (s.value not in not_converged)
        assert str(s) == s.value and StopReason(s.value) is s
    assert {s.value for s in BracketStopReason} == {"rtol", "stalled", "max_n_steps", "trivial"}
    for s in BracketStopReason:
        assert s.converged is (s.value in {"rtol", "trivial"})
        assert str(s) == s.value and BracketStopReason(s.value) is s


def test_the_warning_is_a_runtime_warning():
    assert issubclass(GeodesicWarning, RuntimeWarning)


def test_log_defaults_to_an_empty_dict_of_its_own():
    kw = dict(path=np.zeros((2, 1, 2)), length=0.0, energy=0.0, lower_bound=0.0, converged=True, n_iter=0,
              grad_norm=None, rel_energy_change=0.0, max_step_over_sigma=0.0, metric="alpha", sigma2=None)
    r1, r2 = GeodesicResult(**kw), GeodesicResult(**kw)
    assert r1.log == {} and r1.log is not r2.log
    assert "log=" not in repr(r1)

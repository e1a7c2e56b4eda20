"""register_many and fits_many on the numpy backend (no JAX: a few hundredths of a second each): the
pairs as a 4-D array equal the same pairs as a list, bad input is refused naming what it got, and
fits_many passes its options to register and assesses nothing (no warning) where register would warn."""

import warnings

import numpy as np
import pytest

import shapelib
from shapelib.pointsets._batch import fits_many

T = np.linspace(0, 2 * np.pi, 12, endpoint=False)
STAR = np.c_[np.cos(T), np.sin(T)] * (1 + 0.3 * np.cos(2 * T) + 0.15 * np.sin(5 * T + 0.4))[:, None]
TRIFOIL = np.c_[np.cos(T), np.sin(T)] * (1 + 0.25 * np.cos(3 * T) + 0.1 * np.cos(T + 1))[:, None]


def test_pairs_as_a_four_d_array_are_the_same_pairs_as_a_list():
    arr = np.stack([np.stack([STAR, TRIFOIL]), np.stack([TRIFOIL, 2.0 * STAR])])   # (pairs, 2, n, d)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", shapelib.RegistrationWarning)
        got = shapelib.register_many(arr)
        ref = [shapelib.register(x, y, transform="nonrigid") for x, y in arr]
    assert [r.sigma2 for r in got] == [r.sigma2 for r in ref]
    np.testing.assert_array_equal(got[1].points, ref[1].points)


@pytest.mark.parametrize("pairs, match", [
    (np.zeros((2, 3, 2)), r"^pairs must be a sequence of \(source, target\) pairs of point sets; got an array of "
                          r"shape \(2, 3, 2\)$"),
    (np.zeros((1, 2, 3, 2, 1)), r"got an array of shape \(1, 2, 3, 2, 1\)$"),
    (5, r"^pairs must be a sequence of \(source, target\) pairs; got int$"),
])
def test_bad_pairs_say_what_they_got(pairs, match):
    with pytest.raises(ValueError, match=match):
        shapelib.register_many(pairs)


def test_fits_many_passes_its_options_and_warns_of_nothing():
    """At max_iter=2 register warns (an EM that did not converge); fits_many gives the same fit silently."""
    with pytest.warns(shapelib.RegistrationWarning):
        ref = shapelib.register(STAR, TRIFOIL, transform="nonrigid", max_iter=2, w=0.0, lam=3.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = fits_many([(STAR, TRIFOIL)], max_iter=2, w=0.0, lam=3.0)
    assert got == [(ref.sigma2, ref.converged, ref.n_iter, ref.deformation_energy)] and ref.n_iter == 2
    assert not ref.converged
    assert [type(v) for v in got[0]] == [float, bool, int, float]


def test_the_numpy_backend_is_register_with_every_option():
    opts = dict(reflection=True, lam=3.0, sigma2_metric=1.0, w=0.0, max_iter=40, tol=1e-3, n_steps=5)
    timings = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", shapelib.RegistrationWarning)
        got = shapelib.register_many([(STAR, TRIFOIL)], timings=timings, **opts)[0]
        ref = shapelib.register(STAR, TRIFOIL, transform="nonrigid", **opts)
        default = shapelib.register(STAR, TRIFOIL, transform="nonrigid")
    assert (got.sigma2, got.n_iter, got.w) == (ref.sigma2, ref.n_iter, ref.w) != (default.sigma2, default.n_iter, default.w)
    np.testing.assert_array_equal(got.points, ref.points)
    assert len(got.path) == len(ref.path) == 6   # n_steps segments of the deformation's geodesic
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", shapelib.RegistrationWarning)
        assert len(shapelib.register_many([(STAR, TRIFOIL)])[0].path) == len(default.path)   # register's default
    assert (timings["prep"], timings["assembly"], timings["device"]) == (0.0, 0.0, "numpy (CPU)")
    assert 0.0 < timings["search"] < 60.0
    # each option on its own changes the fit, and reaches register
    for key, value in (("reflection", True), ("sigma2_metric", 1.0), ("tol", 0.3), ("pose_prior", 1.0)):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", shapelib.RegistrationWarning)
            one = shapelib.register_many([(STAR, TRIFOIL)], **{key: value})[0]
            alone = shapelib.register(STAR, TRIFOIL, **{key: value})
        assert (one.sigma2, one.n_iter, one.reliable) == (alone.sigma2, alone.n_iter, alone.reliable)
        assert (one.sigma2, one.n_iter, one.reliable) != (default.sigma2, default.n_iter, default.reliable), key


def test_register_many_warns_by_default_and_not_with_warn_false():
    with pytest.warns(shapelib.RegistrationWarning):
        shapelib.register_many([(STAR, TRIFOIL)], max_iter=2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        shapelib.register_many([(STAR, TRIFOIL)], max_iter=2, warn=False)


@pytest.mark.parametrize("kw, match", [
    ({"lam": -1.0}, "^lam must be"), ({"sigma2_metric": 0.0}, "^sigma2_metric must be"),
    ({"max_iter": 0}, "^max_iter must be"), ({"n_steps": 0}, "^n_steps must be"), ({"tol": 0.0}, "^tol must be"),
    ({"batch_size": 0}, "^batch_size must be"),
    ({"sigma2": None, "lam": -1.0}, "^lam must be"),   # sigma2=None is "auto": not refused
    ({"metric": None, "lam": -1.0}, r"^metric=None is not batched on JAX"),
])
def test_the_jax_backend_checks_its_options_before_any_work(kw, match):
    """These are refused before JAX is used (no compilation, no device)."""
    with pytest.raises(ValueError, match=match):
        shapelib.register_many([(STAR, TRIFOIL)], backend="jax", **kw)

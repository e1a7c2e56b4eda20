"""Density distances modulo the similarity group: invariances, the batched angle search against
brute force, and the Fisher–Rao value against an independent quadrature."""

import warnings

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

import shapelib as sl
from shapelib.geometry.gmm import l2_inner
from shapelib.pointsets.invariant import (invariant_distance, invariant_distance_matrix, normalise_points,
                                          polar_spectra, rotation_search)

S2 = 0.01


def _blob(n, seed, wobble=0.35):
    """A star-shaped closed curve with a few random harmonics, n points at uneven parameters."""
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0, 2 * np.pi, n))
    r = 1 + sum(wobble * rng.normal() / k * np.cos(k * t + rng.uniform(0, 6)) for k in range(2, 6))
    return np.column_stack([1.6 * r * np.cos(t), r * np.sin(t)])


def _rot(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def _apply(y, theta, reflected):
    if reflected:
        y = y * [1.0, -1.0]
    return y @ _rot(theta).T


X, Y, Z = _blob(70, 1), _blob(55, 2), _blob(90, 3)


@pytest.mark.parametrize("metric", ["alpha_bound", "fisher_rao_bound"])
def test_invariant_to_similarity_reflection_start_point_and_permutation(metric):
    base = invariant_distance(X, Y, metric=metric, sigma2=S2).value
    assert base > 0.05
    rng = np.random.default_rng(0)
    moved = [
        Y + [7.0, -3.0],                                   # translation
        25.0 * Y,                                          # scale
        Y @ _rot(2.1).T,                                   # rotation
        Y * [-1.0, 1.0],                                   # reflection
        np.roll(Y, 17, axis=0)[::-1],                      # start point and direction
        Y[rng.permutation(len(Y))],                        # any order of the points
        0.3 * (Y * [1.0, -1.0]) @ _rot(-0.4).T + [1, 2],   # all at once
    ]
    for m in moved:
        assert invariant_distance(X, m, metric=metric, sigma2=S2).value == pytest.approx(base, rel=1e-7, abs=1e-9)
        assert invariant_distance(m, X, metric=metric, sigma2=S2).value == pytest.approx(base, rel=1e-7, abs=1e-9)
    # the same shape: zero up to the square root of rounding (α, closed form: ~1e-8) or of the polar
    # quadrature's error (Fisher–Rao: ~1e-10 on ∫√(pq), so ~1e-5 on the distance)
    assert invariant_distance(X, 4 * X @ _rot(1.0).T, metric=metric, sigma2=S2).value < (1e-6 if metric == "alpha_bound" else 1e-4)


def test_rotation_only_sees_the_mirror():
    mirrored = X * [1.0, -1.0]
    assert invariant_distance(X, mirrored, sigma2=S2).value < 1e-6
    assert invariant_distance(X, mirrored, sigma2=S2, reflection=False).value > 0.01


@pytest.mark.parametrize("pair", [(X, Y), (Y, Z)])
def test_batched_search_equals_brute_force(pair):
    """The FFT grid + Newton answer equals a brute-force search over 1,440 angles (720 for each
    mirror image) polished by a bounded scalar minimiser, on the closed-form overlap."""
    x, y = (normalise_points(p)[0] for p in pair)
    angles = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    best = (-np.inf, None, None)
    for refl in (False, True):
        vals = np.array([l2_inner(x, _apply(y, t, refl), sigma2=S2) for t in angles])
        k = int(np.argmax(vals))
        res = minimize_scalar(lambda t: -l2_inner(x, _apply(y, t, refl), sigma2=S2),
                              bounds=(angles[k] - 0.009, angles[k] + 0.009), method="bounded",
                              options={"xatol": 1e-10})
        if -res.fun > best[0]:
            best = (-res.fun, res.x, refl)
    d_brute = np.sqrt(l2_inner(x, x, sigma2=S2) + l2_inner(y, y, sigma2=S2) - 2 * best[0])
    r = invariant_distance(x, y, sigma2=S2)
    assert r.reflected == best[2]
    assert np.angle(np.exp(1j * (r.angle - best[1]))) == pytest.approx(0.0, abs=1e-6)
    assert r.value == pytest.approx(d_brute, rel=1e-9)
    # the pose reported is the pose used: the closed form there is the distance
    moved = _apply(y, r.angle, r.reflected)
    assert np.sqrt(l2_inner(x, x, sigma2=S2) + l2_inner(y, y, sigma2=S2) - 2 * l2_inner(x, moved, sigma2=S2)) == pytest.approx(r.value, rel=1e-12)


def test_polar_quadrature_agrees_with_the_closed_form_overlap():
    x, y = (normalise_points(p)[0] for p in (X, Z))
    sp = polar_spectra([x, y], sigma2=S2)
    value, angle, refl = rotation_search(sp, sp, pairs=(np.array([0]), np.array([1])))
    assert value[0] == pytest.approx(l2_inner(x, _apply(y, angle[0], refl[0]), sigma2=S2), rel=1e-7)
    total = np.real(sp.coefficients[:, :, 0] @ sp.weights)  # ∫ p dz = 1
    np.testing.assert_allclose(total, 1.0, rtol=1e-7)


def test_fisher_rao_value_is_the_great_circle_bound_at_the_pose():
    """Same point counts: the library's landmark Fisher–Rao bound (Cartesian quadrature) at the
    found pose is the value (an independent quadrature of ∫√(pq))."""
    x = normalise_points(_blob(30, 4))[0]
    y = normalise_points(_blob(30, 5))[0]
    r = invariant_distance(x, y, metric="fisher_rao_bound", sigma2=S2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = sl.fisher_rao_lower_bound(x, _apply(y, r.angle, r.reflected), sigma2=S2)
    assert r.value == pytest.approx(ref, rel=1e-6)


def test_matrix_is_symmetric_with_consistent_poses():
    sets = [X, Y, Z, 2 * Y @ _rot(0.5).T]
    D, ang, ref = invariant_distance_matrix(sets, sigma2=S2, return_pose=True, exact=True)
    # the polar quadrature's values (the default) agree with the closed form at the same poses
    np.testing.assert_allclose(invariant_distance_matrix(sets, sigma2=S2), D, rtol=1e-7, atol=1e-6)
    np.testing.assert_allclose(D, D.T)
    assert np.all(np.diag(D) == 0) and D[1, 3] < 1e-6
    for i in range(4):
        for j in range(4):
            if i != j:
                assert D[i, j] == pytest.approx(invariant_distance(sets[i], sets[j], sigma2=S2).value, rel=1e-9, abs=1e-7)
                xi, yj = normalise_points(sets[i])[0], normalise_points(sets[j])[0]
                cross = l2_inner(xi, _apply(yj, ang[i, j], ref[i, j]), sigma2=S2)
                d = np.sqrt(max(l2_inner(xi, xi, sigma2=S2) + l2_inner(yj, yj, sigma2=S2) - 2 * cross, 0))
                assert d == pytest.approx(D[i, j], rel=1e-9, abs=1e-6)
    rect = invariant_distance_matrix(sets[:2], sets[2:], sigma2=S2, exact=True)
    np.testing.assert_allclose(rect, D[:2, 2:], rtol=1e-9)


def test_bad_point_sets():
    with pytest.raises(ValueError, match="repeats point 0"):
        invariant_distance(np.ones((5, 2)), Y, sigma2=S2)
    with pytest.raises(ValueError, match=r"\(n, 2\)"):
        invariant_distance(np.arange(15.0).reshape(5, 3), Y, sigma2=S2)
    with pytest.raises(ValueError, match="non-finite"):
        invariant_distance(np.array([[0, 0], [1, np.nan], [2, 1]]), Y, sigma2=S2)
    with pytest.raises(ValueError, match="metric"):
        invariant_distance(X, Y, metric="procrustes", sigma2=S2)
    with pytest.raises(ValueError, match="sigma2"):
        invariant_distance(X, Y, sigma2=-1.0)

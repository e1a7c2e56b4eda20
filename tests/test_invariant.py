"""Density distances modulo the similarity group: invariances, the batched angle search against
brute force, and the Fisher–Rao value against an independent quadrature."""

import warnings

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

import shapelib as sl
from shapelib.geometry.gmm import l2_inner
from shapelib.pointsets.invariant import (distances_from_spectra, invariant_distance, invariant_distance_matrix,
                                          normalise_points, polar_spectra, rotation_search)

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


# --- the search over rotations, block by block, against values computed another way -------------------------------

def _overlap_at_angles(x, y, angles, sigma2=S2):
    """⟨p_x, p_{R_θ y}⟩ at many θ by the closed form of the product of two Gaussians, a double sum
    over the two mixtures: (4πσ²)^{-1} (1/nm) Σ_ab exp(−|x_a − R_θ y_b|²/4σ²)."""
    c, s = np.cos(angles), np.sin(angles)
    ry = np.stack([c[:, None] * y[:, 0] - s[:, None] * y[:, 1], s[:, None] * y[:, 0] + c[:, None] * y[:, 1]], axis=-1)
    d2 = np.sum((x[None, :, None, :] - ry[:, None, :, :]) ** 2, axis=-1)
    return np.exp(-d2 / (4 * sigma2)).mean(axis=(1, 2)) / (4 * np.pi * sigma2)


def _bhattacharyya(x, y, sigma2=S2, h=0.025):
    """∫ √(p_x p_y) dz on a Cartesian grid of step h (the trapezoid rule, spectrally accurate for
    these smooth, fast-decaying integrands): independent of the polar quadrature."""
    reach = max(np.abs(x).max(), np.abs(y).max()) + 9 * np.sqrt(sigma2)
    g = np.arange(-reach, reach + h, h)
    zx, zy = np.meshgrid(g, g, indexing="ij")
    z = np.column_stack([zx.ravel(), zy.ravel()])

    def density(pts):
        return sum(np.exp(-np.sum((z - a) ** 2, axis=1) / (2 * sigma2)) for a in pts) / (len(pts) * 2 * np.pi * sigma2)

    return float(np.sqrt(density(x) * density(y)).sum() * h * h)


def test_block_search_is_the_best_angle_of_the_closed_form_overlap():
    """Every pair of a block (no ``pairs``): the value is the closed-form overlap at the returned pose,
    and no angle of a dense grid (either mirror image) does better; a mirror image is found reflected
    with the self-overlap as its value."""
    a, b, c = _blob(30, 6), _blob(25, 7), _blob(35, 8)
    xs = [normalise_points(p)[0] for p in (a, c)]
    ys = [normalise_points(p)[0] for p in (b, a * [1.0, -1.0] @ _rot(0.9).T, c[::-1])]
    radius = max(np.sqrt(np.sum(p * p, axis=1)).max() for p in xs + ys)
    sa, sb = polar_spectra(xs, sigma2=S2, max_radius=radius), polar_spectra(ys, sigma2=S2, max_radius=radius)
    value, angle, refl = rotation_search(sa, sb)  # reflection is searched by default
    assert value.shape == angle.shape == refl.shape == (2, 3)
    grid = np.linspace(0, 2 * np.pi, 120, endpoint=False)
    for i, x in enumerate(xs):
        for j, y in enumerate(ys):
            at_pose = _overlap_at_angles(x, _apply(y, 0.0, refl[i, j]), np.array([angle[i, j]]))[0]
            assert value[i, j] == pytest.approx(at_pose, rel=1e-7)
            dense = max(_overlap_at_angles(x, y * [1.0, f], grid).max() for f in (1.0, -1.0))
            assert value[i, j] >= dense * (1 - 1e-7)
            assert 0 <= angle[i, j] < 2 * np.pi  # as documented (np.mod(−1e-17, 2π) alone rounds to 2π)
    assert refl[0, 1] and not refl[1, 2]
    assert value[0, 1] == pytest.approx(_overlap_at_angles(xs[0], xs[0], np.zeros(1))[0], rel=1e-7)
    # listed pairs, in any array shape, are the same entries
    i, j = np.array([[0, 1], [1, 0]]), np.array([[2, 0], [1, 1]])
    v2, a2, r2 = rotation_search(sa, sb, pairs=(i, j))
    assert v2.shape == a2.shape == r2.shape == (2, 2)
    np.testing.assert_allclose(v2, value[i, j], rtol=1e-12)
    np.testing.assert_allclose(a2, angle[i, j], atol=1e-9)
    np.testing.assert_array_equal(r2, refl[i, j])


def test_rotation_search_refuses_spectra_of_other_grids_or_kinds():
    x, y = normalise_points(X)[0], normalise_points(Y)[0]
    sa = polar_spectra([x], sigma2=S2, max_radius=2.0)
    for other in (polar_spectra([y], sigma2=S2, max_radius=3.0),      # more rings
                  polar_spectra([y], sigma2=S2, max_radius=2.001)):   # as many rings, other radii
        with pytest.raises(ValueError, match="^spectra must share their polar grid"):
            rotation_search(sa, other)
    with pytest.raises(ValueError, match="polar grid and kind"):
        rotation_search(sa, polar_spectra([y], sigma2=S2, max_radius=2.0, kind="sqrt"))


def test_summary_names_the_pose():
    r = invariant_distance(X, X * [1.0, -1.0] @ _rot(0.3).T, sigma2=S2)
    assert r.reflected and r.summary().endswith(f"θ = {np.degrees(r.angle):.2f}°, reflected")
    r = invariant_distance(X, Y @ _rot(0.3).T, sigma2=S2, reflection=False)
    assert not r.reflected and r.summary().endswith(f"θ = {np.degrees(r.angle):.2f}°")
    assert f"{r.value:.6g}" in r.summary() and "alpha_bound" in r.summary()


def test_one_set_and_the_identity_pose_on_the_diagonal():
    for metric in ("alpha_bound", "fisher_rao_bound"):
        D, ang, ref = invariant_distance_matrix([X], metric=metric, sigma2=S2, return_pose=True)
        np.testing.assert_array_equal(D, [[0.0]])
        np.testing.assert_array_equal(ang, [[0.0]])
        assert ref.dtype == bool and not ref[0, 0]
        # a set against itself is the identity pose, not a search's rounding of it
        D, ang, ref = invariant_distance_matrix([X, Y, Z, X[::-1]], metric=metric, sigma2=S2, return_pose=True)
        assert ref.dtype == bool and ang.dtype == np.float64
        assert np.all(np.diag(D) == 0) and np.all(np.diag(ang) == 0) and not np.diag(ref).any()
        assert np.isfinite(D).all() and D[0, 3] < (1e-6 if metric == "alpha_bound" else 1e-4)


def test_copies_of_one_set_are_at_distance_zero_not_nan():
    """The Bhattacharyya coefficient of two copies rounds to 1 or just above: the distance is 0."""
    copies = [3 * X @ _rot(t).T + [1, 2] for t in np.linspace(0, 6, 7)]
    D = invariant_distance_matrix(copies, metric="fisher_rao_bound", sigma2=S2)
    assert np.isfinite(D).all() and D.max() < 1e-4
    for n, seed in ((20, 2), (40, 4)):  # the same array twice: the coefficient rounds to 1 + 4e-16 here
        D = invariant_distance_matrix([_blob(n, seed)] * 2, metric="fisher_rao_bound", sigma2=S2)
        np.testing.assert_array_equal(D, np.zeros((2, 2)))


def test_many_sets_every_block_of_rows():
    """More than two blocks of 64 rows: every entry is searched (all off-diagonal distances of these
    distinct ellipses positive), and the entries of the last block are the closed form at their poses."""
    t = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    sets = [np.column_stack([(1 + 0.02 * i) * np.cos(t), np.sin(t) + 0.1 * np.cos(2 * t)]) for i in range(131)]
    D, ang, ref = invariant_distance_matrix(sets, sigma2=0.05, return_pose=True)
    off = ~np.eye(len(sets), dtype=bool)
    assert np.all(D[off] > 1e-3) and np.all(np.diag(D) == 0)
    np.testing.assert_array_equal(D, D.T)
    for i, j in [(130, 129), (129, 130), (2, 130), (70, 65), (64, 0)]:
        x, y = normalise_points(sets[i])[0], normalise_points(sets[j])[0]
        cross = _overlap_at_angles(x, _apply(y, 0.0, ref[i, j]), np.array([ang[i, j]]), 0.05)[0]
        selfs = [_overlap_at_angles(p, p, np.zeros(1), 0.05)[0] for p in (x, y)]
        assert D[i, j] == pytest.approx(np.sqrt(selfs[0] + selfs[1] - 2 * cross), rel=1e-6)


def test_rectangular_matrices_against_independent_values():
    """Rows and columns of different sets (the spikier columns reach farther than the rows): the α
    value by the quadrature and the Fisher–Rao value against the closed form and a Cartesian
    quadrature at the pose found."""
    rows = [normalise_points(p)[0] for p in (_blob(30, 9), _blob(40, 10))]
    spiky = _blob(35, 11)
    spiky[0] *= 2.5  # one point far out: the columns' farthest normalised point is beyond the rows'
    cols = [normalise_points(p)[0] for p in (spiky, 0.5 * _blob(40, 10) @ _rot(1.0).T)]
    far = max(np.sqrt(np.sum(p * p, axis=1)).max() for p in cols)
    assert far > 1.2 * max(np.sqrt(np.sum(p * p, axis=1)).max() for p in rows)
    D, ang, ref = invariant_distance_matrix(rows, cols, sigma2=S2, normalised=True, return_pose=True)
    F, fang, fref = invariant_distance_matrix(rows, cols, metric="fisher_rao_bound", sigma2=S2, return_pose=True)
    for i, x in enumerate(rows):
        for j, y in enumerate(cols):
            selfs = [_overlap_at_angles(p, p, np.zeros(1))[0] for p in (x, y)]
            cross = _overlap_at_angles(x, _apply(y, 0.0, ref[i, j]), np.array([ang[i, j]]))[0]
            assert D[i, j] == pytest.approx(np.sqrt(max(selfs[0] + selfs[1] - 2 * cross, 0)), rel=1e-6, abs=1e-6)
            bc = _bhattacharyya(x, _apply(y, fang[i, j], fref[i, j]))
            assert np.cos(F[i, j] / 2) == pytest.approx(bc, rel=2e-7)  # the coefficient: well conditioned at 1
    assert D[1, 1] < 1e-6
    # the default grid reaches the farthest normalised point of both sides
    np.testing.assert_allclose(invariant_distance_matrix(rows, cols, sigma2=S2, normalised=True, max_radius=far), D,
                               rtol=1e-13)


def test_normalised_sets_and_errors_name_the_set():
    xs = [normalise_points(p)[0] for p in (X, Y, Z)]
    np.testing.assert_allclose(invariant_distance_matrix(xs, sigma2=S2, normalised=True),
                               invariant_distance_matrix([X, 3 * Y + 1, Z], sigma2=S2), rtol=1e-9, atol=1e-12)
    for normalised in (False, True):
        with pytest.raises(ValueError, match=r"point_sets\[1\]"):
            invariant_distance_matrix([X, np.arange(6.0).reshape(2, 3)], sigma2=S2, normalised=normalised)
        with pytest.raises(ValueError, match=r"others\[0\]"):
            invariant_distance_matrix([X], [np.arange(6.0).reshape(2, 3)], sigma2=S2, normalised=normalised)
    with pytest.raises(ValueError, match=r"point_sets\[2\]"):
        invariant_distance_matrix([X, Y, np.ones((4, 2))], sigma2=S2)


def test_distances_from_spectra_defaults_and_kind():
    xs = [normalise_points(p)[0] for p in (X, X * [1.0, -1.0], Y)]
    sa = polar_spectra(xs, sigma2=S2)
    D = distances_from_spectra(xs, sa, metric="alpha_bound")
    assert isinstance(D, np.ndarray) and D.shape == (3, 3)
    assert D[0, 1] < 1e-6  # the mirror image: reflection is searched by default
    with pytest.raises(ValueError, match="kind 'sqrt'"):
        distances_from_spectra(xs, sa, metric="fisher_rao_bound")
    sq = polar_spectra(xs, sigma2=S2, kind="sqrt")
    with pytest.raises(ValueError, match="kind 'density'"):
        distances_from_spectra(xs, sa, xs, sq, metric="alpha_bound")


def test_pose_result_carries_the_overlap_at_the_pose():
    """``overlap`` is the closed-form L² overlap (α) or the Bhattacharyya coefficient by a Cartesian
    quadrature (Fisher–Rao) at the pose returned, for a mirrored and turned set too."""
    x = _blob(30, 12)
    y = 2 * (x + 0.03 * np.random.default_rng(13).normal(size=x.shape)) * [1.0, -1.0] @ _rot(0.8).T
    xs, ys = normalise_points(x)[0], normalise_points(y)[0]
    for metric in ("alpha_bound", "fisher_rao_bound"):
        r = invariant_distance(x, y, metric=metric, sigma2=S2)
        assert r.reflected and r.metric == metric and r.sigma2 == S2
        posed = _apply(ys, r.angle, r.reflected)
        if metric == "alpha_bound":
            assert r.overlap == pytest.approx(_overlap_at_angles(xs, posed, np.zeros(1))[0], rel=1e-10)
        else:
            assert r.overlap == pytest.approx(_bhattacharyya(xs, posed), rel=2e-7)  # the polar quadrature's error
            assert r.value == pytest.approx(2 * np.arccos(r.overlap), rel=1e-12)


def test_spectra_default_grid_options_and_errors():
    x = normalise_points(_blob(30, 14))[0]
    far = float(np.sqrt(np.sum(x * x, axis=1)).max())
    sp = polar_spectra([x, 0.5 * x], sigma2=S2)
    # the default grid covers the farthest point of the sets
    np.testing.assert_array_equal(sp.coefficients, polar_spectra([x, 0.5 * x], sigma2=S2, max_radius=far).coefficients)
    # a narrower band keeps fewer frequencies (and angles); √p needs the wider band
    narrow = polar_spectra([x], sigma2=S2, angular_band=1.0)
    assert narrow.coefficients.shape[2] < sp.coefficients.shape[2] and narrow.n_angles < sp.n_angles
    assert polar_spectra([x], sigma2=S2, kind="sqrt").coefficients.shape[2] > sp.coefficients.shape[2]
    for bad in ({"kind": "log"}, {"angular_band": 0.0}, {"rings_per_sigma": -1.0}):
        with pytest.raises(ValueError, match=f"^{next(iter(bad))} must be"):
            polar_spectra([x], sigma2=S2, **bad)


def test_spectra_of_a_ring_of_points_far_from_the_centre():
    """A circle of points: the inner rings, out of reach of every point, are empty, the outer ones
    are not; ∫ p dz = 1 and ∫ p² dz is the closed form (4πσ²)^{-1} (1/n²) Σ_ab exp(−|x_a − x_b|²/4σ²)."""
    t = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    x = np.column_stack([np.cos(t), np.sin(t)])
    sp = polar_spectra([x], sigma2=S2)
    assert sp.radii[0] < 0.1 and np.all(sp.coefficients[0, 0] == 0)
    assert np.real(sp.coefficients[0, :, 0] @ sp.weights) == pytest.approx(1.0, rel=1e-9)
    value, angle, refl = rotation_search(sp, sp, reflection=False, pairs=([0], [0]))
    assert value[0] == pytest.approx(_overlap_at_angles(x, x, np.zeros(1))[0], rel=1e-7)


def test_parabola_and_newton_steps_close_in_on_the_best_angle():
    """The best angle after 0, 1 and 2 Newton steps against a bounded scalar maximisation of the
    closed-form overlap: the parabola through the best grid angle's neighbours is within a fifth of
    a grid cell, one Newton step within 1 % of a cell, two within 1e-7 rad."""
    sets = [normalise_points(_blob(40, s))[0] for s in range(20, 25)]
    sp = polar_spectra(sets, sigma2=S2)
    cell = np.pi / sp.coefficients.shape[2]  # the default grid: 2K angles
    i, j = np.array([0, 1, 2, 3]), np.array([1, 2, 3, 4])
    for steps, bound in ((0, 0.2 * cell), (1, 0.01 * cell), (2, 1e-7)):
        value, angle, refl = rotation_search(sp, sp, reflection=False, pairs=(i, j), newton_steps=steps)
        assert refl.dtype == bool and not refl.any()
        for q in range(len(i)):
            x, y = sets[i[q]], sets[j[q]]
            res = minimize_scalar(lambda t: -_overlap_at_angles(x, y, np.array([t]))[0],
                                  bounds=(angle[q] - cell, angle[q] + cell), method="bounded",
                                  options={"xatol": 1e-11})
            assert abs(np.angle(np.exp(1j * (angle[q] - res.x)))) < bound
            assert value[q] <= -res.fun * (1 + 1e-7)


def test_normalise_points_scale_threshold_and_names():
    x, centre, scale = normalise_points([[0.0, 0.0], [3e-12, 0.0]])  # tiny, but above 1e-12 of the unit
    np.testing.assert_allclose(x, [[-1.0, 0.0], [1.0, 0.0]])
    assert scale == pytest.approx(1.5e-12)
    with pytest.raises(ValueError, match="^points: all points coincide"):
        normalise_points([[5.0, 5.0], [5.0 + 5e-12, 5.0]])  # 2.5e-12 is below 1e-12 of the coordinates (5)
    with pytest.raises(ValueError, match="^points: all points coincide"):
        normalise_points([[0.0, 0.0], [1e-13, 0.0]])
    with pytest.raises(ValueError, match="outline.*planar"):
        normalise_points(np.arange(9.0).reshape(3, 3), name="outline")
    with pytest.raises(ValueError, match="outline: point 1 repeats point 0"):
        normalise_points([[1.0, 2.0], [1.0, 2.0], [0.0, 0.0]], name="outline")


def test_invariant_distance_names_its_own_arguments():
    """Bad input to invariant_distance is named as the caller passed it (``x``, ``y``), not by the
    matrix function it calls (``point_sets[0]``, ``others[0]``)."""
    bad = np.arange(6.0).reshape(2, 3)
    with pytest.raises(ValueError, match=r"^x\b"):
        invariant_distance(bad, X, sigma2=S2)
    with pytest.raises(ValueError, match=r"^y\b"):
        invariant_distance(X, np.ones((4, 2)), sigma2=S2)


def test_angles_next_to_zero_wrap_into_the_documented_range():
    """A set against itself turned by ±δ (δ small): the angle returned is δ's inverse taken into
    [0, 2π) — just above 0 or just below 2π — never left outside the range or snapped to 0."""
    x = normalise_points(_blob(30, 5))[0]
    for delta in (-2e-3, -1e-5, 1e-5, 2e-3):
        y = x @ _rot(delta).T  # x turned by δ: R_θ y matches x at θ = −δ (mod 2π)
        sp = polar_spectra([x, y], sigma2=S2)
        value, angle, refl = rotation_search(sp, sp, reflection=False, pairs=(np.array([0]), np.array([1])))
        want = np.mod(-delta, 2 * np.pi)
        assert 0 <= angle[0] < 2 * np.pi
        assert abs(np.angle(np.exp(1j * (angle[0] - want)))) < 1e-7
        assert abs(angle[0] - want) < 1e-7 or abs(angle[0] - want) > 2 * np.pi - 1e-7

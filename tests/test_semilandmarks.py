"""Sliding semilandmarks: first-order conditions of both criteria, points on a straight edge stay
on it, bending energy goes down, on a curved outline each slide ends where a brute-force search
along the tangent lines finds the minimum, tpsDig CURVES slide and the metrics take the result."""

import numpy as np
import pytest

import shapelib as sl
from shapelib import io
from shapelib.geometry.semilandmarks import _slide_one, bending_energy_matrix, curve_sliders, slide_semilandmarks


def _quads_with_an_edge_curve(rng, n=8):
    """A jittered quadrilateral (landmarks 0-3) and 5 points on its bottom edge from corner 0 to
    corner 1 (indices 4-8; 4 and 8 sit on the corners and stay fixed), unevenly spaced."""
    out = []
    for _ in range(n):
        quad = np.array([[0, 0], [2, 0], [2.2, 1], [-0.1, 1.1]]) + rng.normal(scale=0.05, size=(4, 2))
        s = np.r_[0.0, np.sort(rng.uniform(0.05, 0.95, 3)), 1.0]
        out.append(np.vstack([quad, quad[0] + s[:, None] * (quad[1] - quad[0])]))
    return np.stack(out)


@pytest.mark.parametrize("criterion", ["procrustes", "bending_energy"])
def test_points_on_a_straight_edge_slide_along_it(rng, criterion):
    x = _quads_with_an_edge_curve(rng)
    res = slide_semilandmarks(x, curve_sliders(4, 5), criterion=criterion)
    assert res.converged
    for s in res.shapes:
        edge = s[1] - s[0]
        rel = s[4:9] - s[0]
        assert np.abs(edge[0] * rel[:, 1] - edge[1] * rel[:, 0]).max() < 1e-12  # still on the line


def test_procrustes_sliding_meets_its_first_order_condition(rng):
    x = _quads_with_an_edge_curve(rng)
    res = slide_semilandmarks(x, curve_sliders(4, 5), criterion="procrustes")
    for s in res.shapes:
        t = s[[6, 7, 8]] - s[[4, 5, 6]]
        t /= np.linalg.norm(t, axis=1, keepdims=True)
        assert np.abs(np.einsum("jd,jd->j", t, res.mean[[5, 6, 7]] - s[[5, 6, 7]])).max() < 1e-3 * 0.2


def test_bending_energy_sliding_lowers_the_bending_energy(rng):
    x = _quads_with_an_edge_curve(rng)
    aligned, mean = sl.generalized_procrustes(x)
    lk = bending_energy_matrix(mean)

    def energy(shapes, ref_l):
        return sum(float(np.trace(s.T @ ref_l @ s)) for s in shapes)

    before = energy(aligned, lk)
    res = slide_semilandmarks(x, curve_sliders(4, 5), criterion="bending_energy")
    assert energy(res.shapes, bending_energy_matrix(res.mean)) < 0.5 * before
    # affine maps bend nothing
    np.testing.assert_allclose(lk @ (mean @ np.array([[1.3, 0.2], [-0.4, 0.8]])), 0.0, atol=1e-9)


def _arcs(rng, n=6):
    """Two fixed landmarks below an elliptic arc (semi-axes about 2 and 1) of 8 points from angle 0
    to π (indices 2-9; the ends fixed), the 6 interior ones at jittered angles: a curved outline,
    where the chord tangent, a one-sided one and the mean's differ."""
    out = []
    for _ in range(n):
        a, b = 2.0 + 0.1 * rng.normal(), 1.0 + 0.1 * rng.normal()
        ang = np.linspace(0, np.pi, 8)
        ang[1:-1] += rng.uniform(-0.15, 0.15, 6)
        arc = np.column_stack([a * np.cos(ang), b * np.sin(ang)])
        fixed = np.array([[0.0, -0.8 * b], [0.9 * a, -0.5]]) + 0.03 * rng.normal(size=(2, 2))
        out.append(np.vstack([fixed, arc]))
    return np.stack(out)


def _tps_bending_energy(src, dst):
    """Bending energy of the 2-D thin-plate spline taking ``src`` onto ``dst``, from its own linear
    system: ``[[K, P], [Pᵀ, 0]] [W; A] = [dst − src; 0]``, energy ``tr(Wᵀ K W)`` (up to 8π)."""
    k = len(src)
    r = np.linalg.norm(src[:, None] - src[None], axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        kern = np.where(r > 0, r ** 2 * np.log(r), 0.0)
    p = np.hstack([np.ones((k, 1)), src])
    w = np.linalg.solve(np.block([[kern, p], [p.T, np.zeros((3, 3))]]), np.vstack([dst - src, np.zeros((3, 2))]))[:k]
    return float(np.trace(w.T @ kern @ w))


def _brute_force_slide(y, mean, sliders, criterion):
    """The criterion minimised by scipy over the slide parameters ``t`` (one per semilandmark), each
    point moving along the chord of its neighbours in ``y``; returns the slid shape and ``t``."""
    from scipy.optimize import minimize

    tang = y[sliders[:, 2]] - y[sliders[:, 0]]
    tang /= np.linalg.norm(tang, axis=1, keepdims=True)

    def moved(t):
        z = y.copy()
        z[sliders[:, 1]] += t[:, None] * tang
        return z

    def cost(t):
        z = moved(t)
        return _tps_bending_energy(mean, z) if criterion == "bending_energy" else float(np.sum((z - mean) ** 2))

    t = minimize(cost, np.zeros(len(sliders)), method="BFGS", options=dict(gtol=1e-12)).x
    return moved(t), t


@pytest.mark.parametrize("criterion", ["procrustes", "bending_energy"])
def test_one_slide_on_a_curved_outline_ends_at_the_brute_force_minimum(criterion):
    rng = np.random.default_rng(4)
    aligned, mean = sl.generalized_procrustes(_arcs(rng), scaling=False)
    sliders = curve_sliders(2, 8)
    lk = bending_energy_matrix(mean) if criterion == "bending_energy" else None
    for y in aligned[:3]:
        expected, t = _brute_force_slide(y, mean, sliders, criterion)
        assert np.abs(t).max() > 0.01  # the points do move (unit-size shapes, spacing about 0.13)
        np.testing.assert_allclose(_slide_one(y, mean, sliders, criterion, lk), expected, atol=2e-6)


@pytest.mark.parametrize("criterion", ["procrustes", "bending_energy"])
def test_slid_curved_outlines_sit_at_the_minimum_along_their_tangents(criterion):
    """After sliding (the default 20 iterations), no specimen can lower the criterion against the
    result's mean by sliding its points further along their tangent lines: the brute-force search
    moves them by less than 1e-3 (a first slide from the plain alignment moves them by 0.03 with
    bending energy, 0.16 with Procrustes distance, in the test above). The set as a whole keeps creeping along the arc by about 1e-4 an iteration (the
    chords leave the curve), so the sum of squares does not settle to the default tolerance
    here and ``converged`` is not asserted."""
    rng = np.random.default_rng(5)
    x = _arcs(rng)
    sliders = curve_sliders(2, 8)
    res = slide_semilandmarks(x, sliders, criterion=criterion)
    for y in res.shapes:
        _, t = _brute_force_slide(y, res.mean, sliders, criterion)
        assert np.abs(t).max() < 1e-3


def test_tpsdig_curves_slide_and_the_metrics_take_the_result(rng, tmp_path):
    x = _quads_with_an_edge_curve(rng, n=5)
    path = io.write_tps(tmp_path / "c.tps", x[:, :4] + 10, [f"s{i}" for i in range(5)],
                        curves=[[c + 10] for c in x[:, 4:]])
    shapes, spec, curves = io.read_tps(path, return_curves=True)
    both = np.stack([np.vstack([s, *c]) for s, c in zip(shapes, curves)])
    res = slide_semilandmarks(both, curve_sliders(4, 5))
    d = sl.distance(res.shapes[0], res.shapes[1], metric="alpha_bound", sigma2=0.01)
    assert np.isfinite(d) and d > 0
    with pytest.raises(ValueError, match="slides twice"):
        slide_semilandmarks(both, np.array([[4, 5, 6], [5, 5, 6]]))


def test_curve_sliders_open_and_closed():
    np.testing.assert_array_equal(curve_sliders(3, 4), [[3, 4, 5], [4, 5, 6]])
    np.testing.assert_array_equal(curve_sliders(0, 3), [[0, 1, 2]])  # open by default: the ends stay
    np.testing.assert_array_equal(curve_sliders(2, 4, closed=True), [[5, 2, 3], [2, 3, 4], [3, 4, 5], [4, 5, 2]])
    two = curve_sliders(5, 2)  # no interior point: no slider, still an (m, 3) integer array
    assert two.shape == (0, 3) and np.issubdtype(two.dtype, np.integer)


@pytest.mark.parametrize("d", [2, 3])
def test_bending_energy_matrix_is_positive_semidefinite_with_the_affine_maps_as_null_space(rng, d):
    import warnings

    ref = rng.normal(size=(9, d))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # r² log r at r = 0 is 0, silently
        lk = bending_energy_matrix(ref)
    np.testing.assert_allclose(lk, lk.T, atol=1e-12)
    affine = np.column_stack([np.ones(9), ref])
    np.testing.assert_allclose(lk @ affine, 0.0, atol=1e-9)
    eig = np.linalg.eigvalsh(lk)
    assert eig.min() > -1e-9 * eig.max()  # a bending energy is never negative
    assert np.sum(eig > 1e-9 * eig.max()) == 9 - (d + 1)  # and zero only for the affine maps
    np.testing.assert_allclose(bending_energy_matrix(np.round(ref * 10).astype(int)),
                               bending_energy_matrix(np.round(ref * 10)), atol=1e-12)


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e4, 1e6])
def test_bending_energy_matrix_keeps_its_accuracy_at_any_coordinate_size(rng, d, scale):
    """Against the null-space form ``Q (Qᵀ U Q)⁻¹ Qᵀ`` (``Q`` an orthonormal basis of ``Pᵀv = 0``),
    computed here independently: raw pixel coordinates (10⁴) once lost 0.4 % of the matrix in 2-D,
    10⁶ lost 1–3 %; and the energy scales as a bending energy must, ``s⁻²`` in 2-D, ``s⁻¹`` in 3-D."""
    from scipy.linalg import null_space

    x = scale * (rng.normal(size=(12, d)) + 5.0)  # off-centre, as raw coordinates are
    r = np.linalg.norm(x[:, None] - x[None], axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where(r > 0, r ** 2 * np.log(r), 0.0) if d == 2 else -r
    q = null_space(np.column_stack([np.ones(12), x]).T)
    expected = q @ np.linalg.solve(q.T @ u @ q, q.T)
    lk = bending_energy_matrix(x)
    np.testing.assert_allclose(lk, expected, rtol=0, atol=1e-9 * np.abs(expected).max())
    unit = bending_energy_matrix(x / scale)
    np.testing.assert_allclose(lk * scale ** (2 if d == 2 else 1), unit, rtol=0, atol=1e-9 * np.abs(unit).max())


def test_bending_energy_matrix_of_coincident_landmarks_is_an_error():
    with pytest.raises(ValueError, match="^reference: all its landmarks coincide: there is no thin-plate spline$"):
        bending_energy_matrix(np.full((6, 2), 3.0))


def test_a_semilandmark_between_coincident_neighbours_stays():
    """Its tangent is undefined (a zero chord): the point does not move, and nothing is NaN."""
    y = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.5], [0.2, 0.7]])
    mean = y + 0.1
    sliders = np.array([[0, 4, 0], [1, 5, 2]])
    for criterion in ("procrustes", "bending_energy"):
        lk = bending_energy_matrix(mean) if criterion == "bending_energy" else None
        out = _slide_one(y, mean, sliders, criterion, lk)
        assert np.all(np.isfinite(out))
        np.testing.assert_array_equal(out[4], y[4])


def test_slide_result_reports_what_it_did_and_stops_by_its_rule(rng):
    """The shapes at unit centroid size; the result names its sliders and criterion; it stops at
    the first iteration whose Procrustes sum of squares (recomputed here) changed by less than tol,
    or after exactly max_iter iterations."""
    x = _quads_with_an_edge_curve(rng)
    sliders = curve_sliders(4, 5)
    tol = 1e-4
    res = slide_semilandmarks(x, sliders, criterion="procrustes", tol=tol)
    assert res.converged and res.stop_reason == "tol" and res.criterion == "procrustes" and res.n_iter >= 2
    np.testing.assert_array_equal(res.sliders, sliders)
    np.testing.assert_allclose([sl.geometry.procrustes.centroid_size(s) for s in res.shapes], 1.0, rtol=1e-12)

    def ss(n):
        r = slide_semilandmarks(x, sliders, criterion="procrustes", tol=1e-300, max_iter=n)
        assert r.n_iter == n and not r.converged and r.stop_reason == "max_iter"
        return float(np.sum((r.shapes - r.mean) ** 2))

    last, before, earlier = ss(res.n_iter), ss(res.n_iter - 1), ss(res.n_iter - 2)
    assert abs(before - last) / last < tol <= abs(earlier - before) / before
    assert res.summary() == (f"3 semilandmarks slid by minimum procrustes on 8 shapes: converged True in "
                             f"{res.n_iter} iterations (tol)")
    assert slide_semilandmarks(x, sliders).summary().startswith("3 semilandmarks slid by minimum bending energy on")
    curved = slide_semilandmarks(_arcs(rng), curve_sliders(2, 8))  # creeps along the arc: the default 20
    assert (curved.n_iter, curved.converged, curved.stop_reason) == (20, False, "max_iter")


def test_bad_sliders_and_shapes_are_value_errors_that_say_what_is_wrong(rng):
    x = _quads_with_an_edge_curve(rng, n=3)  # 9 landmarks
    ok = curve_sliders(4, 5)
    for bad in (np.array([4, 5, 6]), np.array([[4, 5], [5, 6]]), ok.astype(float)):
        with pytest.raises(ValueError, match=r"^sliders must be an \(m, 3\) array of landmark indices; got "):
            slide_semilandmarks(x, bad)
    with pytest.raises(ValueError, match=r"^sliders name landmark 9; the shapes have landmarks 0 to 8$"):
        slide_semilandmarks(x, np.array([[7, 8, 9]]))
    with pytest.raises(ValueError, match=r"^sliders name landmark -1; the shapes have landmarks 0 to 8$"):
        slide_semilandmarks(x, np.array([[-1, 0, 1]]))
    assert slide_semilandmarks(x, np.array([[0, 4, 8]])).shapes.shape == x.shape  # 0 and 8 are landmarks
    with pytest.raises(ValueError, match=r"^a landmark slides twice: each point may appear once in the middle "
                                         r"column of sliders$"):
        slide_semilandmarks(x, np.array([[4, 5, 6], [4, 5, 7]]))
    with pytest.raises(ValueError, match=r"^criterion must be one of \('bending_energy', 'procrustes'\); got 'x'"):
        slide_semilandmarks(x, ok, criterion="x")
    with pytest.raises(ValueError, match=r"^shapes must contain at least 2 shape"):
        slide_semilandmarks(x[:1], ok)


def test_slid_shapes_slid_again_stop_after_one_iteration(rng):
    """Shapes already slid to convergence: the first iteration changes the sum of squares by less
    than tol (measured from their own alignment), so it stops there, converged, in 1 iteration."""
    x = _quads_with_an_edge_curve(rng)
    first = slide_semilandmarks(x, curve_sliders(4, 5), criterion="procrustes", tol=1e-4)
    again = slide_semilandmarks(first.shapes, curve_sliders(4, 5), criterion="procrustes", tol=1e-4)
    assert (again.n_iter, again.converged, again.stop_reason) == (1, True, "tol")

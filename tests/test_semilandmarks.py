"""Sliding semilandmarks: first-order conditions of both criteria, points on a straight edge stay
on it, bending energy goes down, tpsDig CURVES slide and the metrics take the result."""

import numpy as np
import pytest

import shapelib as sl
from shapelib import io
from shapelib.geometry.semilandmarks import bending_energy_matrix, curve_sliders, slide_semilandmarks


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

"""Outlines traced from binary images: closed forms on synthetic disks and ellipses, holes and parts."""

import numpy as np
import pytest
from scipy.special import ellipe

from shapelib.pointsets.outline import outline_components, outline_topology, resample_closed, trace_outline
from tests.conftest import requires_data

#: a binary image's 0.5 iso-line is made of axis-parallel and 45° steps; along a straight edge at
#: angle φ its length is (|cos φ| + (√2 − 1)|sin φ|) times the edge's (φ ≤ 45°), so on a curve
#: whose tangent turns uniformly the traced length is (4/π)(sin 45° + (√2 − 1)(1 − cos 45°)) ≈
#: 1.0548 times the true length
STAIRCASE = 4 / np.pi * (np.sin(np.pi / 4) + (np.sqrt(2) - 1) * (1 - np.cos(np.pi / 4)))


def _ellipse_image(a, b, shape=(130, 150), centre=(70.3, 60.2)):
    rr, cc = np.mgrid[:shape[0], :shape[1]]
    return ((cc - centre[0]) / a) ** 2 + ((rr - centre[1]) / b) ** 2 < 1


def _area(p):
    x, y = p[:, 0], p[:, 1]
    return 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)


def _length(p):
    return np.sum(np.linalg.norm(np.diff(np.vstack([p, p[:1]]), axis=0), axis=1))


def _arc_positions(samples, polygon):
    """Arc-length parameter of each sample along the closed polygon (the sample lies on it)."""
    closed = np.vstack([polygon, polygon[:1]])
    seg = np.diff(closed, axis=0)
    s0 = np.concatenate([[0.0], np.cumsum(np.linalg.norm(seg, axis=1))])
    out = []
    for q in samples:
        t = np.clip(np.einsum("kd,kd->k", q - closed[:-1], seg) / np.einsum("kd,kd->k", seg, seg), 0, 1)
        dist = np.linalg.norm(closed[:-1] + t[:, None] * seg - q, axis=1)
        k = int(np.argmin(dist))
        assert dist[k] < 1e-9
        out.append(s0[k] + t[k] * np.linalg.norm(seg[k]))
    return np.array(out), s0[-1]


@pytest.mark.parametrize("a, b", [(40, 40), (55, 25)])
def test_disk_and_ellipse_area_perimeter_and_uniform_arc_length(a, b):
    img = _ellipse_image(a, b)
    outer, holes = outline_components(img)
    assert len(outer) == 1 and holes == []
    poly = outer[0]
    assert _area(poly) == pytest.approx(np.pi * a * b, rel=2e-3)  # counter-clockwise: positive area
    perimeter = 4 * a * ellipe(1 - (b / a) ** 2)
    assert _length(poly) == pytest.approx(STAIRCASE * perimeter, rel=5e-3)
    pts = trace_outline(img, n_points=150)
    assert pts.shape == (150, 2)
    assert pts.mean(axis=0) == pytest.approx([70.3, img.shape[0] - 1 - 60.2], abs=0.3)  # y up (unflipped: 60.2)
    s, total = _arc_positions(pts, poly)
    steps = np.diff(np.concatenate([s, [s[0] + total]]))
    np.testing.assert_allclose(steps, total / 150, rtol=1e-9)
    assert _area(pts) > 0


def test_resample_closed_square():
    sq = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]])
    r = resample_closed(sq, 16)
    np.testing.assert_allclose(r[:5], [[0, 0], [1, 0], [2, 0], [3, 0], [4, 0]])
    np.testing.assert_allclose(np.linalg.norm(np.diff(np.vstack([r, r[:1]]), axis=0), axis=1), 1.0)


def test_holes_and_parts():
    img = np.zeros((60, 90), bool)
    img[5:45, 5:45] = True          # a square with a hole ...
    img[15:25, 15:25] = False
    img[10:30, 60:80] = True        # ... and a smaller second part
    outer, holes = outline_components(img)
    assert len(outer) == 2 and len(holes) == 1
    assert _area(outer[0]) > 0 and _area(holes[0]) < 0
    top = outline_topology(img)
    assert (top.n_parts, top.n_holes) == (2, 1)
    # kept: the big square's outline (area 40² inside it) over the foreground 40² − 10² + 20²
    assert top.kept_area == pytest.approx(1600 / (1600 - 100 + 400), rel=0.01)
    pts = trace_outline(img, n_points=64)
    assert pts[:, 0].max() < 50  # the big part, not the small one


def test_bad_images():
    with pytest.raises(ValueError, match="no foreground"):
        trace_outline(np.zeros((5, 5), bool), n_points=10)
    with pytest.raises(ValueError, match="2-D"):
        trace_outline(np.ones((2, 3, 4)), n_points=10)
    with pytest.raises(ValueError, match="at least 3"):
        resample_closed([[0, 0], [1, 0], [1, 1]], 2)


@requires_data
def test_load_mpeg7_outlines_and_labels():
    from shapelib.datasets import load_mpeg7, mpeg7_classes

    assert len(mpeg7_classes()) == 70
    data = load_mpeg7(classes=["deer", "fork"], per_class=3, n_points=40)
    assert data.shapes.shape == (6, 40, 2)
    assert data.labels.tolist() == ["deer"] * 3 + ["fork"] * 3
    assert data.names == ["deer-1", "deer-2", "deer-3", "fork-1", "fork-2", "fork-3"]
    images = load_mpeg7(classes=["deer"], per_class=1)
    np.testing.assert_allclose(trace_outline(images.shapes[0], n_points=40), data.shapes[0])
    top = outline_topology(images.shapes[0])
    assert top.n_holes >= 1 and top.kept_area > 1  # deer-1: the antlers enclose holes, filled in by the outline
    with pytest.raises(ValueError, match="unknown MPEG-7 class"):
        load_mpeg7(classes=["unicorn"])
    with pytest.raises(ValueError, match="per_class"):
        load_mpeg7(classes=["deer"], per_class=21)


#: the 0.5 iso-line around an n × n block of pixels runs through the midpoints between pixel centres
#: and cuts each corner by a diagonal of √½: perimeter 4(n − 1) + 2√2, area n² − ½ (a pixel: a
#: diamond of perimeter 2√2 and area ½); the same around a block of background pixels (a hole)


def _perimeter(n):
    return 4 * (n - 1) + 2 * np.sqrt(2)


def test_blocks_and_holes_have_their_closed_form_lengths_and_areas():
    """Two blocks (10 and 5 pixels): kept length and area of the larger; a block of 20 with a 2 × 2
    and a one-pixel hole: the holes are holes (the pixel's area ½ too), the longer first."""
    from shapelib.pointsets.outline import _length, _signed_area

    img = np.zeros((40, 40), bool)
    img[5:15, 5:15] = True
    img[25:30, 25:30] = True
    top = outline_topology(img)
    assert (top.n_parts, top.n_holes) == (2, 0)
    assert top.kept_length == pytest.approx(_perimeter(10) / (_perimeter(10) + _perimeter(5)), rel=1e-12)
    assert top.kept_area == pytest.approx(99.5 / (99.5 + 24.5), rel=1e-12)
    outer, _ = outline_components(img)
    assert _length(outer[0]) == pytest.approx(_perimeter(10), rel=1e-12)
    assert _signed_area(outer[0]) == pytest.approx(99.5, rel=1e-12)
    img = np.zeros((40, 40), bool)
    img[5:25, 5:25] = True
    img[10, 10] = False
    img[15:17, 15:17] = False
    outer, holes = outline_components(img)
    assert len(outer) == 1 and len(holes) == 2
    np.testing.assert_allclose([_length(h) for h in holes], [_perimeter(2), _perimeter(1)], rtol=1e-12)
    np.testing.assert_allclose([_signed_area(h) for h in holes], [-3.5, -0.5], rtol=1e-12)
    top = outline_topology(img)
    assert (top.n_parts, top.n_holes) == (1, 2)
    total = _perimeter(20) + _perimeter(2) + _perimeter(1)
    assert top.kept_length == pytest.approx(_perimeter(20) / total, rel=1e-12)


def test_grey_images_are_cut_at_half_their_maximum():
    """Grey levels 200 and 100 in two blocks: only the 200 block is above half the maximum (100 is
    not); a grey image whose maximum is below 1 is cut the same way; NaN and an empty or all-dark
    image are refused, naming the image."""
    grey = np.zeros((40, 40))
    grey[5:15, 5:15] = 200.0
    grey[25:30, 25:30] = 100.0
    want = outline_topology(grey == 200.0)
    assert outline_topology(grey) == want and want.n_parts == 1
    assert outline_topology(grey / 250.0) == want  # maximum 0.8
    assert outline_topology(grey.astype(int)) == want
    with pytest.raises(ValueError, match=r"^image contains non-finite values$"):
        outline_topology(np.where(grey > 150, np.nan, grey))
    for dark in (np.zeros((5, 5)), np.zeros((0, 0)), np.zeros((5, 5), bool)):
        with pytest.raises(ValueError, match=r"^image has no foreground pixel \(nothing to trace\)$"):
            outline_topology(dark)
    with pytest.raises(ValueError, match=r"^image must be a 2-D array: "):
        outline_topology([[1.0, 2.0], [3.0]])
    with pytest.raises(ValueError, match=r"^image must be a 2-D binary image; got shape \(2, 3, 4\)$"):
        outline_topology(np.ones((2, 3, 4)))


def test_resample_closed_small_and_degenerate_polygons():
    """A triangle shorter than 1 in three samples, a there-and-back segment in four, a repeated first
    point; and each refusal in its words."""
    tri = np.array([[0.0, 0.0], [0.15, 0.0], [0.0, 0.2]])  # sides 0.15, 0.25, 0.2: perimeter 0.6, steps 0.2
    np.testing.assert_allclose(resample_closed(tri, 3), [[0.0, 0.0], [0.12, 0.04], [0.0, 0.2]], atol=1e-15)
    np.testing.assert_allclose(resample_closed([[0, 0], [2, 0]], 4), [[0, 0], [1, 0], [2, 0], [1, 0]])
    np.testing.assert_allclose(resample_closed([[0, 0], [0, 0], [2, 0]], 4), [[0, 0], [1, 0], [2, 0], [1, 0]])
    with pytest.raises(ValueError, match=r"^n\b"):
        resample_closed(tri, 0)
    with pytest.raises(ValueError, match=r"^n must be at least 3; got 2$"):
        resample_closed(tri, 2)
    with pytest.raises(ValueError, match=r"^points must be an \(m, d\) array with m >= 2; got shape \(1, 2\)$"):
        resample_closed([[1.0, 2.0]], 4)
    with pytest.raises(ValueError, match=r"^points contain non-finite values$"):
        resample_closed([[0.0, 0.0], [np.inf, 1.0]], 4)
    with pytest.raises(ValueError, match=r"^the polygon has zero length \(all points coincide\)$"):
        resample_closed([[1.0, 1.0], [1.0, 1.0], [1.0, 1.0]], 4)

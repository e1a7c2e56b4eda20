"""Bull's-eye scores on constructed distance matrices with known answers; the Procrustes outline baseline."""

import json

import numpy as np
import pytest

import shapelib as sl
from shapelib.retrieval import bullseye, nearest_wrong, procrustes_outline_matrix


def test_bullseye_known_answer():
    # 3 classes of 4 on a line; class c at 10c + (0, 1, 2, 3); class 2 is squeezed next to class 1
    pos = np.array([0, 1, 2, 3, 10, 11, 12, 13, 13.5, 14.5, 15.5, 16.5])
    labels = ["a"] * 4 + ["b"] * 4 + ["c"] * 4
    d = np.abs(pos[:, None] - pos[None, :])
    s = bullseye(d, labels, top=4)
    # by hand, each query's 4 nearest (itself first): "a" queries find their 4 class-mates; "b" at
    # 10 and 11: 10, 11, 12, 13 -> 4; at 12: 12, 11 and 13 (1), 13.5 (1.5) -> 3; at 13: 13,
    # 13.5 (0.5), 12 (1), 14.5 (1.5) -> 2. "c" at 13.5: 13.5, 13 (0.5), 14.5 (1), 12 (1.5) -> 2;
    # at 14.5: 14.5, 13.5 and 15.5 (1), 13 (1.5) -> 3; at 15.5 and 16.5 -> 4
    expected_hits = [4, 4, 4, 4, 4, 4, 3, 2, 2, 3, 4, 4]
    np.testing.assert_array_equal(s.hits, expected_hits)
    assert s.value == pytest.approx(sum(expected_hits) / 48)
    assert s.per_class == pytest.approx({"a": 1.0, "b": 13 / 16, "c": 13 / 16})
    assert s.summary().startswith("bull's-eye 87.50 %")
    # default top: twice the class size -> every query finds all 4 among its 8 nearest here
    assert bullseye(d, labels).value == 1.0


def test_bullseye_default_top_is_twice_the_largest_class():
    # three classes of c = 2 on a line: a at 0 and 3.5, b at 1 and 2, c far away at 20 and 21. By hand:
    # the query a@0 ranks 0, 1, 2, 3.5 and a@3.5 ranks 3.5, 2, 1, 0: each finds its class-mate 4th,
    # inside the 2c = 4 nearest but not the 2c - 1 = 3 nearest; b and c find theirs 2nd or 3rd
    pos = np.array([0.0, 3.5, 1.0, 2.0, 20.0, 21.0])
    labels = ["a", "a", "b", "b", "c", "c"]
    d = np.abs(pos[:, None] - pos[None, :])
    s = bullseye(d, labels)
    assert s.top == 4
    np.testing.assert_array_equal(s.hits, [2, 2, 2, 2, 2, 2])
    assert s.value == 1.0
    three = bullseye(d, labels, top=3)  # one fewer: the a queries lose their class-mate
    np.testing.assert_array_equal(three.hits, [1, 1, 2, 2, 2, 2])
    assert three.value == pytest.approx(10 / 12)


def test_bullseye_counts_the_query_itself_first():
    d = np.zeros((4, 4))  # every distance ties: the query comes first, then index order
    s = bullseye(d, [0, 1, 0, 1], top=2)
    # ties go by index after the query: 0 -> (0, 1), 1 -> (1, 0), 2 -> (2, 0), 3 -> (3, 0)
    np.testing.assert_array_equal(s.hits, [1, 1, 2, 1])


def test_nearest_wrong():
    pos = np.array([0.0, 0.4, 1.0, 3.0, 3.2])
    labels = np.array(["a", "a", "b", "b", "c"])
    d = np.abs(pos[:, None] - pos[None, :])
    np.testing.assert_array_equal(nearest_wrong(d, labels, k=2), [[2, 3], [2, 3], [1, 0], [4, 1], [3, 2]])
    with pytest.raises(ValueError, match="k must"):
        nearest_wrong(d, labels, k=4)


def test_bad_input():
    with pytest.raises(ValueError, match="square"):
        bullseye(np.zeros((3, 4)), [0, 1, 2])
    with pytest.raises(ValueError, match="NaN"):
        bullseye(np.array([[0, np.nan], [1, 0]]), [0, 1])
    with pytest.raises(ValueError, match="one entry per row"):
        bullseye(np.zeros((3, 3)), [0, 1])


def _outline(seed, n=48):
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = 1 + sum(0.3 * rng.normal() / k * np.cos(k * t + rng.uniform(0, 6)) for k in range(2, 5))
    return np.column_stack([r * np.cos(t), 0.7 * r * np.sin(t)])


def test_procrustes_outline_equals_best_shift_of_the_landmark_procrustes_distance():
    a, b = _outline(1), _outline(2)
    rot = np.array([[0.6, -0.8], [0.8, 0.6]])
    moved = 2.5 * np.roll(b, 11, axis=0)[::-1] @ rot.T + [3, -1]  # other start, direction, pose
    D = procrustes_outline_matrix([a, b, moved, a * [-1, 1]])
    # brute force with the landmark Procrustes distance over every start point, direction and mirror image
    mirror = b * [1, -1]
    brute = min(sl.procrustes_distance(a, np.roll(w, s, axis=0))
                for w in (b, b[::-1], mirror, mirror[::-1]) for s in range(len(b)))
    assert D[0, 1] == pytest.approx(brute, abs=1e-9)
    assert D[0, 2] == pytest.approx(brute, abs=1e-9)
    assert D[1, 2] < 1e-7 and D[0, 3] < 1e-7  # the mirror image matches with reflection=True
    assert procrustes_outline_matrix([a, a * [-1, 1]], reflection=False)[0, 1] > 0.01
    np.testing.assert_allclose(D, D.T)


def test_procrustes_outline_matrix_of_many_outlines_in_small_chunks_is_the_brute_force_one():
    """Every entry against the landmark Procrustes distance minimised over start points and
    directions (no mirror images: ``reflection=False``), rows computed 2 at a time or all at
    once; small outlines (centroid size below 1) are no special case."""
    outlines = np.stack([_outline(s, n=16) for s in range(5)]) * 0.05
    D = procrustes_outline_matrix(outlines, reflection=False, chunk=2)
    for i in range(5):
        for j in range(5):
            brute = min(sl.procrustes_distance(outlines[i], np.roll(w, s, axis=0))
                        for w in (outlines[j], outlines[j][::-1]) for s in range(16))
            assert D[i, j] == pytest.approx(brute, abs=1e-9), (i, j)
    assert np.all(np.diag(D) == 0.0)
    np.testing.assert_allclose(procrustes_outline_matrix(outlines, reflection=False), D, atol=1e-12)


def test_bad_outlines_are_value_errors_naming_the_outlines():
    with pytest.raises(ValueError, match=r"^outlines must be an \(N, n, 2\) array.*got shape \(2, 5, 3\)"):
        procrustes_outline_matrix(np.zeros((2, 5, 3)))
    with pytest.raises(ValueError, match=r"^outlines contains non-finite values"):
        procrustes_outline_matrix(np.stack([_outline(1, n=8), np.full((8, 2), np.nan)]))
    with pytest.raises(ValueError, match=r"^outlines\[1\]: all points coincide"):
        procrustes_outline_matrix(np.stack([_outline(1, n=8), np.ones((8, 2))]))


def test_bullseye_edge_cases_ties_and_summary():
    d = np.abs(np.subtract.outer([0.0, 1.0, 5.0, 6.0, 6.5], [0.0, 1.0, 5.0, 6.0, 6.5]))
    labels = np.array([3, 3, 7, 7, 3])
    # top = 1: each query finds itself only, a perfect score; top = 0 is no score
    assert bullseye(d, labels, top=1).value == 1.0
    with pytest.raises(ValueError, match="^top must be at least 1; got 0"):
        bullseye(d, labels, top=0)
    # integer distances are distances (the query still comes first)
    np.testing.assert_array_equal(bullseye(d.astype(int), labels, top=2).hits, bullseye(d, labels, top=2).hits)
    # the per-class scores are keyed by plain Python labels (they go into JSON)
    s = bullseye(d, labels, top=2)
    # by hand at top 2 (itself and its nearest): class 3 at 0 and 1 find each other (2 hits each), at
    # 6.5 finds 6 of class 7 (1): 5/6; class 7 at 5 finds 6 (2), at 6 finds 6.5 (1): 3/4; 8/10 overall
    assert json.loads(json.dumps(s.per_class)) == {"3": pytest.approx(5 / 6), "7": 0.75}
    # the summary lists the worst classes first, in percent
    assert s.summary() == "bull's-eye 80.00 % (5 queries, top 2); worst classes: 7 75.0 %, 3 83.3 %"
    # 40 shapes at one distance from each other: ties go by index after the query, whatever
    # the size (an unstable sort reorders ties beyond 16 elements)
    ties = np.ones((40, 40))
    found = nearest_wrong(ties, np.arange(40) % 2, k=20)
    np.testing.assert_array_equal(found, [np.arange(1 - q % 2, 40, 2) for q in range(40)])


def test_nearest_wrong_default_and_the_largest_k():
    pos = np.array([0.0, 0.4, 1.0, 3.0, 3.2])
    labels = np.array(["a", "a", "b", "b", "c"])
    d = np.abs(pos[:, None] - pos[None, :])
    np.testing.assert_array_equal(nearest_wrong(d, labels), [[2], [2], [1], [4], [3]])
    assert nearest_wrong(d, labels, k=3).shape == (5, 3)  # "a" and "b" have exactly 3 others
    with pytest.raises(ValueError, match="k must"):
        nearest_wrong(d, labels, k=0)


def test_summary_names_the_three_worst_classes():
    from shapelib.retrieval import BullseyeScore

    s = BullseyeScore(0.5, {"w": 0.9, "x": 0.2, "y": 0.5, "z": 0.4}, np.ones(8, int), 4)
    assert s.summary() == "bull's-eye 50.00 % (8 queries, top 4); worst classes: x 20.0 %, z 40.0 %, y 50.0 %"

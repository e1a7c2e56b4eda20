"""Point sets: input checks, density quantities between sets of different sizes (closed forms,
gradients against finite differences, invariances) and the pose search over every rotation."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import shapelib as sl
from shapelib.geometry.gmm import l2_distance
from shapelib.pointsets import (align, as_point_set, as_point_sets, bhattacharyya_affinity, density_distance,
                                density_inner, hellinger_sq, l2_distance_sq)
from shapelib.pointsets._transforms import Model


def pear(n=40):
    """An outline with no rotational symmetry (a mirror symmetry about the x-axis only)."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.column_stack([2 * np.cos(t) + 0.5 * np.cos(2 * t), np.sin(t)])


def rot2(a):
    return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])


# ---------------------------------------------------------------------------------------------
# checks
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("bad, words", [
    (np.zeros((0, 2)), "outline is empty"),
    ([[1.0, 2.0]], "outline has 1 point"),
    ([[0, 0], [1, np.nan], [2, 2]], "outline: point 1 has a non-finite coordinate 1"),
    ([[0, 0], [1, 1], [2, 2], [1, 1]], "outline: point 3 repeats point 1 at (1, 1)"),
    (np.zeros((4, 4)), "outline: landmarks must have d = 2 or 3"),
    ([1.0, 2.0, 3.0], "outline must be a 2-D array"),
    ([["a", "b"], ["c", "d"]], "outline must be a numeric"),
])
def test_bad_point_sets_get_one_clear_error_each(bad, words):
    with pytest.raises(sl.InputError) as info:
        as_point_set(bad, name="outline")
    assert words in str(info.value)


def test_point_indices_are_facts_and_a_collection_names_the_set_with_another_dimension():
    with pytest.raises(sl.InputError) as info:
        as_point_set([[0, 0], [1, 1], [0, 0]], name="s")
    assert info.value.facts["points"] == (0, 2)
    with pytest.raises(sl.InputError, match=r"outlines\[2\] has d = 3 .* outlines\[0\] has d = 2"):
        as_point_sets([pear(5), pear(7), np.ones((4, 3)) * np.arange(4)[:, None]], name="outlines")
    with pytest.raises(sl.InputError, match=r"outlines\[1\]: point 1 has a non-finite"):
        as_point_sets([pear(5), [[0, 0], [np.inf, 0]]], name="outlines")
    assert [s.shape for s in as_point_sets([pear(5), pear(9)])] == [(5, 2), (9, 2)]


# ---------------------------------------------------------------------------------------------
# density quantities
# ---------------------------------------------------------------------------------------------


def test_inner_product_and_l2_match_the_landmark_formulas_and_a_direct_integral():
    rng = np.random.default_rng(0)
    x, y = rng.normal(size=(6, 2)), rng.normal(size=(6, 2))
    # equal sizes: the landmark formula of shapelib.geometry.gmm
    assert np.sqrt(l2_distance_sq(x, y, sigma2=0.3)) == pytest.approx(l2_distance(x, y, sigma2=0.3), rel=1e-10)
    # different sizes: a direct integral of p_x p_y on a fine grid
    y = rng.normal(size=(9, 2))
    g = np.linspace(-7, 7, 281)
    xx, yy = np.meshgrid(g, g, indexing="ij")
    z = np.column_stack([xx.ravel(), yy.ravel()])
    px, py = sl.gmm_density(z, x, sigma2=0.3), sl.gmm_density(z, y, sigma2=0.3)
    h2 = (g[1] - g[0]) ** 2
    assert density_inner(x, y, sigma2=0.3) == pytest.approx(np.sum(px * py) * h2, rel=1e-8)
    assert l2_distance_sq(x, y, sigma2=0.3) == pytest.approx(np.sum((px - py) ** 2) * h2, rel=1e-8)
    assert hellinger_sq(x, y, sigma2=0.3) == pytest.approx(np.sum((np.sqrt(px) - np.sqrt(py)) ** 2) * h2, rel=1e-6)
    bc = bhattacharyya_affinity(x, y, sigma2=0.3)
    assert density_distance(x, y, sigma2=0.3, metric="fisher_rao") == pytest.approx(2 * np.arccos(bc), rel=1e-10)


def test_the_fisher_rao_bound_of_sets_in_correspondence_is_the_landmark_bound():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(7, 2))
    y = x + 0.3 * rng.normal(size=(7, 2))
    mine = density_distance(x, y, sigma2=0.4, metric="fisher_rao")
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # pose and scale advice for random shapes
        assert mine == pytest.approx(sl.fisher_rao_lower_bound(x, y, sigma2=0.4), rel=1e-10)


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("which", ["l2", "hellinger"])
def test_gradients_match_finite_differences(d, which):
    rng = np.random.default_rng(d)
    x, y = rng.normal(size=(5, d)), rng.normal(size=(8, d))
    if which == "l2":
        f = l2_distance_sq
    else:
        def f(a, b, **kw):
            return hellinger_sq(a, b, grid_spacing=0.5, grid_margin=5.0, **kw)
    s2 = 0.3  # not 0.5, where 1/(2σ²) = 2σ² and a misplaced factor would pass
    _, g = f(x, y, sigma2=s2, grad=True)
    eps = 1e-6
    fd = np.zeros_like(x)
    for i in range(x.shape[0]):
        for j in range(d):
            e = np.zeros_like(x)
            e[i, j] = eps
            fd[i, j] = (f(x + e, y, sigma2=s2) - f(x - e, y, sigma2=s2)) / (2 * eps)
    # the Hellinger grid moves with x (lattice anchored at 0, so only its far margin changes)
    assert np.abs(fd - g).max() <= (1e-8 if which == "l2" else 1e-6) * np.abs(g).max()


def test_distances_ignore_the_order_of_points_and_are_zero_only_for_the_same_set():
    x = pear(30)
    p = np.random.default_rng(2).permutation(30)
    assert l2_distance_sq(x, x[p], sigma2=0.05) == pytest.approx(0.0, abs=1e-14)
    assert density_distance(x, x[p], sigma2=0.05, metric="fisher_rao") == pytest.approx(0.0, abs=1e-6)
    assert l2_distance_sq(x, x[:-1], sigma2=0.05) > 0


@pytest.mark.parametrize("transform", ["rigid", "similarity", "affine"])
@pytest.mark.parametrize("d", [2, 3])
def test_transform_parameter_derivatives_are_exact(transform, d):
    rng = np.random.default_rng(3)
    m = Model(transform, d, Rotation.random(random_state=1).as_matrix()[:d, :d] if d == 3 else rot2(0.4), 1.3)
    p = m.start() + 0.2 * rng.normal(size=m.start().shape)
    _, _, da = m.matrix(p)
    eps = 1e-7
    for k in range(m.n_lin):
        e = np.zeros_like(p)
        e[k] = eps
        fd = (m.matrix(p + e)[0] - m.matrix(p - e)[0]) / (2 * eps)
        assert np.allclose(fd, da[k], atol=1e-7)


# ---------------------------------------------------------------------------------------------
# pose search
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("angle", [0.0, 60.0, 90.0, 135.0, 180.0, 225.0, 300.0])
def test_any_rotation_is_recovered_exactly_from_shuffled_points(angle):
    x = pear()
    y = x @ rot2(np.radians(angle)).T + [3.0, -1.0]
    perm = np.random.default_rng(int(angle)).permutation(len(y))
    pose = align(x, y[perm], sigma2=0.01)
    assert pose.converged
    assert np.abs(pose.points - y).max() < 1e-6
    assert (pose.angle - angle + 180) % 360 - 180 == pytest.approx(0.0, abs=1e-5)


@pytest.mark.parametrize("transform", ["similarity", "affine"])
def test_similarity_and_affine_recover_their_transform(transform):
    x = pear()
    a = 1.7 * rot2(2.2) if transform == "similarity" else np.array([[1.2, 0.4], [-0.3, 0.8]]) @ rot2(2.2)
    y = x @ a.T + [0.5, 2.0]
    pose = align(x, y[::-1], sigma2=0.01, transform=transform)
    assert np.abs(pose.points - y).max() < 1e-5
    assert np.allclose(pose.matrix, a, atol=1e-6)


def test_a_mirror_is_found_only_when_asked():
    x = pear()
    x3 = x[np.argsort(x[:, 0])][:30]  # half a pear has no symmetry at all
    y3 = x3 @ np.diag([-1.0, 1.0]) @ rot2(1.1).T
    mirrored = align(x3, y3, sigma2=0.01, reflection=True)
    assert mirrored.reflection and np.abs(mirrored.points - y3).max() < 1e-6
    proper = align(x3, y3, sigma2=0.01)
    assert not proper.reflection and proper.value > 10 * mirrored.value


def test_different_sizes_and_three_dimensions():
    rng = np.random.default_rng(4)
    x = rng.normal(size=(60, 3)) * [3.0, 2.0, 1.0]
    for seed in range(3):
        r = Rotation.random(random_state=seed).as_matrix()
        y = x @ r.T + [1.0, 2.0, 3.0]
        pose = align(x, y[rng.permutation(60)], sigma2=0.05)
        assert np.abs(pose.points - y).max() < 1e-6 and np.allclose(pose.rotation, r, atol=1e-7)
    # a target with half of the source's points: the pose is still the one that made it
    r = Rotation.random(random_state=9).as_matrix()
    y = (x @ r.T)[::2]
    pose = align(x, y, sigma2=0.3)
    assert np.allclose(pose.rotation, r, atol=0.05)


def test_the_fisher_rao_pose_search_recovers_a_rotation():
    x = pear(24)
    y = x @ rot2(np.radians(200)).T
    pose = align(x, y, sigma2=0.04, metric="fisher_rao")
    assert np.abs(pose.points - y).max() < 1e-4 and pose.value < 1e-3


def test_align_rejects_bad_options():
    with pytest.raises(ValueError, match="transform must be one of"):
        align(pear(), pear(), sigma2=0.1, transform="projective")
    with pytest.raises(ValueError, match="sigma2 must be a positive"):
        align(pear(), pear(), sigma2=0)
    with pytest.raises(sl.InputError, match="source has d = 2 coordinates per point and target d = 3"):
        align(pear(), np.eye(3), sigma2=0.1)


def test_alpha_density_distance_is_the_closed_form_l2(rng):
    """‖p_x − p_y‖ with ⟨p_x, p_y⟩ = (1/(nm)) Σ (4πσ²)^(−d/2) exp(−|x_i − y_j|²/4σ²), summed here point
    by point: the default metric, and the one named alpha; unequal point counts."""
    import math

    x, y, s2 = rng.normal(size=(3, 2)), rng.normal(size=(4, 2)), 0.3

    def inner(a, b):
        return sum(math.exp(-((p[0] - q[0]) ** 2 + (p[1] - q[1]) ** 2) / (4 * s2)) for p in a for q in b) \
            / (4 * math.pi * s2) / (len(a) * len(b))

    want = math.sqrt(inner(x, x) + inner(y, y) - 2 * inner(x, y))
    assert density_distance(x, y, sigma2=s2) == pytest.approx(want, rel=1e-12)
    assert density_distance(x, y, sigma2=s2, metric="alpha") == pytest.approx(want, rel=1e-12)
    assert density_inner(x, y, sigma2=s2) == pytest.approx(inner(x, y), rel=1e-12)


def test_fisher_rao_density_distance_and_affinity_use_the_grid_given(rng):
    """On a coarse grid: 4 arcsin(H/2) and 1 − H²/2 of hellinger_sq on that grid, not the default."""
    x, y = rng.normal(size=(3, 2)), rng.normal(size=(4, 2))
    grid = dict(grid_spacing=0.9, grid_margin=3.0)
    h2 = hellinger_sq(x, y, sigma2=0.3, **grid)
    assert h2 != hellinger_sq(x, y, sigma2=0.3) and h2 != hellinger_sq(x, y, sigma2=0.3, grid_spacing=0.9)
    assert h2 != hellinger_sq(x, y, sigma2=0.3, grid_margin=3.0)
    assert density_distance(x, y, sigma2=0.3, metric="fisher_rao", **grid) == pytest.approx(
        4 * np.arcsin(np.sqrt(h2) / 2), rel=1e-14)
    assert bhattacharyya_affinity(x, y, sigma2=0.3, **grid) == pytest.approx(1 - h2 / 2, rel=1e-14)


def test_density_functions_name_the_point_set_at_fault(rng):
    x = rng.normal(size=(3, 2))
    with pytest.raises(ValueError, match=r"^x\b"):
        density_distance(np.zeros(3), x, sigma2=0.3)
    with pytest.raises(ValueError, match=r"^y\b"):
        density_distance(x, np.zeros(3), sigma2=0.3)
    with pytest.raises(ValueError, match=r"\bx\b.*\by\b"):
        density_distance(x, rng.normal(size=(3, 3)), sigma2=0.3)
    with pytest.raises(ValueError, match=r"^metric must be one of \('alpha', 'fisher_rao'\); got 'l2'$"):
        density_distance(x, x + 1, sigma2=0.3, metric="l2")


def test_point_set_errors_say_which_points_and_sets():
    """Each refusal of as_point_set / as_point_sets: its words, the default names, and the facts
    (indices from 0) a caller may act on."""
    from shapelib import InputError

    with pytest.raises(InputError, match=r"^points must be a numeric \(n, d\) array of points: could not convert"):
        as_point_set("abc")
    with pytest.raises(InputError, match=r"^points has 1 point\(s\); a point set needs at least 2$"):
        as_point_set([[0.0, 0.0]])
    with pytest.raises(ValueError, match=r"^outline\b"):
        as_point_set(np.zeros((3, 4)), name="outline")
    with pytest.raises(InputError, match=r"^points: point 1 has a non-finite coordinate 0 \(nan\); 2 point\(s\) "
                                         r"in all are not finite$") as exc:
        as_point_set([[0.0, 0.0], [np.nan, 1.0], [2.0, np.inf]])
    assert exc.value.facts == {"points": (1,)}
    with pytest.raises(InputError, match=r"^points: point 2 repeats point 0 at \(0, 0\)") as exc:
        as_point_set([[0.0, 0.0], [1.0, 0.0], [0.0, 0.0]])  # one y for all: the repeat is found by x too
    assert exc.value.facts == {"points": (0, 2)}
    with pytest.raises(InputError, match=r"^point sets must be a list of \(n, d\) point sets or an \(N, n, d\) array; "
                                         r"got shape \(3, 2\)$"):
        as_point_sets(np.zeros((3, 2)))
    with pytest.raises(InputError, match=r"got shape \(1, 3, 2, 1\)$"):
        as_point_sets(np.zeros((1, 3, 2, 1)))
    with pytest.raises(InputError, match=r"^point sets must be a list of \(n, d\) point sets; got int$"):
        as_point_sets(5)
    with pytest.raises(InputError, match=r"^point sets is empty: give at least one point set$"):
        as_point_sets([])
    with pytest.raises(InputError, match=r"^point sets\[0\] has 2 point\(s\); a point set needs at least 3$"):
        as_point_sets([[[0.0, 0.0], [1.0, 1.0]]], min_points=3)
    assert [s.shape for s in as_point_sets([[[0.0, 0.0], [1.0, 1.0]]])] == [(2, 2)]
    with pytest.raises(InputError, match=r"^sets\[2\] has d = 3 coordinates per point but sets\[0\] has d = 2") as exc:
        as_point_sets([pear(5), pear(6), np.eye(4, 3)], name="sets")
    assert exc.value.facts == {"sets": (0, 2)}

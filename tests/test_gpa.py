"""Generalised Procrustes analysis against independent computations: the fixed point it returns
(each shape rotated optimally onto the mean by scipy's orthogonal Procrustes, the scales the
generalised eigenvector of the Gram matrix — Ten Berge's correlation route solved another way),
the closed-form two-shape case from scipy.spatial.procrustes, the mean's invariance to the poses
of the shapes, and the degenerate cases."""

import warnings
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
from scipy.spatial import procrustes as scipy_procrustes
from scipy.spatial.transform import Rotation

from shapelib import generalized_procrustes
from shapelib.geometry import procrustes as procrustes_module

#: mutmut (benchmarks/mutation.py) runs these tests against a copy of the module whose functions
#: go through a trampoline, one more stack frame between the caller and the code
UNDER_MUTMUT = any("__mutmut_" in name for name in vars(procrustes_module))


def rot(a):
    return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])


def noisy_copies(d=2, n=4, k=8, seed=1):
    """n noisy copies of one configuration, each scaled, rotated and moved differently."""
    rng = np.random.default_rng(seed)
    base = rng.normal(size=(k, d))
    rots = [rot(a) for a in rng.uniform(-3, 3, n)] if d == 2 else Rotation.random(n, random_state=seed).as_matrix()
    return np.stack([s * (base + 0.15 * rng.normal(size=base.shape)) @ r.T + rng.normal(size=d)
                     for s, r in zip(rng.uniform(0.5, 3.0, n), rots)])


def optimal_scales(aligned):
    """The scales β minimising Σ‖β_i A_i − mean_j(β_j A_j)‖² = Σβ_i²‖A_i‖² − βᵀGβ/N subject to
    Σβ_i²‖A_i‖² = N: the leading generalised eigenvector of G v = λ diag(G) v, normalised."""
    flat = aligned.reshape(len(aligned), -1)
    gram = flat @ flat.T
    dg = np.diag(np.diag(gram))
    _, vecs = scipy.linalg.eigh(gram, dg)
    v = vecs[:, -1] * np.sign(vecs[:, -1].sum())
    return v * np.sqrt(len(aligned) / (v @ dg @ v))


@pytest.mark.parametrize("d", [2, 3])
def test_full_gpa_returns_its_own_fixed_point(d):
    """Every aligned shape is centred and already rotated optimally onto the mean (scipy's
    orthogonal Procrustes gives the identity), the scales are already optimal (the generalised
    eigenvector is all ones), the total size is N and the mean is the unit-size average."""
    shapes = noisy_copies(d=d)
    aligned, mean = generalized_procrustes(shapes)
    n = len(shapes)
    assert np.abs(aligned.mean(axis=1)).max() < 1e-14
    assert np.sum(aligned ** 2) == pytest.approx(n, rel=1e-12)
    assert np.linalg.norm(mean) == pytest.approx(1.0, rel=1e-14)
    avg = aligned.mean(axis=0)
    assert np.allclose(mean, avg / np.linalg.norm(avg), atol=1e-12)
    for a in aligned:
        r, _ = scipy.linalg.orthogonal_procrustes(a, mean)
        assert np.abs(r - np.eye(d)).max() < 1e-9
    assert np.abs(optimal_scales(aligned) - 1.0).max() < 1e-9
    sizes = np.sqrt(np.sum(aligned ** 2, axis=(1, 2)))
    assert sizes.max() - sizes.min() > 0.005  # the scales were fitted: not all at unit size


def test_without_scaling_every_shape_keeps_unit_size_and_is_rotated_onto_the_mean():
    shapes = noisy_copies()
    aligned, mean = generalized_procrustes(shapes, scaling=False)
    assert np.allclose(np.sum(aligned ** 2, axis=(1, 2)), 1.0, rtol=1e-12)
    for a in aligned:
        r, _ = scipy.linalg.orthogonal_procrustes(a, mean)
        assert np.abs(r - np.eye(2)).max() < 1e-9
    avg = aligned.mean(axis=0)
    assert np.allclose(mean, avg / np.linalg.norm(avg), atol=1e-12)
    # the default fits the scales
    default, _ = generalized_procrustes(shapes)
    assert np.allclose(default, generalized_procrustes(shapes, scaling=True)[0], atol=1e-15)
    assert np.abs(default - aligned).max() > 1e-3


@pytest.mark.parametrize("scaling", [False, True])
def test_two_shapes_meet_at_the_closed_form_partial_procrustes_distance(scaling):
    """For two unit pre-shapes at Procrustes angle ρ (cos ρ = Σ singular values; scipy's disparity is
    1 − cos²ρ) GPA leaves them at ‖A₁ − A₂‖² = 2 − 2 cos ρ, the mean halfway between; two shapes of
    equal size need no scaling, so both options agree."""
    shapes = noisy_copies(n=2, k=10, seed=3)
    _, _, disparity = scipy_procrustes(shapes[0], shapes[1])
    cos_rho = np.sqrt(1 - disparity)
    aligned, mean = generalized_procrustes(shapes, scaling=scaling)
    assert np.sum((aligned[0] - aligned[1]) ** 2) == pytest.approx(2 - 2 * cos_rho, rel=1e-10)
    assert np.linalg.norm(mean - aligned[0]) == pytest.approx(np.linalg.norm(mean - aligned[1]), rel=1e-10)
    assert np.allclose(np.sum(aligned ** 2, axis=(1, 2)), 1.0, rtol=1e-12)


@pytest.mark.parametrize("scaling", [False, True])
def test_the_mean_and_the_aligned_shapes_do_not_depend_on_the_poses_of_the_shapes(scaling):
    """Rotating, scaling and moving each input shape changes the GPA result by one common rotation:
    scipy's Procrustes disparity between the two means is 0, and the shapes keep their sizes."""
    shapes = noisy_copies(n=5, seed=2)
    rng = np.random.default_rng(7)
    moved = np.stack([rng.uniform(0.2, 5) * s @ rot(rng.uniform(-3, 3)).T + rng.normal(size=2) * 10
                      for s in shapes])
    a1, m1 = generalized_procrustes(shapes, scaling=scaling)
    a2, m2 = generalized_procrustes(moved, scaling=scaling)
    assert scipy_procrustes(m1, m2)[2] < 1e-20
    r, _ = scipy.linalg.orthogonal_procrustes(m2, m1)
    assert np.allclose(a2 @ r, a1, atol=1e-9)


def test_a_single_shape_is_its_own_centred_unit_size_mean():
    shape = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [1.0, 5.0]])
    centred = shape - shape.mean(axis=0)
    want = centred / np.sqrt(np.sum(centred ** 2))
    for scaling in (False, True):
        aligned, mean = generalized_procrustes(shape[None], scaling=scaling)
        assert np.allclose(aligned[0], want, atol=1e-15) and np.allclose(mean, want, atol=1e-15)


def test_two_landmark_shapes_all_align_onto_one_segment():
    rng = np.random.default_rng(0)
    segments = rng.normal(size=(4, 2, 2))
    aligned, mean = generalized_procrustes(segments, scaling=False)
    assert np.allclose(aligned, mean, atol=1e-12)
    # a centred unit-size segment: its two ends opposite, each 1/√2 from the centre
    assert np.allclose(mean[0], -mean[1], atol=1e-15) and np.linalg.norm(mean[0]) == pytest.approx(np.sqrt(0.5))


def test_bad_shapes_are_named():
    with pytest.raises(ValueError, match=r"^shapes must have shape \(N, K, d\); got shape \(3, 4\)$"):
        generalized_procrustes(np.zeros((3, 4)))
    with pytest.raises(ValueError, match=r"^shapes\[0\] must have at least 2 landmark"):
        generalized_procrustes(np.zeros((3, 1, 2)))


def test_a_search_that_cannot_converge_warns_at_the_caller_after_max_iter():
    """tol = 0: the change of the mean is never below it, so every iteration runs and GPA says so
    (1000 by default)."""
    shapes = noisy_copies(n=3, k=5)
    for kwargs, n in ((dict(max_iter=5), 5), ({}, 1000)):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            generalized_procrustes(shapes, tol=0.0, **kwargs)
        assert [w.category for w in caught] == [RuntimeWarning]
        assert str(caught[0].message) == f"generalized_procrustes did not converge in {n} iterations"
        assert "shapelib" not in Path(caught[0].filename).parts  # not inside the library
        if not UNDER_MUTMUT:  # mutmut's trampoline adds a frame of its own
            assert caught[0].filename == __file__
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        generalized_procrustes(shapes)

"""What shapelib checks for the user (docs/guide/checks.md): the layout of shape arrays on every
entry point, the pose of the shapes for pose-dependent metrics, σ against the landmarks' scale
for every σ² metric, and honest convergence words. CLI cases: tests/test_cli_checks.py."""

import warnings

import numpy as np
import pytest

import shapelib as sl
from shapelib.distances import METRICS

SIGMA2_METRICS = ("alpha", "fisher_rao", "alpha_bound", "fisher_rao_bound")


def outline(k, rng, *, size=200.0, noise=0.03):
    """A closed outline of ``k`` landmarks (an ellipse with noise), in pixel-like units."""
    t = np.linspace(0, 2 * np.pi, k, endpoint=False)
    base = np.stack([1.6 * np.cos(t), np.sin(t)], axis=1)
    return size * (base + noise * rng.normal(size=base.shape))


def population(n, k, rng, **kw):
    """``n`` specimens of one outline, each moved by a random rotation and translation (raw data)."""
    out = []
    for _ in range(n):
        a = rng.uniform(0, 2 * np.pi)
        r = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        out.append(outline(k, rng, **kw) @ r.T + rng.uniform(300, 600, size=2))
    return np.stack(out)


# ---------------------------------------------------------------------------------------------
# Layout: (N, K, d) with d in {2, 3} on every entry point that takes shapes
# ---------------------------------------------------------------------------------------------


@pytest.fixture
def nkd(rng):
    return population(12, 8, rng)


LAYOUT_ENTRY_POINTS = {
    "pairwise_distances": lambda x: sl.pairwise_distances(x, metric="procrustes", n_jobs=1, progress=False),
    "generalized_procrustes": lambda x: sl.generalized_procrustes(x),
    "to_centroid_size": lambda x: sl.to_centroid_size(x),
    "landmark_spacing": lambda x: sl.landmark_spacing(x),
    "sigma_ratio": lambda x: sl.sigma_ratio(x, 0.5),
    "check_scale": lambda x: sl.geometry.scale.check_scale(x, 0.5),
}


@pytest.mark.parametrize("entry", sorted(LAYOUT_ENTRY_POINTS))
def test_a_geomorph_pkn_array_is_refused_with_the_conversion(nkd, entry):
    pkn = sl.io.to_pkn(nkd)  # (8, 2, 12): read as 8 shapes of 2 landmarks in 12 dimensions
    with pytest.raises(ValueError, match=r"12 dimensions.*p x k x n.*shapelib\.io\.from_pkn"):
        LAYOUT_ENTRY_POINTS[entry](pkn)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sl.ScaleWarning)  # pixel units against sigma2 = 0.5
        LAYOUT_ENTRY_POINTS[entry](nkd)  # the right layout passes


@pytest.mark.parametrize("entry", sorted(LAYOUT_ENTRY_POINTS))
def test_an_n_d_k_array_is_refused_with_the_conversion(nkd, entry):
    ndk = nkd.transpose(0, 2, 1)  # (12, 2, 8): read as 12 shapes of 2 landmarks in 8 dimensions
    with pytest.raises(ValueError, match=r"8 dimensions.*\(N, d, K\).*swapaxes"):
        LAYOUT_ENTRY_POINTS[entry](ndk)


@pytest.mark.parametrize("entry", ["procrustes_distance", "procrustes_align", "centroid_size", "preshape"])
def test_procrustes_functions_refuse_a_transposed_shape(nkd, entry):
    u, v = nkd[0].T, nkd[1].T  # (2, 8): 2 landmarks in 8 dimensions
    f = getattr(sl, entry)
    with pytest.raises(ValueError, match=r"8 dimensions.*\(K, d\).*transposed"):
        f(u, v) if entry.startswith("procrustes") else f(u)


@pytest.mark.parametrize("metric", sorted(METRICS))
def test_every_metric_refuses_a_transposed_pair(nkd, metric):
    params = {"sigma2": 0.5} if metric in SIGMA2_METRICS else {}
    u, v = nkd[0].T, nkd[1].T
    with pytest.raises(ValueError, match=r"8 dimensions.*\(K, d\)"):
        sl.distance(u, v, metric=metric, **params)
    with pytest.raises(ValueError, match=r"8 dimensions.*\(K, d\)"):
        sl.pair_record(u, v, metric=metric, **params)

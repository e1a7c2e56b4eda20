"""Tangent PCA (shapelib.statistics.tangent_pca): orthonormality in g(mean), round trips, the
small-σ limit (ordinary PCA), the scikit-learn transformer, 2-D and 3-D."""

import warnings

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.decomposition import PCA

import shapelib
from shapelib.solver.path_metric import path_metric
from shapelib.statistics.frechet import frechet_mean
from shapelib.statistics.tangent_pca import TangentPCA, tangent_pca
from tests.conftest import ellipse_population


def population(rng, n=10, k=10, d=2, noise=0.15):
    """Two modes (a stretch and a slide along the outline) plus noise."""
    return ellipse_population(rng, n, k, d, noise=noise, second_mode=0.3)


@pytest.fixture(scope="module")
def shapes():
    return population(np.random.default_rng(3))


@pytest.fixture(scope="module")
def mean(shapes):
    return frechet_mean(shapes, sigma2=1.0, tol=1e-5, n_jobs=1)


@pytest.fixture(scope="module")
def pca(shapes, mean):
    return tangent_pca(shapes, mean=mean, modes=(0, 1), sd=(-2, 0, 2), n_jobs=1)


def test_components_are_orthonormal_in_the_metric_not_in_coordinates(pca, mean):
    c = pca.components.reshape(pca.n_components, -1)
    g = shapelib.alpha_metric(mean.mean, sigma2=1.0)
    assert np.allclose(c @ g @ c.T, np.eye(pca.n_components), atol=1e-8)
    assert not np.allclose(c @ c.T, np.diag(np.diag(c @ c.T)), atol=1e-3)


def test_variances_and_scores(pca, mean, shapes):
    assert np.all(np.diff(pca.explained_variance) <= 1e-12)
    assert np.allclose(pca.scores.var(axis=0, ddof=1), pca.explained_variance)
    assert np.isclose(pca.explained_variance_ratio.sum(), 1.0)  # all components kept
    # total tangent variance = Fréchet variance (‖log‖² = d²) with the N - 1 normalisation
    n = len(shapes)
    assert np.isclose(pca.total_variance * (n - 1) / n, mean.spread**2, rtol=1e-6)
    assert abs(mean.spread**2 / mean.variance - 1) < 0.1  # ‖log‖² = d² up to the O(1/n) error of the log
    # at a Fréchet mean the logs average to ~zero: the centre is the first-order condition
    assert np.linalg.norm(pca.center) <= 1e-5 * mean.spread
    # the scores are the logs' metric coordinates along the components
    proj = np.einsum("nkd,kde->ne", mean.logs.reshape(n, -1)[:, :, None] * 1.0,
                     (mean.tangent.metric_tensor @ pca.components.reshape(pca.n_components, -1).T)[:, None, :])
    assert np.allclose(proj - proj.mean(axis=0), pca.scores, atol=1e-8 * mean.spread)


def test_mode_shapes_go_both_ways_through_the_mean(pca):
    sh = pca.mode_shapes[0]
    assert sh.shape == (3, *pca.mean.shape)
    assert np.allclose(sh[1], pca.shape([0.0]))
    two_sd = 2 * np.sqrt(pca.explained_variance[0])
    model = path_metric("alpha", 1.0)
    for sign, end in ((-1, sh[0]), (1, sh[2])):
        path = pca.shape([sign * two_sd], return_path=True)
        assert np.allclose(path[-1], end)
        length = shapelib.path_length(path, sigma2=1.0)
        # chord <= distance <= length of the discrete geodesic, which leaves with metric speed 2 SD
        assert 0.8 * two_sd < model.lower_bound(pca.mean, end) <= length < 1.15 * two_sd


def test_sklearn_transformer_round_trips(shapes, mean, pca):
    est = TangentPCA(sigma2=1.0, mean=mean).fit(shapes.reshape(len(shapes), -1))
    assert est.n_components_ == pca.n_components
    assert np.allclose(est.explained_variance_, pca.explained_variance)
    assert est.components_.shape == (est.n_components_, shapes[0].size)
    scores = est.transform(shapes[:3].reshape(3, -1))
    assert np.allclose(scores, pca.scores[:3], atol=1e-6 * np.sqrt(pca.total_variance))
    back = est.inverse_transform(scores).reshape(3, *shapes.shape[1:])
    model = path_metric("alpha", 1.0)
    for b, x in zip(back, shapes[:3]):  # all components: the shape comes back, in density
        assert model.lower_bound(b, x) < 2e-3 * model.lower_bound(mean.mean, x)
    # within the retained components: transform(inverse_transform(s)) = s
    est2 = clone(est).set_params(n_components=2).fit(shapes)
    s = np.array([[0.5, -0.3], [-1.0, 0.2]]) * np.sqrt(est2.explained_variance_)
    assert np.allclose(est2.transform(est2.inverse_transform(s)), s, atol=2e-3 * np.abs(s).max())
    assert np.allclose(est2.fit_transform(shapes), pca.scores[:, :2], atol=1e-6 * np.sqrt(pca.total_variance))


@pytest.mark.parametrize("metric", ["alpha", "fisher_rao"])
def test_small_sigma_limit_is_ordinary_pca(metric):
    rng = np.random.default_rng(9)
    base = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 1.7]])
    x = shapelib.pose_align(np.stack([5 * base + 0.2 * rng.normal(size=base.shape) + rng.normal() * 0.3 * base
                                      for _ in range(12)]))[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", shapelib.ScaleWarning)
        res = tangent_pca(x, metric=metric, sigma2=0.09, tol=1e-9, modes=(0,), sd=(1.0,), n_jobs=1)
    ref = PCA().fit(x.reshape(len(x), -1))
    # the directions alignment removed (rotation, translation) have no variance: no defined component
    k = min(res.n_components, int(np.sum(ref.explained_variance_ratio_ > 1e-9)))
    assert np.allclose(res.explained_variance_ratio[:k], ref.explained_variance_ratio_[:k], atol=1e-6)
    c = res.components[:k].reshape(k, -1)
    c = c / np.linalg.norm(c, axis=1, keepdims=True)
    assert np.allclose(np.abs(np.sum(c * ref.components_[:k], axis=1)), 1.0, atol=1e-6)
    scale = res.explained_variance[0] / ref.explained_variance_[0]  # the metric's constant factor
    assert np.allclose(res.explained_variance[:k] / scale, ref.explained_variance_[:k], rtol=1e-6)
    # and the mode shape is the straight line mean + sd·√λ·c
    assert np.allclose(res.mode_shapes[0][0], x.mean(axis=0) + ref.components_[0].reshape(5, 2) * np.sqrt(
        ref.explained_variance_[0]) * np.sign(np.sum(c[0] * ref.components_[0])), atol=1e-6)


def test_three_dimensional_landmarks():
    x = population(np.random.default_rng(4), n=8, k=8, d=3)
    res = tangent_pca(x, sigma2=1.0, tol=1e-4, modes=(0,), sd=(-1.0, 1.0), n_jobs=1)
    c = res.components.reshape(res.n_components, -1)
    g = shapelib.alpha_metric(res.mean, sigma2=1.0)
    assert np.allclose(c @ g @ c.T, np.eye(res.n_components), atol=1e-8)
    assert res.mode_shapes[0].shape == (2, 8, 3)


def test_given_mean_shape_and_n_components(shapes, mean, pca):
    res = tangent_pca(shapes, sigma2=1.0, mean=mean.mean, n_components=3, modes=(), n_jobs=1)
    assert res.n_components == 3 and res.frechet is None
    assert np.allclose(res.explained_variance, pca.explained_variance[:3], rtol=1e-3)
    assert "PC1" in res.summary()


def test_bad_input(shapes, mean):
    with pytest.raises(ValueError, match="n_components"):
        tangent_pca(shapes, sigma2=1.0, mean=mean, n_components=0, n_jobs=1)
    with pytest.raises(ValueError, match="Fréchet mean of"):
        tangent_pca(shapes[:5], sigma2=1.0, mean=mean, n_jobs=1)
    with pytest.raises(ValueError, match="n_dim"):
        TangentPCA(sigma2=1.0, n_dim=3).fit(shapes.reshape(len(shapes), -1)[:, :-1])
    est = TangentPCA(sigma2=1.0, mean=mean).fit(shapes)
    with pytest.raises(ValueError, match="components"):
        est.inverse_transform(np.zeros((1, est.n_components_ + 1)))


def test_ktch_shape_variation_plot_takes_the_transformer(shapes, mean):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from ktch.plot import shape_variation_plot

    est = TangentPCA(sigma2=1.0, mean=mean, n_components=3).fit(shapes.reshape(len(shapes), -1))
    fig = shape_variation_plot(est, n_dim=2, components=(0, 1), sd_values=(-2.0, 0.0, 2.0))
    assert len(fig.axes) == 6
    # the shape ktch draws at +2 SD of PC1 is the exponential map at the mean
    drawn = est.inverse_transform(np.array([[2 * np.sqrt(est.explained_variance_[0]), 0.0, 0.0]]))[0]
    assert np.allclose(drawn.reshape(-1, 2), est.result_.shape([2 * np.sqrt(est.explained_variance_[0])]))
    plt.close(fig)

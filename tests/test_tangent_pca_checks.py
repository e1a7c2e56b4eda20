"""Tangent PCA checked against independent computations on a small population (6 shapes of 6
landmarks, 4-segment geodesics: a few hundredths of a second each): the PCA against scikit-learn's on
the isometric coordinates built from the metric tensor's eigenvectors, the shapes along the modes
against the log map recomputed by the geodesic solver, the options and the refusals, and the
scikit-learn transformer against the function."""

import importlib
import warnings

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.decomposition import PCA

import shapelib
from shapelib.solver.logexp import DEFAULT_LOG_STEPS, DEFAULT_RCOND, tangent_space
from shapelib.statistics.frechet import frechet_mean
from shapelib.statistics.tangent_pca import DEFAULT_SD, TangentPCA, tangent_pca
from tests.conftest import CountingExecutor, ellipse_population

#: mutmut (benchmarks/mutation.py) runs these tests against a copy of the module whose functions go
#: through a trampoline, one more stack frame between the caller and the code (the module, not the
#: function of the same name that shapelib.statistics exports)
UNDER_MUTMUT = any("__mutmut_" in name for name in vars(importlib.import_module("shapelib.statistics.tangent_pca")))
SIGMA2 = 1.0
N_STEPS = 4


@pytest.fixture(scope="module")
def x():
    return ellipse_population(np.random.default_rng(3), 6, 6, 2, noise=0.15, second_mode=0.3)


@pytest.fixture(scope="module")
def fm(x):
    return frechet_mean(x, sigma2=SIGMA2, n_steps=N_STEPS, tol=1e-6, n_jobs=1)


@pytest.fixture
def pca(x, fm):
    # per test (a few hundredths of a second): mutmut counts a test as covering tangent_pca only when
    # the call happens inside it, not in a module fixture set up by another test
    return tangent_pca(x, mean=fm, modes=(0, 1), sd=(-2.0, 0.0, 1.5), n_jobs=1)


def _iso(fm):
    """Isometric coordinates of the logs, from the metric tensor's eigenvectors (numpy's eigh):
    z = Λ^½ Uᵀ v over the retained eigenvalues."""
    lam, vec = np.linalg.eigh(tangent_space(fm.mean, sigma2=SIGMA2).metric_tensor)
    keep = lam > fm.options.rcond * lam.max()
    return (fm.logs.reshape(len(fm.logs), -1) @ vec[:, keep]) * np.sqrt(lam[keep]), vec[:, keep], lam[keep]


def _log(base, y):
    """The discrete log map recomputed by the geodesic solver (straight-line start, tight tolerance)."""
    geo = shapelib.geodesic(base, y, sigma2=SIGMA2, n_steps=N_STEPS, tol=1e-11, max_iter=3000)
    return N_STEPS * (geo.path[1] - geo.path[0])


def test_the_pca_is_scikit_learns_on_the_isometric_coordinates(x, fm, pca):
    z, _, _ = _iso(fm)
    ref = PCA().fit(z)
    k = len(ref.explained_variance_)
    assert pca.n_components == k == min(len(x), z.shape[1])
    tiny = 1e-12 * ref.explained_variance_.sum()   # the centred logs of N shapes span N - 1 directions
    np.testing.assert_allclose(pca.explained_variance, ref.explained_variance_, rtol=1e-9, atol=tiny)
    np.testing.assert_allclose(pca.explained_variance_ratio, ref.explained_variance_ratio_, rtol=1e-9, atol=1e-12)
    assert pca.total_variance == pytest.approx(np.var(z, axis=0, ddof=1).sum(), rel=1e-12)
    assert np.linalg.norm(pca.center) == pytest.approx(np.linalg.norm(z.mean(axis=0)), rel=1e-6, abs=1e-14)
    # the scores are scikit-learn's up to the sign of each axis, which is fixed: its largest |loading| positive
    signs = np.sign(np.sum(pca.scores * ref.transform(z), axis=0))
    np.testing.assert_allclose(pca.scores, ref.transform(z) * signs, atol=1e-10)
    big = pca.axes[np.arange(k), np.argmax(np.abs(pca.axes), axis=1)]
    assert np.all(big > 0)
    live = ref.explained_variance_ > tiny
    assert live.sum() == len(x) - 1
    # the principal directions in landmark coordinates, v = U Λ^-½ a, up to sign
    _, vec, lam = _iso(fm)
    ref_dirs = (ref.components_[live] / np.sqrt(lam)) @ vec.T
    np.testing.assert_allclose(pca.components.reshape(k, -1)[live], ref_dirs * signs[live, None], atol=1e-8)


def test_the_components_are_the_axes_in_landmark_coordinates(x, fm, pca):
    """Orthonormal in g(mean); each shape's log is the centre's vector plus its scores along them."""
    g = tangent_space(fm.mean, sigma2=SIGMA2).metric_tensor
    c = pca.components.reshape(pca.n_components, -1)
    np.testing.assert_allclose(c @ g @ c.T, np.eye(pca.n_components), atol=1e-9)
    flat = fm.logs.reshape(len(x), -1)
    np.testing.assert_allclose(flat @ g @ c.T - (flat @ g @ c.T).mean(axis=0), pca.scores, atol=1e-10)
    np.testing.assert_allclose(pca.vector(pca.scores[2]).ravel(), pca.vector([]).ravel() + pca.scores[2] @ c,
                               atol=1e-10)
    # all components kept and a full-rank g: the vector of a shape's scores is its log
    np.testing.assert_allclose(pca.vector(pca.scores[2]), fm.logs[2], atol=1e-9)
    np.testing.assert_allclose(pca.vector(pca.scores[2][:2]).ravel(),
                               pca.vector([]).ravel() + pca.scores[2][:2] @ c[:2], atol=1e-10)
    assert pca.discarded_fraction == pytest.approx(0.0, abs=1e-12)
    assert pca.frechet is fm and np.array_equal(pca.mean, fm.mean) and pca.tangent is fm.tangent
    assert pca.options is fm.options


def test_the_shapes_along_a_mode_have_the_mode_as_their_log(fm, pca):
    """``shape(s)`` is exp_mean(vector(s)): its log map at the mean, recomputed, is vector(s)."""
    assert set(pca.mode_shapes) == {0, 1}
    for j in (0, 1):
        assert pca.mode_shapes[j].shape == (3, *fm.mean.shape)
        for s, shape in zip((-2.0, 0.0, 1.5), pca.mode_shapes[j]):
            scores = np.zeros(pca.n_components)
            scores[j] = s * np.sqrt(pca.explained_variance[j])
            np.testing.assert_allclose(_log(fm.mean, shape), pca.vector(scores), atol=2e-4 * fm.spread)
    path = pca.shape([1.0], return_path=True)
    assert path.shape == (N_STEPS + 1, *fm.mean.shape)
    np.testing.assert_allclose(path[0], fm.mean, atol=1e-12)
    np.testing.assert_array_equal(path[-1], pca.shape([1.0]))
    np.testing.assert_allclose(N_STEPS * (path[1] - path[0]), pca.vector([1.0]), atol=1e-9)


def test_modes_draws_what_it_is_asked_and_refuses_components_out_of_range(pca):
    out = pca.modes(components=(2,), sd=(1.0,))
    assert list(out) == [2] and out[2].shape == (1, *pca.mean.shape) and 2 in pca.mode_shapes
    default = pca.modes(components=(0,))
    assert default[0].shape == (len(DEFAULT_SD), *pca.mean.shape) and DEFAULT_SD == (-2.0, -1.0, 0.0, 1.0, 2.0)
    np.testing.assert_allclose(default[0][2], pca.shape([0.0]), atol=1e-12)
    for j in (-1, pca.n_components):
        with pytest.raises(ValueError, match=f"^component {j} out of range: {pca.n_components} components"):
            pca.modes(components=(j,))


def test_n_components_keeps_the_first_and_their_share_of_the_total(x, fm, pca):
    two = tangent_pca(x, mean=fm, n_components=2, modes=(0, 2, 5), sd=(1.0,), n_jobs=1)
    assert two.n_components == 2 and list(two.mode_shapes) == [0]   # modes past n_components are not drawn
    np.testing.assert_allclose(two.explained_variance, pca.explained_variance[:2], rtol=1e-12)
    np.testing.assert_allclose(two.explained_variance_ratio, pca.explained_variance_ratio[:2], rtol=1e-12)
    assert two.total_variance == pca.total_variance and two.explained_variance_ratio.sum() < 1
    assert two.components.shape == (2, *fm.mean.shape) and two.scores.shape == (len(x), 2)
    many = tangent_pca(x, mean=fm, n_components=50, modes=(), n_jobs=1)
    assert many.n_components == pca.n_components


def test_copies_have_no_variance():
    y = ellipse_population(np.random.default_rng(0), 1, 6, 2, noise=0.1)[0]
    res = tangent_pca(np.repeat(y[None], 3, axis=0), sigma2=SIGMA2, n_steps=N_STEPS, modes=(), n_jobs=1)
    assert res.total_variance == 0 and np.all(res.explained_variance == 0)
    assert np.all(res.explained_variance_ratio == 0) and len(res.explained_variance_ratio) == res.n_components


def test_at_a_given_shape_the_logs_are_computed_there(x, fm):
    base = x[0]
    res = tangent_pca(x, sigma2=SIGMA2, mean=base, n_steps=N_STEPS, modes=(), n_jobs=1)
    assert res.frechet is None and np.array_equal(res.mean, base)
    assert res.options.n_steps == N_STEPS and res.options.sigma2 == SIGMA2
    logs = np.stack([_log(base, y) for y in x])
    g = tangent_space(base, sigma2=SIGMA2).metric_tensor
    c = res.components.reshape(res.n_components, -1)
    proj = logs.reshape(len(x), -1) @ g @ c.T
    np.testing.assert_allclose(proj - proj.mean(axis=0), res.scores, atol=1e-4 * np.sqrt(res.total_variance))
    np.testing.assert_allclose(res.tangent.base, base)
    assert res.center @ res.center > 0.01 * res.total_variance   # not a mean: the logs do not average to 0


def test_the_frechet_mean_is_computed_with_the_options_given(x, fm):
    res = tangent_pca(x, sigma2=SIGMA2, n_steps=N_STEPS, tol=1e-6, modes=(), n_jobs=1)
    assert res.frechet is not None and res.frechet.tol == 1e-6
    np.testing.assert_allclose(res.mean, fm.mean, atol=1e-12)
    assert res.frechet.options.n_steps == N_STEPS and res.options.n_steps == N_STEPS
    fr = tangent_pca(x, metric="fisher_rao", sigma2=0.8, n_steps=3, rcond=1e-5, grid_spacing=0.4, grid_margin=2.5,
                     log_tol=1e-7, log_max_iter=60, max_iter=0, warn=False, modes=(), n_jobs=1)
    for o in (fr.options, fr.frechet.options):
        assert (o.metric, o.sigma2, o.n_steps, o.rcond, o.grid_spacing, o.grid_margin, o.tol, o.max_iter) == \
            ("fisher_rao", 0.8, 3, 1e-5, 0.4, 2.5, 1e-7, 60)
    assert fr.frechet.n_iter == 0 and fr.frechet.log[-1]["mode"] == "in-process"
    f = tangent_pca(x, sigma2=0.8, n_steps=3, rcond=1e-5, log_tol=1e-7, log_max_iter=60, max_iter=0, warn=False,
                    modes=(), n_jobs=1).frechet.options
    assert (f.sigma2, f.n_steps, f.rcond, f.tol, f.max_iter) == (0.8, 3, 1e-5, 1e-7, 60)
    d = tangent_pca(x, sigma2=SIGMA2, mean=fm.mean, modes=(), n_jobs=1).options
    assert (d.n_steps, d.rcond) == (DEFAULT_LOG_STEPS, DEFAULT_RCOND)


def test_the_summary_states_the_shares(pca, x):
    text = pca.summary()
    r = pca.explained_variance_ratio
    assert text.startswith(f"tangent PCA (alpha, σ² = 1) of {len(x)} shapes: "
                           f"PC1 {100 * r[0]:.1f} %, PC2 {100 * r[1]:.1f} %")
    assert f"PC5 {100 * r[4]:.1f} %; total variance {pca.total_variance:.4g} in 12 retained directions" in text
    assert "PC6" not in text and text.endswith(f"({pca.discarded_fraction:.1e} of it outside)")


@pytest.mark.parametrize("kw, match", [
    ({"n_components": 0}, "^n_components "),
    ({"sigma2": None}, "^tangent_pca needs sigma2"),
    ({"mean": "x0", "tol": 1e-3}, r"^options of the Fréchet mean \(tol\) given with mean="),
    ({"mean": "x0[:4]"}, r"^mean must have shape \(6, 2\)"),
    ({"mean": "fm", "n_jobs": 0}, "^n_jobs must be"),
    ({"mean": "fm3"},
     r"^mean: a Fréchet mean of 3 shapes of shape \(6, 2\), not of these 6 shapes of shape \(6, 2\)$"),
    ({"shapes": 5, "mean": "fm"},
     r"^mean: a Fréchet mean of 6 shapes of shape \(6, 2\), not of these 5 shapes of shape "),
    ({"sigma2": None, "mean": "x0"}, r"^tangent_pca needs sigma2=\.\.\. unless mean= is a FrechetMeanResult$"),
    ({"mean": "x0", "tol": 1e-3, "max_iter": 3}, r"^options of the Fréchet mean \(max_iter, tol\) given with mean=$"),
    ({"mean": "x0[None]"}, "^mean must be a 2-D array"),
    ({"mean": "fm", "client": object(), "scheduler": "tcp://127.0.0.1:1"}, "^give client or scheduler, not both"),
])
def test_bad_input_names_the_parameter(x, fm, kw, match):
    kw = dict(kw)
    warnings.simplefilter("ignore", shapelib.PoseWarning)
    if "mean" in kw:
        fm3 = frechet_mean(x[:3], sigma2=SIGMA2, n_steps=N_STEPS, max_iter=0, warn=False, n_jobs=1)
        kw["mean"] = {"x0": x[0], "x0[:4]": x[0, :4], "fm": fm, "x0[None]": x[:1], "fm3": fm3}[kw["mean"]]
    shapes = x[:kw.pop("shapes", len(x))]
    with pytest.raises(ValueError, match=match):
        tangent_pca(shapes, **{"sigma2": SIGMA2, "n_steps": N_STEPS, "modes": (), "n_jobs": 1, **kw})


def test_a_population_out_of_pose_is_warned_at_the_caller(x):
    turned = x.copy()
    c, s = np.cos(0.4), np.sin(0.4)
    turned[0] = x[0] @ np.array([[c, -s], [s, c]])
    with pytest.warns(shapelib.PoseWarning) as record:
        tangent_pca(turned, sigma2=SIGMA2, mean=x[1], n_steps=N_STEPS, modes=(), n_jobs=1)
    assert sum(issubclass(w.category, shapelib.PoseWarning) for w in record) == 1
    if not UNDER_MUTMUT:  # mutmut's trampoline adds a frame of its own
        assert record[0].filename == __file__


def test_the_transformer_is_the_function(x, fm):
    est = TangentPCA(sigma2=SIGMA2, n_steps=N_STEPS, n_components=3, tol=1e-6)
    flat = x.reshape(len(x), -1)
    z = est.fit_transform(flat)
    ref = tangent_pca(x, sigma2=SIGMA2, n_steps=N_STEPS, n_components=3, tol=1e-6, modes=(), n_jobs=1)
    np.testing.assert_allclose(z, ref.scores, atol=1e-10)
    z[0, 0] += 1.0
    assert est.result_.scores[0, 0] != z[0, 0]   # a copy
    assert est.result_.frechet.tol == 1e-6 and est.result_.mode_shapes == {}
    np.testing.assert_array_equal(est.mean_, ref.mean.ravel())
    np.testing.assert_allclose(est.components_, ref.components.reshape(3, -1), atol=1e-10)
    np.testing.assert_allclose(est.explained_variance_, ref.explained_variance, rtol=1e-10)
    np.testing.assert_allclose(est.explained_variance_ratio_, ref.explained_variance_ratio, rtol=1e-10)
    zz, _, _ = _iso(est.result_.frechet)
    np.testing.assert_allclose(est.singular_values_, PCA(3).fit(zz).singular_values_, rtol=1e-9)
    assert est.n_components_ == 3 and est.n_features_in_ == 12
    np.testing.assert_allclose(est.transform(flat), ref.scores, atol=1e-5 * np.sqrt(ref.total_variance))
    np.testing.assert_allclose(est.transform(x), est.transform(flat), atol=1e-12)   # (N, K, d) too
    back = est.inverse_transform(ref.scores[:2, :2])
    assert back.shape == (2, 12)
    np.testing.assert_allclose(back[1], ref.shape(ref.scores[1, :2]).ravel(), atol=1e-12)
    np.testing.assert_allclose(est.inverse_transform(ref.scores[1, :2]), back[1:], atol=1e-12)   # one row
    with pytest.raises(ValueError, match="^X has 4 scores per row; the model has 3 components"):
        est.inverse_transform(np.zeros((1, 4)))
    with pytest.raises(ValueError, match=r"^X has landmarks of shape \(5, 2\); the model was fitted on \(6, 2\)"):
        est.transform(x[:, :5])


def test_the_transformer_takes_a_mean_and_its_own_defaults(x, fm):
    est = TangentPCA(mean=fm).fit(x)
    assert est.result_.frechet is fm and est.n_components_ == min(len(x), 12)
    plain = TangentPCA(sigma2=SIGMA2)
    params = plain.get_params()
    assert params == {"metric": "alpha", "sigma2": SIGMA2, "n_components": None, "n_dim": 2, "mean": None,
                      "n_steps": DEFAULT_LOG_STEPS, "rcond": DEFAULT_RCOND, "tol": 1e-3, "executor": None}
    assert clone(plain).get_params() == params
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", shapelib.GeodesicWarning)
        fitted = TangentPCA(sigma2=SIGMA2, n_steps=3).fit(x)
    assert fitted.result_.frechet.tol == 1e-3 and fitted.result_.options.n_steps == 3
    assert fitted.result_.options.rcond == DEFAULT_RCOND
    # the metric, σ² and rcond reach the analysis
    fr = TangentPCA(metric="fisher_rao", sigma2=0.8, n_steps=3, rcond=1e-5, tol=1e-2).fit(x)
    assert (fr.result_.options.metric, fr.result_.options.sigma2, fr.result_.options.rcond) == ("fisher_rao", 0.8, 1e-5)
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(2) as ex:
        threaded = TangentPCA(sigma2=SIGMA2, mean=fm.mean, n_steps=N_STEPS, executor=ex).fit(x)
        np.testing.assert_allclose(threaded.transform(x[:2]), threaded.result_.scores[:2], atol=1e-6)


def test_three_d_landmarks_flattened_by_n_dim():
    y = ellipse_population(np.random.default_rng(4), 5, 5, 3, noise=0.15)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", shapelib.GeodesicWarning)
        est = TangentPCA(sigma2=SIGMA2, n_dim=3, n_steps=3, n_components=2).fit(y.reshape(5, -1))
    assert est.result_.mean.shape == (5, 3) and est.components_.shape == (2, 15)


@pytest.mark.parametrize("n_dim, cols", [(3, 11), (4, 12), (1, 12)])
def test_the_transformer_refuses_flat_input_of_another_n_dim(x, n_dim, cols):
    with pytest.raises(ValueError, match=f"^X has {cols} features, not a multiple of n_dim = {n_dim}"):
        TangentPCA(sigma2=SIGMA2, n_dim=n_dim).fit(x.reshape(len(x), -1)[:, :cols])


def test_the_transformer_needs_sigma2_without_a_frechet_mean(x):
    for mean in (None, x[0]):
        with pytest.raises(ValueError, match="^TangentPCA needs sigma2"):
            TangentPCA(mean=mean).fit(x)


def test_two_shapes_have_one_component_of_half_their_squared_log(x):
    """At x0, the logs of (x0, x1) are 0 and v = log_x0(x1): centred ±v/2, whose sample variance (N − 1 = 1)
    is ‖v‖²_g / 2, all in one component."""
    res = tangent_pca(x[:2], sigma2=SIGMA2, mean=x[0], n_steps=N_STEPS, modes=(), n_jobs=1)
    v = _log(x[0], x[1]).ravel()
    g = tangent_space(x[0], sigma2=SIGMA2).metric_tensor
    assert res.explained_variance[0] == pytest.approx(v @ g @ v / 2, rel=1e-5)
    assert res.explained_variance_ratio[0] == pytest.approx(1.0, abs=1e-12)
    est = TangentPCA(sigma2=SIGMA2, mean=x[0], n_steps=N_STEPS, n_components=1).fit(x[:2])
    assert est.singular_values_[0] == pytest.approx(np.sqrt(v @ g @ v / 2), rel=1e-5)


def test_bad_shapes_name_the_parameter(x):
    with pytest.raises(ValueError, match=r"^shapes must have shape \(N, K, d\)"):
        tangent_pca(x[0], sigma2=SIGMA2, n_jobs=1)
    with pytest.raises(ValueError, match=r"^X must have shape \(N, K, d\)"):
        TangentPCA(sigma2=SIGMA2).fit(x[..., None])
    with pytest.raises(ValueError, match=r"^TangentPCA needs sigma2=\.\.\., as tangent_pca does \(or mean=, a "
                                         r"FrechetMeanResult, which carries its own\)$"):
        TangentPCA().fit(x)


def test_the_pose_warning_names_the_metric(x):
    turned = x.copy()
    c, s = np.cos(0.4), np.sin(0.4)
    turned[0] = x[0] @ np.array([[c, -s], [s, c]])
    with pytest.warns(shapelib.PoseWarning, match="^fisher_rao depends on the pose"):
        tangent_pca(turned, metric="fisher_rao", sigma2=SIGMA2, mean=x[1], n_steps=N_STEPS, modes=(), n_jobs=1)


def test_the_log_maps_run_on_the_executor_in_tasks_of_chunk_size(x, fm):
    ex = CountingExecutor()
    try:
        at = tangent_pca(x, sigma2=SIGMA2, mean=x[0], n_steps=N_STEPS, modes=(), executor=ex, chunk_size=4)
        assert ex.tasks == [4, 2]   # the 6 log maps at the given shape
        ref = tangent_pca(x, sigma2=SIGMA2, mean=x[0], n_steps=N_STEPS, modes=(), n_jobs=1)
        np.testing.assert_allclose(at.scores, ref.scores, atol=1e-9)
        ex.tasks.clear()
        full = tangent_pca(x, sigma2=SIGMA2, n_steps=N_STEPS, tol=1e-6, modes=(), executor=ex, chunk_size=4)
        assert sum(ex.tasks) == full.frechet.n_log_maps and set(ex.tasks) == {4, 2}   # the Fréchet mean's too
        np.testing.assert_allclose(full.mean, fm.mean, atol=1e-10)
        ex.tasks.clear()
        est = TangentPCA(sigma2=SIGMA2, mean=x[0], n_steps=N_STEPS, executor=ex).fit(x)
        assert sum(ex.tasks) == len(x) and est.get_params()["executor"] is ex
        ex.tasks.clear()
        np.testing.assert_allclose(est.transform(x[:3]), est.result_.scores[:3],
                                   atol=1e-6 * np.sqrt(ref.total_variance))
        assert sum(ex.tasks) == 3
    finally:
        ex.pool.shutdown()
    # the caller's executor with an engine keyword is refused
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(1) as pool:
        for kw in ({"n_jobs": 2}, {"client": object()}, {"scheduler": "tcp://127.0.0.1:1"}):
            for mean in (x[0], None):
                with pytest.raises(ValueError, match="^give executor, or n_jobs / client / scheduler, not both"):
                    tangent_pca(x, sigma2=SIGMA2, mean=mean, n_steps=N_STEPS, modes=(), executor=pool, **kw)


def test_n_jobs_none_decides_and_stays_in_this_process_for_a_small_population(x):
    auto = tangent_pca(x, sigma2=SIGMA2, mean=x[0], n_steps=N_STEPS, modes=())   # one log map timed first
    ref = tangent_pca(x, sigma2=SIGMA2, mean=x[0], n_steps=N_STEPS, modes=(), n_jobs=1)
    np.testing.assert_allclose(auto.scores, ref.scores, atol=1e-12)
    est = TangentPCA(sigma2=SIGMA2, n_steps=N_STEPS, tol=1e-4).fit(x)   # no executor: in this process
    assert est.result_.frechet.log[-1]["mode"] == "in-process"


def test_a_rank_deficient_tangent_space_discards_a_share_of_the_logs(x):
    fm = frechet_mean(x, sigma2=SIGMA2, n_steps=N_STEPS, rcond=0.4, max_iter=1, warn=False, n_jobs=1)
    res = tangent_pca(x, mean=fm, modes=(), n_jobs=1)
    lam, vec = np.linalg.eigh(tangent_space(fm.mean, sigma2=SIGMA2).metric_tensor)
    c = fm.logs.reshape(len(x), -1) @ vec
    dropped = lam < 0.4 * lam.max()
    expected = np.sum(lam[dropped] * c[:, dropped] ** 2) / np.sum(lam * c ** 2)
    assert dropped.any() and expected > 1e-6 and res.discarded_fraction == pytest.approx(expected, rel=1e-6)
    assert res.n_components == min(len(x), int((~dropped).sum()))


def test_the_transformer_at_a_shape_that_is_not_a_mean(x):
    """At x0 the logs do not average to zero (the centre is far from 0): transform still gives the
    centred scores, and inverse_transform takes as many scores as there are components."""
    est = TangentPCA(sigma2=SIGMA2, mean=x[0], n_steps=N_STEPS, n_components=3)
    z = est.fit_transform(x)
    assert est.result_.center @ est.result_.center > 0.01 * est.result_.total_variance
    np.testing.assert_allclose(est.transform(x), z, atol=1e-6 * np.sqrt(est.result_.total_variance))
    assert est.inverse_transform(z[:2]).shape == (2, 12)
    assert est.result_.frechet is None and est.result_.options.tol == 1e-6   # geodesic_options' default path solves

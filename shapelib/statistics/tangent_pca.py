"""Tangent PCA at the Fréchet mean, orthonormal in the metric ``g(mean)``.

Principal component analysis of the log maps ``v_i = log_m(x_i)`` at the Fréchet mean ``m``
(Fletcher et al. 2004's linearised principal geodesic analysis), with the inner product of the
tangent space — ``⟨v, w⟩ = vᵀ g(m) w`` — rather than that of raw landmark coordinates. PCA in raw
coordinates (as geomstats' ``TangentPCA`` does) weighs every landmark displacement alike,
including the slides along the contour that change no density; here they weigh what they change.

In the isometric coordinates ``z = Λ_r^{1/2} U_rᵀ v`` of the retained subspace of ``g(m)``
(:class:`~shapelib.solver.logexp.TangentSpace`), tangent PCA is ordinary PCA of the ``z_i``:

* components ``c_j`` (K, d) are orthonormal in ``g(m)``: ``c_jᵀ g c_k = δ_jk``;
* explained variances are those of the scores, with sklearn's ``N − 1`` normalisation; the
  ratios are relative to the total tangent variance (all retained directions);
* the shapes along a mode are ``exp_m(s √λ_j c_j)`` for ``s`` standard deviations;
* none of it depends on how the landmarks slide in the flat directions: those are outside the
  retained subspace (their share of the variance is ``discarded_fraction``, ~1e-7 on the corpus
  callosum), and the components, as vectors in the retained subspace, have no sliding part.

:class:`TangentPCA` is the same as a scikit-learn transformer (``fit``, ``transform``,
``inverse_transform``, ``components_``, ``explained_variance_``, ``n_components_``, flattened
(N, K·d) shapes like :class:`sklearn.decomposition.PCA`), which is what ktch's
``shape_variation_plot`` takes. Unlike sklearn's PCA, ``inverse_transform`` is the exponential
map, not ``scores @ components_ + mean_``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from sklearn.base import BaseEstimator, TransformerMixin
from sklearn.utils.validation import check_is_fitted

from .._executor import check_where
from .._validate import as_shape, as_shapes, check_positive_int
from ..geometry.quadrature import DEFAULT_MARGIN, DEFAULT_SPACING
from ..solver.logexp import DEFAULT_LOG_STEPS, DEFAULT_RCOND, TangentSpace, exp_path, tangent_space
from .frechet import FrechetMeanResult, check_population, frechet_mean, geodesic_options
from ._run import where_logs_run
from .population_logs import population_logs

__all__ = ["TangentPCAResult", "TangentPCA", "tangent_pca", "DEFAULT_SD"]

#: standard deviations at which the shapes along each mode are drawn
DEFAULT_SD = (-2.0, -1.0, 0.0, 1.0, 2.0)


def _pca(z, n_components):
    """PCA of isometric coordinates z (N, r): centre, SVD; returns what both APIs store."""
    n = len(z)
    centre = z.mean(axis=0)
    zc = z - centre
    _, s, wt = np.linalg.svd(zc, full_matrices=False)
    # a deterministic sign: the largest |loading| of every axis positive (as sklearn's svd_flip)
    signs = np.sign(wt[np.arange(len(wt)), np.argmax(np.abs(wt), axis=1)])
    signs[signs == 0] = 1
    wt *= signs[:, None]
    var = s**2 / max(n - 1, 1)
    total = float(var.sum())
    k = min(len(s), n_components) if n_components is not None else len(s)
    return centre, wt[:k], var[:k], (var[:k] / total if total > 0 else np.zeros(k)), s[:k], total


@dataclass
class TangentPCAResult:
    """Tangent PCA of a population (see :mod:`shapelib.statistics.tangent_pca`).

    Attributes
    ----------
    mean : ndarray (K, d)
    components : ndarray (n_components, K, d)
        Principal directions, orthonormal in ``g(mean)``.
    explained_variance : ndarray (n_components,)
        Variance of the scores along each (``N − 1`` normalisation).
    explained_variance_ratio : ndarray (n_components,)
        Relative to ``total_variance``.
    total_variance : float
        Sum of the variances of all retained directions.
    scores : ndarray (N, n_components)
        Metric coordinates of every shape's log map along the components (centred).
    center : ndarray (rank,)
        Mean of the isometric coordinates (≈ 0 at a Fréchet mean: its first-order condition).
    tangent : TangentSpace
        ``g(mean)`` and the retained subspace.
    discarded_fraction : float
        Share of ``Σ ‖log_i‖²_g`` outside the retained subspace.
    frechet : FrechetMeanResult or None
        The mean the analysis was made at, when it was computed here or given as such.
    mode_shapes : dict
        ``{j: ndarray (len(sd), K, d)}`` — shapes along mode j at ``sd`` standard deviations,
        filled by :meth:`modes`.

    See Also
    --------
    tangent_pca : What returns it.
    TangentPCA : The same as a scikit-learn transformer.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> t = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    >>> rng = np.random.default_rng(0)
    >>> x = np.stack([np.c_[2 * np.cos(t), np.sin(t)] + 0.05 * rng.normal(size=(8, 2)) for _ in range(5)])
    >>> x = sl.pose_align(x)[0]  # the metrics depend on pose: align first
    >>> pca = sl.tangent_pca(x, sigma2=0.5, modes=(0,), n_jobs=1)
    >>> pca.n_components, pca.scores.shape, pca.explained_variance_ratio[:2].round(3)
    (5, (5, 5), array([0.496, 0.298]))
    >>> pca.mode_shapes[0].shape   # the shapes at -2, -1, 0, 1, 2 standard deviations of PC1
    (5, 8, 2)
    >>> bool(np.allclose(pca.scores.mean(axis=0), 0))
    True
    """

    mean: np.ndarray
    components: np.ndarray
    explained_variance: np.ndarray
    explained_variance_ratio: np.ndarray
    total_variance: float
    scores: np.ndarray
    center: np.ndarray
    axes: np.ndarray
    tangent: TangentSpace
    discarded_fraction: float
    options: object
    frechet: FrechetMeanResult | None = None
    mode_shapes: dict = field(default_factory=dict, repr=False)

    @property
    def n_components(self) -> int:
        return len(self.explained_variance)

    def vector(self, scores) -> np.ndarray:
        """The tangent vector (K, d) at the mean with these ``scores`` (added to the centre)."""
        s = np.zeros(self.n_components)
        scores = np.asarray(scores, dtype=np.float64)
        s[:len(scores)] = scores
        return self.tangent.vectors(self.center + s @ self.axes)

    def shape(self, scores, *, return_path: bool = False):
        """``exp_mean(vector(scores))``: the shape with these scores (and the discrete geodesic to it)."""
        path, _ = exp_path(self.mean, self.vector(scores), options=self.options)
        return path if return_path else path[-1]

    def modes(self, components=(0, 1, 2), sd=DEFAULT_SD) -> dict:
        """Shapes along each of ``components`` at ``sd`` standard deviations: ``{j: (len(sd), K, d)}``
        (also stored in :attr:`mode_shapes`)."""
        for j in components:
            if not 0 <= j < self.n_components:
                raise ValueError(f"component {j} out of range: {self.n_components} components")
            shapes = []
            for s in sd:
                scores = np.zeros(self.n_components)
                scores[j] = s * np.sqrt(self.explained_variance[j])
                shapes.append(self.shape(scores))
            self.mode_shapes[j] = np.stack(shapes)
        return {j: self.mode_shapes[j] for j in components}

    def summary(self) -> str:
        k = min(5, self.n_components)
        ratios = ", ".join(f"PC{j + 1} {100 * r:.1f} %" for j, r in enumerate(self.explained_variance_ratio[:k]))
        return (f"tangent PCA ({self.options.metric}, σ² = {self.options.sigma2:g}) of {len(self.scores)} shapes: "
                f"{ratios}; total variance {self.total_variance:.4g} in {self.tangent.rank} retained directions "
                f"({self.discarded_fraction:.1e} of it outside)")


def _from_logs(mean, logs, ts, options, n_components, frechet=None) -> TangentPCAResult:
    z = ts.coords(logs)
    centre, axes, var, ratio, _, total = _pca(z, n_components)
    comps = ts.vectors(axes)
    return TangentPCAResult(mean=np.asarray(mean), components=comps, explained_variance=var,
                            explained_variance_ratio=ratio, total_variance=total, scores=(z - centre) @ axes.T,
                            center=centre, axes=axes, tangent=ts, discarded_fraction=ts.discarded_fraction(logs),
                            options=options, frechet=frechet)


def tangent_pca(shapes, *, metric: str = "alpha", sigma2=None, mean=None, n_components: int | None = None,
                n_steps: int = DEFAULT_LOG_STEPS, rcond: float = DEFAULT_RCOND, modes=(0, 1, 2), sd=DEFAULT_SD,
                executor=None, chunk_size: int | None = None, grid_spacing: float = DEFAULT_SPACING,
                grid_margin: float = DEFAULT_MARGIN, n_jobs: int | None = None, client=None, scheduler=None,
                **mean_options) -> TangentPCAResult:
    """Tangent PCA of ``shapes`` (N, K, d) at their Fréchet mean, orthonormal in ``g(mean)``.

    The log maps ``v_i = log_m(x_i)`` at the mean ``m`` are expressed in an orthonormal basis of
    the retained subspace of ``g(m)`` and their covariance diagonalised: the principal geodesic
    modes ``exp_m(±sd · √λ_j e_j)``.

    Parameters
    ----------
    shapes : array_like (N, K, d)
    metric, sigma2
        The metric (:func:`shapelib.statistics.frechet.frechet_mean`).
    mean : FrechetMeanResult or array_like (K, d), optional
        The mean to analyse at: a :class:`FrechetMeanResult` of these shapes (its log maps are
        used as they are: no path solve), or a shape (the log maps are computed at it), or None
        (the Fréchet mean is computed, with ``mean_options`` such as ``tol``).
    n_components : int, optional
        Components kept (default all: ``min(N, rank)``).
    n_steps, rcond, grid_spacing, grid_margin
        The discrete geodesics and the retained subspace.
    modes, sd
        Components whose shapes are drawn at ``sd`` standard deviations (exp map), stored in
        ``result.mode_shapes``; ``modes=()`` draws none.
    executor, chunk_size
        Where the log maps run (:mod:`shapelib.statistics.population_logs`).
    n_jobs, client, scheduler
        Or on the engine, as for :func:`shapelib.frechet_mean` (no log map, so in this process,
        when ``mean`` is a :class:`FrechetMeanResult`).

    Returns
    -------
    TangentPCAResult

    See Also
    --------
    shapelib.frechet_mean, TangentPCA

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> t = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    >>> rng = np.random.default_rng(0)
    >>> x = np.stack([np.c_[2 * np.cos(t), np.sin(t)] + 0.05 * rng.normal(size=(8, 2)) for _ in range(5)])
    >>> x = sl.pose_align(x)[0]  # the metrics depend on pose: align first
    >>> pca = sl.tangent_pca(x, sigma2=0.5, modes=(), n_jobs=1)
    >>> bool(pca.explained_variance_ratio.sum() > 0.999)
    True
    """
    x = as_shapes(shapes, name="shapes")
    if n_components is not None:
        n_components = check_positive_int(n_components, name="n_components")
    engine = dict(executor=executor, n_jobs=n_jobs, client=client, scheduler=scheduler, chunk_size=chunk_size)
    if isinstance(mean, FrechetMeanResult):
        check_where(n_jobs, client, scheduler)
        if mean.logs.shape != x.shape:
            raise ValueError(f"mean: a Fréchet mean of {mean.logs.shape[0]} shapes of shape {mean.logs.shape[1:]}, "
                             f"not of these {x.shape[0]} shapes of shape {x.shape[1:]}")
        fm, opts = mean, mean.options
        m, logs, ts = fm.mean, fm.logs, fm.tangent
    else:
        if sigma2 is None:
            raise ValueError("tangent_pca needs sigma2=... unless mean= is a FrechetMeanResult")
        opts = geodesic_options(metric, sigma2=sigma2, n_steps=n_steps, rcond=rcond, grid_spacing=grid_spacing,
                                grid_margin=grid_margin, **{k: mean_options.pop(k) for k in ("log_tol", "log_max_iter")
                                                            if k in mean_options})
        if mean is not None and mean_options:
            raise ValueError(f"options of the Fréchet mean ({', '.join(sorted(mean_options))}) given with mean=")
        if mean is None:
            fm = frechet_mean(x, metric=metric, sigma2=sigma2, n_steps=n_steps, rcond=rcond, grid_spacing=grid_spacing,
                              grid_margin=grid_margin, log_tol=opts.tol, log_max_iter=opts.max_iter, **engine,
                              **mean_options)
            m, logs, ts = fm.mean, fm.logs, fm.tangent
        else:
            fm = None
            m = as_shape(mean, name="mean")
            if m.shape != x.shape[1:]:
                raise ValueError(f"mean must have shape {x.shape[1:]}; got {m.shape}")
            check_population(x, metric=metric, sigma2=opts.sigma2, stacklevel=3)
            with where_logs_run(x, opts, base=m, rounds=1.0, **engine) as where:
                logs = np.stack([r.vector for r in population_logs(m, x, options=opts, executor=where.executor,
                                                                   chunk_size=where.chunk_size)])
            ts = tangent_space(m, options=opts)
    res = _from_logs(m, logs, ts, opts, n_components, frechet=fm)
    res.modes(tuple(j for j in modes if j < res.n_components), sd)
    return res


class TangentPCA(TransformerMixin, BaseEstimator):
    """Tangent PCA as a scikit-learn transformer (see :mod:`shapelib.statistics.tangent_pca`).

    ``X`` is (N, K·d) — flattened landmarks, as :class:`sklearn.decomposition.PCA` and ktch take
    them (``n_dim`` coordinates per landmark) — or (N, K, d).

    Parameters
    ----------
    metric : {"alpha", "fisher_rao"}
    sigma2 : float
        σ² of eq. (5): required, as by :func:`tangent_pca` (unless ``mean`` is a
        :class:`FrechetMeanResult`, which carries its own); :meth:`fit` raises ``ValueError``
        without it.
    n_components : int, optional
    n_dim : int
        Coordinates per landmark of flattened input (2 or 3).
    mean : array_like (K, d) or FrechetMeanResult, optional
        Analyse at this mean instead of computing the Fréchet mean in :meth:`fit`.
    n_steps, rcond, tol
        Discrete geodesics, retained subspace, Fréchet mean certificate.
    executor : concurrent.futures.Executor, optional
        Where the log maps of :meth:`fit` and :meth:`transform` run (default: in this process).

    Attributes
    ----------
    mean_ : ndarray (K·d,)
    components_ : ndarray (``n_components_``, K·d)
        Orthonormal in ``g(mean)`` (not in Euclidean coordinates).
    explained_variance_, explained_variance_ratio_, singular_values_ : ndarray
    n_components_ : int
    n_features_in_ : int
    result_ : TangentPCAResult

    See Also
    --------
    tangent_pca : The function it calls.
    sklearn.decomposition.PCA : The Euclidean analogue, with the same interface.

    Examples
    --------
    Flattened landmarks (8 landmarks, 16 features) in, two scores per shape out, and back:

    >>> import numpy as np
    >>> import shapelib as sl
    >>> t = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    >>> rng = np.random.default_rng(0)
    >>> x = np.stack([np.c_[2 * np.cos(t), np.sin(t)] + 0.05 * rng.normal(size=(8, 2)) for _ in range(5)])
    >>> x = sl.pose_align(x)[0]  # the metrics depend on pose: align first
    >>> from shapelib.statistics import TangentPCA
    >>> est = TangentPCA(sigma2=0.5, n_components=2)
    >>> Z = est.fit_transform(x.reshape(5, -1))
    >>> Z.shape, est.components_.shape, est.explained_variance_ratio_.round(3)
    ((5, 2), (2, 16), array([0.496, 0.298]))
    >>> bool(np.allclose(est.transform(x.reshape(5, -1)), Z, atol=1e-6))
    True
    >>> est.inverse_transform(Z[:1]).shape
    (1, 16)
    """

    def __init__(self, metric: str = "alpha", sigma2: float | None = None, n_components: int | None = None, n_dim: int = 2,
                 mean=None, n_steps: int = DEFAULT_LOG_STEPS, rcond: float = DEFAULT_RCOND, tol: float = 1e-3,
                 executor=None):
        self.metric = metric
        self.sigma2 = sigma2
        self.n_components = n_components
        self.n_dim = n_dim
        self.mean = mean
        self.n_steps = n_steps
        self.rcond = rcond
        self.tol = tol
        self.executor = executor

    def _shapes(self, X, *, fitted=True):
        arr = np.asarray(X, dtype=np.float64)
        if arr.ndim == 2:
            if self.n_dim not in (2, 3) or arr.shape[1] % self.n_dim:
                raise ValueError(f"X has {arr.shape[1]} features, not a multiple of n_dim = {self.n_dim}")
            arr = arr.reshape(len(arr), -1, self.n_dim)
        x = as_shapes(arr, name="X")
        if fitted and x.shape[1:] != self.result_.mean.shape:
            raise ValueError(f"X has landmarks of shape {x.shape[1:]}; the model was fitted on {self.result_.mean.shape}")
        return x

    def fit(self, X, y=None):
        """Fréchet mean (unless ``mean`` was given), log maps and their PCA."""
        x = self._shapes(X, fitted=False)
        sigma2 = self.sigma2
        if sigma2 is None and not isinstance(self.mean, FrechetMeanResult):
            raise ValueError("TangentPCA needs sigma2=..., as tangent_pca does (or mean=, a FrechetMeanResult, "
                             "which carries its own)")
        self.result_ = tangent_pca(x, metric=self.metric, sigma2=sigma2, mean=self.mean,
                                   n_components=self.n_components, n_steps=self.n_steps, rcond=self.rcond,
                                   executor=self.executor, n_jobs=None if self.executor is not None else 1, modes=(),
                                   **({"tol": self.tol} if self.mean is None else {}))
        r = self.result_
        self._train_scores = r.scores
        self.mean_ = r.mean.ravel()
        self.components_ = r.components.reshape(r.n_components, -1)
        self.explained_variance_ = r.explained_variance
        self.explained_variance_ratio_ = r.explained_variance_ratio
        self.singular_values_ = np.sqrt(r.explained_variance * max(len(x) - 1, 1))
        self.n_components_ = r.n_components
        self.n_features_in_ = x.shape[1] * x.shape[2]
        return self

    def fit_transform(self, X, y=None, **fit_params):
        return self.fit(X).result_.scores.copy()

    def transform(self, X):
        """Scores (N, ``n_components_``): the metric coordinates of ``log_mean(x)`` along the components."""
        check_is_fitted(self, "result_")
        r = self.result_
        x = self._shapes(X)
        logs = np.stack([res.vector for res in population_logs(r.mean, x, options=r.options,
                                                               executor=self.executor)])
        return (r.tangent.coords(logs) - r.center) @ r.axes.T

    def inverse_transform(self, X):
        """Shapes (N, K·d) with scores ``X``: ``exp_mean(Σ_j X_j c_j)`` (the exponential map)."""
        check_is_fitted(self, "result_")
        scores = np.atleast_2d(np.asarray(X, dtype=np.float64))
        if scores.shape[1] > self.n_components_:
            raise ValueError(f"X has {scores.shape[1]} scores per row; the model has {self.n_components_} components")
        return np.stack([self.result_.shape(s).ravel() for s in scores])

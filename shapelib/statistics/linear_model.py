"""Linear models on shape: Procrustes ANOVA with several factors, interactions and covariates,
tested by residual randomisation (RRPP, as geomorph's ``procD.lm`` and RRPP's ``lm.rrpp``).

The response is a matrix ``Y`` (N × p) of shape coordinates in a tangent space: the aligned
Procrustes coordinates (geomorph's choice; at small σ the information metrics' tangent space at
the mean agrees with it), or any coordinates whose Gram matrix ``Y Yᵀ`` is given — e.g. the log
maps at the Fréchet mean under the α-order or Fisher–Rao metric, whose Gram matrix in the metric
``g(mean)`` is ``FrechetMeanResult.tangent.gram(FrechetMeanResult.logs)``. Every sum of squares is
``SS(model) = ‖H_model Y‖²`` (``H`` the hat matrix of the model's design), so only ``Y Yᵀ``
matters: the same model on a distance matrix ``D`` (``G = −½ J D² J``) is PERMANOVA.

For term ``j`` with reduced model ``R_j`` and full model ``F_j`` (:data:`SS_TYPES`):

* type I (sequential): ``R_j`` = the terms before ``j``, ``F_j = R_j + j``;
* type II: ``R_j`` = every term that does not contain ``j`` (``j``'s interactions left out),
  ``F_j = R_j + j``;
* type III (marginal): ``R_j`` = all terms but ``j``, ``F_j`` = all terms;

``SS_j = ‖H_{F_j} Y‖² − ‖H_{R_j} Y‖²`` and ``F = (SS_j / df_j) / (RSS / df_res)``, RSS the full
model's residual. RRPP: permutation ``π`` gives ``Y* = H_{R_j} Y + P_π (I − H_{R_j}) Y`` (the
reduced model's fitted values plus its permuted residuals), and ``F*`` is computed from ``Y*``
in the same way, its residual that of the full model fitted to ``Y*``;
``p = (1 + #{F* ≥ F}) / (1 + n_permutations)``. With a single term the reduced model is the mean,
RRPP permutes whole rows, and the test is PERMANOVA's (Goodall's F on the Procrustes
coordinates).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .._validate import as_shapes, check_positive_int

__all__ = ["shape_lm", "ShapeLinearModel", "procrustes_coordinates", "SS_TYPES"]

#: the kinds of sums of squares :func:`shape_lm` computes
SS_TYPES = ("I", "II", "III")
_SS_WORDS = {"I": "I (sequential)", "II": "II (hierarchical)", "III": "III (marginal)"}
#: relative tolerance within which a permuted F counts as at least the observed one
TIE_RTOL = 1e-9


@dataclass
class ShapeLinearModel:
    """Result of :func:`shape_lm`.

    Attributes
    ----------
    table : pandas.DataFrame
        One row per term, then ``Residual`` and ``Total``: ``df``, ``sum_of_squares``, ``r2``,
        ``F``, ``p_value``, ``z`` (the effect size ``(log F − mean log F*) / sd log F*``, as RRPP), ``ss_type`` and
        ``reduced_model`` (the model whose residuals are permuted for the term).
    formula : str
    ss_type : {"I", "II", "III"}
    n_permutations : int
    null : dict
        ``{term: ndarray (n_permutations,)}``: the permuted F values.
    coefficients : pandas.DataFrame
        Least-squares coefficients of the full model, one row per design column, one column per
        response coordinate.
    fitted, residuals : ndarray (N, p)
        Of the full model, in the response's coordinates.

    See Also
    --------
    shape_lm : The fit and its tests.
    shapelib.statistics.allometry.AllometryResult : The one-covariate case of allometry.

    Notes
    -----
    The p-values are those of residual randomisation (RRPP) [1]_; with a single term, PERMANOVA's [2]_.

    References
    ----------
    .. [1] M. L. Collyer, D. J. Sekora and D. C. Adams, "A method for analysis of phenotypic change for phenotypes
       described by high-dimensional data", *Heredity* 115, 357–365, 2015.
    .. [2] M. J. Anderson, "A new method for non-parametric multivariate analysis of variance", *Austral
       Ecology* 26, 32–46, 2001.

    Examples
    --------
    >>> import numpy as np, pandas as pd
    >>> from shapelib.statistics.linear_model import shape_lm
    >>> rng = np.random.default_rng(1)
    >>> base = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])
    >>> shapes = base + rng.normal(scale=0.02, size=(12, 4, 2))
    >>> fit = shape_lm("~ size", pd.DataFrame({"size": rng.uniform(1, 2, 12)}), shapes, n_permutations=19)
    >>> fit.table.index.tolist(), fit.null["size"].shape, fit.fitted.shape
    (['size', 'Residual', 'Total'], (19,), (12, 8))
    """

    table: pd.DataFrame
    formula: str
    ss_type: str
    n_permutations: int
    null: dict = field(repr=False)
    coefficients: pd.DataFrame = field(repr=False)
    fitted: np.ndarray = field(repr=False)
    residuals: np.ndarray = field(repr=False)

    def summary(self) -> str:
        """The ANOVA table with the type of its sums of squares and the permutation scheme."""
        head = (f"shape ~ {self.formula.lstrip('~ ').strip()}: sums of squares type {_SS_WORDS[self.ss_type]}, "
                f"RRPP with {self.n_permutations} permutations (residuals of each term's reduced model permuted)")
        body = self.table.drop(columns=["ss_type", "reduced_model"]).to_string(float_format=lambda v: f"{v:.4g}")
        reduced = "\n".join(f"p of {t}: residuals of ~ {self.table.loc[t, 'reduced_model']} permuted"
                            for t in self.table.index[:-2])
        return "\n".join([head, body, reduced])


def procrustes_coordinates(shapes) -> np.ndarray:
    """Shapes (N, K, d) as rows of aligned Procrustes coordinates (N, K·d): generalized Procrustes
    alignment at unit centroid size, as geomorph's ``gpagen`` then ``two.d.array``.

    These are the Procrustes tangent coordinates of [1]_, aligned by generalized Procrustes
    analysis [2]_: the response of the linear models of :func:`shape_lm`.

    Parameters
    ----------
    shapes : array_like, shape (N, K, d)
        Landmark configurations, N ≥ 2.

    Returns
    -------
    ndarray, shape (N, K·d)
        One row per shape: its aligned coordinates, landmark by landmark (x₁, y₁, x₂, y₂, …).

    See Also
    --------
    shape_lm : Linear models on these coordinates.
    shapelib.geometry.procrustes.generalized_procrustes : The alignment.

    References
    ----------
    .. [1] I. L. Dryden and K. V. Mardia, *Statistical Shape Analysis*, Wiley, 1998.
    .. [2] J. C. Gower, "Generalized Procrustes analysis", *Psychometrika* 40(1), 33–51, 1975.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.statistics.linear_model import procrustes_coordinates
    >>> x = np.random.default_rng(0).normal(size=(5, 4, 2))
    >>> procrustes_coordinates(x).shape
    (5, 8)
    """
    from ..geometry.procrustes import generalized_procrustes

    x = as_shapes(shapes, name="shapes", min_shapes=2)
    aligned, _ = generalized_procrustes(x, scaling=False)
    return aligned.reshape(len(aligned), -1)


def _response(shapes, gram):
    if (shapes is None) == (gram is None):
        raise ValueError("give shapes (N, K, d) or gram (N, N), one of the two")
    if gram is None:
        y = np.asarray(shapes, dtype=np.float64)
        return procrustes_coordinates(y) if y.ndim == 3 else _finite_matrix(y, "shapes")
    g = _finite_matrix(gram, "gram")
    if g.shape[0] != g.shape[1] or not np.allclose(g, g.T, rtol=1e-10, atol=1e-12 * np.abs(g).max()):
        raise ValueError(f"gram must be a symmetric (N, N) matrix; got shape {g.shape}")
    w, v = np.linalg.eigh((g + g.T) / 2)
    keep = w > max(w.max(), 0.0) * 1e-12
    return v[:, keep] * np.sqrt(w[keep])  # coordinates with Y Yᵀ = G on its positive part


def _finite_matrix(a, name):
    a = np.asarray(a, dtype=np.float64)
    if a.ndim != 2:
        raise ValueError(f"{name} must be a 2-D array; got shape {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError(f"{name} has non-finite values")
    return a


def _basis(x):
    """Orthonormal basis of the column space of ``x`` (rank-revealing)."""
    if x.shape[1] == 0:
        return x
    u, s, _ = np.linalg.svd(x, full_matrices=False)
    return u[:, s > s.max() * 1e-10 * max(x.shape)]


def _design(formula, data):
    try:
        import formulaic
    except ImportError:
        raise ImportError("shape_lm reads formulas with formulaic: pip install 'shapelib[models]'") from None
    rhs = formula.split("~", 1)[1] if "~" in formula else formula
    try:
        mm = formulaic.model_matrix(f"~ {rhs}", data, na_action="raise")
    except Exception as exc:  # formulaic's own errors name the term; say which formula
        raise ValueError(f"formula {formula!r}: {exc}") from None
    slices = mm.model_spec.term_slices
    x = np.asarray(mm, dtype=np.float64)
    intercept = [t for t in slices if not list(t.factors) or str(t) == "1"]
    terms = [t for t in slices if t not in intercept]
    if not terms:
        raise ValueError(f"formula {formula!r} has no terms to test")
    cols = {str(t): x[:, slices[t]] for t in terms}
    factors = {str(t): {str(f) for f in t.factors} for t in terms}
    base = x[:, slices[intercept[0]]] if intercept else np.zeros((len(x), 0))
    return base, cols, factors, list(mm.columns), x


def _models(names, factors, ss_type):
    """``{term: (reduced terms, full terms)}`` for the given type of sums of squares."""
    out = {}
    for k, t in enumerate(names):
        if ss_type == "I":
            reduced = names[:k]
            full = names[:k + 1]
        elif ss_type == "II":
            reduced = [s for s in names if not factors[t] <= factors[s]]
            full = reduced + [t]
        else:
            reduced = [s for s in names if s != t]
            full = list(names)
        out[t] = (reduced, full)
    return out


def shape_lm(formula: str, data, shapes=None, *, gram=None, ss_type: str = "I", n_permutations: int = 999,
             seed: int | None = 0) -> ShapeLinearModel:
    """Procrustes ANOVA / linear model of shape on several factors, interactions and covariates,
    tested by residual randomisation (RRPP), as geomorph's ``procD.lm(shape ~ ...)``.

    Parameters
    ----------
    formula : str
        Right-hand side in Wilkinson notation, with or without the response: ``"~ genus * sex +
        log_size"`` (main effects, interaction ``genus:sex``, a continuous covariate). Read by
        formulaic; factors are treatment coded, terms ordered by degree as R does.
    data : pandas.DataFrame or dict
        The variables of the formula, one row per specimen in the order of ``shapes``.
    shapes : array_like (N, K, d) or (N, p), optional
        Landmark configurations (aligned here by generalized Procrustes, unit size: the Procrustes
        coordinates, :func:`procrustes_coordinates`) or a matrix of shape coordinates used as given.
    gram : array_like (N, N), optional
        Instead of ``shapes``: the Gram matrix ``Y Yᵀ`` of tangent coordinates centred at the mean,
        e.g. ``frechet.tangent.gram(frechet.logs)`` for the information metrics, or a Gower-centred
        distance matrix (then this is PERMANOVA).
    ss_type : {"I", "II", "III"}
        Sequential, hierarchical or marginal sums of squares (module docstring); the table says
        which, and for each term which reduced model's residuals are permuted.
    n_permutations : int
        RRPP permutations (>= 19); draw ``i`` is the ``i``-th ``rng.permutation(N)`` of
        ``numpy.random.default_rng(seed)``, shared by all terms.
    seed : int or None

    Returns
    -------
    ShapeLinearModel
        ``table`` (df, SS, R², F, p, Z, type and reduced model per term), ``summary()``, the full
        model's coefficients, fitted values and residuals.

    Notes
    -----
    ``SS_j = ‖H_{F_j} Y‖² − ‖H_{R_j} Y‖²``, ``F_j = (SS_j / df_j) / (RSS / (N − rank X))``; the
    permuted data of term ``j`` are ``H_{R_j} Y + P (I − H_{R_j}) Y`` (module docstring). This is
    the residual randomisation in a permutation procedure (RRPP) of [1]_; with one term it is
    PERMANOVA's test [2]_. The response may be the tangent coordinates of the metrics of [3]_
    (give their Gram matrix).

    See Also
    --------
    procrustes_coordinates : The default response.
    ShapeLinearModel : The result.
    shapelib.statistics.allometry.allometry : Shape on log centroid size.

    References
    ----------
    .. [1] M. L. Collyer, D. J. Sekora and D. C. Adams, "A method for analysis of phenotypic change for phenotypes
       described by high-dimensional data", *Heredity* 115, 357–365, 2015.
    .. [2] M. J. Anderson, "A new method for non-parametric multivariate analysis of variance", *Austral
       Ecology* 26, 32–46, 2001.
    .. [3] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np, pandas as pd
    >>> from shapelib.statistics.linear_model import shape_lm
    >>> rng = np.random.default_rng(0)
    >>> base = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])
    >>> group = np.repeat(["a", "b"], 10)
    >>> shapes = base + rng.normal(scale=0.02, size=(20, 4, 2))
    >>> shapes[group == "b", 2, 0] += 0.1                      # group b: one corner moved out
    >>> fit = shape_lm("~ group", pd.DataFrame({"group": group}), shapes, n_permutations=99)
    >>> bool(fit.table.loc["group", "p_value"] <= 0.05)
    True
    """
    if ss_type not in SS_TYPES:
        raise ValueError(f"ss_type must be one of {SS_TYPES}; got {ss_type!r}")
    n_permutations = check_positive_int(n_permutations, name="n_permutations")
    if n_permutations < 19:
        raise ValueError(f"n_permutations must be at least 19; got {n_permutations}")
    y = _response(shapes, gram)
    n = len(y)
    data = pd.DataFrame(data).reset_index(drop=True)
    if len(data) != n:
        raise ValueError(f"data has {len(data)} rows but there are {n} shapes")
    base, cols, factors, names_x, x = _design(formula, data)
    names = list(cols)
    q_full = _basis(x)
    df_res = n - q_full.shape[1]
    if df_res < 1:
        raise ValueError(f"no residual degrees of freedom: {n} shapes, {q_full.shape[1]} independent model columns")
    y_raw = y
    y = y - y.mean(axis=0) if base.shape[1] else y  # the intercept's part: ‖H Y‖² then counts from the mean
    models = _models(names, factors, ss_type)
    total = float(np.sum(y ** 2))
    if total == 0:
        raise ValueError("the shapes do not vary: there is nothing to model")

    def basis_of(terms):
        return _basis(np.hstack([base] + [cols[t] for t in terms])) if (terms or base.shape[1]) else np.zeros((n, 0))

    def ss_fit(q, yy):  # ‖H_q Y‖², yy (..., N, p)
        return np.sum((np.swapaxes(q, -1, -2) @ yy) ** 2, axis=(-2, -1)) if q.shape[1] else np.zeros(yy.shape[:-2])

    rss = total - float(ss_fit(q_full, y))
    rng = np.random.default_rng(seed)
    perms = np.stack([rng.permutation(n) for _ in range(n_permutations)])
    moves = np.argsort(perms, axis=1)  # draw π moves the residual of specimen i to row π(i)
    rows, null = [], {}
    for t in names:
        reduced, full = models[t]
        qr, qf = basis_of(reduced), basis_of(full)
        df_t = qf.shape[1] - qr.shape[1]
        ss_t = float(ss_fit(qf, y) - ss_fit(qr, y))
        f_obs = (ss_t / df_t) / (rss / df_res) if df_t > 0 else np.nan
        if df_t == 0:  # the term adds no column the others do not span
            raise ValueError(f"term {t} is collinear with {' + '.join(reduced) or 'the intercept'}: it adds no "
                             "independent column to the model (a covariate that repeats another, or an empty cell)")
        fitted_r = qr @ (qr.T @ y) if qr.shape[1] else np.zeros_like(y)
        resid_r = y - fitted_r
        f_null = np.empty(n_permutations)
        for start in range(0, n_permutations, 64):
            ys = fitted_r[None] + resid_r[moves[start:start + 64]]  # (P, N, p)
            tot = np.sum(ys ** 2, axis=(1, 2))
            s_t = ss_fit(qf, ys) - ss_fit(qr, ys)
            s_res = tot - ss_fit(q_full, ys)
            f_null[start:start + 64] = (s_t / df_t) / (s_res / df_res)
        p = (1.0 + np.count_nonzero(f_null >= f_obs - TIE_RTOL * abs(f_obs))) / (1.0 + n_permutations)
        sd = float(np.std(np.log(np.maximum(f_null, 1e-300)), ddof=1))
        z = (np.log(max(f_obs, 1e-300)) - float(np.mean(np.log(np.maximum(f_null, 1e-300))))) / sd if sd > 0 else np.nan
        null[t] = f_null
        rows.append({"term": t, "df": df_t, "sum_of_squares": ss_t, "r2": ss_t / total, "F": f_obs, "p_value": p,
                     "z": z, "ss_type": _SS_WORDS[ss_type], "reduced_model": " + ".join(reduced) or "1"})
    rows.append({"term": "Residual", "df": df_res, "sum_of_squares": rss, "r2": rss / total, "F": np.nan,
                 "p_value": np.nan, "z": np.nan, "ss_type": None, "reduced_model": None})
    rows.append({"term": "Total", "df": n - (1 if base.shape[1] else 0), "sum_of_squares": total, "r2": 1.0,
                 "F": np.nan, "p_value": np.nan, "z": np.nan, "ss_type": None, "reduced_model": None})
    coef, *_ = np.linalg.lstsq(x, y_raw, rcond=None)
    fitted = q_full @ (q_full.T @ y)
    return ShapeLinearModel(table=pd.DataFrame(rows).set_index("term"), formula=formula, ss_type=ss_type,
                            n_permutations=int(n_permutations), null=null,
                            coefficients=pd.DataFrame(coef, index=names_x), fitted=fitted, residuals=y - fitted)

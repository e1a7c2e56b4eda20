"""Population statistics on distance matrices: PERMANOVA with covariates, leave-one-out k-NN,
classical MDS and Mantel correlations.

The paper stops at computing shape distances ("we have yet to perform statistical comparisons on
the computed shape geodesic distances", §V). These are the comparisons, as pure functions of an
``(N, N)`` distance matrix and per-subject labels; they know nothing about shapes.

PERMANOVA (McArdle & Anderson 2001, *Ecology* 82:290). With ``A = −½ D∘D`` and the centring
matrix ``J = I − 11ᵀ/N``, Gower's centred matrix is ``G = J A J``; for Euclidean distances
``G = Y Yᵀ`` for the centred coordinates ``Y``. With the hat matrix ``H`` of a design ``X``
(intercept and covariates), the sums of squares of the linear model are traces:

* total ``SS_T = tr G = Σ_{i<j} d_ij² / N``,
* a term ``T`` added to a model ``Z``: ``SS_term = tr((H_X − H_Z) G)``,
* residual ``SS_res = tr((I − H_full) G)``,

and ``F = (SS_term / df_term) / (SS_res / df_res)``. With one factor and no covariates this is
Anderson's (2001) pseudo-F, the statistic of :func:`skbio.stats.distance.permanova`.

Permutations. ``permute="residuals"`` (default) is Freedman & Lane's (1983) scheme, the one
Anderson (2001, *Can. J. Fish. Aquat. Sci.* 58:626) recommends for a term in the presence of
covariates: the responses are replaced by ``Y* = Ŷ_Z + P R_Z Y`` (fitted values of the reduced
model plus permuted residuals), so the covariates keep their relation to the response under
every permutation and only the tested term's association is broken. The reduced model ``Z`` of
a term is the model with all the *other* terms, for ``by="margin"`` and ``by="terms"`` alike
(the two differ in the statistic, not in the null: no effect of the term given the others).
Were the reduced model of a sequential term only the terms before it, a later term with an
effect would be permuted into noise the full model cannot remove, every permuted F would be too
small, and a term without effect would be rejected in half of the data sets (issue found in
review; ``tests/test_stats.py`` checks the size of both). In Gram form the permuted statistic
needs ``E = R_Z G R_Z``, the permuted design basis and, for a sequential term (not orthogonal to
the later terms in ``Z``), the cross product ``R_Z G H_Z Q_t``; :func:`permanova` computes
them vectorised over permutations. ``permute="rows"`` permutes whole observations (the design
rows), which is exact only when no term has an effect. With an intercept-only reduced model the
two coincide (``R_Z G R_Z = G``) and equal scikit-bio's label permutation, draw for draw.

A permuted statistic counts as "at least as large" as the observed one when it is within a
relative ``1e-9`` below it (:data:`TIE_RTOL`): the permuted sums of squares are computed
differently from the observed one, so an exact tie (discrete distances, a permutation that
maps every group onto itself) can otherwise land a few units of the last place below and be
missed, making ``p`` too small — as R's vegan does with an absolute ``√ε``.

Leave-one-out k-NN uses scikit-learn's neighbour search on the precomputed matrix, and the
permutation p-value of :func:`sklearn.model_selection.permutation_test_score`; see
:func:`knn_loo_accuracy` for why the permutations re-vote instead of refitting.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .._validate import check_positive_int

__all__ = [
    "as_distance_matrix",
    "gower_centered",
    "permanova",
    "PermanovaResult",
    "knn_loo_accuracy",
    "KnnResult",
    "classical_mds",
    "mantel_test",
]

#: Relative tolerance below the observed statistic within which a permuted one still counts as a
#: tie (``F* ≥ F − TIE_RTOL · |F|``); rounding in the vectorised null is ~1e-12 relative.
TIE_RTOL = 1e-9


def as_distance_matrix(d, *, name: str = "distances", atol: float = 1e-9) -> np.ndarray:
    """Validate a distance matrix: square, finite, non-negative, zero diagonal, symmetric.

    Parameters
    ----------
    d : array_like, shape (N, N)
    name : str
        Used in error messages.
    atol : float
        Symmetry and diagonal tolerance, relative to the largest entry.

    Returns
    -------
    ndarray, float64, exactly symmetric (``(d + dᵀ) / 2``) with an exactly zero diagonal.

    Raises
    ------
    ValueError
        Naming ``name`` and the first offending entry.

    See Also
    --------
    permanova, knn_loo_accuracy, classical_mds, mantel_test : What validates its input with it.

    Examples
    --------
    Rounding noise is symmetrised away; an asymmetric matrix is refused, naming the entries:

    >>> import numpy as np
    >>> from shapelib.statistics import as_distance_matrix
    >>> D = np.array([[0.0, 1.0, 2.0], [1.0 + 1e-12, 0.0, 1.0], [2.0, 1.0, 0.0]])
    >>> out = as_distance_matrix(D)
    >>> np.array_equal(out, out.T), float(out[1, 0])
    (True, 1.0000000000005)
    >>> as_distance_matrix([[0, 1, 2], [1, 0, 1], [2, 3, 0]], name="D")
    Traceback (most recent call last):
    ...
    ValueError: D is not symmetric: [1, 2] = 1.0 but [2, 1] = 3.0 (symmetrise an asymmetric measure first)
    """
    x = np.asarray(d, dtype=np.float64)
    if x.ndim != 2 or x.shape[0] != x.shape[1]:
        raise ValueError(f"{name} must be a square (N, N) matrix; got shape {x.shape}")
    if x.shape[0] < 3:
        raise ValueError(f"{name} must hold at least 3 objects; got {x.shape[0]}")
    bad = ~np.isfinite(x)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise ValueError(f"{name}[{i}, {j}] is {float(x[i, j])}: distances must be finite")
    if (x < 0).any():
        i, j = np.argwhere(x < 0)[0]
        raise ValueError(f"{name}[{i}, {j}] = {float(x[i, j])} is negative")
    scale = max(float(x.max()), 1e-300)
    diag = np.abs(np.diag(x))
    if diag.max() > atol * scale:
        i = int(np.argmax(diag))
        raise ValueError(f"{name}[{i}, {i}] = {float(x[i, i])}: the diagonal must be zero")
    asym = np.abs(x - x.T)
    if asym.max() > atol * scale:
        i, j = np.unravel_index(int(np.argmax(asym)), asym.shape)
        raise ValueError(
            f"{name} is not symmetric: [{i}, {j}] = {float(x[i, j])} but [{j}, {i}] = {float(x[j, i])} "
            "(symmetrise an asymmetric measure first)"
        )
    out = 0.5 * (x + x.T)
    np.fill_diagonal(out, 0.0)
    return out


def gower_centered(d) -> np.ndarray:
    r"""Gower's centred matrix ``G = −½ J (D∘D) J`` (McArdle & Anderson 2001, eq. 2).

    With the centring matrix :math:`J = I - \mathbf{1}\mathbf{1}^\top / N`,

    .. math::

        G = J A J, \qquad A_{ij} = -\tfrac12 d_{ij}^2,

    so that :math:`G = Y Y^\top` for the centred coordinates :math:`Y` of Euclidean distances,
    and :math:`\operatorname{tr} G = \sum_{i<j} d_{ij}^2 / N` is the total sum of squares of
    :func:`permanova`.

    Parameters
    ----------
    d : array_like, shape (N, N)
        A distance matrix (checked by :func:`as_distance_matrix`).

    Returns
    -------
    ndarray, shape (N, N), float64
        :math:`G`, symmetric, rows and columns summing to zero.

    See Also
    --------
    permanova : Its sums of squares are traces of :math:`G`.
    classical_mds : The principal coordinates are :math:`G`'s scaled eigenvectors.

    Examples
    --------
    For Euclidean distances :math:`G` is the Gram matrix of the centred points:

    >>> import numpy as np
    >>> from scipy.spatial.distance import pdist, squareform
    >>> from shapelib.statistics import gower_centered
    >>> points = np.random.default_rng(0).normal(size=(6, 2))
    >>> G = gower_centered(squareform(pdist(points)))
    >>> Y = points - points.mean(axis=0)
    >>> bool(np.allclose(G, Y @ Y.T)), bool(np.allclose(G.sum(axis=0), 0))
    (True, True)
    """
    x = as_distance_matrix(d)
    a = -0.5 * x * x
    a -= a.mean(axis=0, keepdims=True)
    a -= a.mean(axis=1, keepdims=True)
    return a


# ---------------------------------------------------------------------------------------------
# PERMANOVA
# ---------------------------------------------------------------------------------------------


@dataclass
class PermanovaResult:
    """Result of :func:`permanova`.

    Attributes
    ----------
    table : pandas.DataFrame
        One row per term, then ``Residual`` and ``Total``; columns ``df``, ``sum_of_squares``,
        ``r2`` (``SS / SS_T``), ``pseudo_F``, ``p_value`` (NaN for Residual and Total), ``ss_type``
        (``"I (sequential)"`` or ``"III (marginal)"``: what the sum of squares and F measure) and
        ``p_tests`` (the null hypothesis the permutations give ``p_value`` for, and how they are
        made).
    notes : list of str
        Terms whose sequential F and p answer different questions (``by="terms"``): the term shares
        most of its sequential sum of squares with later terms, so F is large while ``p``, which
        tests the term given all the others, is not. :meth:`summary` prints them under the table.
    null : dict
        ``{term: ndarray (n_permutations,)}``, the permuted pseudo-F values.
    n_permutations, seed : int
    by : {"margin", "terms"}
    permute : {"residuals", "rows"}

    See Also
    --------
    permanova : What returns it.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.spatial.distance import pdist, squareform
    >>> rng = np.random.default_rng(0)
    >>> group = np.repeat(["a", "b"], 6)
    >>> points = rng.normal(size=(12, 2)) + 3.0 * (group == "b")[:, None]   # two clusters
    >>> D = squareform(pdist(points))
    >>> from shapelib.statistics import permanova
    >>> result = permanova(D, {"group": group}, n_permutations=99)
    >>> result.table.loc["group", ["df", "pseudo_F", "p_value"]].round(3).tolist()
    [1.0, 33.363, 0.01]
    >>> result.null["group"].shape
    (99,)
    >>> print(result.summary().splitlines()[0])
    PERMANOVA, 99 permutations (Freedman-Lane: residuals of the model without the term permuted); sums of squares marginal (type III)
    """

    table: pd.DataFrame
    null: dict = field(repr=False)
    n_permutations: int
    seed: int | None
    by: str
    permute: str
    notes: list = field(default_factory=list)

    def summary(self) -> str:
        """The table, the permutation scheme, and the :attr:`notes`, as text."""
        scheme = ("Freedman-Lane: residuals of the model without the term permuted" if self.permute == "residuals"
                  else "rows permuted")
        kind = "sequential (type I)" if self.by == "terms" else "marginal (type III)"
        head = f"PERMANOVA, {self.n_permutations} permutations ({scheme}); sums of squares {kind}"
        body = self.table.drop(columns=["p_tests"]).to_string(float_format=lambda v: f"{v:.4g}")
        tests = "\n".join(f"p of {t}: {self.table.loc[t, 'p_tests']}" for t in self.table.index
                          if isinstance(self.table.loc[t, "p_tests"], str))
        return "\n".join([head, body, tests, *[f"note: {n}" for n in self.notes]])



def _term_columns(col: pd.Series, term: str) -> np.ndarray:
    """Design columns of one term: treatment-coded indicators (first level dropped) for a
    categorical/boolean/string column, the centred values for a numeric one
    (scaled to unit length, which changes no sum of squares)."""
    if col.isna().any():
        row = int(np.flatnonzero(col.isna().to_numpy())[0])
        raise ValueError(f"covariate {term!r} is missing at row {row}")
    if isinstance(col.dtype, pd.CategoricalDtype) or col.dtype == bool or not pd.api.types.is_numeric_dtype(col):
        levels = sorted(pd.unique(col), key=str) if not isinstance(col.dtype, pd.CategoricalDtype) else [
            c for c in col.cat.categories if (col == c).any()]
        if len(levels) < 2:
            raise ValueError(f"covariate {term!r} has a single level {levels!r}: nothing to test")
        return np.column_stack([(col == lev).to_numpy(dtype=np.float64) for lev in levels[1:]])
    v = col.to_numpy(dtype=np.float64)
    if not np.all(np.isfinite(v)):
        row = int(np.flatnonzero(~np.isfinite(v))[0])
        raise ValueError(f"covariate {term!r} is {float(v[row])} at row {row}")
    if np.ptp(v) == 0:
        raise ValueError(f"covariate {term!r} is constant: nothing to test")
    c = v - v.mean()
    return (c / np.linalg.norm(c))[:, None]  # unit length: the collinearity test is scale-free


def _extend_basis(basis: np.ndarray, block: np.ndarray, term: str) -> np.ndarray:
    """Orthonormal basis of the part of ``block``'s column space orthogonal to ``basis``."""
    r = block - basis @ (basis.T @ block)
    u, s, _ = np.linalg.svd(r, full_matrices=False)
    keep = s > 1e-10 * max(1.0, float(np.linalg.norm(block)))
    if not keep.any():
        raise ValueError(f"term {term!r} is collinear with the terms before it (no degrees of freedom left)")
    return u[:, keep]


def _quadratic_by_column(e: np.ndarray, q: np.ndarray, perms: np.ndarray, chunk: int = 64) -> np.ndarray:
    """``c[p, k] = q[π_p]_kᵀ E q[π_p]_k`` for every permutation ``π_p`` (rows of ``perms``)."""
    out = np.empty((len(perms), q.shape[1]))
    for start in range(0, len(perms), chunk):
        qp = q[perms[start:start + chunk]]  # (P, N, k): rows of the basis permuted
        out[start:start + chunk] = np.einsum("pnk,pnk->pk", qp, np.matmul(e, qp))
    return out


def permanova(distances, covariates, *, terms=None, by: str = "margin", permute: str = "residuals",
              n_permutations: int = 999, seed: int | None = 0) -> PermanovaResult:
    r"""Multi-term PERMANOVA on a distance matrix (McArdle & Anderson 2001; R vegan's ``adonis2``).

    Parameters
    ----------
    distances : array_like, shape (N, N)
        Symmetric distance matrix with zero diagonal.
    covariates : pandas.DataFrame or dict of 1-D arrays
        One column per term, rows in the order of ``distances``. Categorical, boolean and
        string columns are treatment coded (first level in sorted order is the baseline);
        numeric columns enter as one centred column (its units do not matter).
    terms : sequence of str, optional
        Terms in model order (default: all columns of ``covariates``).
    by : {"margin", "terms"}
        ``"margin"``: each term's sum of squares given all the other terms (type III,
        "accounted for the others"); ``"terms"``: sequentially in the given order (type I, given
        the terms before it), as R vegan's ``adonis2``. Every F uses the full model's residual,
        and either way the permutations are those of the model without the term (module
        docstring), so both test "no effect of the term given the others".
    permute : {"residuals", "rows"}
        ``"residuals"``: Freedman–Lane, permute the residuals of the reduced model (see the module
        docstring); ``"rows"``: permute whole observations (exact only if no term has an effect).
    n_permutations : int
        Number of random permutations (``>= 1``); ``p = (1 + #{F* ≥ F}) / (1 + n_permutations)``,
        ties counted within :data:`TIE_RTOL`.
    seed : int or None
        Seed of :func:`numpy.random.default_rng`; permutation ``p`` is the ``p``-th call to
        ``rng.permutation(N)``, the draws scikit-bio makes, shared by all terms. Draw ``π`` gives
        row ``i`` the design row ``π(i)`` (``"rows"``), or, equivalently for the residuals, moves
        the reduced-model residual of object ``i`` to row ``π(i)`` (``"residuals"``).

    Returns
    -------
    PermanovaResult
        ``table`` (per term: ``df``, ``sum_of_squares``, ``r2``, ``pseudo_F``, ``p_value``),
        ``null`` (the permuted pseudo-F of each term) and ``summary()``.

    Notes
    -----
    With Gower's centred matrix :math:`G` (:func:`gower_centered`), the hat matrices
    :math:`H_X` of the design with the term and :math:`H_Z` of the reduced model without it,
    and :math:`H` of the full model,

    .. math::

        F = \frac{\operatorname{tr}\big((H_X - H_Z) G\big) / \mathrm{df}_\text{term}}
                 {\operatorname{tr}\big((I - H) G\big) / \mathrm{df}_\text{res}},
        \qquad
        p = \frac{1 + \#\{F^* \ge F\}}{1 + n_\text{permutations}}.

    See Also
    --------
    permanova_sweep : The same test over several matrices, with a family-wise adjustment.
    gower_centered : The matrix whose traces are the sums of squares.

    Examples
    --------
    Two clusters of points, their Euclidean distances, and a covariate without effect:

    >>> import numpy as np
    >>> from scipy.spatial.distance import pdist, squareform
    >>> rng = np.random.default_rng(0)
    >>> group = np.repeat(["a", "b"], 6)
    >>> points = rng.normal(size=(12, 2)) + 3.0 * (group == "b")[:, None]   # two clusters
    >>> D = squareform(pdist(points))
    >>> from shapelib.statistics import permanova
    >>> age = rng.uniform(20, 60, size=12)
    >>> result = permanova(D, {"group": group, "age": age}, n_permutations=99)
    >>> result.table.loc[["group", "age"], "df"].tolist()
    [1, 1]
    >>> p = result.table["p_value"]
    >>> bool(p["group"] <= 0.05), bool(p["age"] > 0.05)
    (True, True)
    """
    d = as_distance_matrix(distances)
    n = len(d)
    if by not in ("margin", "terms"):
        raise ValueError(f"by must be 'margin' or 'terms'; got {by!r}")
    if permute not in ("residuals", "rows"):
        raise ValueError(f"permute must be 'residuals' or 'rows'; got {permute!r}")
    n_permutations = check_positive_int(n_permutations, name="n_permutations")
    cov = pd.DataFrame(covariates)
    if len(cov) != n:
        raise ValueError(f"covariates have {len(cov)} rows but distances are {n} x {n}")
    cov = cov.reset_index(drop=True)
    terms = list(cov.columns if terms is None else terms)
    if not terms:
        raise ValueError("no terms to test")
    missing = [t for t in terms if t not in cov.columns]
    if missing:
        raise ValueError(f"terms {missing} are not columns of covariates {list(cov.columns)}")
    if len(set(terms)) != len(terms):
        raise ValueError(f"terms repeated: {terms}")
    blocks = {t: _term_columns(cov[t], t) for t in terms}
    one = np.full((n, 1), 1.0 / np.sqrt(n))

    # orthonormal bases: sequential in model order (also gives the full model's residual space)
    seq = {}
    basis = one
    for t in terms:
        seq[t] = _extend_basis(basis, blocks[t], t)
        basis = np.hstack([basis, seq[t]])
    full = basis
    df_res = n - full.shape[1]
    if df_res < 1:
        raise ValueError(f"no residual degrees of freedom: {n} objects, {full.shape[1]} model columns")

    g = gower_centered(d)
    ss_total = float(np.trace(g))
    if ss_total == 0:
        raise ValueError("distances are all zero: there is no variation to test")
    ss_res = ss_total - float(np.einsum("nk,nk->", full, g @ full))
    rng = np.random.default_rng(seed)
    perms = np.stack([rng.permutation(n) for _ in range(n_permutations)])

    rows, null, notes = [], {}, []
    for t in terms:
        # Z: all the other terms (the Freedman–Lane reduced model, for both kinds of test)
        qz = one
        for s in terms:
            if s != t:
                qz = np.hstack([qz, _extend_basis(qz, blocks[s], s)])
        if by == "terms":  # the term given those before it; full = its basis + the others'
            qt = seq[t]
            q_all = np.hstack([qt] + [one] + [seq[s] for s in terms if s != t])
        else:  # the term given all the others
            qt = _extend_basis(qz, blocks[t], t)
            q_all = np.hstack([qt, qz])
        df_t = qt.shape[1]
        ss_t = float(np.einsum("nk,nk->", qt, g @ qt))
        f_obs = (ss_t / df_t) / (ss_res / df_res)
        # Y* = H_Z Y + Pᵀ R_Z Y: Q_tᵀ Y* = (H_Z Q_t)ᵀ Y + (P Q_t)ᵀ R_Z Y, so
        # SS_t* = ‖·‖² of H_Z Q_t (fixed) + 2 ⟨P Q_t, R_Z G H_Z Q_t⟩ + (P Q_t)ᵀ E (P Q_t);
        # H_Z Q_t = 0 for a marginal term. The residual: R_full H_Z = 0, so only E enters.
        if permute == "residuals":
            rz = np.eye(n) - qz @ qz.T
            e = rz @ g @ rz
            hq = qz @ (qz.T @ qt)
            fixed = float(np.einsum("nk,nk->", hq, g @ hq))
            cross = 2.0 * np.einsum("pnk,nk->p", qt[perms], rz @ (g @ hq))
        else:
            e, fixed, cross = g, 0.0, 0.0
        c = _quadratic_by_column(e, q_all, perms)
        s_t = fixed + cross + c[:, :df_t].sum(axis=1)
        s_res = np.trace(e) - c.sum(axis=1)
        f_null = (s_t / df_t) / (s_res / df_res)
        p = (1.0 + np.count_nonzero(f_null >= f_obs - TIE_RTOL * abs(f_obs))) / (1.0 + n_permutations)
        null[t] = f_null
        others = [s for s in terms if s != t]
        given = f"given {' + '.join(others)}" if others else "(no other terms)"
        tests = (f"no effect of {t} {given} (residuals of the model without {t} permuted)" if permute == "residuals"
                 else "no effect of any term (whole rows permuted)")
        rows.append({"term": t, "df": df_t, "sum_of_squares": ss_t, "r2": ss_t / ss_total,
                     "pseudo_F": f_obs, "p_value": p,
                     "ss_type": "I (sequential)" if by == "terms" else "III (marginal)", "p_tests": tests})
        later = terms[terms.index(t) + 1:]
        if by == "terms" and permute == "residuals" and later and ss_t > 0:
            qm = _extend_basis(qz, blocks[t], t)  # the term given all the others
            ss_own = float(np.einsum("nk,nk->", qm, g @ qm))
            if ss_own < 0.5 * ss_t:
                notes.append(
                    f"{t}: F = {f_obs:.4g} is {t} given the terms before it, p = {p:.3g} tests {t} given all the "
                    f"others; {1 - ss_own / ss_t:.0%} of its sequential sum of squares is shared with "
                    f"{' + '.join(later)}, which is why they disagree: a large F with a large p means the effect is "
                    f"not {t}'s own (by='margin' gives F and p of the same question; permute='rows' tests no effect "
                    f"of any term)")
    rows.append({"term": "Residual", "df": df_res, "sum_of_squares": ss_res, "r2": ss_res / ss_total,
                 "pseudo_F": np.nan, "p_value": np.nan, "ss_type": None, "p_tests": None})
    rows.append({"term": "Total", "df": n - 1, "sum_of_squares": ss_total, "r2": 1.0,
                 "pseudo_F": np.nan, "p_value": np.nan, "ss_type": None, "p_tests": None})
    table = pd.DataFrame(rows).set_index("term")
    return PermanovaResult(table=table, null=null, n_permutations=int(n_permutations), seed=seed, by=by,
                           permute=permute, notes=notes)


# ---------------------------------------------------------------------------------------------
# Leave-one-out k-NN
# ---------------------------------------------------------------------------------------------


@dataclass
class KnnResult:
    """Result of :func:`knn_loo_accuracy`.

    Attributes
    ----------
    accuracy : float
        Leave-one-out accuracy of the k-NN classifier.
    p_value : float
        ``(1 + #{accuracy* ≥ accuracy}) / (1 + n_permutations)`` over label permutations.
    null : ndarray, shape (n_permutations,)
        Accuracies with permuted labels.
    majority_rate : float
        Share of the most frequent class (what always guessing it scores).
    predictions : ndarray, shape (N,)
        Leave-one-out predicted label of each object.
    n_neighbors, n_permutations : int

    See Also
    --------
    knn_loo_accuracy : What returns it.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.spatial.distance import pdist, squareform
    >>> rng = np.random.default_rng(0)
    >>> group = np.repeat(["a", "b"], 6)
    >>> points = rng.normal(size=(12, 2)) + 3.0 * (group == "b")[:, None]   # two clusters
    >>> D = squareform(pdist(points))
    >>> from shapelib.statistics import knn_loo_accuracy
    >>> result = knn_loo_accuracy(D, group, n_neighbors=3, n_permutations=99)
    >>> result.accuracy, result.p_value, result.majority_rate
    (1.0, 0.01, 0.5)
    >>> result.predictions[:3], result.null.shape
    (array(['a', 'a', 'a'], dtype='<U1'), (99,))
    """

    accuracy: float
    p_value: float
    null: np.ndarray = field(repr=False)
    majority_rate: float
    predictions: np.ndarray = field(repr=False)
    n_neighbors: int
    n_permutations: int



def knn_loo_accuracy(distances, labels, *, n_neighbors: int = 5, n_permutations: int = 999,
                     seed: int | None = 0) -> KnnResult:
    r"""Leave-one-out k-nearest-neighbour accuracy on a precomputed distance matrix, with a
    label-permutation p-value.

    The statistic is exactly that of ``permutation_test_score(KNeighborsClassifier(n_neighbors,
    metric="precomputed"), D, labels, cv=LeaveOneOut(), n_permutations=n_permutations,
    random_state=seed)`` — the same accuracy and the same permuted accuracies, draw for draw
    (``tests/test_stats.py``) — as long as no two distances tie at the k-th neighbour: such ties
    are broken arbitrarily, here once for the whole matrix and by scikit-learn in every fold, so
    the two may pick different neighbours (both legitimate; observed and permuted labels here
    always vote with the same neighbours). That call refits the classifier N times per permutation (about
    3 s per permutation for N = 647 here, an hour for 999). The leave-one-out neighbours do not
    depend on the labels, so they are found once, with scikit-learn's own query
    (``KNeighborsClassifier.kneighbors()`` without ``X``: each training point's neighbours,
    itself excluded), and every permutation only re-votes (uniform weights; a tied vote goes
    to the first class in sorted order, as ``KNeighborsClassifier.predict`` does).

    Parameters
    ----------
    distances : array_like, shape (N, N)
    labels : array_like, shape (N,)
        Class of each object (any sortable values).
    n_neighbors : int
        ``k`` (use an odd ``k`` with two classes to avoid tied votes).
    n_permutations : int
        Number of label permutations (``>= 1``).
    seed : int or None
        Seed of :class:`numpy.random.RandomState`, as ``permutation_test_score``'s ``random_state``.

    Returns
    -------
    KnnResult
        ``accuracy``, its permutation ``p_value`` and ``null``, the ``majority_rate`` and each
        object's leave-one-out ``predictions``.

    Notes
    -----
    With :math:`\hat y_{-i}` the majority label of object :math:`i`'s ``k`` nearest other
    objects and :math:`a^*` the accuracies of permuted labels,

    .. math::

        a = \frac1N \sum_{i=1}^N [\hat y_{-i} = y_i], \qquad
        p = \frac{1 + \#\{a^* \ge a\}}{1 + n_\text{permutations}}.

    See Also
    --------
    knn_sweep : The same over several matrices, with a family-wise adjustment.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.spatial.distance import pdist, squareform
    >>> rng = np.random.default_rng(0)
    >>> group = np.repeat(["a", "b"], 6)
    >>> points = rng.normal(size=(12, 2)) + 3.0 * (group == "b")[:, None]   # two clusters
    >>> D = squareform(pdist(points))
    >>> from shapelib.statistics import knn_loo_accuracy
    >>> result = knn_loo_accuracy(D, group, n_neighbors=3, n_permutations=99)
    >>> result.accuracy, result.p_value
    (1.0, 0.01)
    """
    from sklearn.neighbors import KNeighborsClassifier

    d = as_distance_matrix(distances)
    n = len(d)
    y = np.asarray(labels)
    if y.shape != (n,):
        raise ValueError(f"labels must have shape ({n},) to match distances; got {y.shape}")
    if pd.isna(pd.Series(y)).any():
        raise ValueError(f"labels are missing at row {int(np.flatnonzero(pd.isna(pd.Series(y)))[0])}")
    if int(n_neighbors) != n_neighbors or not 1 <= n_neighbors < n - 1:
        raise ValueError(f"n_neighbors must be an integer in [1, {n - 2}]; got {n_neighbors!r}")
    n_permutations = check_positive_int(n_permutations, name="n_permutations")
    classes, codes = np.unique(y, return_inverse=True)
    if len(classes) < 2:
        raise ValueError(f"labels have a single class {classes.tolist()}: nothing to classify")
    neigh = KNeighborsClassifier(n_neighbors=int(n_neighbors), metric="precomputed").fit(d, codes).kneighbors(
        return_distance=False)

    def accuracies(ys):  # ys: (P, N) label codes
        votes = ys[:, neigh]  # (P, N, k)
        counts = np.stack([(votes == c).sum(axis=-1) for c in range(len(classes))], axis=-1)
        pred = counts.argmax(axis=-1)  # first class among ties
        return (pred == ys).mean(axis=1), pred

    acc, pred = accuracies(codes[None])
    rs = np.random.RandomState(seed)
    null = np.concatenate([accuracies(codes[np.stack([rs.permutation(n) for _ in range(m)])])[0]
                           for m in np.diff(np.r_[0:n_permutations:256, n_permutations])])
    p = (1.0 + np.count_nonzero(null >= acc[0])) / (1.0 + n_permutations)
    return KnnResult(accuracy=float(acc[0]), p_value=float(p), null=null,
                     majority_rate=float(np.bincount(codes).max() / n), predictions=classes[pred[0]],
                     n_neighbors=int(n_neighbors), n_permutations=int(n_permutations))


# ---------------------------------------------------------------------------------------------
# Ordination and matrix correlation
# ---------------------------------------------------------------------------------------------


def classical_mds(distances, *, n_components: int = 2):
    r"""Classical (Torgerson) MDS / principal coordinates of a distance matrix (scikit-learn).

    The coordinates are the leading eigenvectors :math:`v_k` of Gower's centred matrix
    :math:`G` (:func:`gower_centered`) scaled by the square roots of their eigenvalues,

    .. math::

        G v_k = \lambda_k v_k, \qquad 	ext{coords}_{:, k} = \sqrt{\lambda_k}\, v_k, \qquad
        	ext{explained}_k = \lambda_k / \operatorname{tr} G.

    Parameters
    ----------
    distances : array_like, shape (N, N)
        A distance matrix (checked by :func:`as_distance_matrix`).
    n_components : int
        Axes to return, between 1 and ``N − 1`` (and at most the number of positive
        eigenvalues).

    Returns
    -------
    coords : ndarray, shape (N, n_components)
    explained : ndarray, shape (n_components,)
        Each axis' eigenvalue of Gower's matrix over its trace (the total inertia
        ``Σ_{i<j} d_ij² / N``, as scikit-bio's ``pcoa``). For non-Euclidean distances the trace
        is the positive eigenvalues' sum *minus* the negative ones', so these shares are larger
        than the axes' shares of the positive inertia (and may add up to more than 1): compare
        metrics' shares only for (near-)Euclidean distances.

    Raises
    ------
    ValueError
        If the distances are all zero, or ``n_components`` exceeds the number of positive
        eigenvalues (a Euclidean embedding has no more axes).

    See Also
    --------
    gower_centered : The matrix it diagonalises.

    Examples
    --------
    Euclidean distances of planar points are reproduced exactly by two axes:

    >>> import numpy as np
    >>> from scipy.spatial.distance import pdist, squareform
    >>> from shapelib.statistics import classical_mds
    >>> points = np.random.default_rng(0).normal(size=(8, 2)) * [3.0, 1.0]
    >>> D = squareform(pdist(points))
    >>> coords, explained = classical_mds(D, n_components=2)
    >>> coords.shape, bool(np.allclose(squareform(pdist(coords)), D)), round(float(explained.sum()), 6)
    ((8, 2), True, 1.0)
    """
    from sklearn.manifold import ClassicalMDS

    d = as_distance_matrix(distances)
    n_components = check_positive_int(n_components, name="n_components")
    if n_components >= len(d):
        raise ValueError(f"n_components must be an integer in [1, {len(d) - 1}]; got {n_components!r}")
    total = float(np.sum(d * d) / (2 * len(d)))
    if total == 0:
        raise ValueError("distances are all zero: there is nothing to ordinate")
    mds = ClassicalMDS(n_components=n_components, metric="precomputed")
    with np.errstate(invalid="ignore"):  # √ of a non-positive eigenvalue: refused just below
        coords = mds.fit_transform(d)
    eig = np.asarray(mds.eigenvalues_, dtype=np.float64)  # the largest n_components, descending
    n_pos = int(np.count_nonzero(eig > 1e-12 * eig[0]))
    if n_components > n_pos:
        raise ValueError(f"n_components = {n_components} but Gower's matrix has only {n_pos} positive "
                         "eigenvalues: ask for at most that many axes")
    return coords, eig / total


def mantel_test(x, y, *, method: str = "spearman", n_permutations: int = 999, seed: int | None = 0):
    r"""Mantel correlation between two distance matrices over the same objects (scikit-bio).

    Parameters
    ----------
    x, y : array_like, shape (N, N)
    method : {"spearman", "pearson"}
        Spearman (default) compares the rankings of the pairs, insensitive to monotone
        transformations such as squaring a distance.
    n_permutations : int
    seed : int or None

    Returns
    -------
    r : float
        Correlation of the upper-triangle entries.
    p_value : float
        Two-sided permutation p-value (objects permuted in one matrix).

    Notes
    -----
    The statistic is the correlation of the upper-triangle entries,
    :math:`r = \operatorname{corr}\big((x_{ij})_{i<j}, (y_{ij})_{i<j}\big)` (of their ranks for
    Spearman), and :math:`p = (1 + \#\{|r^*| \ge |r|\}) / (1 + n_\text{permutations})` over
    simultaneous permutations of the rows and columns of ``x``.

    See Also
    --------
    permanova : Distances against covariates rather than another matrix.

    Examples
    --------
    Squaring a distance keeps the ranking of the pairs, so Spearman's correlation is 1:

    >>> import numpy as np
    >>> from scipy.spatial.distance import pdist, squareform
    >>> from shapelib.statistics import mantel_test
    >>> D = squareform(pdist(np.random.default_rng(0).normal(size=(8, 2))))
    >>> r, p = mantel_test(D, D ** 2, n_permutations=99)
    >>> round(r, 12), p <= 0.05
    (1.0, True)
    """
    try:
        from skbio.stats.distance import mantel
    except ImportError:
        raise ImportError("mantel_test runs scikit-bio's Mantel test: pip install scikit-bio "
                          "(it comes with the study extra, pip install 'shapelib[study]')") from None

    a = as_distance_matrix(x, name="x")
    b = as_distance_matrix(y, name="y")
    if a.shape != b.shape:
        raise ValueError(f"x is {a.shape} but y is {b.shape}")
    if method not in ("spearman", "pearson"):
        raise ValueError(f"method must be 'spearman' or 'pearson'; got {method!r}")
    n_permutations = check_positive_int(n_permutations, name="n_permutations")
    iu = np.triu_indices(len(a), 1)
    for name, m in (("x", a), ("y", b)):
        if np.ptp(m[iu]) == 0:
            raise ValueError(f"{name} has all off-diagonal distances equal ({float(m[iu][0])}): "
                             "its correlation with anything is undefined")
    r, p, _ = mantel(a, b, method=method, permutations=n_permutations, alternative="two-sided", seed=seed)
    return float(r), float(p)

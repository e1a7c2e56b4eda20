"""The closed-form lower bounds of a whole population as matrix products.

Both lower bounds the library certifies geodesic distances with are inner products of functions
of one shape each, so the N × N matrix of a population is a handful of matrix products instead
of N(N − 1)/2 separate pairs.

α-order bound (eq. 22's metric is the pull-back of L²; :func:`shapelib.geometry.gmm.l2_distance`)
    ``‖p_i − p_j‖² = ⟨p_i, p_i⟩ + ⟨p_j, p_j⟩ − 2⟨p_i, p_j⟩`` with the closed-form overlap
    ``⟨p_i, p_j⟩ = (4πσ²)^{-d/2} / K² · Σ_ab g(x_ia − x_jb)``, ``g(z) = exp(−|z|²/4σ²)``. The self
    terms are one per shape, so a pair costs its K² cross Gaussians. Shapes of a population are
    close, though, and that difference cancels: at the study's scale the squared distance is
    typically 10⁻³ of ``⟨p_i, p_i⟩`` and down to 10⁻⁸ (:mod:`shapelib.geometry.gmm`, "Near
    shapes"). So the overlaps are taken around a reference shape ``m`` (the mean landmarks):
    with ``q = p − p_m`` and offsets ``δ = x − m``,
    ``‖p_i − p_j‖² = ‖q_i‖² + ‖q_j‖² − 2⟨q_i, q_j⟩``, where

        (K² (4πσ²)^{d/2}) ⟨q_i, q_j⟩ = Σ_ab A_i,ab B_j,ab − Σ_ab g(x_ia − x_jb) expm1(−δ_ia·δ_jb / 2σ²)

    is the sum of the mixed second differences of ``g`` around ``r = m_a − m_b`` (``A``, ``B``:
    ``√g(r)`` times ``expm1`` of per-shape exponents; :func:`_alpha_factors`). The first sum is one
    matrix product (N × K² by K² × N); the second is the K² cross Gaussians of each pair, each
    times one ``expm1``. The squared distances come from one small product per block of shapes,
    ``[x, |x|², 1]·[2y, −1, −|y|²] = −|x − y|²`` (coordinates centred on the population), then one
    ``exp`` and one ``expm1`` pass and two sums: about four times a bare ``numpy.exp`` of the same
    count (``benchmarks/bench_pairwise.py`` measures both). Now the difference cancels only as far
    as two shapes are closer to each other than to ``m``: the pairs where it has cancelled more
    than one digit (:data:`ALPHA_NEAR_CENTRED`) are recomputed pair by pair without any
    cancellation, exactly as :func:`~shapelib.geometry.gmm.l2_distance` does. The expansion needs
    every landmark within √2 σ of ``m`` (beyond, the two sums grow like ``exp(|δ|²/2σ²)`` and
    cancel each other); pairs with a shape further out — at small σ, most of them — use the plain
    overlaps, which at such σ barely cancel (:data:`ALPHA_NEAR_PLAIN`). Either way the result
    agrees with :func:`~shapelib.geometry.gmm.l2_distance` to ~1e-13 relative
    (``tests/test_bound_matrices.py`` asks 1e-12).

Fisher–Rao bound (``2√p`` on the sphere of radius 2; :func:`shapelib.solver.geodesic.fisher_rao_lower_bound`)
    ``4 arcsin(‖ψ_i − ψ_j‖ / 4)``, ``ψ = 2√p``, by the trapezoid rule on one grid covering every
    shape (:func:`shapelib.geometry.quadrature.make_grid`): with ``S`` the N × M matrix of ψ at the
    M nodes and ``w`` the node weight, ``‖ψ_i − ψ_j‖² = w (S Sᵀ)_ii + w (S Sᵀ)_jj − 2 w (S Sᵀ)_ij``.
    On the tensor grid each shape's density is a product of per-axis factors, so a row of ``S``
    is itself one matrix product ``F_x F_yᵀ`` (2-D; 3-D: ``(F_x ⊙ F_y) F_zᵀ``), and ``S Sᵀ`` is one
    symmetric rank-M update (BLAS ``syrk``), accumulated over chunks of nodes so the memory stays
    ``O(N · chunk)``. Pairs whose squared distance is below :data:`FR_NEAR` of ``‖ψ_i‖² + ‖ψ_j‖²``
    (where the difference would keep fewer than ~10 digits) are summed again directly as
    ``w Σ (ψ_i − ψ_j)²``, which is how the per-pair function computes every pair.

    Agreement with the per-pair function. The per-pair bound integrates on the grid fitted to
    its two shapes; the grid here is the same lattice (nodes are multiples of the step, anchored
    at the origin) extended to cover every shape, so the two sums differ only by nodes more than
    ``grid_margin`` σ from both shapes of the pair, where the integrand is below
    ``e^{-margin²/2}`` of its peak. Measured on ADHD-200 pairs (centroid size 20, default grid):
    the two agree to 4e-11 (σ² = 0.007), 2e-9 (σ² = 1.2) and 4e-8 (σ² = 17, where the pair's
    margin is as wide as the shapes); that is the per-pair function's own quadrature error,
    both being within 5e-8 of a finer grid (step 0.2 σ, margin 9 σ). ``tests/test_bound_matrices.py``
    asks 1e-7.

    The grid must stay bounded: it covers every shape, so shapes that do not share their extent
    (not aligned, or in pixel coordinates far apart) ask for far more nodes than any of their
    pairs. :func:`shapelib.geometry.quadrature.make_grid` refuses a grid above its limit with a
    ``ValueError`` saying what to change; the engine (:mod:`shapelib.pairwise`) then computes that
    block pair by pair, on the pairs' own grids.

σ² sweeps
    :func:`bound_matrix_sweep` computes a bound's matrix for a list of σ² values. The α bound
    reuses each block's squared distances across the values (only the exponentials change);
    the Fisher–Rao grid scales with σ (step ``grid_spacing · σ``), so nothing carries over and
    each value is one :func:`fisher_rao_bound_matrix` (its cost grows like σ^{-d}: the small-σ
    end dominates a sweep).

Where each bound lives
    One implementation per bound and scale. One pair: the α bound is
    :func:`shapelib.geometry.gmm.l2_distance` (:func:`shapelib.solver.geodesic.alpha_lower_bound`
    adds the entry checks of a geodesic), the Fisher–Rao bound
    :meth:`shapelib.solver.path_metric.FisherRaoPathMetric.lower_bound`
    (:func:`shapelib.solver.geodesic.fisher_rao_lower_bound`); :func:`shapelib.solver.bracket.lower_bound`
    picks one by metric name. Many pairs: :func:`alpha_bound_block` and :func:`fisher_rao_bound_block`
    here (``cols=None``: the symmetric matrix, which :func:`alpha_bound_matrix` and
    :func:`fisher_rao_bound_matrix` name), the ``block`` function of the ``"alpha_bound"`` and
    ``"fisher_rao_bound"`` records of :mod:`shapelib.distances` (:data:`BLOCKS`, which
    :func:`bound_block` dispatches on); :func:`bound_matrix_sweep` for many σ².

Threads. ``n_threads`` (default: every core this process may use) runs blocks of rows on a
thread pool — ``numpy.exp`` and BLAS release the GIL — with BLAS on one thread inside each, so
the pool does not oversubscribe the cores. The pairwise engine passes ``n_threads=1`` inside its
single-threaded Dask workers.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from threadpoolctl import threadpool_limits

from .._validate import as_shapes, check_positive_int, check_sigma2
from .gmm import NEAR_DISPLACEMENT, _l2_sq_near, _small_displacement
from .quadrature import DEFAULT_MARGIN, DEFAULT_SPACING, make_grid

__all__ = ["alpha_bound_matrix", "alpha_bound_block", "fisher_rao_bound_matrix", "fisher_rao_bound_block",
           "bound_matrix_sweep", "bound_block", "BOUND_METRICS", "FR_NEAR"]

#: the metric names (:mod:`shapelib.distances`) computed here
BOUND_METRICS = ("alpha_bound", "fisher_rao_bound")
#: Fisher–Rao pairs with ``‖ψ_i − ψ_j‖²`` below this fraction of ``‖ψ_i‖² + ‖ψ_j‖²`` are summed again as
#: ``w Σ (ψ_i − ψ_j)²`` (the Gram form keeps ~16 − log10(1/FR_NEAR) − 2 digits: ≳ 1e-10 relative)
FR_NEAR = 1e-4
#: α pairs whose squared distance is below this fraction of ``‖q_i‖² + ‖q_j‖²`` (centred form, ``q = p − p_m``)
#: or of ``‖p_i‖² + ‖p_j‖²`` (plain form) are recomputed pair by pair without cancellation. Measured on
#: ADHD-200 pairs (σ² from 0.007 to 17): relative error of the squared distance ≤ 2e-14 / ratio
#: (centred) and ≤ 2e-14 / ratio (plain, at the smallest σ, where ``|x|² + |y|² − 2x·y`` costs digits
#: of exponents of order extent²/σ²), so both keep the distance within ~1e-13 of the exact value
ALPHA_NEAR_CENTRED = 0.1
ALPHA_NEAR_PLAIN = 0.05
#: α blocks: rows × columns of shapes per exponential pass (``(2K) × (16K)`` Gaussians, ~1 MB for
#: K = 50: the block stays in cache through its passes; measured best of 1–8 × 8–128 on ADHD-200)
_ALPHA_ROWS, _ALPHA_COLS = 2, 16
#: Fisher–Rao: grid nodes per chunk of the ψ matrix (N × chunk doubles), built this many shapes at a time
_FR_CHUNK_NODES = 8192
_FR_SHAPES = 128


# ---------------------------------------------------------------------------------------------
# Shared
# ---------------------------------------------------------------------------------------------


def _threads(n_threads) -> int:
    if n_threads is None:
        try:
            return max(1, len(os.sched_getaffinity(0)))
        except AttributeError:  # pragma: no cover - not Linux
            return os.cpu_count() or 1
    return check_positive_int(n_threads, name="n_threads")


def _run(tasks, n_threads):
    """Run the callables ``tasks`` on ``n_threads`` threads (BLAS on one thread inside each)."""
    with threadpool_limits(limits=1, user_api="blas"):
        if n_threads <= 1 or len(tasks) <= 1:
            for t in tasks:
                t()
            return
        with ThreadPoolExecutor(max_workers=n_threads) as pool:
            for f in [pool.submit(t) for t in tasks]:
                f.result()


def _pair_of_sets(rows, cols):
    """``rows``, ``cols`` as ``(R, K, d)``, ``(C, K, d)`` float64 arrays with the same K and d."""
    x = as_shapes(rows, name="rows")
    y = x if cols is None else as_shapes(cols, name="cols")
    if x.shape[1:] != y.shape[1:]:
        raise ValueError(f"rows and cols must have the same (K, d); got {x.shape[1:]} and {y.shape[1:]}")
    return x, y


def _sigma2s(sigma2s) -> np.ndarray:
    values = np.atleast_1d(np.asarray(sigma2s, dtype=np.float64)) if not np.isscalar(sigma2s) else None
    if values is None or values.ndim != 1 or values.size == 0:
        raise ValueError(f"sigma2s must be a non-empty 1-D sequence of positive numbers; got {sigma2s!r}")
    return np.array([check_sigma2(s) for s in values])


# ---------------------------------------------------------------------------------------------
# α bound: ‖p_i − p_j‖
# ---------------------------------------------------------------------------------------------


def _alpha_block_sums(x, y, dx, dy, s2s, *, triangle, naive, n_threads):
    """Per σ² (``s``), over every landmark pair of rows ``x`` (R, K, d) and columns ``y`` (C, K, d):

    ``t2[s, i, j] = Σ_ab g(x_ia − y_jb) expm1(−δx_ia·δy_jb / 2σ²)`` and, where ``naive[s]``,
    ``plain[s, i, j] = Σ_ab g(x_ia − y_jb)``, with ``g(z) = exp(−|z|²/4σ²)`` and ``δ`` the
    landmarks' offsets from the reference shape. ``triangle``: ``x is y``, only ``j ≥ i`` is filled.
    The squared distances and offset products of a block are computed once for all the σ².
    """
    r, k, d = x.shape
    c = len(y)
    single = len(s2s) == 1
    # one σ²: the scales go into the coordinates (two passes fewer); a sweep scales per value
    sx = np.sqrt(0.25 / s2s[0]) if single else 1.0
    sd = np.sqrt(0.5 / s2s[0]) if single else 1.0
    fx, fy = sx * x.reshape(-1, d), sx * y.reshape(-1, d)
    nx, ny = np.einsum("nd,nd->n", fx, fx), np.einsum("nd,nd->n", fy, fy)
    # [x, |x|², 1]·[2y, −1, −|y|²] = 2 x·y − |x|² − |y|² = −|x − y|²: one product, no extra passes
    fx = np.column_stack([fx, nx, np.ones_like(nx)])
    fy2 = np.column_stack([2.0 * fy, -np.ones_like(ny), -ny])
    ex, ey = -sd * dx.reshape(-1, d), sd * dy.reshape(-1, d)  # ex·ey = −δx·δy (/ 2σ²)
    scales = 0.25 / s2s
    t2 = np.zeros((len(s2s), r, c))
    plain = np.zeros((len(s2s), r, c)) if naive.any() else None

    def reduce(buf, i0, i1, j0, j1):
        part = buf.reshape(i1 - i0, k, -1).sum(axis=1)  # (rows, cols·K)
        return part.reshape(i1 - i0, j1 - j0, k).sum(axis=2)

    def rows(chunks):
        shape = (_ALPHA_ROWS * k, _ALPHA_COLS * k)
        bufs = [np.empty(shape) for _ in range(2 if single else 4)]  # reused: no allocation per block
        for i0, i1 in chunks:
            xi, ei = fx[i0 * k:i1 * k], ex[i0 * k:i1 * k]
            for j0 in range(i0 if triangle else 0, c, _ALPHA_COLS):
                j1 = min(c, j0 + _ALPHA_COLS)
                sq, dd, *work = (b[:(i1 - i0) * k, :(j1 - j0) * k] for b in bufs)
                np.matmul(xi, fy2[j0 * k:j1 * k].T, out=sq)  # −|x − y|²
                np.matmul(ei, ey[j0 * k:j1 * k].T, out=dd)  # −δx·δy
                for s, scale in enumerate(scales):
                    if single:
                        gauss, other = sq, dd
                    else:
                        gauss, other = work
                        np.multiply(sq, scale, out=gauss)
                        np.multiply(dd, 2.0 * scale, out=other)
                    np.exp(gauss, out=gauss)
                    if naive[s]:
                        plain[s, i0:i1, j0:j1] = reduce(gauss, i0, i1, j0, j1)
                    with np.errstate(over="ignore", invalid="ignore"):  # only pairs that use `plain`
                        np.expm1(other, out=other)
                        other *= gauss
                    t2[s, i0:i1, j0:j1] = reduce(other, i0, i1, j0, j1)

    # rows in chunks of _ALPHA_ROWS, grouped into ~4 tasks per thread, interleaved so the
    # triangle's long and short rows are shared out evenly
    chunks = [(i, min(r, i + _ALPHA_ROWS)) for i in range(0, r, _ALPHA_ROWS)]
    n_tasks = min(len(chunks), 4 * n_threads)
    tasks = [lambda part=chunks[t::n_tasks]: rows(part) for t in range(n_tasks)]
    _run(tasks, n_threads)
    return t2, plain


def _alpha_factors(ref, delta, s2):
    """The separable half of the mixed second differences, ``(N, K²)`` each:
    ``A_i,ab = √g(r_ab) expm1(α_i,ab)`` and ``B_j,ab = √g(r_ab) expm1(β_j,ab)``, ``r = m_a − m_b``,
    ``α = −(2r + δ_a)·δ_a / 4σ²``, ``β = (2r − δ_b)·δ_b / 4σ²``. Bounded by e^{1/2} when
    ``|δ|² ≤ 2σ²`` (the exponent is at most ``|δ|²/4σ²``); rows of other shapes are not used."""
    c = 0.25 / s2
    rr = ref[:, None, :] - ref[None, :, :]
    half = np.exp(-0.5 * c * np.einsum("abd,abd->ab", rr, rr))
    lin = 2.0 * np.einsum("abd,nad->nab", rr, delta)  # 2 r_ab·δ_a
    own = np.einsum("nad,nad->na", delta, delta)
    with np.errstate(over="ignore", invalid="ignore"):
        a = half * np.expm1(np.minimum(-c * (lin + own[:, :, None]), 700.0))
        lin = 2.0 * np.einsum("abd,nbd->nab", rr, delta)  # 2 r_ab·δ_b
        b = half * np.expm1(np.minimum(c * (lin - own[:, None, :]), 700.0))
    n = len(delta)
    return a.reshape(n, -1), b.reshape(n, -1)


def _alpha_self(x, delta, ref, s2s):
    """Per σ² and shape: ``⟨p_i, p_i⟩`` and ``⟨p_i − p_m, p_i − p_m⟩`` up to ``(4πσ²)^{-d/2} / K²``."""
    n, k, d = x.shape
    plain, cent = np.empty((len(s2s), n)), np.empty((len(s2s), n))
    for s0 in range(0, n, 256):
        blk, dl = x[s0:s0 + 256], delta[s0:s0 + 256]
        diff = blk[:, :, None, :] - blk[:, None, :, :]
        sq = np.einsum("nabd,nabd->nab", diff, diff)
        dd = np.einsum("nad,nbd->nab", dl, dl)
        for s, s2 in enumerate(s2s):
            gauss = np.exp(sq * (-0.25 / s2))
            plain[s, s0:s0 + 256] = gauss.sum(axis=(1, 2))
            a, b = _alpha_factors(ref, dl, s2)
            with np.errstate(over="ignore", invalid="ignore"):
                cent[s, s0:s0 + 256] = np.einsum("nm,nm->n", a, b) - (gauss * np.expm1(dd * (-0.5 / s2))).sum(
                    axis=(1, 2))
    return plain, cent


def _alpha_matrices(x, y, s2s, *, n_threads):
    """α bound matrices ``(S, R, C)`` of rows ``x`` against columns ``y`` (``y is None``: symmetric).

    For two shapes near a reference shape ``m`` (the mean landmarks), ``q = p − p_m`` is small and
    ``‖p_i − p_j‖² = ‖q_i‖² + ‖q_j‖² − 2⟨q_i, q_j⟩`` cancels only as far as the two shapes are closer
    to each other than to ``m``. ``⟨q_i, q_j⟩`` sums, over landmark pairs, the mixed second
    differences of :mod:`shapelib.geometry.gmm` ("Near shapes") around ``r = m_a − m_b`` with
    steps ``δ_i,a`` and ``−δ_j,b``: ``Σ_ab A_i,ab B_j,ab − Σ_ab g(x_ia − x_jb) expm1(−δ_ia·δ_jb / 2σ²)``,
    a matrix product and one more exponential per Gaussian. This needs every landmark within
    √2 σ of the reference; pairs with a shape further out use the plain overlaps. Pairs where
    either form has cancelled too many digits (:data:`ALPHA_NEAR_CENTRED`, :data:`ALPHA_NEAR_PLAIN`) are
    recomputed pair by pair without cancellation, as :func:`~shapelib.geometry.gmm.l2_distance` does.
    """
    triangle = y is None
    y = x if triangle else y
    both = x if triangle else np.concatenate([x, y])
    origin = both.reshape(-1, both.shape[2]).mean(axis=0)
    x0, y0 = x, y  # as given: the pairs recomputed one by one use these (centring would round the
    x, y = x - origin, y - origin  # landmark displacements); centred: |x|² + |y|² − 2x·y keeps its digits
    ref = both.mean(axis=0)
    # offsets from the uncentred shapes: x0 − ref is exact for landmarks near the reference (Sterbenz),
    # (x0 − origin) − (ref − origin) rounds them to ~1e-16 of the coordinates
    dx, dy = x0 - ref, y0 - ref
    ref = ref - origin
    r, k, d = x.shape
    reach_x = np.einsum("nkd,nkd->nk", dx, dx).max(axis=1)
    reach_y = reach_x if triangle else np.einsum("nkd,nkd->nk", dy, dy).max(axis=1)
    ok_x = reach_x[None, :] <= NEAR_DISPLACEMENT * s2s[:, None]  # (S, R)
    ok_y = reach_y[None, :] <= NEAR_DISPLACEMENT * s2s[:, None]
    naive = ~ok_x.all(axis=1) | ~ok_y.all(axis=1)
    t2, plain = _alpha_block_sums(x, y, dx, dy, s2s, triangle=triangle, naive=naive, n_threads=n_threads)
    px, cx = _alpha_self(x, dx, ref, s2s)
    py, cy = (px, cx) if triangle else _alpha_self(y, dy, ref, s2s)
    out = np.empty_like(t2)
    upper = np.triu(np.ones((r, len(y)), dtype=bool), 1) if triangle else None
    for s, s2 in enumerate(s2s):
        norm = (4 * np.pi * s2) ** (-d / 2) / k ** 2
        ax, _ = _alpha_factors(ref, np.where(ok_x[s][:, None, None], dx, 0.0), s2)
        _, by = _alpha_factors(ref, np.where(ok_y[s][:, None, None], dy, 0.0), s2)
        with threadpool_limits(limits=n_threads, user_api="blas"):
            cross = ax @ by.T - t2[s]
        scale = np.where(ok_x[s][:, None] & ok_y[s][None, :], 1.0, 0.0)
        total = norm * np.where(scale > 0, cx[s][:, None] + cy[s][None, :], px[s][:, None] + py[s][None, :])
        if plain is not None and naive[s]:
            cross = np.where(scale > 0, cross, plain[s])
        sq = total - 2 * norm * cross
        near = sq <= np.where(scale > 0, ALPHA_NEAR_CENTRED, ALPHA_NEAR_PLAIN) * total
        if upper is not None:
            near &= upper
        i, j = np.nonzero(near)
        if len(i):
            keep = _small_displacement(x0[i], y0[j], s2)
            i, j = i[keep], j[keep]
            for s0 in range(0, len(i), 4096):
                sl = slice(s0, s0 + 4096)
                sq[i[sl], j[sl]] = _l2_sq_near(x0[i[sl]], y0[j[sl]], s2)
        out[s] = np.sqrt(np.maximum(sq, 0.0))
        if upper is not None:
            out[s] = np.where(upper, out[s], 0.0)
            out[s] += out[s].T
    return out


def alpha_bound_matrix(shapes, *, sigma2, n_threads: int | None = None) -> np.ndarray:
    r"""All pairwise α-order lower bounds ``‖p_i − p_j‖`` of a population (eqs. 5, 22).

    The α-order metric of eq. (22) is the pull-back of the flat L² metric on densities [1]_, so the
    L² distance of two shapes' mixtures (eq. 5) bounds their geodesic distance from below:

    .. math::

        D_{ij} = \|p_i - p_j\|_{L^2} \le d_\alpha(x_i, x_j).

    Equal, pair by pair, to :func:`shapelib.l2_distance` (to ~1e-13 relative; see the module
    docstring for how), computed as blocks of Gaussian overlaps.

    Parameters
    ----------
    shapes : array_like, shape (N, K, d)
        The population, landmarks in correspondence (aligned: the bound depends on pose).
    sigma2 : float, keyword-only
        σ² > 0 of eq. (5).
    n_threads : int, optional
        Threads (default: every core available to the process).

    Returns
    -------
    ndarray, shape (N, N)
        Symmetric, zero diagonal.

    Raises
    ------
    ValueError
        If ``shapes`` is not a finite ``(N, K, d)`` array, ``sigma2`` is not positive or
        ``n_threads`` is not a positive integer.

    See Also
    --------
    shapelib.l2_distance : The same bound for one pair.
    shapelib.fisher_rao_bound_matrix : The Fisher–Rao counterpart.
    shapelib.bound_matrix_sweep : The matrix for several σ² at once.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> rng = np.random.default_rng(0)
    >>> square = 2.0 * np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> shapes = square + 0.1 * rng.standard_normal((3, 4, 2))
    >>> m = sl.alpha_bound_matrix(shapes, sigma2=0.5)
    >>> m.round(4)
    array([[0.    , 0.0326, 0.0254],
           [0.0326, 0.    , 0.0306],
           [0.0254, 0.0306, 0.    ]])
    >>> bool(np.isclose(m[0, 1], sl.l2_distance(shapes[0], shapes[1], sigma2=0.5)))
    True
    """
    x = as_shapes(shapes, name="shapes")
    return _alpha_matrices(x, None, np.array([check_sigma2(sigma2)]), n_threads=_threads(n_threads))[0]


def alpha_bound_block(rows, cols=None, *, sigma2, n_threads: int | None = None) -> np.ndarray:
    r"""The ``(R, C)`` block of α bounds ``‖p_i − p_j‖`` between two sets of shapes.

    A block of :func:`~shapelib.alpha_bound_matrix` (blocks assemble to the
    full matrix): what the pairwise engine hands a worker. Each entry is the closed-form L² distance
    of eq. (5)'s mixtures, the lower bound on the α-order distance of eq. (22) [1]_:

    .. math::

        B_{rc} = \|p(\cdot \mid x_r) - p(\cdot \mid y_c)\|_{L^2}.

    Parameters
    ----------
    rows : array_like, shape (R, K, d)
        Shapes of the block's rows.
    cols : array_like, shape (C, K, d), optional
        (default None: ``rows`` with itself, the symmetric matrix with a zero diagonal)
        Shapes of its columns (same K and d).
    sigma2 : float, keyword-only
        σ² > 0 of eq. (5).
    n_threads : int, optional
        Threads (default: every core available to the process).

    Returns
    -------
    ndarray, shape (R, C)
        The bounds.

    Raises
    ------
    ValueError
        If the sets differ in K or d, are not finite, or ``sigma2`` is not positive.

    See Also
    --------
    shapelib.alpha_bound_matrix : The symmetric matrix of one population.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> from shapelib.geometry.bound_matrices import alpha_bound_block
    >>> rng = np.random.default_rng(0)
    >>> shapes = 2.0 * np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]) + 0.1 * rng.standard_normal((3, 4, 2))
    >>> block = alpha_bound_block(shapes[:1], shapes[1:], sigma2=0.5)
    >>> block.shape, bool(np.allclose(block, sl.alpha_bound_matrix(shapes, sigma2=0.5)[:1, 1:]))
    ((1, 2), True)
    """
    x, y = _pair_of_sets(rows, cols)
    return _alpha_matrices(x, None if cols is None else y, np.array([check_sigma2(sigma2)]),
                           n_threads=_threads(n_threads))[0]


# ---------------------------------------------------------------------------------------------
# Fisher–Rao bound: 4 arcsin(‖ψ_i − ψ_j‖ / 4), ψ = 2√p, on one grid
# ---------------------------------------------------------------------------------------------


def _axis_factor(x, ax, i, s2):
    """``exp(−(node − x_ai)² / 2σ²)`` at the nodes ``ax`` of axis ``i``: ``(N, len(ax), K)``."""
    return np.exp(-((ax[None, :, None] - x[:, None, :, i]) ** 2) * (0.5 / s2))


def _psi_chunks(x, grid, s2):
    """Yield ``(start, ψ)`` with ψ = 2√p of every shape of ``x`` at a run of grid nodes, ``(N, chunk)``.

    The nodes are the grid's C-order tensor product; each chunk is a range of the first axis, and
    its rows are built a few shapes at a time, so the memory is ``O(N · chunk)`` whatever the grid.
    Far from every landmark the product of factors underflows to 0: ψ there is below 1e-150 and
    its share of the integrals below 1e-300.
    """
    n, k, d = x.shape
    axes = grid.axes
    scale = 4.0 * (2 * np.pi * s2) ** (-d / 2) / k  # ψ² = 4 p
    inner = int(np.prod([len(a) for a in axes[1:]]))
    step = max(1, _FR_CHUNK_NODES // inner)
    for a0 in range(0, len(axes[0]), step):
        a1 = min(len(axes[0]), a0 + step)
        psi = np.empty((n, (a1 - a0) * inner))
        for s0 in range(0, n, _FR_SHAPES):
            xs = x[s0:s0 + _FR_SHAPES]
            first = _axis_factor(xs, axes[0][a0:a1], 0, s2)  # (ns, c, K)
            last = _axis_factor(xs, axes[-1], d - 1, s2).transpose(0, 2, 1)  # (ns, K, n_last)
            if d == 3:  # (F_x ⊙ F_y) F_zᵀ
                first = (first[:, :, None, :] * _axis_factor(xs, axes[1], 1, s2)[:, None, :, :]).reshape(
                    len(xs), -1, k)
            psi[s0:s0 + len(xs)] = np.matmul(first, last).reshape(len(xs), -1)
        np.multiply(psi, scale, out=psi)
        np.sqrt(psi, out=psi)
        yield a0 * inner, psi


def _fr_grid(x, y, s2, spacing, margin):
    points = x if y is None else np.concatenate([x, y])
    return make_grid(points, sigma2=s2, grid_spacing=spacing, grid_margin=margin)


def _fr_matrix(x, y, s2, *, spacing, margin, n_threads):
    """Fisher–Rao bounds of rows ``x`` against columns ``y`` (``None``: symmetric, ``x`` with itself)."""
    grid = _fr_grid(x, y, s2, spacing, margin)
    if len(grid.axes) != x.shape[2]:  # pragma: no cover - make_grid always builds a tensor grid
        raise ValueError("the Fisher-Rao bound matrix needs a tensor-product grid")
    both = x if y is None else np.concatenate([x, y])
    r = len(x)
    gram = np.zeros((len(both), len(both))) if y is None else np.zeros((r, len(y)))
    norms = np.zeros(len(both))

    def accumulate(start, psi):
        norms[:] += np.einsum("nm,nm->n", psi, psi)
        if y is None:
            gram[:] += psi @ psi.T  # numpy calls syrk for a @ a.T
        else:
            gram[:] += psi[:r] @ psi[r:].T

    with threadpool_limits(limits=n_threads, user_api="blas"):
        for start, psi in _psi_chunks(both, grid, s2):
            accumulate(start, psi)
    w = grid.weight
    nx, ny = w * norms[:r], w * norms[r:] if y is not None else w * norms
    sq = nx[:, None] + ny[None, :] - 2 * w * gram
    near = sq <= FR_NEAR * (nx[:, None] + ny[None, :])
    if y is None:
        near &= np.triu(np.ones(near.shape, dtype=bool), 1)
    i, j = np.nonzero(near)
    if len(i):  # the direct sum w Σ (ψ_i − ψ_j)², one more pass over the nodes
        direct = np.zeros(len(i))
        jj = j if y is None else j + r
        for _, psi in _psi_chunks(both, grid, s2):
            for s in range(0, len(i), 2048):
                diff = psi[i[s:s + 2048]] - psi[jj[s:s + 2048]]
                direct[s:s + 2048] += np.einsum("pm,pm->p", diff, diff)
        sq[i, j] = w * direct
    out = 4.0 * np.arcsin(np.minimum(np.sqrt(np.maximum(sq, 0.0)) / 4.0, 1.0))
    if y is None:
        out = np.triu(out, 1)
        out += out.T
    return out


def _check_grid_options(grid_spacing, grid_margin):
    from .._validate import check_positive

    return check_positive(grid_spacing, name="grid_spacing"), check_positive(grid_margin, name="grid_margin")


def fisher_rao_bound_matrix(shapes, *, sigma2, grid_spacing: float = DEFAULT_SPACING,
                            grid_margin: float = DEFAULT_MARGIN, n_threads: int | None = None) -> np.ndarray:
    r"""All pairwise Fisher–Rao lower bounds ``2 arccos ∫ √(p_i p_j) dx`` of a population (eqs. 5, 6).

    The Fisher–Rao metric of eq. (6) is the pull-back of the L² metric by :math:`\theta \mapsto
    2\sqrt{p}`, which maps onto the sphere of radius 2 [1]_ [2]_; no path of mixtures is shorter than
    the great circle:

    .. math::

        D_{ij} = 2 \arccos \int \sqrt{p_i\, p_j}\, dx
        = 4 \arcsin\frac{\|\psi_i - \psi_j\|}{4} \le d_{FR}(x_i, x_j), \qquad \psi = 2\sqrt{p}.

    The great-circle bound of :func:`shapelib.fisher_rao_lower_bound` for every pair, as one Gram
    matrix of ψ on a grid covering all the shapes (module docstring: how, and how closely it agrees
    with the per-pair function).

    Parameters
    ----------
    shapes : array_like, shape (N, K, d)
        d = 2 or 3. Shapes that share their extent (aligned, e.g. :func:`shapelib.to_centroid_size`)
        keep the common grid as small as one pair's.
    sigma2 : float, keyword-only
        σ² > 0 of eq. (5).
    grid_spacing : float, default 0.35
        Quadrature step in units of σ (:mod:`shapelib.geometry.quadrature`).
    grid_margin : float, default 6.0
        Quadrature margin beyond the shapes, in units of σ.
    n_threads : int, optional
        BLAS threads (default: every core available to the process).

    Returns
    -------
    ndarray, shape (N, N)
        Symmetric, zero diagonal, values in [0, π].

    Raises
    ------
    ValueError
        Bad shapes or options, or a grid above ``shapelib.geometry.quadrature.MAX_ENTRIES``
        nodes × landmarks (the message says what to change).

    See Also
    --------
    shapelib.fisher_rao_lower_bound : The same bound for one pair.
    shapelib.alpha_bound_matrix : The closed-form α-order counterpart.
    shapelib.bound_matrix_sweep : The matrix for several σ² at once.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.
    .. [2] S. Amari and H. Nagaoka, *Methods of Information Geometry*, American Mathematical Society and
       Oxford University Press, 2000.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> rng = np.random.default_rng(0)
    >>> square = 2.0 * np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> shapes = square + 0.1 * rng.standard_normal((3, 4, 2))
    >>> m = sl.fisher_rao_bound_matrix(shapes, sigma2=0.5)
    >>> m.round(3)
    array([[0.   , 0.203, 0.144],
           [0.203, 0.   , 0.187],
           [0.144, 0.187, 0.   ]])
    """
    x = as_shapes(shapes, name="shapes")
    spacing, margin = _check_grid_options(grid_spacing, grid_margin)
    return _fr_matrix(x, None, check_sigma2(sigma2), spacing=spacing, margin=margin,
                      n_threads=_threads(n_threads))


def fisher_rao_bound_block(rows, cols=None, *, sigma2, grid_spacing: float = DEFAULT_SPACING,
                           grid_margin: float = DEFAULT_MARGIN, n_threads: int | None = None) -> np.ndarray:
    r"""The ``(R, C)`` block of Fisher–Rao bounds between two sets of shapes, on one grid covering both.

    What the pairwise engine hands a worker; each entry is the great-circle bound of eq. (6)'s
    metric [1]_,

    .. math::

        B_{rc} = 2 \arccos \int \sqrt{p(x \mid x_r)\, p(x \mid y_c)}\, dx.

    Parameters
    ----------
    rows : array_like, shape (R, K, d)
        Shapes of the block's rows.
    cols : array_like, shape (C, K, d), optional
        (default None: ``rows`` with itself, the symmetric matrix with a zero diagonal)
        Shapes of its columns (same K and d).
    sigma2 : float, keyword-only
        σ² > 0 of eq. (5).
    grid_spacing : float, default 0.35
        Quadrature step in units of σ.
    grid_margin : float, default 6.0
        Quadrature margin in units of σ.
    n_threads : int, optional
        BLAS threads (default: every core available to the process).

    Returns
    -------
    ndarray, shape (R, C)
        The bounds.

    Raises
    ------
    ValueError
        Bad shapes or options, or a grid too large (as
        :func:`~shapelib.fisher_rao_bound_matrix`).

    See Also
    --------
    shapelib.fisher_rao_bound_matrix : The symmetric matrix of one population.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> from shapelib.geometry.bound_matrices import fisher_rao_bound_block
    >>> rng = np.random.default_rng(0)
    >>> shapes = 2.0 * np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]) + 0.1 * rng.standard_normal((3, 4, 2))
    >>> block = fisher_rao_bound_block(shapes[:1], shapes[1:], sigma2=0.5)
    >>> block.shape, bool(np.allclose(block, sl.fisher_rao_bound_matrix(shapes, sigma2=0.5)[:1, 1:], rtol=1e-7))
    ((1, 2), True)
    """
    x, y = _pair_of_sets(rows, cols)
    spacing, margin = _check_grid_options(grid_spacing, grid_margin)
    return _fr_matrix(x, None if cols is None else y, check_sigma2(sigma2), spacing=spacing, margin=margin,
                      n_threads=_threads(n_threads))


# ---------------------------------------------------------------------------------------------
# Entry points for the engine and for σ² sweeps
# ---------------------------------------------------------------------------------------------


def bound_block(metric: str, rows, cols=None, *, n_threads: int | None = None, **params) -> np.ndarray:
    r"""A closed-form bound between ``rows`` and ``cols``, by the metric's name.

    ``metric`` is one of ``BOUND_METRICS``: ``"alpha_bound"``, the L² distance
    :math:`\|p_i - p_j\|` (eq. 22's bound), or ``"fisher_rao_bound"``, the great circle
    :math:`2\arccos\int\sqrt{p_i p_j}\,dx` (eq. 6's bound) [1]_. ``cols=None`` gives ``rows``
    with itself, the symmetric matrix.

    Parameters
    ----------
    metric : {"alpha_bound", "fisher_rao_bound"}
        Which bound.
    rows : array_like, shape (R, K, d)
        Shapes of the rows.
    cols : array_like, shape (C, K, d), optional
        Shapes of the columns; ``None``: ``rows`` with itself.
    n_threads : int, optional
        Threads (default: every core available to the process).
    **params
        The metric's options: ``sigma2``; Fisher–Rao also ``grid_spacing``, ``grid_margin``.

    Returns
    -------
    ndarray, shape (R, C) or (R, R)
        The bounds.

    Raises
    ------
    ValueError
        For an unknown ``metric``, or what the bound's own function raises.

    See Also
    --------
    shapelib.alpha_bound_matrix, shapelib.fisher_rao_bound_matrix

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> from shapelib.geometry.bound_matrices import bound_block
    >>> rng = np.random.default_rng(0)
    >>> shapes = 2.0 * np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]) + 0.1 * rng.standard_normal((3, 4, 2))
    >>> bool(np.array_equal(bound_block("alpha_bound", shapes, sigma2=0.5),
    ...                     sl.alpha_bound_matrix(shapes, sigma2=0.5)))
    True
    """
    try:
        block = BLOCKS[metric]
    except (KeyError, TypeError):
        raise ValueError(f"metric must be one of {BOUND_METRICS}; got {metric!r}") from None
    return block(rows, cols, n_threads=n_threads, **params)


def bound_matrix_sweep(shapes, *, metric: str, sigma2s, grid_spacing: float = DEFAULT_SPACING,
                       grid_margin: float = DEFAULT_MARGIN, n_threads: int | None = None) -> np.ndarray:
    r"""A bound's matrix for every σ² of ``sigma2s``: ``out[s]`` is the matrix at ``sigma2s[s]``.

    Equal to calling :func:`shapelib.alpha_bound_matrix` or :func:`shapelib.fisher_rao_bound_matrix`
    once per value; the α bound computes each block's squared landmark distances once for all the
    values (only the exponentials change with σ²). For each σ² the matrix holds

    .. math::

        \|p_i - p_j\|_{L^2} \quad \text{(eq. 22's bound)} \qquad \text{or} \qquad
        2 \arccos \int \sqrt{p_i\, p_j}\, dx \quad \text{(eq. 6's bound)}

    of the mixtures of eq. (5) at that σ² [1]_: what choosing σ² from data needs.

    Parameters
    ----------
    shapes : array_like, shape (N, K, d)
        The population, landmarks in correspondence.
    metric : {"alpha_bound", "fisher_rao_bound"}, keyword-only
        Which bound.
    sigma2s : sequence of float, keyword-only
        σ² values (eq. 5), each > 0.
    grid_spacing : float, default 0.35
        Fisher–Rao quadrature step in units of σ.
    grid_margin : float, default 6.0
        Fisher–Rao quadrature margin in units of σ.
    n_threads : int, optional
        Threads (default: every core available to the process).

    Returns
    -------
    ndarray, shape (len(sigma2s), N, N)
        One symmetric, zero-diagonal matrix per σ².

    Raises
    ------
    ValueError
        For an unknown ``metric``, an empty or non-positive ``sigma2s``, or bad shapes.

    See Also
    --------
    shapelib.alpha_bound_matrix, shapelib.fisher_rao_bound_matrix
    shapelib.estimate_sigma2 : The σ² of the landmarks' own scatter.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> rng = np.random.default_rng(0)
    >>> shapes = 2.0 * np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]) + 0.1 * rng.standard_normal((3, 4, 2))
    >>> out = sl.bound_matrix_sweep(shapes, metric="alpha_bound", sigma2s=[0.1, 0.5, 1.5])
    >>> out.shape, bool(np.allclose(out[1], sl.alpha_bound_matrix(shapes, sigma2=0.5)))
    ((3, 3, 3), True)
    """
    x = as_shapes(shapes, name="shapes")
    s2s = _sigma2s(sigma2s)
    n_threads = _threads(n_threads)
    if metric == "alpha_bound":
        return _alpha_matrices(x, None, s2s, n_threads=n_threads)
    if metric == "fisher_rao_bound":
        spacing, margin = _check_grid_options(grid_spacing, grid_margin)
        return np.stack([_fr_matrix(x, None, s2, spacing=spacing, margin=margin, n_threads=n_threads)
                         for s2 in s2s])
    raise ValueError(f"metric must be one of {BOUND_METRICS}; got {metric!r}")


#: the block function of each closed-form bound (what its :class:`shapelib.distances.MetricInfo` carries)
BLOCKS = {"alpha_bound": alpha_bound_block, "fisher_rao_bound": fisher_rao_bound_block}

"""Many non-rigid registrations at once: :func:`register_many`, one by one through
:func:`shapelib.register` (``backend="numpy"``) or batched over pairs and starts in one JAX array
program (``backend="jax"``: the GPU when JAX sees one, else the CPU).

The batched path is the search of :mod:`shapelib.pointsets._nonrigid` with the equations of
:mod:`shapelib.pointsets._coherent_em`, rewritten as array code over a batch of fits:

1. **Padding.** The normalised sets of a batch of pairs are padded to the batch's largest ``n``
   and ``m`` (rounded up to a multiple of 8, or above 256 points by
   :func:`shapelib.solver.batched.bucket`, so that a few compiled programs serve every size). A padded target point has no Gaussian term (``P_ij = 0`` for every
   ``i``: it takes no posterior and adds nothing to the objective); a padded source point has
   ``P_ij = 0`` for every ``j``, so ``P1_i = 0``, ``B_i = 0`` and its coefficient ``W_i = 0``. The
   outlier term, the mean of the start σ² and the log-likelihood use the true ``n``, ``m`` and
   bounding box of each pair.
2. **Kernel.** ``G_ab = exp(−|u_a − u_b|²/4σ_g²)`` (zero rows and columns at padded points) is
   factored per pair by a batched ``eigh``; eigenvalues below ``EIG_RTOL`` of the largest are dropped
   as in :class:`~shapelib.pointsets._coherent_em.Kernel` (their columns set to zero, their
   eigenvalue to 1, which leaves the Woodbury M-step exact), and the factor is cut to the batch's
   largest kept rank.
3. **EM.** Every fit (a pair × a start rotation × an outlier weight) iterates E-step, Woodbury
   M-step and σ² update in a ``lax.while_loop`` under ``vmap``: a fit that has met its tolerance (or
   ``max_iter``) is frozen while the others go on: ``PLAIN_ITER`` EM iterations, then the cycles of
   :func:`~shapelib.pointsets._coherent_em.run_em`'s acceleration (two EM iterations, SQUAREM's
   extrapolation and one iteration from it, kept if the objective did not increase), each pass of
   a second loop one cycle: all three iterations computed and the cycle's outcome selected, so that
   a fit stops where the compiled loop stops. Screening runs ``SCREEN_ITER`` iterations from every
   start at ``W_SCREEN`` with the kernel truncated at ``SCREEN_EIG_RTOL`` (more columns zero); the
   ``N_KEEP`` starts of least objective (chosen on the host, stable order, as
   :func:`~shapelib.pointsets._nonrigid.fit_all` does) and the source as given (start 0; its fits
   dropped on the host where it is one of them) are fitted at every weight of the grid with the full
   kernel: at ``W_SCREEN`` by continuing the screening's EM from the same means, at the others from
   the start.
4. **Results.** The fits go back to the host as
   :class:`~shapelib.pointsets._coherent_em.EMState` objects, their objectives with the price on the
   pose's rotation added there (:func:`~shapelib.pointsets._nonrigid.with_pose_prior`), and each pair's
   :class:`~shapelib.RegistrationResult` is assembled by the same numpy code as :func:`register`'s
   (reliability, pose, correspondences, warnings).

Everything runs in float64 (JAX's 64-bit mode, enabled for these calls only, as the batched
geodesics do); JAX is imported on first use.
"""

from __future__ import annotations

import functools
import time

import numpy as np

from .._validate import check_nonnegative, check_positive, check_positive_int
from ..geometry import _jax_kernels as jk
from ..solver.batched import DEVICES, bucket, jax_device
from ._coherent_em import EIG_RTOL, PLAIN_ITER, EMState, Kernel, box_volume
from ._nonrigid import (N_KEEP, POSE_PRIOR, SCREEN_EIG_RTOL, SCREEN_ITER, W_GRID, W_SCREEN, ranked, start_rotations,
                        with_pose_prior)
from .checks import as_point_set
from .registration import (MAX_POINTS, SIGMA2_FLOOR, _check_w, _nonrigid_frame, _nonrigid_result, deformation_energy,
                           register)

__all__ = ["register_many", "REGISTER_MANY_BACKENDS"]

#: the values of ``backend=`` of :func:`register_many`
REGISTER_MANY_BACKENDS = ("numpy", "jax")
#: options of :func:`register` that ``backend="jax"`` runs only at their defaults
_JAX_DEFAULTS = {"metric": "alpha", "kernel": "weights", "sigma2": "auto"}


def register_many(pairs, *, backend: str = "numpy", metric: str = "alpha", sigma2="auto", w="auto",
                  reflection: bool = False, lam: float = 2.0, sigma2_metric: float = 2.0, kernel: str = "weights",
                  max_iter: int = 150, tol: float = 1e-5, n_steps: int = 16, warn: bool = True, device=None,
                  batch_size: int | None = None, timings: dict | None = None, pose_prior: float = POSE_PRIOR) -> list:
    """Non-rigid registrations of many ``(source, target)`` pairs: :func:`register` for each, or the
    same search batched on JAX.

    ``backend="numpy"`` registers the pairs one by one with :func:`register` (``transform="nonrigid"``
    and the options given here): the reference. ``backend="jax"`` runs the search of
    :func:`register` — EM from every start rotation (2-D: every 22.5°, 3-D: the 24 rotations of the
    cube, and their mirror images with ``reflection``), the best two starts and the source as given
    fitted at each outlier weight, the fit of least negative log-posterior

    .. math::

        F = -\\sum_j \\log\\Big[\\frac{1 - w}{n} \\sum_i N(y_j; θ_i, σ^2 I) + \\frac{w}{V}\\Big]
            + \\frac{λ}{2} \\operatorname{tr}(W^T G W)

    plus the prices on its pose's rotation and of its outlier weight, ``0.3 · m · w`` for ``m`` target
    points, kept — for ``batch_size`` pairs × starts at once in one array program, the sets padded to the
    batch's largest ``n`` and ``m`` with masks (a padded target point takes no posterior; a padded
    source point has ``Σ_j P_ij = 0`` and so ``W_i = 0``). Each result is then assembled by the numpy
    code of :func:`register`, so the two backends return the same fits within rounding.

    Parameters
    ----------
    pairs : sequence of (array_like, array_like)
        ``(source, target)`` pairs, shapes ``(n_k, d)`` and ``(m_k, d)``: sizes may differ between
        pairs; ``d`` (2 or 3) is the same for all.
    backend : {"numpy", "jax"}
        ``"numpy"``: :func:`register` one pair at a time. ``"jax"``: batched (needs JAX:
        ``pip install "shapelib[jax]"``, or ``"shapelib[gpu]"`` for an NVIDIA GPU).
    metric, sigma2, kernel : optional
        As in :func:`register`. ``backend="jax"`` batches the default search only
        (``metric="alpha"``, ``kernel="weights"``, ``sigma2="auto"``) and refuses others with a
        ValueError naming the option: register those with ``backend="numpy"``.
    w, reflection, lam, sigma2_metric, max_iter, tol, n_steps, warn, pose_prior
        As in :func:`register` (``warn``: one :class:`RegistrationWarning` per pair that did not
        converge or is not ``reliable``).
    device : {None, "cpu", "gpu"}
        ``backend="jax"`` only: JAX's default device (a GPU when JAX sees one), its CPU, or a GPU
        (a RuntimeError when JAX sees none).
    batch_size : int, optional
        ``backend="jax"``: pairs per device call (default: from the device's memory, at most 4096).
    timings : dict, optional
        Filled with the seconds spent: ``"prep"`` (normalisation and the target's leave-one-out σ²
        on the host, once per distinct target), ``"search"`` (the batched EM on the device, padding
        and transfers included) and ``"assembly"`` (the results on the host), and ``"device"`` (the
        JAX device's name).

    Returns
    -------
    list of RegistrationResult
        One per pair, in the order of ``pairs``.

    Raises
    ------
    ValueError
        A pair that is not two point sets of one dimension, dimensions that differ between pairs
        (naming the pair's index), an unknown ``backend``, or an option ``backend="jax"`` does not batch.

    See Also
    --------
    register : One registration, and the meaning of every option.

    Notes
    -----
    Pairs with a set of over ``MAX_POINTS`` (800) points are registered by :func:`register` even with
    ``backend="jax"`` (through farthest-point subsets, one pair at a time). The batched fits equal
    :func:`register`'s to rounding, but EM stops at a relative σ² change below ``tol``, so a fit that
    meets the tolerance within rounding of the threshold can stop one iteration apart on the two
    backends. The model is Coherent Point Drift's [1]_ with the α-order metric of [2]_ as the
    deformation's kernel; the array program is JAX's [3]_.

    References
    ----------
    .. [1] A. Myronenko and X. Song, "Point set registration: coherent point drift", *IEEE Transactions on
       Pattern Analysis and Machine Intelligence* 32(12), 2262–2275, 2010.
    .. [2] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.
    .. [3] J. Bradbury, R. Frostig, P. Hawkins, M. J. Johnson, C. Leary, D. Maclaurin, G. Necula, A. Paszke,
       J. VanderPlas, S. Wanderman-Milne and Q. Zhang, "JAX: composable transformations of Python+NumPy
       programs", 2018, https://github.com/jax-ml/jax.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> t = np.linspace(0, 2 * np.pi, 30, endpoint=False)
    >>> fish = np.column_stack([np.cos(t) + 0.45 * np.cos(2 * t), 0.55 * np.sin(t) + 0.12 * np.sin(2 * t)])
    >>> c, s = np.cos(2.0), np.sin(2.0)
    >>> pairs = [(fish, fish + [0.0, 0.1] * fish[:, :1] ** 2), (fish, fish @ np.array([[c, -s], [s, c]]).T)]
    >>> res = sl.register_many(pairs)
    >>> [bool(np.abs(r.points - target).max() < 1e-3) for r, (_, target) in zip(res, pairs)]
    [True, True]
    """
    return _register_many(pairs, backend=backend, metric=metric, sigma2=sigma2, w=w, reflection=reflection,
                          lam=lam, sigma2_metric=sigma2_metric, kernel=kernel, max_iter=max_iter, tol=tol,
                          n_steps=n_steps, warn=warn, device=device, batch_size=batch_size, timings=timings,
                          pose_prior=pose_prior)


def fits_many(pairs, **options) -> list:
    """What :func:`register_many` finds, without building each :class:`~shapelib.RegistrationResult`:
    ``(sigma2, converged, n_iter, deformation_energy)`` of each pair's registration, equal to the result's
    ``sigma2``, ``converged``, ``n_iter`` and ``deformation_energy`` (the registration distance needs no more; with ``backend="jax"`` the
    results' assembly on the host is most of the time of a batch on a GPU). Options as
    :func:`register_many`'s; ``warn`` is not taken (nothing is assessed)."""
    return _register_many(pairs, warn=False, fits_only=True, **options)


def _register_many(pairs, *, backend: str = "numpy", metric: str = "alpha", sigma2="auto", w="auto",
                   reflection: bool = False, lam: float = 2.0, sigma2_metric: float = 2.0, kernel: str = "weights",
                   max_iter: int = 150, tol: float = 1e-5, n_steps: int = 16, warn: bool = True, device=None,
                   batch_size: int | None = None, timings: dict | None = None, fits_only: bool = False,
                   pose_prior: float = POSE_PRIOR) -> list:
    if backend not in REGISTER_MANY_BACKENDS:
        raise ValueError(f"backend must be one of {REGISTER_MANY_BACKENDS}; got {backend!r}")
    sets = _check_pairs(pairs)
    opts = dict(metric=metric, sigma2=sigma2, w=w, reflection=reflection, lam=lam, sigma2_metric=sigma2_metric,
                kernel=kernel, max_iter=max_iter, tol=tol, n_steps=n_steps, warn=warn,
                pose_prior=check_nonnegative(pose_prior, name="pose_prior"))
    if backend == "numpy":
        if device is not None:
            raise ValueError(f'device={device!r} needs backend="jax"')
        t0 = time.perf_counter()
        out = [register(x, y, transform="nonrigid", **opts) for x, y in sets]
        if fits_only:
            out = [_fit_of(r) for r in out]
        if timings is not None:
            timings.update(prep=0.0, search=time.perf_counter() - t0, assembly=0.0, device="numpy (CPU)")
        return out
    for name, default in _JAX_DEFAULTS.items():
        value = opts[name]
        if not ((isinstance(value, str) and value == default) or (name == "sigma2" and value is None)):
            raise ValueError(f'{name}={value!r} is not batched on JAX (backend="jax" runs {name}={default!r}); '
                             f'register these pairs with backend="numpy"')
    if device not in DEVICES:
        raise ValueError(f"device must be None, 'cpu' or 'gpu'; got {device!r}")
    if batch_size is not None:
        batch_size = check_positive_int(batch_size, name="batch_size")
    lam = check_positive(lam, name="lam")
    s2g = check_positive(sigma2_metric, name="sigma2_metric")
    max_iter = check_positive_int(max_iter, name="max_iter")
    n_steps = check_positive_int(n_steps, name="n_steps")
    tol = check_positive(tol, name="tol")
    auto_w = _check_w(w)
    return _register_jax(sets, w=None if auto_w else float(w), reflection=bool(reflection), lam=lam, s2g=s2g,
                         max_iter=max_iter, tol=tol, n_steps=n_steps, warn=warn, device=device,
                         batch_size=batch_size, timings=timings, fits_only=fits_only, pose_prior=opts["pose_prior"])


def _fit_of(result):
    """``(sigma2, converged, n_iter, deformation_energy)`` of a :class:`~shapelib.RegistrationResult`
    (:func:`fits_many`)."""
    return float(result.sigma2), bool(result.converged), int(result.n_iter), float(result.deformation_energy)


def _check_pairs(pairs):
    """The pairs as float64 point sets, one dimension throughout; ValueError naming the pair's index."""
    if isinstance(pairs, np.ndarray) and pairs.ndim != 4:
        raise ValueError(f"pairs must be a sequence of (source, target) pairs of point sets; got an array of shape "
                         f"{pairs.shape}")
    try:
        items = list(pairs)
    except TypeError:
        raise ValueError(f"pairs must be a sequence of (source, target) pairs; got {type(pairs).__name__}") from None
    sets, d0 = [], None
    for i, pair in enumerate(items):
        try:
            x, y = pair
        except (TypeError, ValueError):
            raise ValueError(f"pairs[{i}] must be a (source, target) pair of point sets") from None
        x = as_point_set(x, name=f"pairs[{i}] source")
        y = as_point_set(y, name=f"pairs[{i}] target")
        if x.shape[1] != y.shape[1]:
            raise ValueError(f"pairs[{i}]: source and target must have the same dimension; got d = {x.shape[1]} "
                             f"and {y.shape[1]}")
        if d0 is None:
            d0 = x.shape[1]
        elif x.shape[1] != d0:
            raise ValueError(f"pairs[{i}] has d = {x.shape[1]} but pairs[0] has d = {d0}: pairs must all be 2-D or "
                             f"all 3-D")
        sets.append((x, y))
    return sets


# -------------------------------------------------------------------------------------------------
# The batched search
# -------------------------------------------------------------------------------------------------


def _auto_batch(n_starts, n, m, device):
    """Pairs per device call: the (n, m) arrays of every start in a share of the device's memory."""
    budget = 2**30
    try:
        stats = jax_device(device).memory_stats() or {}
        if "bytes_limit" in stats:
            budget = 0.3 * stats["bytes_limit"]
    except Exception:  # noqa: BLE001 - memory_stats is optional per platform
        pass
    per_pair = n_starts * n * m * 8 * 8  # a handful of (n, m) float64 arrays per fit
    return int(max(1, min(4096, budget // per_pair)))


def _register_jax(sets, *, w, reflection, lam, s2g, max_iter, tol, n_steps, warn, device, batch_size, timings,
                  fits_only=False, pose_prior=POSE_PRIOR):
    results = [None] * len(sets)
    big = [i for i, (x, y) in enumerate(sets) if max(len(x), len(y)) > MAX_POINTS]
    for i in big:  # farthest-point subsets, one pair at a time (module docstring of registration)
        results[i] = register(*sets[i], w="auto" if w is None else w, reflection=reflection, lam=lam,
                              sigma2_metric=s2g, max_iter=max_iter, tol=tol, n_steps=n_steps, warn=warn,
                              pose_prior=pose_prior)
        if fits_only:
            results[i] = _fit_of(results[i])
    todo = [i for i in range(len(sets)) if max(len(sets[i][0]), len(sets[i][1])) <= MAX_POINTS]
    t_prep = t_search = t_host = 0.0
    dev_name = str(jax_device(device)) if todo else None
    if todo:
        d = sets[todo[0]][0].shape[1]
        rots = start_rotations(d, reflection)
        todo.sort(key=lambda i: max(len(sets[i][0]), len(sets[i][1])))  # similar sizes share a batch: less padding
        if batch_size is None:
            batch_size = _auto_batch(len(rots), max(len(sets[todo[-1]][0]), 1), max(len(sets[todo[-1]][1]), 1),
                                     device)
        grid = W_GRID if w is None else (w,)
        em_opts = dict(lam=lam, fixed_s2=None, max_iter=max_iter, tol=tol)
        for start in range(0, len(todo), batch_size):
            idx = todo[start:start + batch_size]
            t0 = time.perf_counter()
            prep = []
            for i in idx:  # the target's leave-one-out σ² once per distinct target (a matrix's pairs share them)
                y = sets[i][1]
                prep.append(_nonrigid_frame(*sets[i], None, target_s2=_target_sigma2(y.shape, y.tobytes())))
            tp = time.perf_counter()
            fits = _search(prep, rots, w=W_SCREEN if w is None else w, grid=grid, lam=lam, s2g=s2g,
                           max_iter=max_iter, tol=tol, device=device, reflection=reflection, pose_prior=pose_prior)
            t1 = time.perf_counter()
            for i, (frame, _, s2_eval), f in zip(idx, prep, fits):
                if fits_only:  # the best fit's σ² in the target's units and its energy, as _result gives them
                    st = f[0][2]
                    results[i] = (st.s2 * frame[5] ** 2, st.ok, st.it, deformation_energy(st, lam))
                    continue
                results[i] = _nonrigid_result(*sets[i], frame, s2_eval, f, rots, metric="alpha",
                                              reflection=reflection, s2g=s2g, kernel="weights",
                                              em_opts=dict(em_opts, s2_floor=SIGMA2_FLOOR * s2_eval),
                                              n_steps=n_steps, warn=warn, stacklevel=4, pose_prior=pose_prior)
            t_prep += tp - t0
            t_search += t1 - tp
            t_host += time.perf_counter() - t1
    if timings is not None:
        timings.update(prep=t_prep, search=t_search, assembly=t_host, device=dev_name)
    return results


@functools.lru_cache(maxsize=4096)
def _target_sigma2(shape, data):
    """The target's leave-one-out σ² as :func:`register` computes it (``s2_eval`` of
    :func:`~shapelib.pointsets.registration._nonrigid_frame`), remembered by the target's coordinates:
    the pairs of a distance matrix, in one call or many, share their targets (a pure function of
    ``data``, the float64 bytes of a ``shape`` array)."""
    y = np.frombuffer(data, dtype=np.float64).reshape(shape)
    return _nonrigid_frame(y, y, None)[2]


def _pad_size(n):
    """The padded size of a batch's sets: a multiple of 8 up to 256 points (at most 7 padded points: the
    E-step's cost grows as n · m), :func:`~shapelib.solver.batched.bucket` above (few compiled sizes)."""
    return int(-(-n // 8) * 8) if n <= 256 else bucket(n)


def _search(prep, rots, *, w, grid, lam, s2g, max_iter, tol, device, reflection, pose_prior):
    """The fits of every pair of ``prep`` (``(frame, fs2, s2_eval)`` of each), as
    :func:`~shapelib.pointsets._nonrigid.fit_all` returns them: ``(objective, start, EMState)``, best first."""
    b = len(prep)
    d = prep[0][0][0].shape[1]
    ns = np.array([len(p[0][0]) for p in prep])
    ms = np.array([len(p[0][1]) for p in prep])
    bp, n_pad, m_pad = bucket(b), _pad_size(ns.max()), _pad_size(ms.max())
    xs, ys = np.zeros((bp, n_pad, d)), np.zeros((bp, m_pad, d))
    umask, ymask = np.zeros((bp, n_pad), bool), np.zeros((bp, m_pad), bool)
    vol, floor, nreal = np.ones(bp), np.ones(bp), np.ones(bp)
    for k in range(bp):  # padding pairs repeat the first pair (their results are dropped)
        frame, _, s2_eval = prep[k if k < b else 0]
        xn, yn = frame[:2]
        xs[k, :len(xn)], ys[k, :len(yn)] = xn, yn
        umask[k, :len(xn)], ymask[k, :len(yn)] = True, True
        vol[k], floor[k], nreal[k] = box_volume(yn), SIGMA2_FLOOR * s2_eval, len(xn)
    rot_arr = np.array(rots)
    n_rot = len(rots)
    with jk.x64() as jax:
        with jax.default_device(jax_device(device)):
            factor, fit = _programs()
            ev, q = (np.asarray(a) for a in factor(xs, umask, s2g))
            # the eigenvalues kept (module docstring, 2.); the factor cut to the batch's largest kept rank
            keep = ev > EIG_RTOL * np.maximum(ev[:, -1:], 0.0)
            rank = min(bucket(int(keep.sum(axis=1).max())), n_pad)
            keep, ev, q = keep[:, -rank:], ev[:, -rank:], q[:, :, -rank:]
            q = np.where(keep[:, None, :], q, 0.0)
            ev = np.where(keep, ev, 1.0)
            common = (xs, umask, ys, ymask, nreal, vol, floor, q, ev)
            # the screening's kernel (fit_all's SCREEN_EIG_RTOL): its dropped columns zero, their eigenvalue 1
            keep_s = keep & (ev > SCREEN_EIG_RTOL * np.maximum(ev[:, -1:], 0.0))
            q_s, ev_s = np.where(keep_s[:, None, :], q, 0.0), np.where(keep_s, ev, 1.0)
            scalars = (float(lam), float(tol))
            screen = np.broadcast_to(rot_arr, (bp, n_rot, d, d))
            fresh = (np.zeros((bp, n_rot), bool), np.zeros((bp, n_rot, n_pad, d)), np.ones((bp, n_rot)),
                     np.zeros((bp, n_rot), np.int32), np.zeros((bp, n_rot), bool))
            out1 = [np.asarray(a) for a in fit(*common[:7], q_s, ev_s, screen, np.full(n_rot, w), *fresh, *scalars,
                                               min(SCREEN_ITER, max_iter))]
            f_screen = out1[4]
            best = np.argsort(f_screen, axis=1, kind="stable")[:, :N_KEEP]  # fit_all's sort: stable, by objective
            # the source as given (start 0) besides them; where it is one of them already, its fits here are
            # dropped on the host
            kept = np.concatenate([best, np.zeros((bp, 1), best.dtype)], axis=1)
            twice = (best == 0).any(axis=1)
            starts = np.repeat(kept, len(grid), axis=1)  # (bp, kept · len(grid)): start-major, weights inner
            weights = np.tile(np.asarray(grid, float), kept.shape[1])
            # the fit at the screening weight continues the screening's EM from the same means under the full
            # kernel (the coefficients projected on the screening kernel's eigenvectors); one that met the
            # tolerance goes on unless the screening's kernel dropped nothing (fit_all)
            rows = np.arange(bp)[:, None]
            resume = np.broadcast_to(weights == w, starts.shape).copy()
            coef0 = out1[0][rows, starts]
            coef0 = q_s[:, None] @ (np.swapaxes(q_s, 1, 2)[:, None] @ coef0)
            same = (keep_s == keep).all(axis=1)[:, None]
            carried = (resume, coef0, out1[1][rows, starts], out1[2][rows, starts].astype(np.int32),
                       out1[3][rows, starts] & same)
            out2 = [np.asarray(a) for a in fit(*common, rot_arr[starts], weights, *carried, *scalars, max_iter)]
    coef, s2, it, ok, f = out2
    fits = []
    for k in range(b):
        n = ns[k]
        kern = Kernel(q=q[k, :n][:, keep[k]], ev=ev[k][keep[k]])
        xn = prep[k][0][0]
        cands = []
        for j, start in enumerate(starts[k]):
            if twice[k] and j >= N_KEEP * len(grid):  # the source as given, fitted among the best already
                break
            st = EMState(u=xn @ rots[start].T, kernel=kern, coef=coef[k, j, :n].copy(), s2=float(s2[k, j]),
                         w=float(weights[j]), it=int(it[k, j]), ok=bool(ok[k, j]),
                         why="tolerance" if ok[k, j] else "max_iter")
            cands.append((float(f[k, j]), int(start), st))
        fits.append(ranked(with_pose_prior(cands, xn, pose_prior, reflection), ms[k]))
    return fits


@functools.lru_cache(maxsize=None)
def _programs():
    """The compiled programs: the kernels' factors of a batch of pairs, and EM for pairs × fits."""
    import jax
    import jax.numpy as jnp
    from jax import lax
    from jax.scipy.linalg import cho_solve
    from jax.scipy.special import logsumexp

    def sq_dist(a, b):  # the expansion of _coherent_em.sq_dist, clipped at 0
        out = jnp.sum(a * a, axis=1)[:, None] + jnp.sum(b * b, axis=1)[None, :] - 2.0 * (a @ b.T)
        return jnp.maximum(out, 0.0)

    def factor_one(x, umask, s2g):
        both = umask[:, None] & umask[None, :]
        g = jnp.where(both, jnp.exp(-sq_dist(x, x) / (4 * s2g)), 0.0)
        g = g / (jnp.sum(jnp.where(umask, jnp.diag(g), 0.0)) / jnp.sum(umask))
        return jnp.linalg.eigh(0.5 * (g + g.T))

    factor = jax.jit(jax.vmap(factor_one, in_axes=(0, 0, None)))

    def fit_one(x, umask, y, ymask, n, vol, floor, q, ev, rot, w, resume, coef0, s2_init, it0, ok0, lam, tol,
                max_iter):
        d = x.shape[1]
        u = jnp.where(umask[:, None], x @ rot.T, 0.0)
        pair = umask[:, None] & ymask[None, :]
        s2_0 = jnp.sum(jnp.where(pair, sq_dist(u, y), 0.0)) / (n * jnp.sum(ymask)) / d
        yy = jnp.where(ymask, jnp.sum(y * y, axis=1), 0.0)
        c_w = jnp.where(w > 0, w / (1 - w), 0.0) * n / vol

        def dist(theta):  # direct differences, as the compiled E-step
            return jnp.sum((y[None, :, :] - theta[:, None, :]) ** 2, axis=2)

        def apply(coef):  # G W
            return q @ (ev[:, None] * (q.T @ coef))

        m_real = jnp.sum(ymask)
        log_wn = jnp.log((1 - w) / n)

        def step(coef, s2):  # one EM iteration, and F at its input (_coherent_em._em_map)
            gw = apply(coef)
            r = dist(u + gw)
            e = jnp.where(pair, jnp.exp(-r / (2.0 * s2)), 0.0)
            den = jnp.sum(e, axis=0) + (2 * jnp.pi * s2) ** (d / 2) * c_w
            live = ymask & (den > 0)
            p = jnp.where(live[None, :], e / jnp.where(live, den, 1.0)[None, :], 0.0)
            # the columns' log-normalisers (a column whose every term underflows: its largest term's log)
            rmin = jnp.min(jnp.where(pair, r, jnp.inf), axis=0)
            lse = jnp.sum(jnp.where(ymask, jnp.where(live, jnp.log(jnp.where(live, den, 1.0)), -rmin / (2.0 * s2)),
                                    0.0))
            f = 0.5 * lam * jnp.sum(coef * gw) - lse - m_real * (log_wn - 0.5 * d * jnp.log(2 * jnp.pi * s2))
            p1, pt1, py = jnp.sum(p, axis=1), jnp.sum(p, axis=0), p @ y
            lam_s2 = lam * s2
            b = py - p1[:, None] * u
            dq = p1[:, None] * q
            inner = q.T @ dq + jnp.diag(lam_s2 / ev)
            coef = (b - dq @ cho_solve((jnp.linalg.cholesky(inner), True), q.T @ b)) / lam_s2
            theta = u + apply(coef)
            sse = pt1 @ yy - 2.0 * jnp.sum(py * theta) + p1 @ jnp.sum(theta * theta, axis=1)
            return coef, jnp.maximum(sse / (jnp.maximum(jnp.sum(p1), 1e-300) * d), floor), f

        def extrapolate(c0, s0, c1, s1, c2, s2):  # _coherent_em._extrapolate
            l0, l1, l2 = jnp.log(s0), jnp.log(s1), jnp.log(s2)
            rl, vl = l1 - l0, l2 - 2.0 * l1 + l0
            r, v = c1 - c0, c2 - 2.0 * c1 + c0
            rr, vv = jnp.sum(r * r) + rl * rl, jnp.sum(v * v) + vl * vl
            alpha = jnp.minimum(jnp.where(vv > 0, -jnp.sqrt(rr / jnp.where(vv > 0, vv, 1.0)), -1.0), -1.0)
            lx = l0 - 2.0 * alpha * rl + alpha * alpha * vl
            return c0 - 2.0 * alpha * r + alpha * alpha * v, jnp.maximum(jnp.exp(jnp.minimum(lx, 30.0)), floor)

        def cond_plain(state):
            it, _, _, done = state
            return (~done) & (it < jnp.minimum(max_iter, PLAIN_ITER))

        def body_plain(state):  # the first PLAIN_ITER iterations of a fit: plain EM
            it, c0, s0, _ = state
            c1, s1, _ = step(c0, s0)
            return it + 1, c1, s1, jnp.abs(s1 - s0) <= tol * s0

        def cond(state):
            it, _, _, done = state
            return (~done) & (it < max_iter)

        def body(state):  # one cycle of _coherent_em._em_loop (all three iterations computed, one kept)
            it, c0, s0, _ = state
            c1, s1, _ = step(c0, s0)
            conv1 = jnp.abs(s1 - s0) <= tol * s0
            c2, s2, f1 = step(c1, s1)
            conv2 = jnp.abs(s2 - s1) <= tol * s1
            cx, sx = extrapolate(c0, s0, c1, s1, c2, s2)
            c3, s3, fx = step(cx, sx)
            conv3 = jnp.abs(s3 - sx) <= tol * sx
            one = conv1 | (it + 3 > max_iter)  # the cycle ends after its first iteration
            two = ~one & conv2  # ... after its second, converged
            refused = ~one & ~conv2 & ~(fx <= f1)  # three iterations run, the second one's kept
            keep2 = two | refused
            coef = jnp.where(one, c1, jnp.where(keep2, c2, c3))
            return (jnp.where(one, it + 1, jnp.where(two, it + 2, it + 3)), coef,
                    jnp.where(one, s1, jnp.where(keep2, s2, s3)), jnp.where(one, conv1, jnp.where(keep2, conv2, conv3)))

        state = (jnp.where(resume, it0, 0), jnp.where(resume, coef0, 0.0), jnp.where(resume, s2_init, s2_0),
                 resume & ok0)
        it, coef, s2, ok = lax.while_loop(cond, body, lax.while_loop(cond_plain, body_plain, state))
        # the objective F (negative log-posterior) of the final fit
        theta = u + apply(coef)
        logn = jnp.where(pair, -dist(theta) / (2 * s2), -jnp.inf) - 0.5 * d * jnp.log(2 * jnp.pi * s2)
        mix = logsumexp(logn, axis=0) + jnp.log((1 - w) / n)
        ll = jnp.where(w > 0, jnp.logaddexp(mix, jnp.log(jnp.where(w > 0, w, 1.0) / vol)), mix)
        f = -jnp.sum(jnp.where(ymask, ll, 0.0)) + 0.5 * lam * jnp.sum(coef * apply(coef))
        return coef, s2, it, ok, f

    per_pair = jax.vmap(fit_one, in_axes=(None,) * 9 + (0,) * 7 + (None, None, None))
    fit = jax.jit(jax.vmap(per_pair, in_axes=(0,) * 10 + (None,) + (0,) * 5 + (None, None, None)))
    return factor, fit

"""Linear algebra of the block-tridiagonal path Hessian: block Cholesky, solves and products,
with BLAS on one thread for its small dense blocks."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.linalg.blas import dsyrk, dtrsm, dtrsv
from scipy.linalg.lapack import dpotrf
from threadpoolctl import ThreadpoolController

__all__ = ["one_blas_thread", "block_cholesky", "block_solve", "hess_vec", "block_tridiagonal_dense"]


@lru_cache(maxsize=1)
def _blas_controller():
    return ThreadpoolController()


def one_blas_thread():
    r"""Context manager: BLAS/LAPACK on one thread for the solver's small dense blocks.

    The path Hessian of the energy of eq. (8) of [1]_ is factorised block by block ((K d)² blocks,
    126² for K = 63); with the default two OpenBLAS threads on a 2-core machine each small call pays
    thread hand-off costs (measured: block Cholesky for n = 16, K = 63 takes 115 ms with two
    threads, 5 ms with one). The cost of a block factorisation is

    .. math::

        O(q^3), \qquad q = K d,

    too small to split across threads.

    Returns
    -------
    contextlib.AbstractContextManager
        ``threadpoolctl``'s limiter; use it in a ``with`` statement.

    See Also
    --------
    shapelib.solver.linalg.block_cholesky

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.solver.linalg import one_blas_thread
    >>> with one_blas_thread():
    ...     x = np.linalg.solve(np.eye(3), np.ones(3))
    >>> x
    array([1., 1., 1.])
    """
    return _blas_controller().limit(limits=1, user_api="blas")


def block_cholesky(diag, upper, shift):
    r"""Cholesky factors of the block-tridiagonal ``H + shift·I`` (LinAlgError if not PD).

    :math:`H = L L^\top` with lower-triangular diagonal blocks :math:`L_t` and sub-diagonal blocks
    :math:`W_t = (L_t^{-1} U_t)^\top` [1]_:

    .. math::

        L_0 L_0^\top = D_0, \qquad W_t^\top = U_t^\top L_t^{-\top}, \qquad
        L_{t+1} L_{t+1}^\top = D_{t+1} - W_t^\top W_t,

    O(n q³) instead of O(n q³ · 4) for a banded solver of width 2q. Straight LAPACK/BLAS calls
    (``potrf``, ``trsm``, and ``syrk`` for the Schur complement, half a general product): the blocks
    are small (q = 126 for the corpus callosum), so the wrappers' checks were a large part of the
    cost. Stored: :math:`L_t` and :math:`W_t^\top` (as ``trsm`` returns it). The matrix is the
    Hessian of the path energy of eq. (8) of [2]_.

    Parameters
    ----------
    diag : ndarray, shape (m, q, q)
        Diagonal blocks :math:`D_t` (only the lower triangles are read).
    upper : ndarray, shape (m - 1, q, q)
        Super-diagonal blocks :math:`U_t = H[t, t+1]`.
    shift : float
        Added to the diagonal.

    Returns
    -------
    lows : list of ndarray
        :math:`L_t`.
    subs : list of ndarray
        :math:`W_t^\top`.

    Raises
    ------
    numpy.linalg.LinAlgError
        When a block of the shifted matrix is not positive definite.

    See Also
    --------
    shapelib.solver.linalg.block_solve : Solves with the factors.

    References
    ----------
    .. [1] G. H. Golub and C. F. Van Loan, *Matrix Computations*, 4th ed., Johns Hopkins University Press, 2013.
    .. [2] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.solver.linalg import block_cholesky, block_solve, block_tridiagonal_dense
    >>> diag, upper = np.array([[[4.0]], [[4.0]], [[4.0]]]), np.array([[[-1.0]], [[-1.0]]])
    >>> factors = block_cholesky(diag, upper, 0.0)
    >>> x = block_solve(factors, np.ones((3, 1)))
    >>> bool(np.allclose(block_tridiagonal_dense(diag, upper) @ x.ravel(), 1.0))
    True
    """
    m, q, _ = diag.shape
    idx = np.arange(q)
    lows, subs = [], []
    if m == 0:
        return lows, subs
    block = np.array(diag[0], order="F")  # only the lower triangle is read and updated
    for t in range(m):
        if shift:
            block[idx, idx] += shift
        low, info = dpotrf(block, lower=1, clean=1, overwrite_a=1)
        if info != 0:
            raise np.linalg.LinAlgError(f"block {t} of the shifted path Hessian is not positive definite")
        lows.append(low)
        if t < m - 1:
            wt = dtrsm(1.0, low, upper[t].T, side=1, lower=1, trans_a=1)  # W_tᵀ = U_tᵀ L_t⁻ᵀ
            subs.append(wt)
            block = dsyrk(-1.0, wt, beta=1.0, c=np.array(diag[t + 1], order="F"), lower=1, overwrite_c=1)
    return lows, subs


def block_solve(factors, rhs):
    r"""Solve ``H x = rhs`` with the factors of :func:`~shapelib.solver.linalg.block_cholesky`.

    Forward then backward block substitution [1]_:

    .. math::

        L_t y_t = r_t - W_{t-1} y_{t-1}, \qquad L_t^\top x_t = y_t - W_t^\top x_{t+1}.

    The Newton and Levenberg–Marquardt steps of the path solver (eq. 8 of [2]_) are such solves.

    Parameters
    ----------
    factors : tuple (lows, subs)
        From :func:`~shapelib.solver.linalg.block_cholesky`.
    rhs : ndarray, shape (m, q)
        Right-hand side.

    Returns
    -------
    ndarray, shape (m, q)
        :math:`x`.

    See Also
    --------
    shapelib.solver.linalg.block_cholesky

    References
    ----------
    .. [1] G. H. Golub and C. F. Van Loan, *Matrix Computations*, 4th ed., Johns Hopkins University Press, 2013.
    .. [2] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.solver.linalg import block_cholesky, block_solve
    >>> diag, upper = np.array([[[2.0]], [[2.0]]]), np.array([[[-1.0]]])
    >>> block_solve(block_cholesky(diag, upper, 0.0), np.array([[1.0], [1.0]])).ravel()
    array([1., 1.])
    """
    lows, subs = factors
    m = len(lows)
    y = np.empty_like(rhs)
    for t in range(m):
        r = rhs[t] if t == 0 else rhs[t] - subs[t - 1] @ y[t - 1]
        y[t] = dtrsv(lows[t], r, lower=1)
    x = np.empty_like(rhs)
    for t in range(m - 1, -1, -1):
        r = y[t] if t == m - 1 else y[t] - subs[t].T @ x[t + 1]
        x[t] = dtrsv(lows[t], r, lower=1, trans=1)
    return x


def hess_vec(diag, upper, x):
    r"""Product of the symmetric block-tridiagonal matrix ``(diag, upper)`` with ``x``.

    .. math::

        (H x)_t = D_t x_t + U_t x_{t+1} + U_{t-1}^\top x_{t-1},

    the predicted decrease of a Levenberg–Marquardt step on the path energy (eq. 8 of [1]_) needs it.

    Parameters
    ----------
    diag : ndarray, shape (m, q, q)
        Diagonal blocks.
    upper : ndarray, shape (m - 1, q, q)
        Super-diagonal blocks.
    x : ndarray, shape (m, q)
        The vector, block by block.

    Returns
    -------
    ndarray, shape (m, q)
        :math:`H x`.

    See Also
    --------
    shapelib.solver.linalg.block_tridiagonal_dense : The same matrix, dense.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.solver.linalg import hess_vec
    >>> diag, upper = np.array([[[2.0]], [[2.0]]]), np.array([[[-1.0]]])
    >>> hess_vec(diag, upper, np.array([[1.0], [1.0]])).ravel()
    array([1., 1.])
    """
    hx = np.einsum("tij,tj->ti", diag, x)
    if len(upper):
        hx[:-1] += np.einsum("tij,tj->ti", upper, x[1:])
        hx[1:] += np.einsum("tji,tj->ti", upper, x[:-1])
    return hx


def block_tridiagonal_dense(diag, upper) -> np.ndarray:
    r"""The symmetric block-tridiagonal matrix ``(diag, upper)`` as a dense array.

    .. math::

        H = \begin{pmatrix} D_0 & U_0 & & \\ U_0^\top & D_1 & U_1 & \\ & U_1^\top & D_2 & \ddots \\
        & & \ddots & \ddots \end{pmatrix}

    For checks and small problems; the solver of the path energy (eq. 8 of [1]_) never forms it.

    Parameters
    ----------
    diag : ndarray, shape (m, q, q)
        Diagonal blocks.
    upper : ndarray, shape (m - 1, q, q)
        Super-diagonal blocks.

    Returns
    -------
    ndarray, shape (m q, m q)
        :math:`H`.

    See Also
    --------
    shapelib.solver.linalg.block_cholesky : Factorises it without forming it.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.solver.linalg import block_tridiagonal_dense
    >>> block_tridiagonal_dense(np.array([[[2.0]], [[2.0]]]), np.array([[[-1.0]]]))
    array([[ 2., -1.],
           [-1.,  2.]])
    """
    m, q, _ = diag.shape
    h = np.zeros((m * q, m * q))
    for t in range(m):
        h[t * q:(t + 1) * q, t * q:(t + 1) * q] = diag[t]
    for t in range(m - 1):
        h[t * q:(t + 1) * q, (t + 1) * q:(t + 2) * q] = upper[t]
        h[(t + 1) * q:(t + 2) * q, t * q:(t + 1) * q] = upper[t].T
    return h

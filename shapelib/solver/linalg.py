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
    """Context manager: BLAS/LAPACK on one thread for the solver's small dense blocks.

    The path Hessian is factorised block by block ((K d)² blocks, 126² for K = 63); with the
    default two OpenBLAS threads on this 2-core machine each small call pays thread hand-off
    costs (measured: block Cholesky for n = 16, K = 63 takes 115 ms with two threads, 5 ms
    with one).
    """
    return _blas_controller().limit(limits=1, user_api="blas")


def block_cholesky(diag, upper, shift):
    """Cholesky factors of the block-tridiagonal ``H + shift·I`` (LinAlgError if not PD).

    ``H = L Lᵀ`` with lower-triangular diagonal blocks ``L_t`` and sub-diagonal blocks
    ``W_t = (L_t⁻¹ U_t)ᵀ``; O(n q³) instead of O(n q³ · 4) for a banded solver of width 2q.
    Straight LAPACK/BLAS calls (``potrf``, ``trsm``, and ``syrk`` for the Schur complement
    ``D_{t+1} − W_tᵀ W_t``, half a general product): the blocks are small (q = 126 for the
    corpus callosum), so the wrappers' checks were a large part of the cost. Stored: ``L_t``
    and ``W_tᵀ`` (as ``trsm`` returns it).
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
    """Solve ``H x = rhs`` (rhs (m, q)) with the factors of :func:`block_cholesky`."""
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
    hx = np.einsum("tij,tj->ti", diag, x)
    if len(upper):
        hx[:-1] += np.einsum("tij,tj->ti", upper, x[1:])
        hx[1:] += np.einsum("tji,tj->ti", upper, x[:-1])
    return hx


def block_tridiagonal_dense(diag, upper) -> np.ndarray:
    """The symmetric block-tridiagonal matrix ``(diag, upper)`` as a dense array (for checks and
    small problems; the solver never forms it)."""
    m, q, _ = diag.shape
    h = np.zeros((m * q, m * q))
    for t in range(m):
        h[t * q:(t + 1) * q, t * q:(t + 1) * q] = diag[t]
    for t in range(m - 1):
        h[t * q:(t + 1) * q, (t + 1) * q:(t + 2) * q] = upper[t]
        h[(t + 1) * q:(t + 2) * q, t * q:(t + 1) * q] = upper[t].T
    return h

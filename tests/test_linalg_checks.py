"""The block-tridiagonal linear algebra of the path solver (``shapelib.solver.linalg``), number by
number: the block Cholesky factors are the blocks of NumPy's dense Cholesky factor (the factor is
unique), the solves agree with a dense solve, the edge sizes (no block, one block) and the block an
indefinite matrix fails at; ``one_blas_thread`` is checked with threadpoolctl's own report of the
thread pools. The solver's use of these pieces is tested in tests/test_geodesic.py and
tests/test_solver_pieces.py."""

import numpy as np
import pytest
import sklearn.cluster  # noqa: F401  its k-means extension loads the OpenMP runtime before any test runs
from threadpoolctl import threadpool_info, threadpool_limits

from shapelib.solver.linalg import block_cholesky, block_solve, block_tridiagonal_dense, hess_vec, one_blas_thread


def _blocks(rng, m, q):
    """A random positive-definite block-tridiagonal matrix: its diagonal and super-diagonal blocks."""
    a = rng.normal(size=(m * q, m * q))
    band = np.abs(np.subtract.outer(np.arange(m * q) // q, np.arange(m * q) // q)) <= 1
    h = (a @ a.T) * band
    h += (0.1 - min(np.linalg.eigvalsh(h)[0], 0.0)) * np.eye(m * q)
    diag = np.stack([h[t * q:(t + 1) * q, t * q:(t + 1) * q] for t in range(m)])
    upper = np.array([h[t * q:(t + 1) * q, (t + 1) * q:(t + 2) * q] for t in range(m - 1)]).reshape(m - 1, q, q)
    return h, diag, upper


@pytest.mark.parametrize("shift", [0.0, 0.7])
def test_factors_are_the_blocks_of_the_dense_cholesky_factor(rng, shift):
    """The Cholesky factor of a positive-definite matrix is unique, so the factors of the block
    recursion are the blocks of np.linalg.cholesky(H + shift I): L_t on the diagonal, and the stored
    W_tᵀ = U_tᵀ L_t⁻ᵀ below it; each L_t lower triangular (its upper triangle zero)."""
    m, q = 4, 3
    h, diag, upper = _blocks(rng, m, q)
    dense = np.linalg.cholesky(h + shift * np.eye(m * q))
    lows, subs = block_cholesky(diag, upper, shift)
    assert len(lows) == m and len(subs) == m - 1
    for t in range(m):
        np.testing.assert_allclose(lows[t], dense[t * q:(t + 1) * q, t * q:(t + 1) * q], atol=1e-12)
        assert not np.triu(lows[t], 1).any()
    for t in range(m - 1):
        np.testing.assert_allclose(subs[t], dense[(t + 1) * q:(t + 2) * q, t * q:(t + 1) * q], atol=1e-12)


def test_one_block_and_no_block(rng):
    """One interior node (a path of two steps): the factor is the Cholesky factor of the one block
    and the solve is the dense solve. No interior node: no factors, and an empty solution."""
    h, diag, upper = _blocks(rng, 1, 3)
    lows, subs = block_cholesky(diag, upper, 0.25)
    np.testing.assert_allclose(lows[0], np.linalg.cholesky(h + 0.25 * np.eye(3)), atol=1e-12)
    assert subs == []
    rhs = rng.normal(size=(1, 3))
    np.testing.assert_allclose(block_solve((lows, subs), rhs)[0], np.linalg.solve(h + 0.25 * np.eye(3), rhs[0]))
    np.testing.assert_allclose(hess_vec(diag, upper, rhs)[0], h @ rhs[0])
    assert block_cholesky(np.zeros((0, 3, 3)), np.zeros((0, 3, 3)), 0.0) == ([], [])
    assert block_solve(([], []), np.zeros((0, 3))).shape == (0, 3)


def test_the_solve_inverts_the_dense_matrix_and_the_product_is_the_dense_product(rng):
    """block_solve against np.linalg.solve and hess_vec against the dense product, on several
    right-hand sides at once (the solve of a matrix's columns is its inverse)."""
    m, q = 5, 2
    h, diag, upper = _blocks(rng, m, q)
    assert np.array_equal(block_tridiagonal_dense(diag, upper), h)
    factors = block_cholesky(diag, upper, 0.0)
    inverse = np.stack([block_solve(factors, e.reshape(m, q)).ravel() for e in np.eye(m * q)], axis=1)
    np.testing.assert_allclose(inverse, np.linalg.inv(h), atol=1e-10 * np.abs(np.linalg.inv(h)).max())
    x = rng.normal(size=(m, q))
    np.testing.assert_allclose(hess_vec(diag, upper, x).ravel(), h @ x.ravel())


def test_an_indefinite_matrix_fails_at_its_first_indefinite_block():
    """Block-diagonal (no coupling), with blocks 0 and 1 positive definite and block 2 not: the
    factorisation stops at block 2 and says so; a shift that makes every block positive definite
    factorises it."""
    q = 2
    diag = np.stack([np.eye(q), 2 * np.eye(q), np.diag([1.0, -0.5]), np.eye(q)])
    upper = np.zeros((3, q, q))
    with pytest.raises(np.linalg.LinAlgError, match="block 2 "):
        block_cholesky(diag, upper, 0.0)
    lows, _ = block_cholesky(diag, upper, 0.6)
    np.testing.assert_allclose(lows[2], np.diag(np.sqrt([1.6, 0.1])))


def _pools():
    return [(pool["user_api"], pool["filepath"], pool["num_threads"]) for pool in threadpool_info()]


def test_one_blas_thread_limits_the_blas_pools_to_one_thread_and_leaves_openmp_alone():
    """Inside the context every BLAS library reports one thread (threadpoolctl's own inspection, not
    the controller's), the OpenMP runtime loaded by scikit-learn keeps its threads, and on exit
    every pool is as before. Every pool starts at two threads, so that there is something to limit and
    to restore whatever the suite's own setting (one per xdist worker)."""
    with threadpool_limits(2):
        before = _pools()
        assert any(api == "blas" for api, _, _ in before) and all(n == 2 for _, _, n in before)
        with one_blas_thread():
            inside = _pools()
            np.linalg.solve(np.eye(3), np.ones(3))
        after = _pools()
    assert [n for api, _, n in inside if api == "blas"] == [1] * sum(api == "blas" for api, _, _ in before)
    assert [p for p in inside if p[0] != "blas"] == [p for p in before if p[0] != "blas"]
    assert after == before

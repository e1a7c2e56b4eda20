"""The compiled α kernels (shapelib.geometry._kernels) against the numpy formulas of shapelib.geometry.metrics and
shapelib.geodesic, which stay as the test oracle (the finite-difference checks of those are in
tests/test_metrics.py and tests/test_geodesic.py)."""
import numpy as np
import pytest

from shapelib.geometry import _kernels
from shapelib.solver.energy import exact_path_hessian as _exact_path_hessian
from shapelib.solver.energy import path_energy as _energy
from shapelib.solver.energy import segment_nodes as _segment_nodes
from shapelib.solver.path_metric import GL3_NODES as _GL3_NODES
from shapelib.solver.path_metric import AlphaPathMetric as _AlphaModel
from shapelib.geometry.metrics import _alpha_qform, _alpha_qform_grad


def _rel(a, b):
    return np.abs(a - b).max() / np.abs(b).max()


@pytest.mark.parametrize("d", [2, 3])
def test_alpha_qform_and_gradient_match_numpy(rng, d):
    theta, vel = rng.normal(size=(2, 7, 6, d))
    s2 = 0.4
    assert _rel(_kernels.alpha_qform(theta, vel, s2), _alpha_qform(theta, vel, s2)) < 1e-12
    for got, ref in zip(_kernels.alpha_qform_grad(theta, vel, s2), _alpha_qform_grad(theta, vel, s2)):
        assert _rel(got, ref) < 1e-12


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("n", [2, 3, 5])
def test_alpha_path_hessian_matches_numpy_assembly(rng, d, n):
    """The fused path Hessian equals the per-node numpy Hessian (metrics.alpha_qform_hessian)
    combined by geodesic._exact_path_hessian, block by block."""
    k = 6
    path = rng.normal(size=(n + 1, k, d))
    model = _AlphaModel(0.4)
    theta, vel = _segment_nodes(path, _GL3_NODES)
    ref = _exact_path_hessian(model, theta.reshape(-1, k, d), np.repeat(vel, len(_GL3_NODES), axis=0), None, n)
    got = model.path_grad_hessian(path, None)[3]
    assert got[0].shape == (n - 1, k * d, k * d) and got[1].shape == (n - 2, k * d, k * d)
    assert _rel(got[0], ref[0]) < 1e-12
    if n > 2:
        assert _rel(got[1], ref[1]) < 1e-12


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("n", [1, 2, 5])
def test_alpha_path_pass_gradient_is_the_node_kernels(rng, d, n):
    """The Hessian pass also returns Q and its gradients at the segment nodes: the very numbers
    of the separate kernel (same formulas, same order of summation), for d = 2 and 3."""
    k = 7
    path = rng.normal(size=(n + 1, k, d))
    theta, vel = _segment_nodes(path, _GL3_NODES)
    ref = _kernels.alpha_qform_grad(theta.reshape(-1, k, d), np.repeat(vel, len(_GL3_NODES), axis=0), 0.4)
    got = _AlphaModel(0.4).path_grad_hessian(path, None)[:3]
    for g, r in zip(got, ref):
        assert g.shape == r.shape and np.array_equal(g, r)


def test_alpha_path_hessian_degenerate_paths():
    """n = 1 has no interior point; n = 2 one diagonal block and no off-diagonal block."""
    path = np.linspace(np.zeros((3, 2)), np.ones((3, 2)), 2)
    diag, upper = _AlphaModel(0.5).path_grad_hessian(path, None)[3]
    assert diag.shape == (0, 6, 6) and upper.shape == (0, 6, 6)
    _, _, (diag, upper) = _energy(_AlphaModel(0.5), np.linspace(np.zeros((3, 2)), np.ones((3, 2)), 3), hessian="exact")
    assert diag.shape == (1, 6, 6) and upper.shape == (0, 6, 6) and np.allclose(diag[0], diag[0].T)


@pytest.mark.parametrize("d", [2, 3])
def test_fisher_rao_compiled_match_numpy(rng, d):
    """Fused Fisher–Rao quadratic form, gradient and second derivatives == the numpy versions of
    shapelib.geometry.metrics on the same grid (which the finite-difference tests check)."""
    from shapelib.geometry.metrics import (
        _fr_qform,
        fr_qform_compiled,
        _fr_qform_grad,
        fr_qform_grad_compiled,
        fr_qform_grad_hessian_compiled,
        _fr_qform_hessian,
        fr_qform_hessian_compiled,
    )
    from shapelib.geometry.quadrature import make_grid

    theta, vel = rng.normal(size=(2, 3, 5, d))
    s2 = 0.4
    grid = make_grid(theta, sigma2=s2, grid_margin=6)
    tol = 1e-10  # sums over ~10⁴ nodes with cancellation, in another order than numpy's: ~1e-12 apart
    assert _rel(fr_qform_compiled(theta, vel, s2, grid), _fr_qform(theta, vel, s2, grid)) < 1e-12
    grad = _fr_qform_grad(theta, vel, s2, grid)
    hess = _fr_qform_hessian(theta, vel, s2, grid)
    for got, ref in zip(fr_qform_grad_compiled(theta, vel, s2, grid), grad):
        assert _rel(got, ref) < tol
    for got, ref in zip(fr_qform_hessian_compiled(theta, vel, s2, grid), hess):
        assert _rel(got, ref) < tol
    *g2, h2 = fr_qform_grad_hessian_compiled(theta, vel, s2, grid)
    for got, ref in zip(list(g2) + list(h2), list(grad) + list(hess)):
        assert _rel(got, ref) < tol


def test_fisher_rao_compiled_forms_take_one_layout(rng):
    """The compiled Fisher–Rao forms convert their inputs once at the door: positions and velocities
    given in single precision, Fortran order and read-only give the values of the same numbers given as
    C-ordered float64, and every specialisation the compiled kernels hold is of C-ordered, writable
    float64 arrays (a transposed, read-only or float32 array would compile, and cache, another)."""
    from numba.core import types

    from shapelib.geometry import _kernels
    from shapelib.geometry.metrics import (fr_qform_compiled, fr_qform_grad_compiled, fr_qform_grad_hessian_compiled,
                                           fr_qform_hessian_compiled)
    from shapelib.geometry.quadrature import make_grid

    theta, vel = rng.normal(size=(2, 2, 4, 2)).astype(np.float32)
    exact = [a.astype(np.float64) for a in (theta, vel)]
    fortran32 = [np.asfortranarray(a) for a in (theta, vel)]
    read_only = [a.copy() for a in exact]
    for a in fortran32 + read_only:
        a.flags.writeable = False
    assert not fortran32[0].flags.c_contiguous and fortran32[0].dtype == np.float32
    assert read_only[0].flags.c_contiguous and not read_only[0].flags.writeable
    s2 = 0.4
    grid = make_grid(exact[0], sigma2=s2, grid_margin=6)
    for form in (fr_qform_compiled, fr_qform_grad_compiled, fr_qform_hessian_compiled,
                 fr_qform_grad_hessian_compiled):
        ref = _arrays(form(*exact, s2, grid))
        for odd in (fortran32, read_only):
            got = _arrays(form(*odd, s2, grid))
            assert len(got) == len(ref) > 0
            assert all(g.dtype == np.float64 and np.array_equal(g, r) for g, r in zip(got, ref))
    for kernel in (_kernels.fr_psidot, _kernels.fr_qform_grad, _kernels.fr_hessian_parts):
        arrays = [t for sig in kernel.signatures for t in sig if isinstance(t, types.Array)]
        assert arrays, kernel
        assert all(t.dtype == types.float64 and t.layout == "C" and t.mutable for t in arrays), kernel.signatures


def _arrays(out):
    """The arrays of a result, nested tuples flattened."""
    return [a for part in out for a in _arrays(part)] if isinstance(out, tuple) else [np.asarray(out)]

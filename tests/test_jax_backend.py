"""backend="jax": the JAX path energy equals the compiled kernels, its gradient is the energy's,
the L-BFGS geodesics and brackets agree with the CPU solver and are certified the same way, batches
equal single solves; the errors for a missing extra and a missing GPU. Run on JAX's CPU backend."""

import json
import subprocess
import sys

import numpy as np
import pytest

from tests.conftest import ROOT

import shapelib
from shapelib.solver.energy import path_energy
from shapelib.solver.path_metric import path_metric

jax = pytest.importorskip("jax")

from shapelib.geometry import _jax_kernels as jk  # noqa: E402
from shapelib.solver import batched  # noqa: E402

S2 = 0.5


def _shape(rng, k, d):
    return rng.normal(size=(k, d)) * 1.6


@pytest.fixture(scope="module")
def pair2():
    rng = np.random.default_rng(7)
    u = _shape(rng, 5, 2)
    return u, u + rng.normal(size=u.shape) * 0.35


def _wiggly_path(rng, u, v, n):
    path = np.linspace(u, v, n + 1) + 0.2 * rng.normal(size=(n + 1,) + u.shape)
    path[0], path[-1] = u, v
    return path


@pytest.mark.parametrize("metric", ["alpha", "fisher_rao"])
@pytest.mark.parametrize("d", [2, 3])
def test_energy_and_gradient_equal_the_compiled_kernels(metric, d):
    rng = np.random.default_rng(d)
    u = _shape(rng, 4, d)
    v = u + rng.normal(size=u.shape) * 0.5
    path = _wiggly_path(rng, u, v, 4)
    model = path_metric(metric, S2)
    e_cpu, g_cpu, _ = path_energy(model, path)
    nodes = weights = None
    if metric == "fisher_rao":
        nodes, weights = batched.stack_grids([model.prepare(path)], d)  # padded: zero weights add nothing
    e, g = jk.batched_value_and_grad(path[None], S2, nodes, weights, metric=metric)
    assert e[0] == pytest.approx(e_cpu, rel=1e-11)
    np.testing.assert_allclose(g[0], g_cpu, rtol=0, atol=1e-10 * np.abs(g_cpu).max())


def test_gradient_is_the_derivative_of_the_energy(pair2):
    """Central differences of the JAX energy along random directions (Fisher–Rao, 2-D)."""
    u, v = pair2
    rng = np.random.default_rng(3)
    path = _wiggly_path(rng, u, v, 4)
    nodes, weights = batched.stack_grids([path_metric("fisher_rao", S2).prepare(path)], 2)
    _, g = jk.batched_value_and_grad(path[None], S2, nodes, weights, metric="fisher_rao")
    h = 1e-5
    for _ in range(3):
        direction = np.zeros_like(path)
        direction[1:-1] = rng.normal(size=path[1:-1].shape)
        e = jk.batched_value_and_grad(np.stack([path + h * direction, path - h * direction]), S2,
                                      np.repeat(nodes, 2, 0), np.repeat(weights, 2, 0), metric="fisher_rao")[0]
        assert (e[0] - e[1]) / (2 * h) == pytest.approx(np.sum(g[0] * direction[1:-1]), rel=1e-6)


@pytest.fixture(scope="module")
def fr_geodesics(pair2):
    u, v = pair2
    kw = dict(metric="fisher_rao", sigma2=S2, n_steps=6, tol=1e-8, max_iter=2000)
    return (shapelib.geodesic(u, v, **kw),
            shapelib.geodesic(u, v, **kw, backend="jax", device="cpu"))


def test_converged_geodesic_matches_the_cpu_solver_and_is_certified_the_same_way(pair2, fr_geodesics):
    u, v = pair2
    cpu, gpu_path = fr_geodesics
    assert gpu_path.converged and gpu_path.log["backend"] == "jax"
    assert gpu_path.stop_reason.converged
    # same local minimum of the same discrete energy, to the solvers' tolerance
    assert gpu_path.energy == pytest.approx(cpu.energy, rel=1e-6)
    assert gpu_path.length == pytest.approx(cpu.length, rel=1e-6)
    # certified as on the CPU: the same closed-form bound, and the length is the returned path's
    # length by the CPU code's quadrature (its own grid)
    assert gpu_path.lower_bound == pytest.approx(cpu.lower_bound, rel=1e-13)
    assert gpu_path.length == pytest.approx(shapelib.path_length(gpu_path.path, metric="fisher_rao", sigma2=S2), rel=1e-11)
    assert gpu_path.energy == pytest.approx(path_energy(path_metric("fisher_rao", S2), gpu_path.path, gradient=False)[0],
                                            rel=1e-11)
    assert gpu_path.lower_bound <= gpu_path.length <= np.sqrt(gpu_path.energy) * (1 + 1e-12)
    np.testing.assert_array_equal(gpu_path.path[[0, -1]], np.stack([u, v]))


def test_batched_geodesics_equal_one_by_one(pair2, fr_geodesics):
    u, v = pair2
    rng = np.random.default_rng(11)
    v2 = u + rng.normal(size=u.shape) * 0.3
    res = batched.batched_geodesics(np.stack([u, u, v]), np.stack([v, v2, v]), metric="fisher_rao", sigma2=S2,
                                    n_steps=6, tol=1e-8, max_iter=2000, device="cpu")
    one = fr_geodesics[1]
    assert res[0].length == pytest.approx(one.length, rel=1e-10)
    assert res[0].n_iter == one.n_iter
    np.testing.assert_allclose(res[0].path, one.path, atol=1e-8)
    assert res[2].stop_reason == shapelib.StopReason.TRIVIAL and res[2].length == 0.0
    single = shapelib.geodesic(u, v2, metric="fisher_rao", sigma2=S2, n_steps=6, tol=1e-8, max_iter=2000,
                               backend="jax", device="cpu")
    assert res[1].length == pytest.approx(single.length, rel=1e-10)


def test_bracket_contains_the_cpu_value_in_2d_and_3d():
    rng = np.random.default_rng(5)
    for d, metric in ((2, "fisher_rao"), (3, "alpha")):
        u = _shape(rng, 4, d)
        v = u + rng.normal(size=u.shape) * 0.2
        b = shapelib.distance_bracket(u, v, metric=metric, sigma2=S2, rtol=1e-2, n_steps=4, max_n_steps=4,
                                      backend="jax", device="cpu", warn=False)
        cpu = shapelib.geodesic(u, v, metric=metric, sigma2=S2, n_steps=16, tol=1e-9)
        assert b.stopped_by in ("rtol", "max_n_steps") and b.log["backend"] == "jax"
        assert b.lower == pytest.approx(cpu.lower_bound, rel=1e-12)
        assert b.lower <= cpu.length <= b.upper
        assert b.upper == pytest.approx(shapelib.path_length(b.path, metric=metric, sigma2=S2), rel=1e-11)


def test_backend_and_device_are_checked():
    u = np.eye(3)[:, :2]
    with pytest.raises(ValueError, match="backend must be one of"):
        shapelib.geodesic(u, u + 0.1, sigma2=S2, backend="cuda")
    with pytest.raises(ValueError, match='needs backend="jax"'):
        shapelib.geodesic(u, u + 0.1, sigma2=S2, device="gpu")
    with pytest.raises(ValueError, match="device must be"):
        shapelib.distance_bracket(u, u + 0.1, metric="alpha", sigma2=S2, backend="jax", device="tpu0")


@pytest.mark.skipif(any(d.platform == "gpu" for d in jax.devices()), reason="a GPU is visible")
def test_gpu_without_a_gpu_is_a_one_line_error_not_a_cpu_fallback():
    u = np.eye(3)[:, :2]
    with pytest.raises(RuntimeError, match="JAX sees no GPU") as err:
        shapelib.geodesic(u, u + 0.1, metric="fisher_rao", sigma2=S2, backend="jax", device="gpu")
    assert "\n" not in str(err.value) and "shapelib[gpu]" in str(err.value)


def test_missing_jax_is_a_one_line_import_error_naming_the_extra():
    code = ("import sys; sys.modules['jax'] = None\n"
            "import numpy as np, shapelib\n"
            "u = np.eye(3)[:, :2]\n"
            "try:\n    shapelib.geodesic(u, u + 0.1, sigma2=0.5, backend='jax')\n"
            "except ImportError as e:\n    print(repr(str(e)))\n"
            "assert 'jax' not in [m.split('.')[0] for m in sys.modules if sys.modules[m] is not None]\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    assert 'pip install \\"shapelib[gpu]\\"' in proc.stdout or 'pip install "shapelib[gpu]"' in proc.stdout
    assert proc.stdout.count("\n") == 1


def test_bench_gpu_cpu_check_writes_a_record(tmp_path):
    out = tmp_path / "bench_gpu.json"
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_gpu.py"), "--cpu-check", "--json", str(out)],
                          capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr[-2000:]
    rec = json.loads(out.read_text())
    res = rec["results"]
    assert res["mode"] == "cpu-check" and res["device"]["platform"] == "cpu" and rec["machine"]["date"]
    rows = res["rows"]
    # the same pairs on both paths: certified, and the two lengths agree to the solvers' tolerance
    for row in rows["geodesic"]:
        assert row["lower"] <= row["length_jax"] and row["lower"] <= row["length_cpu"]
        assert row["length_jax"] == pytest.approx(row["length_cpu"], rel=1e-3)
    assert 0.0 <= rows["brackets"]["certified_rate"] <= 1.0

"""backend="jax": the JAX path energy equals the compiled kernels, its gradient is the energy's,
the L-BFGS geodesics and brackets agree with the CPU solver and are certified the same way, batches
equal single solves; the errors for a missing extra and a missing GPU. Run on JAX's CPU backend."""

import importlib.util
import json
import os
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import ROOT, import_or_missing

import shapelib
from shapelib.solver.energy import path_energy
from shapelib.solver.path_metric import path_metric

if "jax" not in sys.modules:  # compile time dominates these small problems: XLA's cheapest code generation
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + " --xla_backend_optimization_level=0").strip()
jax = import_or_missing("jax", "JAX (the dev or jax extra) is not installed")

from shapelib.geometry import _jax_kernels as jk  # noqa: E402
from shapelib.solver import batched  # noqa: E402
from shapelib.solver import bracket as bracket_module  # noqa: E402
from shapelib.solver.bracket import JAX_LEVEL_ITER  # noqa: E402

S2 = 0.5
#: mutmut (benchmarks/mutation.py) runs these tests against a copy of the module whose functions
#: go through a trampoline, one more stack frame between the caller and the code
UNDER_MUTMUT = any("__mutmut_" in name for name in vars(bracket_module))


def _shape(rng, k, d):
    return rng.normal(size=(k, d)) * (1.6 if d == 2 else 0.8)  # σ about half a landmark spacing


def _pair(rng, k, d, scale):
    """Two shapes in correspondence, ``v`` aligned to ``u`` (no pose warning)."""
    u = _shape(rng, k, d)
    return u, shapelib.procrustes_align(u, u + rng.normal(size=u.shape) * scale, scaling=False)


@pytest.fixture(scope="module")
def pair2():
    return _pair(np.random.default_rng(7), 5, 2, 0.35)


def _case(metric, d):
    """A wiggly path (4 segments, 4 landmarks) and its Fisher–Rao grid as the CPU solver builds it."""
    rng = np.random.default_rng(d)
    u, v = _pair(rng, 4, d, 0.5)
    path = _wiggly_path(rng, u, v, 4)
    nodes = weights = None
    if metric == "fisher_rao":
        nodes, weights = batched.stack_grids([path_metric(metric, S2).prepare(path)], d)  # padded: zero weights
    return path, nodes, weights


def _wiggly_path(rng, u, v, n):
    path = np.linspace(u, v, n + 1) + 0.2 * rng.normal(size=(n + 1,) + u.shape)
    path[0], path[-1] = u, v
    return path


@pytest.mark.parametrize("metric", ["alpha", "fisher_rao"])
@pytest.mark.parametrize("d", [2, 3])
def test_energy_and_gradient_equal_the_compiled_kernels(metric, d):
    path, nodes, weights = _case(metric, d)
    e_cpu, g_cpu, _ = path_energy(path_metric(metric, S2), path)
    e, g = jk.batched_value_and_grad(path[None], S2, nodes, weights, metric=metric)
    assert e[0] == pytest.approx(e_cpu, rel=1e-11)
    np.testing.assert_allclose(g[0], g_cpu, rtol=0, atol=1e-10 * np.abs(g_cpu).max())


@pytest.mark.parametrize("metric", ["alpha", "fisher_rao"])
def test_gradient_is_the_derivative_of_the_energy(metric):
    """Central differences of the JAX energy along random directions (2-D)."""
    path, nodes, weights = _case(metric, 2)
    rng = np.random.default_rng(3)
    _, g = jk.batched_value_and_grad(path[None], S2, nodes, weights, metric=metric)
    h = 1e-5
    for _ in range(3):
        direction = np.zeros_like(path)
        direction[1:-1] = rng.normal(size=path[1:-1].shape)
        plus, minus = (jk.batched_value_and_grad((path + s * h * direction)[None], S2, nodes, weights, metric=metric)[0][0]
                       for s in (1, -1))
        assert (plus - minus) / (2 * h) == pytest.approx(np.sum(g[0] * direction[1:-1]), rel=1e-6)


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


@pytest.mark.slow  # 7 s of CPU beyond its fixture (JAX compiles the batched Fisher–Rao programs); test_each_pair_of_a_batch_gets_its_own_geodesic checks α batches in `make test`
def test_batched_geodesics_equal_one_by_one(pair2, fr_geodesics):
    u, v = pair2
    v2 = shapelib.procrustes_align(u, _pair(np.random.default_rng(11), 5, 2, 0.3)[1] * 0.2 + 0.8 * v, scaling=False)
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


def test_each_pair_of_a_batch_gets_its_own_geodesic():
    """Three different pairs in one device batch (α, 3 landmarks, 4 steps: seconds of compilation):
    each result has its own pair's endpoints and the length and path of the CPU solver's geodesic
    of that pair alone."""
    rng = np.random.default_rng(3)
    u = _shape(rng, 3, 2)
    v = [shapelib.procrustes_align(u, u + rng.normal(size=u.shape) * s, scaling=False) for s in (0.2, 0.5, 0.9)]
    us, vs = np.stack([u, v[0], u]), np.stack(v)
    kw = dict(metric="alpha", sigma2=S2, n_steps=4, tol=1e-9, max_iter=500)
    res = batched.batched_geodesics(us, vs, device="cpu", batch_size=3, **kw)
    lengths = []
    for a, b, r in zip(us, vs, res):
        one = shapelib.geodesic(a, b, **kw)
        assert r.converged and one.converged
        np.testing.assert_array_equal(r.path[[0, -1]], np.stack([a, b]))
        assert r.length == pytest.approx(one.length, rel=1e-7)
        np.testing.assert_allclose(r.path, one.path, atol=1e-6)
        lengths.append(one.length)
    assert min(abs(p - q) for i, p in enumerate(lengths) for q in lengths[i + 1:]) > 1e-3  # three different answers


@pytest.fixture(scope="module")
def alpha3():
    """A converged 3-D α geodesic on both paths, and the JAX bracket of the same pair (same programs)."""
    path = _case("alpha", 3)[0]
    u, v = path[0], path[-1]
    kw = dict(metric="alpha", sigma2=S2, n_steps=4)
    return (u, v, shapelib.geodesic(u, v, **kw, tol=1e-9),
            shapelib.geodesic(u, v, **kw, tol=1e-9, max_iter=300, backend="jax", device="cpu"),
            shapelib.distance_bracket(u, v, **kw, rtol=1e-2, max_n_steps=4, backend="jax", device="cpu", warn=False))


def test_converged_3d_geodesic_matches_the_cpu_solver(alpha3):
    u, v, cpu, jx, _ = alpha3
    assert jx.converged and jx.energy == pytest.approx(cpu.energy, rel=1e-7)
    assert jx.length == pytest.approx(shapelib.path_length(jx.path, metric="alpha", sigma2=S2), rel=1e-11)
    assert jx.lower_bound == pytest.approx(cpu.lower_bound, rel=1e-13) and jx.lower_bound <= jx.length


@pytest.mark.parametrize("d", [2, 3])
def test_bracket_contains_the_cpu_value(pair2, fr_geodesics, alpha3, d):
    """Same closed-form lower end; the CPU solver's converged length lies inside; the upper end is
    the returned path's length by the CPU quadrature."""
    if d == 2:  # the pair of the Fisher–Rao geodesic tests: same programs
        (u, v), cpu, metric = pair2, fr_geodesics[0], "fisher_rao"
        b = shapelib.distance_bracket(u, v, metric=metric, sigma2=S2, rtol=1e-2, n_steps=6, max_n_steps=6,
                                      grid_spacing=0.35, backend="jax", device="cpu", warn=False)
    else:
        u, v, cpu, _, b = alpha3
        metric = "alpha"
    assert b.stopped_by in ("rtol", "max_n_steps") and b.log["backend"] == "jax"
    assert b.lower == pytest.approx(cpu.lower_bound, rel=1e-12)
    assert b.lower <= cpu.length <= b.upper * (1 + 1e-6)
    assert b.upper == pytest.approx(shapelib.path_length(b.path, metric=metric, sigma2=S2), rel=1e-11)


def test_backend_and_device_are_checked():
    u = np.array([[-0.5, -0.3], [0.5, -0.3], [0.0, 0.6]])  # centred: u * 1.1 has the same pose
    with pytest.raises(ValueError, match="backend must be one of"):
        shapelib.geodesic(u, u * 1.1, sigma2=S2, backend="cuda")
    with pytest.raises(ValueError, match='needs backend="jax"'):
        shapelib.geodesic(u, u * 1.1, sigma2=S2, device="gpu")
    with pytest.raises(ValueError, match="device must be"):
        shapelib.distance_bracket(u, u * 1.1, metric="alpha", sigma2=S2, backend="jax", device="tpu0")


def test_gpu_without_a_gpu_is_a_one_line_error_not_a_cpu_fallback():
    if any(d.platform == "gpu" for d in jax.devices()):  # asked here, not at collection: starting JAX's
        pytest.skip("a GPU is visible")                  # backend makes a process unsafe to fork
    u = np.array([[-0.5, -0.3], [0.5, -0.3], [0.0, 0.6]])  # centred: u * 1.1 has the same pose
    with pytest.raises(RuntimeError, match="JAX sees no GPU") as err:
        shapelib.geodesic(u, u * 1.1, metric="fisher_rao", sigma2=S2, backend="jax", device="gpu")
    assert "\n" not in str(err.value) and "shapelib[gpu]" in str(err.value)


def test_missing_jax_is_a_one_line_import_error_naming_the_extra():
    code = ("import sys; sys.modules['jax'] = None\n"
            "import numpy as np, shapelib\n"
            "u = np.eye(3)[:, :2]\n"
            "try:\n    shapelib.geodesic(u, u * 1.1, sigma2=0.5, backend='jax')\n"
            "except ImportError as e:\n    print(repr(str(e)))\n"
            "assert 'jax' not in [m.split('.')[0] for m in sys.modules if sys.modules[m] is not None]\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    assert 'pip install \\"shapelib[gpu]\\"' in proc.stdout or 'pip install "shapelib[gpu]"' in proc.stdout
    assert proc.stdout.count("\n") == 1


@pytest.mark.slow  # 35 s of CPU (the GPU benchmark's CPU check, JAX compiling in a subprocess): `make test-all`
def test_bench_gpu_cpu_check_writes_a_record(tmp_path):
    out = tmp_path / "bench_gpu.json"
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_gpu.py"), "--cpu-check", "--json", str(out)],
                          capture_output=True, text=True, timeout=900, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr[-2000:]
    rec = json.loads(out.read_text())
    res = rec["results"]
    assert res["mode"] == "cpu-check" and res["device"]["platform"] == "cpu" and rec["machine"]["date"]
    rows = res["rows"]
    spec = importlib.util.spec_from_file_location("shapelib_docs", ROOT / "docs" / "_ext" / "shapelib_docs.py")
    docs = importlib.util.module_from_spec(spec)
    sys.modules["shapelib_docs"] = docs  # dataclasses look their module up
    try:
        spec.loader.exec_module(docs)
        for table in docs.RENDERERS["bench_gpu"](res):  # the performance page renders the record
            assert table.rows and all(len(row) == len(table.header) for row in table.rows)
    finally:
        sys.modules.pop("shapelib_docs", None)
    # the same pairs on both paths: certified, and the two lengths agree to the solvers' tolerance
    for row in rows["geodesic"]:
        assert row["lower"] <= row["length_jax"] and row["lower"] <= row["length_cpu"]
        assert row["length_jax"] == pytest.approx(row["length_cpu"], rel=1e-3)
    assert 0.0 <= rows["brackets"]["certified_rate"] <= 1.0
    # the batched geodesics of ADHD-200 pairs agree with the CPU path; the record was closed as complete
    assert rows["geodesic_batch"]["max_rel_length_difference"] < 1e-3
    assert rows["geodesic_batch"]["converged"] == rows["geodesic_batch"]["pairs"]
    assert res["complete"] is True


@pytest.fixture(scope="module")
def three(pair2):
    """Three aligned shapes: the pairs of the batched test (same compiled programs)."""
    u, v = pair2
    v2 = shapelib.procrustes_align(u, _pair(np.random.default_rng(11), 5, 2, 0.3)[1] * 0.2 + 0.8 * v, scaling=False)
    return np.stack([u, v, v2])


@pytest.mark.slow  # 9 s of CPU (JAX compiles the engine's block programs): `make test-all`
@pytest.mark.filterwarnings("ignore::shapelib.PoseWarning")
def test_pairwise_engine_sends_a_block_to_the_device_as_one_batch(three, fr_geodesics):
    d = shapelib.pairwise_distances(three, metric="fisher_rao", sigma2=S2, n_steps=6, tol=1e-8, max_iter=2000,
                                    backend="jax", device="cpu", n_jobs=1, progress=False)
    np.testing.assert_array_equal(d, d.T)
    assert d[0, 1] == pytest.approx(fr_geodesics[1].length, rel=1e-10)  # the single JAX geodesic
    assert d[0, 1] == pytest.approx(fr_geodesics[0].length, rel=1e-6)  # and the CPU one


@pytest.mark.slow  # 6 s of CPU (JAX compiles the batched log maps): `make test-all`
@pytest.mark.filterwarnings("ignore::shapelib.PoseWarning")
def test_frechet_mean_with_batched_log_maps_matches_the_cpu_mean(three):
    # α: its programs do not depend on a grid, so the moving base compiles nothing new per iteration
    kw = dict(metric="alpha", sigma2=S2, n_steps=6, log_tol=1e-8, tol=1e-4)
    cpu = shapelib.frechet_mean(three, **kw, n_jobs=1)
    jx = shapelib.frechet_mean(three, **kw, backend="jax", device="cpu")
    assert jx.converged and jx.certificate <= 1e-4
    spread = np.abs(three - cpu.mean).max()
    assert np.abs(jx.mean - cpu.mean).max() <= 1e-3 * spread


@pytest.mark.parametrize("batched_entry", ["geodesics", "distance_brackets"])
def test_a_batch_warns_at_the_callers_line_as_a_single_pair_does(batched_entry):
    """The pose check of each pair of a batch names the line that called the batched entry point."""
    u = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 1.5]])
    v = u @ np.array([[0.0, -1.0], [1.0, 0.0]]) + 5.0  # rotated and moved: not aligned
    with pytest.warns(shapelib.PoseWarning) as record:
        getattr(shapelib, batched_entry)(u[None], v[None], metric="alpha", sigma2=S2, device="cpu", warn=False)
    files = {w.filename for w in record if issubclass(w.category, shapelib.PoseWarning)}
    assert len(files) == 1 and "shapelib" not in Path(files.pop()).parts  # not inside the library
    if not UNDER_MUTMUT:  # mutmut's trampoline adds a frame of its own
        assert {w.filename for w in record if issubclass(w.category, shapelib.PoseWarning)} == {__file__}


@pytest.fixture(scope="module")
def batch3():
    """One device batch of three α pairs (3 landmarks, n_steps 2 then 4): a small deformation that meets
    rtol at the first level, identical shapes, and a large one whose geodesic is longer than the bound
    (it stalls after the second level). The geodesic of each pair is longer than the chord by 0.6 % and
    11.6 %, so rtol = 1e-2 tells them apart."""
    rng = np.random.default_rng(5)
    u = rng.normal(size=(3, 2)) * 1.6
    a = shapelib.procrustes_align(u, u + 0.15 * rng.normal(size=u.shape), scaling=False)
    c = shapelib.procrustes_align(u, u + 0.8 * rng.normal(size=u.shape), scaling=False)
    us, vs = np.stack([u, a, u]), np.stack([a, a, c])
    kw = dict(metric="alpha", sigma2=S2, rtol=1e-2, n_steps=2, max_n_steps=4, level_iter=2, level_tol=1e-5,
              min_shrink=0.1)
    t0 = time.perf_counter()
    with pytest.warns(shapelib.GeodesicWarning) as record:
        out = shapelib.distance_brackets(us, vs, device="cpu", **kw)
    wall = time.perf_counter() - t0
    return us, vs, kw, out, wall, record


def test_batched_brackets_are_certified_per_pair_and_agree_with_the_cpu_brackets(batch3):
    """Each bracket: its own pair's closed-form bound and endpoints, its upper end the length of its path by
    the CPU quadrature, the CPU solver's converged geodesic inside it; the stop reasons, levels and ends of
    the CPU bracket with the same options; n_steps doubled from n_steps; the options and the time logged."""
    us, vs, kw, out, wall, _ = batch3
    assert [b.stopped_by for b in out] == ["rtol", "trivial", "stalled"]
    assert [[lv["n_steps"] for lv in b.log["levels"]] for b in out] == [[2], [], [2, 4]]
    for u, v, b in zip(us, vs, out):
        cpu = shapelib.distance_bracket(u, v, **kw, warn=False)
        assert (b.metric, b.sigma2, b.n_steps, b.stopped_by, b.converged) == (
            "alpha", S2, cpu.n_steps, cpu.stopped_by, cpu.stopped_by in ("rtol", "trivial"))
        assert b.path.shape == (b.n_steps + 1,) + u.shape
        np.testing.assert_array_equal(b.path[[0, -1]], np.stack([u, v]))
        log = b.log
        assert (log["backend"], log["hessian"], log["rtol"], log["n_steps"], log["max_n_steps"], log["level_iter"],
                log["level_tol"], log["min_shrink"]) == ("jax", None, 1e-2, 2, 4, 2, 1e-5, 0.1)
        assert log["sigma_ratio"] == pytest.approx(shapelib.sigma_ratio(np.stack([u, v]), sigma2=S2), rel=1e-12)
        assert 0.0 <= b.seconds <= wall
        if b.stopped_by == "trivial":
            assert (b.lower, b.upper, b.rel_gap, b.energy, b.n_iter) == (0.0, 0.0, 0.0, 0.0, 0)
            np.testing.assert_array_equal(b.path, np.broadcast_to(u, b.path.shape))
            continue
        assert "cpu" in log["device"].lower()
        assert b.lower == pytest.approx(shapelib.l2_distance(u, v, sigma2=S2), rel=1e-12)
        assert b.upper == pytest.approx(shapelib.path_length(b.path, metric="alpha", sigma2=S2), rel=1e-11)
        assert b.energy == pytest.approx(path_energy(path_metric("alpha", S2), b.path, gradient=False)[0], rel=1e-11)
        assert b.lower <= b.upper <= np.sqrt(b.energy) * (1 + 1e-12)
        assert b.rel_gap == pytest.approx(b.upper / b.lower - 1, rel=1e-12)
        fine = shapelib.geodesic(u, v, metric="alpha", sigma2=S2, n_steps=16, tol=1e-10)
        assert b.lower <= fine.length <= b.upper * (1 + 1e-9)
        levels = log["levels"]
        assert levels[-1]["upper"] == b.upper and levels[-1]["rel_gap"] == b.rel_gap
        assert b.n_iter == sum(lv["n_iter"] for lv in levels) and b.seconds == sum(lv["seconds"] for lv in levels)
        assert all(lv["n_iter"] <= 2 * JAX_LEVEL_ITER for lv in levels)  # level_iter · JAX_LEVEL_ITER at most
        if b.stopped_by == "rtol":  # the first level ended as soon as the energy certified rtol
            assert levels[0]["stopped_by"] == "target_energy"
            assert b.rel_gap <= 1e-2 and np.sqrt(b.energy) <= b.lower * (1 + 1e-2) * (1 + 1e-12)
        else:  # both solvers at the minimum of the discrete energy at n_steps = 4
            assert b.upper == pytest.approx(cpu.upper, rel=1e-8) and b.rel_gap > 1e-2


def test_a_batch_warns_once_for_the_pairs_above_rtol(batch3):
    *_, out, _, record = batch3
    caught = [w for w in record if issubclass(w.category, shapelib.GeodesicWarning)]
    assert len(caught) == 1
    if not UNDER_MUTMUT:  # mutmut's trampoline adds frames of its own
        assert caught[0].filename == __file__
    assert str(caught[0].message) == (f"alpha distance brackets: 1 of 3 pairs stopped above rtol 1.0e-02 "
                                      f"(first: {out[2].summary()})")


def test_a_single_jax_bracket_warns_as_the_cpu_one(batch3):
    """One pair that stops above rtol: the single-pair message, with its level, iterations and interval."""
    us, vs, kw, *_ = batch3
    with pytest.warns(shapelib.GeodesicWarning) as record:
        b = shapelib.distance_bracket(us[2], vs[2], **{**kw, "max_n_steps": 2}, backend="jax", device="cpu")
    caught = [w for w in record if issubclass(w.category, shapelib.GeodesicWarning)]
    assert len(caught) == 1
    if not UNDER_MUTMUT:  # mutmut's trampoline adds frames of its own
        assert caught[0].filename == __file__
    assert b.stopped_by == "max_n_steps" and b.n_iter > 0
    assert str(caught[0].message).startswith(
        f"alpha distance bracket stopped (max_n_steps) at relative gap {b.rel_gap:.2e} > rtol 1.0e-02 "
        f"(n_steps 2, {b.n_iter} iterations): the distance is certified only to lie in "
        f"[{b.lower:.6g}, {b.upper:.6g}]; raise max_n_steps")
    with pytest.warns(shapelib.GeodesicWarning) as record:  # σ = 0.04 landmark spacings (and ScaleWarning)
        b = shapelib.distance_bracket(20 * us[2], 20 * vs[2], **kw, backend="jax", device="cpu")
    caught = [w for w in record if issubclass(w.category, shapelib.GeodesicWarning)]
    assert len(caught) == 1 and b.stopped_by == "stalled"
    assert f"; sigma is {b.log['sigma_ratio']:.3g} landmark spacings" in str(caught[0].message)
    assert b.log["sigma_ratio"] == pytest.approx(shapelib.sigma_ratio(20 * np.stack([us[2], vs[2]]), sigma2=S2))


@pytest.mark.parametrize("kwargs, match", [({"rtol": 0.0}, "rtol"), ({"n_steps": 0}, "n_steps"),
                                           ({"max_n_steps": 1}, "max_n_steps"), ({"device": "tpu"}, "device"),
                                           ({"metric": "euclid"}, "metric must be"), ({"sigma2": 0.0}, "sigma2")])
def test_batched_bracket_arguments_are_checked_before_any_solve(kwargs, match):
    u = np.array([[-0.5, -0.3], [0.5, -0.3], [0.0, 0.6]])
    with pytest.raises(ValueError, match=match):
        shapelib.distance_brackets(u[None], 1.1 * u[None], **{"metric": "alpha", "sigma2": S2, "n_steps": 2,
                                                              "device": "cpu", **kwargs})


def test_each_level_of_a_batch_is_the_device_solver_warm_started_from_the_last(batch3):
    """The pair that goes on first in the batch: level 1 (n_steps 2, both unfinished pairs) is
    batched_geodesics from the straight line, level 2 (n_steps 4, that pair alone) batched_geodesics
    started from level 1's path refined, with level_iter · JAX_LEVEL_ITER iterations, level_tol, a
    JAX_LEVEL_WINDOW window and the target (lower · (1 + rtol))²; the pair after it is still done."""
    from shapelib.solver.bracket import JAX_LEVEL_WINDOW, refine_path

    us, vs, kw, *_ = batch3
    us, vs = us[::-1].copy(), vs[::-1].copy()  # the large deformation first, then the trivial and the small one
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", shapelib.GeodesicWarning)
        one = shapelib.distance_brackets(us, vs, device="cpu", **{**kw, "max_n_steps": 2})
    with pytest.warns(shapelib.GeodesicWarning) as record:
        two = shapelib.distance_brackets(us, vs, device="cpu", **kw)
    assert [b.stopped_by for b in two] == ["stalled", "trivial", "rtol"]
    assert [str(w.message) for w in record if issubclass(w.category, shapelib.GeodesicWarning)] == [
        f"alpha distance brackets: 1 of 3 pairs stopped above rtol 1.0e-02 (first: {two[0].summary()})"]
    lower = [b.lower for b in two]
    solve = dict(metric="alpha", sigma2=S2, tol=kw["level_tol"], max_iter=kw["level_iter"] * JAX_LEVEL_ITER,
                 window=JAX_LEVEL_WINDOW, device="cpu", warn=False)
    first = batched.batched_geodesics(us[[0, 2]], vs[[0, 2]], n_steps=2, lower_bounds=[lower[0], lower[2]],
                                      target_energy=[(lower[0] * 1.01) ** 2, (lower[2] * 1.01) ** 2], **solve)
    for b, r in zip((one[0], one[2]), first):
        np.testing.assert_array_equal(b.path, r.path)
        assert b.n_iter == r.n_iter
    second = batched.batched_geodesics(us[:1], vs[:1], n_steps=4, init=refine_path(one[0].path)[None],
                                       lower_bounds=lower[:1], target_energy=[(lower[0] * 1.01) ** 2], **solve)[0]
    level = two[0].log["levels"][1]
    assert level["n_steps"] == 4 and level["n_iter"] == second.n_iter
    np.testing.assert_array_equal(two[0].path, second.path)


def test_a_device_bracket_of_relabelled_landmarks_reports_an_infinite_gap(batch3):
    """Relabelled landmarks: the densities coincide, so the bound is 0 while the landmarks must move;
    the gap is infinite (no division by zero) and the bracket stalls, as on the CPU."""
    us, _, kw, *_ = batch3
    u = us[0]
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        warnings.simplefilter("ignore", shapelib.PoseWarning)
        b = shapelib.distance_bracket(u, u[[1, 0, 2]], **kw, backend="jax", device="cpu", warn=False)
    assert b.lower == 0.0 and b.upper > 0.1 and b.rel_gap == np.inf and b.stopped_by == "stalled"


def test_a_fisher_rao_device_batch_uses_the_grid_asked_for(pair2):
    """grid_spacing and grid_margin reach the bound and the length: both are the CPU quadrature's on
    that grid, not on the default one."""
    u, v = pair2
    grid = dict(grid_spacing=0.45, grid_margin=4.5)
    b = shapelib.distance_brackets(u[None], v[None], metric="fisher_rao", sigma2=S2, rtol=1e-2, n_steps=6,
                                   max_n_steps=6, device="cpu", warn=False, **grid)[0]
    assert (b.log["grid_spacing"], b.log["grid_margin"]) == (0.45, 4.5)
    assert b.lower == pytest.approx(shapelib.fisher_rao_lower_bound(u, v, sigma2=S2, **grid), rel=1e-13)
    assert b.lower != pytest.approx(shapelib.fisher_rao_lower_bound(u, v, sigma2=S2), rel=1e-13)
    assert b.upper == pytest.approx(shapelib.path_length(b.path, metric="fisher_rao", sigma2=S2, **grid), rel=1e-11)
    assert b.upper != pytest.approx(shapelib.path_length(b.path, metric="fisher_rao", sigma2=S2), rel=1e-11)


def test_a_device_bracket_of_identical_shapes_is_trivial_and_logs_no_hessian(batch3):
    """No solve: zero bounds at once, the time since the call, and hessian None (L-BFGS uses none)."""
    us, _, kw, *_ = batch3
    t0 = time.perf_counter()
    b = shapelib.distance_bracket(us[0], us[0].copy(), **{**kw, "n_steps": 3, "max_n_steps": 3}, backend="jax",
                                  device="cpu")
    wall = time.perf_counter() - t0
    assert (b.lower, b.upper, b.rel_gap, b.n_iter, b.stopped_by, b.n_steps) == (0.0, 0.0, 0.0, 0, "trivial", 3)
    assert b.path.shape == (4,) + us[0].shape and 0.0 <= b.seconds <= wall
    assert b.log["backend"] == "jax" and b.log["hessian"] is None and b.log["levels"] == []

"""The geodesic module's public door (shapelib.solver.geodesic) against independent values: closed
forms of one-landmark shapes (flat metrics: the Fisher–Rao metric of one isotropic Gaussian is I/σ²,
the α metric I/(8πσ⁴)), the L² distance of two mixtures summed from Gaussian overlaps, the Bhattacharyya
coefficient of two Gaussians, finite differences of the metric tensor (the Christoffel symbols of
eq. 11), the conserved speed of a geodesic, RK4's fourth order, and the documented entry checks and
underflow rule."""

import warnings

import numpy as np
import pytest
from scipy.spatial import cKDTree

import shapelib as sl
from shapelib._validate import set_checked
from shapelib.solver import geodesic as geodesic_module
from shapelib.geometry.scale import SIGMA_RATIO_MIN, ScaleWarning
from shapelib.solver.geodesic import (GeodesicResult, GeodesicWarning, _check_entries, _mark_underflow, _underflow,
                                      alpha_lower_bound, check_entry, fisher_rao_lower_bound, geodesic,
                                      geodesic_acceleration, geodesics, path_length, shoot)

# four well separated landmarks (in pose with themselves), a generic velocity
U = np.array([[0.0, 0.0], [1.5, 0.2], [1.2, 1.6], [-0.3, 1.1]])
V0 = np.array([[0.3, -0.2], [-0.1, 0.4], [0.2, 0.1], [-0.3, -0.2]])


def _overlap(a, b, s2):
    """∫ N(x; a, σ²I) N(x; b, σ²I) dx = N(a − b; 0, 2σ²I)."""
    d = a.shape[-1]
    return np.exp(-np.sum((a - b) ** 2) / (4 * s2)) / (4 * np.pi * s2) ** (d / 2)


def _l2(u, v, s2):
    """‖p_u − p_v‖ of two equal-weight mixtures, summed from the pairwise Gaussian overlaps."""
    k = len(u)
    tot = sum(_overlap(a, b, s2) for a in u for b in u) + sum(_overlap(a, b, s2) for a in v for b in v) \
        - 2 * sum(_overlap(a, b, s2) for a in u for b in v)
    return np.sqrt(tot) / k


# --------------------------------------------------------------------------------------------- path_length


@pytest.mark.parametrize("s2", [0.3, 1.0])
def test_path_length_of_one_landmark_is_the_flat_distance(s2):
    """K = 1: g_FR = I/σ², g_α = I/(8πσ⁴) (d = 2): the length of any straight path is |Δ| times √g."""
    path = np.array([[[0.0, 0.0]], [[0.25, 0.1]], [[1.0, 0.4]]])  # uneven steps: the same straight line
    dist = np.linalg.norm([1.0, 0.4])
    assert path_length(path, metric="alpha", sigma2=s2) == pytest.approx(dist / np.sqrt(8 * np.pi * s2**2), rel=1e-12)
    # the quadrature grid's margin is what limits the Fisher–Rao value: 9σ leaves nothing
    fine = path_length(path, metric="fisher_rao", sigma2=s2, grid_margin=9.0)
    assert fine == pytest.approx(dist / np.sqrt(s2), rel=1e-13)
    default = path_length(path, metric="fisher_rao", sigma2=s2)
    assert default == pytest.approx(dist / np.sqrt(s2), rel=1e-8)
    # the options reach the grid: a 3σ margin or a 2σ step is visibly worse
    assert abs(path_length(path, metric="fisher_rao", sigma2=s2, grid_margin=3.0) / fine - 1) > 1e-4
    assert abs(path_length(path, metric="fisher_rao", sigma2=s2, grid_spacing=2.0, grid_margin=9.0) / fine - 1) > 1e-4


def test_path_length_checks_its_path():
    one = np.zeros((1, 3, 2))
    with pytest.raises(ValueError, match=r"path must have shape \(n \+ 1, K, d\) with n >= 1; got \(1, 3, 2\)"):
        path_length(one, sigma2=0.5)
    with pytest.raises(ValueError, match="path must have shape"):
        path_length(np.zeros((3, 2)), sigma2=0.5)
    assert path_length(np.zeros((2, 3, 2)), sigma2=0.5) == 0.0  # the smallest path accepted
    bad = np.zeros((3, 3, 2))
    bad[1, 0, 0] = np.inf
    with pytest.raises(ValueError, match="^path contains non-finite values$"):
        path_length(bad, sigma2=0.5)
    with pytest.raises(ValueError, match="sigma2"):
        path_length(np.zeros((2, 3, 2)), sigma2=0.0)


# --------------------------------------------------------------------------------------------- bounds


@pytest.mark.parametrize("s2", [0.2, 0.5, 2.0])
def test_fisher_rao_bound_of_one_landmark_is_the_bhattacharyya_angle(s2):
    """Two Gaussians N(a, σ²I), N(b, σ²I): ∫√(p_a p_b) = exp(−|a − b|²/(8σ²))."""
    u, v = np.array([[0.0, 0.0]]), np.array([[1.0, 0.4]])
    exact = 2 * np.arccos(np.exp(-np.sum((v - u) ** 2) / (8 * s2)))
    assert fisher_rao_lower_bound(u, v, sigma2=s2, grid_margin=9.0) == pytest.approx(exact, rel=1e-12)
    assert fisher_rao_lower_bound(u, v, sigma2=s2) == pytest.approx(exact, rel=1e-8)
    # the grid options are the quadrature's: a 3σ margin or a 2σ step misses
    assert abs(fisher_rao_lower_bound(u, v, sigma2=s2, grid_margin=3.0) / exact - 1) > 1e-4
    assert abs(fisher_rao_lower_bound(u, v, sigma2=s2, grid_spacing=2.0, grid_margin=9.0) / exact - 1) > 1e-4
    with pytest.raises(ValueError, match="^grid_spacing must be a positive"):
        fisher_rao_lower_bound(u, v, sigma2=s2, grid_spacing=0.0)
    with pytest.raises(ValueError, match="^grid_margin must be a positive"):
        fisher_rao_lower_bound(u, v, sigma2=s2, grid_margin=-1.0)


@pytest.mark.parametrize("d", [2, 3])
def test_alpha_bound_is_the_l2_distance_from_gaussian_overlaps(d):
    rng = np.random.default_rng(3)
    u = np.array([[0.0, 0.0, 0.0], [1.5, 0.2, 0.3], [1.2, 1.6, -0.2]])[:, :d]
    v = sl.procrustes_align(u, u + 0.2 * rng.normal(size=u.shape), scaling=False)
    assert alpha_lower_bound(u, v, sigma2=0.5) == pytest.approx(_l2(u, v, 0.5), rel=1e-10)
    with pytest.raises(ValueError, match="sigma2"):
        alpha_lower_bound(u, v, sigma2=-0.5)


def test_bounds_check_the_pose_and_name_themselves():
    u = U
    v = U @ np.array([[0.0, -1.0], [1.0, 0.0]]).T + [3.0, 0.0]  # the same shape turned and moved
    with pytest.warns(sl.PoseWarning, match="fisher_rao_bound depends on the pose"):
        fisher_rao_lower_bound(u, v, sigma2=0.5)
    with pytest.warns(sl.PoseWarning, match="alpha_bound depends on the pose"):
        alpha_lower_bound(u, v, sigma2=0.5)
    with pytest.raises(ValueError, match="same number of landmarks"):
        fisher_rao_lower_bound(u, v[:3], sigma2=0.5)


# --------------------------------------------------------------------------------------------- entry checks


def test_check_entry_returns_sigma_over_the_mean_nearest_spacing():
    rng = np.random.default_rng(5)
    u = rng.uniform(0, 4, size=(7, 2))
    v = u + 0.01 * rng.normal(size=u.shape)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ratio = check_entry(u, v, 0.36, metric="alpha", stacklevel=3)
    spacing = np.mean([cKDTree(s).query(s, k=2)[0][:, 1].mean() for s in (u, v)])
    assert ratio == pytest.approx(0.6 / spacing, rel=1e-12)


def test_check_entry_refuses_what_it_should():
    with pytest.raises(ValueError, match=r"metric must be one of \('alpha', 'fisher_rao'\); got 'l2'"):
        check_entry(U, U, 0.5, metric="l2", stacklevel=3)
    with pytest.raises(ValueError, match=r"^u: landmarks must have d = 2 or 3 coordinates; got 4 dimensions"):
        check_entry(np.zeros((3, 4)), np.zeros((3, 4)), 0.5, metric="alpha", stacklevel=3)
    square = 10.0 * np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    # σ = 0.3 is 0.03 spacings: too small for the Fisher–Rao quadrature (an error before any work) ...
    with pytest.warns(ScaleWarning), pytest.raises(ValueError, match="fisher_rao.*too small"):
        check_entry(square, square, 0.09, metric="fisher_rao", stacklevel=3)
    # ... named by the bound that asks
    with pytest.warns(ScaleWarning), pytest.raises(ValueError, match=r"^fisher_rao_bound: sigma2 = 0.09 is too small"):
        check_entry(square, square, 0.09, metric="fisher_rao", stacklevel=3, what="fisher_rao_bound")
    # ... but only a warning for α, whose metric is closed form
    with pytest.warns(ScaleWarning):
        assert check_entry(square, square, 0.09, metric="alpha", stacklevel=3) == pytest.approx(0.03)


def test_check_entry_of_a_bound_inside_a_checked_set():
    """The α bound skips the per-pair scale check where the pairwise engine checked the set; the
    geodesic and the Fisher–Rao bound do not."""
    square = 10.0 * np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    with set_checked():
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            assert check_entry(square, square, 0.09, metric="alpha", stacklevel=3, what="alpha_bound") is None
        with pytest.warns(ScaleWarning):
            assert check_entry(square, square, 0.09, metric="alpha", stacklevel=3) == pytest.approx(0.03)
    with pytest.warns(ScaleWarning):
        assert check_entry(square, square, 0.09, metric="alpha", stacklevel=3, what="alpha_bound") \
            == pytest.approx(0.03)


def test_check_entries_names_the_pair_and_returns_each_ratio():
    us = np.stack([U, 2 * U])
    vs = us + 0.01  # moved: a PoseWarning, not the subject here
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sl.PoseWarning)
        out_u, out_v, ratios = _check_entries(us, vs, 1.0, metric="alpha", stacklevel=3)
    assert np.array_equal(out_u, us) and np.array_equal(out_v, vs)
    spacing = cKDTree(U).query(U, k=2)[0][:, 1].mean()  # (u and u + 0.01 have the same spacing)
    assert ratios == pytest.approx([1 / spacing, 1 / (2 * spacing)], rel=1e-12)
    bad = us.copy()
    bad[1, 2, 0] = np.nan
    with pytest.raises(ValueError, match=r"vs\[1\]"):
        _check_entries(us, bad, 1.0, metric="alpha", stacklevel=3)
    with pytest.raises(ValueError, match=r"us\[1\]"):
        _check_entries(bad, us, 1.0, metric="alpha", stacklevel=3)


# --------------------------------------------------------------------------------------------- underflow rule


def _result(**kw):
    base = dict(path=np.zeros((5, 3, 2)), length=3.0, energy=9.0, lower_bound=1.0, converged=True, n_iter=0,
                grad_norm=0.0, rel_energy_change=0.0, max_step_over_sigma=1.0, metric="alpha", sigma2=0.01,
                log={"stopped_by": "newton_decrement"})
    base.update(kw)
    return GeodesicResult(**base)


def test_underflow_rule_as_documented():
    """Converged before the first step, several landmarks, σ below SIGMA_RATIO_MIN spacings and a
    length over twice the bound: not a geodesic. An energy of zero between distinct shapes: neither."""
    low = SIGMA_RATIO_MIN / 2
    why = _underflow(_result(), low)
    assert why.startswith("the solver stopped before its first step with length 3")
    assert "3 times the lower bound 1" in why and "norm 0.00e+00" in why and "sigma = 0.1 is 0.1 landmark" in why
    assert _underflow(_result(grad_norm=None), low) is not None
    assert _underflow(_result(), SIGMA_RATIO_MIN) is None  # the threshold itself is fine
    assert _underflow(_result(), 0.999 * SIGMA_RATIO_MIN) is not None
    assert _underflow(_result(length=2.0), low) is None  # twice the bound exactly: fine
    assert _underflow(_result(length=2.001), low) is not None
    assert _underflow(_result(path=np.zeros((5, 1, 2))), low) is None  # one landmark: nothing to bend
    assert _underflow(_result(path=np.zeros((5, 2, 2))), low) is not None  # two landmarks: their overlap bends
    assert "2.5 times the lower bound 2," in _underflow(_result(length=5.0, lower_bound=2.0), low)
    assert _underflow(_result(n_iter=1), low) is None
    assert _underflow(_result(converged=False), low) is None
    assert _underflow(_result(log={"stopped_by": "trivial"}), low) is None
    zero = _underflow(_result(energy=0.0, n_iter=3), 1.0)
    assert zero.startswith("the path energy underflows to 0.0 between distinct shapes (sigma = 0.1 is 1 landmark")
    assert _underflow(_result(energy=1e-300, n_iter=3), 1.0) is None


def test_mark_underflow_marks_only_what_the_rule_names():
    r = _result()
    reason = _mark_underflow(r, SIGMA_RATIO_MIN / 2)
    assert reason is not None and r.converged is False
    assert r.log["stopped_by"] == "underflow" and r.log["reason"] == reason
    assert r.stop_reason is sl.StopReason.UNDERFLOW
    ok = _result(n_iter=2)
    assert _mark_underflow(ok, SIGMA_RATIO_MIN / 2) is None
    assert ok.converged and ok.log == {"stopped_by": "newton_decrement"}


def test_geodesic_marks_the_underflows_it_meets():
    """σ = 4e-5 spacings of 10: every overlap of two landmarks underflows, the gradient is zero and the
    solver stops before its first step on a path 60 times the bound; and two shapes 1e-200 apart have
    a path energy that underflows to 0. Neither is a geodesic, and the results say so."""
    u = 10.0 * np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    v = u + [[0.05, 0.0], [0.0, 0.0], [0.0, 0.0]]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ScaleWarning)
        warnings.simplefilter("ignore", sl.PoseWarning)
        with pytest.warns(GeodesicWarning, match="alpha geodesic not converged: the solver stopped before its "
                                                 "first step.*Bring the shapes to a scale that fits sigma2"):
            r = geodesic(u, v, metric="alpha", sigma2=1.6e-7, n_steps=2)
        assert not r.converged and r.log["stopped_by"] == "underflow" and r.n_iter == 0
        assert r.length > 2 * r.lower_bound
        with warnings.catch_warnings():
            warnings.simplefilter("error", GeodesicWarning)
            quiet = geodesic(u, v, metric="alpha", sigma2=1.6e-7, n_steps=2, warn=False)
        assert not quiet.converged and quiet.log["stopped_by"] == "underflow"
        tiny = u / 10 + [[1e-200, 0.0], [0.0, 0.0], [0.0, 0.0]]
        with pytest.warns(GeodesicWarning, match="the path energy underflows to 0.0 between distinct shapes"):
            z = geodesic(u / 10, tiny, metric="alpha", sigma2=0.5, n_steps=2)
        assert z.energy == 0.0 and not z.converged


# --------------------------------------------------------------------------------------------- geodesic door


def test_geodesic_of_one_landmark_is_the_straight_line_at_the_flat_distance():
    u, v = np.array([[0.0, 0.0]]), np.array([[1.0, 0.4]])
    dist = np.linalg.norm(v - u)
    r = geodesic(u, v, metric="fisher_rao", sigma2=0.5, n_steps=4, grid_margin=9.0)
    assert r.length == pytest.approx(dist / np.sqrt(0.5), rel=1e-12)
    assert r.lower_bound == pytest.approx(2 * np.arccos(np.exp(-dist**2 / (8 * 0.5))), rel=1e-12)
    assert np.allclose(r.path[:, 0], np.linspace(u[0], v[0], 5), atol=1e-9)
    coarse = geodesic(u, v, metric="fisher_rao", sigma2=0.5, n_steps=4, grid_margin=3.0)
    assert abs(coarse.length / r.length - 1) > 1e-4  # the grid options reach the solver


def test_geodesic_reversed_pair_reverses_the_path():
    """d(u, v) = d(v, u) and the geodesic from v is the one from u run backwards."""
    rng = np.random.default_rng(7)
    v = sl.procrustes_align(U, U + 0.3 * rng.normal(size=U.shape), scaling=False)
    fwd = geodesic(U, v, metric="alpha", sigma2=0.5, n_steps=6, tol=1e-12)
    back = geodesic(v, U, metric="alpha", sigma2=0.5, n_steps=6, tol=1e-12)
    assert fwd.converged and back.converged
    assert back.length == pytest.approx(fwd.length, rel=1e-8)
    assert np.allclose(back.path[::-1], fwd.path, atol=1e-5)
    assert fwd.lower_bound == pytest.approx(_l2(U, v, 0.5), rel=1e-10)


def test_geodesic_options_and_errors():
    rng = np.random.default_rng(8)
    v = sl.procrustes_align(U, U + 0.3 * rng.normal(size=U.shape), scaling=False)
    r = geodesic(U, v, sigma2=0.5, n_steps=3, tol=1e-3, max_iter=40, window=2)
    assert r.path.shape == (4, 4, 2) and r.n_iter <= 40
    with pytest.raises(ValueError, match="backend"):
        geodesic(U, v, sigma2=0.5, backend="tpu")
    with pytest.raises(ValueError, match="hessian must be"):
        geodesic(U, v, sigma2=0.5, hessian="bfgs")


def test_geodesics_on_the_cpu_pass_every_option_to_geodesic():
    rng = np.random.default_rng(10)
    vs = np.stack([sl.procrustes_align(U, U + 0.3 * rng.normal(size=U.shape), scaling=False) for _ in range(2)])
    us = np.stack([U, U])
    kw = dict(metric="fisher_rao", sigma2=0.5, n_steps=3, tol=1e-9, max_iter=6, window=2, grid_spacing=0.5,
              grid_margin=7.0, hessian="model", warn=False)
    out = geodesics(us, vs, backend="cpu", **kw)
    with warnings.catch_warnings():
        warnings.simplefilter("error", GeodesicWarning)  # warn=False reaches each geodesic
        stopped = geodesics(us, vs, backend="cpu", **{**kw, "max_iter": 1})
    assert not any(r.converged for r in stopped)
    for r, v in zip(out, vs):
        one = geodesic(U, v, **kw)
        assert np.array_equal(r.path, one.path) and r.n_iter == one.n_iter <= 6 and r.log["hessian"] == "model"
        assert (r.log["grid_spacing"], r.log["grid_margin"], r.log["tol"]) == (0.5, 7.0, 1e-9)
    with pytest.warns(GeodesicWarning, match="did not converge"):
        geodesics(us, vs, backend="cpu", **{**kw, "warn": True, "max_iter": 1})


def _no_device(monkeypatch):
    """check_backend asks JAX for the device, which starts JAX's multithreaded backend (a process
    forked after that, as mutmut's are, can hang): the device is taken as named instead."""
    from shapelib.solver import batched

    monkeypatch.setattr(batched, "jax_device", lambda device=None: device)


def test_geodesic_on_a_device_hands_the_pair_over(monkeypatch):
    """geodesic(backend="jax"): the pair, checked as on the CPU, goes to the batched solver as a batch
    of one with every option; its non-convergence warns with the L-BFGS count; the underflow rule
    applies. The batch is solved here by the CPU solver (no JAX needed)."""
    calls = []
    _no_device(monkeypatch)
    monkeypatch.setattr(geodesic_module, "batched_geodesics", _batched_on_the_cpu(calls, init=True))
    rng = np.random.default_rng(14)
    v = sl.procrustes_align(U, U + 0.3 * rng.normal(size=U.shape), scaling=False)
    r = geodesic(U, v, sigma2=1, backend="jax", device="cpu")
    call = calls[-1]
    assert (call["metric"], call["sigma2"], call["n_steps"], call["tol"], call["max_iter"], call["window"]) \
        == ("alpha", 1.0, 16, 1e-6, 500, 5)
    assert type(call["sigma2"]) is float and call["grid"] == (0.35, 6.0) and call["device"] == "cpu"
    assert call["warn"] is False and call["init"] is None
    assert np.array_equal(call["us"], U[None]) and np.array_equal(call["vs"], v[None])
    assert r.converged and r.length == geodesic(U, v, sigma2=1.0).length
    start = np.linspace(U, v, 4)
    geodesic(U, v, metric="fisher_rao", sigma2=0.5, n_steps=3, tol=1e-4, max_iter=40, window=3, grid_spacing=0.5,
             grid_margin=7.0, init=start.tolist(), backend="jax", device="cpu")
    call = calls[-1]
    assert (call["metric"], call["n_steps"], call["tol"], call["max_iter"], call["window"], call["grid"]) \
        == ("fisher_rao", 3, 1e-4, 40, 3, (0.5, 7.0))
    assert np.array_equal(call["init"], start[None])
    with pytest.warns(GeodesicWarning, match=r"^alpha geodesic did not converge in 1 L-BFGS iterations \(") as seen:
        stuck = geodesic(U, v, sigma2=0.5, max_iter=1, backend="jax", device="cpu")
    assert stuck.summary() in str(seen[0].message)
    assert UNDER_MUTMUT or seen[0].filename == __file__  # the caller's line (mutmut's trampoline adds a frame)
    with warnings.catch_warnings():
        warnings.simplefilter("error", GeodesicWarning)
        geodesic(U, v, sigma2=0.5, max_iter=1, backend="jax", device="cpu", warn=False)
    for bad in ("bfgs", None):
        with pytest.raises(ValueError, match="^hessian must be 'exact' or 'model'; got"):
            geodesic(U, v, sigma2=0.5, hessian=bad, backend="jax", device="cpu")
    assert geodesic(U, v, sigma2=0.5, hessian="model", backend="jax", device="cpu").converged
    far = 10.0 * np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ScaleWarning)
        warnings.simplefilter("ignore", sl.PoseWarning)
        with pytest.warns(GeodesicWarning, match="alpha geodesic not converged: the solver stopped before its first"):
            marked = geodesic(far, far + [[0.05, 0.0], [0.0, 0.0], [0.0, 0.0]], sigma2=1.6e-7, n_steps=2,
                              backend="jax", device="cpu")
    assert marked.log["stopped_by"] == "underflow"


def _batched_on_the_cpu(calls, init=False):
    """A stand-in for shapelib.solver.batched.batched_geodesics (JAX): each pair minimised by the CPU
    path solver, unchecked and unmarked as the device's results are."""
    from shapelib.solver.minimise import minimise_path
    from shapelib.solver.path_metric import path_metric

    def run(us, vs, *, metric, sigma2, n_steps, tol, max_iter, window, grid_spacing, grid_margin, device, warn,
            batch_size=None, **more):
        assert set(more) <= ({"init"} if init else set())
        starts = more.get("init")
        calls.append(dict(us=np.array(us), vs=np.array(vs), metric=metric, sigma2=sigma2, n_steps=n_steps, tol=tol,
                          max_iter=max_iter, window=window, grid=(grid_spacing, grid_margin), device=device,
                          batch_size=batch_size, warn=warn, init=starts))
        model = path_metric(metric, sigma2, grid_spacing=grid_spacing, grid_margin=grid_margin)
        return [minimise_path(model, u, v, n_steps=n_steps, tol=tol, max_iter=max_iter, window=window,
                              init=None if starts is None else starts[i], warn=False, length_scale=np.sqrt(sigma2),
                              sigma2=sigma2) for i, (u, v) in enumerate(zip(us, vs))]
    return run


def test_geodesics_on_a_device_hand_the_checked_batch_over(monkeypatch):
    """backend="jax" (the default): the pairs are checked as geodesic checks them, handed to the batched
    solver in one call with every option, marked where they underflow, and one warning names the failures.
    The batch is solved here pair by pair by the CPU solver (no JAX needed)."""
    calls = []
    _no_device(monkeypatch)
    monkeypatch.setattr(geodesic_module, "batched_geodesics", _batched_on_the_cpu(calls))
    rng = np.random.default_rng(13)
    vs = np.stack([sl.procrustes_align(U, U + 0.3 * rng.normal(size=U.shape), scaling=False) for _ in range(2)])
    us = np.stack([U, U])
    out = geodesics(us.tolist(), vs, sigma2=1, device="cpu")
    call = calls[-1]
    assert (call["metric"], call["sigma2"], call["n_steps"], call["tol"], call["max_iter"], call["window"]) \
        == ("alpha", 1.0, 16, 1e-6, 500, 5)  # geodesic's defaults
    assert type(call["sigma2"]) is float and call["grid"] == (0.35, 6.0) and call["device"] == "cpu"
    assert call["batch_size"] is None and call["warn"] is False
    assert np.array_equal(call["us"], us) and np.array_equal(call["vs"], vs)
    for r, v in zip(out, vs):
        assert r.converged and r.length == geodesic(U, v, sigma2=1.0).length
    geodesics(us, vs, metric="fisher_rao", sigma2=0.5, n_steps=3, tol=1e-4, max_iter=40, window=3, grid_spacing=0.5,
              grid_margin=7.0, device="cpu", batch_size=7)
    call = calls[-1]
    assert (call["metric"], call["n_steps"], call["tol"], call["max_iter"], call["window"], call["grid"],
            call["batch_size"]) == ("fisher_rao", 3, 1e-4, 40, 3, (0.5, 7.0), 7)
    # a pair that stops early: one warning for the batch, naming the count and the first failure
    with pytest.warns(GeodesicWarning, match=r"alpha geodesics: 2 of 2 pairs did not converge \(first: ") as seen:
        stuck = geodesics(us, vs, sigma2=0.5, max_iter=1, device="cpu")
    assert len([w for w in seen if issubclass(w.category, GeodesicWarning)]) == 1
    assert stuck[0].summary() in str(seen[0].message) and not any(r.converged for r in stuck)
    with warnings.catch_warnings():
        warnings.simplefilter("error", GeodesicWarning)
        geodesics(us, vs, sigma2=0.5, max_iter=1, device="cpu", warn=False)
        geodesics(us, vs, sigma2=0.5, device="cpu")  # all converge: no warning
    # the underflow rule marks each pair as geodesic does
    far = 10.0 * np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ScaleWarning)
        warnings.simplefilter("ignore", sl.PoseWarning)
        with pytest.warns(GeodesicWarning, match="1 of 2 pairs"):
            marked = geodesics(np.stack([far / 10, far]), np.stack([far / 10 + 0.01, far + [[0.05, 0], [0, 0], [0, 0]]]),
                               sigma2=1.6e-7 * 100, n_steps=2, device="cpu")
    assert [r.log["stopped_by"] for r in marked][1] == "underflow" and marked[0].converged
    # the entry checks name the pair
    bad = vs.copy()
    bad[1, 0, 0] = np.nan
    with pytest.raises(ValueError, match=r"vs\[1\]"):
        geodesics(us, bad, sigma2=0.5, device="cpu")
    with pytest.raises(ValueError, match="sigma2"):
        geodesics(us, vs, sigma2=0.0, device="cpu")
    with pytest.raises(ValueError, match="metric must be"):
        geodesics(us, vs, metric="l2", sigma2=0.5, device="cpu")
    with pytest.raises(ValueError, match="device"):
        geodesics(us, vs, sigma2=0.5, device="tpu")


def test_geodesics_on_the_cpu_are_geodesic_pair_by_pair():
    rng = np.random.default_rng(9)
    vs = np.stack([sl.procrustes_align(U, U + 0.2 * rng.normal(size=U.shape), scaling=False) for _ in range(2)])
    us = np.stack([U, U])
    out = geodesics(us, vs, sigma2=0.5, n_steps=4, tol=1e-9, backend="cpu")
    for r, v in zip(out, vs):
        one = geodesic(U, v, sigma2=0.5, n_steps=4, tol=1e-9)
        assert r.length == one.length and np.array_equal(r.path, one.path)
    with pytest.raises(ValueError, match="backend"):
        geodesics(us, vs, sigma2=0.5, backend="tpu")


# --------------------------------------------------------------------------------------------- the geodesic ODE


def _christoffel_acceleration(theta, v, s2, h=1e-5):
    """−g⁻¹ Γ(v, v) with Γ_k = Σ_ij (∂_i g_kj − ½ ∂_k g_ij) v_i v_j, ∂g by central differences of the
    dense α metric tensor (shapelib.alpha_metric)."""
    x, w = theta.ravel(), v.ravel()
    n = x.size
    g = sl.alpha_metric(theta, sigma2=s2)
    dg = np.empty((n, n, n))
    for i in range(n):
        e = np.zeros(n)
        e[i] = h
        dg[i] = (sl.alpha_metric((x + e).reshape(theta.shape), sigma2=s2)
                 - sl.alpha_metric((x - e).reshape(theta.shape), sigma2=s2)) / (2 * h)
    gamma = np.einsum("ikj,i,j->k", dg, w, w) - 0.5 * np.einsum("kij,i,j->k", dg, w, w)
    return -np.linalg.solve(g, gamma).reshape(theta.shape)


def test_geodesic_acceleration_is_the_christoffel_term_of_the_metric():
    acc = geodesic_acceleration(U, V0, metric="alpha", sigma2=0.5)
    ref = _christoffel_acceleration(U, V0, 0.5)
    assert np.abs(ref).max() > 0.05  # curved: far from zero
    assert np.allclose(acc, ref, rtol=1e-6, atol=1e-7 * np.abs(ref).max())
    # quadratic in the velocity
    assert np.allclose(geodesic_acceleration(U, 2 * V0, metric="alpha", sigma2=0.5), 4 * acc,
                       rtol=1e-6, atol=1e-8 * np.abs(ref).max())


def test_geodesic_acceleration_of_a_flat_metric_vanishes():
    """One landmark: g_FR = I/σ² and g_α constant; a shape far apart (overlaps underflow) is flat too."""
    for metric in ("alpha", "fisher_rao"):
        assert np.allclose(geodesic_acceleration([[0.2, -0.1]], [[1.0, 0.5]], metric=metric, sigma2=0.5), 0.0,
                           atol=1e-6)


def test_geodesic_acceleration_takes_a_grid():
    from shapelib.solver.path_metric import path_metric

    model = path_metric("fisher_rao", 0.5)
    grid = model.prepare(U)
    with_grid = geodesic_acceleration(U, V0, metric="fisher_rao", sigma2=0.5, grid=grid)
    own = geodesic_acceleration(U, V0, metric="fisher_rao", sigma2=0.5)
    assert np.allclose(with_grid, own, rtol=1e-6, atol=1e-9)
    coarse = geodesic_acceleration(U, V0, metric="fisher_rao", sigma2=0.5, grid=path_metric(
        "fisher_rao", 0.5, grid_margin=2.0).prepare(U))
    assert np.abs(coarse - own).max() > 1e-4 * np.abs(own).max()
    assert np.abs(geodesic_acceleration(U, V0, metric="fisher_rao", sigma2=0.5, grid_margin=2.0) - own).max() \
        > 1e-4 * np.abs(own).max()


def test_shoot_keeps_the_speed_of_the_geodesic():
    """A geodesic has constant speed √(θ̇ᵀ g θ̇): its length over [0, 1] is the initial speed (the
    metric tensor from shapelib.alpha_metric), while the path bends."""
    traj = shoot(U, V0, metric="alpha", sigma2=0.5, n_steps=40)
    assert traj.shape == (41, 4, 2) and np.array_equal(traj[0], U)
    speed = np.sqrt(V0.ravel() @ sl.alpha_metric(U, sigma2=0.5) @ V0.ravel())
    assert path_length(traj, metric="alpha", sigma2=0.5) == pytest.approx(speed, rel=1e-4)
    assert np.abs(traj[-1] - U - V0).max() > 0.05  # not the straight line
    # the speed at the end, from the trajectory's last step, is the initial one too
    end_v = 40 * (3 * traj[-1] - 4 * traj[-2] + traj[-3]) / 2
    end_speed = np.sqrt(end_v.ravel() @ sl.alpha_metric(traj[-1], sigma2=0.5) @ end_v.ravel())
    assert end_speed == pytest.approx(speed, rel=1e-3)


def test_shoot_is_fourth_order():
    """RK4: halving the step divides the end point's error by about 16."""
    ref = shoot(U, V0, metric="alpha", sigma2=0.5, n_steps=64)[-1]
    e4 = np.abs(shoot(U, V0, metric="alpha", sigma2=0.5, n_steps=4)[-1] - ref).max()
    e8 = np.abs(shoot(U, V0, metric="alpha", sigma2=0.5, n_steps=8)[-1] - ref).max()
    assert e4 > 0 and 10 < e4 / e8 < 25


def test_shoot_of_one_landmark_is_the_straight_line_and_checks_its_input():
    traj = shoot([[0.0, 0.0]], [[1.0, 0.5]], metric="fisher_rao", sigma2=0.5, n_steps=3)
    assert np.allclose(traj[:, 0], np.linspace([0.0, 0.0], [1.0, 0.5], 4), atol=1e-6)
    with pytest.raises(ValueError, match="velocity"):
        shoot(U, V0[:3], sigma2=0.5)
    with pytest.raises(ValueError, match="sigma2"):
        shoot(U, V0, sigma2=0.0)
    # n_steps was unchecked: 0 divided by zero, -1 returned the start alone as a "trajectory"
    for bad in (0, -1, 2.5):
        with pytest.raises(ValueError, match="n_steps must be a positive integer"):
            shoot(U, V0, sigma2=0.5, n_steps=bad)


def test_geodesic_acceleration_checks_its_step():
    """eps = 0 gave NaN (0/0) instead of an error."""
    for bad in (0.0, -1e-6):
        with pytest.raises(ValueError, match="eps must be a positive finite number"):
            geodesic_acceleration(U, V0, sigma2=0.5, eps=bad)


# --------------------------------------------------------------------------------------------- where warnings point


#: mutmut (benchmarks/mutation.py) runs these tests against a copy of the module whose functions
#: are trampolines: a frame more between the caller and the warning, so no stacklevel names the caller
UNDER_MUTMUT = any("__mutmut_" in name for name in vars(geodesic_module))


def _caught(fn, category):
    """The warnings of ``category`` that ``fn`` emits; each names this file (outside mutmut)."""
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        fn()
    hits = [w for w in seen if issubclass(w.category, category)]
    assert hits, f"no {category.__name__}"
    if UNDER_MUTMUT:
        return [warnings.WarningMessage(w.message, w.category, __file__, w.lineno) for w in hits]
    return hits


def test_warnings_point_at_the_callers_line():
    """Each entry point's warnings name the line that called it (stacklevel), not shapelib's."""
    turned = U @ np.array([[0.0, -1.0], [1.0, 0.0]]).T + [3.0, 0.0]
    for fn in (lambda: fisher_rao_lower_bound(U, turned, sigma2=0.5),
               lambda: alpha_lower_bound(U, turned, sigma2=0.5),
               lambda: geodesic(U, turned, sigma2=0.5, n_steps=2)):
        assert all(w.filename == __file__ for w in _caught(fn, sl.PoseWarning))
    # (geodesics(backend="cpu") calls geodesic from its own line, so its warnings name that line)
    far = 10 * U
    for fn in (lambda: fisher_rao_lower_bound(far, far, sigma2=1.0),
               lambda: alpha_lower_bound(far, far, sigma2=0.01),
               lambda: geodesic(far, far + 0.01, sigma2=0.01, n_steps=2, warn=False)):
        assert all(w.filename == __file__ for w in _caught(fn, ScaleWarning))
    rng = np.random.default_rng(11)
    v = sl.procrustes_align(U, U + 0.3 * rng.normal(size=U.shape), scaling=False)
    hits = _caught(lambda: geodesic(U, v, sigma2=0.5, n_steps=4, max_iter=1), GeodesicWarning)
    assert [w.filename for w in hits] == [__file__] and "did not converge" in str(hits[0].message)
    u = 10.0 * np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ScaleWarning)
        hits = _caught(lambda: geodesic(u, u + [[0.05, 0.0], [0.0, 0.0], [0.0, 0.0]], sigma2=1.6e-7, n_steps=2),
                       GeodesicWarning)
    assert [w.filename for w in hits] == [__file__]


def test_check_entry_counts_its_stacklevel_from_itself():
    turned = U @ np.array([[0.0, -1.0], [1.0, 0.0]]).T + [3.0, 0.0]

    def entry():  # an entry point of shapelib as check_entry's callers are: stacklevel 3 names our caller
        check_entry(U, turned, 0.5, metric="alpha", stacklevel=3)

    assert all(w.filename == __file__ for w in _caught(entry, sl.PoseWarning))
    hits = _caught(lambda: _check_entries(U[None], turned[None], 0.5, metric="alpha", stacklevel=2), sl.PoseWarning)
    assert all(w.filename == __file__ for w in hits)


def test_geodesic_passes_its_options_to_the_solver():
    rng = np.random.default_rng(12)
    v = sl.procrustes_align(U, U + 0.3 * rng.normal(size=U.shape), scaling=False)
    best = geodesic(U, v, sigma2=0.5, n_steps=5, tol=1e-12)
    assert best.path.shape == (6, 4, 2) and best.log["tol"] == 1e-12 and best.log["hessian"] == "exact"
    assert best.sigma2 == 0.5 and best.metric == "alpha"
    steps = np.linalg.norm(np.diff(best.path, axis=0), axis=2)
    assert best.max_step_over_sigma == pytest.approx(steps.max() / np.sqrt(0.5), rel=1e-12)
    warm = geodesic(U, v, sigma2=0.5, n_steps=5, tol=1e-12, init=best.path)
    assert warm.n_iter < best.n_iter and warm.energy == pytest.approx(best.energy, rel=1e-10)
    loose = geodesic(U, v, sigma2=0.5, n_steps=5, tol=1e-3)
    assert loose.n_iter < best.n_iter and loose.log["tol"] == 1e-3
    model = geodesic(U, v, sigma2=0.5, n_steps=5, tol=1e-12, hessian="model", window=2, max_iter=7, warn=False)
    assert model.log["hessian"] == "model" and model.n_iter <= 7
    fr = geodesic(U, v, metric="fisher_rao", sigma2=0.5, n_steps=3, grid_spacing=0.5, grid_margin=7.0)
    assert (fr.log["grid_spacing"], fr.log["grid_margin"]) == (0.5, 7.0) and fr.metric == "fisher_rao"
    assert fr.lower_bound == pytest.approx(fisher_rao_lower_bound(U, v, sigma2=0.5, grid_spacing=0.5,
                                                                  grid_margin=7.0), rel=1e-12)


def test_shoot_passes_its_grid_and_its_default_step_count():
    traj = shoot(U, V0, sigma2=0.5)
    assert traj.shape == (201, 4, 2)  # the documented 200 RK4 steps
    own = shoot(U, V0, metric="fisher_rao", sigma2=0.5, n_steps=4)
    margin = shoot(U, V0, metric="fisher_rao", sigma2=0.5, n_steps=4, grid_margin=2.0)
    spacing = shoot(U, V0, metric="fisher_rao", sigma2=0.5, n_steps=4, grid_spacing=2.5)
    assert np.abs(margin - own).max() > 1e-5 and np.abs(spacing - own).max() > 1e-5
    with pytest.raises(ValueError, match="u and velocity must have the same number"):
        shoot(U, V0[:3], sigma2=0.5)
    with pytest.raises(ValueError, match="velocity contains non-finite"):
        shoot(U, np.full_like(V0, np.nan), sigma2=0.5)


def test_geodesic_acceleration_grid_spacing_reaches_the_metric():
    own = geodesic_acceleration(U, V0, metric="fisher_rao", sigma2=0.5)
    wide = geodesic_acceleration(U, V0, metric="fisher_rao", sigma2=0.5, grid_spacing=2.5)
    assert np.abs(wide - own).max() > 1e-4 * np.abs(own).max()
    # integer input is read as float
    ui, vi = np.array([[0, 0], [2, 0], [1, 2], [-1, 1]]), np.array([[1, 0], [0, 1], [1, 1], [-1, 0]])
    assert np.array_equal(geodesic_acceleration(ui, vi, sigma2=0.5),
                          geodesic_acceleration(ui.astype(float), vi.astype(float), sigma2=0.5))

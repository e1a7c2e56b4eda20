"""register_many: the batched search on JAX (its CPU backend here) equals register one pair at a time
(the same start, the same fit to rounding, the same reliability), the padding of sets of different
sizes changes nothing, a permutation of the pairs permutes the results, and bad input is refused
naming the parameter and the pair."""

import os
import sys
import time
import warnings

import numpy as np
import pytest

from tests.conftest import import_or_missing

import shapelib

if "jax" not in sys.modules:  # compile time dominates these small problems: XLA's cheapest code generation
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + " --xla_backend_optimization_level=0").strip()


def _outline(n, phase=0.0):
    """A fish-like closed outline sampled at ``n`` points."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False) + phase
    return np.column_stack([np.cos(t) + 0.45 * np.cos(2 * t), 0.55 * np.sin(t) + 0.12 * np.sin(2 * t)])


def _bend(x):
    return x + np.column_stack([0.05 * np.sin(2 * x[:, 1]), 0.25 * x[:, 0] ** 2])


def _rot(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def _pairs():
    rng = np.random.default_rng(3)
    bent = (_outline(30), _bend(_outline(30)))
    # a bent outline of other samples, turned by 120 degrees, scaled and moved: the search must find the start
    turned = (_outline(40), 1.3 * _bend(_outline(36, phase=0.05)) @ _rot(2 * np.pi / 3).T + [2.0, -1.0])
    # clutter on the target: 6 uniform points in its box
    clutter = (_outline(45), np.vstack([_bend(_outline(38, phase=0.02)), rng.uniform(-1.4, 1.4, (6, 2))]))
    return [bent, turned, clutter]


PAIRS = _pairs()


def _quiet(fn, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", shapelib.RegistrationWarning)
        return fn(*args, **kw)


@pytest.fixture(scope="module")
def both():
    import_or_missing("jax", "JAX (the dev or jax extra) is not installed")
    one_by_one = [_quiet(shapelib.register, x, y) for x, y in PAIRS]
    batched = _quiet(shapelib.register_many, PAIRS, backend="jax", device="cpu")
    return one_by_one, batched


def test_the_numpy_backend_is_register_one_by_one():
    res = _quiet(shapelib.register_many, PAIRS[:1], backend="numpy")
    ref = _quiet(shapelib.register, *PAIRS[0])
    np.testing.assert_array_equal(res[0].points, ref.points)
    assert res[0].diagnostics["candidates"] == ref.diagnostics["candidates"]


def test_the_jax_batch_equals_register_one_by_one(both):
    one_by_one, batched = both
    assert len(batched) == len(PAIRS)
    for i, (ref, got) in enumerate(zip(one_by_one, batched)):
        size = ref._frame[1]  # the target's RMS radius: the normalised units
        assert np.abs(got.points - ref.points).max() / size < 1e-6, i
        # the same start rotation and outlier weight won, with the same objective (to rounding)
        np.testing.assert_allclose(got._start[0], ref._start[0], atol=1e-12)
        assert got.w == ref.w
        assert [k for _, k, _ in got.diagnostics["candidates"]] == [k for _, k, _ in ref.diagnostics["candidates"]]
        np.testing.assert_allclose([f for f, _, _ in got.diagnostics["candidates"]],
                                   [f for f, _, _ in ref.diagnostics["candidates"]], rtol=1e-8, atol=1e-8)
        assert got.sigma2 == pytest.approx(ref.sigma2, rel=1e-6)
        assert (got.n_iter, got.converged, got.stop_reason, got.reliable, got.reasons) == \
            (ref.n_iter, ref.converged, ref.stop_reason, ref.reliable, ref.reasons), i
        assert got.pose.stop_reason == ref.pose.stop_reason == "tolerance", i
        np.testing.assert_array_equal(got.correspondence, ref.correspondence)
        np.testing.assert_array_equal(got.target_correspondence, ref.target_correspondence)
        assert got.objective == pytest.approx(ref.objective, rel=1e-6)
        np.testing.assert_allclose(got.pose.matrix, ref.pose.matrix, atol=1e-8)


def test_the_batch_registers_what_it_should(both):
    """Independently of register: the bent outline is matched point for point, the turned one lands on
    its target (turned by 120 degrees), the clutter is left to the outlier component."""
    _, (bent, turned, clutter) = both
    np.testing.assert_allclose(bent.points, PAIRS[0][1], atol=1e-3)
    np.testing.assert_array_equal(bent.correspondence, np.arange(30))
    angle = np.degrees(np.arctan2(turned.pose.matrix[1, 0], turned.pose.matrix[0, 0]))
    assert abs(angle - 120.0) < 10.0 and turned.pose.scale == pytest.approx(1.3, rel=0.1)
    near = np.min(np.linalg.norm(turned.points[:, None] - PAIRS[1][1][None], axis=2), axis=1)
    assert near.max() < 0.1 * turned._frame[1]
    assert np.all(clutter.target_correspondence[:38] >= 0) and np.sum(clutter.target_correspondence[38:] >= 0) <= 1
    # (the turned pair's starts at 112.5 and 135 degrees reach distinct fits, 0.175 per target point apart:
    # more than AMBIGUOUS_PER_POINT, and the fit is right; test_the_jax_batch_equals_register_one_by_one
    # checks that register says the same)
    assert bent.reliable and clutter.reliable and turned.reliable


def test_a_permutation_of_the_pairs_permutes_the_results(both):
    _, batched = both
    order = [2, 0, 1]
    again = _quiet(shapelib.register_many, [PAIRS[i] for i in order], backend="jax", device="cpu")
    for j, i in enumerate(order):
        np.testing.assert_allclose(again[j].points, batched[i].points, atol=1e-9)
        assert again[j].diagnostics["candidates"][0][1:] == batched[i].diagnostics["candidates"][0][1:]


def test_sets_over_max_points_go_through_register_in_their_place(both, monkeypatch):
    """A pair over ``MAX_POINTS`` is registered by register (its subsets path) even with backend="jax": here
    the bound is lowered to 40 points so that the 45-point pair takes that path, and the other stays batched,
    alone: padded to 32 points instead of 48 in the full batch, its fit is the same."""
    from shapelib.pointsets import _batch

    _, batched = both
    monkeypatch.setattr(_batch, "MAX_POINTS", 40)
    got = _quiet(shapelib.register_many, [PAIRS[2], PAIRS[0]], backend="jax", device="cpu")
    ref = _quiet(shapelib.register, *PAIRS[2])
    np.testing.assert_array_equal(got[0].points, ref.points)  # register itself, bit for bit
    assert got[0].diagnostics["candidates"] == ref.diagnostics["candidates"]
    np.testing.assert_allclose(got[1].points, batched[0].points, atol=1e-9)
    assert got[1].n_iter == batched[0].n_iter


def test_three_d_pairs_on_jax_equal_register():
    import_or_missing("jax", "JAX (the dev or jax extra) is not installed")
    rng = np.random.default_rng(5)
    x = rng.normal(size=(24, 3)) * [1.0, 0.7, 0.4]
    y = (x + 0.05 * np.sin(2 * x)) @ np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]).T
    ref = _quiet(shapelib.register, x, y[:20])
    got = _quiet(shapelib.register_many, [(x, y[:20])], backend="jax", device="cpu")[0]
    assert np.abs(got.points - ref.points).max() / ref._frame[1] < 1e-6
    np.testing.assert_allclose(got._start[0], ref._start[0], atol=1e-12)
    assert (got.n_iter, got.reliable) == (ref.n_iter, ref.reliable)


def test_an_empty_list_gives_an_empty_list():
    assert shapelib.register_many([]) == []
    assert shapelib.register_many([], backend="jax") == []


@pytest.mark.parametrize("pairs, match", [
    ([(np.eye(3, 2), np.eye(3, 2)), (np.zeros((3, 3)) + np.arange(3)[:, None], np.eye(3))], r"pairs\[1\].*d = 3"),
    ([(np.eye(3, 2), np.eye(3, 2) * 2), (np.arange(4.0), np.eye(3, 2))], r"pairs\[1\] source"),
    ([(np.eye(3, 2), np.eye(3, 2) * 2), (np.eye(3, 2), np.eye(3))], r"pairs\[1\].*same dimension"),
    ([(np.eye(3, 2), np.eye(3, 2) * 2, np.eye(3, 2))], r"pairs\[0\].*\(source, target\) pair"),
    ([(np.eye(3, 2), [[0.0, np.nan], [1.0, 1.0]])], r"pairs\[0\] target"),
    (5, r"pairs must be a sequence"),
])
def test_bad_pairs_are_refused_naming_the_pair(pairs, match):
    with pytest.raises(ValueError, match=match):
        shapelib.register_many(pairs)


@pytest.mark.parametrize("kw, match", [
    (dict(backend="torch"), "backend"),
    (dict(backend="jax", metric="fisher_rao"), "metric='fisher_rao' is not batched"),
    (dict(backend="jax", kernel="means"), "kernel='means' is not batched"),
    (dict(backend="jax", sigma2=0.1), "sigma2=0.1 is not batched"),
    (dict(backend="jax", sigma2=np.array([0.1, 0.2])), "sigma2=array"),
    (dict(backend="numpy", device="gpu"), "device"),
    (dict(backend="jax", device="tpu"), "device"),
    (dict(backend="jax", batch_size=0), "batch_size"),
    (dict(backend="jax", w="many"), "w must be"),
    (dict(backend="jax", max_iter=0), "max_iter"),
    (dict(backend="jax", lam=-1.0), "lam"),
    (dict(backend="jax", pose_prior=-1.0), "pose_prior must be a non-negative"),
    (dict(backend="numpy", pose_prior=float("nan")), "pose_prior must be a non-negative"),
])
def test_bad_options_are_refused_naming_the_option(kw, match):
    with pytest.raises(ValueError, match=match):
        shapelib.register_many(PAIRS[:1], **kw)


def test_fits_many_gives_what_the_results_say(both):
    """``fits_many`` skips the results' assembly: its (σ², converged, n_iter, deformation energy) are the
    results' own, on both backends, in the order of the pairs."""
    from shapelib.pointsets._batch import fits_many

    one_by_one, batched = both
    for backend, results, kw in (("numpy", one_by_one, {}), ("jax", batched, {"device": "cpu"})):
        fits = fits_many(PAIRS, backend=backend, **kw)
        assert len(fits) == len(PAIRS)
        for (s2, ok, it, energy), r in zip(fits, results):
            assert s2 == pytest.approx(r.sigma2, rel=1e-12) and ok == r.converged and it == r.n_iter
            assert energy == pytest.approx(r.deformation_energy, rel=1e-12) and energy > 0
        # the two backends' energies agree as their fits do
        for (_, _, _, e1), (_, _, _, e2) in zip(fits_many(PAIRS), fits):
            assert e2 == pytest.approx(e1, rel=1e-4)


def test_the_targets_sigma2_does_not_depend_on_the_source():
    """The remembered leave-one-out σ² of a target (the pairs of a matrix share targets) is the one the
    search computes for any source: it is a function of the target alone, and of its coordinates, not
    of the array's identity (a copy gets the same value, a moved copy another)."""
    from shapelib.pointsets._batch import _target_sigma2
    from shapelib.pointsets.registration import _nonrigid_frame

    y = _bend(_outline(33))
    for x in (_outline(20), 3.0 * _outline(41) + 1.0):
        assert _target_sigma2(y.shape, y.tobytes()) == _nonrigid_frame(x, y, None)[2]
    other = y + 0.01 * np.sin(7 * y[:, ::-1])
    assert _target_sigma2(other.shape, other.tobytes()) == _nonrigid_frame(y, other, None)[2]
    assert _target_sigma2(other.shape, other.tobytes()) != _target_sigma2(y.shape, y.tobytes())


def test_reflection_reaches_each_fit_of_the_jax_batch():
    """A bent outline and a turned mirror image of it, each way round, each pair in its own device call
    (``batch_size=1``): with ``reflection=True`` a mirror start wins (register's default, rotations only,
    fits another start), on JAX as in register, and ``timings`` says where the search ran."""
    jax = import_or_missing("jax", "JAX (the dev or jax extra) is not installed")
    s = _bend(_outline(30))
    mirrored = (_bend(_outline(30, phase=0.04)) * [1.0, -1.0]) @ _rot(0.5).T
    pairs = [(s, mirrored), (mirrored, s)]
    timings = {}
    t0 = time.perf_counter()
    got = _quiet(shapelib.register_many, pairs, backend="jax", device="cpu", reflection=True, batch_size=1,
                 timings=timings)
    elapsed = time.perf_counter() - t0
    for (x, y), g in zip(pairs, got):
        ref = _quiet(shapelib.register, x, y, reflection=True)
        assert np.linalg.det(ref._start[0]) < 0 < np.linalg.det(_quiet(shapelib.register, x, y)._start[0])
        assert np.abs(g.points - ref.points).max() / ref._frame[1] < 1e-6
        np.testing.assert_allclose(g._start[0], ref._start[0], atol=1e-12)
        assert (g.w, g.n_iter, g.reliable) == (ref.w, ref.n_iter, ref.reliable)
        np.testing.assert_allclose(g.pose.matrix, ref.pose.matrix, atol=1e-8)   # the pose: a mirror image too
        assert np.linalg.det(g.pose.matrix) < 0
        # every final fit's objective, the price on its turn or its mirror included, as register's
        assert [(k, w) for _, k, w in g.diagnostics["candidates"]] == [(k, w) for _, k, w in ref.diagnostics["candidates"]]
        np.testing.assert_allclose([f for f, _, _ in g.diagnostics["candidates"]],
                                   [f for f, _, _ in ref.diagnostics["candidates"]], rtol=1e-6, atol=1e-6)
    assert set(timings) == {"prep", "search", "assembly", "device"}
    assert timings["device"] == str(jax.devices("cpu")[0]) and timings["search"] > 0.0
    parts = [timings[k] for k in ("prep", "search", "assembly")]
    assert all(type(t) is float and t >= 0.0 for t in parts) and sum(parts) <= elapsed   # parts of the call


def test_a_fixed_outlier_weight_and_the_em_options_reach_the_jax_batch():
    """With ``w=0`` (not in the searched grid) and other ``lam``, ``sigma2_metric``, ``tol`` and ``max_iter``
    the batched fit is register's with the same options, not register's default."""
    import_or_missing("jax", "JAX (the dev or jax extra) is not installed")
    opts = dict(w=0.0, lam=3.0, sigma2_metric=1.0, tol=1e-4, max_iter=60, n_steps=5)
    got = _quiet(shapelib.register_many, PAIRS[:1], backend="jax", device="cpu", **opts)[0]
    ref = _quiet(shapelib.register, *PAIRS[0], **opts)
    default = _quiet(shapelib.register, *PAIRS[0])
    assert got.w == ref.w == 0.0 != default.w
    assert np.abs(got.points - ref.points).max() / ref._frame[1] < 1e-6
    assert np.abs(default.points - ref.points).max() / ref._frame[1] > 1e-4   # the options change the fit
    assert (got.n_iter, got.reliable) == (ref.n_iter, ref.reliable)
    assert got.sigma2 == pytest.approx(ref.sigma2, rel=1e-6)
    assert got.sigma2_metric == pytest.approx(ref.sigma2_metric, rel=1e-12) != default.sigma2_metric
    assert len(got.path) == len(ref.path) == 6 != len(default.path)   # n_steps segments of the deformation


def test_the_price_on_the_turn_reaches_each_fit_of_the_jax_batch(monkeypatch):
    """A target turned by 2 rad: with a price on the turn the data cannot pay (50 nats per point at a quarter
    turn) register keeps the source nearly unturned and flags it; the batch does the same, and fits_many
    gives that fit, not the default's; so does a pair over MAX_POINTS, which goes to register."""
    import_or_missing("jax", "JAX (the dev or jax extra) is not installed")
    from shapelib.pointsets import _batch
    from shapelib.pointsets._batch import fits_many

    s = _bend(_outline(30))
    pair = (s, _bend(_outline(30, phase=0.04)) @ _rot(2.0).T)
    default = _quiet(shapelib.register, *pair)
    ref = _quiet(shapelib.register, *pair, pose_prior=50.0)
    got = _quiet(shapelib.register_many, [pair], backend="jax", device="cpu", pose_prior=50.0)[0]
    assert np.abs(got.points - ref.points).max() / ref._frame[1] < 1e-6
    assert (got.n_iter, got.reliable, got.reasons) == (ref.n_iter, ref.reliable, ref.reasons)
    assert default.reliable and not ref.reliable   # the price changes the answer
    assert np.abs(default.points - ref.points).max() / ref._frame[1] > 0.1
    (s2, ok, it, energy), = fits_many([pair], backend="jax", device="cpu", pose_prior=50.0)
    assert s2 == pytest.approx(ref.sigma2, rel=1e-6) and (ok, it) == (ref.converged, ref.n_iter)
    assert energy == pytest.approx(ref.deformation_energy, rel=1e-5)
    monkeypatch.setattr(_batch, "MAX_POINTS", 10)
    big = _quiet(shapelib.register_many, [pair], backend="jax", device="cpu", pose_prior=50.0)[0]
    np.testing.assert_array_equal(big.points, _quiet(shapelib.register, *pair, pose_prior=50.0).points)


def test_the_jax_batch_warns_by_default_and_not_with_warn_false():
    """Two EM iterations do not converge: one RegistrationWarning by default, none with ``warn=False``, and
    the result says why EM stopped, as register's does."""
    import_or_missing("jax", "JAX (the dev or jax extra) is not installed")
    with pytest.warns(shapelib.RegistrationWarning) as caught:
        shapelib.register_many(PAIRS[:1], backend="jax", device="cpu", max_iter=2)
    assert any("after 2 iterations without converging" in str(w.message) for w in caught)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = shapelib.register_many(PAIRS[:1], backend="jax", device="cpu", max_iter=2, warn=False)
    ref = _quiet(shapelib.register, *PAIRS[0], max_iter=2)
    assert (got[0].n_iter, got[0].converged, got[0].stop_reason) == (ref.n_iter, ref.converged, ref.stop_reason) \
        == (2, False, "max_iter")


def test_device_gpu_runs_on_a_gpu_or_is_refused_saying_jax_sees_none():
    jax = import_or_missing("jax", "JAX (the dev or jax extra) is not installed")
    try:
        gpus = jax.devices("gpu")
    except RuntimeError:
        gpus = []
    if gpus:
        timings = {}
        _quiet(shapelib.register_many, PAIRS[:1], backend="jax", device="gpu", timings=timings)
        assert timings["device"] == str(gpus[0])
    else:
        with pytest.raises(RuntimeError, match='^device="gpu" but JAX sees no GPU'):
            shapelib.register_many(PAIRS[:1], backend="jax", device="gpu")


def test_a_batch_padded_with_repeated_pairs_gives_each_pair_its_own_fit():
    """Nine pairs run as a batch of ten (the device programs are compiled for a few batch sizes; the tenth
    repeats the first pair and is dropped): each result is register's for its own pair."""
    import_or_missing("jax", "JAX (the dev or jax extra) is not installed")
    pairs = [(_outline(8 + k % 3), _bend(_outline(8, phase=0.1 * k)) @ _rot(0.3 * k).T) for k in range(9)]
    got = _quiet(shapelib.register_many, pairs, backend="jax", device="cpu")
    assert len(got) == 9
    for k, ((x, y), g) in enumerate(zip(pairs, got)):
        ref = _quiet(shapelib.register, x, y)
        assert np.abs(g.points - ref.points).max() / ref._frame[1] < 1e-6, k
        np.testing.assert_allclose(g._start[0], ref._start[0], atol=1e-12)


def test_a_jax_call_whose_every_pair_is_over_max_points_names_no_device(monkeypatch):
    """No pair reaches the device (each is register's, bit for bit): the timings name no device and count
    no search time."""
    import_or_missing("jax", "JAX (the dev or jax extra) is not installed")
    from shapelib.pointsets import _batch

    monkeypatch.setattr(_batch, "MAX_POINTS", 20)
    timings = {}
    got = _quiet(shapelib.register_many, PAIRS[:1], backend="jax", device="cpu", timings=timings)
    np.testing.assert_array_equal(got[0].points, _quiet(shapelib.register, *PAIRS[0]).points)
    assert timings == {"prep": 0.0, "search": 0.0, "assembly": 0.0, "device": None}


def test_a_pair_of_exactly_max_points_points_is_batched(monkeypatch):
    """``MAX_POINTS`` is the largest set the batch takes: a pair of that many points is fitted on the device."""
    import_or_missing("jax", "JAX (the dev or jax extra) is not installed")
    from shapelib.pointsets import _batch

    monkeypatch.setattr(_batch, "MAX_POINTS", len(PAIRS[0][0]))
    timings = {}
    got = _quiet(shapelib.register_many, PAIRS[:1], backend="jax", device="cpu", timings=timings)[0]
    ref = _quiet(shapelib.register, *PAIRS[0])
    assert np.abs(got.points - ref.points).max() / ref._frame[1] < 1e-6
    assert timings["device"] is not None and timings["search"] > 0.0


def test_every_option_reaches_register_for_a_pair_over_max_points(monkeypatch):
    """A pair over ``MAX_POINTS`` goes to register with each option given to the JAX call: register's result
    with that option, bit for bit, not its default's; fits_many gives that result's fit."""
    import_or_missing("jax", "JAX (the dev or jax extra) is not installed")
    from shapelib.pointsets import _batch
    from shapelib.pointsets._batch import fits_many

    monkeypatch.setattr(_batch, "MAX_POINTS", 10)
    s = _bend(_outline(14))
    pair = (s, (_bend(_outline(14, phase=0.04)) * [1.0, -1.0]) @ _rot(0.5).T)  # a mirror image: reflection wins
    default = _quiet(shapelib.register, *pair)
    for key, value in (("reflection", True), ("w", 0.0), ("lam", 0.5), ("sigma2_metric", 0.5), ("max_iter", 3),
                       ("tol", 0.05), ("n_steps", 3)):
        got = _quiet(shapelib.register_many, [pair], backend="jax", **{key: value})[0]
        ref = _quiet(shapelib.register, *pair, **{key: value})
        np.testing.assert_array_equal(got.points, ref.points, err_msg=key)
        assert len(got.path) == len(ref.path) and got.sigma2_metric == ref.sigma2_metric, key
        assert (got.n_iter, len(got.path), got.sigma2_metric, got.w, np.linalg.det(got._start[0])) != \
            (default.n_iter, len(default.path), default.sigma2_metric, default.w, np.linalg.det(default._start[0])), key
        assert fits_many([pair], backend="jax", **{key: value}) == [(ref.sigma2, ref.converged, ref.n_iter,
                                                                     ref.deformation_energy)], key
    with pytest.warns(shapelib.RegistrationWarning):
        shapelib.register_many([pair], backend="jax", max_iter=2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        shapelib.register_many([pair], backend="jax", max_iter=2, warn=False)


def test_a_fit_that_converges_in_the_screening_with_nothing_truncated_is_kept_in_the_jax_batch():
    """A narrow kernel on a few points keeps every eigenvalue at the screening's threshold, and a loose
    tolerance lets the screening's EM converge: register keeps that fit as it stopped (fewer iterations than
    the screening's), and so must the batch — not run it on with the full kernel."""
    import_or_missing("jax", "JAX (the dev or jax extra) is not installed")
    x = _outline(7)
    y = _bend(_outline(7)) * 1.1
    opts = dict(w=0.2, sigma2_metric=0.05, tol=0.05)
    ref = _quiet(shapelib.register, x, y, **opts)
    assert ref.converged and ref.n_iter < shapelib.pointsets._nonrigid.SCREEN_ITER
    got = _quiet(shapelib.register_many, [(x, y)], backend="jax", device="cpu", **opts)[0]
    assert (got.n_iter, got.converged, got.stop_reason) == (ref.n_iter, ref.converged, ref.stop_reason)
    assert np.abs(got.points - ref.points).max() / ref._frame[1] < 1e-6

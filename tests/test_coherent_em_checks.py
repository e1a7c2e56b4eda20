"""The registration EM's Python pieces (shapelib.pointsets._coherent_em) against independent values:
one EM iteration against the posterior written out point by point and the M-step's closed form solved
by numpy.linalg.solve (Myronenko & Song 2010, the non-rigid M-step), σ²'s update against its closed
form, the objective against scipy's log-densities, the kernel's factor against its matrix and its
invariance to scale, the outlier term and the bounding box against their definitions."""

import numpy as np
import pytest
from scipy.special import logsumexp
from scipy.stats import multivariate_normal

from shapelib.pointsets._coherent_em import (EIG_RTOL, PLAIN_ITER, EMState, Kernel, box_volume, initial_sigma2,
                                             objective, outlier_term, point_spacing, posteriors, run_em,
                                             sq_dist)


def _sets(n=14, m=17, d=2, seed=0):
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, d))
    y = np.vstack([u[:m - 4] @ np.eye(d) * 1.1 + 0.05 * rng.normal(size=(m - 4, d)) + 0.1,
                   rng.uniform(-2, 2, size=(4, d))]) if m > 4 else rng.normal(size=(m, d))
    return u, y


def _bent_outline(n=40, m=34, seed=5):
    """A bent outline with noise, partly resampled: EM needs many iterations and σ² stays at the noise."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    u = np.column_stack([np.cos(t) + 0.45 * np.cos(2 * t), 0.55 * np.sin(t) + 0.12 * np.sin(2 * t)])
    y = u + np.column_stack([0.05 * np.sin(2 * u[:, 1]), 0.25 * u[:, 0] ** 2]) + 0.03 * rng.normal(size=u.shape)
    return u, y[rng.permutation(n)[:m]]


def _gauss(u, s2g=0.6):
    d2 = np.sum((u[:, None, :] - u[None, :, :]) ** 2, axis=2)
    return np.exp(-d2 / (4 * s2g))


def _p_by_hand(theta, y, s2, w, volume):
    """P_ij of the CPD model with a uniform outlier density 1/V of weight w, term by term."""
    n, d = theta.shape
    dens = np.array([[np.exp(-np.sum((yj - ti) ** 2) / (2 * s2)) for yj in y] for ti in theta])
    c = (2 * np.pi * s2) ** (d / 2) * w / (1 - w) * n / volume
    return dens / (dens.sum(axis=0) + c)


def _one_em_iteration_by_hand(u, g, coef, y, s2, w, volume, lam):
    """The E-step at θ = u + G W, the M-step (diag(P1) G + λσ² I) W' = P y − diag(P1) u by
    numpy.linalg.solve, and σ²' = Σ_ij P_ij |y_j − θ'_i|² / (d Σ_ij P_ij)."""
    n, d = u.shape
    p = _p_by_hand(u + g @ coef, y, s2, w, volume)
    p1 = p.sum(axis=1)
    new = np.linalg.solve(np.diag(p1) @ g + lam * s2 * np.eye(n), p @ y - p1[:, None] * u)
    theta = u + g @ new
    r = np.array([[np.sum((yj - ti) ** 2) for yj in y] for ti in theta])
    return new, float(np.sum(p * r) / (d * p.sum()))


@pytest.mark.parametrize("dense", [False, True])
@pytest.mark.parametrize("d", [2, 3])
def test_one_em_iteration_is_the_closed_form_m_step_and_sigma2_update(dense, d):
    u, y = _sets(d=d)
    g = _gauss(u)
    coef0 = 0.05 * np.sin(u)
    volume, lam, s2, w = 9.0, 2.5, 0.4, 0.15
    kernel = Kernel(full=np.kron(g, np.eye(d))) if dense else Kernel.of(g)
    st = run_em(EMState(u=u, kernel=kernel, coef=coef0.copy(), s2=s2, w=w), y, lam=lam, volume=volume, max_iter=1,
                tol=0.0, s2_floor=1e-12)
    coef, s2_new = _one_em_iteration_by_hand(u, g, coef0, y, s2, w, volume, lam)
    np.testing.assert_allclose(st.coef, coef, rtol=1e-9, atol=1e-11)
    assert st.s2 == pytest.approx(s2_new, rel=1e-10)
    assert st.it == 1 and not st.ok and st.why == "max_iter"
    np.testing.assert_allclose(st.theta, u + g @ coef, rtol=1e-9, atol=1e-11)


def test_without_a_kernel_em_moves_sigma2_alone_to_its_closed_form():
    u, y = _sets()
    volume, s2, w = 9.0, 0.7, 0.25
    st = run_em(EMState(u=u, kernel=None, coef=np.zeros_like(u), s2=s2, w=w), y, lam=2.0, volume=volume, max_iter=1,
                tol=0.0)
    p = _p_by_hand(u, y, s2, w, volume)
    r = np.sum((y[None] - u[:, None]) ** 2, axis=2)
    assert st.s2 == pytest.approx(np.sum(p * r) / (2 * p.sum()), rel=1e-11)
    np.testing.assert_array_equal(st.theta, u)
    np.testing.assert_array_equal(st.coef, 0.0)


def test_a_fixed_sigma2_runs_every_iteration_and_counts_as_converged():
    u, y = _sets()
    st = EMState(u=u, kernel=Kernel.of(_gauss(u)), coef=np.zeros_like(u), s2=0.3, w=0.1, it=4)
    run_em(st, y, lam=2.0, volume=9.0, max_iter=6, tol=0.5, fixed_s2=0.3)
    assert st.s2 == 0.3 and st.it == 10 and st.ok and st.why == "tolerance"
    # the iterations are EM at that σ²: the closed form six times
    coef = np.zeros_like(u)
    for _ in range(6):
        coef, _ = _one_em_iteration_by_hand(u, _gauss(u), coef, y, 0.3, 0.1, 9.0, 2.0)
    np.testing.assert_allclose(st.coef, coef, rtol=1e-8, atol=1e-10)


def test_em_stops_at_its_relative_tolerance_and_not_before():
    """The σ² of plain EM by hand, iteration after iteration: the fit stops at the first iteration whose
    relative change is at most tol, with that iteration's σ²."""
    u, y = _bent_outline()
    g = _gauss(u)
    volume, lam, w = 9.0, 2.0, 0.1
    s2s, coef = [1.0], np.zeros_like(u)
    for _ in range(30):
        coef, s2 = _one_em_iteration_by_hand(u, g, coef, y, s2s[-1], w, volume, lam)
        s2s.append(s2)
    change = np.abs(np.diff(s2s)) / np.array(s2s[:-1])
    tol = float(np.sort(change)[12]) * (1 + 1e-6)  # some iteration's change, met part way
    assert np.min(np.abs(change / tol - 1)) < 1e-5 and np.sort(np.abs(change / tol - 1))[1] > 1e-3
    stop = int(np.argmax(change <= tol)) + 1
    assert 1 < stop < 30
    st = run_em(EMState(u=u, kernel=Kernel.of(g), coef=np.zeros_like(u), s2=1.0, w=w), y, lam=lam, volume=volume,
                max_iter=30, tol=tol, accelerate=False)
    assert st.it == stop and st.ok and st.why == "tolerance"
    assert st.s2 == pytest.approx(s2s[stop], rel=1e-5)  # the Woodbury form rounds differently


def test_the_acceleration_starts_after_plain_iter_iterations_of_the_whole_fit():
    """A fit that has run k iterations already accelerates after PLAIN_ITER − k more: the same iterates as
    a fresh fit with accelerate=False for those, and as one uninterrupted fit in all."""
    u, y = _bent_outline()
    g = _gauss(u)
    o = dict(lam=2.0, volume=9.0, tol=0.0, s2_floor=1e-9)
    whole = run_em(EMState(u=u, kernel=Kernel.of(g), coef=np.zeros_like(u), s2=1.0, w=0.1), y, max_iter=PLAIN_ITER + 9,
                   **o)
    part = run_em(EMState(u=u, kernel=Kernel.of(g), coef=np.zeros_like(u), s2=1.0, w=0.1), y, max_iter=10, **o)
    assert part.it == 10
    run_em(part, y, max_iter=PLAIN_ITER - 1, **o)
    assert part.it == whole.it == PLAIN_ITER + 9
    # the same to rounding (G W is carried through the uninterrupted fit and recomputed from W by the
    # resumed one); acceleration from the wrong iteration changes W by about 1e-3 of its size
    np.testing.assert_allclose(part.coef, whole.coef, rtol=1e-8, atol=1e-8)
    plain = run_em(EMState(u=u, kernel=Kernel.of(g), coef=np.zeros_like(u), s2=1.0, w=0.1), y,
                   max_iter=PLAIN_ITER + 9, accelerate=False, **o)
    assert abs(plain.s2 - whole.s2) > 1e-9 * whole.s2  # the cycles after PLAIN_ITER are not plain EM


def test_the_objective_without_a_kernel_is_the_mixtures_negative_log_likelihood():
    u, y = _sets()
    for w, s2 in ((0.0, 0.5), (0.4, 0.05)):
        st = EMState(u=u, kernel=None, coef=np.zeros_like(u), s2=s2, w=w)
        comp = np.array([multivariate_normal(mean=t, cov=s2 * np.eye(2)).logpdf(y) for t in u])
        terms = [logsumexp(comp, axis=0) + np.log((1 - w) / len(u))]
        if w > 0:
            terms.append(np.full(len(y), np.log(w / 9.0)))
        assert objective(st, y, lam=5.0, volume=9.0) == pytest.approx(-logsumexp(np.stack(terms), axis=0).sum(),
                                                                      rel=1e-11)


def test_the_objective_adds_the_dense_kernels_energy():
    u, y = _sets()
    g = np.kron(_gauss(u), np.eye(2))
    coef = 0.1 * np.cos(u)
    st = EMState(u=u, kernel=Kernel(full=g), coef=coef, s2=0.2, w=0.1)
    bare = EMState(u=st.theta, kernel=None, coef=coef, s2=0.2, w=0.1)
    energy = float(coef.ravel() @ g @ coef.ravel())
    assert st.kernel.energy(coef) == pytest.approx(energy, rel=1e-12)
    assert objective(st, y, lam=3.0, volume=9.0) == pytest.approx(objective(bare, y, lam=3.0, volume=9.0)
                                                                   + 1.5 * energy, rel=1e-12)


def test_the_factored_kernel_rebuilds_its_matrix_and_drops_only_negligible_eigenvalues():
    rng = np.random.default_rng(1)
    u = rng.normal(size=(12, 2))
    g = _gauss(u, 0.3)
    k = Kernel.of(g)
    np.testing.assert_allclose(k.q @ np.diag(k.ev) @ k.q.T, g, atol=1e-12)
    np.testing.assert_allclose(k.q.T @ k.q, np.eye(k.ev.size), atol=1e-12)
    coef = rng.normal(size=(12, 2))
    np.testing.assert_allclose(k.apply(coef), g @ coef, atol=1e-12)
    assert k.energy(coef) == pytest.approx(float(np.sum(coef * (g @ coef))), rel=1e-12)
    # a repeated point makes G singular: its zero eigenvalue is dropped, and the rest kept
    v = np.vstack([u, u[:3]])
    gv = _gauss(v, 0.3)
    kv = Kernel.of(gv)
    ev = np.linalg.eigvalsh(gv)
    assert kv.ev.size == int(np.sum(ev > EIG_RTOL * ev[-1])) == 12
    np.testing.assert_allclose(kv.q @ np.diag(kv.ev) @ kv.q.T, gv, atol=1e-10)
    # the threshold is relative: the same kernel at any scale keeps the same eigenvalues
    for scale in (1e-8, 1e-4, 1e4):
        assert Kernel.of(scale * gv).ev.size == 12
        assert Kernel.of(scale * g).ev.size == k.ev.size
    # only the symmetric part counts (what a kernel matrix is)
    skew = np.triu(rng.normal(size=(12, 12)), 1)
    ks = Kernel.of(g + skew - skew.T)
    np.testing.assert_allclose(ks.q @ np.diag(ks.ev) @ ks.q.T, g, atol=1e-12)


def test_coefficients_in_the_kernels_range_keep_the_fit_and_are_reproduced_by_the_untruncated_kernel():
    """A converged fit's W has a part along the eigenvectors the truncation dropped (the M-step's
    B / λσ² there); Q Qᵀ W keeps G W and the prior, and the untruncated kernel applied to it gives
    G W at the source points, which W itself does not."""
    u, y = _bent_outline()
    g = _gauss(u, s2g=2.0)  # a wide kernel: many eigenvalues under EIG_RTOL of the largest
    kernel = Kernel.of(g)
    assert 0 < kernel.ev.size < len(u)
    st = run_em(EMState(u=u, kernel=kernel, coef=np.zeros_like(u), s2=1.0, w=0.1), y, lam=2.0, volume=9.0,
                max_iter=200, tol=1e-8)
    w_in = kernel.in_range(st.coef)
    np.testing.assert_allclose(kernel.apply(w_in), kernel.apply(st.coef), atol=1e-12)
    assert kernel.energy(w_in) == pytest.approx(kernel.energy(st.coef), rel=1e-9)
    np.testing.assert_allclose(g @ w_in, kernel.apply(st.coef), atol=1e-9)
    assert np.abs(g @ st.coef - kernel.apply(st.coef)).max() > 1e3 * np.abs(g @ w_in - kernel.apply(st.coef)).max()
    np.testing.assert_allclose(kernel.in_range(w_in), w_in, atol=1e-12)  # a projection
    dense = Kernel(full=np.kron(g, np.eye(2)))
    assert dense.in_range(st.coef) is st.coef


def test_the_eigenvalue_threshold_is_relative_to_the_largest_at_any_scale():
    """A kernel built from chosen eigenvalues: those below EIG_RTOL of the largest are dropped (not those
    below EIG_RTOL of the second largest, nor of 1), whatever the kernel's scale; a zero kernel keeps none."""
    q, _ = np.linalg.qr(np.random.default_rng(8).normal(size=(9, 9)))
    r = EIG_RTOL  # 0.5 r: under EIG_RTOL of 1, over of 0.3
    ev = np.array([1.0, 0.3, 1e-2, 1e3 * r, 10 * r, 3 * r, 0.5 * r, 0.05 * r, 1e-4 * r])
    g = q @ np.diag(ev) @ q.T
    for scale in (1e-6, 1.0, 1e6):
        k = Kernel.of(scale * g)
        np.testing.assert_allclose(np.sort(k.ev), np.sort(scale * ev[ev > EIG_RTOL]), rtol=1e-5)
    assert Kernel.of(np.zeros((4, 4))).ev.size == 0


def test_the_dense_kernel_applies_as_its_matrix():
    rng = np.random.default_rng(4)
    full = rng.normal(size=(10, 10))
    coef = rng.normal(size=(5, 2))
    k = Kernel(full=full)
    np.testing.assert_allclose(k.apply(coef), (full @ coef.reshape(-1)).reshape(5, 2), atol=1e-14)


def test_the_outlier_term_and_the_box_are_their_definitions():
    assert outlier_term(10, 2, 0.5, 0.2, 4.0) == pytest.approx(np.pi * 0.25 * 10 / 4.0, rel=1e-14)
    assert outlier_term(7, 3, 2.0, 0.5, 3.0) == pytest.approx((4 * np.pi) ** 1.5 * 7 / 3.0, rel=1e-14)
    assert outlier_term(7, 3, 2.0, 0.0, 3.0) == 0.0
    # each side of the box is at least the target's spacing, the median distance to the nearest other point
    grid = np.stack(np.meshgrid(np.arange(3.0), np.arange(4.0)), axis=-1).reshape(-1, 2)  # spacing 1, sides 2, 3
    assert box_volume(grid) == pytest.approx(2.0 * 3.0, rel=1e-15)
    y = np.array([[0.0, 1.0], [2.0, -1.0], [0.5, 3.0]])
    nearest = [min(np.linalg.norm(y[i] - y[j]) for j in range(3) if j != i) for i in range(3)]
    assert box_volume(y) == pytest.approx(max(2.0, np.median(nearest)) * 4.0, rel=1e-15)
    pair = np.array([[0.0, 1.0, 2.0], [3.0, -1.0, 2.5]])
    assert box_volume(pair) == pytest.approx(np.linalg.norm(pair[1] - pair[0]) ** 3, rel=1e-14)
    # a flat target (all on one line) is a slab one spacing thick
    line = np.column_stack([np.linspace(0, 2, 5), np.zeros(5)])
    assert box_volume(line) == pytest.approx(2.0 * 0.5, rel=1e-15)
    # a single point has no other point: spacing 0
    assert point_spacing(np.array([[0.3, -1.0]])) == 0.0


def test_the_posteriors_are_the_models_and_a_point_no_component_reaches_takes_none():
    u, y = _sets()
    for w in (0.0, 0.3):
        np.testing.assert_allclose(posteriors(u, y, 0.2, w, 9.0), _p_by_hand(u, y, 0.2, w, 9.0), rtol=1e-12,
                                   atol=1e-300)
    # without outliers, a target point beyond every component's reach: a column of zeros, not NaN
    far = np.vstack([y, [[1e3, 1e3]]])
    p = posteriors(u, far, 0.01, 0.0, 9.0)
    assert np.all(np.isfinite(p)) and np.all(p[:, -1] == 0.0)
    np.testing.assert_allclose(p[:, :-1].sum(axis=0), 1.0, rtol=1e-12)


def test_squared_distances_are_never_negative_and_match_the_differences():
    rng = np.random.default_rng(6)
    x = rng.normal(size=(8, 3)) * 1e3
    y = rng.normal(size=(5, 3))
    np.testing.assert_allclose(sq_dist(x, y), np.sum((x[:, None] - y[None]) ** 2, axis=2), rtol=1e-12)
    same = sq_dist(x, x)
    assert np.all(same >= 0.0) and np.all(np.diag(same) <= 1e-6)


def test_the_start_sigma2_of_a_set_on_itself_and_of_one_point():
    p = np.array([[1.5, -2.0]])
    assert initial_sigma2(p, p) == 0.0
    assert initial_sigma2(p, p + [3.0, 4.0]) == pytest.approx(25.0 / 2, rel=1e-14)


@pytest.mark.parametrize("dense", [False, True])
def test_single_precision_inputs_give_the_double_precision_fit_of_the_same_values(dense):
    """run_em works in float64 whatever its arrays' types: float32 sets, kernel and coefficients give
    bit for bit the fit of the same values in float64."""
    u, y = _bent_outline(n=16, m=14)
    g = _gauss(u)
    u32, y32 = u.astype(np.float32), y.astype(np.float32)
    k = Kernel(full=np.kron(g, np.eye(2))) if dense else Kernel.of(g)
    k32 = Kernel(full=k.full.astype(np.float32)) if dense else Kernel(q=k.q.astype(np.float32),
                                                                         ev=k.ev.astype(np.float32))
    k64 = Kernel(full=k32.full.astype(float)) if dense else Kernel(q=k32.q.astype(float), ev=k32.ev.astype(float))
    c32 = (0.01 * np.cos(u)).astype(np.float32)
    o = dict(lam=2.0, volume=9.0, max_iter=8, tol=0.0)
    a = run_em(EMState(u=u32, kernel=k32, coef=c32, s2=0.5, w=0.1), y32, **o)
    b = run_em(EMState(u=u32.astype(float), kernel=k64, coef=c32.astype(float), s2=0.5, w=0.1), y32.astype(float),
               **o)
    np.testing.assert_array_equal(a.coef, b.coef)
    assert a.s2 == b.s2 and a.coef.dtype == np.float64

"""The batched bound matrices (shapelib.geometry.bound_matrices) against the per-pair functions,
closed forms and an independent high-precision sum; symmetry, blocks, σ² sweeps."""

from decimal import Decimal, getcontext

import numpy as np
import pytest

from shapelib import fisher_rao_lower_bound, l2_distance
from shapelib.geometry.bound_matrices import (
    alpha_bound_block,
    alpha_bound_matrix,
    bound_block,
    bound_matrix_sweep,
    fisher_rao_bound_block,
    fisher_rao_bound_matrix,
)
from shapelib.geometry.gmm import _l2_sq_near


#: the populations here are noisy copies of one random shape, at σ chosen for the identities tested
#: (small σ on purpose): the pose and scale advice of the per-pair entry points is not the subject
pytestmark = [pytest.mark.filterwarnings("ignore::shapelib.geometry.procrustes.PoseWarning"),
              pytest.mark.filterwarnings("ignore::shapelib.geometry.scale.ScaleWarning")]

def _population(rng, n, k, d, *, spread=0.15, size=3.0):
    """``n`` noisy copies of one random shape (a population: close shapes, the hard case)."""
    base = rng.normal(size=(k, d)) * size
    return base + spread * rng.normal(size=(n, k, d))


def _with_near_pairs(x, rng, eps=(1e-4, 1e-7, 1e-10)):
    """Append shapes within ``eps`` of shape 0 and an exact copy of shape 1."""
    extra = [x[0] + e * rng.normal(size=x[0].shape) for e in eps] + [x[1].copy()]
    return np.concatenate([x, np.stack(extra)])


def _decimal_l2_sq(u, v, s2):
    """‖p_u − p_v‖² summed in 60-digit decimal arithmetic: an independent reference."""
    getcontext().prec = 60
    k, d = u.shape
    c = 1 / (4 * Decimal(s2))

    def overlap(a, b):
        return sum((-(sum((Decimal(float(p[t])) - Decimal(float(q[t]))) ** 2 for t in range(d))) * c).exp()
                   for p in a for q in b)

    pi = Decimal("3.14159265358979323846264338327950288419716939937510582097494")
    norm = (4 * pi * Decimal(s2)) ** (Decimal(-d) / 2) / k ** 2
    return float((overlap(u, u) + overlap(v, v) - 2 * overlap(u, v)) * norm)


# ---------------------------------------------------------------------------------------------
# α bound
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("s2", [0.01, 0.3, 5.0])
def test_alpha_matrix_equals_l2_distance_pair_by_pair(rng, d, s2):
    x = _with_near_pairs(_population(rng, 14, 9, d), rng)
    a = alpha_bound_matrix(x, sigma2=s2)
    n = len(x)
    for i in range(n):
        for j in range(i + 1, n):
            ref = l2_distance(x[i], x[j], sigma2=s2)
            assert a[i, j] == pytest.approx(ref, rel=1e-12, abs=0), (i, j)
    assert a[1, n - 1] == 0.0  # an exact copy: the cancellation-free form gives exactly 0


@pytest.mark.parametrize("d", [2, 3])
def test_alpha_near_pairs_match_a_60_digit_sum(rng, d):
    """Shapes 1e-6 and 1e-9 apart: the plain difference of overlaps has lost 12 and 18 digits;
    the batched matrix and l2_distance both keep them."""
    u = rng.normal(size=(5, d)) * 2
    x = np.stack([u, u + 1e-6 * rng.normal(size=u.shape), u + 1e-9 * rng.normal(size=u.shape),
                  u + 0.3 * rng.normal(size=u.shape)])
    s2 = 0.7
    a = alpha_bound_matrix(x, sigma2=s2)
    for j in (1, 2, 3):
        exact = np.sqrt(_decimal_l2_sq(x[0], x[j], s2))
        assert a[0, j] == pytest.approx(exact, rel=1e-12, abs=0)  # abs=0: approx's default 1e-12 would swamp 1e-9
        assert l2_distance(x[0], x[j], sigma2=s2) == pytest.approx(exact, rel=1e-12, abs=0)
    assert _l2_sq_near(x[:1], x[2:3], s2)[0] == pytest.approx(_decimal_l2_sq(x[0], x[2], s2), rel=1e-12, abs=0)


@pytest.mark.parametrize("d", [2, 3])
def test_alpha_matrix_single_landmark_closed_form(rng, d):
    """K = 1: ‖p_u − p_v‖² = 2 (4πσ²)^{-d/2} (1 − exp(−|u − v|²/4σ²))."""
    x = rng.normal(size=(6, 1, d))
    s2 = 0.4
    a = alpha_bound_matrix(x, sigma2=s2)
    r2 = np.sum((x[:, None, 0] - x[None, :, 0]) ** 2, axis=-1)
    want = np.sqrt(2 * (4 * np.pi * s2) ** (-d / 2) * -np.expm1(-r2 / (4 * s2)))
    np.testing.assert_allclose(a, want, rtol=1e-12, atol=0)


def test_alpha_matrix_far_from_the_reference_uses_plain_overlaps(rng):
    """Shapes spread far beyond √2 σ of their mean (unaligned, small σ): the plain overlaps, still
    equal to l2_distance pair by pair; mixed populations (some shapes near the mean) too."""
    base = rng.normal(size=(8, 2)) * 3
    x = np.stack([base + rng.normal(size=2) * 5 for _ in range(6)] + [base + 0.01 * rng.normal(size=base.shape)
                                                                      for _ in range(6)])
    for s2 in (0.05, 2.0):
        a = alpha_bound_matrix(x, sigma2=s2)
        for i in range(len(x)):
            for j in range(i + 1, len(x)):
                assert a[i, j] == pytest.approx(l2_distance(x[i], x[j], sigma2=s2), rel=1e-12)


def test_alpha_matrix_is_a_symmetric_distance_matrix_and_threads_agree(rng):
    x = _population(rng, 20, 7, 2)
    a1 = alpha_bound_matrix(x, sigma2=0.5, n_threads=1)
    a2 = alpha_bound_matrix(x, sigma2=0.5, n_threads=2)
    np.testing.assert_array_equal(a1, a2)
    np.testing.assert_array_equal(a1, a1.T)
    assert np.all(np.diag(a1) == 0) and np.all(a1[~np.eye(20, dtype=bool)] > 0)
    # triangle inequality (it is the L² distance of densities)
    assert np.all(a1[:, None, :] <= a1[:, :, None] + a1[None, :, :] + 1e-12)  # d(i,k) <= d(i,j) + d(j,k)


@pytest.mark.parametrize("d", [2, 3])
def test_alpha_blocks_assemble_to_the_full_matrix(rng, d):
    x = _with_near_pairs(_population(rng, 11, 6, d), rng)
    full = alpha_bound_matrix(x, sigma2=0.3)
    cut = [0, 5, 9, len(x)]
    for a0, a1 in zip(cut[:-1], cut[1:]):
        for b0, b1 in zip(cut[:-1], cut[1:]):
            blk = alpha_bound_block(x[a0:a1], x[b0:b1], sigma2=0.3)
            mask = full[a0:a1, b0:b1] > 0
            np.testing.assert_allclose(blk[mask], full[a0:a1, b0:b1][mask], rtol=1e-12)
            assert np.all(blk[~mask] == 0)  # the same shape, or an exact copy


# ---------------------------------------------------------------------------------------------
# Fisher–Rao bound
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("d, s2, n", [(2, 0.05, 7), (2, 0.5, 7), (3, 0.5, 4)])
def test_fisher_rao_matrix_equals_the_per_pair_bound_within_quadrature_accuracy(rng, d, s2, n):
    x = _with_near_pairs(_population(rng, n, 6, d, size=1.5), rng, eps=(1e-4, 1e-7))
    f = fisher_rao_bound_matrix(x, sigma2=s2)
    n = len(x)
    for i in range(n):
        for j in range(i + 1, n):
            ref = fisher_rao_lower_bound(x[i], x[j], sigma2=s2)
            assert f[i, j] == pytest.approx(ref, rel=1e-7, abs=0), (i, j)
    assert f[1, n - 1] == 0.0


def test_fisher_rao_near_pairs_keep_their_digits(rng):
    """A pair 1e-8 apart: 1 − ∫√(p_u p_v) is 1e-16-small, so 2 arccos of the Bhattacharyya
    coefficient would be noise; the batched bound is first order in the displacement, like the
    per-pair one, and both scale linearly with it."""
    u = rng.normal(size=(6, 2))
    step = rng.normal(size=u.shape)
    x = np.stack([u, u + 1e-8 * step, u + 2e-8 * step])
    f = fisher_rao_bound_matrix(x, sigma2=0.5)
    assert f[0, 1] == pytest.approx(fisher_rao_lower_bound(u, x[1], sigma2=0.5), rel=1e-7)
    assert f[0, 2] == pytest.approx(2 * f[0, 1], rel=1e-6)


@pytest.mark.parametrize("d", [2, 3])
def test_fisher_rao_matrix_single_landmark_closed_form(rng, d):
    """K = 1: ∫√(p_u p_v) = exp(−|u − v|²/8σ²), so the bound is 2 arccos of it."""
    x = rng.normal(size=(5, 1, d))
    s2 = 0.6
    f = fisher_rao_bound_matrix(x, sigma2=s2)
    r2 = np.sum((x[:, None, 0] - x[None, :, 0]) ** 2, axis=-1)
    want = 2 * np.arccos(np.exp(-r2 / (8 * s2)))
    np.testing.assert_allclose(f, want, rtol=1e-8, atol=1e-12)


def test_fisher_rao_matrix_agrees_with_a_finer_grid(rng):
    x = _population(rng, 6, 8, 2, size=1.5)
    default = fisher_rao_bound_matrix(x, sigma2=0.3)
    fine = fisher_rao_bound_matrix(x, sigma2=0.3, grid_spacing=0.2, grid_margin=9.0)
    off = ~np.eye(6, dtype=bool)
    np.testing.assert_allclose(default[off], fine[off], rtol=1e-6)


@pytest.mark.parametrize("d", [2, 3])
def test_fisher_rao_blocks_assemble_to_the_full_matrix(rng, d):
    x = _population(rng, 9, 5, d, size=1.5)
    full = fisher_rao_bound_matrix(x, sigma2=0.4)
    for a0, a1, b0, b1 in ((0, 4, 4, 9), (4, 9, 0, 4), (0, 9, 0, 9)):
        blk = fisher_rao_bound_block(x[a0:a1], x[b0:b1], sigma2=0.4)
        np.testing.assert_allclose(blk, full[a0:a1, b0:b1], rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(full, full.T)
    assert np.all(np.diag(full) == 0) and np.all(full <= 2 * np.pi)


def test_fisher_rao_matrix_refuses_a_grid_it_cannot_hold(rng):
    """Shapes in pixel coordinates far apart ask one grid for every shape: refused with
    make_grid's message before anything is allocated (the engine then goes pair by pair)."""
    x = _population(rng, 3, 5, 2)
    x[1] += 5000.0
    with pytest.raises(ValueError, match="quadrature grid would have"):
        fisher_rao_bound_matrix(x, sigma2=0.5)


# ---------------------------------------------------------------------------------------------
# Sweeps and dispatch
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("d", [2, 3])
def test_sweep_equals_separate_calls(rng, d):
    x = _with_near_pairs(_population(rng, 8, 6, d, size=1.5), rng, eps=(1e-6,))
    s2s = [0.02, 0.3, 4.0]
    sweep = bound_matrix_sweep(x, metric="alpha_bound", sigma2s=s2s)
    assert sweep.shape == (3, len(x), len(x))
    for s, s2 in enumerate(s2s):
        np.testing.assert_allclose(sweep[s], alpha_bound_matrix(x, sigma2=s2), rtol=1e-12, atol=0)
    fr = bound_matrix_sweep(x, metric="fisher_rao_bound", sigma2s=s2s[1:], grid_spacing=0.5)
    for s, s2 in enumerate(s2s[1:]):
        np.testing.assert_array_equal(fr[s], fisher_rao_bound_matrix(x, sigma2=s2, grid_spacing=0.5))


def test_small_sigma_limit_is_the_separated_gaussians(rng):
    """σ far below the landmark spacing: the K Gaussians of a shape no longer overlap each other
    nor those of another shape's displaced landmarks, so ‖p_u‖² → (4πσ²)^{-d/2}/K and the α bound
    of two shapes whose landmarks all moved tends to √(2 (4πσ²)^{-d/2} / K)."""
    x = _population(rng, 4, 5, 2, spread=0.5, size=4.0)
    s2 = 1e-4
    a = alpha_bound_matrix(x, sigma2=s2)
    limit = np.sqrt(2 * (4 * np.pi * s2) ** -1 / 5)
    np.testing.assert_allclose(a[~np.eye(4, dtype=bool)], limit, rtol=1e-6)


def test_bad_input_is_named(rng):
    x = _population(rng, 4, 5, 2)
    with pytest.raises(ValueError, match="rows and cols must have the same"):
        alpha_bound_block(x, x[:, :4], sigma2=0.5)
    with pytest.raises(ValueError, match="sigma2"):
        alpha_bound_matrix(x, sigma2=0.0)
    with pytest.raises(ValueError, match="sigma2s must be a non-empty"):
        bound_matrix_sweep(x, metric="alpha_bound", sigma2s=[])
    with pytest.raises(ValueError, match="sigma2"):
        bound_matrix_sweep(x, metric="alpha_bound", sigma2s=[0.5, -1.0])
    with pytest.raises(ValueError, match="metric must be one of"):
        bound_matrix_sweep(x, metric="alpha", sigma2s=[0.5])
    with pytest.raises(ValueError, match="grid_spacing"):
        fisher_rao_bound_matrix(x, sigma2=0.5, grid_spacing=0)
    with pytest.raises(ValueError, match="n_threads"):
        alpha_bound_matrix(x, sigma2=0.5, n_threads=0)
    bad = x.copy()
    bad[2, 1, 0] = np.nan
    with pytest.raises(ValueError, match=r"shapes\[2\]"):
        fisher_rao_bound_matrix(bad, sigma2=0.5)
    np.testing.assert_array_equal(bound_block("alpha_bound", x, sigma2=0.5), alpha_bound_matrix(x, sigma2=0.5))


def test_near_form_in_chunks_and_at_a_wide_sigma(rng):
    """The cancellation-free ‖p_u − p_v‖² against the 60-digit sum: pairs taken one chunk at a time
    (a chunk smaller than one pair's K² terms), and l2_distance at σ = 1000 where landmarks move by
    about 1 (within √2 σ, so the near form applies; the plain difference has lost 8 digits there)."""
    u = rng.normal(size=(4, 3, 2))
    v = u + 1e-5 * rng.normal(size=u.shape)
    got = _l2_sq_near(u, v, 0.7, chunk=4)
    np.testing.assert_allclose(got, [_decimal_l2_sq(u[p], v[p], 0.7) for p in range(4)], rtol=1e-12)
    wide = np.random.default_rng(4)
    u = wide.normal(size=(5, 2))
    v = u + 0.5 * wide.normal(size=u.shape)
    assert l2_distance(u, v, sigma2=1e6) == pytest.approx(np.sqrt(_decimal_l2_sq(u, v, 1e6)), rel=1e-12, abs=0)


@pytest.mark.parametrize("call, message", [
    (lambda x: alpha_bound_block(x[0], x, sigma2=0.5), r"^rows must have shape \(N, K, d\)"),
    (lambda x: fisher_rao_bound_block(x, x[0], sigma2=0.5), r"^cols must have shape \(N, K, d\)"),
    (lambda x: alpha_bound_block(x, x[:, :4], sigma2=0.5),
     r"^rows and cols must have the same \(K, d\); got \(5, 2\) and \(4, 2\)$"),
    (lambda x: bound_matrix_sweep(x[0], metric="alpha_bound", sigma2s=[0.5]), r"^shapes must have shape \(N, K, d\)"),
    (lambda x: alpha_bound_matrix(x[0], sigma2=0.5), r"^shapes must have shape \(N, K, d\)"),
    (lambda x: fisher_rao_bound_matrix(x, sigma2=0.5, grid_spacing=0), r"^grid_spacing must be a positive finite number"),
    (lambda x: fisher_rao_bound_block(x, sigma2=0.5, grid_margin=-1.0), r"^grid_margin must be a positive finite number"),
    (lambda x: fisher_rao_bound_matrix(x, sigma2=0.5, n_threads=0), r"^n_threads must be a positive integer"),
    (lambda x: bound_matrix_sweep(x, metric="alpha_bound", sigma2s=0.5),
     r"^sigma2s must be a non-empty 1-D sequence of positive numbers; got 0.5$"),
    (lambda x: bound_matrix_sweep(x, metric="alpha_bound", sigma2s=[[0.5, 1.0]]),
     r"^sigma2s must be a non-empty 1-D sequence of positive numbers"),
    (lambda x: bound_block("alpha", x, sigma2=0.5), r"^metric must be one of \('alpha_bound', 'fisher_rao_bound'\); got 'alpha'$"),
    (lambda x: bound_block("alpha_bound", x, sigma2=0.5, n_threads=0), r"^n_threads must be a positive integer"),
    (lambda x: bound_block("fisher_rao_bound", x, x[:2], sigma2=0.5, n_threads=0), r"^n_threads must be a positive integer"),
    (lambda x: alpha_bound_block(x, x[:2], sigma2=0.5, n_threads=0), r"^n_threads must be a positive integer"),
    (lambda x: fisher_rao_bound_block(x, sigma2=0.5, n_threads=0), r"^n_threads must be a positive integer"),
    (lambda x: bound_matrix_sweep(x, metric="alpha_bound", sigma2s=[0.5], n_threads=0), r"^n_threads must be a positive integer"),
    (lambda x: bound_matrix_sweep(x, metric="fisher_rao_bound", sigma2s=[0.5], n_threads=0),
     r"^n_threads must be a positive integer"),
])
def test_each_entry_point_names_the_argument_at_fault(rng, call, message):
    with pytest.raises(ValueError, match=message):
        call(_population(rng, 4, 5, 2))


@pytest.mark.parametrize("metric", ["alpha_bound", "fisher_rao_bound"])
def test_bound_block_by_name_is_the_per_pair_bound_of_rows_against_cols(rng, metric):
    """``bound_block(metric, rows, cols)``: entry (r, c) is the per-pair bound of rows[r] and
    cols[c] (l2_distance; fisher_rao_lower_bound to its quadrature accuracy), not rows with itself."""
    x = _population(rng, 5, 6, 2, size=1.5)
    rows, cols = x[:2], x[2:]
    got = bound_block(metric, rows, cols, sigma2=0.4, n_threads=1)
    assert got.shape == (2, 3)
    one = l2_distance if metric == "alpha_bound" else fisher_rao_lower_bound
    want = np.array([[one(u, v, sigma2=0.4) for v in cols] for u in rows])
    np.testing.assert_allclose(got, want, rtol=1e-12 if metric == "alpha_bound" else 1e-7, atol=0)


def test_alpha_matrix_far_from_the_reference_is_quiet(rng):
    """Shapes 5 apart at σ² = 0.01 (|δ|²/2σ² ~ 1e3), one of them mirrored (landmark offsets from the
    reference in opposite directions): the centred form's exponentials overflow for the pairs and
    self terms that use the plain overlaps, which must happen silently (no RuntimeWarning) and leave
    every entry equal to l2_distance."""
    import warnings

    base = rng.normal(size=(4, 2)) * 3
    x = np.stack([base + rng.normal(size=2) * 5 for _ in range(5)] + [-base])  # mirrored: δ_a·δ_b < 0
    s2 = 0.01
    want = np.array([[l2_distance(u, v, sigma2=s2) for v in x] for u in x])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = alpha_bound_matrix(x, sigma2=s2, n_threads=1)
        sweep = bound_matrix_sweep(x, metric="alpha_bound", sigma2s=[s2, 2 * s2], n_threads=1)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=0)
    np.testing.assert_allclose(sweep[0], want, rtol=1e-12, atol=0)


def _direct_fisher_rao(rows, cols, s2, spacing, margin):
    """4 arcsin(‖ψ_r − ψ_c‖/4) with ψ = 2√p from gmm_density at the nodes of the grid covering both
    sets, ‖·‖² the node sum times the node weight: the sum the batched bound evaluates, term by term."""
    from shapelib.geometry.gmm import gmm_density
    from shapelib.geometry.quadrature import make_grid

    grid = make_grid(np.concatenate([rows, cols]), sigma2=s2, grid_spacing=spacing, grid_margin=margin)
    psi = lambda xs: np.stack([2 * np.sqrt(gmm_density(grid.nodes, u, sigma2=s2)) for u in xs])  # noqa: E731
    pr, pc = psi(rows), psi(cols)
    sq = grid.weight * ((pr[:, None, :] - pc[None, :, :]) ** 2).sum(axis=-1)
    return 4 * np.arcsin(np.minimum(np.sqrt(sq) / 4, 1.0)), len(grid.nodes)


def test_fisher_rao_block_and_matrix_are_the_direct_sums_on_their_grid(rng):
    """A narrow grid (step 0.2 σ, margin 2.5 σ: not the defaults) covering rows and columns
    that are far apart (Bhattacharyya coefficient near 0), one column a 1e-7 copy of a row: every
    entry is the direct sum w Σ (ψ_r − ψ_c)² on that grid (ψ from gmm_density), to rounding. The grid
    has more nodes than one chunk of the ψ matrix, so the sums run over several chunks."""
    s2 = 0.25
    rows = rng.normal(size=(3, 4, 2)) * 1.5
    cols = np.stack([rows[0] + 1e-7 * rng.normal(size=(4, 2)), rows[1] + [9.0, 0.0], rng.normal(size=(4, 2)) * 1.5])
    want, n_nodes = _direct_fisher_rao(rows, cols, s2, 0.2, 2.5)
    assert n_nodes > 8192 and want[1, 1] > 3.0 and want[0, 0] < 1e-5
    got = fisher_rao_bound_block(rows, cols, sigma2=s2, grid_spacing=0.2, grid_margin=2.5, n_threads=1)
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=0)
    x = np.concatenate([rows, cols])
    full, _ = _direct_fisher_rao(x, x, s2, 0.2, 2.5)
    np.fill_diagonal(full, 0.0)
    got = fisher_rao_bound_matrix(x, sigma2=s2, grid_spacing=0.2, grid_margin=2.5, n_threads=1)
    np.testing.assert_allclose(got, full, rtol=1e-9, atol=0)


@pytest.mark.parametrize("metric, n", [("alpha_bound", 130), ("fisher_rao_bound", 70)])
def test_many_near_pairs_are_all_recomputed(rng, metric, n):
    """n copies of one shape, each moved by ~1e-7 (a population as tight as that): more near pairs
    than one batch of the cancellation-free recomputation (4096 pairs for α, more than 8192 here;
    2048 for Fisher–Rao). The matrix equals its blocks of ten rows, each of which has fewer near
    pairs than one batch; α pairs also equal l2_distance to 1e-12 (the offsets from the reference
    shape are taken from the uncentred landmarks, so they keep their digits)."""
    u = rng.normal(size=(3, 2))
    x = u + 1e-7 * rng.normal(size=(n, 3, 2))
    assert n * (n - 1) // 2 > (8192 if metric == "alpha_bound" else 2048)
    full = bound_block(metric, x, sigma2=0.5, n_threads=1)
    blocks = np.concatenate([bound_block(metric, x[i:i + 10], x, sigma2=0.5, n_threads=1) for i in range(0, n, 10)])
    off = ~np.eye(n, dtype=bool)
    assert np.all(full[off] > 0)
    np.testing.assert_allclose(full[off], blocks[off], rtol=1e-6 if metric == "fisher_rao_bound" else 1e-12, atol=0)
    if metric == "alpha_bound":
        for i, j in rng.integers(0, n, size=(20, 2)):
            if i != j:
                assert full[i, j] == pytest.approx(l2_distance(x[i], x[j], sigma2=0.5), rel=1e-12, abs=0)


def test_alpha_matrix_of_more_shapes_than_one_block_of_self_terms(rng):
    """300 shapes: the self terms ⟨p_i, p_i⟩ and ‖p_i − p_m‖² are taken 256 shapes at a time; every
    entry still equals l2_distance (a sample of pairs, including ones across the 256 boundary)."""
    x = _population(rng, 300, 3, 2, spread=0.3)
    a = alpha_bound_matrix(x, sigma2=0.5, n_threads=1)
    pairs = [(0, 299), (255, 256), (256, 257), (10, 280), (299, 298)] + [tuple(p) for p in rng.integers(0, 300, size=(10, 2))]
    for i, j in pairs:
        want = 0.0 if i == j else l2_distance(x[i], x[j], sigma2=0.5)
        assert a[i, j] == pytest.approx(want, rel=1e-12, abs=0), (i, j)


def test_alpha_block_with_shapes_on_both_sides_of_the_reach(rng):
    """Blocks whose rows are all within √2σ of the reference shape (centred form) and whose columns
    include a shape far outside (plain overlaps), and the other way round; and a population whose
    shapes sit 3σ-ish from their mean at σ² = 0.1, where the centred form would cancel e^{45}-sized
    terms: every entry equals l2_distance."""
    s2 = 0.5
    base = rng.normal(size=(4, 2)) * 2
    near = base + 0.01 * rng.normal(size=(5, 4, 2))
    mixed = np.stack([base + 0.01 * rng.normal(size=(4, 2)), base + [5.0, 0.0]])
    for rows, cols in ((near, mixed), (mixed, near)):
        got = alpha_bound_block(rows, cols, sigma2=s2, n_threads=1)
        want = np.array([[l2_distance(u, v, sigma2=s2) for v in cols] for u in rows])
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=0)
    directions = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
    x = base + 3.0 * directions[:, None, :] + 0.01 * rng.normal(size=(4, 4, 2))
    got = alpha_bound_matrix(x, sigma2=0.1, n_threads=1)
    want = np.array([[0.0 if i == j else l2_distance(x[i], x[j], sigma2=0.1) for j in range(4)] for i in range(4)])
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=0)


def test_alpha_many_near_pairs_within_clusters(rng):
    """Two clusters of 95 shapes, 0.3 either side of the mean shape and 1e-9 apart within a cluster:
    8,930 pairs much closer to each other than to the reference (more than two batches of the
    cancellation-free recomputation), each equal to its blocks' value and to l2_distance."""
    u = rng.normal(size=(3, 2))
    step = np.array([0.3, 0.0])
    x = np.concatenate([u + step + 1e-9 * rng.normal(size=(95, 3, 2)), u - step + 1e-9 * rng.normal(size=(95, 3, 2))])
    full = alpha_bound_matrix(x, sigma2=0.5, n_threads=1)
    blocks = np.concatenate([alpha_bound_block(x[i:i + 10], x, sigma2=0.5, n_threads=1) for i in range(0, 190, 10)])
    off = ~np.eye(190, dtype=bool)
    np.testing.assert_allclose(full[off], blocks[off], rtol=1e-12, atol=0)
    for i, j in [(0, 94), (3, 90), (95, 189), (100, 188), (0, 189)]:
        assert full[i, j] == pytest.approx(l2_distance(x[i], x[j], sigma2=0.5), rel=1e-12, abs=0)


def test_alpha_matrix_of_shapes_near_the_origin(rng):
    """Landmarks within ~0.2 of the origin (offsets from the reference comparable to the coordinates
    themselves), centred form: every entry equals l2_distance."""
    x = rng.normal(size=(3, 2)) * 0.2 + 0.01 * rng.normal(size=(6, 3, 2))
    got = alpha_bound_matrix(x, sigma2=0.5, n_threads=1)
    want = np.array([[0.0 if i == j else l2_distance(x[i], x[j], sigma2=0.5) for j in range(6)] for i in range(6)])
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=0)

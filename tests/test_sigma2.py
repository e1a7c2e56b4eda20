"""σ² from the data (shapelib.geometry.sigma2, scale.estimate_sigma2): recovered on landmarks
drawn from a GMM with a known σ², invariant to pose, its standard error the real spread, and the
advice of the ScaleWarning."""

import warnings

import numpy as np
import pytest

from shapelib import ScaleWarning, geodesic, landmark_spacing
from shapelib.geometry.scale import estimate_sigma2
from shapelib.geometry.procrustes import pose_align
from shapelib.geometry.sigma2 import predictive_sigma2, scatter_sigma2
from tests.conftest import ellipse_population


def _contour(k, d, rng):
    """A mean shape with landmark spacing about 1: a circle (2-D) or a twisted ring (3-D)."""
    t = np.linspace(0, 2 * np.pi, k, endpoint=False)
    r = k / (2 * np.pi)
    if d == 2:
        return np.c_[r * np.cos(t), r * np.sin(t)]
    return np.c_[r * np.cos(t), r * np.sin(t), 0.3 * r * np.sin(2 * t)]


def _random_rotation(d, rng):
    q, r = np.linalg.qr(rng.normal(size=(d, d)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def _gmm_population(rng, *, n, k, d, sigma, pose=False):
    """Each landmark a draw from its mixture component: x_ia = μ_a + N(0, σ² I); with ``pose``,
    every shape then moved rigidly at random (which is not landmark noise)."""
    mu = _contour(k, d, rng)
    x = mu + sigma * rng.normal(size=(n, k, d))
    if pose:
        x = np.stack([s @ _random_rotation(d, rng).T + rng.normal(size=d) * 10 for s in x])
    return x


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("ratio", [0.1, 0.5, 2.0])
def test_scatter_recovers_a_known_sigma2_despite_pose(rng, d, ratio):
    """Landmarks drawn from the eq. (5) mixture of a known mean shape with a known σ², each shape
    then rotated and translated at random: the estimate is within 3 of its standard errors, at
    σ well below, near and above the landmark spacing."""
    x = _gmm_population(rng, n=120, k=24, d=d, sigma=ratio, pose=True)
    est = estimate_sigma2(x)
    assert abs(est.sigma2 - ratio ** 2) <= 3 * est.standard_error, (est.sigma2, ratio ** 2, est.standard_error)
    assert est.method == "scatter" and est.pose_share > 0.9  # the shapes as given are mostly pose
    assert "align the shapes first" in est.summary()
    aligned, _ = pose_align(x)
    again = estimate_sigma2(aligned)
    assert again.sigma2 == pytest.approx(est.sigma2, rel=1e-8) and again.pose_share < 0.02
    assert again.sigma_over_spacing == pytest.approx(np.sqrt(again.sigma2) / landmark_spacing(aligned))


def test_standard_error_is_the_spread_of_the_estimate(rng):
    """σ̂² (as given, no pose fitted) is σ² χ²_df / df: unbiased, with standard deviation σ² √(2/df)."""
    sigma2 = 0.3
    reps = np.array([scatter_sigma2(_gmm_population(rng, n=8, k=5, d=2, sigma=np.sqrt(sigma2)),
                                    superimpose=False)[:2]
                     for _ in range(400)])
    est, se = reps[:, 0], reps[:, 1]
    df = 7 * 5 * 2
    assert se.mean() == pytest.approx(sigma2 * np.sqrt(2 / df), rel=0.05)
    assert est.mean() == pytest.approx(sigma2, abs=4 * sigma2 * np.sqrt(2 / df) / np.sqrt(400))
    assert est.std() == pytest.approx(sigma2 * np.sqrt(2 / df), rel=0.15)


def test_scatter_scales_as_a_squared_length_and_sees_unequal_landmarks(rng):
    x = _gmm_population(rng, n=40, k=10, d=2, sigma=0.2)
    s2, _, per = scatter_sigma2(x)
    assert scatter_sigma2(3.0 * x)[0] == pytest.approx(9 * s2, rel=1e-10)
    assert per.mean() == pytest.approx(s2, rel=1e-12)
    noisy = x.copy()
    noisy[:, 0] += rng.normal(size=(40, 2))  # landmark 0 varies 5x more than the others
    est = estimate_sigma2(noisy)
    lo, hi = est.landmark_range
    assert hi > 2.5 > 1 > lo


@pytest.mark.parametrize("d", [2, 3])
def test_predictive_rule_agrees_at_small_sigma_and_is_low_once_gaussians_overlap(rng, d):
    """The correspondence-free rule: within 10 % of the truth at σ = 0.1 spacing; at one spacing
    the neighbouring components explain part of the scatter and it comes out low (< 0.8)."""
    small = _gmm_population(rng, n=40, k=20, d=d, sigma=0.1)
    assert predictive_sigma2(small, partners=6) == pytest.approx(0.01, rel=0.1)
    overlapping = _gmm_population(rng, n=40, k=20, d=d, sigma=1.0)
    assert predictive_sigma2(overlapping, partners=6) < 0.8
    assert scatter_sigma2(overlapping)[0] == pytest.approx(1.0, rel=0.1)
    est = estimate_sigma2(small, method="predictive")
    assert est.standard_error is None and "held-out prediction" in est.summary()


def test_bad_input_is_named(rng):
    x = _gmm_population(rng, n=5, k=6, d=2, sigma=0.1)
    with pytest.raises(ValueError, match="method must be one of"):
        estimate_sigma2(x, method="median")
    with pytest.raises(ValueError, match="at least 2 shape"):
        estimate_sigma2(x[:1])
    with pytest.raises(ValueError, match="every shape is the same"):
        estimate_sigma2(np.stack([x[0]] * 4))
    with pytest.raises(ValueError, match="no degrees of freedom"):
        scatter_sigma2(rng.normal(size=(2, 2, 2)))


def test_scale_warning_advises_the_estimate(rng):
    """Pixel-scale shapes with σ² = 0.5: the warning gives the data's σ² (and says when even that
    is below the overlap regime, so the bounds are the distances to use)."""
    u = _contour(12, 2, rng) * 50
    v = u + rng.normal(size=u.shape) * 2.0  # scatter 2 px against a 26 px spacing: 0.08 spacings
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("ignore")  # the solver's own warnings (not converged: the gradient underflows)
        warnings.simplefilter("always", ScaleWarning)
        geodesic(u, v, metric="alpha", sigma2=0.5, n_steps=2, max_iter=1)
    text = [str(w.message) for w in caught if issubclass(w.category, ScaleWarning)]
    assert len(text) == 1
    s2 = estimate_sigma2(np.stack([u, v])).sigma2
    assert f"estimate_sigma2(shapes) gives sigma2 = {s2:.3g}" in text[0]
    assert "below 0.2 spacings too" in text[0] and "closed-form bounds (alpha_bound, fisher_rao_bound) are still exact" in text[0]


@pytest.mark.parametrize("d, k", [(2, 4), (2, 2), (3, 2)])
def test_predictive_sigma2_of_two_far_spread_shapes_has_its_closed_form(d, k):
    """Two shapes whose landmarks are 100 apart and differ by radial moves (zero mean, no torque: the
    superimposition leaves them), so each landmark is predicted by its own counterpart alone:
    ŝ² = mean |δ_a|² / d, and the rule returns ŝ²/2 times the pose correction kd / (kd − d(d+1)/2)
    (1 when the pose has as many parameters as the coordinates: two landmarks in 3-D)."""
    if k == 4:
        u = 100.0 * np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])
        eps = np.array([0.3, 0.1, 0.3, 0.1])  # opposite corners move alike
    else:
        u = 100.0 * np.eye(d)[:1] * [[1.0], [-1.0]]
        eps = np.array([0.2, 0.2])
    v = u + eps[:, None] * u / np.linalg.norm(u, axis=1, keepdims=True)
    s2 = np.mean(eps ** 2) / d
    # 2-D: 2k coordinates, 3 pose parameters (2 shifts, 1 rotation); 3-D: 6 coordinates, 6 pose parameters
    pose = {(2, 4): 8 / (8 - 3), (2, 2): 4 / (4 - 3), (3, 2): 1.0}[d, k]
    # the bounded search runs to xatol 1e-8 in log s², plus scipy's own √eps·|log s²| (about 1e-7 here);
    # left at scipy's default xatol (1e-5) it is 5e-7 off in the first case
    assert predictive_sigma2(np.stack([u, v])) == pytest.approx(s2 / 2 * pose, rel=2e-7)


def test_predictive_sigma2_draws_partners_with_its_seed(rng):
    x = ellipse_population(rng, 10, k=6, noise=0.1)
    a = [predictive_sigma2(x, partners=2, seed=s) for s in (0, 0, 3)]
    assert a[0] == a[1] and a[0] != a[2]
    assert predictive_sigma2(x, partners=2) == a[0]
    with pytest.raises(ValueError, match="partners"):
        predictive_sigma2(x, partners=0)


def test_predictive_sigma2_of_three_shapes_pairs_each_with_the_two_others():
    """Three far-spread shapes differing by radial moves A and B: the ordered pairs (u, v), (u, w),
    (v, w) and back differ by A, B and A − B, never a shape with itself (nor a pair twice)."""
    u = 100.0 * np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])
    radial = u / np.linalg.norm(u, axis=1, keepdims=True)
    a, b = np.array([0.3, 0.1, 0.3, 0.1]), np.array([-0.05, 0.2, -0.05, 0.2])
    x = np.stack([u, u + a[:, None] * radial, u + b[:, None] * radial])
    s2 = np.mean(np.concatenate([a ** 2, b ** 2, (a - b) ** 2])) / 2
    assert predictive_sigma2(x) == pytest.approx(s2 / 2 * 8 / 5, rel=1e-6)
    assert predictive_sigma2(x, partners=2, seed=7) == pytest.approx(s2 / 2 * 8 / 5, rel=1e-6)


def test_predictive_sigma2_input_errors():
    with pytest.raises(ValueError, match="^shapes: all landmarks coincide, so no sigma2 can be estimated from them$"):
        predictive_sigma2(np.zeros((3, 4, 2)))
    with pytest.raises(ValueError, match="^shapes must contain at least 2 shape"):
        predictive_sigma2(np.ones((1, 4, 2)))
    with pytest.raises(ValueError, match=r"\bpartners\b"):
        predictive_sigma2(np.random.default_rng(0).normal(size=(3, 4, 2)), partners=0)


def test_scatter_sigma2_of_two_shapes_differing_by_radial_moves_has_its_closed_form():
    """Two squares 100 wide, corners moved radially by δ_a (the superimposition leaves them): each
    deviation from the mean is ±δ_a/2, the degrees of freedom (N − 1) K d − N d(d + 1)/2 = 8 − 6 = 2,
    so σ² = Σ δ_a² / 2 / 2 with standard error σ² √(2/2); and one degree of freedom is enough."""
    u = 100.0 * np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])
    eps = np.array([0.3, 0.1, 0.3, 0.1])
    v = u + eps[:, None] * u / np.linalg.norm(u, axis=1, keepdims=True)
    s2, se, per = scatter_sigma2(np.stack([u, v]))
    assert s2 == pytest.approx(np.sum(eps ** 2) / 4, rel=1e-9) and se == pytest.approx(s2, rel=1e-9)
    np.testing.assert_allclose(per, eps ** 2 / 2 / (2 / 4), rtol=1e-9)
    one = scatter_sigma2(np.random.default_rng(1).normal(size=(5, 2, 2)))  # 4·2·2 − 5·3 = 1
    assert one[1] == pytest.approx(one[0] * np.sqrt(2.0), rel=1e-12)
    with pytest.raises(ValueError, match=r"^shapes: 2 shapes of 2 landmarks in 2-D leave no degrees of freedom once "
                                         r"their pose is fitted; sigma2 cannot be estimated from them$"):
        scatter_sigma2(np.random.default_rng(1).normal(size=(2, 2, 2)))
    with pytest.raises(ValueError, match="^shapes: every shape is the same, so the landmark scatter"):
        scatter_sigma2(np.stack([u, u, u]))
    with pytest.raises(ValueError, match="^shapes must contain at least 2 shape"):
        scatter_sigma2(u[None])


def test_predictive_sigma2_default_partners_keep_to_two_million_landmark_pairs():
    """Four far-spread rings of 520 landmarks (spacing 1) differing by radial moves: all partners would
    be 4 · 3 · 520² = 3.2 million landmark pairs, so the default takes the most partners that keep
    within 2²¹ pairs, one each (4 · 520² = 1.08 million). Each ordered pair (i, j) alone has the closed
    form q_ij = mean_a |δ_a|² / d, and the rule returns the mean of q over the pairs it used, / 2,
    times the pose correction: one of the 3⁴ one-partner choices, not the all-pairs mean."""
    k, d = 520, 2
    t = 2 * np.pi * np.arange(k) / k
    radial = np.c_[np.cos(t), np.sin(t)]
    alt = (-1.0) ** np.arange(k)  # radial moves with no net shift (K even) and no torque
    moves = [0.0 * alt, 0.05 + 0.02 * alt, -0.1 + 0.05 * alt, 0.15 - 0.01 * alt]
    x = np.stack([(k / (2 * np.pi) + m)[:, None] * radial for m in moves])
    q = np.array([[np.mean((a - b) ** 2) / d for b in moves] for a in moves])
    pose = k * d / (k * d - 3)
    one_each = {round(np.mean([q[i, j] for i, j in enumerate(js)]) / 2 * pose, 12)
                for js in np.ndindex(4, 4, 4, 4) if all(i != j for i, j in enumerate(js))}
    all_pairs = q[~np.eye(4, dtype=bool)].mean() / 2 * pose
    got = predictive_sigma2(x)
    assert min(abs(got - v) for v in one_each) <= 1e-7 * got
    assert abs(got - all_pairs) > 1e-3 * got

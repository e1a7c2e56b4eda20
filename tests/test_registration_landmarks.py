"""Known correspondences (``register(..., landmarks=...)``): the E-step and the objective with observed
labels against brute-force computations, a pose that only the landmarks decide, and the checks."""

import warnings

import numpy as np
import pytest
from scipy.special import logsumexp
from scipy.stats import multivariate_normal

import shapelib as sl
from shapelib.pointsets import registration
from shapelib.pointsets._coherent_em import (EMState, Kernel, _estep, _neg_loglik, label_array, objective,
                                             outlier_term, posteriors)


def _sets(n=7, m=9, d=2, seed=0):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(n, d)), rng.normal(size=(m, d))


def _brute_posteriors(theta, y, s2, c, lab):
    """P by its definition, column by column: the Gaussian terms over their sum plus the outlier term, or the
    indicator of the known source point."""
    n, m = len(theta), len(y)
    p = np.zeros((n, m))
    for j in range(m):
        if lab[j] >= 0:
            p[lab[j], j] = 1.0
            continue
        e = np.array([np.exp(-np.sum((y[j] - theta[i]) ** 2) / (2 * s2)) for i in range(n)])
        p[:, j] = e / (e.sum() + c)
    return p


@pytest.mark.parametrize("d", [2, 3])
def test_the_estep_with_known_points_equals_the_posteriors_with_indicator_columns(d):
    theta, y = _sets(d=d)
    s2, c = 0.4, 0.03
    lab = label_array(np.array([[2, 0], [5, 4], [0, 8]]), len(y))
    assert lab.tolist() == [2, -1, -1, -1, 5, -1, -1, -1, 0]
    p = _brute_posteriors(theta, y, s2, c, lab)
    p1, pt1, py, sse, lse = _estep(theta, y, s2, c, True, lab)
    np.testing.assert_allclose(p1, p.sum(axis=1), rtol=1e-12)
    np.testing.assert_allclose(pt1, p.sum(axis=0), rtol=1e-12)
    np.testing.assert_allclose(py, p @ y, rtol=1e-12, atol=1e-15)
    d2 = np.sum((y[None] - theta[:, None]) ** 2, axis=2)
    assert sse == pytest.approx(np.sum(p * d2), rel=1e-12)
    # the log-normalisers: log(Σ_i e_ij + c) for an unknown point, −|y_j − θ_i|²/2σ² for a known one
    free = lab < 0
    expect = np.sum(np.log(np.exp(-d2[:, free] / (2 * s2)).sum(axis=0) + c))
    expect -= sum(d2[lab[j], j] / (2 * s2) for j in np.flatnonzero(~free))
    assert lse == pytest.approx(expect, rel=1e-12)
    # posteriors() gives the same matrix; the known columns are indicators and every other column as before
    volume = 3.0
    w = 0.2
    c_w = outlier_term(len(theta), d, s2, w, volume)
    np.testing.assert_allclose(posteriors(theta, y, s2, w, volume, lab), _brute_posteriors(theta, y, s2, c_w, lab),
                               rtol=1e-12)
    np.testing.assert_array_equal(posteriors(theta, y, s2, w, volume, lab)[:, free],
                                  posteriors(theta, y, s2, w, volume)[:, free])


def test_the_objective_with_known_points_is_the_complete_data_negative_log_likelihood():
    """F: −Σ_j log[(1 − w)/n Σ_i N(y_j; θ_i) + w/V] over the unknown points, −log[(1 − w)/n N(y_j; θ_{l_j})]
    over the known ones (scipy's normal densities), plus the deformation prior."""
    u, y = _sets(n=6, m=8)
    rng = np.random.default_rng(1)
    g = np.exp(-np.sum((u[:, None] - u[None]) ** 2, axis=2) / 4)
    st = EMState(u=u, kernel=Kernel.of(g), coef=0.1 * rng.normal(size=u.shape), s2=0.3, w=0.15)
    volume, lam = 5.0, 1.5
    pairs = np.array([[1, 2], [4, 7]])
    lab = label_array(pairs, len(y))
    theta = st.theta
    n = len(u)
    expect = 0.0
    for j in range(len(y)):
        logs = np.array([multivariate_normal(theta[i], 0.3 * np.eye(2)).logpdf(y[j]) for i in range(n)])
        if lab[j] >= 0:
            expect -= np.log(0.85 / n) + logs[lab[j]]
        else:
            expect -= logsumexp(np.append(np.log(0.85 / n) + logs, np.log(0.15 / volume)))
    expect += 0.5 * lam * np.sum(st.coef * (g @ st.coef))
    assert objective(st, y, lam=lam, volume=volume, labels=lab) == pytest.approx(expect, rel=1e-10)
    # no labels: the usual F, different from the labelled one
    plain = _neg_loglik(theta, y, 0.3, np.log(0.85 / n), np.log(0.15 / volume), label_array(None, len(y)))
    assert plain + 0.5 * lam * np.sum(st.coef * (g @ st.coef)) == pytest.approx(
        objective(st, y, lam=lam, volume=volume), rel=1e-12)
    assert abs(plain - (expect - 0.5 * lam * np.sum(st.coef * (g @ st.coef)))) > 1e-3


def _ellipse_case():
    """A bent ellipse (symmetric under a half turn before the bend is small) turned by 2 rad, its points
    shuffled: target point j is source point perm[j]."""
    t = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    x = np.column_stack([np.cos(t), 0.5 * np.sin(t)])
    bent = x + np.column_stack([0.1 * x[:, 1] ** 2, 0.05 * np.sin(3 * t)])
    c, s = np.cos(2.0), np.sin(2.0)
    truth = bent @ np.array([[c, -s], [s, c]]).T
    perm = np.random.default_rng(0).permutation(60)
    return x, truth[perm], truth, perm


def test_two_landmarks_decide_the_pose_of_a_near_symmetric_shape_and_are_kept():
    x, y, truth, perm = _ellipse_case()
    where = np.argsort(perm)  # where[i]: the target index of source point i
    lm = np.array([[0, where[0]], [15, where[15]]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # reliable: no warning
        res = sl.register(x, y, landmarks=lm)
    assert res.reliable
    assert np.abs(res.points - truth).max() < 1e-3
    np.testing.assert_array_equal(res.correspondence, where)
    np.testing.assert_array_equal(res.target_correspondence, perm)
    assert np.all(res.probabilities[lm[:, 0], lm[:, 1]] == 1.0)
    # the order of the rows does not matter
    again = sl.register(x, y, landmarks=lm[::-1])
    np.testing.assert_allclose(again.points, res.points, rtol=0, atol=1e-12)
    # the landmarks that a half turn would swap decide the other pose: the source turned first
    flipped = sl.register(-x, y, landmarks=lm)
    assert flipped.reliable and np.abs(flipped.points - truth).max() < 1e-3


def test_without_landmarks_the_same_shape_is_flagged_as_ambiguous():
    """The case of the test above is ambiguous without the landmarks: the result says so."""
    x, y, _, _ = _ellipse_case()
    with pytest.warns(sl.RegistrationWarning, match="another pose"):
        res = sl.register(x, y)
    assert not res.reliable


def test_landmarks_reach_the_subsets_of_a_large_registration(monkeypatch):
    """Sets over MAX_POINTS: the landmarks join the farthest-point subsets and keep their correspondence."""
    monkeypatch.setattr(registration, "MAX_POINTS", 40)
    x, y, truth, perm = _ellipse_case()
    where = np.argsort(perm)
    lm = np.array([[0, where[0]], [15, where[15]], [33, where[33]]])
    res = sl.register(x, y, landmarks=lm)
    assert 37 <= min(res.diagnostics["subsets"]) and max(res.diagnostics["subsets"]) <= 40  # 37 spread + 3 at most
    np.testing.assert_array_equal(res.correspondence[lm[:, 0]], lm[:, 1])
    np.testing.assert_array_equal(res.target_correspondence[lm[:, 1]], lm[:, 0])
    # the right pose (the half turn would leave a mean error near 1); the warp of 40-point subsets is coarse
    assert np.mean(np.linalg.norm(res.points - truth, axis=1)) < 0.1
    with pytest.raises(ValueError, match="at most 20 known correspondences"):
        sl.register(x, y, landmarks=np.column_stack([np.arange(21), where[:21]]))


@pytest.mark.parametrize("landmarks, match", [
    (np.array([0, 1]), r"shape \(k, 2\)"),
    (np.array([[0.5, 1]]), "integers"),
    (np.array([[60, 1]]), "source point 60, outside 0..59"),
    (np.array([[0, -1]]), "target point -1"),
    (np.array([[0, 1], [0, 2]]), "source point 0 is named in more than one row"),
    (np.array([[0, 1], [2, 1]]), "target point 1 is named in more than one row"),
])
def test_bad_landmarks_are_refused_naming_the_row_or_point(landmarks, match):
    x, y, _, _ = _ellipse_case()
    with pytest.raises(ValueError, match=match):
        sl.register(x, y, landmarks=landmarks)


def test_landmarks_belong_to_the_nonrigid_registration():
    x, y, _, _ = _ellipse_case()
    with pytest.raises(ValueError, match="transform='nonrigid'"):
        sl.register(x, y, transform="similarity", landmarks=[[0, 1]])
    # no landmarks (None or none at all) is the plain registration
    a = sl.register(x, y, landmarks=np.zeros((0, 2), dtype=int), warn=False)
    b = sl.register(x, y, warn=False)
    np.testing.assert_array_equal(a.points, b.points)

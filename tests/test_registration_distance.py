"""The registration distance against its definition computed independently: each directed misfit is
the σ² that :func:`shapelib.register` (non-rigid, ``w = 0``) leaves when it registers the raw sets,
divided by the target's mean squared radius, times ``exp(κ E / m)`` for the fit's deformation energy
``E`` (checked in tests/test_registration_checks.py); the options, the
defaults, the combinations and the refusals of bad input. Small sets (12 points): each registration takes a few hundredths of a second."""

import numpy as np
import pytest

import shapelib as sl
from shapelib.pointsets.registration_distance import (ENERGY_WEIGHT, REGISTRATION_COMBINE, registration_distance,
                                                      registration_misfits, registration_misfits_many)

T = np.linspace(0, 2 * np.pi, 12, endpoint=False)
# no symmetry, so that each registration has one best pose (as in tests/test_pairwise_registration.py)
STAR = np.c_[np.cos(T), np.sin(T)] * (1 + 0.3 * np.cos(2 * T) + 0.15 * np.sin(5 * T + 0.4))[:, None]
TRIFOIL = np.c_[np.cos(T), np.sin(T)] * (1 + 0.25 * np.cos(3 * T) + 0.1 * np.cos(T + 1))[:, None]
# the documented defaults of registration_distance / registration_misfits(_many)
DEFAULTS = {"reflection": True, "lam": 2.0, "sigma2_metric": 1.0, "max_iter": 150, "tol": 1e-5}
pytestmark = pytest.mark.filterwarnings("ignore::shapelib.RegistrationWarning")


def _msr(y):
    """The mean squared radius of ``y`` about its centroid."""
    y = np.asarray(y, float)
    return float(np.mean(np.sum((y - y.mean(axis=0)) ** 2, axis=1)))


def _reference(u, v, energy_weight=ENERGY_WEIGHT, **opts):
    """``(m_uv, m_vu, converged, n_iter)`` from two calls of :func:`shapelib.register` on the raw sets (the
    registration is a similarity plus a warp, so σ² in the target's own units over its mean squared radius
    does not depend on where the sets are or how large, nor does the energy in nats), with no prior on the
    pose's rotation."""
    kw = {**DEFAULTS, **opts}
    a = sl.register(u, v, transform="nonrigid", w=0.0, pose_prior=0.0, **kw)
    b = sl.register(v, u, transform="nonrigid", w=0.0, pose_prior=0.0, **kw)
    return (a.sigma2 / _msr(v) * np.exp(energy_weight * a.deformation_energy / len(v)),
            b.sigma2 / _msr(u) * np.exp(energy_weight * b.deformation_energy / len(u)),
            a.converged and b.converged, a.n_iter + b.n_iter)


U = 3.0 * STAR + np.array([1.0, -2.0])   # moved and scaled: the misfit must not see it
V = 0.5 * TRIFOIL[:10] - 4.0             # another size of set


def _check(got, ref):
    assert got[0] == pytest.approx(ref[0], rel=1e-8) and got[1] == pytest.approx(ref[1], rel=1e-8)
    assert got[2:] == ref[2:]
    assert type(got[2]) is bool and type(got[3]) is int


def test_misfits_with_the_defaults_are_sigma2_over_the_targets_mean_squared_radius():
    ref = _reference(U, V)
    assert ref[0] != pytest.approx(ref[1], rel=1e-3)   # the two directions differ: their order is tested
    _check(registration_misfits(U, V), ref)
    _check(registration_misfits_many([(U, V)])[0], ref)
    d = registration_distance(U, V)
    assert d == pytest.approx(0.5 * (ref[0] + ref[1]), rel=1e-8)
    assert registration_distance(U, V, combine="mean") == d
    assert registration_distance(U, V, combine="max") == pytest.approx(max(ref[:2]), rel=1e-8)
    assert REGISTRATION_COMBINE == ("mean", "max")


def test_the_energy_weight_prices_the_deformation():
    """κ = 0 leaves σ² alone; the default κ multiplies it by exp(κ E / m) with the fit's energy E > 0 (the
    star and the trefoil differ by more than a similarity); a negative κ is refused."""
    plain = _reference(U, V, energy_weight=0.0)
    _check(registration_misfits(U, V, energy_weight=0.0), plain)
    a = sl.register(U, V, transform="nonrigid", w=0.0, pose_prior=0.0, **DEFAULTS)
    assert plain[0] == pytest.approx(a.sigma2 / _msr(V), rel=1e-8) and a.deformation_energy > 0
    priced = registration_misfits(U, V)
    assert priced[0] / plain[0] == pytest.approx(np.exp(ENERGY_WEIGHT * a.deformation_energy / len(V)), rel=1e-8)
    assert priced[0] > plain[0] and priced[1] > plain[1]
    assert registration_distance(U, V, energy_weight=1.0) == pytest.approx(
        0.5 * sum(_reference(U, V, energy_weight=1.0)[:2]), rel=1e-8)
    with pytest.raises(ValueError, match="^energy_weight must be"):
        registration_distance(U, V, energy_weight=-1.0)


def test_a_large_target_shares_the_energy_among_its_subsets_points(monkeypatch):
    """Over ``MAX_POINTS`` points register fits farthest-point subsets of ``MAX_POINTS``: the energy is that
    fit's, and the misfit divides it by the subset's size, not the whole target's."""
    from shapelib.pointsets import _batch, registration

    monkeypatch.setattr(registration, "MAX_POINTS", 8)
    monkeypatch.setattr(_batch, "MAX_POINTS", 8)
    a = sl.register(U, V, transform="nonrigid", w=0.0, pose_prior=0.0, **DEFAULTS)
    assert len(V) > 8 and a.deformation_energy > 0
    got = registration_misfits(U, V)
    assert got[0] == pytest.approx(a.sigma2 / _msr(V) * np.exp(ENERGY_WEIGHT * a.deformation_energy / 8), rel=1e-8)


def test_the_distance_puts_no_price_on_the_turn():
    """A three-lobed outline (three near-equal poses) and a noisy copy turned by 2 rad: register's default price
    on the turn picks another of the poses than the fit of least objective, and the misfit is the latter's."""
    t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    lobes = np.c_[np.cos(t), np.sin(t)] * (1 + 0.3 * np.cos(3 * t))[:, None]
    c, s = np.cos(2.0), np.sin(2.0)
    turned = lobes @ np.array([[c, -s], [s, c]]).T + 0.02 * np.random.default_rng(1).normal(size=lobes.shape)
    free = _reference(lobes, turned)
    priced = sl.register(lobes, turned, transform="nonrigid", w=0.0, **DEFAULTS).sigma2 / _msr(turned)
    assert priced != pytest.approx(_reference(lobes, turned, energy_weight=0.0)[0], rel=1e-2)
    _check(registration_misfits(lobes, turned), free)
    _check(registration_misfits_many([(lobes, turned)])[0], free)


def test_every_option_reaches_the_registration():
    # each option away from its default changes the misfits (checked here), and the misfits follow register's
    for opts in ({"reflection": False}, {"lam": 3.0}, {"sigma2_metric": 2.0}, {"tol": 1e-2}, {"max_iter": 5}):
        ref = _reference(U, V, **opts)
        assert ref[:2] != pytest.approx(_reference(U, V)[:2], rel=1e-6), opts
        _check(registration_misfits(U, V, **opts), ref)
        _check(registration_misfits_many([(U, V)], **opts)[0], ref)
        assert registration_distance(U, V, **opts) == pytest.approx(0.5 * (ref[0] + ref[1]), rel=1e-8), opts
    ref = _reference(U, V, max_iter=5)
    assert not ref[2] and registration_misfits(U, V, max_iter=5)[2] is False   # an EM stopped at max_iter


def test_converged_only_when_both_directions_converged():
    # at 19 iterations the registration of U onto V has converged and that of V onto U not yet
    one = sl.register(U, V, transform="nonrigid", w=0.0, **{**DEFAULTS, "max_iter": 19})
    other = sl.register(V, U, transform="nonrigid", w=0.0, **{**DEFAULTS, "max_iter": 19})
    assert one.converged and not other.converged
    for u, v in ((U, V), (V, U)):
        got = registration_misfits(u, v, max_iter=19)
        _check(got, _reference(u, v, max_iter=19))
        assert got[2] is False


def test_the_backend_reaches_register_many():
    for f in (registration_distance, registration_misfits):
        with pytest.raises(ValueError, match="^backend must be one of"):
            f(U, V, backend="cuda")
    with pytest.raises(ValueError, match="^backend must be one of"):
        registration_misfits_many([(U, V)], backend="cuda")


def test_single_precision_input_is_read_as_its_float64_values():
    u32, v32 = U.astype(np.float32), V.astype(np.float32)
    got = registration_misfits(u32, v32)
    ref = registration_misfits(u32.astype(np.float64), v32.astype(np.float64))
    assert got[0] == pytest.approx(ref[0], rel=1e-12) and got[1] == pytest.approx(ref[1], rel=1e-12)


def test_many_pairs_equal_the_pairs_one_by_one_in_order():
    pairs = [(U, V), (V, STAR), (TRIFOIL, U)]
    many = registration_misfits_many(pairs, max_iter=40)
    assert len(many) == 3
    for got, (u, v) in zip(many, pairs):
        _check(got, _reference(u, v, max_iter=40))
    assert registration_misfits_many([]) == []
    timings = {}
    registration_misfits_many(pairs[:1], max_iter=40, timings=timings, batch_size=1)
    assert set(timings) >= {"prep", "search", "assembly", "device"} and timings["search"] > 0


def test_zero_for_a_similar_copy_whatever_its_size():
    c, s = np.cos(1.0), np.sin(1.0)
    copy = 1e-3 * STAR[::-1] @ np.array([[c, -s], [s, c]]) + 5.0
    assert registration_distance(STAR, copy) < 1e-3 < registration_distance(STAR, TRIFOIL)
    assert registration_distance(1e3 * STAR, TRIFOIL) == pytest.approx(registration_distance(STAR, TRIFOIL), rel=1e-6)


@pytest.mark.parametrize("call, match", [
    (lambda: registration_distance(STAR, TRIFOIL, combine="min"), r"^combine must be one of \('mean', 'max'\)"),
    (lambda: registration_misfits(STAR[:, 0], TRIFOIL), r"^u must be a finite \(n, d\) point set"),
    (lambda: registration_misfits(STAR, np.where(T[:, None] > 1, np.nan, TRIFOIL)), r"^v must be a finite"),
    (lambda: registration_misfits(np.ones((5, 2)), TRIFOIL), r"^u: all points coincide"),
    (lambda: registration_misfits(STAR, np.zeros((5, 2))), r"^v: all points coincide"),
    (lambda: registration_misfits_many([(STAR, TRIFOIL), (STAR, np.zeros((5, 2)))]), r"^pairs\[1\] v: all points"),
    (lambda: registration_misfits_many([(STAR, TRIFOIL), (np.full((5, 2), np.inf), STAR)]),
     r"^pairs\[1\] u must be a finite"),
    (lambda: registration_misfits_many([(STAR, TRIFOIL, STAR)]), r"^pairs\[0\] must be a \(u, v\) pair"),
    (lambda: registration_misfits_many([(STAR, TRIFOIL), STAR]), r"^pairs\[1\] must be a \(u, v\) pair"),
    (lambda: registration_misfits_many([[STAR]]), r"^pairs\[0\] must be a \(u, v\) pair"),
])
def test_bad_input_names_the_parameter(call, match):
    with pytest.raises(ValueError, match=match):
        call()

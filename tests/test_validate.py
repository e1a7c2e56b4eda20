import numpy as np
import pytest

from shapelib._validate import as_shape, as_shape_pair, as_shapes, check_nonnegative_int, check_positive_int, check_sigma2


def test_as_shape_returns_float64_copy_of_valid_input():
    x = as_shape([[0, 1], [2, 3]])
    assert x.dtype == np.float64 and x.shape == (2, 2)


@pytest.mark.parametrize(
    "bad, match",
    [
        (np.zeros(4), r"2-D array.*\(4,\)"),
        (np.zeros((2, 2, 2)), r"2-D array.*\(2, 2, 2\)"),
        (np.zeros((0, 2)), r"at least 1 landmark"),
        (np.array([[0.0, np.nan]]), r"non-finite.*landmark 0, coordinate 1"),
        (np.array([[np.inf, 0.0], [0, 0]]), r"non-finite"),
        ([["a", "b"]], r"numeric"),
    ],
)
def test_as_shape_rejects_bad_input(bad, match):
    with pytest.raises(ValueError, match=match):
        as_shape(bad, name="u")


def test_pair_must_have_same_landmark_count():
    with pytest.raises(ValueError, match=r"same number of landmarks.*\(3, 2\).*\(4, 2\)"):
        as_shape_pair(np.zeros((3, 2)), np.zeros((4, 2)))


def test_as_shapes_checks_each_member():
    with pytest.raises(ValueError, match=r"shapes\[1\].*non-finite"):
        as_shapes(np.stack([np.zeros((3, 2)), np.full((3, 2), np.nan)]))
    with pytest.raises(ValueError, match=r"same \(K, d\)"):
        as_shapes([np.zeros((3, 2)), np.zeros((4, 2))])
    with pytest.raises(ValueError, match=r"\(N, K, d\)"):
        as_shapes(np.zeros((3, 2)))


@pytest.mark.parametrize("bad", [0, -1.0, np.nan, np.inf, "0.5", None, [0.5], True])
def test_sigma2_must_be_positive_finite_number(bad):
    with pytest.raises(ValueError, match="sigma2"):
        check_sigma2(bad)


def test_sigma2_accepts_numpy_scalars():
    assert check_sigma2(np.float32(0.5)) == pytest.approx(0.5)
    assert check_sigma2(2) == 2.0


@pytest.mark.parametrize("bad", [0, -3, 2.5, np.nan, np.inf, "99", None, True, False, [3]])
def test_positive_int_rejects_everything_but_integers_from_one(bad):
    with pytest.raises(ValueError, match=r"permutations must be a positive integer; got"):
        check_positive_int(bad, name="permutations")


def test_positive_int_accepts_integral_numbers_and_returns_int():
    for ok in (1, 999, np.int64(7), 5.0, np.float32(3.0)):
        out = check_positive_int(ok, name="n")
        assert type(out) is int and out == ok


def test_nonnegative_int_allows_zero_only_in_addition():
    assert check_nonnegative_int(0, name="max_iter") == 0 and check_nonnegative_int(3.0, name="max_iter") == 3
    for bad in (-1, True, False, 0.5, None):
        with pytest.raises(ValueError, match=r"max_iter must be a non-negative integer; got"):
            check_nonnegative_int(bad, name="max_iter")

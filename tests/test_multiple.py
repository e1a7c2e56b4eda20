"""Holm's step-down adjustment (shapelib.statistics.multiple.holm_adjust) against values worked by
hand from its definition, as R's ``p.adjust(p, "holm")`` gives them."""

import numpy as np
import pytest

from shapelib.statistics.multiple import holm_adjust


def test_holm_of_four_p_values_worked_by_hand():
    """Sorted 0.005, 0.01, 0.03, 0.04 times 4, 3, 2, 1 = 0.02, 0.03, 0.06, 0.04; the running maximum
    makes the last 0.06; back in the input's order (R: p.adjust(c(0.01, 0.04, 0.03, 0.005), "holm"))."""
    np.testing.assert_allclose(holm_adjust([0.01, 0.04, 0.03, 0.005]), [0.03, 0.06, 0.06, 0.02], rtol=1e-14)


def test_holm_caps_at_one_keeps_ties_and_a_single_value():
    np.testing.assert_allclose(holm_adjust([0.3, 0.4, 0.2]), [0.6, 0.6, 0.6], rtol=1e-14)  # sorted 3·0.2, 2·0.3, 1·0.4 = 0.6, 0.6, 0.4: running max
    assert holm_adjust([0.6, 0.9]).tolist() == [1.0, 1.0]  # 1.2 and 0.9 → 1, 1
    assert holm_adjust([0.02, 0.02]).tolist() == [0.04, 0.04]
    assert holm_adjust([0.7]).tolist() == [0.7]
    assert holm_adjust(np.array([0, 1])).dtype == np.float64


def test_holm_refuses_what_is_not_a_list_of_probabilities():
    with pytest.raises(ValueError, match=r"^p_values must be one-dimensional; got shape \(2, 2\)$"):
        holm_adjust([[0.1, 0.2], [0.3, 0.4]])
    with pytest.raises(ValueError, match=r"^p_values must lie in \[0, 1\]; got \[0.1, 1.5\]$"):
        holm_adjust([0.1, 1.5])
    with pytest.raises(ValueError, match=r"^p_values must lie in \[0, 1\]; got \[-0.1\]$"):
        holm_adjust([-0.1])
    assert holm_adjust([0.0, 1.0]).tolist() == [0.0, 1.0]  # the ends are probabilities


def test_holm_reads_the_p_values_as_floats_whatever_their_type():
    """Exact fractions are adjusted as the floats they round to: sorted 0.05, 0.1, 0.2 times 3, 2, 1 in
    floating point, where 3 × 0.05 is 0.15000000000000002, not the exact 3/20's float 0.15."""
    from fractions import Fraction

    exact = [Fraction(1, 10), Fraction(1, 5), Fraction(1, 20)]
    assert holm_adjust(exact).tolist() == holm_adjust([0.1, 0.2, 0.05]).tolist() == [0.2, 0.2, 3 * 0.05]
    assert 3 * 0.05 != float(Fraction(3, 20))  # the two readings differ here

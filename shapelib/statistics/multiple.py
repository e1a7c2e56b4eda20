"""Multiple testing: Holm's step-down adjustment of a family of p-values."""

from __future__ import annotations

import numpy as np

__all__ = ["holm_adjust"]


def holm_adjust(p_values) -> np.ndarray:
    """Holm's (1979) step-down adjusted p-values, which control the family-wise error rate.

    With the ``m`` p-values sorted, ``p_(1) ≤ … ≤ p_(m)``, the adjusted value of the ``i``-th is

    ``p̃_(i) = min(1, max_{j ≤ i} (m − j + 1) p_(j))``,

    returned in the input's order: reject the hypotheses whose adjusted p is at most α.

    Parameters
    ----------
    p_values : array_like, shape (m,)
        Values in [0, 1], converted to float64 first: exact rationals or decimals give the adjustment
        of their nearest floats, computed in floating point.

    Returns
    -------
    ndarray, shape (m,)

    Examples
    --------
    >>> from shapelib.statistics.multiple import holm_adjust
    >>> holm_adjust([0.01, 0.04, 0.03]).round(3).tolist()
    [0.03, 0.06, 0.06]
    """
    p = np.asarray(p_values, dtype=np.float64)
    if p.ndim != 1:
        raise ValueError(f"p_values must be one-dimensional; got shape {p.shape}")
    if not np.all((p >= 0) & (p <= 1)):
        raise ValueError(f"p_values must lie in [0, 1]; got {p.tolist()}")
    m = len(p)
    order = np.argsort(p, kind="stable")
    stepped = np.maximum.accumulate((m - np.arange(m)) * p[order])
    out = np.empty(m)
    out[order] = np.minimum(stepped, 1.0)
    return out

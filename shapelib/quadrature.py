"""Integration rules for the Fisher–Rao quantities, which have no closed form.

Every Fisher–Rao integral here has a smooth integrand concentrated within a few σ of the
landmarks: ``∫ ṗ²/p = ∫ |∂_t(2√p)|²``, ``∫ (√p_u − √p_v)²``. We integrate them with the
trapezoid rule on a regular grid of step ``h = spacing · σ`` covering the landmarks plus a
margin of ``margin · σ``. The trapezoid rule converges exponentially in ``σ/h`` for such
integrands, but ``N_a/√p`` switches between neighbouring components over a width ~σ²/D for
landmarks a distance D apart, so the error is set by the step rather than by the margin.
Measured on random 20-landmark shapes (max relative error of the metric tensor against
``h = σ/8``, margin 10σ):

=============  ==========  ==========  ==========
 step h         σ² = 0.1    σ² = 0.5    σ² = 1.5
=============  ==========  ==========  ==========
 σ/4            3e-8        2e-9        1e-14
 0.35 σ         2e-6        7e-7        1e-10
 σ/2            8e-5        4e-5        1e-7
=============  ==========  ==========  ==========

A margin of 6σ is enough (5σ starts to show at 3e-6). The defaults are ``h = 0.35σ`` and a
6σ margin; ``tests/test_metrics.py`` checks them against a finer grid and against the exact
K = 1 case ``g = I/σ²``.

The grid is a tensor product, so each isotropic Gaussian factorises over its axes and the
integrands need ``Σ_i n_i K`` exponentials rather than ``M K`` (:func:`shapelib.metrics._psi_coef`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._validate import check_positive

__all__ = ["Grid", "make_grid", "DEFAULT_SPACING", "DEFAULT_MARGIN"]

DEFAULT_SPACING = 0.35
DEFAULT_MARGIN = 6.0


@dataclass(frozen=True)
class Grid:
    """A tensor-product trapezoid rule: ``∫ f ≈ weight · Σ f(nodes)``."""

    nodes: np.ndarray  # (M, d), the tensor product of ``axes`` in C order
    weight: float
    shape: tuple  # grid points per axis
    axes: tuple = ()  # the 1-D node coordinates per axis (empty: nodes are not a tensor grid)

    def integrate(self, values: np.ndarray, axis: int = 0) -> np.ndarray:
        return self.weight * np.sum(values, axis=axis)


def make_grid(points, sigma2: float, *, spacing: float = DEFAULT_SPACING, margin: float = DEFAULT_MARGIN) -> Grid:
    """Regular grid covering ``points`` (any array with last axis d) plus ``margin·σ``, step ``spacing·σ``.

    Parameters
    ----------
    points : array_like, shape (..., d)
        Every landmark position the integrands will see (e.g. all shapes along a path).
    sigma2 : float
        σ² of eq. (5).
    spacing, margin : float
        Grid step and margin in units of σ.
    """
    spacing = check_positive(spacing, name="spacing")
    margin = check_positive(margin, name="margin")
    sigma = np.sqrt(check_positive(sigma2, name="sigma2"))
    pts = np.asarray(points, dtype=np.float64)
    pts = pts.reshape(-1, pts.shape[-1])
    h = spacing * sigma
    # The lattice is anchored at the origin (nodes are integer multiples of h), so grids made
    # for slightly different point sets share their nodes and differ only far out in the
    # margin, where the integrands vanish: quadrature does not add noise to an optimisation.
    lo = np.floor((pts.min(axis=0) - margin * sigma) / h)
    hi = np.ceil((pts.max(axis=0) + margin * sigma) / h)
    axes = [h * np.arange(lo[i], hi[i] + 1) for i in range(pts.shape[1])]
    n = [len(a) for a in axes]
    mesh = np.meshgrid(*axes, indexing="ij")
    nodes = np.stack([m.ravel() for m in mesh], axis=1)
    return Grid(nodes=nodes, weight=float(h ** pts.shape[1]), shape=tuple(int(k) for k in n), axes=tuple(axes))

"""shapelib: information geometry for landmark shape analysis (Peter & Rangarajan).

Shapes are ``(K, d)`` float arrays of landmarks in correspondence; collections are ``(N, K, d)``.
"""

from .procrustes import (
    centroid_size,
    generalized_procrustes,
    preshape,
    procrustes_align,
    procrustes_distance,
)

__version__ = "0.1.0"

__all__ = [
    "centroid_size",
    "generalized_procrustes",
    "preshape",
    "procrustes_align",
    "procrustes_distance",
]

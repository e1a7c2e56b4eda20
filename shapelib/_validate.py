"""Input validation shared by every public function: one place for input errors.

Every helper raises :class:`ValueError` with a message that names the argument and
the offending shape or value, so that a researcher sees what is wrong with their data.
"""

from __future__ import annotations

import numbers

import numpy as np

__all__ = ["as_shape", "as_shapes", "as_shape_pair", "check_sigma2", "check_positive"]


def as_shape(x, *, name: str = "shape", min_landmarks: int = 1) -> np.ndarray:
    """Return ``x`` as a float64 ``(K, d)`` landmark array, or raise ``ValueError``.

    Parameters
    ----------
    x : array_like
        Landmarks, one row per landmark.
    name : str
        Argument name used in error messages.
    min_landmarks : int
        Smallest admissible K.
    """
    try:
        arr = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a numeric (K, 2) array of landmarks: {exc}") from None
    if arr.ndim != 2:
        raise ValueError(
            f"{name} must be a 2-D array of landmarks with shape (K, d); got shape {arr.shape}"
        )
    if arr.shape[1] < 1:
        raise ValueError(f"{name} must have at least one coordinate per landmark; got shape {arr.shape}")
    if arr.shape[0] < min_landmarks:
        raise ValueError(
            f"{name} must have at least {min_landmarks} landmark(s); got shape {arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise ValueError(
            f"{name} contains non-finite values (first at landmark {bad[0]}, coordinate {bad[1]})"
        )
    return arr


def as_shape_pair(u, v, *, names=("u", "v"), min_landmarks: int = 1):
    """Validate two shapes that must be in landmark correspondence (same ``(K, d)``)."""
    a = as_shape(u, name=names[0], min_landmarks=min_landmarks)
    b = as_shape(v, name=names[1], min_landmarks=min_landmarks)
    if a.shape != b.shape:
        raise ValueError(
            f"{names[0]} and {names[1]} must have the same number of landmarks and dimension; "
            f"got {names[0]}.shape={a.shape} and {names[1]}.shape={b.shape}"
        )
    return a, b


def as_shapes(x, *, name: str = "shapes", min_shapes: int = 1, min_landmarks: int = 1) -> np.ndarray:
    """Return ``x`` as a float64 ``(N, K, d)`` collection of shapes, or raise ``ValueError``."""
    if isinstance(x, (list, tuple)) and len(x) and not np.isscalar(x[0]):
        shapes = [np.asarray(s, dtype=np.float64) for s in x]
        if len({s.shape for s in shapes}) > 1:
            raise ValueError(
                f"{name}: all shapes must have the same (K, d); got {[s.shape for s in shapes]}"
            )
    try:
        arr = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a numeric (N, K, d) array: {exc}") from None
    if arr.ndim != 3:
        raise ValueError(f"{name} must have shape (N, K, d); got shape {arr.shape}")
    if arr.shape[0] < min_shapes:
        raise ValueError(f"{name} must contain at least {min_shapes} shape(s); got shape {arr.shape}")
    for i in range(arr.shape[0]):
        as_shape(arr[i], name=f"{name}[{i}]", min_landmarks=min_landmarks)
    return arr


def check_positive(value, *, name: str) -> float:
    """Return ``value`` as a float if it is a finite number > 0, else raise ``ValueError``."""
    if isinstance(value, bool) or not isinstance(value, (numbers.Real, np.floating, np.integer)):
        arr = np.asarray(value)
        if arr.ndim != 0 or not np.issubdtype(arr.dtype, np.number):
            raise ValueError(f"{name} must be a positive finite number; got {value!r}")
        value = arr.item()
    value = float(value)
    if not np.isfinite(value) or value <= 0:
        raise ValueError(f"{name} must be a positive finite number; got {value!r}")
    return value


def check_sigma2(sigma2) -> float:
    """Validate the isotropic GMM variance σ² of eq. (5): a finite number > 0."""
    return check_positive(sigma2, name="sigma2")

"""Input validation shared by every public function: one place for input errors.

Every helper raises :class:`ValueError` with a message that names the argument and
the offending shape or value, so that a researcher sees what is wrong with their data.
"""

from __future__ import annotations

import contextlib
import contextvars
import numbers

import numpy as np

__all__ = ["InputError", "literal", "as_shape", "as_shapes", "as_shape_pair", "as_pair_batch", "check_sigma2", "check_positive", "check_nonnegative", "check_positive_int",
           "check_nonnegative_int", "check_dimension", "LANDMARK_DIMS", "set_checked", "set_was_checked",
           "parse_assignment"]

#: landmark dimensions every shape-taking entry point accepts (``dims=`` of :func:`as_shape`)
LANDMARK_DIMS = (2, 3)

#: how the Python library words each remedy an :class:`InputError` can name (the command line has its own)
LIBRARY_WORDS = {
    "keep_missing": "pass missing='nan' to keep them as NaN (shapelib's distances do not accept NaN: "
                    "estimate or drop them first)",
    "scale": "scale=True",
    "pkn": "convert it with shapelib.io.from_pkn",
    "sigma2": "sigma2=...",
}


def literal(value) -> str:
    """``str(value)`` with braces doubled, for the text of an :class:`InputError` template."""
    return str(value).replace("{", "{{").replace("}", "}}")


class InputError(ValueError):
    """Bad input, with the fix named in the words of whoever called: the library or the command line.

    A :class:`ValueError` (catch it as one). The message is a template whose ``{fields}`` name a
    remedy (``{keep_missing}``, ``{scale}``, ``{pkn}``, ``{sigma2}``); ``str(exc)`` fills them with
    the library's keywords (:data:`LIBRARY_WORDS`), :meth:`phrase` with another vocabulary (the
    command line passes its options), so no caller rewrites another's message.

    Parameters
    ----------
    template : str
        The message; literal text interpolated into it goes through :func:`literal`.
    facts : dict, optional
        What a caller may act on: ``landmarks`` (indices named in the message, counted from 0),
        ``negative_as_missing`` (a tps reader read negative coordinates as missing), ``metric``
        and ``parameters`` (a metric's missing required options).

    Attributes
    ----------
    template : str
        The message with its remedy fields.
    facts : dict
        As given (empty if none).

    See Also
    --------
    shapelib.io.read_landmarks : Raises it for a missing landmark.

    Examples
    --------
    The same error in the library's words and in the command line's:

    >>> from shapelib import InputError
    >>> exc = InputError("fish.tps: specimen 'b': landmark 3 is missing; {keep_missing}", {"landmarks": (2,)})
    >>> isinstance(exc, ValueError), exc.facts["landmarks"]
    (True, (2,))
    >>> print(exc)
    fish.tps: specimen 'b': landmark 3 is missing; pass missing='nan' to keep them as NaN (shapelib's distances do not accept NaN: estimate or drop them first)
    >>> print(exc.phrase({"keep_missing": "pass --keep-missing"}))
    fish.tps: specimen 'b': landmark 3 is missing; pass --keep-missing
    """

    def __init__(self, template: str, facts: dict | None = None):
        super().__init__(template, dict(facts or {}))  # args: what pickling (Dask) rebuilds it from
        self.template, self.facts = template, dict(facts or {})

    def phrase(self, words: dict | None = None) -> str:
        """The message with ``words`` (field -> text) in place of the library's."""
        return self.template.format_map({**LIBRARY_WORDS, **(words or {})})

    def __str__(self) -> str:
        return self.phrase()


def as_shape(x, *, name: str = "shape", min_landmarks: int = 1, dims=LANDMARK_DIMS) -> np.ndarray:
    """Return ``x`` as a float64 ``(K, d)`` landmark array, or raise ``ValueError``.

    Parameters
    ----------
    x : array_like
        Landmarks, one row per landmark.
    name : str
        Argument name used in error messages.
    min_landmarks : int
        Smallest admissible K.
    dims : tuple of int or None
        Admissible d (:func:`check_dimension`: a transposed shape or a geomorph ``p × k × n``
        array is named as such); ``None`` for point sets of any dimension (e.g. a spline with an
        explicit kernel).
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
        raise InputError(
            f"{literal(name)} contains non-finite values (first at landmark {bad[0]}, coordinate {bad[1]})",
            {"landmarks": (int(bad[0]),)},
        )
    if dims is not None:
        check_dimension(arr, name=name, allowed=dims)
    return arr


def as_shape_pair(u, v, *, names=("u", "v"), min_landmarks: int = 1, dims=LANDMARK_DIMS):
    """Validate two shapes that must be in landmark correspondence (same ``(K, d)``)."""
    a = as_shape(u, name=names[0], min_landmarks=min_landmarks, dims=dims)
    b = as_shape(v, name=names[1], min_landmarks=min_landmarks, dims=dims)
    if a.shape != b.shape:
        raise ValueError(
            f"{names[0]} and {names[1]} must have the same number of landmarks and dimension; "
            f"got {names[0]}.shape={a.shape} and {names[1]}.shape={b.shape}"
        )
    return a, b


def as_pair_batch(us, vs):
    """``us`` and ``vs`` as float64 ``(B, K, d)`` arrays of one shape (pairs of shapes, one pair per
    row), or ``ValueError``; each pair is checked by :func:`as_shape_pair` where it is used."""
    us = np.asarray(us, dtype=np.float64)
    vs = np.asarray(vs, dtype=np.float64)
    if us.ndim != 3 or us.shape != vs.shape:
        raise ValueError(f"us and vs must be (B, K, d) arrays of one shape; got {us.shape} and {vs.shape}")
    return us, vs


def as_shapes(x, *, name: str = "shapes", min_shapes: int = 1, min_landmarks: int = 1,
              dims=LANDMARK_DIMS) -> np.ndarray:
    """Return ``x`` as a float64 ``(N, K, d)`` collection of shapes, or raise ``ValueError``
    (``dims`` as in :func:`as_shape`: the layout is checked on the whole array first, so a
    geomorph ``p × k × n`` array is named as one)."""
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
    if dims is not None:
        check_dimension(arr, name=name, allowed=dims)
    for i in range(arr.shape[0]):
        as_shape(arr[i], name=f"{name}[{i}]", min_landmarks=min_landmarks, dims=None)
    return arr


def check_positive(value, *, name: str) -> float:
    """Return ``value`` as a float if it is a finite number > 0, else raise ``ValueError``."""
    return _check_real(value, name=name, strict=True)


def check_nonnegative(value, *, name: str) -> float:
    """Return ``value`` as a float if it is a finite number >= 0, else raise ``ValueError``."""
    return _check_real(value, name=name, strict=False)


def _check_real(value, *, name, strict):
    kind = "a positive finite number" if strict else "a non-negative finite number"
    if isinstance(value, bool) or not isinstance(value, (numbers.Real, np.floating, np.integer)):
        arr = np.asarray(value)
        if arr.ndim != 0 or not np.issubdtype(arr.dtype, np.number):
            raise ValueError(f"{name} must be {kind}; got {value!r}")
        value = arr.item()
    value = float(value)
    if not np.isfinite(value) or value < 0 or (strict and value == 0):
        raise ValueError(f"{name} must be {kind}; got {value!r}")
    return value


def check_positive_int(value, *, name: str) -> int:
    """Return ``value`` as an int if it is an integer ``>= 1`` (an integral float such as ``5.0``
    passes; ``True``, ``None``, ``"99"`` and ``2.5`` do not), else raise ``ValueError``."""
    return _check_int(value, name=name, minimum=1, kind="a positive integer")


def check_nonnegative_int(value, *, name: str) -> int:
    """As :func:`check_positive_int`, with 0 allowed."""
    return _check_int(value, name=name, minimum=0, kind="a non-negative integer")


def _check_int(value, *, name, minimum, kind):
    ok = (not isinstance(value, bool) and isinstance(value, (numbers.Real, np.integer, np.floating))
          and np.isfinite(value) and float(value).is_integer() and value >= minimum)
    if not ok:
        raise ValueError(f"{name} must be {kind}; got {value!r}")
    return int(value)


def check_sigma2(sigma2) -> float:
    """Validate the isotropic GMM variance σ² of eq. (5): a finite number > 0."""
    return check_positive(sigma2, name="sigma2")


def check_dimension(x: np.ndarray, *, name: str = "u", allowed=(2, 3)) -> np.ndarray:
    """Raise ``ValueError`` unless the landmarks of ``x`` (``(K, d)`` or ``(N, K, d)``) have d in ``allowed``.

    A shape passed transposed (``(d, K)``), or a geomorph-style ``p × k × n`` array read as
    ``(N, K, d)``, shows up as a landmark dimension other than 2 or 3; the message says which
    layout shapelib expects and how to convert. ``name``: the argument or file named in it.
    """
    d = x.shape[-1]
    if d not in allowed:
        dims = " or ".join(map(str, allowed))
        if x.ndim == 3 and x.shape[1] in allowed:
            hint = (f"; the array looks like geomorph's p x k x n layout {x.shape}: {{pkn}} "
                    "(or, if it is (N, d, K), with numpy.swapaxes(array, 1, 2))")
        else:
            hint = "; a geomorph-style p x k x n array: {pkn}"
        raise InputError(
            f"{literal(name)}: landmarks must have d = {dims} coordinates; got {d} dimensions (shape {x.shape}). shapelib "
            f"expects one shape as a (K, d) array (one row per landmark) and a collection as (N, K, d) "
            f"(specimens, landmarks, coordinates); a shape stored as (d, K) must be transposed{hint}"
        )
    return x


_SET_CHECKED = contextvars.ContextVar("shapelib_set_checked", default=False)


@contextlib.contextmanager
def set_checked():
    """Within this context the per-pair pose and scale warnings are skipped: the caller (the
    pairwise engine) has checked the whole set of shapes once, and warned once."""
    token = _SET_CHECKED.set(True)
    try:
        yield
    finally:
        _SET_CHECKED.reset(token)


def set_was_checked() -> bool:
    """True inside :func:`set_checked`."""
    return _SET_CHECKED.get()


def parse_assignment(text: str, *, flag: str = "--param", example: str = "n_steps=16") -> tuple[str, object]:
    """``"sigma2=0.5"`` -> ``("sigma2", 0.5)``: ``NAME=VALUE`` with the value read as a Python literal
    (numbers, True, lists, 'text'), else kept as a string. The one parser of ``shapelib --param``
    and ``run_all.py -p``; a ValueError names ``flag`` and the text, and shows ``example``.

    Examples
    --------
    >>> parse_assignment("sigma2=0.5"), parse_assignment("name=fish-2")
    (('sigma2', 0.5), ('name', 'fish-2'))
    """
    key, sep, raw = text.partition("=")
    key, raw = key.strip(), raw.strip()
    if not sep or not key.isidentifier():
        raise ValueError(f"{flag} {text!r}: expected NAME=VALUE, e.g. {flag} {example}")
    try:
        import ast

        return key, ast.literal_eval(raw)
    except (ValueError, TypeError, SyntaxError, MemoryError, RecursionError):
        return key, raw

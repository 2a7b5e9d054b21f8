"""Argument validation shared by every module.

Every public function validates its inputs up front and raises :class:`ValueError`
with a message of the form ``"<name>: expected <what>, got <value>"`` so that users
never see a traceback from deep inside NumPy or JAX. The helpers return the checked
value as a NumPy array (or Python scalar) so that callers can write
``rate = check_positive("birth_rate", birth_rate)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TypeVar

import numpy as np
import numpy.typing as npt

_T = TypeVar("_T")

__all__ = [
    "describe",
    "check_array",
    "check_finite",
    "check_positive",
    "check_nonnegative",
    "check_nonneg_int",
    "check_probability",
    "check_simplex",
    "check_sorted",
    "check_nonempty",
    "check_in",
]


def describe(x: object, limit: int = 60) -> str:
    """Short printable description of a value for error messages."""
    try:
        a = np.asarray(x)
    except Exception:  # pragma: no cover - exotic objects
        return repr(x)[:limit]
    if a.ndim == 0:
        return repr(a.item())[:limit]
    text = np.array2string(a.ravel()[:6], precision=6, separator=", ")
    if a.size > 6:
        text = text[:-1] + ", ...]"
    return f"array of shape {a.shape} {text}"[: limit + 40]


def check_array(
    name: str, x: npt.ArrayLike, dtype: npt.DTypeLike = float, ndim: int | None = None
) -> np.ndarray:
    """Convert ``x`` to an array of ``dtype``; reject what cannot be converted."""
    try:
        a = np.asarray(x, dtype=dtype)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{name}: expected numbers, got {describe(x)}") from err
    if ndim is not None and a.ndim != ndim:
        raise ValueError(f"{name}: expected a {ndim}-d array, got shape {a.shape}")
    return a


def _first_bad(a: np.ndarray, bad: np.ndarray) -> str:
    idx = np.argwhere(bad)[0]
    where = "" if a.ndim == 0 else f" at index {tuple(int(i) for i in idx)}"
    return f"{a[tuple(idx)].item()!r}{where}"


def check_finite(name: str, x: npt.ArrayLike, ndim: int | None = None) -> np.ndarray:
    """Finite real numbers."""
    a = check_array(name, x, float, ndim)
    bad = ~np.isfinite(a)
    if bad.any():
        raise ValueError(f"{name}: expected finite numbers, got {_first_bad(a, bad)}")
    return a


def check_positive(name: str, x: npt.ArrayLike, ndim: int | None = None) -> np.ndarray:
    """Finite numbers > 0."""
    a = check_finite(name, x, ndim)
    bad = a <= 0
    if bad.any():
        raise ValueError(f"{name}: expected finite numbers > 0, got {_first_bad(a, bad)}")
    return a


def check_nonnegative(name: str, x: npt.ArrayLike, ndim: int | None = None) -> np.ndarray:
    """Finite numbers >= 0."""
    a = check_finite(name, x, ndim)
    bad = a < 0
    if bad.any():
        raise ValueError(f"{name}: expected finite numbers >= 0, got {_first_bad(a, bad)}")
    return a


def check_nonneg_int(name: str, x: npt.ArrayLike, ndim: int | None = None) -> np.ndarray:
    """Non-negative integers (floats with integral values are accepted)."""
    a = check_finite(name, x, ndim)
    bad = (a < 0) | (a != np.round(a))
    if bad.any():
        raise ValueError(f"{name}: expected non-negative integers, got {_first_bad(a, bad)}")
    return a.astype(np.int64)


def check_probability(
    name: str, x: npt.ArrayLike, *, closed_right: bool = True, ndim: int | None = None
) -> np.ndarray:
    """Numbers in [0, 1] (or [0, 1) with ``closed_right=False``)."""
    a = check_finite(name, x, ndim)
    bad = (a < 0) | ((a > 1) if closed_right else (a >= 1))
    if bad.any():
        interval = "[0, 1]" if closed_right else "[0, 1)"
        raise ValueError(f"{name}: expected values in {interval}, got {_first_bad(a, bad)}")
    return a


def check_simplex(name: str, x: npt.ArrayLike, atol: float = 1e-6) -> np.ndarray:
    """A 1-d vector of non-negative weights that sums to one."""
    a = check_nonnegative(name, x, ndim=1)
    if a.size == 0:
        raise ValueError(f"{name}: expected at least one weight, got an empty array")
    s = float(a.sum())
    if abs(s - 1.0) > atol:
        raise ValueError(f"{name}: expected weights summing to 1, got sum {s!r}")
    return a


def check_sorted(name: str, x: npt.ArrayLike, strict: bool = True) -> np.ndarray:
    """A 1-d finite vector in increasing order."""
    a = check_finite(name, x, ndim=1)
    d = np.diff(a)
    bad = d <= 0 if strict else d < 0
    if bad.any():
        i = int(np.argmax(bad))
        order = "strictly increasing" if strict else "non-decreasing"
        raise ValueError(
            f"{name}: expected {order} values, got {a[i]!r} then {a[i + 1]!r} "
            f"at indices {i} and {i + 1}"
        )
    return a


def check_nonempty(name: str, x: _T) -> _T:
    """Reject empty arrays / sequences."""
    if np.size(x) == 0:
        raise ValueError(f"{name}: expected at least one value, got an empty input")
    return x


def check_in(name: str, x: _T, allowed: Sequence[_T]) -> _T:
    """One of a fixed set of options."""
    if x not in allowed:
        opts = ", ".join(repr(a) for a in allowed)
        raise ValueError(f"{name}: expected one of {opts}, got {x!r}")
    return x

"""Parameter checks shared by every system: each failure names the parameter and the rule."""

from __future__ import annotations

import math
import numbers

import numpy as np

__all__ = ["require_finite", "require_finite_positive", "require_finite_nonnegative", "require_all_positive", "require_int_at_least", "require_inertia"]


def require_finite(name: str, value) -> float:
    """``value`` as a float; ``ValueError`` unless it is a finite real number."""
    v = _as_real(name, value)
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return v


def require_all_positive(**values) -> list[float]:
    """:func:`require_finite_positive` for each keyword, in order."""
    return [require_finite_positive(name, value) for name, value in values.items()]


def require_finite_positive(name: str, value) -> float:
    """``value`` as a float; ``ValueError`` unless it is finite and > 0."""
    v = _as_real(name, value)
    if not (math.isfinite(v) and v > 0.0):
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    return v


def require_finite_nonnegative(name: str, value) -> float:
    """``value`` as a float; ``ValueError`` unless it is finite and >= 0."""
    v = _as_real(name, value)
    if not (math.isfinite(v) and v >= 0.0):
        raise ValueError(f"{name} must be finite and >= 0, got {value!r}")
    return v


def require_int_at_least(name: str, value, minimum: int) -> int:
    """``value`` as an int; ``ValueError`` unless it is an integer (not a bool) >= ``minimum``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def require_inertia(name: str, value) -> tuple[float, float, float]:
    """Principal moments ``(I1, I2, I3)``: three finite positive numbers obeying the triangle
    inequalities ``Ii + Ij >= Ik`` (equality allowed: a flat plate), as physics.md §1 requires
    of a real body."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be three principal moments (I1, I2, I3), got {value!r}") from None
    if arr.shape != (3,):
        raise ValueError(f"{name} must be three principal moments (I1, I2, I3), got shape {arr.shape}")
    if not (np.all(np.isfinite(arr)) and np.all(arr > 0.0)):
        raise ValueError(f"{name} must be finite and > 0 in every component, got {tuple(arr)}")
    i1, i2, i3 = (float(x) for x in arr)
    # A relative slack of a few ulp keeps an exactly flat plate (I3 = I1 + I2 in decimal) legal.
    slack = 4.0 * np.finfo(float).eps * (i1 + i2 + i3)
    for (a, b, c), label in (((i1, i2, i3), "I1 + I2 >= I3"), ((i2, i3, i1), "I2 + I3 >= I1"), ((i3, i1, i2), "I3 + I1 >= I2")):
        if a + b < c - slack:
            raise ValueError(f"{name} must satisfy the triangle inequality {label} (a real body), got {tuple(arr)}")
    return (i1, i2, i3)


def _as_real(name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a real number, got {value!r}")
    return float(value)

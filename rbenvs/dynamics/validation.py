"""Parameter checks shared by every system and env: each failure names the parameter and the rule.

A value of the wrong *type* (a string where a number belongs, ``"False"`` for a flag, a
complex number) raises :class:`ParameterTypeError`; a value of the right type that breaks a rule
(negative, non-finite, out of range) raises ``ValueError``. ``ParameterTypeError`` is both a
``TypeError`` and a ``ValueError``, so code that catches ``ValueError`` for any invalid
parameter catches it too.
"""

from __future__ import annotations

import difflib
import math
import numbers

import numpy as np

__all__ = [
    "did_you_mean",
    "unknown_keyword",
    "ParameterTypeError",
    "require_finite",
    "require_finite_positive",
    "require_finite_nonnegative",
    "require_all_positive",
    "require_int_at_least",
    "require_int_in",
    "require_inertia",
    "require_bool",
    "require_bool_mask",
    "require_choice",
    "require_real_vector",
    "require_range",
    "require_finite_result",
    "real_array",
]


class ParameterTypeError(TypeError, ValueError):
    """A parameter (or action, or state entry) of the wrong type; names it and the type wanted."""


def _type_name(value) -> str:
    return type(value).__name__


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
        if isinstance(value, numbers.Real):
            raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
        raise ParameterTypeError(
            f"{name} must be an integer >= {minimum}, got {value!r} ({_type_name(value)})"
        )
    if value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def require_int_in(name: str, value, minimum: int, maximum: int, why: str = "") -> int:
    """``value`` as an int in ``[minimum, maximum]`` (``why``: the reason for the upper bound)."""
    v = require_int_at_least(name, value, minimum)
    if v > maximum:
        raise ValueError(f"{name} must be an integer in [{minimum}, {maximum}]{why}, got {value!r}")
    return v


def require_bool(name: str, value) -> bool:
    """``value`` as a bool; only ``True``/``False`` (or numpy's bools) are accepted: ``"False"``,
    ``0`` or ``None`` for a flag are refused rather than read by their truth value."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise ParameterTypeError(
        f"{name} must be True or False (a bool), got {value!r} ({_type_name(value)})"
    )


def require_bool_mask(name: str, value, size: int, what: str = "") -> tuple[bool, ...]:
    """A sequence of ``size`` bools (a list, tuple or bool array); ``what`` says what each is."""
    label = f"{name} must be {size} booleans{what}"
    items = _sequence(label, value)
    if len(items) != size:
        raise ValueError(f"{label}, got {len(items)} entries: {value!r}")
    for item in items:
        if not isinstance(item, (bool, np.bool_)):
            raise ParameterTypeError(
                f"{label}, got the entry {item!r} ({_type_name(item)}) in {value!r}"
            )
    return tuple(bool(x) for x in items)


def _sequence(label: str, value) -> list:
    """The items of a list, tuple or 1-d array (not a string, a mapping or a scalar)."""
    ok = value.ndim == 1 if isinstance(value, np.ndarray) else isinstance(value, (list, tuple))
    if not ok:
        raise ParameterTypeError(f"{label}, got {value!r} ({_type_name(value)})")
    return list(value)


def did_you_mean(word, choices) -> str:
    """``"; did you mean 'x'?"`` for the choice closest to a misspelled ``word`` (difflib's
    ratio, case ignored), or ``""`` where none is close."""
    if not isinstance(word, str):
        return ""
    choices = [str(c) for c in choices]
    lowered = {c.lower(): c for c in choices}
    close = difflib.get_close_matches(word.lower(), list(lowered), n=1, cutoff=0.6)
    return f"; did you mean {lowered[close[0]]!r}?" if close else ""


def require_choice(name: str, value, choices) -> str:
    """One of the strings ``choices``."""
    if not isinstance(value, str):
        raise ParameterTypeError(
            f"{name} must be one of {list(choices)}, got {value!r} ({_type_name(value)})"
        )
    if value not in choices:
        raise ValueError(
            f"{name} must be one of {list(choices)}, got {value!r}{did_you_mean(value, choices)}"
        )
    return value


def unknown_keyword(owner: str, given, valid, where: str) -> TypeError | None:
    """The error for the first keyword of ``given`` that ``owner`` does not take: the closest
    valid one suggested and ``where`` the full list is; ``None`` where every keyword is valid."""
    unknown = [k for k in given if k not in valid]
    if not unknown:
        return None
    return TypeError(
        f"{owner} got an unexpected keyword argument "
        f"{unknown[0]!r}{did_you_mean(unknown[0], valid)} (every keyword: {where})"
    )


def require_real_vector(name: str, value, size: int, what: str = "") -> tuple[float, ...]:
    """``size`` finite real numbers (a sequence or array) as a tuple of floats; ``what`` says
    what they are. Strings, bools, complex numbers and other objects are refused by type."""
    label = f"{name} must be {size} finite real numbers{what}"
    items = _sequence(label, value)
    if len(items) != size:
        raise ValueError(f"{label}, got {len(items)} entries: {value!r}")
    out = []
    for item in items:
        if isinstance(item, (bool, np.bool_)) or not isinstance(item, numbers.Real):
            raise ParameterTypeError(
                f"{label}, got the entry {item!r} ({_type_name(item)}) in {value!r}"
            )
        v = float(item)
        if not math.isfinite(v):
            raise ValueError(f"{label}, got {value!r}")
        out.append(v)
    return tuple(out)


def require_range(name: str, value) -> tuple[float, float]:
    """A number ``v`` (the range ``(v, v)``) or a range ``(low, high)`` with ``low <= high``,
    both finite: a quantity drawn uniformly per episode."""
    if isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_)):
        v = require_finite(name, value)
        return v, v
    if not (
        isinstance(value, (list, tuple)) or (isinstance(value, np.ndarray) and value.ndim == 1)
    ):
        raise ParameterTypeError(
            f"{name} must be a number or a range (low, high), got {value!r} ({_type_name(value)})"
        )
    if len(value) != 2:
        raise ValueError(f"{name} must be a number or a range (low, high), got {value!r}")
    lo, hi = require_finite(f"{name}[0]", value[0]), require_finite(f"{name}[1]", value[1])
    if lo > hi:
        raise ValueError(f"{name} range must have low <= high, got {value!r}")
    return lo, hi


def require_finite_result(names: str, value: float, what: str) -> float:
    """A quantity derived from parameters (``what``, computed from ``names``) must be a finite
    float: magnitudes whose products overflow are refused at construction, naming them."""
    if not math.isfinite(value):
        raise ValueError(f"{names} are too large: {what} is {value!r}, not a finite number")
    return value


def real_array(name: str, value, dtype=np.float64) -> np.ndarray:
    """``value`` as an array of ``dtype`` (``None``: its own real dtype), refusing what is not real
    numbers: strings (even numeric ones), complex numbers, dicts and other objects raise
    :class:`ParameterTypeError` (numpy would convert ``"0.5"`` quietly, or drop an imaginary part
    with a warning)."""
    arr = (
        value
        if isinstance(value, np.ndarray)
        else np.asarray(value)
        if not isinstance(value, (dict, set))
        else None
    )
    if arr is None or arr.dtype.kind not in "iuf":
        kind = _type_name(value) if arr is None else f"{_type_name(value)} of dtype {arr.dtype}"
        raise ParameterTypeError(
            f"{name} must be real numbers (int or float), got {value!r} ({kind})"
        )
    return arr if dtype is None else arr.astype(dtype, copy=False)


def require_inertia(name: str, value) -> tuple[float, float, float]:
    """Principal moments ``(I1, I2, I3)``: three finite positive numbers obeying the triangle
    inequalities ``Ii + Ij >= Ik`` (equality allowed: a flat plate), as docs/physics.md §1 requires
    of a real body."""
    i1, i2, i3 = require_real_vector(name, value, 3, " (the principal moments I1, I2, I3)")
    if not (i1 > 0.0 and i2 > 0.0 and i3 > 0.0):
        raise ValueError(f"{name} must be finite and > 0 in every component, got {(i1, i2, i3)}")
    arr = (i1, i2, i3)
    if not math.isfinite(i1 + i2 + i3):
        raise ValueError(f"{name} is too large: the sum of the moments overflows, got {arr}")
    # A relative slack of a few ulp keeps an exactly flat plate (I3 = I1 + I2 in decimal) legal.
    slack = 4.0 * np.finfo(float).eps * (i1 + i2 + i3)
    for (a, b, c), label in (
        ((i1, i2, i3), "I1 + I2 >= I3"),
        ((i2, i3, i1), "I2 + I3 >= I1"),
        ((i3, i1, i2), "I3 + I1 >= I2"),
    ):
        if a + b < c - slack:
            raise ValueError(
                f"{name} must satisfy the triangle inequality {label} (a real body), got "
                f"{tuple(arr)}"
            )
    return (i1, i2, i3)


def _as_real(name: str, value) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ParameterTypeError(
            f"{name} must be a real number, got {value!r} ({_type_name(value)})"
        )
    return float(value)

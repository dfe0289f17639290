"""Named states: a system's components to and from a dict of named arrays (``get_state`` and
``reset(options={"state": ...})``), checked once here for every system laid out in slices.

A system's ``layout`` maps names to ``(start, stop)`` slices of its components. Exported
arrays are float64 copies (shape ``(k,)`` for one state, ``(k, n)`` for components that are
arrays); an imported dict must have exactly the layout's names, real finite entries of the
right shape; the system then checks its physical constraints (unit vectors, quaternions).
"""

from __future__ import annotations

import numpy as np

from ..jit import jitable
from .validation import real_array

__all__ = ["export_layout", "import_layout", "start_as_drawn"]


@jitable
def start_as_drawn(p, y, d):
    """A task's start, complete as it is: the pure ``kernel_complete`` of a system that adds
    nothing to it (``p`` and the system's draws ``d`` unused)."""
    return y


def export_layout(layout: dict, y) -> dict:
    """``{name: float64 array}`` of the components ``y`` (floats or arrays; copies)."""
    return {name: np.array(y[a:b], dtype=np.float64) for name, (a, b) in layout.items()}


def import_layout(layout: dict, dim: int, state) -> tuple[tuple, dict]:
    """``(components as floats, {name: float64 array})`` from a state dict; ``ValueError``
    (``TypeError`` for entries that are not real numbers) naming the entry otherwise."""
    if not isinstance(state, dict):
        raise ValueError(
            f"options['state'] must be a dict of named arrays, got {type(state).__name__}"
        )
    unknown = sorted(set(state) - set(layout))
    missing = sorted(set(layout) - set(state))
    if unknown or missing:
        raise ValueError(
            f"state must have exactly the names {sorted(layout)} for this scene"
            + (f"; unknown: {unknown}" if unknown else "")
            + (f"; missing: {missing}" if missing else "")
        )
    comps = [0.0] * dim
    arrays = {}
    for name, (a, b) in layout.items():
        arr = real_array(f"state[{name!r}]", state[name])
        if arr.shape != (b - a,):
            raise ValueError(f"state[{name!r}] must have shape ({b - a},), got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"state[{name!r}] must be finite, got {arr}")
        comps[a:b] = (float(x) for x in arr)
        arrays[name] = arr
    return tuple(comps), arrays

"""Why an episode ended: a code per env (what the compiled vector step writes per sub-env) and
the name ``info["terminal_reason"]`` reports, for one env (a string) and a batch (an array of
strings, pooled for the compiled step to write into)."""

from __future__ import annotations

import sys
from functools import cache

import numpy as np

from ..jit import compiled_form, jitable

__all__ = [
    "REASONS",
    "end_code",
    "reason_names",
    "reason_strings",
    "reason_code_points",
    "ReasonPool",
    "terminal_reason",
]

# Why an episode ended, as a code (what the compiled vector step writes per sub-env) and as the
# name ``info["terminal_reason"]`` reports: code k is REASONS[k], the system's terminal event's
# name in place of "event" (:func:`reason_names`).
REASONS = ("", "task", "observation_limit", "event", "numerical_failure")


@jitable
def end_code(failed, fired, over, terminated):
    """The code of :data:`REASONS` for one env: ``numerical_failure`` over the event over
    ``observation_limit`` over ``task``; 0 where the episode goes on."""
    if failed:
        return 4
    if fired:
        return 3
    if over:
        return 2
    if terminated:
        return 1
    return 0


@compiled_form(end_code)
def _end_code_selects(failed, fired, over, terminated):
    """:func:`end_code` compiled: one expression of conditional values, which LLVM turns into
    selections (a batch loop of it stays free of mispredictions)."""
    return 4 if failed else (3 if fired else (2 if over else (1 if terminated else 0)))


def reason_names(event_name) -> tuple:
    """:data:`REASONS` with the system's event name (``""`` where it has none)."""
    return REASONS[:3] + (event_name or "",) + REASONS[4:]


@cache
def _reason_array(event_name):
    names = np.array(reason_names(event_name))
    names.flags.writeable = False
    return names


def reason_strings(codes, event_name):
    """A batch's terminal reasons from their codes: a fixed-width string array (its items are
    str, ``""`` where the episode goes on), written only where a code is set (a zero-filled
    array costs no pass over the batch)."""
    names = _reason_array(event_name)
    reason = np.zeros(np.shape(codes), dtype=names.dtype)
    idx = np.flatnonzero(codes)
    reason[idx] = names[codes[idx]]
    return reason


def reason_code_points(event_name) -> np.ndarray:
    """The names of :func:`reason_names` as rows of UCS-4 code points, ``(5, width)`` uint32:
    what compiled code writes into a reason array's rows (:class:`ReasonPool`)."""
    names = _reason_array(event_name)
    return np.ascontiguousarray(names).view(np.uint32).reshape(len(names), -1)


class ReasonPool:
    """Zero-filled reason arrays (:func:`reason_strings`' type) for a compiled step to write
    into, handed out again once nothing else refers to them.

    Why: a batch's reason array is wide (17 UCS-4 characters a sub-env) and mostly empty; a
    fresh one costs a page fault for every page a reason is written to, and naming the reasons
    with numpy's fancy indexing is slow too: together a large share of a large batch's step
    (``rbenvs bench throughput`` measures the step). An array is taken again only
    when CPython's reference count says that the pool alone holds it (the caller let go of
    that step's ``info``; a view of it keeps it out), after the rows it last held are cleared
    (by the step itself: :meth:`take` returns them). At most ``size`` arrays are kept;
    otherwise a fresh one is made."""

    def __init__(self, n: int, event_name, size: int = 2):
        self.n, self.size = n, size
        # (a writable copy, as pickle gives it back: numba compiles a kernel per writability)
        self.names = reason_code_points(event_name).copy()
        self.dtype = _reason_array(event_name).dtype
        self.entries = []  # [array, its uint32 view, the rows written into it]
        self._none = np.zeros(0, dtype=np.int64)

    def take(self) -> tuple:
        """``(array, its (n, width) uint32 view, the rows to clear, entry)``."""
        for entry in self.entries:
            # 3: the pool's list, the view's base and getrefcount's argument
            if sys.getrefcount(entry[0]) == 3:
                return entry[0], entry[1], entry[2], entry
        array = np.zeros(self.n, dtype=self.dtype)
        view = array.view(np.uint32).reshape(self.n, -1)
        entry = None
        if len(self.entries) < self.size:
            entry = [array, view, self._none]
            self.entries.append(entry)
        return array, view, self._none, entry

    def written(self, entry, rows) -> None:
        """Record the rows a step wrote into ``entry``'s array (cleared when it is next taken)."""
        if entry is not None:
            entry[2] = rows.copy()


def terminal_reason(failed, fired, over, terminated, event_name):
    """Why an episode ended (:func:`end_code`); for one env a string or ``None``, for a batch
    an array of strings (``""`` where the episode goes on)."""
    if not isinstance(over, np.ndarray):
        return reason_names(event_name)[end_code(failed, fired, over, terminated)] or None
    codes = np.zeros(np.shape(over), dtype=np.int8)
    codes[terminated] = 1
    codes[over] = 2
    codes[fired] = 3
    codes[failed] = 4
    return reason_strings(codes, event_name)

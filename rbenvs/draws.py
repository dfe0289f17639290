"""A start's random numbers, declared: which kinds, in which order, from one generator.

A task (and a system that adds to a start, such as the heavy top's heading) declares the raw
numbers one start takes as a string of kinds (``draw_kinds``): ``"u"`` a uniform on ``[0, 1)``
(``Generator.random``), ``"n"`` a standard normal (``Generator.standard_normal``). The
arithmetic that turns them into a state runs once on a batch's rows
(``initial_from_draws``); only the generator calls belong to each sub-env.

Declaring the kinds, not a method that makes the calls, is what lets a vector env restart
sub-envs with no Python per sub-env: with numba (the ``fast`` extra) the calls run in one
compiled loop over the restarting sub-envs' own generators (:func:`batch_draws`), which
numba gives the very streams numpy's ``Generator`` methods give (same bit generator, same
algorithms; tested draw for draw). A sub-env then draws what a single env seeded alike
draws, whichever path made the calls.
"""

from __future__ import annotations

import numpy as np

from . import jit

__all__ = ["UNIFORM", "NORMAL", "draw", "kind_codes", "batch_draws", "GeneratorTable"]

UNIFORM = "u"  # Generator.random(): [0, 1)
NORMAL = "n"  # Generator.standard_normal()
_CODES = {UNIFORM: 0, NORMAL: 1}


def kind_codes(kinds: str) -> np.ndarray:
    """The kinds as the compiled loop's codes (``int8``); an unknown kind is an error."""
    unknown = set(kinds) - set(_CODES)
    if unknown:
        raise ValueError(
            f"draw kinds must be {UNIFORM!r} (uniform) or {NORMAL!r} (normal), got "
            f"{sorted(unknown)}"
        )
    return np.array([_CODES[k] for k in kinds], dtype=np.int8)


def draw(rng: np.random.Generator, kinds: str) -> np.ndarray:
    """One start's numbers from ``rng`` in the order of ``kinds`` (a float64 array): one
    generator call per run of equal kinds (``random(k)``, ``standard_normal(k)``), the same
    numbers as one call per number."""
    out = np.empty(len(kinds))
    i = 0
    while i < len(kinds):
        j = i
        while j < len(kinds) and kinds[j] == kinds[i]:
            j += 1
        out[i:j] = rng.random(j - i) if kinds[i] == UNIFORM else rng.standard_normal(j - i)
        i = j
    return out


def batch_draws(rngs, kinds: str) -> np.ndarray:
    """``(len(kinds), len(rngs))``: column ``i`` is :func:`draw` of ``rngs[i]`` (Python, one
    call per generator and run; :class:`GeneratorTable` does it compiled)."""
    out = np.empty((len(kinds), len(rngs)))
    for i, rng in enumerate(rngs):
        out[:, i] = draw(rng, kinds)
    return out


_kernels: dict = {}


def _table_kernels() -> dict:
    """The compiled functions of a :class:`GeneratorTable` (made once per process, kept on disk by
    :mod:`rbenvs.kernel_cache`): ``draw(generators, idx, codes, out)``, and the typed list's
    ``make(rng)``, ``append(table, rng)`` and ``put(table, i, rng)``. The list is built by these
    rather than by ``numba.typed.List(rngs)``, whose methods numba compiles again in every
    process (most of a vector env's start once its own kernels come from the disk; rbenvs bench
    startup)."""
    if not _kernels:
        from numba.typed import List

        from .kernel_cache import njit

        def draw(generators, idx, codes, out):
            for j in range(idx.shape[0]):
                rng = generators[idx[j]]
                for k in range(codes.shape[0]):
                    if codes[k] == 0:
                        out[k, j] = rng.random()
                    else:
                        out[k, j] = rng.standard_normal()

        def make(rng):
            table = List()
            table.append(rng)
            return table

        def append(table, rng):
            table.append(rng)

        def put(table, i, rng):
            table[i] = rng

        _kernels.update(
            draw=njit(draw, "draws"),
            make=njit(make, "generator table"),
            append=njit(append, "generator table append"),
            put=njit(put, "generator table put"),
        )
    return _kernels


class GeneratorTable:
    """The sub-envs' generators as one numba typed list, so that the draws of any set of
    sub-envs are one compiled call, with no Python per sub-env. The ``Generator`` objects are
    shared, not copied: a draw here advances the same stream a Python call on that generator
    would.

    ``table[i] = rng`` replaces sub-env ``i``'s generator (a reseeded sub-env)."""

    def __init__(self, rngs):
        kernels = _table_kernels()
        rngs = list(rngs)
        if not rngs:
            raise ValueError("a generator table needs at least one generator")
        self._list = kernels["make"](rngs[0])
        for rng in rngs[1:]:
            kernels["append"](self._list, rng)
        self._rngs = rngs  # (the same objects: the draws' Python form before the kernel is built)
        self._drawn = 0  # (sub-envs drawn in Python: jit.COMPILE_AFTER)
        self._kernel = kernels["draw"]
        self._put = kernels["put"]

    def __setitem__(self, i: int, rng) -> None:
        self._put(self._list, i, rng)
        self._rngs[i] = rng

    @property
    def list(self):
        """The typed list itself (compiled code draws from it: :mod:`rbenvs.compiled`)."""
        return self._list

    def draws(self, idx: np.ndarray, codes: np.ndarray) -> np.ndarray:
        """``(len(codes), len(idx))``: column ``j`` the numbers of sub-env ``idx[j]``'s start."""
        if (
            self._drawn < jit.COMPILE_AFTER
        ):  # (in Python, the same numbers: a reset's draws compile nothing)
            self._drawn += len(idx)
            return batch_draws(
                [self._rngs[i] for i in idx], "".join(UNIFORM if c == 0 else NORMAL for c in codes)
            )
        out = np.empty((len(codes), len(idx)))
        self._kernel(self._list, np.asarray(idx, dtype=np.int64), codes, out)
        return out

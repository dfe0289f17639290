"""The vector env's ``num_threads=``: how many of numba's threads one compiled step's chunks of
sub-envs run on (:func:`rbenvs.compiled.split_kernel`, a ``prange`` over the chunks), and when
they cannot run at all.

numba's threading layer is chosen once per process (``tbb`` where it loads, else ``omp``, else
``workqueue``; ``NUMBA_THREADING_LAYER`` overrides). GNU OpenMP's threads do not survive a
``fork``: a child of a process that ran them terminates when it starts a parallel region. A
forked child (gymnasium's ``AsyncVectorEnv`` with the ``fork`` start method, after the parent
stepped a split env) therefore runs its steps as one call, with the same results, and says so
once.
"""

from __future__ import annotations

import os
import warnings

from ..dynamics.validation import require_int_at_least

__all__ = ["resolve_num_threads", "usable_cores", "pool_size", "splits", "launch_us"]

# True in a child forked after this process (or its parent) had started GNU OpenMP's threads
_forked_after_omp = False


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity where the platform tells it)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # (macOS, Windows)
        return max(1, os.cpu_count() or 1)


def resolve_num_threads(value) -> int:
    """``num_threads=``: an integer >= 1, or ``"auto"`` (every core the process may use)."""
    if isinstance(value, str):
        if value == "auto":
            return usable_cores()
        raise ValueError(f"num_threads must be an integer >= 1 or 'auto', got {value!r}")
    return require_int_at_least("num_threads", value, 1)


def pool_size() -> int:
    """The most threads numba may run a parallel region on (``NUMBA_NUM_THREADS``)."""
    import numba

    return int(numba.config.NUMBA_NUM_THREADS)


def _omp_started() -> bool:
    import sys

    numba = sys.modules.get("numba")  # (not imported here: a process without numba has no threads)
    if numba is None:
        return False
    try:
        return numba.threading_layer() == "omp"
    except ValueError:  # no parallel region has run yet
        return False


def _after_fork_in_child() -> None:
    global _forked_after_omp
    _forked_after_omp = _forked_after_omp or _omp_started()


os.register_at_fork(after_in_child=_after_fork_in_child) if hasattr(
    os, "register_at_fork"
) else None
_warned = False


def splits() -> bool:
    """Whether a step may run on numba's threads in this process (not in a child forked after
    GNU OpenMP's threads started: there it runs as one call, with a warning, once)."""
    global _warned
    if not _forked_after_omp:
        return True
    if not _warned:
        _warned = True
        warnings.warn(
            "num_threads: this process was forked from one that ran numba's GNU OpenMP threads, "
            "which cannot start in a forked "
            "child; its vector steps run on one thread (the same results). Start such workers with "
            "'spawn' or 'forkserver' "
            "(AsyncVectorEnv(..., context='spawn')) to run them on threads.",
            RuntimeWarning,
            stacklevel=4,
        )
    return False


def launch_us(threads: int = 2, calls: int = 2000) -> tuple[str, float]:
    """``(numba's threading layer, microseconds of one parallel region of ``threads`` empty
    chunks)``: what a split step pays twice beyond its arithmetic."""
    import time

    import numba
    import numpy as np

    @numba.njit(parallel=True)
    def region(out):
        for c in numba.prange(out.shape[0]):
            out[c] += 1

    out = np.zeros(threads, dtype=np.int64)
    before = numba.get_num_threads()
    numba.set_num_threads(min(threads, pool_size()))  # (as a split step sets it around its call)
    try:
        for _ in range(20):
            region(out)
        start = time.perf_counter()
        for _ in range(calls):
            region(out)
        seconds = time.perf_counter() - start
    finally:
        numba.set_num_threads(before)
    return numba.threading_layer(), 1e6 * seconds / calls

"""The vector env's ``num_threads=``: a team of threads that run one compiled step's chunks of
sub-envs at once (the kernel releases the GIL: :func:`rbenvs.compiled.vector_kernel`).

The team is a handful of daemon threads parked on semaphores, woken once per step; the calling
thread runs chunk 0 itself. A barrier between the step's two phases lets every chunk's check
finish before any chunk writes the episode's bookkeeping (see :class:`rbenvs.compiled.VectorStep`).
Threads, not processes: the chunks share the env's arrays, and a fork of the process (gymnasium's
``AsyncVectorEnv``) finds no threads: the team starts its own again in the child.
"""

from __future__ import annotations

import os
import threading
import weakref

from ..dynamics.validation import require_int_at_least

__all__ = ["ThreadTeam", "resolve_num_threads", "usable_cores"]


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


class _Shared:
    """What the workers read: the step's job and the barrier's action, the first error raised,
    the barrier and the stop flag (kept apart from the team, so that a team nobody holds is collected and its
    workers told to stop)."""

    __slots__ = ("job", "between", "error", "barrier", "stop")

    def __init__(self, size: int):
        self.job = self.between = self.error = None
        self.barrier = threading.Barrier(size, action=self._between)
        self.stop = False

    def _between(self) -> None:
        self.between()

    def failed(self, error: BaseException) -> None:
        """Keep the first error (one that broke the barrier only where no other came), and free
        the chunks waiting at the barrier."""
        if self.error is None or isinstance(self.error, threading.BrokenBarrierError):
            self.error = error
        self.barrier.abort()


def _work(shared: _Shared, chunk: int, go, done) -> None:
    while True:
        go.acquire()
        if shared.stop:
            return
        try:
            shared.job(chunk)
        except BaseException as error:  # (handed to the caller's thread, raised there)
            shared.failed(error)
        finally:
            done.release()


def _stop(shared: _Shared, gos) -> None:
    shared.stop = True
    for go in gos:
        go.release()


class ThreadTeam:
    """``size`` threads (the caller's and ``size - 1`` workers) that run ``job(chunk)`` for every
    chunk at once (:meth:`run`); a job calls :meth:`sync` to wait until every chunk has reached it
    (then ``between()``, given to :meth:`run`, runs once, on one thread, before any goes on)."""

    def __init__(self, size: int):
        self.size = size
        self._pid = None

    def _start(self) -> None:
        self._shared = _Shared(self.size)
        self._gos = [threading.Semaphore(0) for _ in range(self.size - 1)]
        self._dones = [threading.Semaphore(0) for _ in range(self.size - 1)]
        for chunk, (go, done) in enumerate(zip(self._gos, self._dones), start=1):
            threading.Thread(target=_work, args=(self._shared, chunk, go, done), name=f"rbenvs-step-{chunk}", daemon=True).start()
        weakref.finalize(self, _stop, self._shared, self._gos)
        self._pid = os.getpid()

    def run(self, job, between) -> None:
        if self._pid != os.getpid():  # (first use, or a forked child: the parent's threads are not here)
            self._start()
        shared = self._shared
        shared.job, shared.between, shared.error = job, between, None
        for go in self._gos:
            go.release()
        try:
            job(0)
        except BaseException as error:
            shared.failed(error)
        for done in self._dones:
            done.acquire()
        shared.job = shared.between = None
        if shared.error is not None:
            shared.barrier.reset()
            raise shared.error

    def sync(self) -> None:
        """Wait for every chunk; ``between()`` runs once all have come."""
        self._shared.barrier.wait()

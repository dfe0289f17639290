"""Where the grid's cells run: one after another here, or as Ray tasks on a cluster.

A :class:`Backend` takes the cells of :func:`rbenvs_agents.grid.grid_cells` and returns their
results in the same order; each cell is run by :func:`rbenvs_agents.grid.run_cell`, whichever
the backend. :class:`SerialBackend` (the default) needs nothing beyond the ``agents`` extra.
:class:`RayBackend` (the ``ray`` extra) makes every cell a Ray task of one CPU on the cluster of
:func:`rbenvs_agents.cluster.ray_cluster`: an embedded local one that starts and stops with the
command, or a running one joined by its address.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

from .grid import Cell, CellResult, run_cell

__all__ = ["Backend", "SerialBackend", "RayBackend"]


class Backend(Protocol):
    def run(
        self, cells: Sequence[Cell], on_result: Callable[[CellResult], None] | None = None
    ) -> list[CellResult]:
        """The results of ``cells``, in their order; ``on_result`` is called with each result as
        soon as it is in (in the order the cells finish: ``rbenvs-results --records`` keeps
        them)."""


@dataclass(frozen=True)
class SerialBackend:
    """Cell after cell in this process, each training with its progress bar."""

    progress: bool = True

    def run(self, cells, on_result=None):
        results = []
        for cell in cells:
            results.append(run_cell(cell, progress=self.progress))
            if on_result is not None:
                on_result(results[-1])
        return results


@dataclass(frozen=True)
class RayBackend:
    """One Ray task per cell, each holding one CPU (a cell trains on one torch and one numba
    thread). ``address``: a running cluster's (None: start an embedded local one with
    ``num_cpus`` CPUs, all of the machine's if None)."""

    address: str | None = None
    num_cpus: int | None = None

    def run(self, cells, on_result=None):
        from .cluster import ray_cluster

        with ray_cluster(self.address, self.num_cpus) as ray:
            remote_cell = ray.remote(num_cpus=1)(run_cell)
            # the trained cells first: the long tasks start while the CPUs are free and the short
            # baseline evaluations fill the gaps after them; each result is taken as it finishes
            # (on_result), and they are returned in the cells' order
            order = sorted(range(len(cells)), key=lambda i: not cells[i].learned)
            index = {remote_cell.remote(cells[i]): i for i in order}
            results, pending = [None] * len(cells), list(index)
            while pending:
                ready, pending = ray.wait(pending, num_returns=1)
                for future in ready:
                    results[index[future]] = ray.get(future)
                    if on_result is not None:
                        on_result(results[index[future]])
            return results

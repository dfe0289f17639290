"""The exact uncontrolled flow, composed with control kicks when a control acts."""

from __future__ import annotations

from dataclasses import dataclass

from .base import Integrator, StepRegion

__all__ = ["Exact"]


@dataclass(frozen=True)
class Exact(Integrator):
    """``kick(h/2) free(h) kick(h/2)``; with ``u = None`` simply ``free(h)``.

    Without control the step is the exact solution (for the free body, the elliptic-function
    flow of [MR 15.8]): error at round-off for any ``h``. With a control it is a second-order
    Strang splitting whose free part is exact.
    """

    name = "exact"
    order = 2  # with control; exact (to round-off) without
    evaluations = 0
    conserves = ("casimirs", "energy")
    requires = ("free_flow", "kick")
    region = StepRegion.unbounded("the exact flow (torque as exact kicks)", exact_subflows=True)

    def step(self, system, y, u, h):
        if u is None:
            return system.free_flow(y, h)
        y = system.kick(y, u, 0.5 * h)
        y = system.free_flow(y, h)
        return system.kick(y, u, 0.5 * h)

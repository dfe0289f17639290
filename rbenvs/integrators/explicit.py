"""Explicit Runge-Kutta schemes on components: forward Euler and classical RK4."""

from __future__ import annotations

from dataclasses import dataclass

from .base import Integrator

__all__ = ["Euler", "RK4"]


@dataclass(frozen=True)
class Euler(Integrator):
    """Forward Euler: first order, one rhs call; drifts in every invariant and is unstable
    for large ``|Omega| h`` (physics.md §4). The cheapest baseline, not a recommendation."""

    name = "euler"
    order = 1
    evaluations = 1

    def step(self, system, y, u, h):
        k = system.rhs(y, u)
        return system.normalize(tuple(a + h * b for a, b in zip(y, k)))


@dataclass(frozen=True)
class RK4(Integrator):
    """Classical fourth-order Runge-Kutta, four rhs calls; invariants drift slowly."""

    name = "rk4"
    order = 4
    evaluations = 4

    def step(self, system, y, u, h):
        f = system.rhs
        hh = 0.5 * h
        k1 = f(y, u)
        k2 = f(tuple(a + hh * b for a, b in zip(y, k1)), u)
        k3 = f(tuple(a + hh * b for a, b in zip(y, k2)), u)
        k4 = f(tuple(a + h * b for a, b in zip(y, k3)), u)
        h6 = h / 6.0
        out = tuple(a + h6 * (b1 + 2.0 * (b2 + b3) + b4) for a, b1, b2, b3, b4 in zip(y, k1, k2, k3, k4))
        return system.normalize(out)

"""Symmetric (Strang) composition of exact sub-flows: the Lie-Poisson splitting."""

from __future__ import annotations

from dataclasses import dataclass

from .base import Integrator, StepRegion

__all__ = ["Splitting"]


@dataclass(frozen=True)
class Splitting(Integrator):
    """``f1(h/2) ... f_{n-1}(h/2) f_n(h) f_{n-1}(h/2) ... f1(h/2)`` over ``system.split_flows()``.

    Each piece is an exact flow, so whatever all pieces conserve is kept to round-off (for the
    free body ``|Pi|``, the spatial momentum and ``|q|``; for the heavy top ``|Gamma|`` and
    ``Pi.Gamma``: the systems' ``casimirs``) and, the composition being symmetric
    and symplectic on the coadjoint orbit, the energy error stays bounded over long runs.
    Second order; no rhs calls.
    """

    name = "splitting"
    order = 2
    evaluations = 0
    conserves = ("casimirs",)
    requires = ("split_flows",)
    # Every piece is exact (nothing blows up at any h); past about a radian per step the
    # composed pieces stop following the motion (second order in lambda h): an accuracy bound.
    region = StepRegion(rotation=1.0, exact_subflows=True, reason="accuracy: exact pieces, second order in lambda h")

    def step(self, system, y, u, h):
        flows = system.split_flows()
        hh = 0.5 * h
        for flow in flows[:-1]:
            y = flow(y, u, hh)
        y = flows[-1](y, u, h)
        for flow in reversed(flows[:-1]):
            y = flow(y, u, hh)
        return y

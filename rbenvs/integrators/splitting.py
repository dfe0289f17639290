"""Symmetric (Strang) composition of exact sub-flows: the Lie-Poisson splitting."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

from ..codegen import generate
from .base import Integrator, StepRegion

__all__ = ["Splitting"]


def _order(n: int) -> list[tuple[int, str]]:
    """``(flow, step)`` of the symmetric composition of ``n`` flows: half steps out and back
    around a full step of the last."""
    return (
        [(i, "hh") for i in range(n - 1)]
        + [(n - 1, "h")]
        + [(i, "hh") for i in reversed(range(n - 1))]
    )


@cache
def _composition(n: int) -> dict:
    """The generated composition of ``n`` pure flows ``f_i(P_i, y, u, h)``: ``make(f.., P..)``
    gives the step with the parameters bound (the single env), ``pure(f..)`` the step
    ``step(PS, y, u, h)`` with ``PS = (P_0, ...)`` (compiled kernels). The operations are those
    of :meth:`Splitting.step`, in its order."""
    fs, ps = [f"f{i}" for i in range(n)], [f"P{i}" for i in range(n)]
    body = ["hh = 0.5 * h"] + [f"y = f{i}(P{i}, y, u, {h})" for i, h in _order(n)] + ["return y"]
    inner = "".join(f"        {line}\n" for line in body)
    src = f"def make({', '.join(fs + ps)}):\n    def step(y, u, h):\n{inner}    return step\n"
    src += (
        f"def pure({', '.join(fs)}):\n    def step(PS, y, u, h):\n"
        f"        {', '.join(ps)}, = PS\n{inner}    return step\n"
    )
    return generate(src, f"splitting of {n} flows")


@cache
def _pure_step(fns: tuple):
    return _composition(len(fns))["pure"](*fns)


@dataclass(frozen=True)
class Splitting(Integrator):
    """``f1(h/2) ... f_{n-1}(h/2) f_n(h) f_{n-1}(h/2) ... f1(h/2)`` over ``system.split_flows()``.

    Each piece is an exact flow, so whatever all pieces conserve is kept to round-off (for the
    free body ``|Pi|``, the spatial momentum and ``|q|``; for the heavy top ``|Gamma|`` and
    ``Pi.Gamma``: the systems' ``casimirs``) and, the composition being symmetric
    and symplectic on the coadjoint orbit, the energy error stays bounded over long runs.
    Second order; no rhs calls. Where the system offers its flows' pure forms
    (``kernel_split_flows``) the composition is generated from them: the single env's bound
    step and the compiled kernel's step, the same operations as :meth:`step`.
    """

    name = "splitting"
    order = 2
    evaluations = 0
    conserves = ("casimirs",)
    requires = ("split_flows",)
    # Every piece is exact (nothing blows up at any h); past about a radian per step the
    # composed pieces stop following the motion (second order in lambda h): an accuracy bound.
    region = StepRegion(
        rotation=1.0, exact_subflows=True, reason="accuracy: exact pieces, second order in lambda h"
    )

    def step(self, system, y, u, h):
        flows = system.split_flows()
        hh = 0.5 * h
        for flow in flows[:-1]:
            y = flow(y, u, hh)
        y = flows[-1](y, u, h)
        for flow in reversed(flows[:-1]):
            y = flow(y, u, hh)
        return y

    def bind(self, system, dim, compensated=False):
        pure = system.kernel_split_flows
        if (
            compensated or pure is None or type(self).step is not Splitting.step
        ):  # (no compensated form)
            return super().bind(system, dim, compensated)
        fns, params = zip(*pure)
        return _composition(len(fns))["make"](*fns, *params)

    def kernel_step(self, system, compensated=False):
        pure = system.kernel_split_flows
        if compensated or pure is None or type(self).step is not Splitting.step:
            return None
        fns, params = zip(*pure)
        return _pure_step(tuple(fns)), tuple(params)

"""Explicit Runge-Kutta schemes from their Butcher tableaus: forward Euler and classical RK4.

A scheme is its coefficient table (:class:`ButcherTableau`): stage ``i`` evaluates the vector
field at ``y + h sum_j a_ij k_j`` and the step is ``y + h sum_i b_i k_i``. The step is
generated from the table (:mod:`rbenvs.codegen`), unrolled per state dimension: on a
single state of plain floats a loop's generator and zip overhead would cost more than the
physics. Every stage calls the system's one ``rhs``, on floats or on arrays alike.

The generated arithmetic follows fixed rules, so that a scheme's results do not depend on how
it was written: a stage input with one coefficient ``a`` is ``y + (a h) k`` with ``a h``
computed once (``h`` itself for ``a = 1``; a dyadic ``a`` as its exact float, another as
``h * p / q``); several coefficients give ``y + h * (a_1 k_1 + ...)``; the step takes the
weights' common denominator ``D`` (``h / D`` computed once; ``h`` for ``D = 1``) and sums the
integer numerators in stage order, consecutive stages of equal numerator ``n > 1`` grouped as
``n * (k_i + k_j)``. For RK4 that is ``y + h/6 (a + 2 (b + c) + d)``, for Euler ``y + h k``:
the same operations, in the same order, as the hand-written forms they replace (bit for bit;
``tests/test_integrators.py``).

A system that offers its vector field as a pure function (``kernel_rhs = (f, P)``, ``f(P, y,
u)`` equal to ``rhs(y, u)``, and its projection ``kernel_normalize = (g, N)`` or ``None``)
gets the same step with ``f(P, ...)`` in every stage and ``g(N, ...)`` at the end: bound to
``P`` (and ``N``) for the single env, and as the pure ``step(PS, y, u, h)`` that the compiled
batch kernel calls (:mod:`rbenvs.compiled`; ``PS`` is ``P``, or ``(P, N)`` with a projection).
One generator, so the same arithmetic in all three. A new explicit scheme is a new tableau.

Each step is generated twice: plain, and compensated (``bind(..., compensated=True)``,
``kernel_step(..., compensated=True)``: ``step(y, c, u, h) -> (y, c)``), which a tolerance's
steps take (:class:`rbenvs.core.step.Engine`). Its sum is ``z = h/D (...) + c`` (the increment
and the compensation carried in), ``t = y + z``, and it returns ``t`` and ``z - (t - y)``, what
that addition rounded away (Kahan 1965; exact where ``|y| >= |z|``, as for a step's small
increment). With ``c`` zero, ``t`` is the plain step's state, bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from functools import cache
from typing import ClassVar

from ..codegen import generate
from .base import Integrator, StepRegion

__all__ = ["ButcherTableau", "ExplicitRungeKutta", "Euler", "RK4"]


def _fraction(x) -> Fraction:
    """A coefficient as an exact fraction (a float is taken at its exact binary value: give
    coefficients such as 1/3 as ``Fraction(1, 3)``)."""
    return Fraction(x)


@dataclass(frozen=True)
class ButcherTableau:
    """The coefficients of an explicit Runge-Kutta scheme of ``s`` stages: ``a`` (rows
    ``a[i]`` of length ``i``: strictly lower triangular), ``b`` (the weights, ``s``), ``c``
    (the nodes, ``s``), as fractions. Validated: ``c_i = sum_j a_ij`` and ``sum b = 1``."""

    a: tuple
    b: tuple
    c: tuple

    def __post_init__(self):
        a = tuple(tuple(_fraction(x) for x in row) for row in self.a)
        b = tuple(_fraction(x) for x in self.b)
        c = tuple(_fraction(x) for x in self.c)
        s = len(b)
        if s == 0 or len(c) != s or len(a) != s:
            raise ValueError(
                f"a Butcher tableau needs s rows of a, s weights b and s nodes c; got {len(a)}, "
                f"{len(b)}, {len(c)}"
            )
        for i, row in enumerate(a):
            if len(row) != i:
                raise ValueError(
                    f"an explicit scheme's a is strictly lower triangular: row {i} must have {i} "
                    f"entries, got {len(row)}"
                )
            if sum(row, Fraction(0)) != c[i]:
                raise ValueError(
                    f"row {i} of a must sum to its node c[{i}] = {c[i]}, got "
                    f"{sum(row, Fraction(0))}"
                )
        if sum(b, Fraction(0)) != 1:
            raise ValueError(
                f"the weights b must sum to 1 (a consistent scheme), got {sum(b, Fraction(0))}"
            )
        object.__setattr__(self, "a", a)
        object.__setattr__(self, "b", b)
        object.__setattr__(self, "c", c)

    @property
    def stages(self) -> int:
        return len(self.b)


def _literal(x: Fraction) -> str:
    """``x`` as exact source: a dyadic fraction as its float, another as ``(p / q)``."""
    if float(x) == x:
        return repr(float(x))
    return f"({x.numerator}.0 / {x.denominator}.0)"


def _body(
    tableau: ButcherTableau, dim: int, call: str, project: bool, compensated: bool = False
) -> list[str]:
    """The lines of one step of ``tableau`` for states of ``dim`` components (see the module;
    ``compensated``: the step that also takes and returns the sum's compensation ``c``)."""

    def tup(items):
        return "(" + ", ".join(items) + ("," if len(items) == 1 else "") + ")"

    def names(stage):
        return ", ".join(f"k{stage}_{i}" for i in range(dim)) + ("," if dim == 1 else "")

    lines = [", ".join(f"y{i}" for i in range(dim)) + ("," if dim == 1 else "") + " = y"]
    if compensated:
        lines.append(", ".join(f"c{i}" for i in range(dim)) + ("," if dim == 1 else "") + " = c")
    scaled = {}  # coefficient -> name of the hoisted a * h

    def step_of(coef: Fraction) -> str:
        if coef == 1:
            return "h"
        if coef not in scaled:
            name = f"h_{len(scaled)}"
            scaled[coef] = name
            value = (
                f"{_literal(coef)} * h"
                if float(coef) == coef
                else f"h * {coef.numerator}.0 / {coef.denominator}.0"
            )
            lines.append(f"{name} = {value}")
        return scaled[coef]

    for s, row in enumerate(tableau.a):
        if s == 0:
            lines.append(f"{names(0)} = {call}y, u)")
            continue
        terms = [(j, a) for j, a in enumerate(row) if a != 0]
        if not terms:
            inputs = [f"y{i}" for i in range(dim)]
        elif len(terms) == 1:
            j, a = terms[0]
            hs = step_of(a)
            inputs = [f"y{i} + {hs} * k{j}_{i}" for i in range(dim)]
        else:
            inputs = [
                f"y{i} + h * (" + " + ".join(f"{_literal(a)} * k{j}_{i}" for j, a in terms) + ")"
                for i in range(dim)
            ]
        lines.append(f"{names(s)} = {call}{tup(inputs)}, u)")
    denominator = math.lcm(*(w.denominator for w in tableau.b))
    numerators = [int(w * denominator) for w in tableau.b]
    if denominator == 1:
        hd = "h"
    else:
        hd = "h_sum"
        lines.append(f"h_sum = h / {denominator}.0")
    groups = []  # [numerator, [stages]] runs of equal numerators, zero weights left out
    for s, n in enumerate(numerators):
        if n == 0:
            continue
        if groups and groups[-1][0] == n and n != 1:
            groups[-1][1].append(s)
        else:
            groups.append([n, [s]])

    def total(i):
        parts = []
        for n, stages in groups:
            inner = " + ".join(f"k{s}_{i}" for s in stages)
            parts.append(inner if n == 1 else f"{n}.0 * ({inner})")
        return " + ".join(parts)

    def scaled_sum(i):  # a single term needs no parentheses (the same operations either way)
        t = total(i)
        return t if len(groups) == 1 and len(groups[0][1]) == 1 and groups[0][0] == 1 else f"({t})"

    if compensated:  # y + (increment + c), and what that sum rounded away (module docstring)
        lines += [f"z{i} = {hd} * {scaled_sum(i)} + c{i}" for i in range(dim)]
        lines += [f"t{i} = y{i} + z{i}" for i in range(dim)]
        result, lost = (
            tup([f"t{i}" for i in range(dim)]),
            tup([f"z{i} - (t{i} - y{i})" for i in range(dim)]),
        )
        lines.append(
            f"return normalize({result}), {lost}" if project else f"return {result}, {lost}"
        )
        return lines
    result = tup([f"y{i} + {hd} * {scaled_sum(i)}" for i in range(dim)])
    lines.append(f"return normalize({result})" if project else f"return {result}")
    return lines


def _generated(scheme: type, dim: int, project: bool, params: bool) -> dict:
    """The namespace of ``scheme``'s generated step functions (see :class:`ExplicitRungeKutta`),
    made once per scheme class and layout. (Keyed by the class, which hashes by identity:
    hashing the tableau's fractions on every step would cost more than the step.)"""
    key = (scheme, dim, project, params)
    ns = _GENERATED.get(key)
    if ns is None:
        ns = _GENERATED[key] = _generate(scheme.tableau, scheme.name, dim, project, params)
    return ns


_GENERATED: dict = {}


def _generate(tableau: ButcherTableau, label: str, dim: int, project: bool, params: bool) -> dict:
    call = "f(P, " if params else "f("
    src = ""
    # each step twice: plain (``make``, ``pure``, ...) and compensated (``make_c``, ... taking
    # the compensation ``c`` after ``y`` and returning ``(y, c)``)
    for suffix, c_arg in (("", ""), ("_c", "c, ")):
        body = _body(tableau, dim, call, project, compensated=bool(suffix))
        if params and project:  # the pure projection takes its own parameters N
            body[-1] = body[-1].replace("return normalize(", "return normalize(N, ", 1)
        inner = "\n".join("        " + line for line in body)
        if params:  # f(P, y, u) [and normalize(N, y)]: bound to P [and N], or pure with them first
            bound, unpack = (
                ("f, P, normalize, N", "        P, N = PS\n") if project else ("f, P", "")
            )
            src += (
                f"def make{suffix}({bound}):\n    def step(y, {c_arg}u, h):\n"
                + inner
                + "\n    return step\n"
            )
            pure_args = "f, normalize" if project else "f"
            pure_params = "PS" if project else "P"
            src += (
                f"def pure{suffix}({pure_args}):\n    def step({pure_params}, y, {c_arg}u, h):\n"
                + unpack
                + inner
                + "\n    return step\n"
            )
            # the same step with its first stage given (k0 = f(P, y, u), evaluated by the caller:
            # a kernel that needs f at the new state anyway, for an event, passes it on)
            first = inner.replace(f"= {call}y, u)", "= k0", 1)
            src += (
                f"def pure_first{suffix}({pure_args}):\n    def step({pure_params}, y, {c_arg}k0, "
                "u, h):\n" + unpack + first + "\n    return step\n"
            )
        else:
            src += (
                f"def step{suffix}(f, normalize, y, {c_arg}u, h):\n"
                + "\n".join("    " + line for line in body)
                + "\n"
            )
            src += (
                f"def make{suffix}(f, normalize):\n    def step(y, {c_arg}u, h):\n"
                + inner
                + "\n    return step\n"
            )
    flavour = ("" if project else " no projection") + (" pure" if params else "")
    return generate(src, f"{label} dim={dim}{flavour}")


@cache
def _pure_step(scheme: type, dim: int, f, normalize, compensated: bool = False):
    """The pure step ``step(PS, y, u, h)`` of ``scheme`` for the pure vector field ``f`` (and the
    pure projection ``normalize``, or ``None``); one function per combination, as compiled
    kernels key on it. ``compensated``: ``step(PS, y, c, u, h) -> (y, c)``."""
    ns = _generated(scheme, dim, normalize is not None, True)
    name = "pure_c" if compensated else "pure"
    return ns[name](f) if normalize is None else ns[name](f, normalize)


@cache
def _pure_first_step(scheme: type, dim: int, f, normalize, compensated: bool = False):
    """:func:`_pure_step` with the first stage given: ``step(PS, y, k0, u, h)`` (compensated:
    ``step(PS, y, c, k0, u, h) -> (y, c)``)."""
    ns = _generated(scheme, dim, normalize is not None, True)
    name = "pure_first_c" if compensated else "pure_first"
    return ns[name](f) if normalize is None else ns[name](f, normalize)


@dataclass(frozen=True)
class ExplicitRungeKutta(Integrator):
    """An explicit Runge-Kutta scheme: a subclass sets ``name``, ``tableau``, ``order``,
    ``evaluations`` (its stages) and ``region``; the step is generated from the tableau."""

    tableau: ClassVar[ButcherTableau]

    def step(self, system, y, u, h):
        return _generated(type(self), len(y), True, False)["step"](
            system.rhs, system.normalize, y, u, h
        )

    def _overridden(self) -> bool:
        return type(self).step is not ExplicitRungeKutta.step  # a subclass that changes step

    def bind(self, system, dim, compensated=False):
        if self._overridden():
            return super().bind(system, dim, compensated)
        make = "make_c" if compensated else "make"
        pure = system.kernel_rhs
        if (
            pure is not None
        ):  # the pure vector field (and projection): the same step the kernel runs
            f, params = pure
            project = system.kernel_normalize
            if project is None:
                return _generated(type(self), dim, False, True)[make](f, params)
            return _generated(type(self), dim, True, True)[make](f, params, *project)
        return _generated(type(self), dim, system.needs_projection, False)[make](
            system.rhs, system.normalize
        )

    def kernel_step(self, system, compensated=False):
        return self._pure(system, _pure_step, compensated)

    def kernel_step_first_stage(self, system, compensated=False):
        """``(step, PS)`` with ``step(PS, y, k0, u, h)`` equal to :meth:`kernel_step`'s step given
        its first stage ``k0 = f(y, u)`` (every explicit scheme's first stage is the vector field
        at ``y``), or ``None``; ``compensated``: ``step(PS, y, c, k0, u, h) -> (y, c)``."""
        return self._pure(system, _pure_first_step, compensated)

    def _pure(self, system, flavour, compensated=False):
        """``(flavour's step of the system's pure parts, PS)``, or ``None`` without them."""
        pure = system.kernel_rhs
        if pure is None or self._overridden():
            return None
        f, params = pure
        project = system.kernel_normalize
        if project is None:
            return flavour(type(self), system.dim, f, None, compensated), params
        normalize, n_params = project
        return flavour(type(self), system.dim, f, normalize, compensated), (params, n_params)


@dataclass(frozen=True)
class Euler(ExplicitRungeKutta):
    """Forward Euler: first order, one rhs call; drifts in every invariant and is unstable
    for large ``|Omega| h`` (docs/physics.md §4). The cheapest baseline, not a recommendation."""

    name = "euler"
    tableau = ButcherTableau(a=((),), b=(1,), c=(0,))
    order = 1
    evaluations = 1
    # No stability interval on the imaginary axis: a rotation grows by sqrt(1 + (lambda h)^2)
    # a step (0.5 % at 0.1), by at most exp(lambda^2 h dt / 2) a period (1 % at 0.02); on the
    # negative real axis stable for |lambda h| <= 2.
    region = StepRegion(
        rotation=0.1,
        growth=0.02,
        dissipation=2.0,
        reason="accuracy bounds: no stability interval on the imaginary axis; real-axis interval 2",
    )
    # the measured constant rounded up (`rbenvs bench accuracy --tolerance` prints it); theory
    # 1/2: the amplitude grows by z^2 / 2 a step
    error_constant = 0.501


@dataclass(frozen=True)
class RK4(ExplicitRungeKutta):
    """Classical fourth-order Runge-Kutta, four rhs calls; invariants drift slowly."""

    name = "rk4"
    tableau = ButcherTableau(
        a=((), (Fraction(1, 2),), (0, Fraction(1, 2)), (0, 0, 1)),
        b=(Fraction(1, 6), Fraction(1, 3), Fraction(1, 3), Fraction(1, 6)),
        c=(0, Fraction(1, 2), Fraction(1, 2), 1),
    )
    order = 4
    evaluations = 4
    # Stability interval 2 sqrt(2) = 2.83 on the imaginary axis (at 1.0 a rotation's amplitude
    # and phase errors are 0.61 % and 0.56 % a step) and 2.78 on the negative real axis.
    region = StepRegion(
        rotation=1.0,
        dissipation=2.78,
        reason="imaginary-axis interval 2.83 (1.0 kept: 0.6 % amplitude error a step), "
        "real-axis interval 2.78",
    )
    # the measured constant rounded up (`rbenvs bench accuracy --tolerance` prints it); theory
    # 1/120: the phase lags by z^5 / 120 a step
    error_constant = 0.00834
    # |R(i z)| = 1 - z^6 / 144 + ...: the amplitude's error is an order above the phase's
    error_in_phase = True
    # following a stiff mode ds/dt = -lambda (s - phi) driven at frequency w (phi ~ exp(i w t)),
    # rk4's periodic solution errs by c(lambda h) (lambda h)^2 (w h)^2 of phi, c rising with lambda
    # h to 0.02022 at lambda h = 1.39 (half the real-axis interval, the largest a friction guard
    # allows); computed from the stage equations in tests/test_tolerance.py. tolerance= counts a
    # driven stiff mode's error with it (GuardRates.dissipation_share: the tippe top's slip).
    forced_error_constant = 0.0203

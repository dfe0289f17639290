"""What every family of checks shares: the :class:`Check` row, the round-off level and the rule
that scales a scheme's tolerance to another simulator's step."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = [
    "Check",
    "ROUND_OFF",
    "RATE_TOL",
    "MOMENTUM_BOUND",
    "ENERGY_BOUND",
    "ANGLE_BOUND",
    "worst",
    "not_applicable",
    "reference_scheme",
    "scaled_tolerance",
]

ROUND_OFF = 1e-13  # relative; for the invariants an integrator declares it conserves


@dataclass
class Check:
    """One row of the table: ``passed`` when ``|measured - predicted| <= tolerance`` (divided by
    ``|predicted|`` when ``relative``). ``case`` holds what it takes to replay the row. A row
    whose check does not apply to the simulator (``applies`` false) carries the ``reason``,
    reads ``n/a`` and fails nothing."""

    system: str
    integrator: str
    check: str
    predicted: float
    measured: float
    tolerance: float
    relative: bool = False  # compare |measured - predicted| / |predicted|
    case: dict = field(default_factory=dict)
    applies: bool = True
    reason: str = ""

    @property
    def error(self) -> float:
        """``|measured - predicted|`` (relative when ``relative``); ``nan`` if not finite."""
        if not (math.isfinite(self.measured) and math.isfinite(self.predicted)):
            return math.nan
        err = abs(self.measured - self.predicted)
        if self.relative:
            err /= abs(self.predicted)
        return err

    @property
    def passed(self) -> bool:
        if not self.applies:
            return True
        err = self.error
        return bool(math.isfinite(err) and err <= self.tolerance)

    @property
    def result(self) -> str:
        """``PASS``, ``FAIL`` or ``n/a``."""
        return "n/a" if not self.applies else "PASS" if self.passed else "FAIL"


def not_applicable(system: str, simulator: str, checks, reason: str) -> list[Check]:
    """``n/a`` rows for the named ``checks`` a simulator cannot run, with the ``reason``."""
    return [
        Check(system, simulator, name, math.nan, math.nan, math.nan, applies=False, reason=reason)
        for name in checks
    ]


def worst(candidates: list[Check]) -> Check:
    """The case closest to (or farthest beyond) its tolerance; a non-finite one first: the
    row a table of random cases shows for one check."""

    def badness(c):
        err = c.error
        if not math.isfinite(err):
            return math.inf
        if c.tolerance > 0:
            return err / c.tolerance
        return math.inf if err > 0 else 0.0

    return max(candidates, key=badness)


# The tolerance rule for a simulator at its own step (docs/verification.md, "Any simulator"): the
# rows of a theorem's behaviour (a growth rate, a threshold, stability, a final tilt) keep their
# tolerance whatever the step; the accuracy rows (an exact solution, an invariant's drift), which
# rbenvs' integrators meet at their verify steps with tolerances set from their order, take the
# tolerance of rbenvs' scheme of the simulator's declared order, scaled from that scheme's step to
# the simulator's by the order, (omega dt / omega h)^p, and never above the row's physical bound
# (below), plus round-off.
#
# The physical bounds. The behaviour rows hold a rate (a growth rate, a precession rate, the size
# of an orbit) to RATE_TOL relative. The rates of a rotating body scale with its momenta (|Omega|
# = |Pi|/I) and with the square root of its energy: an engine whose momentum-like invariant (|Pi|,
# Pi.Gamma, Jellett's J, an error of the state relative to its momentum) drifts by more than
# RATE_TOL, or whose energy drifts by more than 2 RATE_TOL, has moved the body's rates by more than
# the theorems' rows allow, whatever its order promises at its step. A tilt that should be held is
# held to the bound of a bounded tilt, ANGLE_BOUND. So an order-1 engine at a step far beyond
# Euler's verify step, whose order-scaled bound would promise nothing, is held to these.
RATE_TOL = 0.02  # relative: the behaviour rows' tolerance on a rate
MOMENTUM_BOUND = RATE_TOL  # relative drift of |Pi|, Pi.Gamma, J; a state error relative to |Pi|
ENERGY_BOUND = 2.0 * RATE_TOL  # relative drift of an energy (quadratic in the rates)
ANGLE_BOUND = 1e-2  # rad: a tilt held (the upright heavy top's bound of a bounded tilt)


def reference_scheme(order: int) -> str:
    """rbenvs' integrator whose verify tolerances stand for a simulator of declared ``order``:
    ``rk4`` from order 4, else ``euler`` (a second-order engine is held to first order)."""
    return "rk4" if order >= 4 else "euler"


def scaled_tolerance(
    tolerance: float, step: float, reference_step: float, order: int, steps: int, bound: float
) -> float:
    """``tolerance`` (the reference scheme's at ``reference_step``) at ``step``, both as ``omega h``
    of the same run: ``min(tolerance (step / reference_step)^p, bound)`` with ``p`` the reference
    scheme's order and ``bound`` the row's physical bound (:data:`MOMENTUM_BOUND`,
    :data:`ENERGY_BOUND`, :data:`ANGLE_BOUND`, :data:`RATE_TOL`), plus ``ROUND_OFF sqrt(steps)``."""
    p = 4 if reference_scheme(order) == "rk4" else 1
    return min(tolerance * (step / reference_step) ** p, bound) + ROUND_OFF * math.sqrt(
        max(steps, 1)
    )

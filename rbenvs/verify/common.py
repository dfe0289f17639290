"""What every family of checks shares: the :class:`Check` row, the round-off level and the rule
that scales a scheme's tolerance to another simulator's step."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = ["Check", "ROUND_OFF", "worst", "not_applicable", "reference_scheme", "scaled_tolerance"]

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
    return [Check(system, simulator, name, math.nan, math.nan, math.nan, applies=False, reason=reason) for name in checks]


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
# the simulator's by the order, (omega dt / omega h)^p, plus round-off.
def reference_scheme(order: int) -> str:
    """rbenvs' integrator whose verify tolerances stand for a simulator of declared ``order``:
    ``rk4`` from order 4, else ``euler`` (a second-order engine is held to first order)."""
    return "rk4" if order >= 4 else "euler"


def scaled_tolerance(tolerance: float, step: float, reference_step: float, order: int, steps: int) -> float:
    """``tolerance`` (the reference scheme's at ``reference_step``) at ``step``, both as ``omega h``
    of the same run: ``tolerance (step / reference_step)^p`` with ``p`` the reference scheme's
    order, plus ``ROUND_OFF sqrt(steps)``."""
    p = 4 if reference_scheme(order) == "rk4" else 1
    return tolerance * (step / reference_step) ** p + ROUND_OFF * math.sqrt(max(steps, 1))

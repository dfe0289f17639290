"""What every family of checks shares: the :class:`Check` row and the round-off level."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = ["Check", "ROUND_OFF", "worst"]

ROUND_OFF = 1e-13  # relative; for the invariants an integrator declares it conserves


@dataclass
class Check:
    """One row of the table: ``passed`` when ``|measured - predicted| <= tolerance`` (divided by
    ``|predicted|`` when ``relative``). ``case`` holds what it takes to replay the row."""

    system: str
    integrator: str
    check: str
    predicted: float
    measured: float
    tolerance: float
    relative: bool = False  # compare |measured - predicted| / |predicted|
    case: dict = field(default_factory=dict)

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
        err = self.error
        return bool(math.isfinite(err) and err <= self.tolerance)


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

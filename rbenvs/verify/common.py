"""What every family of checks shares: the :class:`Check` row and the round-off level."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = ["Check", "ROUND_OFF"]

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

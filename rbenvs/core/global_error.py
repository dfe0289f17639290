"""The global error of an episode, estimated by a companion run (``tolerance_check=``).

:mod:`rbenvs.core.guard` bounds the error each period *commits*. A motion that is unstable by
its own theorem (a tippe top that inverts, a top below its critical spin, a spin near the
intermediate axis) amplifies errors already made, by a factor no local estimate knows in
advance, so the error at the end of an episode can pass the tolerance although every period
met its share. The classical remedy is Richardson's: a second solution of the same problem with
a known ratio of steps, whose difference from the first is a multiple of the first's global
error, amplification included (it rests on the asymptotic expansion of the global error,
``y_h(t) - y(t) = e_p(t) h^p + O(h^(p+1))`` with ``e_p`` carried by the linearised flow: Hairer,
Norsett and Wanner, *Solving Ordinary Differential Equations I*, 2nd ed., Springer 1993,
section II.8; docs/physics.md's references).

Here every period takes an even count ``n`` of steps ``h`` (the guard's count, plus one where
it is odd), and the companion starts with the state at every reset and runs each control period
under the same control with ``n / 2`` steps ``2 h``. A scheme of order ``p`` commits the local
error ``c h^(p+1)`` per step, so the companion's period commits ``2^p`` times the main run's;
while both are in the asymptotic range their difference ``D`` is ``2^p - 1`` times the main
run's global error, carried by the same linearised flow, amplification included:
``E = D / (2^p - 1)``, the classical estimate, exact up to the next order's share. Reported
(``info["global_error_estimate"]``) is ``MARGIN = 1.25`` times it: measured against the free
body's exact solution (moments (2, 1.5, 1), 5 rad/s, a start 0.002 off the separatrix and two
others, 400 periods, tolerances 1e-3 to 1e-9) the classical estimate is 0.88 to 2.0 times the
error, against DOP853 on a tippe top through its rise (150 rad/s, from rest, at 1e-6) 1.3 to
1.8 times; with the margin it is above the error, and at most 3 times it, on every period
measured (``tests/test_global_error.py``: the free body and the tippe top that hops; ``rbenvs
verify``'s tolerance rows). A ratio that changed from period to period would weight the
periods' errors unequally, and errors that cancel over an orbit, such as a free body's energy
error near its separatrix, would not cancel in ``D``: measured, an estimate a third of the
error; hence the even counts.

``D`` is measured as :mod:`rbenvs.bench.tolerance` measures the error against its reference:
the largest over the state's blocks (:func:`tolerance_blocks`) of ``|y_b - yc_b| / |y_b|``.
Everything here works on one state (floats) and on a batch (arrays).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["MARGIN", "tolerance_blocks", "companion_ratio", "relative_difference", "GlobalErrorCheck"]

# the reported estimate over the classical one (its next order's share: the module docstring)
MARGIN = 1.25


def tolerance_blocks(system) -> tuple:
    """The ``(start, stop)`` blocks of the state over which a tolerance is measured: every block
    of the layout, less a hybrid system's horizontal position (it drifts along the table: its
    size is no scale of the motion) and its contact flags and hop counts (counts, not
    quantities)."""
    return tuple(tuple(span) for name, span in system.layout.items() if not (system.hybrid and name in ("position", "contact", "hops")))


def companion_ratio(p: float) -> float:
    """``2^p - 1``: the companion's global error over the main run's, less one (order ``p``)."""
    return 2.0 ** float(p) - 1.0


def relative_difference(blocks, y, yc):
    """``max_b |y_b - yc_b| / |y_b|`` over ``blocks`` (a block of norm 0 in both: 0); one state
    (a float) or a batch (an array)."""
    out = 0.0
    for lo, hi in blocks:
        d2 = s2 = 0.0
        for i in range(lo, hi):
            d = y[i] - yc[i]
            d2 = d2 + d * d
            s2 = s2 + y[i] * y[i]
        if isinstance(d2, float):
            r = 0.0 if d2 == 0.0 else (math.sqrt(d2 / s2) if s2 > 0.0 else math.inf)
            out = r if r > out else out
        else:
            with np.errstate(divide="ignore", invalid="ignore"):
                r = np.where(d2 == 0.0, 0.0, np.where(s2 > 0.0, np.sqrt(d2 / np.where(s2 > 0.0, s2, 1.0)), np.inf))
            out = np.maximum(out, r)
    return out


class GlobalErrorCheck:
    """One env's (or one batch's) companion: its state and the periods it has run.
    :meth:`restart` at a reset (rows ``mask`` of a batch); :meth:`period` after each period."""

    __slots__ = ("engine", "blocks", "ratio", "yc", "periods")

    def __init__(self, engine):
        self.engine = engine
        self.blocks = tolerance_blocks(engine.system)
        self.ratio = companion_ratio(engine.integrator.order)
        self.yc = None
        self.periods = 0

    def restart(self, y, mask=None):
        """The companion starts at ``y`` (a batch: at the rows ``mask`` of ``y``, or all)."""
        if mask is None or self.yc is None:
            self.yc = y
            self.periods = np.zeros(len(y[0]), dtype=np.int64) if isinstance(y[0], np.ndarray) else 0
            return
        self.yc = tuple(np.where(mask, c, cc) for c, cc in zip(y, self.yc))
        self.periods = np.where(mask, 0, self.periods)

    def period(self, y, u, n):
        """After a period that took ``y``'s run ``n`` (even) steps under ``u``: the companion's
        period, and the global error estimate of ``y``."""
        self.yc = self.engine.companion(self.yc, u, n)
        self.periods = self.periods + 1
        return MARGIN * relative_difference(self.blocks, y, self.yc) / self.ratio

"""The measured check of the step controller (:mod:`rbenvs.stepsize.controller`).

``tolerance_check=True`` (:class:`GlobalErrorCheck`). The controller's error bound
holds the error each period *commits*. A motion that is unstable by
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
(``info["global_error_estimate"]``) is ``MARGIN = 1.25`` times it, and where it passes the
tolerance the episode ends as a numerical failure at the last state within it
(``tests/test_global_error.py`` and ``rbenvs verify``'s tolerance rows check the estimate
against the free body's exact solution and a DOP853 reference of the tippe top that hops). A
ratio that changed from period to period would weight the periods' errors unequally, and errors
that cancel over an orbit, such as a free body's energy error near its separatrix, would not
cancel in ``D``: hence the even counts.

Roundoff the motion amplifies (near the separatrix) enters ``D`` at ``1 / (2^p - 1)`` of its
size, but the check ends such an episode where the steps' error passes the tolerance, before the
roundoff does: ``rbenvs bench accuracy --floor`` (20 runs 0.0001-0.01 rad/s off the intermediate
axis, tolerances 1e-8 to 1e-12, against mpmath's Taylor series) is within on every period
returned. The runs (the main run's and the companion's) are the engine's
(:meth:`rbenvs.core.period.Period.companion`), compiled where numba is installed
(:class:`rbenvs.compiled.CheckedRuns`, the float path's bits); ``D`` is measured as
:mod:`rbenvs.bench.tolerance` measures the error against its reference: the largest over the
state's blocks (:func:`tolerance_blocks`) of ``|y_b - yc_b| / |y_b|``, on one state (floats) or
a batch (arrays).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "MARGIN",
    "GlobalErrorCheck",
    "require_tolerance_check",
    "tolerance_blocks",
    "companion_ratio",
    "companion_steps",
    "relative_difference",
    "inaccurate_text",
]

# the reported estimate over the classical one (its next order's share: the module docstring)
MARGIN = 1.25


def require_tolerance_check(check, tolerance):
    """``tolerance_check=``: ``False`` or ``True`` (a companion run checks the episode's global
    error against ``tolerance=``, which it then needs)."""
    if isinstance(check, str) and check == "refine":
        raise ValueError(
            "tolerance_check='refine' was removed (2026-11-29: each replay ran the episode again "
            "from its start); use "
            "tolerance_check=True, which ends the episode, flagged, where the estimate passes the "
            "tolerance, with a tighter "
            "tolerance= to hold it longer"
        )
    if not (check is True or check is False):
        raise ValueError(
            "tolerance_check must be False or True (a companion run checks the episode's global "
            "error and ends the episode "
            f"where it passes the tolerance), got {check!r}"
        )
    if check and tolerance is None:
        raise ValueError(
            "tolerance_check=True needs tolerance= (the relative error per episode the global "
            "error estimate is checked against)"
        )
    return check


def tolerance_blocks(system) -> tuple:
    """The ``(start, stop)`` blocks of the state over which a tolerance is measured: every block
    of the layout, less a hybrid system's horizontal position (it drifts along the table: its
    size is no scale of the motion) and its contact flags and hop counts (counts, not
    quantities)."""
    return tuple(
        tuple(span)
        for name, span in system.layout.items()
        if not (system.hybrid and name in ("position", "contact", "hops"))
    )


def companion_ratio(p: float) -> float:
    """``2^p - 1``: the companion's global error over the main run's, less one (order ``p``)."""
    return 2.0 ** float(p) - 1.0


def companion_steps(n):
    """The steps the companion takes beside a checked period of ``n`` (even) steps: ``n / 2`` (an
    int, or an int array)."""
    return n // 2


def block_sums(y, yc, lo, hi):
    """``(|y_b - yc_b|^2, |y_b|^2)`` over the components ``lo:hi`` (floats or arrays: the same
    operations in the same order)."""
    d2 = s2 = 0.0
    for i in range(lo, hi):
        d = y[i] - yc[i]
        d2 = d2 + d * d
        s2 = s2 + y[i] * y[i]
    return d2, s2


def block_difference(blocks, y, yc):
    """:func:`relative_difference` of one state (floats). A block whose difference is NaN (a
    companion that went non-finite beside a finite run)
    counts as ``inf``: the check cannot vouch for the state, so its estimate passes any
    tolerance."""
    out = 0.0
    for lo, hi in blocks:
        d2, s2 = block_sums(y, yc, lo, hi)
        r = 0.0 if d2 == 0.0 else (math.sqrt(d2 / s2) if s2 > 0.0 else math.inf)
        r = r if r == r else math.inf
        out = r if r > out else out
    return out


def relative_difference(blocks, y, yc):
    """``max_b |y_b - yc_b| / |y_b|`` over ``blocks`` (a block of norm 0 in both: 0; a NaN
    difference: ``inf``); one state (a float: :func:`block_difference`) or a batch (an array,
    the same rule element by element)."""
    if not isinstance(y[0], np.ndarray):
        return block_difference(blocks, y, yc)
    out = 0.0
    for lo, hi in blocks:
        d2, s2 = block_sums(y, yc, lo, hi)
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.where(
                d2 == 0.0,
                0.0,
                np.where(s2 > 0.0, np.sqrt(d2 / np.where(s2 > 0.0, s2, 1.0)), np.inf),
            )
        out = np.maximum(out, np.where(r == r, r, np.inf))
    return out


class GlobalErrorCheck:
    """One env's (or one batch's) companion: its state, its compensation and the periods it has
    run. :meth:`restart` at a reset (rows ``mask`` of a batch); :meth:`period` after each period;
    :meth:`step_one` a single env's checked step."""

    __slots__ = ("engine", "blocks", "ratio", "runs", "periods")

    def __init__(self, engine):
        self.engine = engine
        self.blocks = tolerance_blocks(engine.system)
        self.ratio = companion_ratio(engine.integrator.order)
        self.runs = None  # the companion's state and compensation (yc, cc)
        self.periods = 0

    def restart(self, y, mask=None):
        """The companion starts at ``y`` (a batch: at the rows ``mask`` of ``y``, or all)."""
        if mask is None or self.runs is None:
            self.runs = (y, self.engine.fresh_comp)
            self.periods = (
                np.zeros(len(y[0]), dtype=np.int64) if isinstance(y[0], np.ndarray) else 0
            )
            return
        yc, cc = self.runs
        yc = tuple(np.where(mask, c, r) for c, r in zip(y, yc))
        if cc is not None:
            cc = tuple(np.where(mask, 0.0, c) for c in cc)
        self.runs = (yc, cc)
        self.periods = np.where(mask, 0, self.periods)

    def period(self, y, u, n):
        """After a period that took ``y``'s run ``n`` (even) steps under ``u``: the companion's
        period, and the global error estimate of ``y``, ``MARGIN D / (2^p - 1)`` (floats, or
        arrays for a batch)."""
        self.runs = self.engine.companion(self.runs[0], u, n, self.runs[1])
        self.periods = self.periods + 1
        return MARGIN * relative_difference(self.blocks, y, self.runs[0]) / self.ratio

    def step_one(self, y0, a, plain):
        """The engine's :meth:`~rbenvs.core.step.Engine.step_one` with the companion's period after
        it (the single env's step, and a sub-env's in a vector env whose sub-envs step models of
        their own): ``info["global_error_estimate"]``; where the estimate passes the tolerance, the
        episode ends as a numerical failure at ``y0``."""
        engine = self.engine
        comp0 = engine.comp  # (the run's compensation at y0: kept with y0 where the period is not)
        out = engine.step_one(y0, a, plain)
        info = out[4]
        if info["numerical_failure"]:
            return out
        n = int(round(engine.dt / info["internal_step"]))
        runs0 = self.runs
        e = self.period(out[0], out[5], n)
        if e > engine.tolerance:  # the companion and the run stay with the state kept
            self.runs, self.periods = runs0, self.periods - 1
            return engine.inaccurate_one(
                y0, a, info["internal_step"], plain, e, self.periods + 1, comp0
            )
        info["global_error_estimate"] = e
        return out


def inaccurate_text(estimate, periods, tolerance, dt) -> str:
    """Why an episode ended where its global error ``estimate`` passed ``tolerance`` after
    ``periods`` control periods of ``dt``, and what holds it longer (the warning's words)."""
    return (
        f"the global error estimate {float(estimate):.3g} passed tolerance={tolerance!r} "
        f"after {int(periods)} periods "
        f"({int(periods) * dt:.6g} s; tolerance_check: a companion run at twice the step "
        "measures the error the state "
        "carries, errors the motion amplified included, which the steps' estimate does not "
        "budget for; more steps per period "
        "hold it longer: a tighter tolerance= or substeps= (the least count), and 'rbenvs "
        "bench accuracy --tolerance' shows "
        f"the counts that hold each shipped scene)"
    )

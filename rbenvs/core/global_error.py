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

**Holding the tolerance** (``tolerance_check="refine"``): instead of ending the episode where
the estimate passes the tolerance, the check replays the episode from its start under the
controls that acted, with every period's step count (the guard's) multiplied by a factor
``f``, companion included, and then takes the period again. The error falls like ``f^-p``
(measured on the tippe top that hops: doubling every count cut its error 16-fold), and the
errors a motion amplifies were made early (the same top: refining the periods before its slip
leaves the friction band cut its error 6-fold, refining those after it none; an error made at
its start is some 20000 times larger at its peak), so only a replay from the start takes them
back. ``f`` (:func:`refinement`) aims at an eighth of the tolerance at the horizon with the
estimate grown in proportion to the periods run, ``(8 E / tol max(1, N / k))^(1/p)`` after
``k`` of ``N`` periods, at least :data:`MIN_REFINEMENT`; a replayed period whose estimate still
passes raises ``f`` again from there, at most :data:`MAX_REPLAYS` times a period. More steps
make every period's error smaller, so a replay that passes the tolerance no later than the run
did, with no smaller an estimate, says the estimate is not the steps' error: roundoff the
motion amplified (the free body 0.002 off its separatrix: rk4 at 400 fixed substeps ends 8.5e-10
from the exact solution over 20 s, at 800 4.2e-9), or steps outside the scheme's asymptotic
range; the refinement then stops. There, and where the factor would ask more than
``MAX_INTERNAL_STEPS`` steps or the replay ends earlier than the run did (a terminal event, a
non-finite state), the episode ends as with ``True``, saying so. The observations already
returned stay as they were: each was within the tolerance by the estimate when it was returned.

**Roundoff** (the rounding twins). ``D`` sees the steps' ``h^p`` error; roundoff it counts at
``1 / (2^p - 1)``, and near a free body's separatrix the motion amplifies the roundoff of every
passage by the saddle until it passes the steps' error: from 0.0001 rad/s off the intermediate
axis (the body (2, 1.5, 1) at 5 rad/s, an mpmath Taylor solution at 45 digits as reference) the
runs at ``h`` and ``2 h`` end equally far from it after the error's node near period 250 (their
errors in ratio 0.7, not 16), and ``"refine"`` ran that episode to its end ten times outside 1e-9.
Two runs beside the companion, its *rounding twins*, take the companion's steps with every
increment ``d`` off by a unit roundoff, ``+-2^-53 d`` (:func:`rounding_twin`: carried in the
compensation, the sign from mantissa bit 21 of ``d`` for one twin and bit 17 for the other, so
that floats, arrays and compiled code agree bit for bit); a twin's difference from the companion
is roundoff alone, amplified as the motion amplifies the runs' own, and with ``D_t`` the larger
of the two the estimate is ``MARGIN (D / (2^p - 1) + ROUNDOFF_WEIGHT D_t)``. It is a model of
roundoff, not a bound: each twin is one sample of an amplification that varies by orders from one
realization of the rounding to the next (against an 80-bit replay of a run's counts one twin's
difference was 1/24 to 6 times that run's roundoff), and the larger of two samples falls short
less often. More steps do not take the motion's
roundoff down, so ``"refine"`` gives up where the estimate's roundoff part is at least
:data:`ROUNDOFF_SHARE` of the tolerance. Measured (docs/integrators.md "Roundoff"): 0.0001 rad/s
off the error ends 1.28 times ``D / 15 + D_t``; over four starts 0.0001 to 0.01 rad/s off and
tolerances 1e-8 to 1e-12 (``rbenvs bench accuracy --floor``, against mpmath's Taylor series)
``"refine"`` ran 8 of the 20 episodes outside the tolerance without a twin (up to 48 times),
1 with one (2.4 times, ended at period 352) and none with two (and on six more starts, 60 rows,
1 with one twin, none with two); ``True`` is within on all of them with and without. Each twin
costs the check half the main run's steps again.

``D`` is measured as :mod:`rbenvs.bench.tolerance` measures the error against its reference:
the largest over the state's blocks (:func:`tolerance_blocks`) of ``|y_b - yc_b| / |y_b|``.
Everything here works on one state (floats) and on a batch (arrays). The runs themselves (the
main run's, the companion's, the twins', a replay's) are the engine's
(:meth:`rbenvs.core.step.Engine.companion`), compiled where numba is installed
(:class:`rbenvs.compiled.CheckedRuns`, the float path's bits).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from ..jit import compiled_form, float_bits, jitable
from ..rotations import select

__all__ = ["MARGIN", "AIM", "MIN_REFINEMENT", "MAX_REPLAYS", "UNIT_ROUNDOFF", "ROUNDOFF_WEIGHT", "ROUNDOFF_SHARE", "require_tolerance_check", "tolerance_blocks",
           "companion_ratio", "companion_steps", "TWIN_BITS", "rounding_twin", "rounding_twin_term", "rounding_twin_first", "relative_difference", "refinement", "GlobalErrorCheck"]

# the reported estimate over the classical one (its next order's share: the module docstring)
MARGIN = 1.25
# a replay multiplies the step counts by at least this (an estimate just past the tolerance)
MIN_REFINEMENT = 1.1
# a replay aims at the tolerance over this at the horizon, the estimate grown in proportion to the
# periods: an amplifying motion grows it faster than that, and a replay that falls short costs a
# replay more (the hopping tippe top, 180 rad/s, whose error peaks a third of a second after the
# first crossing: aiming at half the tolerance took two replays, 3.2-4.2 times the cheapest fixed
# steps; at an eighth, one)
AIM = 8.0
# at most this many replays for one period; past them the episode ends as with tolerance_check=True
MAX_REPLAYS = 4
# float64's unit roundoff: the rounding twins' increments are off by it (relative), in a sign
# the increment's own low bits pick
UNIT_ROUNDOFF = 2.0**-53
# refine gives up where the estimate's roundoff part is at least this share of the tolerance:
# more steps take the steps' error down, not the roundoff a motion amplified (near the saddle a
# run's rounding repeats itself step after step), so a replay aimed within could not get there
ROUNDOFF_SHARE = 0.5
# the estimate counts the rounding twins' (larger) difference this many times: the main run takes
# twice a twin's steps, each rounding several operations (measured: its error ended 1.28 times the
# truncation estimate plus the twin's difference where roundoff dominated; the module docstring)
ROUNDOFF_WEIGHT = 2.0


def require_tolerance_check(check, tolerance, guard="subdivide"):
    """``tolerance_check=``: ``False``, ``True`` or ``"refine"``; either of the last two needs a
    tolerance (the global error estimate is checked against it), and ``"refine"`` the guard
    that subdivides (it takes more steps)."""
    if not (check is True or check is False or (isinstance(check, str) and check == "refine")):
        raise ValueError("tolerance_check must be False, True (a companion run checks the episode's global error and ends the episode "
                         f"where it passes the tolerance) or 'refine' (the episode is replayed with more steps there), got {check!r}")
    if check is not False and tolerance is None:
        raise ValueError(f"tolerance_check={check!r} needs tolerance= (the relative error per episode the global error estimate is checked against)")
    if check == "refine" and guard != "subdivide":
        raise ValueError(f"tolerance_check='refine' needs guard='subdivide' (it takes more steps per period), got guard={guard!r}")
    return check


def refinement(estimate, tolerance, periods, horizon, order):
    """The factor a replay multiplies the step counts by: ``(AIM E / tol max(1, N / k))^(1/p)``,
    at least :data:`MIN_REFINEMENT` (``E`` the estimate after ``k = periods`` of the ``N =
    horizon`` periods, ``p`` the order): an error falls like ``f^-p``, and one that grew over
    ``k`` periods may grow in proportion over the rest, and faster (:data:`AIM`)."""
    grown = AIM * float(estimate) / tolerance * max(1.0, horizon / max(periods, 1))
    f = grown ** (1.0 / float(order)) if math.isfinite(grown) else math.inf
    return f if f > MIN_REFINEMENT else MIN_REFINEMENT


def tolerance_blocks(system) -> tuple:
    """The ``(start, stop)`` blocks of the state over which a tolerance is measured: every block
    of the layout, less a hybrid system's horizontal position (it drifts along the table: its
    size is no scale of the motion) and its contact flags and hop counts (counts, not
    quantities)."""
    return tuple(tuple(span) for name, span in system.layout.items() if not (system.hybrid and name in ("position", "contact", "hops")))


def companion_ratio(p: float) -> float:
    """``2^p - 1``: the companion's global error over the main run's, less one (order ``p``)."""
    return 2.0 ** float(p) - 1.0


def companion_steps(n):
    """The steps the companion and its two rounding twins take beside a checked period of ``n``
    (even) steps: ``n / 2`` each (an int, or an int array)."""
    return 3 * (n // 2)


# the bit of an increment's mantissa that picks the sign of each twin's rounding error (the 21st
# and the 17th: far below what the step resolves, above what its own rounding touches): two twins,
# two samples of the roundoff the motion amplifies (one sample ran 2 of 100 refine episodes near the
# separatrix outside the tolerance, up to 2.4 times; the larger of two, none: docs/integrators.md)
TWIN_BITS = (2.0**21, 2.0**17)


@jitable
def rounding_twin_term(c, d, bit):
    """One component of a rounding twin's compensation after a step: ``c`` (the compensated
    step's) plus ``+-UNIT_ROUNDOFF d`` for the increment ``d``, the sign from the mantissa bit
    ``bit`` (a power of two, one of :data:`TWIN_BITS`) of ``d``; floats and compiled code (the
    checked period's compiled runs, :func:`rbenvs.compiled.run_kernel`), the same bits."""
    m = abs(math.frexp(d)[0]) * bit
    if m < bit and int(m) & 1:  # (a non-finite increment: either sign)
        return c + UNIT_ROUNDOFF * d
    return c + -(UNIT_ROUNDOFF * d)


@compiled_form(rounding_twin_term)
def _rounding_twin_term_bits(c, d, bit):
    """:func:`rounding_twin_term` compiled: the mantissa bit read from ``d``'s IEEE bits (a
    subnormal scaled by ``2^54`` first, exactly, as ``frexp`` normalises it) and the sign
    selected, not branched on: the same bits for every ``d`` (zero, subnormal, infinite, NaN
    included), and a batch loop of the twins' steps stays in SIMD registers (``frexp`` is a
    libm call per component)."""
    a = abs(d)
    s = select(a < 2.2250738585072014e-308, a * 18014398509481984.0, a)
    f = (float_bits(s) & 4503599627370495) | 4503599627370496  # (the significand 1.f times 2^52)
    odd = ((f // int(9007199254740992.0 / bit)) & 1) == 1  # (frexp's |m| bit is f bit / 2^53: the lowest bit of its integer part)
    e = UNIT_ROUNDOFF * d
    return c + select(odd & (a < math.inf), e, -e)


def rounding_twin(step_c, bit=TWIN_BITS[0]):
    """The compensated step ``step_c(y, c, u, h) -> (y, c)`` of the rounding twin: each
    increment ``d = y_new - y`` off by ``+-UNIT_ROUNDOFF d`` (carried in the compensation, so
    the next step adds it), the sign from ``d``'s own mantissa: a rounding error the size of
    the increment's own, pseudo-random along the run and the same bits on floats, on arrays and
    compiled (the single env's and the vector env's twins agree bit for bit)."""

    def step(y, c, u, h):
        y_new, c_new = step_c(y, c, u, h)
        if not isinstance(y_new[0], np.ndarray):
            return y_new, tuple(rounding_twin_term(ci, a - b, bit) for ci, a, b in zip(c_new, y_new, y))
        out = []
        for ci, a, b in zip(c_new, y_new, y):
            d = np.asarray(a - b, dtype=np.float64)
            odd = np.floor(np.abs(np.frexp(d)[0]) * bit) % 2.0 == 1.0
            out.append(ci + np.where(odd, UNIT_ROUNDOFF * d, -(UNIT_ROUNDOFF * d)))
        return y_new, tuple(out)

    return step


def rounding_twin_first(first_c, bit=TWIN_BITS[0]):
    """:func:`rounding_twin` for a step that takes its first stage, ``first_c(ps, y, c, k, u,
    h) -> (y, c)`` (the tippe top's, whose event's evaluation is the next first stage)."""
    twin = rounding_twin(lambda y, c, args, h: first_c(args[0], y, c, args[1], args[2], h), bit)
    return lambda ps, y, c, k, u, h: twin(y, c, (ps, k, u), h)


@jitable
def block_sums(y, yc, lo, hi):
    """``(|y_b - yc_b|^2, |y_b|^2)`` over the components ``lo:hi`` (floats or arrays: the same
    operations in the same order)."""
    d2 = s2 = 0.0
    for i in range(lo, hi):
        d = y[i] - yc[i]
        d2 = d2 + d * d
        s2 = s2 + y[i] * y[i]
    return d2, s2


@jitable
def block_difference(blocks, y, yc):
    """:func:`relative_difference` of one state (floats; compiled code runs it too). A block
    whose difference is NaN (a companion or twin that went non-finite beside a finite run)
    counts as ``inf``: the check cannot vouch for the state, so its estimate passes any tolerance."""
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
            r = np.where(d2 == 0.0, 0.0, np.where(s2 > 0.0, np.sqrt(d2 / np.where(s2 > 0.0, s2, 1.0)), np.inf))
        out = np.maximum(out, np.where(r == r, r, np.inf))
    return out


@jitable
def estimate_terms(blocks, ratio, y, yc, yt, ys):
    """``(estimate, roundoff)`` of one state ``y`` beside its companion ``yc`` and rounding twins
    ``yt``, ``ys`` (floats): ``MARGIN (D / ratio + ROUNDOFF_WEIGHT D_t)`` and its second term
    (:meth:`GlobalErrorCheck._estimate`'s rule; compiled code runs it too)."""
    d1, d2 = block_difference(blocks, yc, yt), block_difference(blocks, yc, ys)
    roundoff = MARGIN * ROUNDOFF_WEIGHT * (d1 if d1 > d2 else d2)
    return MARGIN * block_difference(blocks, y, yc) / ratio + roundoff, roundoff


@lru_cache(maxsize=None)
def estimate_loop(blocks, dim: int, ratio: float):
    """:func:`estimate_terms` over a batch as one compiled loop (:func:`rbenvs.jit.elementwise`
    over the components of the state, the companion and the twins), ``None`` without numba; a
    call returns ``None`` where it cannot run (the caller's numpy form then does)."""
    from ..jit import available, elementwise

    if not available():
        return None
    from .codegen import generate

    names = [f"{r}{j}" for r in "ycts" for j in range(dim)]
    comps = {r: "(" + "".join(f"{r}{j}, " for j in range(dim)) + ")" for r in "ycts"}
    code = (f"def terms({', '.join(names)}):\n"
            f"    return estimate_terms(BLOCKS, RATIO, {comps['y']}, {comps['c']}, {comps['t']}, {comps['s']})")
    fn = jitable(generate(code, f"estimate terms dim={dim}", {"estimate_terms": estimate_terms, "BLOCKS": blocks, "RATIO": float(ratio)})["terms"])
    return elementwise(fn, 4 * dim, 2)


class GlobalErrorCheck:
    """One env's (or one batch's) companion and rounding twin: their states and the periods
    they have run. :meth:`restart` at a reset (rows ``mask`` of a batch); :meth:`period` after
    each period; with ``refine`` (``tolerance_check="refine"``) also :meth:`record` of each
    period's control once it is kept, and :meth:`hold` where a period's estimate passes the
    tolerance."""

    __slots__ = ("engine", "blocks", "ratio", "runs", "periods", "roundoff", "refine", "y0", "controls", "first", "factor")

    def __init__(self, engine, refine=False):
        self.engine = engine
        self.blocks = tolerance_blocks(engine.system)
        self.ratio = companion_ratio(engine.integrator.order)
        # the companion's state and compensation (yc, cc) and its two rounding twins' (yt, ct, ys, cs)
        self.runs = None
        self.periods = 0
        self.roundoff = 0.0  # the last period's estimate's roundoff part (ROUNDOFF_WEIGHT times the twins' larger difference)
        self.refine = bool(refine)
        # with refine: the episode's start, the controls of its periods (a batch: one entry per
        # step, row i's from index first[i]) and the factor on the guard's counts
        self.y0, self.controls, self.first, self.factor = None, [], 0, 1.0

    def restart(self, y, mask=None):
        """The companion and its twins start at ``y`` (a batch: at the rows ``mask`` of ``y``, or all)."""
        if mask is None or self.runs is None:
            fresh = self.engine.fresh_comp
            self.runs = (y, fresh, y, fresh, y, fresh)
            batch = isinstance(y[0], np.ndarray)
            self.periods = np.zeros(len(y[0]), dtype=np.int64) if batch else 0
            self.roundoff = np.zeros(len(y[0])) if batch else 0.0
            if self.refine:
                self.y0, self.controls = (tuple(np.array(c, dtype=np.float64) for c in y) if batch else y), []
                self.first = np.zeros(len(y[0]), dtype=np.int64) if batch else 0
                self.factor = np.ones(len(y[0])) if batch else 1.0
                if not batch:
                    self.engine.step_factor = 1.0
            return
        states, comps = self.runs[0::2], self.runs[1::2]
        states = [tuple(np.where(mask, c, r) for c, r in zip(y, run)) for run in states]
        if comps[0] is not None:
            comps = [tuple(np.where(mask, 0.0, c) for c in comp) for comp in comps]
        self.runs = tuple(x for pair in zip(states, comps) for x in pair)
        self.periods = np.where(mask, 0, self.periods)
        self.roundoff = np.where(mask, 0.0, self.roundoff)
        if self.refine:
            self.y0 = tuple(np.where(mask, c, c0) for c, c0 in zip(y, self.y0))
            self.first = np.where(mask, len(self.controls), self.first)
            self.factor = np.where(mask, 1.0, self.factor)
            drop = int(self.first.min())
            if drop > 64 and 2 * drop > len(self.controls):  # (no row needs the oldest entries any more)
                del self.controls[:drop]
                self.first = self.first - drop

    def _advance(self, runs, u, n):
        """The companion's and its twins' period beside a main run's ``n`` steps under ``u``."""
        engine, out = self.engine, []
        for twin in range(len(runs) // 2):  # (0: the companion; 1, 2: its twins)
            out.extend(engine.companion(runs[2 * twin], u, n, runs[2 * twin + 1], twin=twin))
        return tuple(out)

    def _estimate(self, y, runs):
        """``(estimate, roundoff)`` of the main run's ``y`` beside the companion and its twins
        (``runs``; floats, or arrays for a batch): ``MARGIN (D / (2^p - 1) + ROUNDOFF_WEIGHT
        D_t)``, ``D_t`` the larger twin's difference, and its second term."""
        if not isinstance(y[0], np.ndarray):
            return estimate_terms(self.blocks, self.ratio, y, runs[0], runs[2], runs[4])
        # a batch: the same function element by element in one compiled loop where the runs are
        # compiled (numba installed, not compiled=False), else its numpy form below
        loop = estimate_loop(self.blocks, len(y), self.ratio) if self.engine.checked_runs is not None else None
        out = None if loop is None else loop(*y, *runs[0], *runs[2], *runs[4])
        if out is not None:
            return out
        d1, d2 = relative_difference(self.blocks, runs[0], runs[2]), relative_difference(self.blocks, runs[0], runs[4])
        larger = np.where(d1 > d2, d1, d2)  # (estimate_terms' rule)
        roundoff = MARGIN * ROUNDOFF_WEIGHT * larger
        return MARGIN * relative_difference(self.blocks, y, runs[0]) / self.ratio + roundoff, roundoff

    def period(self, y, u, n):
        """After a period that took ``y``'s run ``n`` (even) steps under ``u``: the companion's
        and its twins' period, and the global error estimate of ``y`` (:attr:`roundoff`: its
        roundoff part)."""
        self.runs = self._advance(self.runs, u, n)
        self.periods = self.periods + 1
        e, self.roundoff = self._estimate(y, self.runs)
        return e

    def step_one(self, y0, a, plain):
        """The engine's :meth:`~rbenvs.core.step.Engine.step_one` with the companion's period after
        it (``tolerance_check``: the single env's step, and a sub-env's in a vector env whose
        sub-envs step models of their own): ``info["global_error_estimate"]``; where the estimate
        passes the tolerance, the episode ends as a numerical failure at ``y0``, or, with
        ``"refine"``, is replayed with more steps (:meth:`hold`; ``info["step_factor"]``, the
        factor on the guard's counts, and ``info["replayed_steps"]``, the steps this step took
        beyond its period's own)."""
        engine = self.engine
        if self.refine:  # (the engine is made again, factor 1, when the env is copied or pickled)
            engine.step_factor = self.factor
        comp0 = engine.comp  # (the run's compensation at y0: kept with y0 where the period is not)
        out = engine.step_one(y0, a, plain)
        info = out[4]
        if info["numerical_failure"]:
            return out
        n = int(round(engine.dt / info["internal_step"]))
        runs0 = self.runs
        e = self.period(out[0], out[5], n)
        replayed = 0
        if e > engine.tolerance:
            # the companion, its twins and the run stay with the state kept; hold moves them on
            self.runs, self.periods, engine.comp = runs0, self.periods - 1, comp0
            held = None
            if self.refine:

                def redo(y, factor):  # (the period again from the replayed state, at engine.step_factor = factor)
                    again = engine.step_one(y, a, False)
                    if again[4]["numerical_failure"]:
                        return None, None, 0
                    return again, again[0], int(round(engine.dt / again[4]["internal_step"]))

                held, estimate, replayed = self.hold(e, out[5], redo, n + companion_steps(n))
            if held is None:
                engine.comp = comp0
                failed = engine.inaccurate_one(y0, a, info["internal_step"], plain, e, self.periods + 1, self.refine, self.roundoff)
                if self.refine:
                    failed[4].update(step_factor=self.factor, replayed_steps=replayed)
                return failed
            out, e = held, estimate
            info = out[4]
        info["global_error_estimate"], info["global_error_roundoff"] = e, self.roundoff
        if self.refine:
            self.record(out[5])
            info["step_factor"], info["replayed_steps"] = self.factor, replayed
        return out

    def record(self, u):
        """With ``refine``: the control of a period that was kept (a batch: every row's, one
        entry a step)."""
        if self.refine:
            self.controls.append(u)

    def hold(self, estimate, u, redo, spent, row=None):
        """A period under ``u`` whose estimate ``estimate`` passed the tolerance, held within it
        (``tolerance_check="refine"``): the factor raised (:func:`refinement`), the episode
        replayed from its start (:meth:`_replay`), and the period taken again by ``redo(y,
        factor) -> (result, y_new, n)`` from the replayed state (``result``: what the caller
        keeps, ``None`` where the period failed; ``n`` its steps), until its estimate is within,
        at most :data:`MAX_REPLAYS` times. ``row``: a batch's sub-env, whose episode is replayed
        on floats (the single env's steps, bit for bit; ``u`` then that row's floats). ``spent``:
        the steps the period's first try took, the companion's and the twins' included. Returns
        ``(result, estimate, steps)``, ``steps`` all those taken beyond the kept period's own
        (``n`` and :func:`companion_steps`), and leaves the companion, its twins and the factor
        with the result; ``result`` is ``None`` where the tolerance could not be held (the
        factor then stays as it was). With compensation (:attr:`rbenvs.core.step.Engine.step_c`)
        ``redo`` starts from the replayed run's: one state's in ``engine.comp`` (the single
        env's), a row's passed as ``redo(y, factor, comp)``."""
        engine, tol = self.engine, self.engine.tolerance
        if not float(self.roundoff if row is None else self.roundoff[row]) < ROUNDOFF_SHARE * tol:
            return None, estimate, int(spent)  # (roundoff: more steps do not take it down)
        if row is None:
            y0, controls, factor = self.y0, self.controls, self.factor
        else:
            y0 = tuple(float(c[row]) for c in self.y0)
            controls = [None if v is None else tuple(float(c[row]) if np.ndim(c) else float(c) for c in v) for v in self.controls[int(self.first[row]):]]
            factor = float(self.factor[row])
        kept = factor
        k, e, steps = len(controls) + 1, float(estimate), int(spent)
        for _ in range(MAX_REPLAYS):
            factor *= refinement(e, tol, k, engine.model.horizon, engine.integrator.order)
            if not math.isfinite(factor):
                break
            start, e_at, k_at, taken, roundoff = self._replay(y0, controls, factor)
            steps += taken
            if start is None:
                # a replayed period passed the tolerance; with more steps every period's error
                # is smaller, so a pass no later than the last one, no smaller, says the estimate
                # is not the steps' error (roundoff the motion amplified, a non-asymptotic step):
                # no factor holds it (and a non-finite one: an event or a state the run did not
                # meet; and one whose roundoff alone is a share of the tolerance)
                if not math.isfinite(e_at) or k_at < k or (k_at == k and e_at >= e) or not roundoff < ROUNDOFF_SHARE * tol:
                    break
                k, e = k_at, e_at
                continue  # the factor is raised from there
            (y, comp), runs = start
            if row is None:
                engine.step_factor = factor  # (the single env's period reads it)
                if comp is not None:
                    engine.comp = comp
                result, y_new, n = redo(y, factor)
            else:
                result, y_new, n = redo(y, factor, comp)
            if result is None:
                break
            runs = self._advance(runs, u, n)
            e_at, roundoff = self._estimate(y_new, runs)
            if e_at <= tol:
                if row is None:
                    self.factor, self.runs, self.periods, self.roundoff = factor, runs, k, roundoff
                else:
                    self.factor[row], self.periods[row], self.roundoff[row] = factor, k, roundoff
                    shape = np.shape(self.y0[0])
                    # (writable rows)
                    self.runs = tuple(None if r is None else tuple(np.array(np.broadcast_to(c, shape), dtype=np.float64) for c in r) for r in self.runs)
                    for r, v in zip(self.runs, runs):
                        if r is not None:
                            for c, x in zip(r, v):
                                c[row] = x
                return result, e_at, steps
            steps += n + companion_steps(n)
            if (k == len(controls) + 1 and e_at >= e) or not roundoff < ROUNDOFF_SHARE * tol:  # (as above)
                break
            k, e = len(controls) + 1, e_at
        if row is None:
            engine.step_factor = kept
        return None, estimate, steps

    def _replay(self, y0, controls, factor):
        """One state's periods from ``y0`` under ``controls`` with the guard's counts times
        ``factor``, the companion and its twins beside them: ``(((y, comp), runs), e, k, steps, roundoff)``
        at the end (each run with its compensation; ``runs`` the companion's and the twins'),
        or ``(None, e, k, steps)`` at the ``k``-th period, whose estimate ``e`` passed the
        tolerance (``inf``: a terminal event fired or the state went non-finite, which the run
        did not meet); then the estimate's roundoff part."""
        engine, tol = self.engine, self.engine.tolerance
        y, comp = y0, None  # (the episode's start: zero compensation)
        runs = (y0, None) * 3
        e, roundoff, steps = 0.0, 0.0, 0
        for j, u in enumerate(controls):
            y, fired, h, comp = engine.advance(y, u, False, factor=factor, comp=comp)
            n = int(round(engine.dt / h))
            steps += n + companion_steps(n)
            if fired or not all(math.isfinite(c) for c in y):
                return None, math.inf, j + 1, steps, 0.0
            runs = self._advance(runs, u, n)
            e, roundoff = self._estimate(y, runs)
            if not e <= tol:
                return None, e, j + 1, steps, roundoff
        if comp is None:
            fresh = engine.fresh_comp
            comp, runs = fresh, (runs[0], fresh, runs[2], fresh, runs[4], fresh)
        return ((y, comp), runs), e, len(controls) + 1, steps, roundoff

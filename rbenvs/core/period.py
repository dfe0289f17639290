"""A control period's integration, for one state (floats) and for a batch (arrays).

:class:`Period` takes a model's state through one control period: ``substeps`` equal internal
steps, or as many as the step controller asks for per state (:mod:`rbenvs.stepsize.controller`;
each element of a batch takes its own ``h`` and is frozen after its own count), the hybrid
layer's switches after every internal step (:mod:`rbenvs.core.hybrid`) and the system's terminal
event ending a period early; with ``tolerance_check`` the companion run's period beside it. It
holds no run state: a run's compensation (the compensated sums' carry, with a tolerance) goes in
and comes out, so the single env's run, each sub-env's and the companions' share one object.
The engine (:class:`rbenvs.core.step.Engine`) finishes the period (observation, reward, info).
"""

from __future__ import annotations

import math

import numpy as np

from ..stepsize.controller import MAX_INTERNAL_STEPS
from .hybrid import Switching

__all__ = ["Period"]


class Period:
    """The period of ``model``'s states (its system, integrator, step rule, ``dt`` and
    ``substeps``), its counts' plan and the checked runs compiled where ``forms``
    (:class:`rbenvs.core.compiled_forms.CompiledForms`) has them."""

    def __init__(self, model, forms):
        m = model
        self.forms = forms
        self.integrator, self.rule = m.integrator, m.step_rule
        self.dt, self.substeps, self.guard = m.dt, m.substeps, m.guard
        self.h = m.dt / m.substeps
        self.check = m.check
        system = m.system
        # a hybrid system declares its terminal event (ends the episode: the tippe top's
        # lift-off without free flight) and its switches (free flight: hops)
        self.event = system.terminal_event() if system.hybrid else None
        self.switching = (
            Switching(system, m.integrator) if system.hybrid and system.switches else None
        )
        # where the system gives the vector field and the event's value from one evaluation and
        # the scheme takes its first stage, the check at a new state is the next first stage
        # (the tippe top's lift-off: one contact solve per stage instead of one more per step)
        # with a tolerance the internal steps sum with compensation (Kahan 1965): what adding each
        # increment to the state rounds away is carried into the next step's sum, so that the
        # many steps a tight tolerance takes add no more roundoff than a few (near an unstable
        # axis the motion amplifies it: docs/accuracy.md, "Roundoff"). The compensation is
        # part of a run's state: it starts at zero at a reset and after a switch, and each run
        # (the env's, the companion) carries its own from period to period
        # (advance(comp=), companion(comp=); the single env's in its engine's comp)
        # (a default accuracy sums plainly: its scenes keep their bits; the companion's runs need
        # it)
        compensate = m.tolerance is not None and (m.accuracy == "explicit" or m.check)
        self.step_c = (
            m.integrator.bind(system, system.dim, compensated=True) if compensate else None
        )
        # a run's compensation at its start (zeros; None where the steps sum plainly)
        self.fresh_comp = (0.0,) * system.dim if self.step_c is not None else None
        self.shared, self.shared_c = None, None
        if self.event is not None:
            rhs_event = system.kernel_rhs_event  # (an event is a hybrid system's)
            shared = m.integrator.kernel_step_first_stage(system) if rhs_event is not None else None
            if shared is not None:
                self.shared = (shared, rhs_event)
                if compensate:
                    self.shared_c = m.integrator.kernel_step_first_stage(system, compensated=True)
        self.bound_step = m.integrator.bind(system, system.dim)  # the hot path's step, same bits

    def advance(self, y, u, plain: bool, skip=None, comp=None, ratio=None):
        """One control period from ``y`` under ``u``: ``(y, fired, h, comp)``.

        ``fired``: whether the terminal event ended the period (a bool, or a mask for a batch);
        ``h``: the internal step taken (``dt / n``; per element for a batch whose elements take
        different counts). ``plain``: ``substeps`` equal steps, nothing checked. Otherwise the
        guard's count ``n`` per state (``guard="refuse"`` raises instead of subdividing; more
        than ``MAX_INTERNAL_STEPS`` is refused as a numerical failure: the state becomes NaN,
        never a hang). ``skip`` (a batch): elements whose result is discarded (vector
        autoreset) take ``substeps`` steps, are never refused and never stretch the loop.
        ``comp``: the run's compensation at ``y`` (a tolerance: :attr:`step_c`; ``None`` is
        zero), returned as it is after the period (``None`` without compensation; a refused
        period's is zero). ``ratio`` (one state): the guard's ratio at ``y`` under ``u`` where
        the caller has it (:meth:`CompiledForms.plan_one`)."""
        if plain:
            step, h = self.bound_step, self.h
            y = step(y, u, h)
            for _ in range(self.substeps - 1):
                y = step(y, u, h)
            return y, False, h, None
        if comp is None:
            comp = self.fresh_comp
        event = self.event
        if not isinstance(y[0], np.ndarray):  # one state: plain Python (no numpy call per period)
            n = self.substeps
            if self.rule.active:
                n = self.rule.count(self.forms.plan_one(y, u)[0] if ratio is None else ratio, n)
            if n > self.substeps and self.guard == "refuse":
                raise self.refusal(n)
            if self.check:  # even: the companion takes half as many steps of twice the size
                n += n & 1
            if n > MAX_INTERNAL_STEPS:  # NaN at once, a numerical failure (h = dt / n), not a hang
                return tuple(math.nan for _ in y), False, self.dt / n, self.fresh_comp
            h = self.h if n == self.substeps else self.dt / n
            y, fired, comp = self._run_one(y, u, n, h, comp)
            return y, fired, h, comp
        # a batch: the same rules per element (each takes its own count, then is frozen)
        n = self.forms.counts(y, u)
        if self.check:
            n = n + (n & 1)
        if skip is not None:
            n = np.where(skip, self.substeps, n)
        over = n > self.substeps
        if self.guard == "refuse" and over.any():
            raise self.refusal(int(n.max()), f" of sub-envs {np.flatnonzero(over).tolist()}")
        refused = n > MAX_INTERNAL_STEPS
        if refused.any():  # (a failure: off the normal path)
            return self._refused(y, u, n, refused, skip, comp)
        uniform = bool(np.all(n == n.flat[0]))
        if self.integrator.uniform_step_only and not uniform:  # (the reference scheme only)
            return self._grouped(y, u, n)
        h = self.dt / n.flat[0] if uniform else self.dt / n
        y, fired, comp = self._loop(y, u, n, h, comp)
        if uniform and event is None:
            return y, fired, h, comp
        return y, fired, np.broadcast_to(np.asarray(h, dtype=float), n.shape).copy(), comp

    def _refused(self, y, u, n, refused, skip, comp):
        """:meth:`advance` of a batch some of whose elements need more than
        ``MAX_INTERNAL_STEPS``: those become NaN at once (a numerical failure, reported with
        ``h = dt / n``) and are skipped; the others take their period."""
        y = tuple(np.where(refused, np.nan, c) for c in y)
        y, fired, h, comp = self.advance(
            y, u, False, refused if skip is None else (skip | refused), comp=comp
        )
        return y, fired, np.where(refused, self.dt / n, h), comp

    def _grouped(self, y, u, n):
        """:meth:`advance` of a batch of unequal counts ``n`` under a scheme that takes one
        scalar step for the whole batch (adaptive dop853: one solve whose step follows all
        members): one run per group of equal counts."""
        out = [np.array(c, dtype=float) for c in y]
        fired = np.zeros(n.shape, dtype=bool)
        for k in np.unique(n):
            idx = np.flatnonzero(n == k)
            sub_u = None if u is None else tuple(c[idx] if np.ndim(c) else c for c in u)
            sub_y, sub_fired, _ = self._loop(
                tuple(c[idx] for c in y), sub_u, np.full(len(idx), k), self.dt / int(k), None
            )
            for o, c in zip(out, sub_y):
                o[idx] = c
            fired[idx] = sub_fired
        return tuple(out), fired, self.dt / n, None

    def _compensated_steps(self, comp):
        """``(step_c, first_c)``, the compensated step and first-stage step a run takes; ``None``
        each where the run sums plainly (``comp`` is ``None``) or the system has no such step."""
        if comp is None:
            return None, None
        return self.step_c, None if self.shared_c is None else self.shared_c[0]

    def _run_one(self, y, u, n: int, h: float, comp=None):
        """One state's ``n`` internal steps of ``h``, the switches after each and the terminal
        event ending them early: ``(y, fired, comp)``. ``comp``: the run's compensation at
        ``y`` (a tolerance: the compensated step carries it; it starts again from zero after a
        switch); ``None``: the plain step."""
        if (
            self.check and comp is not None
        ):  # (the checked period's runs, compiled where they can be)
            forms = self.forms
            runs = forms.runs if forms.runs_tried else forms.checked_runs
            if runs is not None:
                return runs(y, comp, u, n, h)
        post, event = self.switching, self.event
        step_c, first_c = self._compensated_steps(comp)
        if self.shared is not None:  # (the event's evaluation is the next first stage)
            (first, ps), (rhs_event, pv) = self.shared
            k, g = rhs_event(pv, y, u)
            for _ in range(n):
                if first_c is None:
                    y = first(ps, y, k, u, h)
                else:
                    y, comp = first_c(ps, y, comp, k, u, h)
                if not all(math.isfinite(c) for c in y):
                    return y, False, comp
                k, g = rhs_event(pv, y, u)
                if g < 0.0:
                    return y, True, comp
            return y, False, comp
        step = self.bound_step  # integ.step with the system bound (the same bits)
        if step_c is not None and post is None and event is None:
            for _ in range(n):
                y, comp = step_c(y, comp, u, h)
            return y, False, comp
        for _ in range(n):
            if step_c is None:
                y_prev, y = y, step(y, u, h)
            else:
                y_prev, (y, comp) = y, step_c(y, comp, u, h)
            if post is not None:
                y_post = post.after_step(y_prev, y, u, h)
                if y_post is not y:  # switched: the rest of the step was taken afresh
                    y, comp = y_post, self.fresh_comp
            if event is not None:
                if not all(math.isfinite(c) for c in y):
                    return y, False, comp
                if event[1](y, u):
                    return y, True, comp
        return y, False, comp

    def companion(self, y, u, n, comp=None):
        """The companion run's period (:mod:`rbenvs.stepsize.controller`) from ``y`` under ``u``,
        where the main run took ``n`` (even, with ``tolerance_check``) steps of ``h = dt / n``:
        ``n / 2`` steps of ``2 h`` (one state: ``n`` an int; a batch: an int array); ``(y,
        comp)``, ``comp`` the companion's own compensation as :meth:`advance` carries it."""
        if comp is None:
            comp = self.fresh_comp
        if not isinstance(y[0], np.ndarray):
            y, _, comp = self._run_one(y, u, n // 2, 2.0 * self.dt / n, comp)
            return y, comp
        n = np.asarray(n, dtype=np.int64)
        if n.shape != np.shape(y[0]):  # (broadcast_to costs ~5 us: only where needed)
            n = np.broadcast_to(n, np.shape(y[0]))
        y, _, comp = self._loop(y, u, n // 2, 2.0 * self.dt / n, comp)
        return y, comp

    def _loop(self, y, u, n, h, comp=None):
        """A batch's internal steps: element ``i`` takes ``n[i]`` steps of ``h`` (``h[i]``) and is
        frozen after them or at its terminal event: ``(y, fired, comp)``. ``comp``: each
        element's compensation, carried as :meth:`_run_one` carries it (``None``: plain)."""
        if self.check and comp is not None:  # (the checked runs, compiled where they can be)
            forms = self.forms
            runs = forms.runs if forms.runs_tried else forms.checked_runs
            if runs is not None and u is not None:
                return self._run_each(runs, y, u, n, h, comp)
        step, post, event = self.bound_step, self.switching, self.event
        step_c, first_c = self._compensated_steps(comp)
        fired = np.zeros(n.shape, dtype=bool)
        # the event's evaluation is the next first stage: a loop of its own, taken before the
        # closure below is made (making it costs more than the call)
        if self.shared is not None:
            return self._loop_first_stage(y, u, n, h, comp, first_c, fired)

        def stepped(y, comp):  # one step of every element, and the switches after it
            if step_c is None:
                y_new = step(y, u, h)
            else:
                y_new, comp = step_c(y, comp, u, h)
            if post is not None:
                y_post = post.after_step(y, y_new, u, h)
                if (
                    y_post is not y_new and step_c is not None
                ):  # the elements that switched start their sum afresh
                    moved = np.zeros(n.shape, dtype=bool)
                    for a, b in zip(y_post, y_new):
                        moved |= a != b
                    comp = tuple(np.where(moved, 0.0, ci) for ci in comp)
                y_new = y_post
            return y_new, comp

        if event is None and bool(np.all(n == n.flat[0])):
            for _ in range(int(n.flat[0])):
                y, comp = stepped(y, comp)
            return y, fired, comp
        active = np.ones(n.shape, dtype=bool)
        for k in range(int(n.max())):
            y_new, comp_new = stepped(y, comp)
            active &= k < n
            if event is not None:
                with np.errstate(invalid="ignore"):
                    hit = active & np.asarray(event[1](y_new, u), dtype=bool)
            y = tuple(np.where(active, c_new, c) for c_new, c in zip(y_new, y))
            if step_c is not None:  # (a frozen element keeps its compensation with its state)
                comp = tuple(np.where(active, c_new, c) for c_new, c in zip(comp_new, comp))
            if event is not None:
                fired |= hit
                active &= ~hit
            if not np.any(active):
                break
        return y, fired, comp

    def _loop_first_stage(self, y, u, n, h, comp, first_c, fired):
        """:meth:`_loop` where the event's evaluation is the next step's first stage
        (:attr:`shared`, as :meth:`_run_one` takes it): ``(y, fired, comp)``, ``fired`` (zeros)
        marking the elements whose event ended their steps; ``first_c`` the compensated step."""
        active = np.ones(n.shape, dtype=bool)
        (first, ps), (rhs_event, pv) = self.shared
        kk, _ = rhs_event(pv, y, u)
        for k in range(int(n.max())):
            if first_c is None:
                y_new = first(ps, y, kk, u, h)
            else:
                y_new, comp_new = first_c(ps, y, comp, kk, u, h)
            kk_new, g = rhs_event(pv, y_new, u)
            active &= k < n
            with np.errstate(invalid="ignore"):
                hit = active & (g < 0.0)
            y = tuple(np.where(active, c_new, c) for c_new, c in zip(y_new, y))
            kk = tuple(np.where(active, c_new, c) for c_new, c in zip(kk_new, kk))
            if first_c is not None:  # (a frozen element keeps its compensation with its state)
                comp = tuple(np.where(active, c_new, c) for c_new, c in zip(comp_new, comp))
            fired |= hit
            active &= ~hit
            if not np.any(active):
                break
        return y, fired, comp

    @staticmethod
    def _run_each(runs, y, u, n, h, comp):
        """:meth:`_loop` through the compiled runs (``tolerance_check``,
        :meth:`rbenvs.compiled.CheckedRuns.batch`): element ``i`` takes its ``n[i]`` steps of ``h``
        (``h[i]``) from its state and compensation, as its single env takes them (the same bits as
        the arrays' loop)."""
        size = n.size

        def rows(
            values,
            # (a component may be one float for every element: a fresh compensation, a shared
            # control)
        ):
            out = np.empty((len(values), size))
            for j, c in enumerate(values):
                out[j] = c
            return out

        Y, CC, U = rows(y), rows(comp), rows(u)
        H = np.asarray(h, dtype=np.float64)
        if H.shape != n.shape or not H.flags.c_contiguous:  # (read only by the runs)
            H = np.full(n.shape, H)
        fired = np.zeros(size, dtype=bool)
        runs.batch(Y, CC, U, np.ascontiguousarray(n, dtype=np.int64), H, fired)
        return tuple(Y), fired.reshape(n.shape), tuple(CC)

    def refusal(self, n, where: str = "") -> ValueError:
        """The ``guard="refuse"`` error for a period that needs ``n`` internal steps."""
        return ValueError(
            f"guard='refuse' and the state{where} needs {n} internal steps per control period, "
            "more than "
            f"substeps={self.substeps} (dt={self.dt!r}, integrator {self.integrator.name!r}: "
            f"{self.rule.text}); "
            f"raise substeps to at least {n} or lower dt, or pass guard='subdivide'"
        )

    def internal_steps(self, y, u):
        """The internal steps the guard asks for at ``y`` under ``u`` (an int or an int array)."""
        return self.rule.steps(y, u, self.substeps)

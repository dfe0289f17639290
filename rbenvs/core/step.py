"""The step of a control period, written once, for one state (floats) and for a batch (arrays).

:class:`Engine` runs a :class:`~rbenvs.core.model.Model`: the single env calls it on a tuple of
Python floats (the batch of one: no numpy call overhead inside the integrator), the vector env
on a tuple of arrays, one per component. Each part of the step is here once:

1. the action: validated and clipped (:func:`action_values`, :func:`action_columns`), mapped to
   controls by the model's actuator;
2. the period (:meth:`rbenvs.core.period.Period.advance`): ``substeps`` equal internal steps,
   or as many as the step guard asks for per state (:mod:`rbenvs.stepsize.controller`; each
   element of a batch takes its own ``h`` and is frozen after its own count), the hybrid
   layer's switches after every internal step (:mod:`rbenvs.core.hybrid`) and the system's
   terminal event (the tippe top's lift-off without free flight) ending a period early;
3. numerical failure: a state that went non-finite ends its episode; the last finite state is
   kept and reported (reward 0 and the failure charge, ``NumericalFailureWarning``), never
   passed on;
4. the observation (:meth:`Engine.observe`): the task's components, clipped to the bounds, and
   whether the state left them (``observation_limit``);
5. reward, termination and metrics (the task's ``evaluate``), the read-outs (the system's
   ``readouts`` under the control that acted, and ``internal_step``), assembled into ``info``;
6. the terminal reason (:func:`terminal_reason`): ``numerical_failure`` over the event over
   ``observation_limit`` over ``task``; an episode that ends without success (``is_success``
   false) carries the model's ``failure_charge`` in its last reward
   (:class:`~rbenvs.core.model.Model`), so ending early never pays.

Where a model's parts have pure forms, the single env's step 4-5 runs as one function generated
from them (:meth:`Engine.finish_one`; tested equal to the methods) and the vector env's steps 2-5
as one compiled kernel of the same functions (:mod:`rbenvs.compiled`); those are the same
parts, specialised, not other implementations.
"""

from __future__ import annotations

import functools
import math
import warnings

import numpy as np

from ..dynamics.validation import real_array
from ..stepsize.controller import MAX_INTERNAL_STEPS
from .compiled_forms import CompiledForms
from .finish import generated_finish
from .parts import kernel_parts
from .period import Period
from .reasons import terminal_reason

__all__ = ["Engine", "NumericalFailureWarning", "action_values", "action_columns"]


class NumericalFailureWarning(RuntimeWarning):
    """The state went non-finite; the episode was ended and the last finite state kept."""


# float dtypes an action array may have on the fast path (builtin dtypes are singletons)
_REAL_FLOATS = (np.dtype(np.float32), np.dtype(np.float64))


def action_values(action, shape) -> list:
    """One env's action as a list of Python floats: real numbers only (strings, complex
    numbers, dicts and objects raise ``TypeError``), of ``shape``, finite (``ValueError``),
    clipped to ``[-1, 1]`` (documented)."""
    if type(action) is np.ndarray and action.shape == shape and action.dtype in _REAL_FLOATS:
        values = action.tolist()
        # the common case in three builtins: every entry in [-1, 1] and the sum finite (min
        # and max may step over a NaN, the sum cannot); anything else goes the long way
        if -1.0 <= min(values) and max(values) <= 1.0 and math.isfinite(sum(values)):
            return values
    else:
        arr = real_array("action", action)
        if arr.shape != shape:
            raise ValueError(f"action must have shape {shape}, got {arr.shape}")
        values = arr.tolist()
    out = []
    for v in values:
        v = float(v)
        if not math.isfinite(v):
            raise ValueError(f"action must be finite, got {action!r}")
        out.append(-1.0 if v < -1.0 else (1.0 if v > 1.0 else v))
    return out


def action_columns(actions, shape) -> tuple:
    """A batch's actions ``(n, k)`` as ``k`` contiguous float64 columns: the single env's
    rules (real numbers, the shape, finite; clipped to ``[-1, 1]``)."""
    a = real_array("actions", actions, dtype=None)
    if a.shape != shape:
        raise ValueError(f"actions must have shape {shape}, got {a.shape}")
    if not np.isfinite(a).all():
        bad = np.flatnonzero(~np.all(np.isfinite(a), axis=1))
        raise ValueError(f"actions must be finite; sub-envs {bad.tolist()} are not")
    return tuple(np.clip(a.T, -1.0, 1.0).astype(np.float64, order="C"))


def _to_python(v):
    if v is None:  # (error_estimate, not estimated)
        return None
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):  # counts stay counts
        return int(v)
    return float(v)


class Engine:
    """The step of one :class:`~rbenvs.core.model.Model` (floats or arrays; see the module)."""

    def __init__(self, model, compiled="auto", backend=None):
        m = self.model = model
        # a loader of the compiled backend (rbenvs.contracts.CompiledBackend), called where a
        # compiled form is first wanted; None: the float path only
        self.backend = backend
        self.system, self.task = m.system, m.task
        self.integrator, self.actuator = m.integrator, m.actuator
        self.dt, self.substeps, self.guard, self.rule = m.dt, m.substeps, m.guard, m.step_rule
        # the actuator's pure form bound once: the hot path calls it every step, and the actuators'
        # kernel_control properties make their tuple on each read
        self.control = functools.partial(*m.actuator.kernel_control)
        self.h = m.dt / m.substeps
        self.check = m.check
        # the compiled forms of the step (the single-state step, the checked runs, the period
        # plan), each built on first use where numba is installed and every part has a pure form
        self.forms = CompiledForms(self, compiled)
        # the period's integration (no run state: a run's compensation goes in and out)
        self._take_period(m, Period(m, self.forms))
        self._take_finish(m)
        self.compiled = compiled
        # with a tolerance every period reports its estimated error (info["error_estimate"]): the
        # rate at its start and the step it took; without one the step is untouched
        self.tolerance = m.tolerance
        # the default accuracy's gate: a state within it takes the plain loop (StepRule.plain_gate)
        plain_loop = self.event is None and self.switching is None and self.step_c is None
        self.gated = self.rule.plain_gate(m.substeps, plain_loop and not m.check)
        # tolerance_check: every period takes an even count (its companion half as many steps of
        # twice the size: rbenvs.stepsize.controller), so neither the plain loop (substeps steps)
        # nor the compiled single-state step (the guard's count) runs
        if m.check:
            self.plain = False
        if compiled is True:  # (the form the env runs, demanded: built now, or the reason why not)
            self.forms.require()

    def _take_period(self, m, period):
        """The engine's parts of ``period`` (its event, switches, steps and runs), and whether
        the plain loop may run (:attr:`plain`)."""
        self.period = period
        self.event, self.switching, self.step_c = period.event, period.switching, period.step_c
        self.event_name = None if self.event is None else self.event[0]
        self.fresh_comp, self.bound_step = period.fresh_comp, period.bound_step
        self.comp = self.fresh_comp  # the single env's run's
        self.advance, self.companion = period.advance, period.companion
        self.refusal, self.internal_steps = period.refusal, period.internal_steps
        # the plain loop (substeps equal steps, nothing watched) is exact when no state inside
        # the observation bounds can trip the guard; a step that ends outside them drops to the
        # checked path until the next reset (the single env's and the vector env's rule); a
        # compensated sum runs on the checked path
        self.plain = (
            self.event is None
            and self.switching is None
            and self.rule.idle(m.substeps)
            and self.step_c is None
        )

    def _take_finish(self, m):
        """What the period's finish reads: the observation bounds, the metrics' and read-outs'
        names, the failure charge, and the single env's generated finish (:attr:`finish_one`)."""
        system = m.system
        self.high = np.asarray(m.observation_high, dtype=np.float64)
        self.high32 = self.high.astype(np.float32)
        self.high_list = self.high.tolist()
        self.high_uniform = self.high_list[0] if len(set(self.high_list)) == 1 else None
        self.metric_names = tuple(m.task.metric_names)
        self.failure_charge = m.failure_charge  # added to the last reward of an episode that fails
        self.readout_names = tuple(system.readout_names)
        self.finish_one = generated_finish(
            m.task, system, self.high_list, self.metric_names, self.readout_names
        )

    def __reduce__(self):  # generated and compiled functions are made again, not pickled
        return (
            Engine,
            (self.model, self.compiled, self.backend),
            {"comp": self.comp},
        )  # (the single env's run goes on as it was)

    # ------------------------------------------------------------------ after the period
    def observe(self, y):
        """``(obs, over)``: the task's observation as float32 (one state: ``(k,)``; a batch:
        ``(n, k)``), clipped to the bounds, and whether the state left them (a bool or a mask)."""
        comps = self.task.observe(self.system, y)
        if not isinstance(comps[0], np.ndarray) and not isinstance(y[0], np.ndarray):
            hi = self.high_uniform
            if hi is not None:  # one bound for every component: two builtin calls
                over = not (-hi <= min(comps) and max(comps) <= hi)
            else:
                over = any(not -b <= v <= b for v, b in zip(comps, self.high_list))
            if over:
                return np.clip(np.asarray(comps, dtype=np.float64), -self.high, self.high).astype(
                    np.float32
                ), True
            return np.array(comps, dtype=np.float32), False
        # a batch: the float32 copy checked against the float32 bounds with <; rounding to
        # float32 is monotone, so float32(v) < float32(hi) implies v < hi and passing means
        # every float64 value is inside; otherwise the exact float64 test decides
        n = len(y[0])
        o = np.empty((n, len(comps)), dtype=np.float32)
        for j, c in enumerate(comps):
            o[:, j] = c
        none = np.zeros(n, dtype=bool)
        if (np.abs(o) < self.high32).all():
            return o, none
        o64 = np.empty((n, len(comps)))
        for j, c in enumerate(comps):
            o64[:, j] = c
        outside = ~(np.abs(o64) <= self.high)
        if not outside.any():
            return o64.astype(np.float32), none
        return np.clip(o64, -self.high, self.high).astype(np.float32), outside.any(axis=1)

    def evaluate(self, y, u_norm):
        """``(reward, terminated, metrics)`` (the task's ``evaluate``): for one state a Python
        float, bool and dict; for a batch arrays of the batch's length."""
        reward, terminated, metrics = self.task.evaluate(self.system, y, u_norm)
        if not isinstance(y[0], np.ndarray):
            return float(reward), bool(terminated), metrics
        n = len(y[0])
        # (a task may give one value for the whole batch: np.full, cheaper than broadcast_to's copy)
        reward = np.asarray(reward, dtype=np.float64)
        if reward.shape != (n,):
            reward = np.full(n, reward, dtype=np.float64)
        terminated = np.asarray(terminated, dtype=bool)
        if terminated.shape != (n,):
            terminated = np.full(n, terminated, dtype=bool)
        return reward, terminated, metrics

    def readouts(self, y, u, fired, h) -> dict:
        """The physical read-outs (the system's, under the control ``u`` that acted and with the
        event flag), and ``internal_step`` (``h``), keyed by name."""
        info = dict(zip(self.readout_names, self.system.readouts(y, u, fired)))
        info["internal_step"] = h
        return info

    def info_one(self, y, u, fired, h, metrics, failed: bool) -> dict:
        """One env's ``info``: read-outs, metrics, ``numerical_failure``; Python scalars."""
        info = self.readouts(y, u, fired, h)
        info["error_estimate"] = None  # (not estimated; a tolerance's step writes its period's)
        info.update(metrics)
        for name, v in info.items():
            if type(v) is not float and type(v) is not bool:
                info[name] = _to_python(v)
        info["numerical_failure"] = failed
        return info

    # ------------------------------------------------------------------ one env (floats)
    def reset_one(self, y):
        """``(obs, info)`` of a start ``y`` (no control has acted: ``u = None``); the single env's
        run starts there (its compensation at zero)."""
        self.comp = self.fresh_comp  # the single env's run's
        obs, info = self.fresh_one(y)
        if self.tolerance is not None:
            info["error_estimate"] = 0.0  # (no period yet: the vector env's reset)
        return obs, info

    def fresh_one(self, y):
        """:meth:`reset_one`'s ``(obs, info)`` of ``y`` without starting a run there (the run's
        compensation as it was)."""
        obs, over = self.observe(y)
        if over:
            raise ValueError(
                "the initial state lies outside the observation bounds; raise the limit parameters"
            )
        _, _, metrics = self.evaluate(y, self.actuator.control((0.0,) * self.actuator.size)[0])
        return obs, self.info_one(y, None, False, self.h, metrics, failed=False)

    def step_one(self, y0, a, plain: bool):
        """One control period of one env from ``y0`` under the action ``a`` (validated floats):
        a plain tuple in the fields of :class:`~rbenvs.contracts.StepResult` ``(y, obs, reward,
        terminated, info, u, plain)``, ``u`` the control that acted and ``plain`` whether the
        next period may take the plain loop (a tuple, not the NamedTuple itself: making one
        costs 0.2 us, 4 % of a free-body step; ``StepResult._make`` names it off the hot path)."""
        u_norm, u = self.control(a)
        forms = self.forms
        one = forms.one if forms.one_tried else forms.state_step
        if one is None:  # (the float path: its own method, off the compiled hot path)
            return self._step_float(y0, u_norm, u, plain)
        e = None  # (the period's error estimate: a kernel with a tolerance's returns it last)
        if self.comp is None:
            if one.estimated:
                status, count, h, fired, y, o, over, r, q, e = one(
                    y0, u, u_norm, not plain, self.guard == "refuse"
                )
            else:
                status, count, h, fired, y, o, over, r, q = one(
                    y0, u, u_norm, not plain, self.guard == "refuse"
                )
        elif one.estimated:  # (the run's compensation in and out)
            status, count, h, fired, y, o, over, r, q, comp, e = one.compensated(
                y0, self.comp, u, u_norm, not plain, self.guard == "refuse"
            )
        else:
            status, count, h, fired, y, o, over, r, q, comp = one.compensated(
                y0, self.comp, u, u_norm, not plain, self.guard == "refuse"
            )
        if status < 0:  # refused (guard="refuse"): count is the period's steps
            raise self.refusal(count)
        if status:  # failed: off the normal path
            return self._failed_one(y0, u_norm, u, h, plain, stacklevel=5, estimate=e)
        if self.comp is not None:
            self.comp = comp
        obs, reward, terminated = np.array(o, dtype=np.float32), r[0], r[1]
        info = one.info(q, r, h, e)
        if fired or over or terminated:  # (the common case tests three bools and goes on)
            reward, terminated, plain = self._ended(info, fired, over, terminated, reward, plain)
        return y, obs, reward, terminated, info, u, plain

    def _step_float(self, y0, u_norm, u, plain: bool):
        """:meth:`step_one`'s period and finish on floats (no compiled kernel: numpy, or numba
        absent or turned off)."""
        plan = gated = ratio = None  # a tolerance's: the rates at y0 give the count and estimate
        if self.tolerance is not None:
            gated = self.gated(y0)
            if gated is None:
                plan = self.forms.plan_one(y0, u)  # (x, lam, lam_d, a)
                ratio = plan[0]
        if plain or gated is not None:  # fixed substeps, nothing watched: the loop inline
            step, h, comp, fired = self.bound_step, self.h, None, False
            y = step(y0, u, h)
            if self.substeps != 1:
                for _ in range(self.substeps - 1):
                    y = step(y, u, h)
        else:
            y, fired, h, comp = self.advance(y0, u, False, comp=self.comp, ratio=ratio)
        # the period's estimated relative error (stepsize.forms.error_estimate), or the gate's
        estimate = gated if plan is None else float(self.rule.estimate(plan[1], h, *plan[2:]))
        # a non-finite component makes the sum non-finite; the exact test runs only then
        if not math.isfinite(sum(y)) and not all(math.isfinite(c) for c in y):
            return self._failed_one(y0, u_norm, u, h, plain, stacklevel=5, estimate=estimate)
        if not plain and comp is not None:
            self.comp = comp
        finish = self.finish_one
        if finish is not None:
            fn, po, pe, pr = finish
            obs, over, reward, terminated, info = fn(y, u_norm, po, pe, pr, h, u, fired)
        else:
            obs, over = self.observe(y)
            reward, terminated, metrics = self.evaluate(y, u_norm)
            info = self.info_one(y, u, fired, h, metrics, failed=False)
        if self.tolerance is not None:
            info["error_estimate"] = estimate
        if fired or over or terminated:  # (the common case tests three bools and goes on)
            reward, terminated, plain = self._ended(info, fired, over, terminated, reward, plain)
        return y, obs, reward, terminated, info, u, plain

    def _ended(self, info, fired, over, terminated, reward, plain):
        """``(reward, True, plain)`` of a period that ended its episode (the event ``fired``, the
        state left the bounds: ``over``, the task ``terminated``): its terminal reason in
        ``info``, the failure charge added to ``reward`` where it is no success (ending early
        never pays), and ``plain`` false where it is ``over``."""
        info["terminal_reason"] = terminal_reason(False, fired, over, terminated, self.event_name)
        terminated = True
        if not info["is_success"]:
            reward += self.failure_charge
        if over:
            plain = False  # outside the bounds the guard's static proof is void
        return reward, terminated, plain

    def _cap_text(self, h, y0=None, u=None) -> str:
        """Why a period failed when it was refused past the cap (``h < dt / MAX_INTERNAL_STEPS``):
        which bound asked for the steps; ``""`` otherwise."""
        if not float(np.min(h)) * MAX_INTERNAL_STEPS < self.dt:
            return ""
        bound = self.rule.binding(y0, u) if y0 is not None else f"the step bound ({self.rule.text})"
        return (
            f": the period needs more than MAX_INTERNAL_STEPS = {MAX_INTERNAL_STEPS} internal "
            f"steps to meet {bound}"
        )

    def inaccurate_one(self, y0, a, h, plain, comp, why):
        """The end of an episode whose period from ``y0`` the accuracy check did not accept
        (``tolerance_check``; ``why``: its words): a numerical failure at ``y0``, the last state
        within the tolerance (the run's compensation ``comp`` at it kept with it)."""
        self.comp = comp
        u_norm, u = self.control(a)
        return self._failed_one(y0, u_norm, u, h, plain, why, "the last state within the tolerance")

    def _failed_one(
        self,
        y0,
        u_norm,
        u,
        h,
        plain,
        what=None,
        kept="the last finite state",
        stacklevel=5,
        estimate=None,
    ):
        """The end of an episode at ``y0``, the last state kept (``what``: why; by default a
        refused or non-finite period), with its period's error ``estimate`` in its info."""
        # (stacklevel: the warning names the env's caller; a helper between adds a frame)
        if what is None:
            cap = self._cap_text(h, y0, u)
            what = "the period was refused" + cap if cap else "the state became non-finite"
        warnings.warn(
            f"{what} with integrator {self.integrator.name!r} (internal step h = "
            f"{float(np.max(h)):g} s); "
            f"the episode ends and {kept} is kept",
            NumericalFailureWarning,
            stacklevel=stacklevel,
        )
        obs, _ = self.observe(y0)
        _, _, metrics = self.evaluate(y0, u_norm)
        info = self.info_one(y0, u, False, h, metrics, failed=True)
        info["error_estimate"] = estimate
        info["terminal_reason"] = terminal_reason(True, False, False, True, self.event_name)
        return y0, obs, 0.0 + self.failure_charge, True, info, u, plain

    # ------------------------------------------------------------------ a batch (arrays)
    def settle(self, y0, y, skip, h=None, held=None):
        """``(y, failed)`` after a batch's period: elements that went non-finite keep their
        last finite state, and those ``held`` (``tolerance_check``: their global error estimate
        passed the tolerance) their last state within it; ``failed`` marks them (not those in
        ``skip``, about to restart); a ``NumericalFailureWarning`` names the non-finite ones (the
        single env's words). ``failed`` is ``None`` when none failed."""
        with np.errstate(over="ignore", invalid="ignore"):  # (inf + -inf: not finite, no warning)
            all_finite = bool(np.isfinite(sum(y)).all())
        if held is None and all_finite:
            return y, None
        finite = np.ones(np.shape(y[0]), dtype=bool)
        for c in y:
            finite &= np.isfinite(c)
        failed = ~finite & ~skip
        if failed.any():
            cap = (
                self._cap_text(np.asarray(h)[failed]) if np.ndim(h) else ""
            )  # (the single env's words)
            cap = f" (periods refused{cap})" if cap else ""
            warnings.warn(
                f"sub-envs {np.flatnonzero(failed).tolist()} became non-finite with integrator "
                f"{self.integrator.name!r}{cap}; "
                "their episodes end and their last finite states are kept",
                NumericalFailureWarning,
                stacklevel=3,
            )
        kept = finite
        if held is not None:
            failed, kept = failed | held, finite & ~held
        return tuple(np.where(kept, c, c0) for c, c0 in zip(y, y0)), (
            failed if failed.any() else None
        )

    # ------------------------------------------------------------------ pure forms
    def kernel_parts(self):
        """The model's step in pure forms for the compiled backend (:func:`rbenvs.core.parts.
        kernel_parts`), or ``None`` where a part has none."""
        return kernel_parts(self.period, self.system, self.task)

"""The kernels with their parameters, as the engine and the envs call them: :class:`StateStep`,
:class:`BatchStep`, :class:`VectorStep`, :class:`CheckedRuns`, :class:`PeriodPlan`, and the
:class:`Backend` the step core is given."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..core.finish import info_function
from ..jit import DISABLE_VARIABLE, available
from .batch import NO_COMPENSATION, Layout, batch_kernel, finish_kernel
from .state import plan_kernel, plans_kernel, run_kernel, runs_kernel, state_kernel
from .vector import (
    HEAD_ARGS,
    VectorLayout,
    flat_leaves,
    rows_kernel,
    split_kernel,
    tuple_shape,
    vector_kernel,
)


class PeriodPlan:
    """One env's compiled :func:`plan_kernel` and :func:`plans_kernel` with their parameters:
    calling it with one state ``y`` and its control ``u`` (tuples of floats) returns ``(x, r,
    rate, a)``, the bits of :meth:`rbenvs.stepsize.controller.StepRule.plan`; :meth:`batch` gives a
    batch's rates and :meth:`ratios` its ratios (the vector env's estimate and checked count).
    The first call compiles (once per layout and process) and then takes its overload's entry
    point."""

    def __init__(self, parts, dim: int, n_obs: int, n_control: int, n_action: int, sample):
        layout, params, _, _ = _layout(parts, dim, n_obs, n_control, n_action, sample)
        if layout.rotation is None:
            raise ValueError("the plan needs the guard's rate (a step rule that can ask for steps)")
        self.layout = layout
        self.kernel = plan_kernel(layout)
        self.params = params[4:8]  # PG, PA, PD, CD
        self._call = self._batch = self._ratios = None

    def __call__(self, y, u):
        call = self._call
        if call is not None:
            return call(y, u, self.params)
        out = self.kernel(y, u, self.params)  # compiles
        self._call = _entry_point(self.kernel, (y, u, self.params))
        return out

    def batch(self, Y, U):
        """``(R, RATE, A)`` of the ``(dim, n)`` states ``Y`` under the ``(n_control, n)``
        controls ``U`` (float64, C-contiguous): arrays, ``R`` ``(3, n)`` or ``(1, n)`` (the
        ratio is not evaluated)."""
        if self._batch is None:
            self._batch = plans_kernel(self.layout)
        n = Y.shape[1]
        RATE, A = np.empty(n), np.empty(n)
        R = np.empty((3 if self.layout.motion else 1, n))
        self._batch(Y, U, self.params, R, RATE, A)
        return R, RATE, A

    def ratios(self, Y, U):
        """The guard's ratios ``X`` ``(n,)`` of a batch (as :meth:`batch`'s arguments)."""
        if self._ratios is None:
            self._ratios = plans_kernel(self.layout, True)
        X = np.empty(Y.shape[1])
        self._ratios(Y, U, self.params, X)
        return X


class CheckedRuns:
    """One env's compiled runs for ``tolerance_check`` (:func:`run_kernel`, the main run's and
    the companion's): calling it runs ``c`` steps of ``hi`` from ``y`` with the compensation
    ``cc`` and returns ``(y, fired, cc)``, the bits of the float path's
    :meth:`rbenvs.core.period.Period._run_one`. Each kernel's first call compiles it (once
    per layout and process) and then takes its overload's entry point."""

    def __init__(self, parts, dim: int, n_obs: int, n_control: int, n_action: int, sample):
        layout, params, _, _ = _layout(parts, dim, n_obs, n_control, n_action, sample)
        if layout.step_c is None:
            raise ValueError("the checked runs need a compensated step (a tolerance)")
        self.kernel = run_kernel(layout)
        self.batch_kernel = runs_kernel(layout)
        self.params = (params[0], params[8], params[9])  # PS, PV, PW
        self._call = None

    def batch(self, Y, CC, U, counts, H, fired) -> None:
        """A batch's runs in place (:func:`runs_kernel`): ``Y``, ``CC`` ``(dim, n)``, ``U``
        ``(n_control, n)``, ``counts``, ``H`` ``(n,)``, ``fired`` written."""
        self.batch_kernel(Y, CC, U, counts, H, fired, self.params)

    def __call__(self, y, cc, u, c: int, hi: float):
        if self._call is not None:
            return self._call(y, cc, u, c, hi, self.params)
        import numba

        args = (y, cc, u, c, hi, self.params)
        out = self.kernel(*args)  # compiles
        overload = self.kernel.overloads.get(tuple(numba.typeof(a) for a in args))
        self._call = overload.entry_point if overload is not None else self.kernel
        return out


def _dtypes(values, physical) -> tuple:
    """``(metric dtypes, read-out dtypes)``: each metric's and read-out's array type from its value
    on a float state (``values[2:]``, ``physical``; a bool stays a bool, a count an int). (dtype
    objects, not scalar types: np.empty would convert a type on every call.)"""
    metric_dtypes = tuple(
        np.dtype(np.bool_ if isinstance(v, (bool, np.bool_)) else np.float64) for v in values[2:]
    )
    readout_dtypes = tuple(
        np.dtype(
            np.bool_
            if isinstance(v, (bool, np.bool_))
            else (np.int64 if isinstance(v, (int, np.integer)) else np.float64)
        )
        for v in physical
    )
    return metric_dtypes, readout_dtypes


def _switch_parts(parts) -> tuple:
    """``(layout triples, PW)`` from :attr:`KernelParts.switches` (``((applies, P), (function, P),
    tolerance, (switch, P))`` each)."""
    triples = tuple(
        (applies[0], function[0], switch[0])
        for applies, function, tolerance, switch in parts.switches
    )
    pw = tuple(
        (function[1], float(tolerance), switch[1], applies[1])
        for applies, function, tolerance, switch in parts.switches
    )
    return triples, pw


def _layout(parts, dim: int, n_obs: int, n_control: int, n_action: int, sample) -> tuple:
    """``(layout, kernel parameters, sample evaluation, sample read-outs)`` of
    :class:`rbenvs.core.parts.KernelParts`: the functions for :class:`Layout`, their parameters
    ``(PS, PO, PE, PR, PG, PA, PD, CD, PV, PW)`` in the kernels' order, and the task's evaluation
    and the system's read-outs of the float state ``sample`` (their sizes and types)."""
    (step, ps), (observe, po), (evaluate, pe), (readouts, pr) = (
        parts.step,
        parts.observe,
        parts.evaluate,
        parts.readouts,
    )
    (rotation, pa) = parts.rotation if parts.rotation is not None else (None, ())
    (dissipation, pd) = parts.dissipation if parts.dissipation is not None else (None, ())
    share = None
    if dissipation is not None and parts.share is not None:
        share, pa_d = parts.share
        pd = (pd, pa_d)
    (event, pv) = parts.event if parts.event is not None else (None, ())
    rhs_event = None
    if parts.rhs_event is not None:  # (its parameters take the event's place)
        rhs_event, pv = parts.rhs_event
    switches, pw = _switch_parts(parts)
    values = evaluate(pe, tuple(sample), (0.0,) * n_action)
    physical = readouts(pr, tuple(sample), (0.0,) * n_control, False)
    layout = Layout(
        step,
        dim,
        n_control,
        n_action,
        observe,
        n_obs,
        evaluate,
        len(values) - 2,
        readouts,
        len(physical),
        rotation,
        dissipation,
        event,
        rhs_event,
        switches,
        parts.motion,
        share,
        None if parts.step_c is None else parts.step_c[0],
    )
    params = (ps, po, pe, pr, parts.guard_params, pa, pd, float(parts.dissipation_step), pv, pw)
    return layout, params, values, physical


class StateStep:
    """One env's compiled single-state step: :func:`state_kernel` of its layout, its
    parameters, and a ``(readouts, metrics, h) -> info`` function. Calling it returns the
    kernel's tuple. The first call compiles (once per layout and process) and then takes the
    compiled overload's entry point for these argument types, which skips numba's per-call
    type dispatch (much of a call's cost with the parameter tuples)."""

    def __init__(
        self,
        parts,
        dim: int,
        n_obs: int,
        n_control: int,
        n_action: int,
        sample,
        obs_high,
        h: float,
        dt: float,
        substeps: int,
        metric_names,
        readout_names,
        error=None,
    ):
        layout, params, _, _ = _layout(parts, dim, n_obs, n_control, n_action, sample)
        # error: a tolerance's (C, p, dt): the kernel returns each period's estimate last
        self.estimated = error is not None and layout.rotation is not None
        self.kernel = state_kernel(layout, self.estimated)
        high = tuple(float(v) for v in obs_high)
        self.params = (
            (float(h), float(dt), int(substeps))
            + params
            + (high,)
            + ((tuple(float(v) for v in error),) if self.estimated else ())
        )
        self.info = info_function(tuple(readout_names), tuple(metric_names))
        self._call = None

    def __call__(self, y, u, un, check: bool, refuse: bool):
        call = self._call
        if call is None:
            return self._first(y, u, un, check, refuse, self.params)
        return call(y, u, un, check, refuse, self.params)

    def compensated(self, y, cc, u, un, check: bool, refuse: bool):
        """The call of a layout with ``step_c``: the run's compensation ``cc`` in, and out last."""
        call = self._call
        if call is None:
            return self._first(y, cc, u, un, check, refuse, self.params)
        return call(y, cc, u, un, check, refuse, self.params)

    def _first(self, *args):
        import numba

        out = self.kernel(*args)  # compiles
        overload = self.kernel.overloads.get(tuple(numba.typeof(a) for a in args))
        self._call = overload.entry_point if overload is not None else self.kernel
        return out


class BatchResult(NamedTuple):
    """What :class:`BatchStep` returns. ``status``: 0, the number of non-finite new states (the
    task outputs are then unset), or -1 when ``refuse`` was set and a sub-env needs more than
    ``substeps`` steps (nothing was run; ``counts`` holds the counts). ``fired``: the terminal
    event ended the sub-env's period; ``h``: its internal step; ``counts``: its step count."""

    Y: object
    status: int
    obs: object
    over: object
    reward: object
    terminated: object
    metrics: tuple
    readouts: tuple
    fired: object
    h: object
    counts: object


class BatchStep:
    """One env's compiled batch step: the kernel of its layout plus its parameters.

    ``parts`` is :func:`rbenvs.core.parts.kernel_parts` (a
    :class:`rbenvs.core.parts.KernelParts`); ``dim`` the state size, ``n_obs`` the observation
    size, ``n_control`` the control size, ``n_action`` the normalised action's, ``sample`` any
    state (as floats) used once to learn the metrics' types, ``dt`` the control period.
    """

    def __init__(
        self,
        parts,
        dim: int,
        n_obs: int,
        n_control: int,
        sample,
        obs_high,
        n_action: int | None = None,
        dt: float | None = None,
    ):
        n_action = n_control if n_action is None else n_action
        layout, self.params, values, physical = _layout(
            parts, dim, n_obs, n_control, n_action, sample
        )
        self.n_metrics, self.n_readouts = layout.n_metrics, layout.n_readouts
        self.metric_dtypes, self.readout_dtypes = _dtypes(values, physical)
        self._bool, self._f32 = np.dtype(np.bool_), np.dtype(np.float32)
        self.layout = layout
        self.kernel = batch_kernel(layout)
        self.high = np.asarray(obs_high, dtype=np.float64)
        self.n_obs = n_obs
        self.dt = float(dt) if dt is not None else None

    def __call__(
        self,
        Y,
        u,
        u_norm,
        h: float,
        substeps: int,
        check: bool = False,
        skip=None,
        refuse: bool = False,
        CC=None,
    ) -> BatchResult:
        """One control period of the states ``Y`` ``(dim, n)`` under controls ``u`` and normalised
        actions ``u_norm`` (tuples of ``(n,)`` float64 arrays): a :class:`BatchResult`.
        ``check``: run the guard (else ``substeps`` steps each); ``skip`` (bool ``(n,)``):
        sub-envs about to restart; ``refuse``: ``guard="refuse"``; ``CC`` ``(dim, n)``: the
        runs' compensations, carried on in place (a compensated layout: a tolerance)."""
        n = Y.shape[1]
        Ynew = np.empty_like(Y)
        obs = np.empty((n, self.n_obs), self._f32)
        over = np.empty(n, self._bool)
        reward = np.empty(n)
        terminated = np.empty(n, self._bool)
        fired = np.empty(n, self._bool)
        hstep = np.empty(n)
        counts = np.empty(n, dtype=np.int64)
        metrics = tuple(np.empty(n, t) for t in self.metric_dtypes)
        readouts = tuple(np.empty(n, t) for t in self.readout_dtypes)
        if skip is None:
            skip = np.zeros(n, dtype=bool)
        dt = self.dt if self.dt is not None else h * substeps
        status = self.kernel(
            Y,
            Ynew,
            NO_COMPENSATION if CC is None else CC,
            u,
            u_norm,
            h,
            dt,
            substeps,
            check,
            refuse,
            skip,
            *self.params,  # PS, PO, PE, PR, PG, PA, PD, CD, PV, PW
            self.high,
            counts,
            hstep,
            fired,
            obs,
            over,
            reward,
            terminated,
            *metrics,
            *readouts,
        )
        return BatchResult(
            Ynew, status, obs, over, reward, terminated, metrics, readouts, fired, hstep, counts
        )

    def finish(self, Y):
        """``(obs, over, reward, terminated, metrics, readouts)`` of states ``Y`` ``(dim, k)`` that
        have just been reset (:func:`finish_kernel`: no control acted yet, zero action)."""
        k = Y.shape[1]
        obs = np.empty((k, self.n_obs), dtype=np.float32)
        over = np.empty(k, dtype=bool)
        reward = np.empty(k)
        terminated = np.empty(k, dtype=bool)
        metrics = tuple(np.empty(k, dtype=t) for t in self.metric_dtypes)
        readouts = tuple(np.empty(k, dtype=t) for t in self.readout_dtypes)
        ps, po, pe, pr, pg, pa, pd, cd, pv, pw = self.params
        finish_kernel(self.layout)(
            Y, po, pe, pr, self.high, obs, over, reward, terminated, *metrics, *readouts
        )
        return obs, over, reward, terminated, metrics, readouts


class VectorResult(NamedTuple):
    """What :class:`VectorStep` returns: ``status`` (0; ``-2``: a non-finite action; ``-1``:
    refused, ``counts`` holds the counts; or the number of non-finite new states: the task
    outputs are unset), ``n_ended`` (the sub-envs whose step had an end or a truncation), the
    step's arrays (see :func:`vector_kernel`), ``written``, the sub-envs whose row of the
    reason array may have been written, and ``n_restarted``, the number of sub-envs that
    restarted (NEXT_STEP; drawn inside the step where the model has a pure start). ``over``,
    ``fired``, ``counts`` and ``written`` are scratch, valid until the next step."""

    status: int
    n_ended: int
    Y: object
    obs: object
    over: object
    reward: object
    terminated: object
    truncated: object
    written: object
    metrics: tuple
    readouts: tuple
    fired: object
    h: object
    counts: object
    n_restarted: int
    # each period's error estimate (a layout with VectorLayout.estimate), 0 where no period ran
    estimate: object = None


# a split step's chunks start at multiples of this many sub-envs (no cache line of a bool
# array shared between threads; whole SIMD blocks)
_CHUNK_ALIGN = 64

# vector_kernel's arguments after (lo, hi, phase) and before its parameters
_HEAD = len(HEAD_ARGS)


def _entry_point(dispatcher, args):
    """The compiled overload of ``dispatcher`` for ``args``' types, called without numba's
    per-call typing (costly with forty arguments); the caller then
    passes arguments of those types only. The dispatcher itself where none is found."""
    import numba

    overload = dispatcher.overloads.get(tuple(numba.typeof(a) for a in args))
    return overload.entry_point if overload is not None else dispatcher


def _default_gate(parts, model, error):
    """The default accuracy's gate (``parts.gate``: its function, P and limit) where the stability
    bound alone never asks for more steps and the order ``error[1]`` is a whole number (the
    gate's powers are written out); else ``None``."""
    if parts.gate is not None and model.step_rule.stable(int(model.substeps)):
        return parts.gate if float(error[1]).is_integer() else None
    return None


def _scratch_arrays(n: int, layout) -> tuple:
    """A vector step's scratch ``(counts, fired, over, ends, codes, U, UN)`` for ``n`` sub-envs
    (no caller keeps them past the step: reused until the size changes)."""
    return (
        np.empty(n, dtype=np.int64),
        np.empty(n, dtype=bool),
        np.empty(n, dtype=bool),
        np.empty(n, dtype=np.int64),
        np.empty(n, dtype=np.int64),
        np.empty((layout.batch.n_control, n)),
        np.empty((layout.batch.n_action, n)),
    )


class VectorStep:
    """One vector env's compiled step (:func:`vector_kernel`) with its parameters, and its
    rows outside a step (:func:`rows_kernel`: a reset's finish, SAME_STEP restarts).

    ``parts``: :func:`rbenvs.core.parts.kernel_parts`; ``model``: the env's
    :class:`rbenvs.core.model.Model` (its actuator's and start's pure forms, its draw kinds);
    ``n_obs``: the observation size, ``obs_high`` its bounds; ``max_steps``: the time limit
    (``None``: none); ``error``: a tolerance's ``(C, p, dt)``
    (:attr:`rbenvs.stepsize.controller.StepRule.error`), with which the step also returns each
    period's error estimate (``None``: none). The call goes through the compiled overload's entry
    point after the first (numba's per-call typing of forty arguments costs more than a small
    batch's step); the actions must then be C-contiguous float32 or float64 (the caller converts).
    ``threads`` > 1: each step's sub-envs split into that many chunks, run at once
    (:class:`rbenvs.vector.threads.ThreadTeam`), with the same bits as one call.

    Calling it runs one step of the states ``Y`` ``(dim, n)`` under the actions ``A``
    ``(n, n_in)`` (float32 or float64, C-contiguous); ``steps`` and ``done`` (the episode clocks
    and the sub-envs whose episode ended) are updated in place; ``skip``: the sub-envs to restart
    (with ``next_step``); ``GEN`` the sub-envs' generators (a numba typed list,
    :class:`rbenvs.draws.GeneratorTable`); ``reasons``: ``(RZ, RN, clear)`` of a
    :class:`rbenvs.core.reasons.ReasonPool` array; ``CC`` ``(dim, n)``: the runs'
    compensations, carried on in place (a compensated layout: a tolerance), a restarting
    sub-env's set to zero."""

    def __init__(
        self,
        parts,
        model,
        n_obs: int,
        obs_high,
        max_steps: int | None,
        error=None,
        threads: int = 1,
    ):
        control, pc = model.kernel_control
        u_norm, u = control(pc, (0.0,) * model.actuator.size)
        sample = tuple(float(c) for c in model.initial_state(np.random.default_rng(0)))
        dim = model.system.dim
        layout, params, values, physical = _layout(parts, dim, n_obs, len(u), len(u_norm), sample)
        start = model.kernel_start()
        self.restarts = start is not None  # restarts inside the kernel (else the caller's)
        estimate = error is not None and layout.rotation is not None
        gate = _default_gate(parts, model, error) if estimate else None
        self.layout = VectorLayout(
            layout,
            control,
            model.actuator.size,
            start[0] if start else None,
            model.draw_kinds,
            estimate,
            gate[0] if gate else None,
            int(error[1]) if gate else 0,
        )
        self.kernel = vector_kernel(self.layout)
        # (the rows write no estimate: one kernel for both)
        self._rows = rows_kernel(self.layout._replace(estimate=False, gate=None, gate_order=0))
        self.metric_dtypes, self.readout_dtypes = _dtypes(values, physical)
        self._bool, self._f32 = np.dtype(np.bool_), np.dtype(np.float32)
        self.high = np.asarray(obs_high, dtype=np.float64)
        self.h, self.dt, self.substeps = float(model.h), float(model.dt), int(model.substeps)
        self.max_steps = -1 if max_steps is None else int(max_steps)
        self.charge = float(model.failure_charge)
        self.n_obs, self.dim = n_obs, dim
        # (PC, PI, the layout's ten, the bounds, the tolerance's (C, p, dt) or a placeholder)
        start_params = start[1] if start else ()
        tolerance = tuple(float(v) for v in error) if estimate else (0.0, 1.0, 0.0)
        self.params = (pc, start_params, *params, self.high, tolerance)
        self.gate_params = (gate[1], gate[2]) if gate else ((), 0.0)  # (PGT: its P and limit)
        self._calls = {}
        self._scratch = None
        self.threads = threads
        self._cuts = None
        self._split_calls = {}
        from ..vector.threads import splits

        self._splits = splits  # (False in a forked child that cannot run numba's threads: one call)
        # (a parallel loop's body takes no nested tuple from outside: the split kernel's
        # parameters go in flattened, once)
        self._flat_params, self._flat_gate = flat_leaves(self.params), flat_leaves(self.gate_params)

    def __call__(
        self,
        A,
        Y,
        steps,
        done,
        skip,
        GEN,
        check: bool,
        refuse: bool,
        next_step: bool,
        reasons,
        CC=None,
    ) -> VectorResult:
        """One step (its arguments: the class's docstring)."""
        n = Y.shape[1]
        scratch = self._scratch  # (the arrays no caller keeps past the step: reused)
        if scratch is None or scratch[0].shape[0] != n:
            scratch = self._scratch = _scratch_arrays(n, self.layout)
        counts, fired, over, ends, codes, U, UN = scratch
        estimate = np.empty(n if self.layout.estimate else 0)
        Ynew = np.empty_like(Y)
        hstep = np.empty(n)
        obs = np.empty((n, self.n_obs), self._f32)
        reward = np.empty(n)
        terminated = np.empty(n, self._bool)
        truncated = np.empty(n, self._bool)
        metrics = [np.empty(n, t) for t in self.metric_dtypes]
        readouts = [np.empty(n, t) for t in self.readout_dtypes]
        # the kernel's arguments: one tuple, passed on as it is, (lo, hi, phase) = (0, n, 0) first
        cc = NO_COMPENSATION if CC is None else CC
        head = (0, n, 0, A, Y, Ynew, cc, self.h, self.dt, self.substeps, check, refuse, next_step)
        middle = (self.max_steps, self.charge, steps, done, skip, GEN, *self.params, counts, hstep)
        tail = (fired, obs, over, reward, terminated, truncated, *reasons, ends, codes, U, UN)
        args = (*head, *middle, *tail, estimate, self.gate_params, *metrics, *readouts)
        # (a bad action: refused by the whole step, nothing written)
        if self.threads > 1 and n >= 2 * _CHUNK_ALIGN and np.isfinite(A).all() and self._splits():
            status, k, written, r = self._split(A.dtype, args, n, refuse and CC is not None, ends)
        else:
            call = self._calls.get(A.dtype)
            status, k, m, r = call(*args) if call is not None else self._first(A.dtype, args)
            written = ends[:m]
        return VectorResult(
            status,
            k,
            Ynew,
            obs,
            over,
            reward,
            terminated,
            truncated,
            written,
            metrics,
            readouts,
            fired,
            hstep,
            counts,
            r,
            estimate if self.layout.estimate else None,
        )

    def _first(self, dtype, args) -> tuple:
        """The first call with actions of ``dtype`` (the kernel's arguments ``args``): compiles
        the kernel (or loads it) and keeps its overload's entry point for the next calls."""
        out = self.kernel(*args)  # compiles
        self._calls[dtype] = _entry_point(self.kernel, args)
        return out

    def _split(self, dtype, args, n: int, keep_cc: bool, ends) -> tuple:
        """The step as chunks of sub-envs, one per thread, in one call (:func:`split_kernel`):
        every chunk's phase 1 (the guard's counts, the period, its non-finite check) at once, then,
        where no chunk refused and every new state is finite, every chunk's phase 2.
        ``(status, k, ends, r)`` as one call's: a refusal (-1) before a non-finite count;
        ``args``: the one call's arguments (its ``(0, n, 0)`` dropped here: each chunk has its
        own); ``keep_cc``: the compensations, carried in place, put back on a refusal (one call
        writes none)."""
        import numba

        if self._cuts is None or self._cuts[-1] != n:
            self._chunk(n)
        cuts, S = self._cuts, self._S
        args = args[3:]
        # the leaves: the two parameter tuples flattened (the step's come after the kernel's
        # _HEAD leading arguments, the gate's before the metrics' and read-outs' arrays)
        p, q = _HEAD, _HEAD + len(self.params)
        g = len(args) - len(self.metric_dtypes) - len(self.readout_dtypes) - 1
        leaves = (*args[:p], *self._flat_params, *args[q:g], *self._flat_gate, *args[g + 1 :])
        CC = args[3]
        saved = CC.copy() if keep_cc else None
        call = self._split_calls.get(dtype)
        # the chunks run on this many of numba's threads (a setting of the calling thread, put
        # back after; set only where it differs, so the usual step makes no call to set it)
        before = numba.get_num_threads()
        if before != self._width:
            numba.set_num_threads(self._width)
        try:
            if call is None:  # (compiled or loaded on the first split)
                kernel = split_kernel(self.layout, tuple_shape(args))
                status = kernel(cuts, S, *leaves)
                self._split_calls[dtype] = _entry_point(kernel, (cuts, S, *leaves))
            else:
                status = call(cuts, S, *leaves)
        finally:
            if before != self._width:
                numba.set_num_threads(before)
        if status == -1 and saved is not None:
            CC[...] = saved
        if status != 0:
            return status, 0, ends[:0], 0
        rows = S.tolist()  # (a few Python ints: cheaper than numpy's reductions on a tiny array)
        written = (
            np.concatenate([ends[lo : lo + row[2]] for lo, row in zip(self._lows, rows)])
            if any(row[2] for row in rows)
            else ends[:0]
        )
        return 0, sum(row[1] for row in rows), written, sum(row[3] for row in rows)

    def _chunk(self, n: int) -> None:
        """The split of ``n`` sub-envs (on the first split and a size change): ``_cuts``, the
        chunks' bounds (whole SIMD blocks), ``_S`` their result rows, ``_width`` the threads
        that run them (at most numba's pool), ``_lows`` their starts as ints."""
        from ..vector.threads import pool_size

        cuts = [
            min(n, round(n * c / self.threads / _CHUNK_ALIGN) * _CHUNK_ALIGN)
            for c in range(self.threads + 1)
        ]
        cuts[-1] = n
        self._cuts = np.unique(np.asarray(cuts, dtype=np.int64))
        self._S = np.zeros((len(self._cuts) - 1, 4), dtype=np.int64)
        self._width = min(len(self._cuts) - 1, pool_size())  # (numba's threads: at most its pool)
        self._lows = self._cuts[:-1].tolist()

    def rows(self, idx, draw, Y, GEN, obs, over, hstep, steps, metrics, readouts) -> None:
        """:func:`rows_kernel` on the sub-envs ``idx`` of a step's (or a reset's) arrays: their
        starts drawn where ``draw``, their rows of the observation, metrics and read-outs
        filled."""
        self._rows(
            *self._rows_args(
                np.asarray(idx, dtype=np.int64),
                np.asarray(draw, dtype=np.bool_),
                Y,
                GEN,
                obs,
                over,
                hstep,
                steps,
                metrics,
                readouts,
            )
        )

    def _rows_args(self, idx, draw, Y, GEN, obs, over, hstep, steps, metrics, readouts) -> tuple:
        """:func:`rows_kernel`'s arguments, the start's, task's and read-outs' parameters in
        place."""
        pi, po, pe, pr = self.params[1], self.params[3], self.params[4], self.params[5]
        return (
            idx,
            draw,
            Y,
            GEN,
            pi,
            po,
            pe,
            pr,
            self.high,
            self.h,
            obs,
            over,
            hstep,
            steps,
            *metrics,
            *readouts,
        )

    def finish(self, Y, GEN) -> tuple:
        """``(obs, over, metrics, readouts)`` of the states ``Y`` ``(dim, k)`` as after a reset (no
        control acted, zero action): :func:`rows_kernel` without draws (``GEN``: the env's
        generators, only for the kernel's one signature)."""
        k = Y.shape[1]
        obs = np.empty((k, self.n_obs), dtype=np.float32)
        over = np.empty(k, dtype=bool)
        metrics = tuple(np.empty(k, dtype=t) for t in self.metric_dtypes)
        readouts = tuple(np.empty(k, dtype=t) for t in self.readout_dtypes)
        self.rows(
            np.arange(k),
            np.zeros(k, dtype=bool),
            Y,
            GEN,
            obs,
            over,
            np.empty(k),
            np.zeros(k, dtype=np.int64),
            metrics,
            readouts,
        )
        return obs, over, metrics, readouts


class Backend:
    """What the step core builds from this module (:class:`rbenvs.core.step.Engine` takes a
    loader of it, :class:`rbenvs.contracts.CompiledBackend`): the core imports no compiled code."""

    StateStep = StateStep
    CheckedRuns = CheckedRuns
    PeriodPlan = PeriodPlan
    DISABLE_VARIABLE = DISABLE_VARIABLE
    available = staticmethod(available)

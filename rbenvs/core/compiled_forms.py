"""The compiled forms of one model's step, for the engine that runs it (:mod:`rbenvs.core.step`).

The core imports no compiled code: an engine is given a loader of the backend
(:class:`rbenvs.contracts.CompiledBackend`), and :class:`CompiledForms` builds from it, each on
its first use, the single-state step (``StateStep``: the single env's period and finish as one
call), ``tolerance_check``'s runs (``CheckedRuns``) and a tolerance's period plan
(``PeriodPlan``: the guard's ratio and the rates its estimate reads, from one evaluation).
``compiled="auto"`` uses each where numba is installed and every part of the model has a pure
form (compiling costs about a second per layout and process, so nothing is built before it is
used); ``False`` keeps the float path; ``True`` demands the form the env runs, with a
``ValueError`` saying why it cannot be had. Each form computes the float path's bits (tested).
"""

from __future__ import annotations

import numpy as np

from ..jit import DISABLE_VARIABLE

__all__ = ["CompiledForms"]


class CompiledForms:
    """The compiled forms of ``engine``'s model (its public parts: ``kernel_parts``, its rule and
    sizes), under ``compiled`` (``"auto"``, ``True`` or ``False``)."""

    def __init__(self, engine, compiled):
        self.engine = engine
        m = engine.model
        # the single-state step: not under tolerance_check (its periods take even counts, run by
        # the checked runs, with the finish on floats)
        self.one, self.one_tried = None, compiled is False or m.check
        self.runs, self.runs_tried = None, compiled is False or not m.check
        self.plan, self.plan_tried = (
            None,
            m.tolerance is None or compiled is False or engine.rule.rotation is None,
        )

    def require(self) -> None:
        """``compiled=True``: the form the env runs built now (the checked runs under
        ``tolerance_check``, else the single-state step), or a ``ValueError`` saying why it
        cannot be had."""
        if self.engine.model.check:
            self.runs = self._build_runs(required=True)
        else:
            self.one = self._build_one(required=True)

    @property
    def state_step(self):
        """The compiled single-state step the single env runs (:class:`rbenvs.compiled.StateStep`),
        or ``None`` (the float path); built on first use."""
        if not self.one_tried:
            self.one = self._build_one(required=False)
        return self.one

    @property
    def checked_runs(self):
        """The compiled runs of the checked period (:class:`rbenvs.compiled.CheckedRuns`), or
        ``None`` (the float path; always without ``tolerance_check``); built on first use."""
        if not self.runs_tried:
            self.runs = self._build_runs(required=False)
        return self.runs

    @property
    def planner(self):
        """The compiled plan of one state's period (:class:`rbenvs.compiled.PeriodPlan`), or
        ``None`` (the float path's :meth:`StepRule.plan`; always without a tolerance); built
        on first use."""
        if not self.plan_tried:
            self.plan_tried = True
            inputs = self._inputs(required=False)
            self.plan = (
                None if inputs is None else self.engine.backend().PeriodPlan(inputs[0], *inputs[1])
            )
        return self.plan

    def plan_one(self, y, u):
        """One state's ``(x, lam, lam_d, a)`` (:meth:`StepRule.plan`): the guard's ratio and
        the rates its error estimate reads, compiled where it can be."""
        plan = self.plan if self.plan_tried else self.planner
        if plan is not None:
            return plan(y, u)
        return self.engine.rule.plan(y, u)

    def rates_batch(self, y, u, Y=None):
        """A batch's ``(lam, lam_d, a)``, the rates its error estimate reads (arrays; ``lam`` a
        tuple of three with the state's own speed; :meth:`StepRule.plan`'s per element, its ratio
        not evaluated): compiled in one loop over the batch where it can be
        (:meth:`rbenvs.compiled.PeriodPlan.batch`), else numpy's (:meth:`StepRule.batch_rates`).
        ``u``: the batch's controls (``None``: the zero action's); ``Y``: ``y`` as one ``(dim,
        n)`` float64 array where the caller has it."""
        rule, plan = self.engine.rule, self.plan if self.plan_tried else self.planner
        if plan is not None:
            r, lam_d, a = plan.batch(*self.plan_inputs(plan, y, u, Y))
            return (tuple(r) if rule.motion else r[0]), lam_d, a
        return rule.batch_rates(y, u)

    def plan_inputs(self, plan, y, u, Y=None):
        """``(Y, U)``: a batch's states and controls as the compiled plan takes them."""
        Y = np.ascontiguousarray(np.stack(y) if Y is None else Y, dtype=np.float64)
        U = np.zeros((plan.layout.n_control, Y.shape[1]))
        for j, c in enumerate(
            self.engine.rule.zero_control if u is None else u
        ):  # (None: the zero action's, as StepRule.rate reads it)
            U[j] = c
        return Y, U

    def counts(self, y, u):
        """A batch's guard counts (:meth:`StepRule.steps`), their ratios compiled where they can
        be."""
        engine = self.engine
        rule, plan = engine.rule, self.plan if self.plan_tried else self.planner
        if plan is None or not rule.active:
            return np.broadcast_to(np.asarray(rule.steps(y, u, engine.substeps)), np.shape(y[0]))
        return rule.counts(plan.ratios(*self.plan_inputs(plan, y, u)), engine.substeps)

    def _inputs(self, required: bool):
        """``(parts, sizes and sample)`` for a compiled form of the model's step: the pure parts
        (``kernel_parts``), ``(dim, n_obs, n_control, n_action, sample)``; ``None`` where numba is
        missing or a part has no pure form (``required``: a ``ValueError`` saying which)."""
        engine = self.engine
        backend = None if engine.backend is None else engine.backend()
        usable = backend is not None and backend.available()
        parts = engine.kernel_parts() if usable else None
        if parts is None:
            if required:
                why = (
                    f"numba is not installed (the 'fast' extra) or {DISABLE_VARIABLE}=0 is set"
                    if not usable
                    else f"integrator {engine.integrator.name!r} with task {engine.task.name!r} "
                    "and these settings has no compiled step"
                )
                raise ValueError(f"compiled=True but {why}")
            return None
        m = engine.model
        u_norm, u = m.actuator.control((0.0,) * m.actuator.size)
        sample = tuple(float(c) for c in m.initial_state(np.random.default_rng(0)))
        return parts, (engine.system.dim, len(engine.high_list), len(u), len(u_norm), sample)

    def _build_one(self, required: bool):
        self.one_tried = True
        inputs = self._inputs(required)
        if inputs is None:
            return None
        parts, sizes = inputs
        engine = self.engine
        return engine.backend().StateStep(
            parts,
            *sizes,
            engine.high_list,
            engine.h,
            engine.dt,
            engine.substeps,
            engine.metric_names,
            engine.readout_names,
            engine.rule.error,
        )

    def _build_runs(self, required: bool):
        self.runs_tried = True
        inputs = self._inputs(required)
        return None if inputs is None else self.engine.backend().CheckedRuns(inputs[0], *inputs[1])

"""A model's step in pure forms, ``(function, parameters)`` each: what the compiled backend
(:mod:`rbenvs.compiled`) builds its kernels from. The same functions the float path calls, so
the kernels compute the float path's bits (the lockstep tests)."""

from __future__ import annotations

from typing import NamedTuple

__all__ = ["KernelParts", "kernel_parts"]


def kernel_parts(period, system, task):
    """What :class:`rbenvs.compiled.BatchStep` needs to run a model's ``period``
    (:class:`rbenvs.core.period.Period`) and its finish (``system``'s read-outs, ``task``'s
    observation and evaluation) on a batch (:class:`KernelParts`), or ``None`` where a part has
    no pure form (the batch then runs on numpy): the integrator's pure step, the task's
    observation and evaluation, the system's read-outs, the guard's rates, and a hybrid system's
    terminal event or switches (free flight)."""
    step = period.integrator.kernel_step(system)
    step_c = (
        period.integrator.kernel_step(system, compensated=True)
        if period.step_c is not None
        else None
    )
    readouts = system.kernel_readouts
    if step is None or task.kernels is None or readouts is None:
        return None
    switches = ()
    if period.switching is not None:  # hybrid switching: the system's switches in pure forms
        switches = system.kernel_switches  # (switching is a hybrid system's)
        if switches is None:
            return None
    event = rhs_event = None
    if period.event is not None:
        event = system.kernel_event  # (an event is a hybrid system's)
        if event is None:
            return None
        # the event's evaluation shared with the next step's first stage, where both the
        # system (the vector field and the event from one evaluation) and the scheme allow
        rhs_event = system.kernel_rhs_event
        first = period.integrator.kernel_step_first_stage(system) if rhs_event is not None else None
        if first is not None:
            step = first
            step_c = period.shared_c
        else:
            rhs_event = None
    if period.step_c is not None and step_c is None:  # (the float path sums with compensation)
        return None
    rule = period.rule
    rotation, dissipation = None, None
    if rule.active:  # checked only where asked (a period that may not take the plain loop)
        rotation, dissipation = rule.rotation, rule.dissipation
    observe, evaluate = task.kernels(system)
    return KernelParts(
        step,
        observe,
        evaluate,
        readouts,
        rotation,
        rule.params,
        dissipation,
        rule.dissipation_step,
        event,
        rhs_event,
        tuple(switches),
        rule.motion and rotation is not None,
        rule.share if dissipation is not None else None,
        step_c,
        rule.gate if rotation is not None and dissipation is None else None,
    )


class KernelParts(NamedTuple):
    """A model's step in pure forms, each ``(function, parameters)`` (:func:`kernel_parts`):
    ``step`` (the integrator's, ``step(PS, y, u, h)``), ``observe``, ``evaluate``, ``readouts``
    (the task's and the system's), the guard's ``rotation`` rate (``None``: no check can be
    needed) with ``guard_params`` (``(dt, bound, growth, k, p, kd)`` of
    :func:`rbenvs.stepsize.forms.step_ratio`), its ``dissipation`` rate (or ``None``) with
    ``dissipation_step`` (``h <= c / lambda_d``), the terminal ``event`` (or ``None``; it fires
    where its value is negative) and ``rhs_event``, the vector field and the event's value from
    one evaluation (then ``step`` takes its first stage: ``step(PS, y, k0, u, h)``), or ``None``;
    ``switches``: a hybrid system's switches, ``((applies, P), (function, P), tolerance, (switch,
    P))`` each (``kernel_switches``), made after every internal step as :mod:`rbenvs.core.hybrid`
    makes them."""

    step: tuple
    observe: tuple
    evaluate: tuple
    readouts: tuple
    rotation: tuple | None
    guard_params: tuple
    dissipation: tuple | None
    dissipation_step: float
    event: tuple | None
    rhs_event: tuple | None = None
    switches: tuple = ()
    motion: bool = False  # rotation is (fn, P) with fn(P, y, u) -> (lambda, mu): step_ratio_motion
    share: tuple | None = (
        None  # (fn, P): the decaying mode's share of its error term (StepRule.share)
    )
    # (fn, P): step's compensated form (a tolerance: Period.step_c), fn(PS, y, c, u, h) -> (y, c)
    # (with rhs_event fn(PS, y, c, k0, u, h)); None: the plain step
    step_c: tuple | None = None
    # the default accuracy's gate (StepRule.gate): (fn, P, limit); None: none
    gate: tuple | None = None

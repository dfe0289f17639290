"""An env's accuracy settings, resolved at its construction: ``tolerance=``,
``tolerance_horizon=`` and ``tolerance_check=`` against the env's default accuracy, the scheme
``integrator="auto"`` takes, and the steps a control period needs at the fastest start (a
period that no run could resolve is refused here, not at the first step)."""

from __future__ import annotations

import dataclasses
import math

from ..dynamics.validation import require_int_in
from .check import require_tolerance_check
from .controller import (
    MAX_INTERNAL_STEPS,
    StepRule,
    default_accuracy,
    require_tolerance,
    takes_tolerance,
)
from .forms import relaxation_steps, stability_ratio, step_ratio

__all__ = ["accuracy_settings", "cheapest_scheme", "start_steps", "require_resolvable"]


def accuracy_settings(tolerance, horizon, check, guard: str, default, episode_steps):
    """``(tolerance, horizon, check, accuracy)`` from the keywords: ``tolerance`` validated, the
    env's ``default`` accuracy resolved (``accuracy``: ``"default"`` or ``"explicit"``),
    ``horizon`` the control periods it covers (``None``: the registered episode's
    ``episode_steps``, else 1000; without a tolerance refused) and ``check`` the measured
    check's setting."""
    tolerance = require_tolerance(tolerance)
    if tolerance is None and horizon is not None:
        raise ValueError(
            f"tolerance_horizon={horizon!r} is the span of control periods that tolerance= "
            "covers, and tolerance is None: pass tolerance= with it, or leave tolerance_horizon out"
        )
    tolerance, accuracy = default_accuracy(tolerance, guard, default)
    check = require_tolerance_check(check, tolerance)
    if horizon is None:
        horizon = 1000 if episode_steps is None else episode_steps
    else:
        horizon = require_int_in(
            "tolerance_horizon", horizon, 1, 10**12, " (control periods over which tolerance holds)"
        )
    return tolerance, horizon, check, accuracy


def cheapest_scheme(schemes, system, tolerance, model_with, speed: float, dissipation: float):
    """``integrator="auto"``: of the ``schemes`` (instances, in the registry's order) that
    ``tolerance=`` takes (:func:`~rbenvs.stepsize.controller.takes_tolerance`) and that take
    ``system``, the one whose internal steps at the fastest start (:func:`start_steps`), times
    its vector field's evaluations a step, cost the least (ties: the first).
    ``model_with(scheme)``: the env's model with that scheme."""
    if tolerance is None:
        raise ValueError(
            "integrator='auto' chooses the scheme that meets tolerance= at the least cost: pass "
            "tolerance= (a relative error per episode)"
        )
    best = None
    for scheme in schemes:
        if not takes_tolerance(type(scheme)) or not scheme.evaluations:
            continue
        if not scheme.supports(system):
            continue
        model = model_with(scheme)
        x = start_steps(model, speed, dissipation)[0]
        steps = max(model.substeps, math.ceil(x)) if x <= MAX_INTERNAL_STEPS else math.inf
        cost = steps * scheme.evaluations
        if best is None or cost < best[0]:
            best = (cost, scheme)
    if best is None:
        raise ValueError(
            f"integrator='auto' found no scheme with an error constant for {type(system).__name__}"
        )
    return best[1]


def start_steps(model, speed: float, dissipation: float = 0.0) -> tuple[float, str, bool]:
    """``(x, rule, by_tolerance)``: the internal steps per control period (``ceil(x)``) the step
    rule asks for at the fastest start (``speed``: an upper bound of ``|Omega|`` there;
    ``dissipation``: the stiffest decaying rate, 0 where none), the rule in words, and whether
    only the tolerance asks for more than ``MAX_INTERNAL_STEPS``. Integrators without a bound of
    their own (exact flows, adaptive schemes) count one radian of the fastest rate per step."""
    integrator, dt = model.integrator, model.dt
    region = integrator.region
    if not region.bounded:
        region = dataclasses.replace(
            region, rotation=1.0, reason="one radian of the fastest rate per step"
        )
    rates = model.system.guard_rates(region, speed)
    rule = StepRule.build(
        rates, region, dt, "subdivide", integrator, model.tolerance, model.horizon
    )
    x = step_ratio(rule.params, rates.ceiling)
    d_stable = 0.0
    if rule.dissipation is not None and dissipation > 0.0:
        d_stable = dt / (rule.dissipation_step / dissipation)
        # (the accuracy term 0 without a tolerance; the mode's full share: no state yet)
        x = max(x, d_stable, relaxation_steps(rule.params, dissipation, 1.0))
    if rule.error is None:
        return x, rule.text, False
    if not max(stability_ratio(*rule.params[:3], rates.ceiling), d_stable) <= MAX_INTERNAL_STEPS:
        return x, rule.text, False
    # only the tolerance asks for more: say so, with the reason
    p = integrator.order
    return (
        x,
        f"to keep the error of {model.horizon} periods within it ({rule.accuracy_text}): at a "
        f"fixed step an order-{p} scheme's error grows without bound, like lambda T (lambda "
        f"h)^{p}, so the steps a tolerance costs grow like (lambda T)^{(p + 1) / p:.3g} / "
        f"tolerance^{1 / p:.3g}; raise tolerance, lower tolerance_horizon, or use a "
        "higher-order integrator",
        True,
    )


def require_resolvable(model, speed, dissipation, env_name: str, rate_sources: str) -> None:
    """Refuse, at construction, a control period that no run could resolve: more than
    ``MAX_INTERNAL_STEPS`` internal steps at the start (:func:`start_steps`) would end the first
    step as a numerical failure (``dt=1e300``; a friction, gravity or spin so large that its time
    scale is far below the step). The error names the env's keywords that set the rate
    (``rate_sources``), or the tolerance. ``guard="off"`` opts out: it takes ``substeps`` steps
    whatever the state (a blow-up is then reported as a numerical failure)."""
    if model.guard == "off":
        return
    x, rule, by_tolerance = start_steps(model, speed, dissipation)
    if x <= MAX_INTERNAL_STEPS:
        return
    name = model.integrator.name
    if by_tolerance:
        default = (
            f" (tolerance='default': {env_name}'s default accuracy; tolerance=None runs "
            "unchecked, the stability bound alone)"
            if model.accuracy != "explicit"
            else ""
        )
        raise ValueError(
            f"tolerance={model.tolerance!r}{default} cannot be met: at the start the integrator "
            f"{name!r} needs {x:.3g} internal steps per control period, more than "
            f"MAX_INTERNAL_STEPS = {MAX_INTERNAL_STEPS}, {rule}"
        )
    raise ValueError(
        f"dt={model.dt!r} s cannot be resolved: at the start the integrator {name!r} needs "
        f"{x:.3g} internal steps per control period ({rule}), more than MAX_INTERNAL_STEPS = "
        f"{MAX_INTERNAL_STEPS}; lower dt, or check {rate_sources}, which set the fastest rate"
    )

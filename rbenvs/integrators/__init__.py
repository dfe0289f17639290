"""Integrators as swappable, stateless objects, selected by name.

==========  =====  ===========================================================
name        order  what it is
==========  =====  ===========================================================
euler       1      forward Euler: cheapest, drifts, unstable at large |Omega| h
rk4         4      classical Runge-Kutta: accurate per step, slow drift
splitting   2      Strang composition of exact sub-flows: |Pi| exact, energy bounded
exact       exact  exact uncontrolled flow (+ torque kicks, 2nd order, with control)
dop853      8      scipy adaptive DOP853 at rtol 1e-12: the accuracy reference
==========  =====  ===========================================================

Not registered by name (pass an instance, ``integrator=Ros2()``): ``Ros2``, order 2, the
Rosenbrock-W method of Verwer et al. (1999), L-stable, linearly implicit in the tippe top's
friction and explicit elsewhere (:mod:`.rosenbrock`): an experiment on the stiff friction, not
accurate enough near zero slip at the step counts where it would pay (docs/accuracy.md).
"""

from __future__ import annotations

from ..dynamics.validation import did_you_mean
from .base import Integrator
from .exact import Exact
from .reference import Dop853
from .rosenbrock import Ros2
from .runge_kutta import RK4, ButcherTableau, Euler, ExplicitRungeKutta
from .splitting import Splitting

__all__ = [
    "Integrator",
    "ButcherTableau",
    "ExplicitRungeKutta",
    "Euler",
    "RK4",
    "Splitting",
    "Exact",
    "Dop853",
    "Ros2",
    "INTEGRATORS",
    "get_integrator",
]

INTEGRATORS: dict[str, type[Integrator]] = {
    cls.name: cls for cls in (Euler, RK4, Splitting, Exact, Dop853)
}


def get_integrator(name: str | Integrator, **options) -> Integrator:
    """The integrator called ``name`` (options go to its constructor, e.g. dop853's ``rtol``).

    An :class:`Integrator` instance is passed through unchanged.
    """
    if isinstance(name, Integrator):
        return name
    try:
        cls = INTEGRATORS[name]
    except (KeyError, TypeError):
        raise ValueError(
            f"integrator must be one of {sorted(INTEGRATORS)}, got "
            f"{name!r}{did_you_mean(name, INTEGRATORS)}"
        ) from None
    return cls(**options)


def integrator_for(name, system) -> Integrator:
    """:func:`get_integrator`'s ``name`` for an env of ``system``: its declarations checked
    (:class:`~rbenvs.contracts.Integrator`, read by the step), refused where it does not take
    the system or declares no step region (nothing could guard its step)."""
    from ..contracts import require_parts

    integrator = get_integrator(name)
    require_parts(integrator, Integrator, "integrator")
    if not integrator.supports(system):
        raise ValueError(
            f"integrator {integrator.name!r} is not available for {type(system).__name__}"
        )
    if integrator.region is None:
        raise ValueError(
            f"integrator {integrator.name!r} declares no step region (StepRegion, "
            "rbenvs.contracts): it cannot be guarded"
        )
    return integrator

"""What a tippe top derives from its parameters: the friction law, the pure forms and their
parameters, and the ``kernel_*`` pairs the generated and compiled steps call
(:class:`rbenvs.contracts.HybridSystem`)."""

from __future__ import annotations

from types import SimpleNamespace

from ..contact import FRICTION_LAWS, no_friction
from .forms import (
    flight_airborne,
    flight_gap,
    flight_on_table,
    flight_take_off,
    flight_touch_down,
    pure_forms,
    pure_parameters,
)
from .implicit import ImplicitForms, implicit_forms
from .params import LIFT_OFF_TOL, TOUCHDOWN_TOL
from .stem import (
    STEM_TOL,
    stem_accuracy_rate,
    stem_forms,
    stem_on_sphere,
    stem_on_stem,
    stem_other_gap,
    stem_switch,
)

__all__ = ["DERIVED", "derived_parts"]

# what a top derives from its parameters: the pure forms are functions made per combination
# (closures, which pickle cannot carry), so a pickle carries the parameters and the rest is made
# again on loading
DERIVED = (
    "friction_law",
    "friction",
    "forms",
    "form_params",
    "kernel_rhs",
    "kernel_rhs_normal",
    "kernel_normalize",
    "kernel_readouts",
    "kernel_normal",
    "kernel_gap",
    "kernel_take_off",
    "kernel_touch_down",
    "kernel_on_table",
    "kernel_airborne",
    "kernel_event",
    "kernel_rhs_event",
    "kernel_switches",
    "implicit",
    "kernel_implicit",
)


def derived_parts(params, fidelity: str, rolling: bool, flight: bool, stem: bool) -> dict:
    """The attributes :data:`DERIVED` of a top of ``params`` at ``fidelity`` (with ``rolling``,
    ``flight`` and ``stem`` as it declares them): the friction law's name and object (``None``
    unless gliding), the pure forms and their ``P``, and each ``kernel_*`` pair (``None`` where
    the top has no such form, or for a friction law given by its methods alone)."""
    d = SimpleNamespace()
    d.friction_law = None if fidelity != "gliding" else params.friction_law  # its name
    d.friction = (
        None if d.friction_law is None else FRICTION_LAWS[d.friction_law]
    )  # the law (dynamics.contact)
    coefficient, stiffness = (no_friction, None) if d.friction is None else d.friction.pure_forms()
    if stem:
        d.forms = forms = stem_forms(coefficient, stiffness)
    else:
        d.forms = forms = pure_forms(coefficient, stiffness, rolling, flight)
    d.form_params = p = pure_parameters(params)
    compilable = d.friction is None or d.friction.compilable
    _set_kernel_pairs(d, p, compilable, flight, stem)
    d.implicit, d.kernel_implicit = _implicit_parts(
        d.friction, coefficient, stiffness, p, compilable, (rolling, flight, stem)
    )
    d.kernel_switches = _kernel_switches(params, forms, p, flight, stem, compilable)
    return {name: getattr(d, name) for name in DERIVED}


def _set_kernel_pairs(d, p, compilable: bool, flight: bool, stem: bool) -> None:
    """Each ``kernel_*`` pair ``(fn, p)`` of ``d.forms`` on ``d``: ``None`` where the top has no
    such form, or for a friction law that cannot be compiled."""
    forms = d.forms

    def pair(fn, offered=True):
        return (fn, p) if compilable and offered else None

    d.kernel_rhs = pair(forms.rhs)
    d.kernel_rhs_normal = pair(forms.rhs_normal)
    d.kernel_normalize = pair(forms.normalize)
    d.kernel_readouts = pair(forms.readouts)
    d.kernel_normal = pair(forms.normal)
    d.kernel_gap = pair(forms.gap)
    d.kernel_take_off = pair(flight_take_off, flight)
    d.kernel_touch_down = pair(flight_touch_down, flight)
    d.kernel_on_table = pair(flight_on_table, flight)
    d.kernel_airborne = pair(flight_airborne, flight)
    # the hybrid contract's pure forms (rbenvs.contracts.HybridSystem): without flight the
    # terminal event is the lift-off (N < 0), checked from the contact solve that is also
    # the next step's first stage; with flight the two switches of events()
    d.kernel_event = pair(forms.normal, not flight)
    # (with the stem the switches come between a step and the check: no shared first stage)
    d.kernel_rhs_event = pair(forms.rhs_normal, not flight and not stem)


def _implicit_parts(friction, coefficient, stiffness, p, compilable: bool, kinds: tuple):
    """``(implicit, kernel_implicit)``: the friction's linearisation (ImplicitForms): the
    W-matrix of a linearly implicit scheme, ``(factor, solve, P)``; the tight stiffness rate;
    ``None`` for a law with no slope. ``kinds`` is ``(rolling, flight, stem)``."""
    rolling, flight, stem = kinds
    slope = None if friction is None else friction.kernel_slope
    implicit = None
    if friction is None or (slope is not None and compilable):
        saturates = friction is not None and friction.saturates
        implicit = implicit_forms(coefficient, stiffness, slope, rolling, flight, saturates)
    kernel_implicit = None if implicit is None else (implicit.factor, implicit.solve, p)
    if stem and implicit is not None:
        # with the stem: the accuracy rate at the pressing contact; no W-matrix (the linearly
        # implicit schemes are not offered: their solve is written for the 11 components)
        rate = implicit.accuracy_rate
        implicit = ImplicitForms(
            None, None, None, None if rate is None else stem_accuracy_rate(rate)
        )
        kernel_implicit = None
    return implicit, kernel_implicit


def _kernel_switches(params, forms, p, flight: bool, stem: bool, compilable: bool):
    """The compiled switches ``(applies, function, tolerance, switch)`` of the stem's two
    contacts or of free flight; ``None`` for neither or a law that cannot be compiled."""
    switches = None
    if stem and compilable:
        tol = STEM_TOL * min(params.radius, params.stem[0])
        switches = (
            ((stem_on_sphere, ()), (stem_other_gap, p), tol, (stem_switch, p)),
            ((stem_on_stem, ()), (stem_other_gap, p), tol, (stem_switch, p)),
        )
    if flight and compilable:
        switches = (
            (
                (flight_on_table, ()),
                (forms.normal, p),
                LIFT_OFF_TOL * params.mass * params.gravity,
                (flight_take_off, ()),
            ),
            (
                (flight_airborne, ()),
                (flight_gap, p),
                TOUCHDOWN_TOL * params.radius,
                (flight_touch_down, p),
            ),
        )
    return switches

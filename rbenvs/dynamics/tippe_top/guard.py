"""The tippe top's step guard: the rates a step must resolve (the contact geometry turning with
the body, the friction's stiffness) and the largest stable step under friction."""

from __future__ import annotations

import math

import numpy as np

from ...contracts import GuardRates, StepRegion
from .params import (
    ACCURACY_MARGIN,
    FRICTION_MARGIN,
    SPIN_STEP,
    tippe_rotation_rate,
)

__all__ = ["friction_stiffness", "guard_rates", "max_stable_step"]


# Near zero slip regularised Coulomb friction is a viscous law of rate mu N |M| / eps (viscous:
# mu N |M|), |M| the contact mobility: stiff, a decaying (negative real) rate. The guard takes
# twice the larger of m g and the current N (N varies within a control period) and keeps half
# of the scheme's real-axis interval (FRICTION_MARGIN).
def friction_stiffness(system, mu, normal_force=None):
    """``lambda_d`` [1/s]: the friction law's stiffness (:mod:`rbenvs.dynamics.contact`) at
    twice ``max(m g, N)`` and the contact mobility ``|M|`` (Coulomb: ``mu 2 max(m g, N) |M|
    / eps``); 0 without friction. ``mu`` and ``normal_force`` may be arrays (a batch)."""
    if system.friction is None:
        return 0.0
    prm = system.params
    weight = prm.mass * prm.gravity
    load = weight if normal_force is None else np.maximum(weight, normal_force)
    return system.friction.stiffness(
        mu, 2.0 * load, prm.contact_mobility(), prm.slip_regularization
    )


def guard_rates(system, region, speed_ceiling: float, dt: float) -> GuardRates:
    """The contact geometry turns with the body: ``max(|Omega|, omega_g) h <= SPIN_STEP``
    (0.1 rad, an accuracy bound of this system for every scheme; ``omega_g`` from
    :meth:`TippeTopParams.gravity_rate`), and, with friction, ``h <= c / lambda_d``
    (:func:`friction_stiffness`) with ``c`` half the scheme's real-axis interval (euler
    1.0, rk4 1.39; none for dop853). With ``friction_bound="accuracy"``: ``lambda_a =
    max(lambda, K sqrt(lambda w))`` (``K`` the law's ``accuracy_scale``; :func:`implicit_forms`'
    ``accuracy_rate``; ``lambda`` the law's stiffness at the actual ``N``, the largest mobility
    along the table and the smallest slip a period of ``dt`` can reach, with a floor for the
    sliding top; ``w = max(|Omega|, omega_g)``) and ``c`` ``ACCURACY_MARGIN`` of the interval
    (rk4 1.25); a law without a slope (no ``implicit``) keeps the stability bound."""
    omega_g = system.params.gravity_rate()
    dissipation, margin, text = _dissipation_bound(system, omega_g, dt)
    share = None
    if (
        dissipation is not None
        and system.implicit is not None
        and system.implicit.share is not None
    ):
        share = (
            system.implicit.share,
            (system.form_params, omega_g),
        )  # (the tolerance's relaxation share)
    # tolerance=: the error is measured on v_G and Omega (the horizontal position drifts, the
    # contact flags are not measured), and the attitude turns at |Omega| / 2, integrating Omega
    # (motion_rates)
    measured = tuple(n for n in ("velocity", "angular_velocity") if n in system.layout)
    return GuardRates(
        rotation=(tippe_rotation_rate, (system.layout["angular_velocity"][0], omega_g)),
        rotation_bound=SPIN_STEP,
        dissipation=dissipation,
        dissipation_margin=margin,
        ceiling=max(speed_ceiling, omega_g),
        text=text,
        dissipation_share=share,
        error_blocks=measured,
        rotating_blocks=(("attitude", "angular_velocity"),),
    )


def _dissipation_bound(system, omega_g: float, dt: float) -> tuple:
    """``(dissipation, margin, text)``: the friction's rate form and its ``P`` (``None`` without
    friction), the share of the real-axis interval a step may take of it, and the rule in words:
    the stability bound, or with ``friction_bound="accuracy"`` and a law with an accuracy rate
    the accuracy bound."""
    dissipation = (
        (system.forms.friction_rate, system.form_params)
        if system.friction_law is not None
        else None
    )
    margin = FRICTION_MARGIN
    text = f"lambda = max(|Omega|, omega_g) (omega_g = {omega_g:.6g} rad/s)"
    if (
        dissipation is not None
        and system.friction_bound == "accuracy"
        and system.implicit is not None
        and system.implicit.accuracy_rate is not None
    ):
        dissipation = (
            system.implicit.accuracy_rate,
            (system.form_params, system.friction.accuracy_scale, omega_g, float(dt)),
        )
        margin = ACCURACY_MARGIN
        text += (
            f", lambda_d = the {system.friction_law} law's stiffness at N, the mobility "
            "along the table and the period's smallest slip (friction_bound='accuracy')"
        )
    elif dissipation is not None:
        text += f", lambda_d = the {system.friction_law} law's stiffness at 2 max(m g, N)"
    return dissipation, margin, text


def max_stable_step(
    system, region, mu: float | None = None, normal_force: float | None = None
) -> float:
    """The largest internal step [s] at which the friction law is stable for a scheme of
    ``region`` (a :class:`~rbenvs.contracts.StepRegion`, or an integrator declaring one):
    ``c / lambda_d``, ``c`` =
    ``FRICTION_MARGIN`` of its real-axis interval (euler ``h lambda <= 2``: ``c = 1``; rk4
    2.78: ``c = 1.39``), ``lambda_d`` from :func:`friction_stiffness` at ``mu`` (default:
    the parameter's) and ``normal_force`` (default ``m g``). ``inf`` without friction, when
    rolling, and for schemes without a real-axis bound (dop853). Arrays in, array out."""
    if not isinstance(region, StepRegion):  # an integrator: its region
        region = region.region
    c = FRICTION_MARGIN * region.dissipation
    if system.friction_law is None or c == math.inf:
        return math.inf
    rate = friction_stiffness(system, system.params.friction if mu is None else mu, normal_force)
    with np.errstate(divide="ignore"):
        bound = np.where(rate > 0.0, c / np.where(rate > 0.0, rate, 1.0), np.inf)
    return float(bound) if bound.ndim == 0 else bound

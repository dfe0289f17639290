"""The tippe top: a sphere with an offset centre of mass on a table (docs/physics.md §3).

Geometry ([T 3.92-3.114]): sphere radius ``a``; centre of mass ``G`` at ``h = alpha a``
from the centre ``O`` along the symmetry axis ``k`` (body ``e3``), ``G = O - h k``; moments
about ``G``: ``A = I1 = I2``, ``C = I3``; the table is ``z = 0`` with ``z_hat`` up. ``theta`` is
the angle between ``k`` and ``z_hat``: 0 = on the broad end, centre of mass low; ``pi`` =
inverted on the stem. Contact point ``P = O - a z_hat``, so ``r = P - G = h k - a z_hat``.

The contact is a **constraint**, not a spring: while the sphere touches the table the centre
sits at height ``a``, so ``z_G = a - h cos(theta)`` and ``dz_G/dt`` follow from the attitude
and the angular velocity and are not integrated. The normal force ``N`` is whatever keeps the
second derivative of that constraint satisfied; it is solved in closed form at every
evaluation (it is linear in ``N`` because every friction law scales with ``N``). No
penetration, no bouncing, no energy gain. ``N < 0`` means the table would have to pull: the
top lifts off, which the environment detects and reports.

Fidelity levels (a scene models only what it needs):

* ``"gliding"``: the sphere slides; friction ``F = N f(v_P)`` opposes the slip velocity of the
  contact point ``v_P = v_G + omega x r`` (Coulomb regularised near zero slip, or viscous).
  State ``(x, y, vx, vy, q, Omega)``: 11 components.
* ``"frictionless"``: the same without friction (a sliding top: energy, ``L.z_hat`` and
  ``L.k`` conserved; the horizontal velocity of ``G`` only follows the table). 11 components.
* ``"rolling"``: the non-holonomic pure-rolling limit ``v_P = 0`` (infinite friction); the
  full contact force is the constraint force, from a 3x3 linear solve. ``v_G = -omega x r``
  is not integrated: state ``(x, y, q, Omega)``, 9 components. Energy and Jellett conserved;
  a rolling top does **not** invert (inversion needs sliding friction to dissipate energy).

**Free flight** (``flight=True``, gliding or frictionless): the top may leave the table, as
real tippe tops do (they hop while they rise; Cross, Am. J. Phys. 81, 280 (2013)). The state
then carries the height and vertical velocity of ``G`` and two bookkeeping components: the
contact flag ``c`` (1 on the table, 0 in flight) and the number of lift-offs so far; both have
zero derivative, so every integrator carries them unchanged. In contact (``c = 1``) the vector
field is the constrained one above and :meth:`normalize` keeps ``(z, v_z)`` on the constraint;
in flight (``c = 0``) no contact force acts: ``G`` falls freely and the rotation is torque-free
(Jellett's integral and the energy are conserved in flight). The switches are declared by
:meth:`events` and made between internal steps by the hybrid layer (:mod:`rbenvs.core.hybrid`,
which alone calls the integrator): lift-off when ``N < 0`` and touchdown when the sphere
reaches the table, each located inside the step to round-off by regula falsi on the
integrator's own step; a touchdown is followed by a plastic, frictionless impact (:meth:`impact`):
the normal impulse stops the contact point's vertical motion, removes ``lambda^2 M_zz / 2`` of
energy and keeps Jellett's integral exactly (an impulse at the contact point has no moment about
``r``). State ``(x, y, z, vx, vy, vz, q, Omega, c, hops)``: 15 components.

In every level the equations are written in the table's frame. Controls ``u`` are
``(a_x, a_y, mu, tau1, tau2, tau3)``: the table's horizontal acceleration [m/s^2] (a moving
plate: in its frame a fictitious force ``-m a_T`` acts at ``G``, so it reaches the rotation only
through friction), the friction coefficient, and an optional body torque [N m] about ``G``.
``u = None`` means a table at rest, the parameter's friction coefficient and no torque.

Jellett's integral ``J = L . (a z_hat - h k)`` [T 3.106] is conserved for any force at the
contact point or at ``G``: with no body torque it holds under every friction law and table
motion, which the tests and ``rbenvs verify`` check.

**Pure forms.** The whole arithmetic of a control period (vector field, projection, contact
force, lift-off, the flight switches, read-outs, the guard's friction rate) is written once, as
pure functions ``fn(P, ...)`` of the parameter tuple ``P`` (:func:`pure_parameters`), marked
:func:`rbenvs.jit.jitable`: the methods of :class:`TippeTop` call them on floats or arrays, and
compiled code can call them on floats. The friction law enters as its own pure coefficient
(:mod:`rbenvs.dynamics.contact`), a compile-time constant of the functions made for it: one set
per (law, fidelity, flight) combination (:func:`pure_forms`), no branch on the law's name.

Components are floats (one state) or arrays of one batch shape (many states at once).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cache
from typing import NamedTuple

import numpy as np

from ..contracts import GuardRates, StepRegion
from ..draws import draw
from ..jit import jitable
from ..rotations import atan2, maximum, power, quat_normalize, quat_rate, select, sqrt
from .contact import FRICTION_LAWS, no_friction
from .state import start_as_drawn
from .validation import (
    did_you_mean,
    real_array,
    require_choice,
    require_finite_nonnegative,
    require_finite_positive,
    require_finite_result,
    require_real_vector,
)


class Event(NamedTuple):
    """A switching event of a hybrid system (:meth:`TippeTop.events`): where it can happen
    (``applies(y)``), the function whose sign change (``>= 0`` to ``< 0``) it is, the tolerance
    to locate it to, and the state in the new mode at the event (``switch(y)``)."""

    name: str
    applies: Callable
    function: Callable
    tolerance: float
    switch: Callable


__all__ = [
    "TippeTopParams",
    "TippeTop",
    "TippeForms",
    "flight_gap",
    "Event",
    "FIDELITIES",
    "FRICTION_LAWS",
    "SPIN_STEP",
    "FRICTION_MARGIN",
    "FRICTION_BOUNDS",
    "ACCURACY_MARGIN",
    "PURE_PARAMETERS",
    "tippe_rotation_rate",
    "pure_parameters",
    "pure_forms",
    "tippe_frame",
    "to_space",
    "contact_arm",
    "constraint_vertical_velocity",
    "slip_velocity",
    "rolling_velocity_body",
    "vertical_tilt",
    "tippe_energy",
    "tippe_jellett",
    "applied_rate",
    "rolling_contact",
    "tangential_mobility",
    "ImplicitForms",
    "implicit_forms",
    "sliding_derivative",
    "rolling_derivative",
    "flight_derivative",
    "sliding_normalize",
    "rolling_normalize",
    "flight_normalize",
    "flight_on_table",
    "flight_airborne",
    "flight_take_off",
    "flight_impact",
    "flight_touch_down",
    "STEM_TOL",
    "stem_params",
    "stem_other_gap",
    "stem_impact",
    "stem_switch",
    "stem_forms",
    "stem_jellett",
]

FIDELITIES = ("gliding", "frictionless", "rolling")
# Free flight: the lift-off is located to |N| <= LIFT_OFF_TOL m g and the touchdown to
# |gap| <= TOUCHDOWN_TOL a (a few ulp of the height), by rbenvs.core.hybrid.
LIFT_OFF_TOL = 1e-12
TOUCHDOWN_TOL = 1e-13
# The step guard: the contact geometry turns with the body, so every scheme takes at most
# SPIN_STEP rad of max(|Omega|, omega_g) per internal step (an accuracy bound), and at most
# FRICTION_MARGIN of its real-axis stability interval of the friction's stiffness.
SPIN_STEP = 0.1
FRICTION_MARGIN = 0.5
# friction_bound="accuracy": h <= ACCURACY_MARGIN of the scheme's real-axis interval over
# lambda_a = max(lambda_d, K sqrt(lambda_d w)), lambda_d the tight rate (actual N, mobility along
# the table), w = max(|Omega|, omega_g), K the friction law's accuracy_scale
# (rbenvs.dynamics.contact). For rk4: h <= 1.25 / lambda_d (stable with the tight rate's growth
# within a period, measured up to about twice: 2.5 < 2.78) and h <= 1.25 / (K sqrt(lambda_d w)):
# near zero slip the slip relaxes at lambda_d while the contact geometry that drives it turns at
# w, and rk4's error in the time to 90 degrees follows h^2 lambda_d w per unit time there, so a top
# that rises slowly (long near rolling) gathers more of it; the error falls like K^-4.
FRICTION_BOUNDS = ("stability", "accuracy")
ACCURACY_MARGIN = 0.45


@jitable
def tippe_rotation_rate(p, y):
    """``max(|Omega|, omega_g)`` [rad/s], ``p = (index of Omega_1 in the state, omega_g)``."""
    o, omega_g = p
    w0, w1, w2 = y[o], y[o + 1], y[o + 2]
    return maximum(sqrt(w0 * w0 + w1 * w1 + w2 * w2), omega_g)


@dataclass(frozen=True)
class TippeTopParams:
    """Physical parameters. Defaults: the tippe top of Leine and Glocker (2003), docs/physics.md §3.

    * ``radius`` ``a`` [m]; ``offset`` ``alpha = h / a`` in (0, 1); ``mass`` [kg]; ``gravity``.
    * ``inertia = (A, C)`` about the centre of mass [kg m^2], ``C <= 2 A`` (a real symmetric
      body: triangle inequality ``A + A >= C``).
    * ``friction``: the coefficient ``mu`` (>= 0): dimensionless for Coulomb, [s/m] for the
      viscous law ``F = -mu N v_P``.
    * ``friction_law``: ``"coulomb"``: ``F = -mu N v_P / sqrt(|v_P|^2 + slip_regularization^2)``
      (Coulomb's law, [T 3.96], smoothed for slips below ``slip_regularization`` [m/s]) or
      ``"viscous"``.
    * ``stem``: ``None`` (the sphere alone) or ``(b, d)`` [m]: a second contact, the stem's tip, a
      sphere of radius ``b`` whose centre ``S = G + d k`` lies on the symmetry axis beyond the
      sphere's centre (``d > h``), protruding past the sphere (``d - h + b > a``) and
      smaller than the sphere (``b < a``): the inverted top ends on it (Leine and Glocker 2003:
      ``(0.005, 0.016)``; docs/physics.md §3, "The stem").
    """

    radius: float = 0.015
    mass: float = 0.006
    offset: float = 0.2
    inertia: tuple[float, float] = (8e-7, 7e-7)
    gravity: float = 9.81
    friction: float = 0.3
    friction_law: str = "coulomb"
    slip_regularization: float = 1e-3
    stem: tuple[float, float] | None = None
    height: float = field(init=False, repr=False)  # h = alpha a [m]

    def __post_init__(self):
        a = require_finite_positive("radius", self.radius)
        m = require_finite_positive("mass", self.mass)
        g = require_finite_positive("gravity", self.gravity)
        alpha = require_finite_positive("offset", self.offset)
        if not alpha < 1.0:
            raise ValueError(
                "offset (alpha = h/R, centre-of-mass offset over radius) must lie in (0, 1), got "
                f"{self.offset!r}"
            )
        big_a, big_c = require_real_vector(
            "inertia",
            self.inertia,
            2,
            " (A, C): the transverse and axial moments about the centre of mass",
        )
        big_a = require_finite_positive("inertia[0] (A)", big_a)
        big_c = require_finite_positive("inertia[1] (C)", big_c)
        if big_c > 2.0 * big_a:
            raise ValueError(
                "inertia must satisfy C <= 2 A (triangle inequality of a real body), got "
                f"A={big_a!r}, C={big_c!r}"
            )
        mu = require_finite_nonnegative("friction", self.friction)
        require_choice("friction_law", self.friction_law, FRICTION_LAWS)
        eps = require_finite_positive("slip_regularization", self.slip_regularization)
        # products the dynamics forms: refused here, by name, rather than overflowing in a step
        require_finite_result(
            "mass, radius and inertia", m * a * a + big_a + big_c, "m a^2 + A + C [kg m^2]"
        )
        require_finite_result(
            "radius and inertia",
            (a + alpha * a) * (a + alpha * a) / min(big_a, big_c),
            "(a + h)^2 / min(A, C) [1/kg]",
        )
        require_finite_result("mass and gravity", m * g * a, "m g a [J]")
        stem = self.stem
        if stem is not None:
            b, d = require_real_vector(
                "stem",
                stem,
                2,
                " (b, d): the stem tip's radius and the distance of its centre from the centre of "
                "mass [m]",
            )
            b = require_finite_positive("stem[0] (b)", b)
            d = require_finite_positive("stem[1] (d)", d)
            h = alpha * a
            if not b < a:
                raise ValueError(
                    f"stem radius b must be below the sphere's radius a = {a!r} m, got {b!r}"
                )
            if not d > h:
                raise ValueError(
                    f"stem distance d must exceed h = alpha a = {h!r} m (the stem's centre lies "
                    f"beyond the sphere's centre), got {d!r}"
                )
            if not d - h + b > a:
                raise ValueError(
                    "the stem must protrude past the sphere (d - h + b > a): d - h + b = "
                    f"{d - h + b!r} m, a = {a!r} m"
                )
            require_finite_result(
                "stem", (b + d) * (b + d) / min(big_a, big_c), "(b + d)^2 / min(A, C) [1/kg]"
            )
            stem = (b, d)
        set_ = object.__setattr__
        for name, value in (
            ("radius", a),
            ("mass", m),
            ("gravity", g),
            ("offset", alpha),
            ("inertia", (big_a, big_c)),
            ("friction", mu),
            ("slip_regularization", eps),
            ("stem", stem),
            ("height", alpha * a),
        ):
            set_(self, name, value)

    @property
    def gamma(self) -> float:
        """``A / C``: inversion needs ``1 - alpha < gamma < 1 + alpha`` (docs/physics.md §3)."""
        return self.inertia[0] / self.inertia[1]

    def gravity_rate(self) -> float:
        """``sqrt(m g (a + h) / min(A, C))`` [rad/s]: an upper bound of the rates gravity drives
        through the contact (the weight at the longest arm ``|r| <= a + h`` over the smallest
        moment; the rocking frequency ``sqrt(m g h / (A + m (a - h)^2))`` of a top at rest is
        below it). The guard resolves it as it does the spin (``rbenvs.envs.tippe_top``)."""
        return math.sqrt(self.mass * self.gravity * self.longest_arm() / min(self.inertia))

    def longest_arm(self) -> float:
        """``a + h``, the longest arm ``|r|`` of the sphere's contact; with the stem, the larger
        of it and the stem's ``b + d``."""
        arm = self.radius + self.height
        if self.stem is not None:
            arm = max(arm, self.stem[0] + self.stem[1])
        return arm

    def contact_mobility(self) -> float:
        """An upper bound of ``|M|``, ``M = 1/m + [r x]^T I^-1 [r x]``: the contact point's
        acceleration per unit contact force [1/kg] (``|r| <= a + h``; with the stem ``|r| <=
        max(a + h, b + d)``)."""
        return 1.0 / self.mass + self.longest_arm() ** 2 / min(self.inertia)

    def stem_touch_tilt(self) -> float:
        """The tilt [rad] at which the stem first touches the table while the sphere does:
        ``cos(theta*) = -(a - b)/(d - h)`` (both contacts' heights of ``G`` agree, ``a - h cos =
        b - d cos``); ``nan`` without a stem."""
        if self.stem is None:
            return math.nan
        b, d = self.stem
        return math.acos(-(self.radius - b) / (d - self.height))


# ------------------------------------------------------------------------------------------
# Pure forms: the top's arithmetic as functions of (P, state[, control]); the methods of TippeTop
# call them on floats or arrays, compiled code on floats. ``P`` is one flat tuple per top.
PURE_PARAMETERS = (
    "radius",
    "height",
    "mass",
    "gravity",
    "A",
    "C",
    "friction",
    "slip_regularization",
    "contact_mobility",
)


def pure_parameters(params: TippeTopParams) -> tuple:
    """``P`` of every pure form: the floats named in :data:`PURE_PARAMETERS` (``friction`` is
    the coefficient a control ``u = None`` means; ``contact_mobility`` the guard's ``|M|``)."""
    big_a, big_c = params.inertia
    p = (
        params.radius,
        params.height,
        params.mass,
        params.gravity,
        big_a,
        big_c,
        params.friction,
        params.slip_regularization,
        params.contact_mobility(),
    )
    if params.stem is not None:  # (b, d) after the nine: the stem's layout (stem_forms) reads them
        p = p + (params.stem[0], params.stem[1])
    return p


@jitable
def tippe_frame(qw, qx, qy, qz):
    """The rotation matrix of ``q`` (body -> space) row by row, ``(R11, R12, ..., R33)``; its last
    row is ``Gamma = R^T z_hat``, the upward vertical in the body frame. (Each product of two
    quaternion components is formed once: the same values as forming it per entry.)"""
    xx, yy, zz = qx * qx, qy * qy, qz * qz
    xy, xz, yz = qx * qy, qx * qz, qy * qz
    wx, wy, wz = qw * qx, qw * qy, qw * qz
    return (
        1.0 - 2.0 * (yy + zz),
        2.0 * (xy - wz),
        2.0 * (xz + wy),
        2.0 * (xy + wz),
        1.0 - 2.0 * (xx + zz),
        2.0 * (yz - wx),
        2.0 * (xz - wy),
        2.0 * (yz + wx),
        1.0 - 2.0 * (xx + yy),
    )


@jitable
def to_space(rm, v1, v2, v3):
    """``R v``: a body-frame vector in space."""
    return (
        rm[0] * v1 + rm[1] * v2 + rm[2] * v3,
        rm[3] * v1 + rm[4] * v2 + rm[5] * v3,
        rm[6] * v1 + rm[7] * v2 + rm[8] * v3,
    )


@jitable
def contact_arm(p, g1, g2, g3):
    """``r = P - G = h e3 - a Gamma`` in the body frame."""
    a, h = p[0], p[1]
    return -a * g1, -a * g2, h - a * g3


@jitable
def constraint_vertical_velocity(p, rm, w1, w2):
    """``v_z = d/dt (a - h cos(theta)) = -h (Omega2 Gamma1 - Omega1 Gamma2)`` [m/s]: the vertical
    velocity of ``G`` the contact allows (``rm`` from :func:`tippe_frame`)."""
    return -p[1] * (w2 * rm[6] - w1 * rm[7])


@jitable
def slip_velocity(rm, r, vx, vy, vz, w1, w2, w3):
    """``v_P = v_G + Omega x r`` in the body frame [m/s], ``v_G = (vx, vy, vz)`` in space."""
    v1 = rm[0] * vx + rm[3] * vy + rm[6] * vz
    v2 = rm[1] * vx + rm[4] * vy + rm[7] * vz
    v3 = rm[2] * vx + rm[5] * vy + rm[8] * vz
    return v1 + w2 * r[2] - w3 * r[1], v2 + w3 * r[0] - w1 * r[2], v3 + w1 * r[1] - w2 * r[0]


@jitable
def rolling_velocity_body(p, rm, w1, w2, w3):
    """``v_G = -Omega x r`` in the body frame: the velocity that puts the contact point at rest."""
    r = contact_arm(p, rm[6], rm[7], rm[8])
    return -(w2 * r[2] - w3 * r[1]), -(w3 * r[0] - w1 * r[2]), -(w1 * r[1] - w2 * r[0])


@jitable
def vertical_tilt(g1, g2, g3):
    """``theta`` [rad] between the symmetry axis and the upward vertical ``Gamma``."""
    return atan2(sqrt(g1 * g1 + g2 * g2), g3)


@jitable
def tippe_energy(p, v1, v2, v3, w1, w2, w3, z):
    """Kinetic (``G`` at ``v``, rotation about ``G``) plus potential ``m g z`` energy [J]."""
    m, g, big_a, big_c = p[2], p[3], p[4], p[5]
    kin = 0.5 * m * (v1 * v1 + v2 * v2 + v3 * v3) + 0.5 * (
        big_a * (w1 * w1 + w2 * w2) + big_c * w3 * w3
    )
    return kin + m * g * z


@jitable
def tippe_jellett(p, rm, w1, w2, w3):
    """``J = L.(a Gamma - h e3)`` [kg m^2/s] [T 3.106] in the body frame."""
    a, h, big_a, big_c = p[0], p[1], p[4], p[5]
    return big_a * a * (w1 * rm[6] + w2 * rm[7]) + big_c * w3 * (a * rm[8] - h)


@jitable
def applied_rate(p, u, w1, w2, w3):
    """``(a_x, a_y, mu, dOmega0)`` under ``u = (a_x, a_y, mu, tau1, tau2, tau3)`` (``None``: a table
    at rest, the parameter's friction coefficient, no torque): ``dOmega0 = I^-1 (L x Omega +
    tau)`` [rad/s^2] is the angular acceleration before the contact force."""
    big_a, big_c = p[4], p[5]
    if u is None:
        ax, ay, mu, t1, t2, t3 = 0.0, 0.0, p[6], 0.0, 0.0, 0.0
    else:
        ax, ay, mu, t1, t2, t3 = u
    return (
        ax,
        ay,
        mu,
        ((big_a - big_c) * w2 * w3 + t1) / big_a,
        ((big_c - big_a) * w3 * w1 + t2) / big_a,
        t3 / big_c,
    )


@jitable
def rolling_contact(p, y, u):
    """Pure rolling (9 components): the contact force ``Lambda`` (body frame) keeps ``dv_P/dt = 0``.

    ``(1/m + [r x]^T I^-1 [r x]) Lambda = g Gamma + a_T - w0 x r - h Omega x (Omega x e3)``
    (from ``dv_G/dt = Lambda/m - g z_hat - a_T``, Euler's equations about ``G`` and
    ``dr/dt = h omega x k``); the matrix is symmetric positive definite. Returns the contact
    tuple of :class:`TippeForms` (``N``, the friction ``F_x, F_y`` in space: the tangential part
    of ``Lambda``, ``dOmega``, ``a_x, a_y``, and the horizontal part of ``v_G = -omega x r`` in
    space: the vector field does not use its vertical part).
    """
    _, h, m, g, big_a, big_c, _, _, _ = p
    qw, qx, qy, qz, w1, w2, w3 = y[2], y[3], y[4], y[5], y[6], y[7], y[8]
    rm = tippe_frame(qw, qx, qy, qz)
    g1, g2, g3 = rm[6], rm[7], rm[8]
    r1, r2, r3 = contact_arm(p, g1, g2, g3)
    ax, ay, _, w01, w02, w03 = applied_rate(p, u, w1, w2, w3)
    d1, d2, d3 = 1.0 / big_a, 1.0 / big_a, 1.0 / big_c
    im = 1.0 / m
    m11 = im + d2 * r3 * r3 + d3 * r2 * r2
    m22 = im + d1 * r3 * r3 + d3 * r1 * r1
    m33 = im + d1 * r2 * r2 + d2 * r1 * r1
    m12, m13, m23 = -d3 * r1 * r2, -d2 * r1 * r3, -d1 * r2 * r3
    # a_T in the body frame; h Omega x (Omega x e3) = h (Omega Omega3 - e3 |Omega|^2)
    at1, at2, at3 = rm[0] * ax + rm[3] * ay, rm[1] * ax + rm[4] * ay, rm[2] * ax + rm[5] * ay
    wsq = w1 * w1 + w2 * w2 + w3 * w3
    b1 = g * g1 + at1 - (w02 * r3 - w03 * r2) - h * w1 * w3
    b2 = g * g2 + at2 - (w03 * r1 - w01 * r3) - h * w2 * w3
    b3 = g * g3 + at3 - (w01 * r2 - w02 * r1) - h * (w3 * w3 - wsq)
    # symmetric 3x3 solve by cofactors
    c11 = m22 * m33 - m23 * m23
    c12 = m13 * m23 - m12 * m33
    c13 = m12 * m23 - m13 * m22
    c22 = m11 * m33 - m13 * m13
    c23 = m12 * m13 - m11 * m23
    c33 = m11 * m22 - m12 * m12
    det = m11 * c11 + m12 * c12 + m13 * c13
    l1 = (c11 * b1 + c12 * b2 + c13 * b3) / det
    l2 = (c12 * b1 + c22 * b2 + c23 * b3) / det
    l3 = (c13 * b1 + c23 * b2 + c33 * b3) / det
    n = l1 * g1 + l2 * g2 + l3 * g3
    f1, f2, f3 = l1 - n * g1, l2 - n * g2, l3 - n * g3  # the tangential part: friction
    vb1, vb2, vb3 = -(w2 * r3 - w3 * r2), -(w3 * r1 - w1 * r3), -(w1 * r2 - w2 * r1)  # v_P = 0
    return (
        n,
        rm[0] * f1 + rm[1] * f2 + rm[2] * f3,
        rm[3] * f1 + rm[4] * f2 + rm[5] * f3,
        w01 + d1 * (r2 * l3 - r3 * l2),
        w02 + d2 * (r3 * l1 - r1 * l3),
        w03 + d3 * (r1 * l2 - r2 * l1),
        ax,
        ay,
        rm[0] * vb1 + rm[1] * vb2 + rm[2] * vb3,
        rm[3] * vb1 + rm[4] * vb2 + rm[5] * vb3,
    )


@jitable
def sliding_derivative(p, y, c):
    """``dy/dt`` (gliding or frictionless, 11 components) from the contact tuple ``c``."""
    m = p[2]
    return (
        (c[8], c[9], c[1] / m - c[6], c[2] / m - c[7])
        + quat_rate((y[4], y[5], y[6], y[7]), (y[8], y[9], y[10]))
        + (c[3], c[4], c[5])
    )


@jitable
def rolling_derivative(p, y, c):
    """``dy/dt`` (rolling, 9 components): ``v_G = -omega x r`` is not integrated."""
    return (
        (c[8], c[9]) + quat_rate((y[2], y[3], y[4], y[5]), (y[6], y[7], y[8])) + (c[3], c[4], c[5])
    )


@jitable
def flight_derivative(p, y, c):
    """``dy/dt`` with free flight (15 components). The contact solve has already set the contact
    force to zero where ``c = 0``; what remains is the height: the constraint's rate on the
    table, the state's ``v_z`` in flight (a blend ``c X + (1 - c) Y``, exact for ``c`` in {0, 1},
    so one expression serves floats and batches). The friction force is horizontal: ``N``
    alone lifts ``G``."""
    m, g = p[2], p[3]
    flag = y[13]
    zero = 0.0 * flag
    return (
        (
            c[8],
            c[9],
            flag * c[10] + (1.0 - flag) * y[5],
            c[1] / m - c[6],
            c[2] / m - c[7],
            c[0] / m - g,
        )
        + quat_rate((y[6], y[7], y[8], y[9]), (y[10], y[11], y[12]))
        + (c[3], c[4], c[5], zero, zero)
    )


@jitable
def sliding_normalize(p, y):
    """The quaternion of an 11-component state projected back onto the unit sphere."""
    return y[:4] + quat_normalize(y[4:8]) + y[8:]


@jitable
def rolling_normalize(p, y):
    """The quaternion of a 9-component (rolling) state projected back onto the unit sphere."""
    return y[:2] + quat_normalize(y[2:6]) + y[6:]


@jitable
def flight_normalize(p, y):
    """The quaternion projected and, in contact (``c = 1``), the height and vertical velocity
    put on the constraint (a blend, as :func:`flight_derivative`)."""
    a, h = p[0], p[1]
    y = y[:6] + quat_normalize(y[6:10]) + y[10:]
    c = y[13]
    f = 1.0 - c
    rm = tippe_frame(y[6], y[7], y[8], y[9])
    z = c * (a - h * rm[8]) + f * y[2]
    vz = c * constraint_vertical_velocity(p, rm, y[10], y[11]) + f * y[5]
    return y[:2] + (z, y[3], y[4], vz) + y[6:]


@jitable
def flight_on_table(p, y):
    """Whether a state with flight is on the table (contact flag 1)."""
    return y[13] == 1.0


@jitable
def flight_airborne(p, y):
    """Whether a state with flight is in flight."""
    return y[13] != 1.0


@jitable
def flight_gap(p, y, u):
    """The touchdown switch's function (:meth:`TippeTop.events`): the gap of a state with flight
    to the table, ``z_G + h cos(theta) - a`` [m] (``u`` plays no part)."""
    return y[2] + p[1] * tippe_frame(y[6], y[7], y[8], y[9])[8] - p[0]


@jitable
def flight_take_off(p, y):
    """The state at a lift-off: in flight, one more hop."""
    return y[:13] + (0.0, y[14] + 1.0)


@jitable
def flight_impact(p, y):
    """Touchdown of a state at the table (gap 0, approaching): a plastic, frictionless impact;
    ``(state in contact, lambda)`` (:meth:`TippeTop.impact`). One state of floats: the impulse
    is clamped by a float branch."""
    m, big_a, big_c = p[2], p[4], p[5]
    rm = tippe_frame(y[6], y[7], y[8], y[9])
    g1, g2, g3 = rm[6], rm[7], rm[8]
    w1, w2, w3 = y[10], y[11], y[12]
    r1, r2, r3 = contact_arm(p, g1, g2, g3)
    # moment arm of a vertical unit impulse, r x Gamma (body)
    t1, t2, t3 = r2 * g3 - r3 * g2, r3 * g1 - r1 * g3, r1 * g2 - r2 * g1
    m_zz = 1.0 / m + t1 * t1 / big_a + t2 * t2 / big_a + t3 * t3 / big_c
    # vertical velocity of the contact point: v_z + (Omega x r).Gamma = v_z + Omega.(r x Gamma)
    v_pz = y[5] + (w1 * t1 + w2 * t2 + w3 * t3)
    lam = -v_pz / m_zz
    if lam < 0.0:  # separating, not touching down: no impulse
        lam = 0.0
    w = (w1 + lam * t1 / big_a, w2 + lam * t2 / big_a, w3 + lam * t3 / big_c)
    out = y[:5] + (y[5] + lam / m,) + y[6:10] + w + (1.0, y[14])
    return flight_normalize(p, out), lam


@jitable
def flight_touch_down(p, y):
    """The state after a touchdown: the plastic impact's (:func:`flight_impact`)."""
    return flight_impact(p, y)[0]


@jitable  # (registered so that compiled code can name it; it only ever runs on arrays)
def _counts_arrays(x):
    return x.astype(np.int64)


@jitable  # (registered so that compiled code can name it; it only ever runs on arrays)
def _zero_counts_arrays(x):
    return np.zeros(np.shape(x), dtype=np.int64)


class TippeForms(NamedTuple):
    """The pure functions of one (law, fidelity, flight) combination (:func:`pure_forms`), each
    ``fn(P, ...)`` with ``P`` from :func:`pure_parameters`; floats or arrays.

    State functions ``fn(P, y)``: ``frame`` (:func:`tippe_frame` of the state's quaternion),
    ``angular_velocity``, ``velocity`` (of ``G``, space, vertical part included), ``height``,
    ``gap``, ``slip_speed``, ``energy``, ``jellett``, ``tilt``, ``spin``, ``normalize``; and
    ``state(P, x, y, q, w, v=None)``, the components of a top from its position, attitude,
    angular velocity and the horizontal velocity of ``G`` (``None``: the contact point at rest)
    (starts).

    Contact functions ``fn(P, y, u)`` (``u`` the 6 controls or ``None``): ``contact``, the contact
    tuple ``(N, F_x, F_y, dOmega1, dOmega2, dOmega3, a_x, a_y, v_x, v_y[, v_z])`` (normal force,
    friction in space, angular acceleration, the table's acceleration and the velocity of ``G``
    the vector field uses: sliding, the state's horizontal part and the constraint's ``v_z``;
    rolling, the horizontal part of ``-omega x r``); ``derivative(P, y, contact) -> dy``; ``rhs``
    (``dy``), ``rhs_normal`` (``(dy, N)`` from one solve), ``normal`` (``N``; 0 in flight),
    ``friction_rate`` (the guard's
    ``lambda_d``; ``None`` without friction) and ``readouts(P, y, u, fired)``.
    """

    frame: Callable
    angular_velocity: Callable
    velocity: Callable
    height: Callable
    gap: Callable
    slip_speed: Callable
    energy: Callable
    jellett: Callable
    tilt: Callable
    spin: Callable
    normalize: Callable
    contact: Callable
    derivative: Callable
    rhs: Callable
    rhs_normal: Callable
    normal: Callable
    readouts: Callable
    friction_rate: Callable | None
    state: Callable


@cache
def _state_forms(rolling: bool, flight: bool) -> tuple:
    """The state functions of :class:`TippeForms` for one layout (no friction law in them). The
    layout is a constant of each function (``rolling``, ``flight``, the offsets ``Q`` of the
    quaternion and ``W`` of ``Omega``): compiled code keeps the one branch that applies."""
    Q, W = (6, 10) if flight else ((2, 6) if rolling else (4, 8))

    @jitable
    def frame(p, y):
        return tippe_frame(y[Q], y[Q + 1], y[Q + 2], y[Q + 3])

    @jitable
    def angular_velocity(p, y):
        return (y[W], y[W + 1], y[W + 2])

    @jitable
    def velocity(p, y):
        if flight:
            return (y[3], y[4], y[5])
        rm = frame(p, y)
        w1, w2, w3 = y[W], y[W + 1], y[W + 2]
        if rolling:
            v1, v2, v3 = rolling_velocity_body(p, rm, w1, w2, w3)
            return to_space(rm, v1, v2, v3)
        return (y[2], y[3], constraint_vertical_velocity(p, rm, w1, w2))

    @jitable
    def height(p, y):
        if flight:
            return y[2]
        return p[0] - p[1] * frame(p, y)[8]

    @jitable
    def gap(p, y):
        if not flight:
            return 0.0 * y[0]
        return y[2] + p[1] * frame(p, y)[8] - p[0]

    @jitable
    def slip_speed(p, y):
        if rolling:
            return 0.0 * y[0]
        rm = frame(p, y)
        w1, w2, w3 = y[W], y[W + 1], y[W + 2]
        r = contact_arm(p, rm[6], rm[7], rm[8])
        vx, vy = (y[3], y[4]) if flight else (y[2], y[3])
        s1, s2, s3 = slip_velocity(
            rm, r, vx, vy, constraint_vertical_velocity(p, rm, w1, w2), w1, w2, w3
        )
        return sqrt(s1 * s1 + s2 * s2 + s3 * s3)

    @jitable
    def energy(p, y):
        v1, v2, v3 = velocity(p, y)
        return tippe_energy(p, v1, v2, v3, y[W], y[W + 1], y[W + 2], height(p, y))

    @jitable
    def jellett(p, y):
        return tippe_jellett(p, frame(p, y), y[W], y[W + 1], y[W + 2])

    @jitable
    def tilt(p, y):
        rm = frame(p, y)
        return vertical_tilt(rm[6], rm[7], rm[8])

    @jitable
    def spin(p, y):
        return y[W + 2]

    @jitable
    def state_readouts(p, y, n, fired):
        """The read-outs with the normal force ``n`` solved (see :meth:`TippeTop.readouts`)."""
        if flight:
            hops = y[14]
            airborne, lifted = y[13] == 0.0, hops > 0.0
            count = int(hops) if isinstance(hops, float) else _counts_arrays(hops)
        else:
            airborne, lifted = 0.0 * y[0] != 0.0, fired
            count = 0 if isinstance(y[0], float) else _zero_counts_arrays(y[0])
        return (
            energy(p, y),
            jellett(p, y),
            tilt(p, y),
            n,
            slip_speed(p, y),
            lifted,
            airborne,
            count,
            gap(p, y),
            spin(p, y),
        )

    normalize = (
        flight_normalize if flight else (rolling_normalize if rolling else sliding_normalize)
    )

    @jitable
    def state(p, x, y0, q, w, v=None):
        """The components at the horizontal position ``(x, y0)`` [m], attitude ``q``, body
        angular velocity ``w`` [rad/s] and horizontal velocity of ``G`` ``v = (v_x, v_y)`` [m/s]
        in space (``None``: the contact point at rest, ``v_G = -omega x r``; a rolling top
        always has that one); with flight on the table, ``(z, v_z)`` from the constraint."""
        if rolling:
            return (x, y0) + q + w
        if v is None:
            rm = tippe_frame(q[0], q[1], q[2], q[3])
            v1, v2, v3 = rolling_velocity_body(p, rm, w[0], w[1], w[2])
            vx, vy, _ = to_space(rm, v1, v2, v3)
        else:
            vx, vy = v[0], v[1]
        if flight:
            zero = 0.0 * q[0]
            return normalize(p, (x, y0, zero, vx, vy, zero) + q + w + (zero + 1.0, zero))
        return (x, y0, vx, vy) + q + w

    return (
        frame,
        angular_velocity,
        velocity,
        height,
        gap,
        slip_speed,
        energy,
        jellett,
        tilt,
        spin,
        normalize,
        state,
    ), state_readouts


@cache
def pure_forms(coefficient, stiffness, rolling: bool, flight: bool) -> TippeForms:
    """The :class:`TippeForms` of one combination: the friction law's pure ``coefficient(mu, s1,
    s2, s3, eps)`` and ``stiffness(mu, N, mobility, eps)`` (:mod:`rbenvs.dynamics.contact`;
    :func:`~rbenvs.dynamics.contact.no_friction` and ``None`` without friction), ``rolling`` and
    ``flight``. Made once per combination (the functions close over the law's functions, which
    compiled code then calls as constants)."""
    (
        (
            frame,
            angular_velocity,
            velocity,
            height,
            gap,
            slip_speed,
            energy,
            jellett,
            tilt,
            spin,
            normalize,
            state,
        ),
        state_readouts,
    ) = _state_forms(rolling, flight)
    derivative = (
        flight_derivative if flight else (rolling_derivative if rolling else sliding_derivative)
    )

    @jitable
    def sliding_contact(p, y, u):
        """The contact while the sphere slides: ``N`` is whatever keeps the second derivative
        of ``z_G = a - h Gamma.e3`` zero (linear in ``N``: the friction law scales with it)."""
        _, h, m, g, big_a, big_c, _, eps, _ = p
        if flight:
            vx, vy, qw, qx, qy, qz, w1, w2, w3 = (
                y[3],
                y[4],
                y[6],
                y[7],
                y[8],
                y[9],
                y[10],
                y[11],
                y[12],
            )
        else:
            vx, vy, qw, qx, qy, qz, w1, w2, w3 = (
                y[2],
                y[3],
                y[4],
                y[5],
                y[6],
                y[7],
                y[8],
                y[9],
                y[10],
            )
        rm = tippe_frame(qw, qx, qy, qz)
        g1, g2, g3 = rm[6], rm[7], rm[8]
        r = contact_arm(p, g1, g2, g3)
        r1, r2, r3 = r
        # with flight the constraint's v_z (normalize keeps it in the state while c = 1)
        vz = constraint_vertical_velocity(p, rm, w1, w2)
        s1, s2, s3 = slip_velocity(rm, r, vx, vy, vz, w1, w2, w3)
        ax, ay, mu, w01, w02, w03 = applied_rate(p, u, w1, w2, w3)
        sv = s1 * g1 + s2 * g2 + s3 * g3  # zero by the constraint; removed against round-off
        s1, s2, s3 = s1 - sv * g1, s2 - sv * g2, s3 - sv * g3
        k = coefficient(mu, s1, s2, s3, eps)
        f1, f2, f3 = k * s1, k * s2, k * s3  # friction per unit normal force
        e1, e2, e3 = g1 + f1, g2 + f2, g3 + f3  # contact force per unit N
        # torque per unit N about G, over the moments: a1 = I^-1 (r x e)
        a11 = (r2 * e3 - r3 * e2) / big_a
        a12 = (r3 * e1 - r1 * e3) / big_a
        a13 = (r1 * e2 - r2 * e1) / big_c
        # second derivative of z_G = a - h Gamma.e3 = 0 gives N (linear in N)
        c = w3 * (w1 * g1 + w2 * g2) - (w1 * w1 + w2 * w2) * g3
        den = 1.0 + m * h * (a12 * g1 - a11 * g2)
        n = m * (g - h * (w02 * g1 - w01 * g2 + c)) / den
        if flight:  # in flight (contact flag 0) no contact force: the same lines with N = 0
            n = y[13] * n
        fb1, fb2, fb3 = n * f1, n * f2, n * f3
        return (
            n,
            rm[0] * fb1 + rm[1] * fb2 + rm[2] * fb3,
            rm[3] * fb1 + rm[4] * fb2 + rm[5] * fb3,
            w01 + n * a11,
            w02 + n * a12,
            w03 + n * a13,
            ax,
            ay,
            vx,
            vy,
            vz,
        )

    contact = rolling_contact if rolling else sliding_contact

    @jitable
    def rhs(p, y, u):
        return derivative(p, y, contact(p, y, u))

    @jitable
    def rhs_normal(p, y, u):
        c = contact(p, y, u)
        return derivative(p, y, c), c[0]

    @jitable
    def normal(p, y, u):
        return contact(p, y, u)[0]

    @jitable
    def readouts(p, y, u, fired):
        return state_readouts(p, y, contact(p, y, u)[0], fired)

    friction_rate = None
    if stiffness is not None:

        @jitable
        def friction_rate(p, y, u):
            """The guard's ``lambda_d`` [1/s]: the law's stiffness at twice ``max(m g, N)``
            (:meth:`TippeTop.friction_stiffness`) and ``u``'s friction coefficient."""
            m, g, mu0, eps, mobility = p[2], p[3], p[6], p[7], p[8]
            mu = mu0 if u is None else u[2]
            # np.maximum on floats too (an IEEE max that keeps a NaN, as on arrays)
            load = np.maximum(m * g, contact(p, y, u)[0])
            return stiffness(mu, 2.0 * load, mobility, eps)

    forms = TippeForms(
        frame,
        angular_velocity,
        velocity,
        height,
        gap,
        slip_speed,
        energy,
        jellett,
        tilt,
        spin,
        normalize,
        contact,
        derivative,
        rhs,
        rhs_normal,
        normal,
        readouts,
        friction_rate,
        state,
    )
    return forms


# ------------------------------------------------------------------------------------------
# The stem (docs/physics.md §3, "The stem"): a second sphere, radius b, centre S = G + d k. On
# the stem alone the top is the same system as on the sphere with (a, h) replaced by (b, d)
# (G = S - d k as G = O - h k): the same contact arm, constraint, friction law and Jellett
# integral, so the stem's contact is the sphere's pure forms at the parameters stem_params gives.
# The state is the gliding one (11 components) and a contact flag s (0 on the sphere, 1 on the
# stem; zero derivative). The switches (events of TippeTop) are the other contact's touchdown,
# located as the free flight's are, with a plastic frictionless impact there; since the coupling
# mobility of the two contacts' vertical motions, 1/m + h d sin^2(theta)/A, is positive, the
# impulse that stops the touching contact lifts the other one: one contact presses at a time.
STEM_TOL = 1e-13  # the other contact's touchdown is located to |gap| <= STEM_TOL a


@jitable
def stem_params(p, s):
    """The nine parameters of the contact of flag ``s`` (0: the sphere's ``(a, h)``, 1: the
    stem's ``(b, d)``, from ``P = (nine, b, d)``); a blend, exact for ``s`` in {0, 1}."""
    f = 1.0 - s
    return (f * p[0] + s * p[9], f * p[1] + s * p[10], p[2], p[3], p[4], p[5], p[6], p[7], p[8])


@jitable
def stem_other_gap(p, y, u):
    """The switch's function: the gap [m] to the table of the contact that does not press (the
    stem on the sphere, the sphere on the stem), ``z_G + h_o cos(theta) - r_o`` with ``z_G =
    r - h_ cos(theta)`` from the pressing one's constraint (``u`` plays no part)."""
    s = y[11]
    pa, po = stem_params(p, s), stem_params(p, 1.0 - s)
    g3 = tippe_frame(y[4], y[5], y[6], y[7])[8]
    return (pa[0] - pa[1] * g3) + po[1] * g3 - po[0]


@jitable
def stem_on_sphere(p, y):
    """Whether a state with the stem presses on the sphere (flag 0)."""
    return y[11] == 0.0


@jitable
def stem_on_stem(p, y):
    """Whether a state with the stem presses on the stem (flag 1)."""
    return y[11] == 1.0


@jitable
def stem_impact(p, y):
    """The other contact's touchdown (gap 0, approaching): a plastic, frictionless impact there,
    ``lambda = -v_Pz / M_zz`` with ``M_zz = 1/m + (r_o x Gamma).I^-1(r_o x Gamma)`` (as
    :func:`flight_impact`); the velocity of ``G`` stays horizontal-wise, its vertical part is the
    new contact's constraint's. Returns ``(state pressing on the other contact, lambda)``. One
    state of floats (the impulse is clamped by a float branch)."""
    m, big_a, big_c = p[2], p[4], p[5]
    s = y[11]
    o = 1.0 - s
    pa, po = stem_params(p, s), stem_params(p, o)
    rm = tippe_frame(y[4], y[5], y[6], y[7])
    g1, g2, g3 = rm[6], rm[7], rm[8]
    w1, w2, w3 = y[8], y[9], y[10]
    r1, r2, r3 = contact_arm(po, g1, g2, g3)
    t1, t2, t3 = r2 * g3 - r3 * g2, r3 * g1 - r1 * g3, r1 * g2 - r2 * g1
    m_zz = 1.0 / m + t1 * t1 / big_a + t2 * t2 / big_a + t3 * t3 / big_c
    v_pz = constraint_vertical_velocity(pa, rm, w1, w2) + (w1 * t1 + w2 * t2 + w3 * t3)
    lam = -v_pz / m_zz
    if lam < 0.0:  # separating, not touching down: no impulse
        lam = 0.0
    w = (w1 + lam * t1 / big_a, w2 + lam * t2 / big_a, w3 + lam * t3 / big_c)
    return sliding_normalize(p, y[:8] + w + (o,)), lam


@jitable
def stem_switch(p, y):
    """The state after the other contact's touchdown: :func:`stem_impact`'s."""
    return stem_impact(p, y)[0]


@jitable
def stem_derivative(p, y, c):
    """``dy/dt`` with the stem (12 components): the gliding one and the flag's zero."""
    return sliding_derivative(p, y, c) + (0.0 * y[11],)


@cache
def stem_forms(coefficient, stiffness) -> TippeForms:
    """The :class:`TippeForms` of a gliding or frictionless top with the stem (``P`` of
    :func:`pure_parameters` with ``(b, d)``; state: the gliding one and the contact flag): the
    sphere's forms at :func:`stem_params` of the flag. The read-outs: the energy, the normal
    force and the slip of the pressing contact, Jellett's integral of the sphere ``L.(a z_hat - h
    k)`` (:func:`stem_jellett` gives the stem's), and as ``gap`` the sphere's gap (0 while it
    presses)."""
    base = pure_forms(coefficient, stiffness, False, False)
    (
        (
            frame,
            angular_velocity,
            velocity0,
            height0,
            _,
            slip0,
            energy0,
            jellett,
            tilt,
            spin,
            normalize,
            state0,
        ),
        _,
    ) = _state_forms(False, False)
    contact0, friction_rate0 = base.contact, base.friction_rate

    @jitable
    def velocity(p, y):
        return velocity0(stem_params(p, y[11]), y)

    @jitable
    def height(p, y):
        return height0(stem_params(p, y[11]), y)

    @jitable
    def gap(p, y):
        return y[11] * stem_other_gap(p, y, None)

    @jitable
    def slip_speed(p, y):
        return slip0(stem_params(p, y[11]), y)

    @jitable
    def energy(p, y):
        return energy0(stem_params(p, y[11]), y)

    @jitable
    def state(p, x, y0, q, w, v=None):
        """On the sphere (flag 0), as the gliding top's state."""
        z = state0(p, x, y0, q, w, v)
        return z + (0.0 * z[0],)

    @jitable
    def contact(p, y, u):
        return contact0(stem_params(p, y[11]), y, u)

    @jitable
    def rhs(p, y, u):
        return stem_derivative(p, y, contact(p, y, u))

    @jitable
    def rhs_normal(p, y, u):
        c = contact(p, y, u)
        return stem_derivative(p, y, c), c[0]

    @jitable
    def normal(p, y, u):
        return contact(p, y, u)[0]

    @jitable
    def readouts(p, y, u, fired):
        count = 0 if isinstance(y[0], float) else _zero_counts_arrays(y[0])
        return (
            energy(p, y),
            jellett(p, y),
            tilt(p, y),
            contact(p, y, u)[0],
            slip_speed(p, y),
            fired,
            0.0 * y[0] != 0.0,
            count,
            gap(p, y),
            spin(p, y),
        )

    friction_rate = None
    if friction_rate0 is not None:

        @jitable
        def friction_rate(p, y, u):
            return friction_rate0(stem_params(p, y[11]), y, u)

    return TippeForms(
        frame,
        angular_velocity,
        velocity,
        height,
        gap,
        slip_speed,
        energy,
        jellett,
        tilt,
        spin,
        normalize,
        contact,
        stem_derivative,
        rhs,
        rhs_normal,
        normal,
        readouts,
        friction_rate,
        state,
    )


@jitable
def stem_jellett(p, y):
    """The stem's Jellett integral ``L.(b z_hat - d k)`` [kg m^2/s] (conserved while the stem
    alone presses, as the sphere's while the sphere does)."""
    return tippe_jellett(
        (p[9], p[10], p[2], p[3], p[4], p[5]),
        tippe_frame(y[4], y[5], y[6], y[7]),
        y[8],
        y[9],
        y[10],
    )


@cache
def stem_accuracy_rate(accuracy_rate0):
    """The guard's rate with ``friction_bound="accuracy"`` with the stem: the sphere's
    (:func:`implicit_forms`' ``accuracy_rate``) at the pressing contact's parameters."""

    @jitable
    def accuracy_rate(q, y, u):
        return accuracy_rate0((stem_params(q[0], y[11]), q[1], q[2]), y, u)

    return accuracy_rate


# ------------------------------------------------------------------------------------------
# The friction's linearisation: what a linearly implicit scheme (rbenvs.integrators.rosenbrock)
# and the tight stiffness rate need. Near zero slip the friction relaxes the slip at a rate far
# above every other rate of the top: the stiff part. Its Jacobian is low rank: a state increment
# x changes the slip by sigma = C x (C: the tangential part of R^T dv_G + dOmega x r), the slip
# changes the force per unit N by D sigma (D = k I + slope s s^T: the law's slope) and a force F
# at the contact changes the state's velocities by B F (dv_G = R F / m, dOmega = I^-1 (r x F));
# C B = P M P with M = 1/m + [r x]^T I^-1 [r x] the contact mobility and P = I - Gamma Gamma^T.
# The W-matrix of a Rosenbrock-W step, W = I - g N B D C (g = gamma h; N, the geometry and the
# slip frozen at the step's start: a W-method keeps its order with any such approximation), is
# inverted by Woodbury through a 3x3 solve: W^-1 x = x + B G C x, G = g N D (I - g N P M D)^-1.


@jitable
def _mat_mul(a, b):
    """The product of two 3x3 matrices given row by row (9-tuples)."""
    return (
        a[0] * b[0] + a[1] * b[3] + a[2] * b[6],
        a[0] * b[1] + a[1] * b[4] + a[2] * b[7],
        a[0] * b[2] + a[1] * b[5] + a[2] * b[8],
        a[3] * b[0] + a[4] * b[3] + a[5] * b[6],
        a[3] * b[1] + a[4] * b[4] + a[5] * b[7],
        a[3] * b[2] + a[4] * b[5] + a[5] * b[8],
        a[6] * b[0] + a[7] * b[3] + a[8] * b[6],
        a[6] * b[1] + a[7] * b[4] + a[8] * b[7],
        a[6] * b[2] + a[7] * b[5] + a[8] * b[8],
    )


@jitable
def _mat_inverse(a):
    """The inverse of a 3x3 matrix given row by row, by its adjugate."""
    c00, c01, c02 = a[4] * a[8] - a[5] * a[7], a[5] * a[6] - a[3] * a[8], a[3] * a[7] - a[4] * a[6]
    det = a[0] * c00 + a[1] * c01 + a[2] * c02
    inv = 1.0 / det
    return (
        c00 * inv,
        (a[2] * a[7] - a[1] * a[8]) * inv,
        (a[1] * a[5] - a[2] * a[4]) * inv,
        c01 * inv,
        (a[0] * a[8] - a[2] * a[6]) * inv,
        (a[2] * a[3] - a[0] * a[5]) * inv,
        c02 * inv,
        (a[1] * a[6] - a[0] * a[7]) * inv,
        (a[0] * a[4] - a[1] * a[3]) * inv,
    )


@jitable
def tangential_mobility(p, g1, g2, g3):
    """``P M P`` (row by row) and its largest eigenvalue [1/kg]: the contact mobility ``M = 1/m +
    [r x]^T I^-1 [r x]`` restricted to the table's plane (``P = I - Gamma Gamma^T``), i.e. the
    acceleration of the contact point along the slip per unit friction force. Its eigenvalues
    are 0 (along ``Gamma``) and ``l1, l2``: from its trace ``l1 + l2`` and the sum of its principal
    2x2 minors ``l1 l2``."""
    m, big_a, big_c = p[2], p[4], p[5]
    r1, r2, r3 = contact_arm(p, g1, g2, g3)
    d1, d3 = 1.0 / big_a, 1.0 / big_c
    im = 1.0 / m
    m11 = im + d1 * r3 * r3 + d3 * r2 * r2
    m22 = im + d1 * r3 * r3 + d3 * r1 * r1
    m33 = im + d1 * r2 * r2 + d1 * r1 * r1
    m12, m13, m23 = -d3 * r1 * r2, -d1 * r1 * r3, -d1 * r2 * r3
    # M Gamma and Gamma.M Gamma; P M P = M - G (M G)^T - (M G) G^T + (G.M G) G G^T
    n1 = m11 * g1 + m12 * g2 + m13 * g3
    n2 = m12 * g1 + m22 * g2 + m23 * g3
    n3 = m13 * g1 + m23 * g2 + m33 * g3
    gg = g1 * n1 + g2 * n2 + g3 * n3
    q11 = m11 - 2.0 * g1 * n1 + gg * g1 * g1
    q22 = m22 - 2.0 * g2 * n2 + gg * g2 * g2
    q33 = m33 - 2.0 * g3 * n3 + gg * g3 * g3
    q12 = m12 - g1 * n2 - n1 * g2 + gg * g1 * g2
    q13 = m13 - g1 * n3 - n1 * g3 + gg * g1 * g3
    q23 = m23 - g2 * n3 - n2 * g3 + gg * g2 * g3
    trace = q11 + q22 + q33
    minors = q11 * q22 - q12 * q12 + q11 * q33 - q13 * q13 + q22 * q33 - q23 * q23
    half = 0.5 * trace
    top = half + sqrt(maximum(half * half - minors, 0.0 * half))
    return (q11, q12, q13, q12, q22, q23, q13, q23, q33), top


@jitable
def frame_derivative(qw, qx, qy, qz, dw, dx, dy, dz):
    """The derivative of :func:`tippe_frame` at ``q`` in the direction ``dq`` (row by row; the
    frame is quadratic in ``q``, so this is its exact bilinear part, twice)."""
    xx, yy, zz = 2.0 * qx * dx, 2.0 * qy * dy, 2.0 * qz * dz
    xy, xz, yz = dx * qy + qx * dy, dx * qz + qx * dz, dy * qz + qy * dz
    wx, wy, wz = dw * qx + qw * dx, dw * qy + qw * dy, dw * qz + qw * dz
    return (
        -2.0 * (yy + zz),
        2.0 * (xy - wz),
        2.0 * (xz + wy),
        2.0 * (xy + wz),
        -2.0 * (xx + zz),
        2.0 * (yz - wx),
        2.0 * (xz - wy),
        2.0 * (yz + wx),
        -2.0 * (xx + yy),
    )


class ImplicitForms(NamedTuple):
    """The friction's linearisation for one (law, fidelity, flight) combination
    (:func:`implicit_forms`), pure ``fn(P, ...)`` with ``P`` from :func:`pure_parameters`:

    * ``factor(P, y, u, g) -> W``: what ``W^-1`` needs at ``y`` (``g = gamma h``): the frame, the
      contact arm and ``G = g N D (I - g N P M D)^-1`` (a tuple of floats);
    * ``solve(P, W, x) -> W^-1 x``: ``x + B G C x`` on the state's velocities, ``x`` a derivative
      (tuple of components);
    * ``rate(P, y, u) -> lambda_d``: the tight stiffness, the law's at the actual normal force
      and the largest tangential mobility (:func:`tangential_mobility`), at zero slip;
    * ``accuracy_rate((P, K, omega_g), y, u)``: the guard's rate with ``friction_bound="accuracy"``;
    * ``share(((P, omega_g), c_f / C), y, u, dt, p, lambda_g) -> a``: the share of ``C (lambda_g
    h)^p``
      (``lambda_g`` the friction guard's rate at ``y``) that the slip relaxation's error is in a
      period ``dt`` from ``y`` under ``u``, for a scheme of order ``p`` (docs/accuracy.md):
      at most ``(kappa lambda_d / lambda_g)^p``, ``kappa = k(s_min) / k(0)`` the law's
      coefficient at the smallest slip the period can reach (``|s|`` closing at twice its
      present rate) over its value at zero slip: the law's stiffness there is ``kappa
      lambda_d``, and a sliding top's saturated Coulomb friction (``|s| >> eps``) is not stiff
      until its slip reaches the band ``|s| ~ eps`` (viscous: ``kappa = 1``). With rk4 (``p =
      4``, a scheme declaring ``c_f``) the transient, that bound times the slip's distance from its
      slow manifold ``|ds/dt + Omega x s| / lambda_d`` against ``|v_G|`` (``eps`` at least), plus
      the forced part, ``c_f (kappa lambda_d h)^2 (w h)^2`` (the contact turning at ``w =
      max(|Omega|, omega_g)`` drives the stiff mode; the whole velocity counted as the drive;
      ``c_f`` the scheme's ``forced_error_constant``, ``q``'s second item ``c_f / C``, given by the
      guard). The tolerance's relaxation term (:func:`rbenvs.stepsize.forms.relaxation_steps`) takes
      it.

    Without friction (frictionless, rolling, in flight ``N = 0``) ``W = I``.
    """

    factor: Callable
    solve: Callable
    rate: Callable | None
    accuracy_rate: Callable | None
    share: Callable | None = None


@cache
def implicit_forms(
    coefficient, stiffness, slope, rolling: bool, flight: bool, saturates: bool = False
) -> ImplicitForms:
    """The :class:`ImplicitForms` of a law's pure ``coefficient``, ``stiffness`` and ``slope``
    (:mod:`rbenvs.dynamics.contact`; ``slope is None``: no friction, ``W = I``); ``saturates``:
    the law's (:attr:`~rbenvs.dynamics.contact.FrictionLaw.saturates`), which ``share`` reads."""
    forms = pure_forms(coefficient, stiffness, rolling, flight)
    contact, vector_field = forms.contact, forms.rhs
    Q, W, V = (6, 10, 3) if flight else ((2, 6, 0) if rolling else (4, 8, 2))
    frictionless = slope is None or rolling

    @jitable
    def table_slip(p, y):
        """``(frame, contact arm, v_z, slip)`` at ``y``: the slip velocity's part along the table
        (body frame), with the frame, the arm and the constraint's vertical velocity it took."""
        rm = tippe_frame(y[Q], y[Q + 1], y[Q + 2], y[Q + 3])
        g1, g2, g3 = rm[6], rm[7], rm[8]
        w1, w2, w3 = y[W], y[W + 1], y[W + 2]
        r = contact_arm(p, g1, g2, g3)
        vz = constraint_vertical_velocity(p, rm, w1, w2)
        s1, s2, s3 = slip_velocity(rm, r, y[V], y[V + 1], vz, w1, w2, w3)
        sv = s1 * g1 + s2 * g2 + s3 * g3
        return rm, r, vz, (s1 - sv * g1, s2 - sv * g2, s3 - sv * g3)

    @jitable
    def factor(p, y, u, gam):
        if frictionless:
            return ()
        eps = p[7]
        mu = p[6] if u is None else u[2]
        rm, r, vz, (s1, s2, s3) = table_slip(p, y)
        g1, g2, g3 = rm[6], rm[7], rm[8]
        w1, w2, w3 = y[W], y[W + 1], y[W + 2]
        k = coefficient(mu, s1, s2, s3, eps)
        sl = slope(mu, s1, s2, s3, eps)
        # D = k P + sl s s^T (per unit N; on the table's plane), scaled by g N
        c = gam * contact(p, y, u)[0]
        ck, cs = c * k, c * sl
        dm = (
            ck * (1.0 - g1 * g1) + cs * s1 * s1,
            -ck * g1 * g2 + cs * s1 * s2,
            -ck * g1 * g3 + cs * s1 * s3,
            -ck * g2 * g1 + cs * s2 * s1,
            ck * (1.0 - g2 * g2) + cs * s2 * s2,
            -ck * g2 * g3 + cs * s2 * s3,
            -ck * g3 * g1 + cs * s3 * s1,
            -ck * g3 * g2 + cs * s3 * s2,
            ck * (1.0 - g3 * g3) + cs * s3 * s3,
        )
        pmp, _ = tangential_mobility(p, g1, g2, g3)
        e = _mat_mul(pmp, dm)
        e = (1.0 - e[0], -e[1], -e[2], -e[3], 1.0 - e[4], -e[5], -e[6], -e[7], 1.0 - e[8])
        return (
            rm
            + r
            + _mat_mul(dm, _mat_inverse(e))
            + (y[Q], y[Q + 1], y[Q + 2], y[Q + 3], y[V], y[V + 1], vz, w1, w2, w3)
        )

    @jitable
    def slip_change(p, rm, r1, r2, r3, qw, qx, qy, qz, v1, v2, v3, w1, w2, w3, x):
        """``sigma = C x``: the slip's change (body frame) along a state derivative ``x`` at the
        state of frame ``rm``, contact arm ``r``, attitude ``q``, ``v_G`` (space) and ``Omega``:
        ``R^T (xv1, xv2, 0) + dOmega x r``, and through the attitude ``dR^T v_G + Omega x dr``
        (``dr = -a dGamma``); its normal part included."""
        a = p[0]
        xv1, xv2, o1, o2, o3 = x[V], x[V + 1], x[W], x[W + 1], x[W + 2]
        dr = frame_derivative(qw, qx, qy, qz, x[Q], x[Q + 1], x[Q + 2], x[Q + 3])
        e1, e2, e3 = -a * dr[6], -a * dr[7], -a * dr[8]
        t1 = (
            rm[0] * xv1
            + rm[3] * xv2
            + o2 * r3
            - o3 * r2
            + dr[0] * v1
            + dr[3] * v2
            + dr[6] * v3
            + w2 * e3
            - w3 * e2
        )
        t2 = (
            rm[1] * xv1
            + rm[4] * xv2
            + o3 * r1
            - o1 * r3
            + dr[1] * v1
            + dr[4] * v2
            + dr[7] * v3
            + w3 * e1
            - w1 * e3
        )
        t3 = (
            rm[2] * xv1
            + rm[5] * xv2
            + o1 * r2
            - o2 * r1
            + dr[2] * v1
            + dr[5] * v2
            + dr[8] * v3
            + w1 * e2
            - w2 * e1
        )
        return t1, t2, t3

    @jitable
    def solve(p, wf, x):
        if frictionless:
            return x
        m, big_a, big_c = p[2], p[4], p[5]
        rm, r1, r2, r3, gm = wf[:9], wf[9], wf[10], wf[11], wf[12:21]
        qw, qx, qy, qz, v1, v2, v3, w1, w2, w3 = wf[21:]
        xv1, xv2, o1, o2, o3 = x[V], x[V + 1], x[W], x[W + 1], x[W + 2]
        # sigma = C x (its normal part is removed by G's D)
        t1, t2, t3 = slip_change(p, rm, r1, r2, r3, qw, qx, qy, qz, v1, v2, v3, w1, w2, w3, x)
        f1 = gm[0] * t1 + gm[1] * t2 + gm[2] * t3
        f2 = gm[3] * t1 + gm[4] * t2 + gm[5] * t3
        f3 = gm[6] * t1 + gm[7] * t2 + gm[8] * t3
        # B F: dv_G = R F / m (horizontal: F is in the table's plane), dOmega = I^-1 (r x F)
        dv1 = (rm[0] * f1 + rm[1] * f2 + rm[2] * f3) / m
        dv2 = (rm[3] * f1 + rm[4] * f2 + rm[5] * f3) / m
        dw1, dw2, dw3 = (
            (r2 * f3 - r3 * f2) / big_a,
            (r3 * f1 - r1 * f3) / big_a,
            (r1 * f2 - r2 * f1) / big_c,
        )
        v1, v2, w1, w2, w3 = xv1 + dv1, xv2 + dv2, o1 + dw1, o2 + dw2, o3 + dw3
        if flight:  # (each layout written out: compiled code slices tuples by literals only)
            return (
                x[0],
                x[1],
                x[2],
                v1,
                v2,
                x[5],
                x[6],
                x[7],
                x[8],
                x[9],
                w1,
                w2,
                w3,
                x[13],
                x[14],
            )
        return (x[0], x[1], v1, v2, x[4], x[5], x[6], x[7], w1, w2, w3)

    rate = None
    if stiffness is not None and not rolling:

        @jitable
        def rate_at(p, y, u, top):
            """The law's stiffness at the actual ``N`` and the mobility ``top`` along the table."""
            mu = p[6] if u is None else u[2]
            return stiffness(mu, maximum(contact(p, y, u)[0], 0.0 * mu), top, p[7])

        @jitable
        def rate(p, y, u):
            rm = tippe_frame(y[Q], y[Q + 1], y[Q + 2], y[Q + 3])
            _, top = tangential_mobility(p, rm[6], rm[7], rm[8])
            return rate_at(p, y, u, top)

    accuracy_rate = None
    if rate is not None:

        @jitable
        def accuracy_rate(q, y, u):
            """``max(lambda_d, K sqrt(lambda_d w))``, ``q = (P, K, omega_g)``, ``w = max(|Omega|,
            omega_g)``: the friction guard's rate with ``friction_bound="accuracy"`` (see
            the friction law's ``accuracy_scale``)."""
            p, k, omega_g = q
            lam = rate(p, y, u)
            w = sqrt(y[W] * y[W] + y[W + 1] * y[W + 1] + y[W + 2] * y[W + 2])
            w = maximum(w, 0.0 * w + omega_g)
            return maximum(lam, k * sqrt(lam * w))

    share = None
    if rate is not None:

        @jitable
        def share(q, y, u, dt, order, guard):
            (p, omega_g), forced_ratio = q
            mu = p[6] if u is None else u[2]
            eps = p[7]
            rm, (r1, r2, r3), vz, (s1, s2, s3) = table_slip(p, y)
            g1, g2, g3 = rm[6], rm[7], rm[8]
            w1, w2, w3 = y[W], y[W + 1], y[W + 2]
            f = vector_field(p, y, u)
            t1, t2, t3 = slip_change(
                p,
                rm,
                r1,
                r2,
                r3,
                y[Q],
                y[Q + 1],
                y[Q + 2],
                y[Q + 3],
                y[V],
                y[V + 1],
                vz,
                w1,
                w2,
                w3,
                f,
            )
            tn = t1 * g1 + t2 * g2 + t3 * g3
            t1, t2, t3 = t1 - tn * g1, t2 - tn * g2, t3 - tn * g3
            # kappa: the law's stiffness at the smallest slip the period can reach, over its value
            # at zero slip (|s| closing at twice its present rate: a sliding slip's closing speeds
            # up as the top's motion turns, measured 1.8x from one period to the next from rest)
            ns = sqrt(s1 * s1 + s2 * s2 + s3 * s3)
            closing = (s1 * t1 + s2 * t2 + s3 * t3) / maximum(ns, 0.0 * ns + 1e-300)
            reach = ns + 2.0 * dt * select(closing < 0.0, closing, 0.0 * closing)
            reach = select(reach > 0.0, reach, 0.0 * reach)
            k0 = coefficient(mu, 0.0 * ns, 0.0 * ns, 0.0 * ns, eps)
            kappa = coefficient(mu, reach, 0.0 * ns, 0.0 * ns, eps) / select(
                k0 < 0.0, k0, 0.0 * k0 - 1.0
            )
            # the mode at its local stiffness kappa lambda_d (lambda_d the law's at zero slip, the
            # guard's rate at least), as large as the state
            _, top = tangential_mobility(p, g1, g2, g3)
            lam = rate_at(p, y, u, top)
            full = power(kappa * lam / maximum(guard, 0.0 * guard + 1e-300), order)
            if forced_ratio == 0.0:  # (a scheme without a forced-mode error constant)
                return select(full < 1.0, full, 0.0 * full + 1.0)
            # the transient, |s - s*| = |ds/dt| / lambda_d (the slip's rate in the table's
            # frame, ds/dt + Omega x s) against the velocity it perturbs, v_G (eps at least) ...
            c1, c2, c3 = t1 + w2 * s3 - w3 * s2, t2 + w3 * s1 - w1 * s3, t3 + w1 * s2 - w2 * s1
            speed = sqrt(y[V] * y[V] + y[V + 1] * y[V + 1])
            scale = lam * maximum(speed, 0.0 * speed + eps)
            transient = full * (
                sqrt(c1 * c1 + c2 * c2 + c3 * c3) / maximum(scale, 0.0 * scale + 1e-300)
            )
            # ... and the forced part: the contact turning at w drives the stiff mode; the scheme's
            # error in following it is c_f (kappa lambda_d h)^2 (w h)^2 of the velocity (rk4's
            # forced_error_constant), counted in units of C (forced_ratio = c_f / C)
            w = maximum(sqrt(w1 * w1 + w2 * w2 + w3 * w3), 0.0 * w1 + omega_g)
            m = kappa * lam * w
            forced = forced_ratio * (m * m) / maximum(power(guard, 4.0), 0.0 * guard + 1e-300)
            # both are errors of the slip in its stiffest mode; the state carries them in v_G,
            # where an error dF of the friction force moves the slip by M dF h and v_G by dF h / m:
            # along that mode 1 / (m l_max) of it, l_max the mobility's largest eigenvalue (the
            # default top: 0.29; measured before this split, the rolling top's v_G error was
            # 0.17-0.32 of the forced term). The slower mode (l_min = r l_max) relaxes r times
            # slower, so its forced error is r^2 of this one's and reaches v_G 1 / r more
            # strongly: r times as much again (r = 0.94-1 for the default top; its transient r^3).
            # It is NOT counted here: with (1 + r) the rolling rows of the tolerance bench cost 1.67
            # times the cheapest fixed steps, while at small tilts the estimate is already ~2x the
            # error measured period by period. After an inversion (tilt ~125 deg) this v_G share
            # was 2.6-5.8x under a period's own v_G error (the drive |ds/dt| at mu = 0 is 0.2-0.3
            # of w |v_G| upright, 0.8-1.9 inverted); with a saturating law the share below is
            # held at the slip's scale instead, and a period's v_G error is 0.01-0.05 of it at
            # both tilts (restarted from the run's own state against DOP853, tippe_invert, 1e-6)
            a = (transient + forced) / (p[2] * top)
            a = select(a < full, a, full)
            if saturates:
                # a law that saturates (Coulomb): the slip can leave the band, where it stops
                # relaxing and grows from the band's scale to a sliding speed (the tippe top that
                # rises: 56 times in 0.2 s), carrying the error it had relative to itself; that
                # error is no longer forgotten but amplified by the growth. So the slip's error is
                # held relative to the slip, max(|s|, eps), not to v_G: the v_G split undone (m
                # l_max) and |v_G| / max(|s|, eps) on top, not capped at the mode's full error at
                # v_G's scale. Measured (rbenvs bench accuracy --tolerance): the top that inverts
                # from rest ended 85-100 times outside 1e-6 and 1e-9 with the share at v_G's scale,
                # and ends within them at the cost of the cheapest fixed steps that meet them
                return (
                    a
                    * (p[2] * top)
                    * maximum(speed, 0.0 * speed + eps)
                    / maximum(ns, 0.0 * ns + eps)
                )
            return select(a < 1.0, a, 0.0 * a + 1.0)

    return ImplicitForms(factor, solve, rate, accuracy_rate, share)


class TippeTop:
    """Vector field, contact forces and read-outs of the tippe top at one fidelity level.

    The arithmetic is in the pure forms (:func:`pure_forms` of this top's law, fidelity and
    flight, parameters ``P`` = :func:`pure_parameters`): the methods call them, and the
    ``kernel_*`` attributes expose them as ``(fn, P)`` pairs for generated and compiled steps
    (:class:`rbenvs.contracts.System`): ``kernel_rhs``, ``kernel_rhs_normal`` (``(dy, N)`` from one
    contact solve), ``kernel_normalize``, ``kernel_readouts``, ``kernel_normal`` (``N``),
    ``kernel_gap`` and, with flight, the switches ``kernel_take_off``, ``kernel_touch_down``,
    ``kernel_on_table``, ``kernel_airborne`` (``None`` without); all ``None`` for a friction law
    given by its methods alone (which compiled code cannot call; the methods then run it on
    floats and arrays).
    """

    def __init__(
        self,
        params: TippeTopParams,
        fidelity: str = "gliding",
        flight: bool = False,
        friction_bound: str = "stability",
    ):
        self._memo = None  # the last contact solve (see _contact)
        if fidelity not in FIDELITIES:
            raise ValueError(
                f"fidelity must be one of {list(FIDELITIES)}, got "
                f"{fidelity!r}{did_you_mean(fidelity, FIDELITIES)}"
            )
        if friction_bound not in FRICTION_BOUNDS:
            raise ValueError(
                f"friction_bound must be one of {list(FRICTION_BOUNDS)}, got "
                f"{friction_bound!r}{did_you_mean(friction_bound, FRICTION_BOUNDS)}"
            )
        self.friction_bound = friction_bound
        self.fidelity = fidelity
        self.rolling = fidelity == "rolling"
        self.flight = bool(flight)
        if self.flight and self.rolling:
            raise ValueError(
                "flight=True needs fidelity 'gliding' or 'frictionless' (a rolling top has no slip "
                "to resume after a touchdown)"
            )
        self.stem = params.stem is not None
        if self.stem and self.rolling:
            raise ValueError(
                "stem needs fidelity 'gliding' or 'frictionless' (the rolling limit has no slip to "
                "resume after the stem's touchdown)"
            )
        if self.stem and self.flight:
            raise ValueError(
                "stem with flight=True is not modelled: a touchdown from flight could meet both "
                "contacts at once, "
                "which needs a two-contact impact law (docs/physics.md §3, 'The stem')"
            )
        if self.stem:
            self.layout = {
                "position": (0, 2),
                "velocity": (2, 4),
                "attitude": (4, 8),
                "angular_velocity": (8, 11),
                "contact": (11, 12),
            }
            self.dim = 12
            self._q, self._w = 4, 8
        elif self.flight:
            self.layout = {
                "position": (0, 3),
                "velocity": (3, 6),
                "attitude": (6, 10),
                "angular_velocity": (10, 13),
                "contact": (13, 14),
                "hops": (14, 15),
            }
            self.dim = 15
            self._q, self._w = 6, 10
        elif self.rolling:
            self.layout = {"position": (0, 2), "attitude": (2, 6), "angular_velocity": (6, 9)}
            self.dim = 9
            self._q, self._w = 2, 6
        else:
            self.layout = {
                "position": (0, 2),
                "velocity": (2, 4),
                "attitude": (4, 8),
                "angular_velocity": (8, 11),
            }
            self.dim = 11
            self._q, self._w = 4, 8
        self.params = params  # (sets the law and the pure forms: see the setter)

    @property
    def params(self) -> TippeTopParams:
        """The parameters. Setting them sets everything derived from them: the friction law,
        the pure forms and their ``P`` (:attr:`forms`, :attr:`form_params`) and the ``kernel_*``
        pairs."""
        return self._params

    @params.setter
    def params(self, params: TippeTopParams):
        if (params.stem is not None) != self.stem:  # (set first by __init__ and __setstate__)
            raise ValueError(
                "params must keep the stem as it is (a stem changes the state's layout)"
            )
        self._params = params
        self._memo = None
        self.friction_law = None if self.fidelity != "gliding" else params.friction_law  # its name
        self.friction = (
            None if self.friction_law is None else FRICTION_LAWS[self.friction_law]
        )  # the law (dynamics.contact)
        coefficient, stiffness = (
            (no_friction, None) if self.friction is None else self.friction.pure_forms()
        )
        if self.stem:
            self.forms = forms = stem_forms(coefficient, stiffness)
        else:
            self.forms = forms = pure_forms(coefficient, stiffness, self.rolling, self.flight)
        self.form_params = p = pure_parameters(params)
        compilable = self.friction is None or self.friction.compilable

        def pair(fn, offered=True):
            return (fn, p) if compilable and offered else None

        self.kernel_rhs = pair(forms.rhs)
        self.kernel_rhs_normal = pair(forms.rhs_normal)
        self.kernel_normalize = pair(forms.normalize)
        self.kernel_readouts = pair(forms.readouts)
        self.kernel_normal = pair(forms.normal)
        self.kernel_gap = pair(forms.gap)
        self.kernel_take_off = pair(flight_take_off, self.flight)
        self.kernel_touch_down = pair(flight_touch_down, self.flight)
        self.kernel_on_table = pair(flight_on_table, self.flight)
        self.kernel_airborne = pair(flight_airborne, self.flight)
        # the hybrid contract's pure forms (rbenvs.contracts.HybridSystem): without flight the
        # terminal event is the lift-off (N < 0), checked from the contact solve that is also
        # the next step's first stage; with flight the two switches of events()
        self.kernel_event = pair(forms.normal, not self.flight)
        # (with the stem the switches come between a step and the check: no shared first stage)
        self.kernel_rhs_event = pair(forms.rhs_normal, not self.flight and not self.stem)
        # the friction's linearisation (ImplicitForms): the W-matrix of a linearly implicit
        # scheme, (factor, solve, P); the tight stiffness rate; None for a law with no slope
        slope = None if self.friction is None else self.friction.kernel_slope
        self.implicit = None
        if self.friction is None or (slope is not None and compilable):
            saturates = self.friction is not None and self.friction.saturates
            self.implicit = implicit_forms(
                coefficient, stiffness, slope, self.rolling, self.flight, saturates
            )
        self.kernel_implicit = (
            None if self.implicit is None else (self.implicit.factor, self.implicit.solve, p)
        )
        if self.stem and self.implicit is not None:
            # with the stem: the accuracy rate at the pressing contact; no W-matrix (the linearly
            # implicit schemes are not offered: their solve is written for the 11 components)
            rate = self.implicit.accuracy_rate
            self.implicit = ImplicitForms(
                None, None, None, None if rate is None else stem_accuracy_rate(rate)
            )
            self.kernel_implicit = None
        self.kernel_switches = None
        if self.stem and compilable:
            tol = STEM_TOL * min(params.radius, params.stem[0])
            self.kernel_switches = (
                ((stem_on_sphere, ()), (stem_other_gap, p), tol, (stem_switch, p)),
                ((stem_on_stem, ()), (stem_other_gap, p), tol, (stem_switch, p)),
            )
        if self.flight and compilable:
            self.kernel_switches = (
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

    # what the parameters' setter derives: the pure forms are functions made per combination
    # (closures, which pickle cannot carry), so a pickle carries the parameters and the setter
    # makes the rest again on loading
    _DERIVED = (
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

    def __getstate__(self):
        state = {k: v for k, v in self.__dict__.items() if k not in self._DERIVED}
        state["_memo"] = None
        return state

    def __setstate__(self, state):
        state = dict(state)
        params = state.pop("_params")
        self.__dict__.update(state)
        self.params = params

    # ------------------------------------------------------------------ kinematics
    def frame(self, y):
        """Rotation matrix entries of ``q`` (body -> space) and ``Gamma = R^T z_hat``."""
        return self.forms.frame(self.form_params, y)

    def angular_velocity(self, y):
        o = self._w
        return (y[o], y[o + 1], y[o + 2])

    def vertical(self, y):
        """``Gamma``: the upward vertical in the body frame."""
        rm = self.frame(y)
        return (rm[6], rm[7], rm[8])

    def contact_arm(self, g1, g2, g3):
        """``r = P - G = h e3 - a Gamma`` in the body frame."""
        return contact_arm(self.form_params, g1, g2, g3)

    def velocity(self, y):
        """Velocity of ``G`` relative to the table, space frame, vertical part included."""
        return self.forms.velocity(self.form_params, y)

    def height(self, y):
        """``z_G`` [m]: ``a - h cos(theta)`` on the table (the constraint); with flight, the
        state's."""
        return self.forms.height(self.form_params, y)

    def gap(self, y):
        """Height of the sphere's lowest point above the table [m]: ``z_G + h cos(theta) - a``
        (0 on the table; positive in flight)."""
        return self.forms.gap(self.form_params, y)

    def gap_rate(self, y):
        """``d gap / dt`` [m/s]: ``v_z + h d(cos theta)/dt``, ``d Gamma/dt = Gamma x Omega``."""
        if not self.flight:
            return 0.0 * y[0]
        rm = self.frame(y)
        w1, w2, _ = self.angular_velocity(y)
        return y[5] + self.params.height * (rm[6] * w2 - rm[7] * w1)

    def in_contact(self, y):
        """Whether the sphere is on the table (the contact flag; always true without flight)."""
        if not self.flight:
            return 0.0 * y[0] == 0.0
        return y[13] == 1.0

    # ------------------------------------------------------------------ contact
    def _contact(self, y, u):
        """The contact tuple of :class:`TippeForms` (``N``, friction, ``dOmega``, ...) at ``y``
        under ``u``.

        The last result is kept for the same ``y`` and ``u`` objects: a look at the contact
        force at a state (:meth:`contact_forces`, :meth:`constraint_normal_force`) and the
        vector field there (the next step's first stage of an integrator that calls :meth:`rhs`,
        as ``Integrator.step`` does) share one solve. A pure cache: same inputs, same outputs.
        (The envs' bound steps call ``kernel_rhs`` itself, and their lift-off checks
        ``kernel_normal``.)"""
        memo = self._memo
        if memo is not None and memo[0] is y and memo[1] is u:
            return memo[2]
        out = self._solve_contact(y, u)
        self._memo = (y, u, out)
        return out

    def _solve_contact(self, y, u):
        return self.forms.contact(self.form_params, y, u)

    # ------------------------------------------------------------------ vector field
    def rhs(self, y, u):
        """``dy/dt`` at ``y`` under ``u`` (``None``: a table at rest, the parameter's friction
        coefficient, no torque): ``kernel_rhs``, through the shared contact solve."""
        return self.forms.derivative(self.form_params, y, self._contact(y, u))

    def normalize(self, y):
        """The quaternion projected back onto the unit sphere; with flight, in contact, also
        ``(z, v_z)`` put on the constraint (``kernel_normalize``)."""
        return self.forms.normalize(self.form_params, y)

    # ------------------------------------------------------------------ free flight: switches
    def impact(self, y):
        """Touchdown of a state at the table (gap 0, approaching): a plastic, frictionless
        impact. The normal impulse ``lambda z_hat`` at the contact point ends the vertical motion
        of the contact point, ``lambda = -v_Pz / M_zz``, ``M_zz = 1/m + (r x Gamma).I^-1(r x
        Gamma)``; the energy drops by ``lambda^2 M_zz / 2`` and Jellett's integral ``-L.r`` is
        unchanged (``(r x Gamma).r = 0``). Returns the state in contact (``c = 1``) and ``lambda``
        [N s] (:func:`flight_impact`; one state of floats)."""
        return flight_impact(self.form_params, y)

    # ------------------------------------------------------------------ hybrid system
    # (rbenvs.contracts.HybridSystem) A contact that can open: without free flight a lift-off
    # ends the episode (the terminal event); with it the top flies and lands (the switches).
    hybrid = True
    # the optional capabilities (rbenvs.contracts.System): the Rosenbrock-W schemes' linear
    # solve (kernel_implicit, None with a stem); no exact sub-flows
    provides = frozenset({"implicit"})
    kernel_split_flows = None
    needs_projection = True  # (the quaternion)

    @property
    def switches(self) -> bool:
        """Whether the contact switches (free flight; the stem's and sphere's touchdowns) rather
        than ending the episode (with the stem a lift-off still ends it)."""
        return self.flight or self.stem

    def terminal_event(self):
        """``("lift_off", fn)``: the event that ends an episode, ``fn(y, u)`` true where the
        contact would have to pull (``N < 0``); ``None`` with free flight (the top flies)."""
        return None if self.flight else ("lift_off", self.lifts_off)

    def lifts_off(self, y, u):
        """Lift-off: the contact would have to pull (``N < 0``); a bool or a mask
        (``kernel_normal``, called directly: the step after it does not go through :meth:`rhs`)."""
        return self.forms.normal(self.form_params, y, u) < 0.0

    readout_names = (
        "energy",
        "jellett",
        "tilt",
        "normal_force",
        "slip_speed",
        "lifted_off",
        "airborne",
        "hops",
        "gap",
        "spin",
    )

    def readouts(self, y, u=None, fired=False) -> tuple:
        """The read-outs in :attr:`readout_names` order under the control ``u`` that acted
        (``None``: a table at rest; the normal force depends on it): energy, Jellett's
        integral, tilt, normal force, slip speed, ``lifted_off`` (with free flight: a hop so
        far; without: the lift-off that ended this period, ``fired``), ``airborne``, ``hops``,
        the gap to the table and the spin. Floats (``hops`` an int, the flags bools) or arrays
        (``kernel_readouts``)."""
        return self.forms.readouts(self.form_params, y, u, fired)

    start_draw_kinds = ""  # the system adds no numbers to a task's start (rbenvs.draws)

    def start_draws(self, rng):
        return draw(rng, self.start_draw_kinds)

    def complete_initial_state(self, y, d):
        """A task's start as it is."""
        return y

    kernel_complete = (start_as_drawn, ())  # the pure form of complete_initial_state

    def events(self, u):
        """The contact switches to watch after each internal step under control ``u``
        (:class:`rbenvs.contracts.HybridSystem`; located and applied by
        :mod:`rbenvs.core.hybrid`, which calls the integrator: the dynamics never does).

        * lift-off, from the table (``c = 1``): the constraint's normal force turns negative
          (located to ``|N| <= LIFT_OFF_TOL m g``); the state goes to flight (``c = 0``) and the
          hop count up by one. Locating it matters for the energy: past ``N = 0`` the friction
          law would push along the slip.
        * touchdown, in flight: the sphere's gap to the table turns negative (located to
          ``|gap| <= TOUCHDOWN_TOL a``); the state after the plastic :meth:`impact`.
        """
        if self.stem:
            p = self.form_params
            tol = STEM_TOL * min(self.params.radius, self.params.stem[0])

            def other_gap(z):
                return stem_other_gap(p, z, u)

            def switch(z):
                return stem_switch(p, z)

            return (
                Event("stem_touchdown", self.on_sphere, other_gap, tol, switch),
                Event("sphere_touchdown", self.on_stem, other_gap, tol, switch),
            )
        if not self.flight:
            return ()
        prm = self.params
        forms_normal, p = self.forms.normal, self.form_params

        def normal(z):  # (the pure normal force: after every internal step, no method between)
            return forms_normal(p, z, u)

        lift_off = Event(
            "lift_off", self.on_table, normal, LIFT_OFF_TOL * prm.mass * prm.gravity, self.take_off
        )
        touchdown = Event(
            "touchdown", self.airborne, self.gap, TOUCHDOWN_TOL * prm.radius, self.touch_down
        )
        return (lift_off, touchdown)

    @staticmethod
    def on_sphere(y) -> bool:
        """With the stem: whether the sphere presses (contact flag 0)."""
        return stem_on_sphere((), y)

    @staticmethod
    def on_stem(y) -> bool:
        """With the stem: whether the stem presses (contact flag 1)."""
        return stem_on_stem((), y)

    def stem_impact(self, y):
        """With the stem: the other contact's touchdown at ``y`` (its gap 0, approaching), a
        plastic frictionless impact: ``(state pressing on it, lambda [N s])``
        (:func:`stem_impact`; one state of floats)."""
        return stem_impact(self.form_params, y)

    def stem_jellett(self, y):
        """With the stem: its Jellett integral ``L.(b z_hat - d k)`` [kg m^2/s] (conserved while
        the stem alone presses)."""
        return stem_jellett(self.form_params, y)

    def other_gap(self, y):
        """With the stem: the gap [m] of the contact that does not press (the stem's while the
        sphere presses, the sphere's while the stem does)."""
        return stem_other_gap(self.form_params, y, None)

    @staticmethod
    def on_table(y) -> bool:
        return flight_on_table((), y)

    @staticmethod
    def airborne(y) -> bool:
        return flight_airborne((), y)

    @staticmethod
    def take_off(y):
        """The state at a lift-off: in flight, one more hop."""
        return flight_take_off((), y)

    def touch_down(self, y):
        """The state after a touchdown: the plastic impact's."""
        return self.impact(y)[0]

    def constraint_normal_force(self, y, u):
        """``N`` [N] the contact constraint asks for at ``y`` under ``u`` (negative: the table
        would have to pull; lift-off); 0 in flight (``kernel_normal``)."""
        return self._contact(y, u)[0]

    # ------------------------------------------------------------------ read-outs
    def contact_forces(self, y, u=None):
        """``(N, (Fx, Fy), slip_speed)``: normal force [N], friction in space [N] and the slip
        speed ``|v_P|`` [m/s] (0 when rolling)."""
        c = self._contact(y, u)
        return c[0], (c[1], c[2]), self.slip_speed(y)

    def slip_speed(self, y):
        """``|v_P|`` [m/s], the speed of the material point at the contact."""
        return self.forms.slip_speed(self.form_params, y)

    def energy(self, y):
        """Kinetic (translation + rotation about ``G``) plus potential ``m g z_G`` [J], table
        frame."""
        return self.forms.energy(self.form_params, y)

    def jellett(self, y):
        """``J = L . (a z_hat - h k)`` [kg m^2/s] [T 3.106], in the body frame
        ``L.(a Gamma - h e3)``."""
        return self.forms.jellett(self.form_params, y)

    def tilt(self, y):
        """``theta`` [rad] between the symmetry axis and the upward vertical (0 upright, pi
        inverted on the stem)."""
        return self.forms.tilt(self.form_params, y)

    def spin(self, y):
        """``Omega3`` [rad/s], the angular velocity about the symmetry axis."""
        return y[self._w + 2]

    # ------------------------------------------------------------------ state construction
    def state(self, position, attitude, angular_velocity, velocity=None):
        """Components from a horizontal position ``(x, y)`` [m], an attitude quaternion, the body
        angular velocity [rad/s] and the horizontal velocity of ``G`` [m/s] (``None``: the
        contact point at rest, ``v_G = -omega x r``; ignored when rolling, where it is always
        that)."""
        pos = tuple(position)[:2]
        v = None if velocity is None else tuple(velocity)[:2]
        return self.forms.state(
            self.form_params, pos[0], pos[1], tuple(attitude), tuple(angular_velocity), v
        )

    def no_slip_velocity(self, attitude, angular_velocity):
        """``v_G = -omega x r`` in space [m/s]: the velocity that puts the contact point at rest."""
        qw, qx, qy, qz = attitude
        w1, w2, w3 = angular_velocity
        rm = tippe_frame(qw, qx, qy, qz)
        v1, v2, v3 = rolling_velocity_body(self.form_params, rm, w1, w2, w3)
        return to_space(rm, v1, v2, v3)

    def export_state(self, y) -> dict:
        """Named arrays: ``position`` (3, with ``z_G`` from the constraint), ``velocity`` (3,
        space, table frame), ``attitude`` (4, w x y z, body to space), ``angular_velocity`` (3,
        body)."""
        o = self._q
        return {
            "position": np.array([y[0], y[1], self.height(y)], dtype=np.float64),
            "velocity": np.array(self.velocity(y), dtype=np.float64),
            "attitude": np.array(y[o : o + 4], dtype=np.float64),
            "angular_velocity": np.array(y[o + 4 : o + 7], dtype=np.float64),
        }

    def import_state(self, state: dict) -> tuple:
        """Components from :meth:`export_state`'s dict, checked against the contact constraint:
        ``z_G = a - h cos(theta)``, ``v_z`` (and, rolling, the whole velocity) as the attitude and
        angular velocity require. ``ValueError`` naming the entry otherwise."""
        names = ("position", "velocity", "attitude", "angular_velocity")
        if not isinstance(state, dict):
            raise ValueError(
                f"options['state'] must be a dict of named arrays, got {type(state).__name__}"
            )
        unknown, missing = sorted(set(state) - set(names)), sorted(set(names) - set(state))
        if unknown or missing:
            raise ValueError(
                f"state must have exactly the names {sorted(names)}"
                + (f"; unknown: {unknown}" if unknown else "")
                + (f"; missing: {missing}" if missing else "")
            )
        arrs = {}
        for name, size in zip(names, (3, 3, 4, 3)):
            arr = real_array(f"state[{name!r}]", state[name])
            if arr.shape != (size,):
                raise ValueError(f"state[{name!r}] must have shape ({size},), got {arr.shape}")
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"state[{name!r}] must be finite, got {arr}")
            arrs[name] = arr
        qn = float(np.linalg.norm(arrs["attitude"]))
        if abs(qn - 1.0) > 1e-6:
            raise ValueError(
                f"state['attitude'] must be a unit quaternion (|q| = 1 within 1e-6), got |q| = {qn}"
            )
        q = tuple(float(c) for c in arrs["attitude"])
        w = tuple(float(c) for c in arrs["angular_velocity"])
        pos = tuple(float(c) for c in arrs["position"])
        vel = tuple(float(c) for c in arrs["velocity"])
        y = self.state(pos, q, w, vel[:2])
        prm = self.params
        if self.flight:
            return self._place_flight_state(y, pos, vel)
        if self.stem:  # on the stem where its constraint's height is the one given
            on_stem = y[:11] + (1.0,)
            if (
                abs(pos[2] - self.height(on_stem)) <= 1e-9 * prm.radius + 1e-12
                and self.other_gap(on_stem) >= 0.0
            ):
                y = on_stem
        z = self.height(y)
        if abs(pos[2] - z) > 1e-9 * prm.radius + 1e-12:
            raise ValueError(
                f"state['position'][2] must be the contact height a - h cos(theta) = {z!r} m for "
                f"this attitude (the sphere touches the table), got {pos[2]!r}"
            )
        v_need = self.velocity(y)
        scale = 1e-9 * (1.0 + prm.radius * float(np.linalg.norm(w)))
        checked = range(3) if self.rolling else (2,)
        for i in checked:
            if abs(vel[i] - v_need[i]) > scale:
                what = (
                    "the rolling velocity -omega x r"
                    if self.rolling
                    else "the vertical velocity the contact constraint gives"
                )
                raise ValueError(
                    f"state['velocity'] must equal {what} ({list(v_need)}), got {list(vel)}"
                )
        return y

    def _place_flight_state(self, y, pos, vel):
        """With flight: the given height and vertical velocity, classified. On the table (gap
        within round-off of 0, not approaching faster than round-off): in contact, ``v_z`` must
        be the constraint's; above it: in flight; below it: refused."""
        prm = self.params
        tol = 1e-9 * prm.radius + 1e-12
        air = y[:2] + (pos[2],) + y[3:5] + (vel[2],) + y[6:13] + (0.0, 0.0)
        gap = self.gap(air)
        if gap < -tol:
            raise ValueError(
                f"state['position'][2] puts the sphere {-gap!r} m into the table (z_G must be >= a "
                f"- h cos(theta) = {pos[2] - gap!r} m)"
            )
        if gap > tol:
            return air
        v_need = self.velocity(y)[2]  # y is on the table: the constraint's v_z
        scale = 1e-9 * (1.0 + prm.radius * float(np.linalg.norm(y[10:13])))
        if vel[2] - v_need > scale:  # on the table and leaving it: in flight
            return air
        if abs(vel[2] - v_need) > scale:
            raise ValueError(
                "state['velocity'][2] must be the vertical velocity the contact constraint gives "
                f"({v_need!r}) or above it (leaving the table), got {vel[2]!r}"
            )
        return y

    # ------------------------------------------------------------------ step guard
    # Near zero slip regularised Coulomb friction is a viscous law of rate mu N |M| / eps (viscous:
    # mu N |M|), |M| the contact mobility: stiff, a decaying (negative real) rate. The guard takes
    # twice the larger of m g and the current N (N varies within a control period) and keeps half
    # of the scheme's real-axis interval (FRICTION_MARGIN).
    def friction_stiffness(self, mu, normal_force=None):
        """``lambda_d`` [1/s]: the friction law's stiffness (:mod:`rbenvs.dynamics.contact`) at
        twice ``max(m g, N)`` and the contact mobility ``|M|`` (Coulomb: ``mu 2 max(m g, N) |M|
        / eps``); 0 without friction. ``mu`` and ``normal_force`` may be arrays (a batch)."""
        if self.friction is None:
            return 0.0
        prm = self.params
        weight = prm.mass * prm.gravity
        load = weight if normal_force is None else np.maximum(weight, normal_force)
        return self.friction.stiffness(
            mu, 2.0 * load, prm.contact_mobility(), prm.slip_regularization
        )

    def guard_rates(self, region, speed_ceiling: float = math.inf) -> GuardRates:
        """The contact geometry turns with the body: ``max(|Omega|, omega_g) h <= SPIN_STEP``
        (0.1 rad, an accuracy bound of this system for every scheme; ``omega_g`` from
        :meth:`TippeTopParams.gravity_rate`), and, with friction, ``h <= c / lambda_d``
        (:meth:`friction_stiffness`) with ``c`` half the scheme's real-axis interval (euler
        1.0, rk4 1.39; none for dop853). With ``friction_bound="accuracy"``: ``lambda_a =
        max(lambda_d, K sqrt(lambda_d w))`` (``K`` the law's ``accuracy_scale``;
        :func:`implicit_forms`'
        ``accuracy_rate``; ``lambda_d`` the tight rate: the law's stiffness at the actual ``N`` and
        the largest mobility along the table; ``w = max(|Omega|, omega_g)``) and ``c``
        ``ACCURACY_MARGIN`` of the interval (rk4 1.25); a law without a slope (no ``implicit``)
        keeps the stability bound."""
        omega_g = self.params.gravity_rate()
        dissipation = (
            (self.forms.friction_rate, self.form_params) if self.friction_law is not None else None
        )
        margin = FRICTION_MARGIN
        text = f"lambda = max(|Omega|, omega_g) (omega_g = {omega_g:.6g} rad/s)"
        if (
            dissipation is not None
            and self.friction_bound == "accuracy"
            and self.implicit is not None
            and self.implicit.accuracy_rate is not None
        ):
            dissipation = (
                self.implicit.accuracy_rate,
                (self.form_params, self.friction.accuracy_scale, omega_g),
            )
            margin = ACCURACY_MARGIN
            text += (
                f", lambda_d = the {self.friction_law} law's stiffness at N and the mobility "
                "along the table (friction_bound='accuracy')"
            )
        elif dissipation is not None:
            text += f", lambda_d = the {self.friction_law} law's stiffness at 2 max(m g, N)"
        share = None
        if (
            dissipation is not None
            and self.implicit is not None
            and self.implicit.share is not None
        ):
            share = (
                self.implicit.share,
                (self.form_params, omega_g),
            )  # (the tolerance's relaxation share)
        # tolerance=: the error is measured on v_G and Omega (the horizontal position drifts, the
        # contact flags are not measured), and the attitude turns at |Omega| / 2, integrating Omega
        # (motion_rates)
        measured = tuple(n for n in ("velocity", "angular_velocity") if n in self.layout)
        return GuardRates(
            rotation=(tippe_rotation_rate, (self._w, omega_g)),
            rotation_bound=SPIN_STEP,
            dissipation=dissipation,
            dissipation_margin=margin,
            ceiling=max(speed_ceiling, omega_g),
            text=text,
            dissipation_share=share,
            error_blocks=measured,
            rotating_blocks=(("attitude", "angular_velocity"),),
        )

    def max_stable_step(
        self, region, mu: float | None = None, normal_force: float | None = None
    ) -> float:
        """The largest internal step [s] at which the friction law is stable for a scheme of
        ``region`` (a :class:`~rbenvs.contracts.StepRegion`, or an integrator declaring one):
        ``c / lambda_d``, ``c`` =
        ``FRICTION_MARGIN`` of its real-axis interval (euler ``h lambda <= 2``: ``c = 1``; rk4
        2.78: ``c = 1.39``), ``lambda_d`` from :meth:`friction_stiffness` at ``mu`` (default:
        the parameter's) and ``normal_force`` (default ``m g``). ``inf`` without friction, when
        rolling, and for schemes without a real-axis bound (dop853). Arrays in, array out."""
        if not isinstance(region, StepRegion):  # an integrator: its region
            region = region.region
        c = FRICTION_MARGIN * region.dissipation
        if self.friction_law is None or c == math.inf:
            return math.inf
        rate = self.friction_stiffness(self.params.friction if mu is None else mu, normal_force)
        with np.errstate(divide="ignore"):
            bound = np.where(rate > 0.0, c / np.where(rate > 0.0, rate, 1.0), np.inf)
        return float(bound) if bound.ndim == 0 else bound

"""The tippe top: a sphere with an offset centre of mass on a table (physics.md §3).

Geometry (seed 2, 3.92-3.114): sphere radius ``a``; centre of mass ``G`` at ``h = alpha a``
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
integrator's own step; a touchdown is followed by a plastic, frictionless impact (:meth:`impact`): the normal
impulse stops the contact point's vertical motion, removes ``lambda^2 M_zz / 2`` of energy and
keeps Jellett's integral exactly (an impulse at the contact point has no moment about ``r``).
State ``(x, y, z, vx, vy, vz, q, Omega, c, hops)``: 15 components.

In every level the equations are written in the table's frame. Controls ``u`` are
``(a_x, a_y, mu, tau1, tau2, tau3)``: the table's horizontal acceleration [m/s^2] (a moving
plate: in its frame a fictitious force ``-m a_T`` acts at ``G``, so it reaches the rotation only
through friction), the friction coefficient, and an optional body torque [N m] about ``G``.
``u = None`` means a table at rest, the parameter's friction coefficient and no torque.

Jellett's integral ``J = L . (a z_hat - h k)`` (3.106) is conserved for any force at the
contact point or at ``G``: with no body torque it holds under every friction law and table
motion, which the tests and ``rbenvs verify`` check.

Components are floats (one state) or arrays of one batch shape (many states at once).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, NamedTuple

import numpy as np

from ..contracts import GuardRates
from ..jit import jitable
from ..rotations import atan2, maximum, quat_normalize, sqrt
from .contact import FRICTION_LAWS
from .validation import real_array, require_choice, require_finite_nonnegative, require_finite_positive, require_finite_result, require_real_vector

class Event(NamedTuple):
    """A switching event of a hybrid system (:meth:`TippeTop.events`): where it can happen
    (``applies(y)``), the function whose sign change (``>= 0`` to ``< 0``) it is, the tolerance
    to locate it to, and the state in the new mode at the event (``switch(y)``)."""

    name: str
    applies: Callable
    function: Callable
    tolerance: float
    switch: Callable


__all__ = ["TippeTopParams", "TippeTop", "Event", "FIDELITIES", "FRICTION_LAWS", "SPIN_STEP", "FRICTION_MARGIN", "tippe_rotation_rate"]

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


@jitable
def tippe_rotation_rate(p, y):
    """``max(|Omega|, omega_g)`` [rad/s], ``p = (index of Omega_1 in the state, omega_g)``."""
    o, omega_g = p
    w0, w1, w2 = y[o], y[o + 1], y[o + 2]
    return maximum(sqrt(w0 * w0 + w1 * w1 + w2 * w2), omega_g)


@dataclass(frozen=True)
class TippeTopParams:
    """Physical parameters. Defaults: the tippe top of Leine and Glocker (2003), physics.md §3.

    * ``radius`` ``a`` [m]; ``offset`` ``alpha = h / a`` in (0, 1); ``mass`` [kg]; ``gravity``.
    * ``inertia = (A, C)`` about the centre of mass [kg m^2], ``C <= 2 A`` (a real symmetric
      body: triangle inequality ``A + A >= C``).
    * ``friction``: the coefficient ``mu`` (>= 0): dimensionless for Coulomb, [s/m] for the
      viscous law ``F = -mu N v_P``.
    * ``friction_law``: ``"coulomb"``: ``F = -mu N v_P / sqrt(|v_P|^2 + slip_regularization^2)``
      (Coulomb's law, 3.96, smoothed for slips below ``slip_regularization`` [m/s]) or
      ``"viscous"``.
    """

    radius: float = 0.015
    mass: float = 0.006
    offset: float = 0.2
    inertia: tuple[float, float] = (8e-7, 7e-7)
    gravity: float = 9.81
    friction: float = 0.3
    friction_law: str = "coulomb"
    slip_regularization: float = 1e-3
    height: float = field(init=False, repr=False)  # h = alpha a [m]

    def __post_init__(self):
        a = require_finite_positive("radius", self.radius)
        m = require_finite_positive("mass", self.mass)
        g = require_finite_positive("gravity", self.gravity)
        alpha = require_finite_positive("offset", self.offset)
        if not alpha < 1.0:
            raise ValueError(f"offset (alpha = h/R, centre-of-mass offset over radius) must lie in (0, 1), got {self.offset!r}")
        big_a, big_c = require_real_vector("inertia", self.inertia, 2, " (A, C): the transverse and axial moments about the centre of mass")
        big_a = require_finite_positive("inertia[0] (A)", big_a)
        big_c = require_finite_positive("inertia[1] (C)", big_c)
        if big_c > 2.0 * big_a:
            raise ValueError(f"inertia must satisfy C <= 2 A (triangle inequality of a real body), got A={big_a!r}, C={big_c!r}")
        mu = require_finite_nonnegative("friction", self.friction)
        require_choice("friction_law", self.friction_law, FRICTION_LAWS)
        eps = require_finite_positive("slip_regularization", self.slip_regularization)
        # products the dynamics forms: refused here, by name, rather than overflowing in a step
        require_finite_result("mass, radius and inertia", m * a * a + big_a + big_c, "m a^2 + A + C [kg m^2]")
        require_finite_result("radius and inertia", (a + alpha * a) * (a + alpha * a) / min(big_a, big_c), "(a + h)^2 / min(A, C) [1/kg]")
        require_finite_result("mass and gravity", m * g * a, "m g a [J]")
        set_ = object.__setattr__
        for name, value in (("radius", a), ("mass", m), ("gravity", g), ("offset", alpha), ("inertia", (big_a, big_c)),
                            ("friction", mu), ("slip_regularization", eps), ("height", alpha * a)):
            set_(self, name, value)

    @property
    def gamma(self) -> float:
        """``A / C``: inversion needs ``1 - alpha < gamma < 1 + alpha`` (physics.md §3)."""
        return self.inertia[0] / self.inertia[1]

    def gravity_rate(self) -> float:
        """``sqrt(m g (a + h) / min(A, C))`` [rad/s]: an upper bound of the rates gravity drives
        through the contact (the weight at the longest arm ``|r| <= a + h`` over the smallest
        moment; the rocking frequency ``sqrt(m g h / (A + m (a - h)^2))`` of a top at rest is
        below it). The guard resolves it as it does the spin (``rbenvs.envs.tippe_top``)."""
        return math.sqrt(self.mass * self.gravity * (self.radius + self.height) / min(self.inertia))

    def contact_mobility(self) -> float:
        """An upper bound of ``|M|``, ``M = 1/m + [r x]^T I^-1 [r x]``: the contact point's
        acceleration per unit contact force [1/kg] (``|r| <= a + h``)."""
        return 1.0 / self.mass + (self.radius + self.height) ** 2 / min(self.inertia)


class TippeTop:
    """Vector field, contact forces and read-outs of the tippe top at one fidelity level."""

    def __init__(self, params: TippeTopParams, fidelity: str = "gliding", flight: bool = False):
        self._memo = None  # the last contact solve (see _contact)
        self._v = 2  # index of v_x in the state (not used when rolling)
        if fidelity not in FIDELITIES:
            raise ValueError(f"fidelity must be one of {list(FIDELITIES)}, got {fidelity!r}")
        self.params = params
        self.fidelity = fidelity
        self.rolling = fidelity == "rolling"
        self.flight = bool(flight)
        if self.flight and self.rolling:
            raise ValueError("flight=True needs fidelity 'gliding' or 'frictionless' (a rolling top has no slip to resume after a touchdown)")
        self.friction_law = None if fidelity != "gliding" else params.friction_law  # its name
        self.friction = None if self.friction_law is None else FRICTION_LAWS[self.friction_law]  # the law (dynamics.contact)
        if self.flight:
            self.layout = {"position": (0, 3), "velocity": (3, 6), "attitude": (6, 10), "angular_velocity": (10, 13), "contact": (13, 14), "hops": (14, 15)}
            self.dim = 15
            self._q, self._w = 6, 10
            self._v = 3  # index of v_x (2 without flight)
        elif self.rolling:
            self.layout = {"position": (0, 2), "attitude": (2, 6), "angular_velocity": (6, 9)}
            self.dim = 9
            self._q, self._w = 2, 6
        else:
            self.layout = {"position": (0, 2), "velocity": (2, 4), "attitude": (4, 8), "angular_velocity": (8, 11)}
            self.dim = 11
            self._q, self._w = 4, 8

    # ------------------------------------------------------------------ kinematics
    def frame(self, y):
        """Rotation matrix entries of ``q`` (body -> space) and ``Gamma = R^T z_hat``."""
        o = self._q
        w, x, yy, z = y[o], y[o + 1], y[o + 2], y[o + 3]
        r11, r12, r13 = 1.0 - 2.0 * (yy * yy + z * z), 2.0 * (x * yy - w * z), 2.0 * (x * z + w * yy)
        r21, r22, r23 = 2.0 * (x * yy + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (yy * z - w * x)
        r31, r32, r33 = 2.0 * (x * z - w * yy), 2.0 * (yy * z + w * x), 1.0 - 2.0 * (x * x + yy * yy)
        return (r11, r12, r13, r21, r22, r23, r31, r32, r33)

    def angular_velocity(self, y):
        o = self._w
        return (y[o], y[o + 1], y[o + 2])

    def vertical(self, y):
        """``Gamma``: the upward vertical in the body frame."""
        rm = self.frame(y)
        return (rm[6], rm[7], rm[8])

    def _contact_arm(self, g1, g2, g3):
        """``r = P - G = h e3 - a Gamma`` in the body frame."""
        a, h = self.params.radius, self.params.height
        return -a * g1, -a * g2, h - a * g3

    def _g_velocity_body(self, y, rm, w, r):
        """Velocity of ``G`` relative to the table, in the body frame."""
        w1, w2, w3 = w
        if self.rolling:  # v_P = 0: v_G = -Omega x r
            return -(w2 * r[2] - w3 * r[1]), -(w3 * r[0] - w1 * r[2]), -(w1 * r[1] - w2 * r[0])
        h = self.params.height
        vx, vy = y[self._v], y[self._v + 1]
        # d/dt (a - h cos(theta)), from the constraint (with flight: the contact's value, which
        # normalize() keeps in the state while c = 1; the flight branch does not use vb)
        vz = -h * (w2 * rm[6] - w1 * rm[7])
        return (rm[0] * vx + rm[3] * vy + rm[6] * vz, rm[1] * vx + rm[4] * vy + rm[7] * vz, rm[2] * vx + rm[5] * vy + rm[8] * vz)

    def velocity(self, y):
        """Velocity of ``G`` relative to the table, space frame, vertical part included."""
        if self.flight:
            return (y[3], y[4], y[5])
        rm = self.frame(y)
        w = self.angular_velocity(y)
        if not self.rolling:
            h = self.params.height
            return (y[2], y[3], -h * (w[1] * rm[6] - w[0] * rm[7]))
        vb = self._g_velocity_body(y, rm, w, self._contact_arm(rm[6], rm[7], rm[8]))
        return tuple(rm[3 * i] * vb[0] + rm[3 * i + 1] * vb[1] + rm[3 * i + 2] * vb[2] for i in range(3))

    def height(self, y):
        """``z_G`` [m]: ``a - h cos(theta)`` on the table (the constraint); with flight, the state's."""
        if self.flight:
            return y[2]
        rm = self.frame(y)
        return self.params.radius - self.params.height * rm[8]

    def gap(self, y):
        """Height of the sphere's lowest point above the table [m]: ``z_G + h cos(theta) - a``
        (0 on the table; positive in flight)."""
        if not self.flight:
            return 0.0 * y[0]
        rm = self.frame(y)
        return y[2] + self.params.height * rm[8] - self.params.radius

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
        """Everything the vector field needs: ``(dOmega, N, F_body, v_G_body, frame)``.

        The last result is kept for the same ``y`` and ``u`` objects: the lift-off check after
        an internal step solves the contact at the new state, and the next step's first stage
        asks for the same state (the very tuple the step returned), so one solve serves both
        (it was a fifth of a tippe-top step). A pure cache: same inputs, same outputs."""
        memo = self._memo
        if memo is not None and memo[0] is y and memo[1] is u:
            return memo[2]
        out = self._solve_contact(y, u)
        self._memo = (y, u, out)
        return out

    def _solve_contact(self, y, u):
        prm = self.params
        big_a, big_c = prm.inertia
        m, g, h = prm.mass, prm.gravity, prm.height
        rm = self.frame(y)
        g1, g2, g3 = rm[6], rm[7], rm[8]
        w1, w2, w3 = self.angular_velocity(y)
        r = self._contact_arm(g1, g2, g3)
        vb = self._g_velocity_body(y, rm, (w1, w2, w3), r)
        if u is None:
            ax = ay = t1 = t2 = t3 = 0.0
            mu = prm.friction
        else:
            ax, ay, mu, t1, t2, t3 = u
        # gyroscopic + applied torque, per moment: w0 = I^-1 (L x Omega + tau)
        w01 = ((big_a - big_c) * w2 * w3 + t1) / big_a
        w02 = ((big_c - big_a) * w3 * w1 + t2) / big_a
        w03 = t3 / big_c
        if self.rolling:
            return self._rolling_contact(rm, (w1, w2, w3), r, vb, (w01, w02, w03), (ax, ay))
        # slip velocity of the contact point, body frame, horizontal part
        s1 = vb[0] + w2 * r[2] - w3 * r[1]
        s2 = vb[1] + w3 * r[0] - w1 * r[2]
        s3 = vb[2] + w1 * r[1] - w2 * r[0]
        sv = s1 * g1 + s2 * g2 + s3 * g3  # zero by the constraint; removed against round-off
        s1, s2, s3 = s1 - sv * g1, s2 - sv * g2, s3 - sv * g3
        law = self.friction
        k = 0.0 if law is None else law.coefficient(mu, s1, s2, s3, prm.slip_regularization)
        f1, f2, f3 = k * s1, k * s2, k * s3  # friction per unit normal force
        e1, e2, e3 = g1 + f1, g2 + f2, g3 + f3  # contact force per unit N
        # torque per unit N about G, over the moments: a1 = I^-1 (r x e)
        a11 = (r[1] * e3 - r[2] * e2) / big_a
        a12 = (r[2] * e1 - r[0] * e3) / big_a
        a13 = (r[0] * e2 - r[1] * e1) / big_c
        # second derivative of z_G = a - h Gamma.e3 = 0 gives N (linear in N)
        c = w3 * (w1 * g1 + w2 * g2) - (w1 * w1 + w2 * w2) * g3
        den = 1.0 + m * h * (a12 * g1 - a11 * g2)
        n = m * (g - h * (w02 * g1 - w01 * g2 + c)) / den
        if self.flight:  # in flight (contact flag 0) no contact force: the same lines with N = 0
            n = y[13] * n
        dw = (w01 + n * a11, w02 + n * a12, w03 + n * a13)
        return dw, n, (n * f1, n * f2, n * f3), vb, rm, (ax, ay)

    def _rolling_contact(self, rm, w, r, vb, w0, accel):
        """Pure rolling: the contact force ``Lambda`` (body frame) keeps ``dv_P/dt = 0``.

        ``(1/m + [r x]^T I^-1 [r x]) Lambda = g Gamma + a_T - w0 x r - h Omega x (Omega x e3)``
        (from ``dv_G/dt = Lambda/m - g z_hat - a_T``, Euler's equations about ``G`` and
        ``dr/dt = h omega x k``); the matrix is symmetric positive definite.
        """
        prm = self.params
        big_a, big_c = prm.inertia
        m, g, h = prm.mass, prm.gravity, prm.height
        g1, g2, g3 = rm[6], rm[7], rm[8]
        w1, w2, w3 = w
        r1, r2, r3 = r
        d1, d2, d3 = 1.0 / big_a, 1.0 / big_a, 1.0 / big_c
        im = 1.0 / m
        m11 = im + d2 * r3 * r3 + d3 * r2 * r2
        m22 = im + d1 * r3 * r3 + d3 * r1 * r1
        m33 = im + d1 * r2 * r2 + d2 * r1 * r1
        m12, m13, m23 = -d3 * r1 * r2, -d2 * r1 * r3, -d1 * r2 * r3
        ax, ay = accel
        atb = (rm[0] * ax + rm[3] * ay, rm[1] * ax + rm[4] * ay, rm[2] * ax + rm[5] * ay)  # a_T in body
        # h Omega x (Omega x e3) = h (Omega Omega3 - e3 |Omega|^2)
        wsq = w1 * w1 + w2 * w2 + w3 * w3
        b1 = g * g1 + atb[0] - (w0[1] * r3 - w0[2] * r2) - h * w1 * w3
        b2 = g * g2 + atb[1] - (w0[2] * r1 - w0[0] * r3) - h * w2 * w3
        b3 = g * g3 + atb[2] - (w0[0] * r2 - w0[1] * r1) - h * (w3 * w3 - wsq)
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
        dw = (
            w0[0] + d1 * (r2 * l3 - r3 * l2),
            w0[1] + d2 * (r3 * l1 - r1 * l3),
            w0[2] + d3 * (r1 * l2 - r2 * l1),
        )
        n = l1 * g1 + l2 * g2 + l3 * g3
        return dw, n, (l1 - n * g1, l2 - n * g2, l3 - n * g3), vb, rm, accel

    # ------------------------------------------------------------------ vector field
    def rhs(self, y, u):
        dw, n, fb, vb, rm, (ax, ay) = self._contact(y, u)
        o = self._q
        qw, qx, qy, qz = y[o], y[o + 1], y[o + 2], y[o + 3]
        h1, h2, h3 = 0.5 * y[self._w], 0.5 * y[self._w + 1], 0.5 * y[self._w + 2]
        dq = (
            -qx * h1 - qy * h2 - qz * h3,
            qw * h1 + qy * h3 - qz * h2,
            qw * h2 - qx * h3 + qz * h1,
            qw * h3 + qx * h2 - qy * h1,
        )
        if self.flight:
            return self._flight_rhs(y, dq, dw, n, fb, rm, ax, ay)
        # horizontal velocity of G in space: from the state, or (rolling) from -Omega x r
        if self.rolling:
            dpos = (rm[0] * vb[0] + rm[1] * vb[1] + rm[2] * vb[2], rm[3] * vb[0] + rm[4] * vb[1] + rm[5] * vb[2])
            return dpos + dq + dw
        m = self.params.mass
        fx = rm[0] * fb[0] + rm[1] * fb[1] + rm[2] * fb[2]
        fy = rm[3] * fb[0] + rm[4] * fb[1] + rm[5] * fb[2]
        return (y[2], y[3], fx / m - ax, fy / m - ay) + dq + dw

    def _flight_rhs(self, y, dq, dw, n, fb, rm, ax, ay):
        """Vector field with free flight. ``_contact`` has already set the contact force to zero
        where ``c = 0``; what remains is the height: the constraint's rate on the table, the
        state's ``v_z`` in flight (a blend ``c X + (1 - c) Y``, exact for ``c`` in {0, 1}, so one
        expression serves floats and batches)."""
        prm = self.params
        m = prm.mass
        c = y[13]
        w1, w2, _ = self.angular_velocity(y)
        fx = rm[0] * fb[0] + rm[1] * fb[1] + rm[2] * fb[2]
        fy = rm[3] * fb[0] + rm[4] * fb[1] + rm[5] * fb[2]
        vz_contact = -prm.height * (w2 * rm[6] - w1 * rm[7])
        zero = 0.0 * c
        return (
            y[3],
            y[4],
            c * vz_contact + (1.0 - c) * y[5],
            fx / m - ax,
            fy / m - ay,
            n / m - prm.gravity,  # the friction force is horizontal: N alone lifts G
        ) + dq + dw + (zero, zero)

    def normalize(self, y):
        o = self._q
        y = tuple(y[:o]) + quat_normalize(y[o : o + 4]) + tuple(y[o + 4 :])
        if not self.flight:
            return y
        # in contact (c = 1) the height and vertical velocity are the constraint's
        c = y[13]
        f = 1.0 - c
        rm = self.frame(y)
        w1, w2, _ = self.angular_velocity(y)
        prm = self.params
        z = c * (prm.radius - prm.height * rm[8]) + f * y[2]
        vz = c * (-prm.height * (w2 * rm[6] - w1 * rm[7])) + f * y[5]
        return y[:2] + (z, y[3], y[4], vz) + y[6:]

    # ------------------------------------------------------------------ free flight: switches
    def impact(self, y):
        """Touchdown of a state at the table (gap 0, approaching): a plastic, frictionless
        impact. The normal impulse ``lambda z_hat`` at the contact point ends the vertical motion
        of the contact point, ``lambda = -v_Pz / M_zz``, ``M_zz = 1/m + (r x Gamma).I^-1(r x Gamma)``;
        the energy drops by ``lambda^2 M_zz / 2`` and Jellett's integral ``-L.r`` is unchanged
        (``(r x Gamma).r = 0``). Returns the state in contact (``c = 1``) and ``lambda`` [N s]."""
        prm = self.params
        big_a, big_c = prm.inertia
        rm = self.frame(y)
        g1, g2, g3 = rm[6], rm[7], rm[8]
        w1, w2, w3 = self.angular_velocity(y)
        r1, r2, r3 = self._contact_arm(g1, g2, g3)
        # moment arm of a vertical unit impulse, r x Gamma (body)
        t1, t2, t3 = r2 * g3 - r3 * g2, r3 * g1 - r1 * g3, r1 * g2 - r2 * g1
        m_zz = 1.0 / prm.mass + t1 * t1 / big_a + t2 * t2 / big_a + t3 * t3 / big_c
        # vertical velocity of the contact point: v_z + (Omega x r).Gamma = v_z + Omega.(r x Gamma)
        v_pz = y[5] + (w1 * t1 + w2 * t2 + w3 * t3)
        lam = -v_pz / m_zz
        if lam < 0.0:  # separating, not touching down: no impulse
            lam = 0.0
        w = (w1 + lam * t1 / big_a, w2 + lam * t2 / big_a, w3 + lam * t3 / big_c)
        out = y[:5] + (y[5] + lam / prm.mass,) + y[6:10] + w + (1.0, y[14])
        return self.normalize(out), lam

    # ------------------------------------------------------------------ hybrid system
    # (rbenvs.contracts.HybridSystem) A contact that can open: without free flight a lift-off
    # ends the episode (the terminal event); with it the top flies and lands (the switches).
    hybrid = True
    kernel_rhs = None  # no pure forms (yet)
    kernel_normalize = None
    kernel_readouts = None

    @property
    def switches(self) -> bool:
        """Whether the contact switches (free flight) rather than ending the episode."""
        return self.flight

    def terminal_event(self):
        """``("lift_off", fn)``: the event that ends an episode, ``fn(y, u)`` true where the
        contact would have to pull (``N < 0``); ``None`` with free flight (the top flies)."""
        return None if self.flight else ("lift_off", self.lifts_off)

    def lifts_off(self, y, u):
        """Lift-off: the contact would have to pull (``N < 0``); a bool or a mask."""
        return self.contact_forces(y, u)[0] < 0.0

    readout_names = ("energy", "jellett", "tilt", "normal_force", "slip_speed", "lifted_off", "airborne", "hops", "gap", "spin")

    def readouts(self, y, u=None, fired=False) -> tuple:
        """The read-outs in :attr:`readout_names` order under the control ``u`` that acted
        (``None``: a table at rest; the normal force depends on it): energy, Jellett's
        integral, tilt, normal force, slip speed, ``lifted_off`` (with free flight: a hop so
        far; without: the lift-off that ended this period, ``fired``), ``airborne``, ``hops``,
        the gap to the table and the spin. Floats or arrays."""
        normal, _, slip = self.contact_forces(y, u)
        if self.flight:
            hops, airborne = y[14], y[13] == 0.0
            lifted = hops > 0.0
            hops = int(hops) if isinstance(hops, float) else hops.astype(np.int64)
        else:
            airborne, lifted = 0.0 * y[0] != 0.0, fired
            hops = 0 if isinstance(y[0], float) else np.zeros(np.shape(y[0]), dtype=np.int64)
        return (self.energy(y), self.jellett(y), self.tilt(y), normal, slip, lifted, airborne, hops, self.gap(y), self.spin(y))

    def start_draws(self, rng):
        """The generator's numbers the system adds to a task's start: none."""
        return rng.random(0)

    def complete_initial_state(self, y, d):
        """A task's start as it is."""
        return y

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
        if not self.flight:
            return ()
        prm = self.params

        def normal(z):
            return self.constraint_normal_force(z, u)

        lift_off = Event("lift_off", self.on_table, normal, LIFT_OFF_TOL * prm.mass * prm.gravity, self.take_off)
        touchdown = Event("touchdown", self.airborne, self.gap, TOUCHDOWN_TOL * prm.radius, self.touch_down)
        return (lift_off, touchdown)

    @staticmethod
    def on_table(y) -> bool:
        return y[13] == 1.0

    @staticmethod
    def airborne(y) -> bool:
        return y[13] != 1.0

    @staticmethod
    def take_off(y):
        """The state at a lift-off: in flight, one more hop."""
        return y[:13] + (0.0, y[14] + 1.0)

    def touch_down(self, y):
        """The state after a touchdown: the plastic impact's."""
        return self.impact(y)[0]

    def constraint_normal_force(self, y, u):
        """``N`` [N] the contact constraint asks for at ``y`` under ``u`` (negative: the table
        would have to pull; lift-off); 0 in flight."""
        return self._contact(y, u)[1]

    # ------------------------------------------------------------------ read-outs
    def contact_forces(self, y, u=None):
        """``(N, (Fx, Fy), slip_speed)``: normal force [N], friction in space [N] and the slip
        speed ``|v_P|`` [m/s] (0 when rolling)."""
        dw, n, fb, vb, rm, _ = self._contact(y, u)
        fx = rm[0] * fb[0] + rm[1] * fb[1] + rm[2] * fb[2]
        fy = rm[3] * fb[0] + rm[4] * fb[1] + rm[5] * fb[2]
        return n, (fx, fy), self.slip_speed(y)

    def slip_speed(self, y):
        """``|v_P|`` [m/s], the speed of the material point at the contact."""
        if self.rolling:
            return 0.0 * y[0]
        rm = self.frame(y)
        w1, w2, w3 = self.angular_velocity(y)
        r = self._contact_arm(rm[6], rm[7], rm[8])
        vb = self._g_velocity_body(y, rm, (w1, w2, w3), r)
        s1 = vb[0] + w2 * r[2] - w3 * r[1]
        s2 = vb[1] + w3 * r[0] - w1 * r[2]
        s3 = vb[2] + w1 * r[1] - w2 * r[0]
        return sqrt(s1 * s1 + s2 * s2 + s3 * s3)

    def energy(self, y):
        """Kinetic (translation + rotation about ``G``) plus potential ``m g z_G`` [J], table frame."""
        prm = self.params
        big_a, big_c = prm.inertia
        w1, w2, w3 = self.angular_velocity(y)
        v = self.velocity(y)
        kin = 0.5 * prm.mass * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) + 0.5 * (big_a * (w1 * w1 + w2 * w2) + big_c * w3 * w3)
        return kin + prm.mass * prm.gravity * self.height(y)

    def jellett(self, y):
        """``J = L . (a z_hat - h k)`` [kg m^2/s] (3.106), in the body frame ``L.(a Gamma - h e3)``."""
        prm = self.params
        big_a, big_c = prm.inertia
        a, h = prm.radius, prm.height
        rm = self.frame(y)
        w1, w2, w3 = self.angular_velocity(y)
        return big_a * a * (w1 * rm[6] + w2 * rm[7]) + big_c * w3 * (a * rm[8] - h)

    def tilt(self, y):
        """``theta`` [rad] between the symmetry axis and the upward vertical (0 upright, pi
        inverted on the stem)."""
        rm = self.frame(y)
        return atan2(sqrt(rm[6] * rm[6] + rm[7] * rm[7]), rm[8])

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
        q = tuple(attitude)
        w = tuple(angular_velocity)
        if self.rolling:
            return pos + q + w
        if velocity is None:
            velocity = self.no_slip_velocity(q, w)[:2]
        if self.flight:  # on the table: z and v_z from the constraint (normalize), no lift-off yet
            zero = 0.0 * q[0]
            y = pos + (zero,) + tuple(velocity)[:2] + (zero,) + q + w + (zero + 1.0, zero)
            return self.normalize(y)
        return pos + tuple(velocity)[:2] + q + w

    def no_slip_velocity(self, attitude, angular_velocity):
        """``v_G = -omega x r`` in space [m/s]: the velocity that puts the contact point at rest."""
        y = (0.0 * attitude[0],) * self._q + tuple(attitude) + tuple(angular_velocity)
        rm = self.frame(y)  # (reads only the attitude)
        w = tuple(angular_velocity)
        r = self._contact_arm(rm[6], rm[7], rm[8])
        vb = (-(w[1] * r[2] - w[2] * r[1]), -(w[2] * r[0] - w[0] * r[2]), -(w[0] * r[1] - w[1] * r[0]))
        return tuple(rm[3 * i] * vb[0] + rm[3 * i + 1] * vb[1] + rm[3 * i + 2] * vb[2] for i in range(3))

    def export_state(self, y) -> dict:
        """Named arrays: ``position`` (3, with ``z_G`` from the constraint), ``velocity`` (3,
        space, table frame), ``attitude`` (4, w x y z, body to space), ``angular_velocity`` (3, body)."""
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
            raise ValueError(f"options['state'] must be a dict of named arrays, got {type(state).__name__}")
        unknown, missing = sorted(set(state) - set(names)), sorted(set(names) - set(state))
        if unknown or missing:
            raise ValueError(f"state must have exactly the names {sorted(names)}" + (f"; unknown: {unknown}" if unknown else "") + (f"; missing: {missing}" if missing else ""))
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
            raise ValueError(f"state['attitude'] must be a unit quaternion (|q| = 1 within 1e-6), got |q| = {qn}")
        q = tuple(float(c) for c in arrs["attitude"])
        w = tuple(float(c) for c in arrs["angular_velocity"])
        pos = tuple(float(c) for c in arrs["position"])
        vel = tuple(float(c) for c in arrs["velocity"])
        y = self.state(pos, q, w, vel[:2])
        prm = self.params
        if self.flight:
            return self._place_flight_state(y, pos, vel)
        z = self.height(y)
        if abs(pos[2] - z) > 1e-9 * prm.radius + 1e-12:
            raise ValueError(f"state['position'][2] must be the contact height a - h cos(theta) = {z!r} m for this attitude (the sphere touches the table), got {pos[2]!r}")
        v_need = self.velocity(y)
        scale = 1e-9 * (1.0 + prm.radius * float(np.linalg.norm(w)))
        checked = range(3) if self.rolling else (2,)
        for i in checked:
            if abs(vel[i] - v_need[i]) > scale:
                what = "the rolling velocity -omega x r" if self.rolling else "the vertical velocity the contact constraint gives"
                raise ValueError(f"state['velocity'] must equal {what} ({list(v_need)}), got {list(vel)}")
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
            raise ValueError(f"state['position'][2] puts the sphere {-gap!r} m into the table (z_G must be >= a - h cos(theta) = {pos[2] - gap!r} m)")
        if gap > tol:
            return air
        v_need = self.velocity(y)[2]  # y is on the table: the constraint's v_z
        scale = 1e-9 * (1.0 + prm.radius * float(np.linalg.norm(y[10:13])))
        if vel[2] - v_need > scale:  # on the table and leaving it: in flight
            return air
        if abs(vel[2] - v_need) > scale:
            raise ValueError(f"state['velocity'][2] must be the vertical velocity the contact constraint gives ({v_need!r}) or above it (leaving the table), got {vel[2]!r}")
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
        return self.friction.stiffness(mu, 2.0 * load, prm.contact_mobility(), prm.slip_regularization)

    def friction_rate(self, _p, y, u):
        """The guard's ``lambda_d`` at ``y`` under ``u`` (``(fn, P)`` form: ``P`` unused)."""
        mu = self.params.friction if u is None else u[2]
        return self.friction_stiffness(mu, self.contact_forces(y, u)[0])

    def guard_rates(self, region, speed_ceiling: float = math.inf) -> GuardRates:
        """The contact geometry turns with the body: ``max(|Omega|, omega_g) h <= SPIN_STEP``
        (0.1 rad, an accuracy bound of this system for every scheme; ``omega_g`` from
        :meth:`TippeTopParams.gravity_rate`), and, with friction, ``h <= c / lambda_d``
        (:meth:`friction_stiffness`) with ``c`` half the scheme's real-axis interval (euler
        1.0, rk4 1.39; none for dop853)."""
        omega_g = self.params.gravity_rate()
        dissipation = (self.friction_rate, ()) if self.friction_law is not None else None
        text = f"lambda = max(|Omega|, omega_g) (omega_g = {omega_g:.6g} rad/s)"
        if dissipation is not None:
            text += f", lambda_d = the {self.friction_law} law's stiffness at 2 max(m g, N)"
        return GuardRates(rotation=(tippe_rotation_rate, (self._w, omega_g)), rotation_bound=SPIN_STEP, dissipation=dissipation,
                          dissipation_margin=FRICTION_MARGIN, ceiling=max(speed_ceiling, omega_g), text=text)

    def max_stable_step(self, region, mu: float | None = None, normal_force: float | None = None) -> float:
        """The largest internal step [s] at which the friction law is stable for a scheme of
        ``region`` (a :class:`~rbenvs.contracts.StepRegion`, or an integrator declaring one):
        ``c / lambda_d``, ``c`` =
        ``FRICTION_MARGIN`` of its real-axis interval (euler ``h lambda <= 2``: ``c = 1``; rk4
        2.78: ``c = 1.39``), ``lambda_d`` from :meth:`friction_stiffness` at ``mu`` (default:
        the parameter's) and ``normal_force`` (default ``m g``). ``inf`` without friction, when
        rolling, and for schemes without a real-axis bound (dop853). Arrays in, array out."""
        region = getattr(region, "region", region)  # an integrator, or its region
        c = FRICTION_MARGIN * region.dissipation
        if self.friction_law is None or c == math.inf:
            return math.inf
        rate = self.friction_stiffness(self.params.friction if mu is None else mu, normal_force)
        with np.errstate(divide="ignore"):
            bound = np.where(rate > 0.0, c / np.where(rate > 0.0, rate, 1.0), np.inf)
        return float(bound) if bound.ndim == 0 else bound

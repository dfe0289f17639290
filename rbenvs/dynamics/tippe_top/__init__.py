"""The tippe top: a sphere with an offset centre of mass on a table (docs/physics.md §3).

The package by concern: :mod:`.params` (the parameters and the step rule's settings),
:mod:`.forms` (the pure forms of the contact, the vector fields and the flight switches),
:mod:`.stem` (the stem's second contact), :mod:`.implicit` (the friction's linearisation for
the linearly implicit schemes) and :mod:`.system` (:class:`TippeTop`).

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

from ..contact import FRICTION_LAWS
from .forms import (
    PURE_PARAMETERS,
    TippeForms,
    applied_rate,
    constraint_vertical_velocity,
    contact_arm,
    flight_airborne,
    flight_derivative,
    flight_gap,
    flight_impact,
    flight_normalize,
    flight_on_table,
    flight_take_off,
    flight_touch_down,
    pure_forms,
    pure_parameters,
    rolling_contact,
    rolling_derivative,
    rolling_normalize,
    rolling_velocity_body,
    sliding_derivative,
    sliding_normalize,
    slip_velocity,
    tippe_energy,
    tippe_frame,
    tippe_jellett,
    to_space,
    vertical_tilt,
)
from .implicit import ImplicitForms, implicit_forms, tangential_mobility
from .params import (
    ACCURACY_MARGIN,
    FIDELITIES,
    FRICTION_BOUNDS,
    FRICTION_MARGIN,
    JELLETT_SCALE,
    LIFT_OFF_TOL,
    SPIN_STEP,
    STIFF_BAND,
    TOUCHDOWN_TOL,
    Event,
    TippeTopParams,
    tippe_rotation_rate,
)
from .stem import (
    STEM_TOL,
    stem_forms,
    stem_impact,
    stem_jellett,
    stem_other_gap,
    stem_params,
    stem_switch,
)
from .system import TippeTop

__all__ = [
    "LIFT_OFF_TOL",
    "TOUCHDOWN_TOL",
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
    "STIFF_BAND",
    "JELLETT_SCALE",
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

"""The tippe top's stem: a second contact sphere (docs/physics.md §3, "The stem")."""

from __future__ import annotations

from functools import cache

from ...jit import jitable
from .forms import (
    TippeForms,
    _zero_counts_arrays,
    constraint_vertical_velocity,
    contact_arm,
    pure_forms,
    sliding_derivative,
    sliding_normalize,
    solve_forms,
    tippe_frame,
    tippe_jellett,
)

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


def _stem_state_forms(base: TippeForms) -> dict:
    """The state functions that read the pressing contact (``velocity``, ``height``,
    ``slip_speed``, ``energy``), ``gap`` (the sphere's) and ``state`` (on the sphere)."""
    velocity0, height0, slip0 = base.velocity, base.height, base.slip_speed
    energy0, state0 = base.energy, base.state

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

    return dict(
        velocity=velocity,
        height=height,
        gap=gap,
        slip_speed=slip_speed,
        energy=energy,
        state=state,
    )


def _stem_contact_forms(base: TippeForms, energy, slip_speed, gap) -> dict:
    """The contact functions at the pressing contact's parameters (:func:`stem_params`)."""
    contact0, friction_rate0 = base.contact, base.friction_rate
    jellett, tilt, spin = base.jellett, base.tilt, base.spin

    @jitable
    def contact(p, y, u):
        return contact0(stem_params(p, y[11]), y, u)

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

    return dict(
        contact=contact,
        **solve_forms(contact, stem_derivative),
        readouts=readouts,
        friction_rate=friction_rate,
    )


@cache
def stem_forms(coefficient, stiffness) -> TippeForms:
    """The :class:`TippeForms` of a gliding or frictionless top with the stem (``P`` of
    :func:`pure_parameters` with ``(b, d)``; state: the gliding one and the contact flag): the
    sphere's forms at :func:`stem_params` of the flag. The read-outs: the energy, the normal
    force and the slip of the pressing contact, Jellett's integral of the sphere ``L.(a z_hat - h
    k)`` (:func:`stem_jellett` gives the stem's), and as ``gap`` the sphere's gap (0 while it
    presses)."""
    base = pure_forms(coefficient, stiffness, False, False)
    states = _stem_state_forms(base)
    contacts = _stem_contact_forms(base, states["energy"], states["slip_speed"], states["gap"])
    return base._replace(derivative=stem_derivative, **states, **contacts)


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
        return accuracy_rate0((stem_params(q[0], y[11]), q[1], q[2], q[3]), y, u)

    return accuracy_rate

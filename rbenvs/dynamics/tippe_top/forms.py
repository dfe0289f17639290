"""The tippe top's pure forms: its arithmetic as functions of ``(P, state[, control])`` (see
the package)."""

from __future__ import annotations

from collections.abc import Callable
from functools import cache
from typing import NamedTuple

import numpy as np

from ...jit import jitable
from ...rotations import atan2, quat_normalize, quat_rate, sqrt
from .params import TippeTopParams

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


def _offsets(rolling: bool, flight: bool) -> tuple:
    """``(Q, W)``: where a layout's quaternion and ``Omega`` start, constants of each state
    function (compiled code keeps the one branch that applies)."""
    return (6, 10) if flight else ((2, 6) if rolling else (4, 8))


def _kinematic_forms(rolling: bool, flight: bool) -> tuple:
    """``(frame, angular_velocity, velocity, height, gap)`` of one layout."""
    Q, W = _offsets(rolling, flight)

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

    return frame, angular_velocity, velocity, height, gap


def _measure_forms(rolling: bool, flight: bool, frame, velocity, height) -> tuple:
    """``(slip_speed, energy, jellett, tilt, spin)`` of one layout, from its kinematic forms."""
    W = _offsets(rolling, flight)[1]

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

    return slip_speed, energy, jellett, tilt, spin


def _state_readouts_form(flight: bool, energy, jellett, tilt, slip_speed, gap, spin):
    """``state_readouts(P, y, n, fired)``: the read-outs given the normal force ``n``."""

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

    return state_readouts


def _start_form(rolling: bool, flight: bool, normalize):
    """``state(P, x, y, q, w, v=None)``: a layout's components from a top's motion (starts)."""

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

    return state


@cache
def _state_forms(rolling: bool, flight: bool) -> tuple:
    """``(fields, state_readouts)``: the state functions of :class:`TippeForms` for one layout
    by field name (no friction law in them) and the read-outs given ``N``."""
    frame, angular_velocity, velocity, height, gap = _kinematic_forms(rolling, flight)
    slip_speed, energy, jellett, tilt, spin = _measure_forms(
        rolling, flight, frame, velocity, height
    )
    normalize = (
        flight_normalize if flight else (rolling_normalize if rolling else sliding_normalize)
    )
    fields = dict(
        frame=frame,
        angular_velocity=angular_velocity,
        velocity=velocity,
        height=height,
        gap=gap,
        slip_speed=slip_speed,
        energy=energy,
        jellett=jellett,
        tilt=tilt,
        spin=spin,
        normalize=normalize,
        state=_start_form(rolling, flight, normalize),
    )
    return fields, _state_readouts_form(flight, energy, jellett, tilt, slip_speed, gap, spin)


def _sliding_contact_form(coefficient, flight: bool):
    """``sliding_contact(P, y, u)``: the contact tuple of a gliding or frictionless top under the
    law's pure ``coefficient`` (with ``flight``: zero off the table)."""

    @jitable
    def sliding_contact(p, y, u):
        """The contact while the sphere slides: ``N`` is whatever keeps the second derivative
        of ``z_G = a - h Gamma.e3`` zero (linear in ``N``: the friction law scales with it)."""
        _, h, m, g, big_a, big_c, _, eps, _ = p
        if flight:  # (the flight state carries z_G and v_z before the attitude)
            vx, vy = y[3], y[4]
            qw, qx, qy, qz, w1, w2, w3 = y[6], y[7], y[8], y[9], y[10], y[11], y[12]
        else:
            vx, vy = y[2], y[3]
            qw, qx, qy, qz, w1, w2, w3 = y[4], y[5], y[6], y[7], y[8], y[9], y[10]
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

    return sliding_contact


def _contact_forms(contact, derivative, state_readouts) -> dict:
    """The fields ``rhs``, ``rhs_normal``, ``normal`` (:func:`solve_forms`) and ``readouts`` of
    :class:`TippeForms`: each one contact solve."""

    @jitable
    def readouts(p, y, u, fired):
        return state_readouts(p, y, contact(p, y, u)[0], fired)

    return dict(**solve_forms(contact, derivative), readouts=readouts)


def solve_forms(contact, derivative) -> dict:
    """``rhs``, ``rhs_normal`` and ``normal`` through one contact solve each (the sphere's and
    the stem's alike)."""

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

    return dict(rhs=rhs, rhs_normal=rhs_normal, normal=normal)


def _friction_rate_form(contact, stiffness):
    """``friction_rate(P, y, u)``: the guard's ``lambda_d`` of the law's pure ``stiffness``."""

    @jitable
    def friction_rate(p, y, u):
        """The guard's ``lambda_d`` [1/s]: the law's stiffness at twice ``max(m g, N)``
        (:meth:`TippeTop.friction_stiffness`) and ``u``'s friction coefficient."""
        m, g, mu0, eps, mobility = p[2], p[3], p[6], p[7], p[8]
        mu = mu0 if u is None else u[2]
        # np.maximum on floats too (an IEEE max that keeps a NaN, as on arrays)
        load = np.maximum(m * g, contact(p, y, u)[0])
        return stiffness(mu, 2.0 * load, mobility, eps)

    return friction_rate


@cache
def pure_forms(coefficient, stiffness, rolling: bool, flight: bool) -> TippeForms:
    """The :class:`TippeForms` of one combination: the friction law's pure ``coefficient(mu, s1,
    s2, s3, eps)`` and ``stiffness(mu, N, mobility, eps)`` (:mod:`rbenvs.dynamics.contact`;
    :func:`~rbenvs.dynamics.contact.no_friction` and ``None`` without friction), ``rolling`` and
    ``flight``. Made once per combination (the functions close over the law's functions, which
    compiled code then calls as constants)."""
    fields, state_readouts = _state_forms(rolling, flight)
    derivative = (
        flight_derivative if flight else (rolling_derivative if rolling else sliding_derivative)
    )
    sliding_contact = _sliding_contact_form(coefficient, flight)
    contact = rolling_contact if rolling else sliding_contact
    friction_rate = None if stiffness is None else _friction_rate_form(contact, stiffness)
    return TippeForms(
        contact=contact,
        derivative=derivative,
        friction_rate=friction_rate,
        **_contact_forms(contact, derivative, state_readouts),
        **fields,
    )

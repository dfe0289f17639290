"""The friction's linearisation: what the linearly implicit schemes and the tight stiffness rate
need."""

from __future__ import annotations

from collections.abc import Callable
from functools import cache
from typing import NamedTuple

from ...jit import jitable
from ...rotations import maximum, power, select, sqrt
from .forms import constraint_vertical_velocity, contact_arm, pure_forms, slip_velocity, tippe_frame
from .params import JELLETT_SCALE, STIFF_BAND

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
    * ``accuracy_rate((P, K, omega_g, dt), y, u)``: the guard's rate with
      ``friction_bound="accuracy"`` over a period of ``dt``;
    * ``share(((P, omega_g), c_f / C), y, u, dt, p, lambda_g) -> a``: the share of ``C (lambda_g
      h)^p`` (``lambda_g`` the friction guard's rate at ``y``) that the slip relaxation's error is
      in a
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
    contact = forms.contact
    layout = (6, 10, 3) if flight else ((2, 6, 0) if rolling else (4, 8, 2))
    frictionless = slope is None or rolling
    table_slip = _table_slip_form(layout)
    slip_change = _slip_change_form(layout)
    factor = _factor_form(layout, frictionless, coefficient, slope, contact, table_slip)
    solve = _solve_form(layout, frictionless, flight, slip_change)
    rate = accuracy_rate = share = None
    if stiffness is not None and not rolling:
        rate_at, rate = _rate_forms(layout, stiffness, contact)
        slip_rates = _slip_rates_form(layout, table_slip, slip_change, forms.rhs_normal)
        ratio = _stiffness_ratio_form(coefficient)
        accuracy_rate = _accuracy_rate_form(layout, slip_rates, ratio, rate_at)
        share = _share_form(layout, slip_rates, ratio, rate_at, saturates)
    return ImplicitForms(factor, solve, rate, accuracy_rate, share)


def _table_slip_form(layout: tuple):
    """``table_slip(P, y)`` of a layout ``(Q, W, V)``: the quaternion's, ``Omega``'s and
    ``v_G``'s offsets in the state."""
    Q, W, V = layout

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

    return table_slip


def _factor_form(layout: tuple, frictionless: bool, coefficient, slope, contact, table_slip):
    """``factor(P, y, u, g)``: what ``W^-1`` needs at ``y`` (:class:`ImplicitForms`)."""
    Q, W, V = layout

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

    return factor


def _slip_change_form(layout: tuple):
    """``slip_change(P, frame, arm, q, v_G, Omega, x)``: ``sigma = C x`` of a layout."""
    Q, W, V = layout

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

    return slip_change


def _solve_form(layout: tuple, frictionless: bool, flight: bool, slip_change):
    """``solve(P, W, x) -> W^-1 x`` (:class:`ImplicitForms`)."""
    Q, W, V = layout

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

    return solve


def _rate_forms(layout: tuple, stiffness, contact) -> tuple:
    """``(rate_at, rate)``: the law's stiffness at a given normal force and mobility, and the
    tight rate (:class:`ImplicitForms`' ``rate``) at the actual ``N`` and the largest tangential
    mobility."""
    Q = layout[0]

    @jitable
    def rate_at(p, u, normal, top):
        """The law's stiffness at the normal force ``normal`` and the mobility ``top`` along the
        table."""
        mu = p[6] if u is None else u[2]
        return stiffness(mu, maximum(normal, 0.0 * mu), top, p[7])

    @jitable
    def rate(p, y, u):
        rm = tippe_frame(y[Q], y[Q + 1], y[Q + 2], y[Q + 3])
        _, top = tangential_mobility(p, rm[6], rm[7], rm[8])
        return rate_at(p, u, contact(p, y, u)[0], top)

    return rate_at, rate


def _accuracy_rate_form(layout: tuple, slip_rates, stiffness_ratio, rate_at):
    """``accuracy_rate((P, K, omega_g, dt), y, u)`` (:class:`ImplicitForms`)."""
    W = layout[1]

    @jitable
    def accuracy_rate(q, y, u):
        """The friction guard's rate with ``friction_bound="accuracy"``, ``q = (P, K, omega_g,
        dt)``: ``lambda_a(kappa' lambda_d)`` with ``lambda_a(x) = max(x, K sqrt(x w))``, ``w =
        max(|Omega|, omega_g)``, ``kappa' = min(1, STIFF_BAND kappa)``, ``kappa`` the law's
        coefficient at the smallest slip the period of ``dt`` can reach over its value at zero
        slip (``share``'s), and at least ``min(lambda_a(lambda_d), JELLETT_SCALE w)``
        (:mod:`rbenvs.dynamics.tippe_top.params`; the law's ``accuracy_scale``)."""
        p, k, omega_g, dt = q
        mu = p[6] if u is None else u[2]
        rm, (s1, s2, s3), (t1, t2, t3), normal = slip_rates(p, y, u)
        _, kappa = stiffness_ratio(mu, p[7], s1, s2, s3, t1, t2, t3, dt)
        _, top = tangential_mobility(p, rm[6], rm[7], rm[8])
        full = rate_at(p, u, normal, top)
        band = STIFF_BAND * kappa
        lam = select(band < 1.0, band, 0.0 * band + 1.0) * full
        w = sqrt(y[W] * y[W] + y[W + 1] * y[W + 1] + y[W + 2] * y[W + 2])
        w = maximum(w, 0.0 * w + omega_g)
        whole = maximum(full, k * sqrt(full * w))
        floor = JELLETT_SCALE * w
        floor = select(floor < whole, floor, whole)
        return maximum(maximum(lam, k * sqrt(lam * w)), floor)

    return accuracy_rate


def _slip_rates_form(layout: tuple, table_slip, slip_change, rhs_normal):
    """``slip_rates(P, y, u)``: the frame, the table slip and its rate along the vector field
    (both on the table's plane) and the normal force, from one contact solve: what the accuracy
    rate and ``share`` read."""
    Q, W, V = layout

    @jitable
    def slip_rates(p, y, u):
        rm, (r1, r2, r3), vz, (s1, s2, s3) = table_slip(p, y)
        g1, g2, g3 = rm[6], rm[7], rm[8]
        w1, w2, w3 = y[W], y[W + 1], y[W + 2]
        f, normal = rhs_normal(p, y, u)
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
        return rm, (s1, s2, s3), (t1 - tn * g1, t2 - tn * g2, t3 - tn * g3), normal

    return slip_rates


def _stiffness_ratio_form(coefficient):
    """``stiffness_ratio(mu, eps, s, t, dt) -> (|s|, kappa)`` of the law's pure ``coefficient``."""

    @jitable
    def stiffness_ratio(mu, eps, s1, s2, s3, t1, t2, t3, dt):
        """``kappa``: the law's coefficient at the smallest slip the period can reach (``|s|``
        closing at twice its present rate ``t``) over its value at zero slip."""
        ns = sqrt(s1 * s1 + s2 * s2 + s3 * s3)
        closing = (s1 * t1 + s2 * t2 + s3 * t3) / maximum(ns, 0.0 * ns + 1e-300)
        reach = ns + 2.0 * dt * select(closing < 0.0, closing, 0.0 * closing)
        reach = select(reach > 0.0, reach, 0.0 * reach)
        k0 = coefficient(mu, 0.0 * ns, 0.0 * ns, 0.0 * ns, eps)
        kappa = coefficient(mu, reach, 0.0 * ns, 0.0 * ns, eps) / select(
            k0 < 0.0, k0, 0.0 * k0 - 1.0
        )
        return ns, kappa

    return stiffness_ratio


def _share_form(layout: tuple, slip_rates, stiffness_ratio, rate_at, saturates: bool):
    """``share(((P, omega_g), c_f / C), y, u, dt, p, lambda_g)`` (:class:`ImplicitForms`)."""
    W, V = layout[1], layout[2]

    @jitable
    def share(q, y, u, dt, order, guard):
        (p, omega_g), forced_ratio = q
        mu = p[6] if u is None else u[2]
        eps = p[7]
        rm, (s1, s2, s3), (t1, t2, t3), normal = slip_rates(p, y, u)
        g1, g2, g3 = rm[6], rm[7], rm[8]
        w1, w2, w3 = y[W], y[W + 1], y[W + 2]
        ns, kappa = stiffness_ratio(mu, eps, s1, s2, s3, t1, t2, t3, dt)
        # the mode at its local stiffness kappa lambda_d (lambda_d the law's at zero slip, the
        # guard's rate at least), as large as the state
        _, top = tangential_mobility(p, g1, g2, g3)
        lam = rate_at(p, u, normal, top)
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
        # both are errors of the slip in its stiffest mode, carried in v_G: an error dF of the
        # friction force moves the slip by M dF h and v_G by dF h / m, so 1 / (m l_max) of it
        # (l_max the mobility's largest eigenvalue; the slower mode is not counted)
        a = (transient + forced) / (p[2] * top)
        a = select(a < full, a, full)
        if saturates:
            # a saturating law (Coulomb): the slip can leave the band and grow to a sliding
            # speed, amplifying the error it carries; so the error is held relative to the slip,
            # max(|s|, eps), not to v_G (the v_G split undone), and not capped
            return (
                a * (p[2] * top) * maximum(speed, 0.0 * speed + eps) / maximum(ns, 0.0 * ns + eps)
            )
        return select(a < 1.0, a, 0.0 * a + 1.0)

    return share

"""The free rigid body: Euler's equations with a body-frame torque (docs/physics.md §1).

State layout (components, see :mod:`rbenvs.rotations` for the convention):

* ``(Pi1, Pi2, Pi3)``: body angular momentum ``Pi`` [kg m^2/s], principal body frame;
* optionally followed by ``(qw, qx, qy, qz)``: attitude, unit quaternion body -> space.

A scene that ignores the attitude does not carry it (``attitude=False``): Euler's equations
close on ``Pi`` alone, and the quaternion would cost four more components in every stage.

Everything here is pure: a frozen parameter object and components in, components out. Each
component is a float (single state) or an array of any batch shape (many states at once).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..contracts import GuardRates
from ..draws import draw
from ..elliptic import elliptic_f_sc, elliptic_k, jacobi_sn_cn_dn
from ..jit import jitable
from ..rotations import maximum, quat_multiply, quat_normalize, quat_rate, select, sqrt
from .flows import AxisRotation
from .state import export_layout, import_layout, start_as_drawn
from .validation import require_inertia

__all__ = [
    "FreeBodyParams",
    "FreeBody",
    "FreeBodyOrbit",
    "euler_rhs",
    "kinetic_energy",
    "momentum_norm",
    "angular_velocity",
    "rotation_rate",
    "jacobian_rate",
    "error_rate",
    "error_rate_params",
    "free_body_readouts",
    "attitude_rhs",
    "attitude_normalize",
    "free_body_kick",
]

_CYCLIC = {(0, 1, 2), (1, 2, 0), (2, 0, 1)}


@dataclass(frozen=True)
class FreeBodyParams:
    """Principal moments of inertia ``(I1, I2, I3)`` [kg m^2] about the centre of mass.

    Validated at construction: finite, positive, and the triangle inequalities
    ``Ii + Ij >= Ik`` (equality allowed: a flat plate).
    """

    inertia: tuple[float, float, float]
    # Derived coefficients of Euler's equations, dPi1/dt = c1 Pi2 Pi3 + tau1 etc. (docs/physics.md
    # §1)
    coefficients: tuple[float, float, float] = field(init=False, repr=False)
    inverse: tuple[float, float, float] = field(init=False, repr=False)

    def __post_init__(self):
        i1, i2, i3 = require_inertia("inertia", self.inertia)
        object.__setattr__(self, "inertia", (i1, i2, i3))
        object.__setattr__(
            self,
            "coefficients",
            ((i2 - i3) / (i2 * i3), (i3 - i1) / (i3 * i1), (i1 - i2) / (i1 * i2)),
        )
        object.__setattr__(self, "inverse", (1.0 / i1, 1.0 / i2, 1.0 / i3))

    @property
    def axis_order(self) -> tuple[int, int, int]:
        """Indices of the (major, intermediate, minor) axes; ties broken by index."""
        order = sorted(range(3), key=lambda i: (-self.inertia[i], i))
        return (order[0], order[1], order[2])


# Pure functions on the momentum components ``y[0:3]`` (floats or arrays; compiled by
# rbenvs.compiled for the batch kernel). The methods of FreeBody call them.
@jitable
def euler_rhs(c, y, u):
    """``dPi/dt = Pi x Omega + tau`` [MR 15.3.9-10] with ``c`` the coefficients of
    :class:`FreeBodyParams`: ``dPi1/dt = c1 Pi2 Pi3 + tau1`` etc."""
    c1, c2, c3 = c
    p1, p2, p3 = y[0], y[1], y[2]
    d1 = c1 * p2 * p3
    d2 = c2 * p3 * p1
    d3 = c3 * p1 * p2
    if u is not None:
        d1 = d1 + u[0]
        d2 = d2 + u[1]
        d3 = d3 + u[2]
    return (d1, d2, d3)


@jitable
def kinetic_energy(inv, y):
    """``H = 1/2 sum Pi_i^2 / I_i`` [J], ``inv`` the inverse moments."""
    j1, j2, j3 = inv
    return 0.5 * (j1 * y[0] * y[0] + j2 * y[1] * y[1] + j3 * y[2] * y[2])


@jitable
def momentum_norm(y):
    """``|Pi|`` [kg m^2/s]."""
    return sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2])


@jitable
def angular_velocity(inv, y):
    """``Omega = I^-1 Pi`` [rad/s]."""
    j1, j2, j3 = inv
    return (j1 * y[0], j2 * y[1], j3 * y[2])


@jitable
def rotation_rate(p, y):
    """``lambda = w |Omega| + r`` [1/s], ``p = (inv, w, r)``: a rigid body's fastest rotation
    rate for the step guard (the body-frame vectors turn about ``Omega`` at ``|Omega|``; ``r``
    adds state-independent rates such as gravity's). ``w = 0`` skips ``|Omega|``."""
    inv, weight, fixed = p
    if weight != 0.0:
        w = angular_velocity(inv, y)
        speed = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
        return weight * speed + fixed
    return fixed


@jitable
def jacobian_rate(p, y):
    """``lambda_e = s |Pi|`` [1/s], ``p = (s,)`` with ``s = max_i 1/I_i - min_i 1/I_i``: a bound of
    the Jacobian of Euler's equations and of their second derivative's share, the rate of the
    error ``tolerance=`` estimates (:func:`rbenvs.stepsize.forms.motion_rates`).

    Why: ``Pi x (a Pi) = 0`` for any ``a``, so ``dPi/dt = Pi x D Pi + tau`` with ``D = I^-1 - a``;
    with ``a`` the midpoint of the inverse moments ``|D| = s / 2``. Then ``f'(Pi) v = v x D Pi +
    Pi x D v`` has norm ``<= s |Pi|``, ``f''(v, w) = v x D w + w x D v`` norm ``<= s`` and the
    third derivative is 0: every elementary differential of a scheme's local error is bounded by
    powers of ``s |Pi|`` times ``|dPi/dt|``. The moments' spread sets how fast ``Pi`` moves in the
    body frame, not ``|Omega|`` (``s |Pi| <= |Omega|`` where ``I_max <= 2 I_min``; nearly equal
    moments: ``s -> 0``, ``Pi`` barely moves whatever the spin)."""
    (spread,) = p
    return spread * sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2])


@jitable
def _cross(a1, a2, a3, b1, b2, b3):
    return (a2 * b3 - a3 * b2, a3 * b1 - a1 * b3, a1 * b2 - a2 * b1)


@jitable
def error_rate(p, y):
    """``lambda_e = min(s |Pi|, (|dddPi| / |dPi|)^(1/2) + sigma |Pi|)`` [1/s], ``p = (inv, s,
    sigma)``: the rate of the error ``tolerance=`` estimates for the free body without attitude
    (:func:`rbenvs.stepsize.forms.motion_rates`), the torque-free motion's own frequency where that
    is sharper than :func:`jacobian_rate`'s bound ``s |Pi|``.

    Why: ``Pi`` moves on its polhode, and near a stable axis or about the symmetry axis of a
    body with two equal moments it moves harmonically, ``dddPi = -w^2 dPi`` at its frequency
    ``w``: ``(|dddPi| / |dPi|)^(1/2) = w`` exactly (on every point of an elliptic orbit, where
    ``|ddPi| / |dPi|`` would not be), and a scheme's local error is ``C h^(p+1) w^p |dPi|`` as
    on a rotation at ``w``. About the symmetry axis ``w = |Pi3 (1/I3 - 1/I1)|``, which every
    Runge-Kutta method conserves (``dPi3/dt = 0``), so the error adds up period by period and
    nothing more: the estimate is the error (nearly equal moments: ``w`` is the slow precession,
    not ``s |Pi|``). On a triaxial body the integrator's drift of ``H`` and ``|Pi|`` changes
    the frequency and the phase error grows faster, most near the separatrix, where the motion
    is stretched at up to ``sqrt((j_m - j_l)(j_h - j_m)) |Pi|`` (``j`` the inverse moments sorted:
    the intermediate axis's rate of instability, 0 with two equal moments): ``sigma`` is that
    coefficient times :data:`SEPARATRIX_MARGIN`, and its rate is added. The Jacobian's bound
    caps it (``rbenvs bench accuracy --tolerance`` and ``tests/test_tolerance.py`` check it
    against the exact solution). A state at rest in the body frame (``dPi = 0``, a steady spin)
    commits no error (``mu = 0``); there the bound is returned."""
    inv, spread, sigma = p
    j1, j2, j3 = inv
    p1, p2, p3 = y[0], y[1], y[2]
    w1, w2, w3 = j1 * p1, j2 * p2, j3 * p3
    a1, a2, a3 = _cross(p1, p2, p3, w1, w2, w3)  # dPi = Pi x Omega
    b1, b2, b3 = j1 * a1, j2 * a2, j3 * a3  # dOmega
    c1, c2, c3 = _cross(a1, a2, a3, w1, w2, w3)  # ddPi = dPi x Omega + Pi x dOmega
    e1, e2, e3 = _cross(p1, p2, p3, b1, b2, b3)
    c1, c2, c3 = c1 + e1, c2 + e2, c3 + e3
    d1, d2, d3 = j1 * c1, j2 * c2, j3 * c3  # ddOmega
    f1, f2, f3 = _cross(
        c1, c2, c3, w1, w2, w3
    )  # dddPi = ddPi x Omega + 2 dPi x dOmega + Pi x ddOmega
    g1, g2, g3 = _cross(a1, a2, a3, b1, b2, b3)
    k1, k2, k3 = _cross(p1, p2, p3, d1, d2, d3)
    f1, f2, f3 = f1 + 2.0 * g1 + k1, f2 + 2.0 * g2 + k2, f3 + 2.0 * g3 + k3
    speed2 = a1 * a1 + a2 * a2 + a3 * a3
    norm = sqrt(p1 * p1 + p2 * p2 + p3 * p3)
    bound = spread * norm
    moving = speed2 > 0.0
    lam = (
        sqrt(sqrt((f1 * f1 + f2 * f2 + f3 * f3) / select(moving, speed2, 0.0 * speed2 + 1.0)))
        + sigma * norm
    )
    lam = select(moving, lam, bound)
    return select(lam < bound, lam, bound)


@jitable
def period_speed(p, y, u, dt):
    """An upper bound of ``|dPi/dt| / |Pi|`` [1/s] over a control period of ``dt`` from ``y`` under
    the torque ``u``; ``p = (inv, s)`` (inverse moments, their spread). The state's own speed of
    :func:`rbenvs.stepsize.forms.motion_rates` is read at the period's start, and a period can be
    far longer than the motion's time scale: near the intermediate axis ``Pi`` rests by the
    saddle and then runs its separatrix orbit in ``1 / sigma`` (at 1e4 rad/s many times a
    period), so the speed at the start says nothing of the period's error
    (``tests/test_tolerance.py``: the intermediate axis at 1e4 rad/s).

    Two bounds, the smaller taken: ``|d(dPi)/dt| <= s |Pi| |dPi|`` (:func:`jacobian_rate`), so
    the speed grows at most by ``exp(z) <= 1 + (e - 1) z`` for ``z = s |Pi| dt <= 1``; and the
    torque-free orbit through ``Pi`` (``|Pi|^2`` and ``Pi . Omega`` conserved): ``|dPi|^2 / |Pi|^2
    = |Omega|^2 - (Pi . Omega)^2 / |Pi|^2``, linear in ``x_i = Pi_i^2`` through ``|Omega|^2 = sum
    j_i^2 x_i``, is largest at an end of the orbit's segment ``x + t d`` (``d = (1, 1, 1) x j``,
    ``x >= 0``), plus ``|tau| / |Pi|`` for the torque."""
    inv, spread = p
    j1, j2, j3 = inv
    p1, p2, p3 = y[0], y[1], y[2]
    x1, x2, x3 = p1 * p1, p2 * p2, p3 * p3
    m = sqrt(x1 + x2 + x3)
    scale = 1.0 / maximum(m, 1e-300)
    e = (j1 * x1 + j2 * x2 + j3 * x3) * scale
    q = j1 * j1 * x1 + j2 * j2 * x2 + j3 * j3 * x3
    d1, d2, d3 = j2 - j3, j3 - j1, j1 - j2
    g = j1 * j1 * d1 + j2 * j2 * d2 + j3 * j3 * d3  # d|Omega|^2 / dt along the segment
    if g < 0.0:
        d1, d2, d3, g = -d1, -d2, -d3, -g
    t = _segment_end(_segment_end(_segment_end(0.0 * q + math.inf, d1, x1), d2, x2), d3, x3)
    t = select(t < math.inf, t, 0.0 * t)  # (a sphere: d = 0, one point)
    orbit = sqrt(maximum(q + g * t - e * e, 0.0 * q))
    w1, w2, w3 = j1 * p1, j2 * p2, j3 * p3
    a1, a2, a3 = _cross(p1, p2, p3, w1, w2, w3)
    if u is not None:
        a1, a2, a3 = a1 + u[0], a2 + u[1], a3 + u[2]
        orbit = orbit + sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]) * scale
    mu0 = sqrt(a1 * a1 + a2 * a2 + a3 * a3) * scale
    orbit = maximum(orbit, mu0)
    z = spread * m * dt
    grown = mu0 * (1.0 + (math.e - 1.0) * z)
    return select(z <= 1.0, select(grown < orbit, grown, orbit), orbit)


@jitable
def _segment_end(t, d, x):
    """``min(t, x / -d)`` where ``d < 0`` (the segment ``x + t d`` leaves ``x >= 0``), else
    ``t``."""
    return select(d < 0.0, select(x < -d * t, x / select(d < 0.0, -d, 1.0), t), t)


def error_rate_params(inverse) -> tuple:
    """``p`` of :func:`error_rate` for the inverse moments ``inverse``: ``(inv, s, sigma)``."""
    inv = tuple(float(j) for j in inverse)
    lo, mid, hi = sorted(inv)
    return (inv, hi - lo, SEPARATRIX_MARGIN * math.sqrt((mid - lo) * (hi - mid)))


# error_rate's sigma is the intermediate axis's rate of instability times this: with 1 the summed
# estimate fell below rk4's error just off the separatrix, 1.5 keeps the margin the Jacobian's
# bound alone gives (`rbenvs bench accuracy --tolerance`'s fb_triaxial row; tests/test_tolerance.py)
SEPARATRIX_MARGIN = 1.5


@jitable
def attitude_rhs(p, y, u):
    """Euler's equations and ``dq/dt = q * (0, Omega) / 2`` for ``y = (Pi, q)``; ``p = (c, inv)``,
    the coefficients and inverse moments of :class:`FreeBodyParams`."""
    c, inv = p
    return euler_rhs(c, y, u) + quat_rate((y[3], y[4], y[5], y[6]), angular_velocity(inv, y))


@jitable
def attitude_normalize(p, y):
    """``(Pi, q)`` with ``q`` projected back onto the unit sphere (``p`` unused: ``()``)."""
    q = quat_normalize((y[3], y[4], y[5], y[6]))
    return (y[0], y[1], y[2], q[0], q[1], q[2], q[3])


@jitable
def free_body_kick(p, y, u, h):
    """Exact flow of the torque alone for time ``h``: ``Pi += h tau`` (attitude unchanged; ``p``
    unused: ``()``)."""
    if u is None:
        return y
    return (y[0] + h * u[0], y[1] + h * u[1], y[2] + h * u[2]) + y[3:]


@jitable
def free_body_readouts(inv, y, u, fired):
    """The env's physical read-outs ``(energy, momentum_norm)`` (names: FreeBody.readout_names;
    the control ``u`` and the event flag ``fired`` play no part)."""
    return (kinetic_energy(inv, y), momentum_norm(y))


class FreeBody:
    """Vector field, invariants and exact sub-flows of the free rigid body.

    ``attitude=True`` appends the quaternion to the state. Controls ``u`` are body torques
    ``(tau1, tau2, tau3)`` [N m], constant over a step, or ``None`` for zero torque.
    """

    # read-outs that are Casimirs of the Lie-Poisson bracket (kept by the exact sub-flows)
    casimirs = ("momentum_norm",)

    def __init__(self, params: FreeBodyParams, attitude: bool = False):
        self.params = params
        self.attitude = bool(attitude)
        self.dim = 7 if self.attitude else 3
        # without a quaternion there is nothing to project: integrators may skip normalize()
        self.needs_projection = self.attitude
        self.layout = {"angular_momentum": (0, 3)} | ({"attitude": (3, 7)} if self.attitude else {})
        self._split = (
            self.kick,
            self.axis_rotation(0),
            self.axis_rotation(1),
            self.axis_rotation(2),
        )
        # the hot path reads it on every call: a plain attribute, not a params.<field> chain
        self._inverse = params.inverse
        # the vector field and the projection as pure functions of (P, y, u) and (N, y), for the
        # generated integrator steps and the compiled batch kernel (rbenvs.contracts.System)
        if self.attitude:
            self.kernel_rhs = (attitude_rhs, (params.coefficients, params.inverse))
            self.kernel_normalize = (attitude_normalize, ())
        else:
            self.kernel_rhs = (euler_rhs, params.coefficients)
            self.kernel_normalize = None
        self.kernel_readouts = (free_body_readouts, params.inverse)

    readout_names = ("energy", "momentum_norm")

    # a smooth system: no events, no switches (rbenvs.contracts.HybridSystem)
    hybrid = False
    # the optional capabilities (rbenvs.contracts.System): exact sub-flows and the exact flow
    provides = frozenset({"split_flows", "free_flow", "kick"})
    kernel_implicit = None

    def readouts(self, y, u=None, fired=False):
        """``(energy, momentum_norm)`` (:attr:`readout_names`); the control plays no part."""
        return free_body_readouts(self._inverse, y, u, fired)

    start_draw_kinds = ""  # the system adds no numbers to a task's start (rbenvs.draws)

    def start_draws(self, rng):
        return draw(rng, self.start_draw_kinds)

    def complete_initial_state(self, y, d):
        """A task's start as it is (the task draws the attitude where it needs one)."""
        return y

    kernel_complete = (start_as_drawn, ())  # the pure form of complete_initial_state

    def export_state(self, y) -> dict:
        """``{"angular_momentum": Pi (3,), "attitude": q (4,) (reorient only)}``, float64 copies."""
        return export_layout(self.layout, y)

    def import_state(self, state: dict) -> tuple:
        """Components from :meth:`export_state`'s dict; the attitude must be a unit quaternion
        (within 1e-6)."""
        y, arrays = import_layout(self.layout, self.dim, state)
        if "attitude" in arrays:
            n = float(np.linalg.norm(arrays["attitude"]))
            if abs(n - 1.0) > 1e-6:
                raise ValueError(
                    "state['attitude'] must be a unit quaternion (|q| = 1 within 1e-6), got |q| = "
                    f"{n}"
                )
        return y

    def guard_rates(self, region, speed_ceiling: float, dt: float) -> GuardRates:
        """In the body frame ``Pi`` turns about ``Omega`` at ``|Omega|`` (at a steady spin the
        linearisation's eigenvalues have modulus ``<= |Omega|``, [MR 15.9.1]): one oscillatory rate,
        ``lambda = |Omega|``, for every scheme (the splitting's pieces are exact rotations,
        but their composition follows the motion only below about a radian per step). Without
        attitude the error ``tolerance=`` estimates takes the sharper :func:`error_rate`, the
        motion's own frequency within :func:`jacobian_rate`'s bound (the attitude itself turns
        at ``|Omega| / 2``: with it, ``lambda`` stays)."""
        accuracy = bound = None
        if not self.attitude:
            accuracy = (error_rate, error_rate_params(self._inverse))
        inv, spread, _ = error_rate_params(self._inverse)
        # (the default accuracy's gate: error_rate is capped at the Jacobian's bound s |Pi|)
        bound = (jacobian_rate, (spread,)) if accuracy is not None else None
        return GuardRates(
            rotation=(rotation_rate, (self._inverse, 1.0, 0.0)),
            ceiling=speed_ceiling,
            text="lambda = |Omega|",
            accuracy=accuracy,
            speed=(period_speed, (inv, spread)),
            accuracy_bound=bound,
        )

    # ------------------------------------------------------------------ vector field
    def rhs(self, y, u):
        """``dy/dt``: ``dPi/dt = Pi x Omega + tau`` [MR 15.3.9-10],
        ``dq/dt = q * (0, Omega) / 2``."""
        return self.kernel_rhs[0](self.kernel_rhs[1], y, u)

    def normalize(self, y):
        """Renormalise the quaternion (no-op without attitude: see :attr:`needs_projection`)."""
        if not self.attitude:
            return y
        return attitude_normalize((), y)

    # ------------------------------------------------------------------ invariants
    def energy(self, y):
        """Kinetic energy ``H = 1/2 sum Pi_i^2 / I_i`` [J]."""
        return kinetic_energy(self._inverse, y)

    def momentum_norm(self, y):
        """``|Pi|`` [kg m^2/s], the Casimir (its square) of the Lie-Poisson bracket."""
        return momentum_norm(y)

    def angular_velocity(self, y):
        """Body angular velocity ``Omega = I^-1 Pi`` [rad/s]."""
        return angular_velocity(self._inverse, y)

    # ------------------------------------------------------------------ exact pieces
    def kick(self, y, u, h):
        """Exact flow of the torque alone for time ``h``: ``Pi += h tau`` (attitude unchanged)."""
        return free_body_kick((), tuple(y), u, h)

    def axis_rotation(self, i: int) -> AxisRotation:
        """Exact flow of ``H_i = Pi_i^2 / (2 I_i)``: a rotation about body axis ``i``
        (``Pi`` turns by ``-Omega_i h``, the attitude by ``+Omega_i h``)."""
        return AxisRotation(i, self.params.inverse[i], (0,), 3 if self.attitude else None)

    @property
    def kernel_split_flows(self) -> tuple:
        """The pure forms of :meth:`split_flows` (generated flows are made on access, not
        stored: the system pickles)."""
        return ((free_body_kick, ()),) + tuple(flow.kernel for flow in self._split[1:])

    def split_flows(self):
        """Pieces for a symmetric (Strang) splitting: torque kick, then the three axis rotations.

        Lie-Poisson splitting of ``H = sum Pi_i^2/(2 I_i)`` (docs/physics.md §4): explicit,
        second order, ``|Pi|`` exact, energy error bounded.
        """
        return self._split

    def free_flow(self, y, h):
        """Exact torque-free flow for time ``h`` (elliptic functions, [MR 15.8])."""
        orbit = FreeBodyOrbit(self.params, y[0:3])
        out = orbit.momentum_at(h)
        if self.attitude:
            out = out + quat_normalize(quat_multiply(y[3:7], orbit.attitude_increment(h)))
        if isinstance(y[0], float):  # a single state stays plain floats
            return tuple(float(c) for c in out)
        return out


class FreeBodyOrbit:
    """The exact torque-free motion through a given ``Pi`` (docs/physics.md §1, [MR 15.8]).

    The orbit circulates the major or the minor axis ("c"); "b" is the intermediate axis and
    "a" the remaining extreme one. With ``Omega_i = Pi_i / I_i``:

    ``Omega_a = A cn(u), Omega_b = B sn(u), Omega_c = C dn(u)``, ``u = tau0 + nu t``,

    ``A^2 = (2 H I_c - |Pi|^2) / (I_a (I_c - I_a))``, ``B^2 = (2 H I_c - |Pi|^2) / (I_b (I_c -
    I_b))``,
    ``C^2 = (|Pi|^2 - 2 H I_a) / (I_c (I_c - I_a))``, ``m = (I_b - I_a)(2 H I_c - |Pi|^2) /
    ((I_c - I_b)(|Pi|^2 - 2 H I_a))`` and ``|nu|^2 = (I_c - I_b)(|Pi|^2 - 2 H I_a) / (I_a I_b
    I_c)``.

    The signs of ``C`` (and of ``A`` on the separatrix) come from the initial state and the sign
    of ``nu`` from Euler's equations. Each combination ``2 H I_k - |Pi|^2`` is formed as a sum
    over the other two axes, so no energy-momentum cancellation enters; the complementary
    parameter ``m1 = (I_c - I_a)(|Pi|^2 - 2 H I_b) / ((I_c - I_b)(|Pi|^2 - 2 H I_a))`` carries the
    separatrix distance exactly as far as that distance itself is known. Equal moments give
    ``m = 0`` (uniform precession); states on the separatrix give ``m = 1`` (sech/tanh
    heteroclinic orbits, [MR 15.8.10]); equilibria (a principal-axis spin, any ``Pi`` when all
    moments are equal) stay put.

    Components may be floats or arrays of one batch shape; the inertia is shared.
    """

    def __init__(self, params: FreeBodyParams, pi):
        inertia = params.inertia
        i_major, i_mid, i_minor = params.axis_order
        self._idx = (i_major, i_mid, i_minor)
        p = [np.asarray(x, dtype=float) for x in pi]
        pM, pb, pm = p[i_major], p[i_mid], p[i_minor]
        IM, Ib, Im = inertia[i_major], inertia[i_mid], inertia[i_minor]
        # Separatrix distance |Pi|^2 - 2 H I_b, the b term dropped exactly.
        dist = pM * pM * ((IM - Ib) / IM) + pm * pm * ((Im - Ib) / Im)
        # Orbit family: around the major axis if dist > 0, the minor one if < 0. On the
        # separatrix either labelling works unless the chosen c-axis ties with b.
        c_major = (dist > 0.0) | ((dist == 0.0) & (Im == Ib))
        self.c_is_major = c_major
        pa = np.where(c_major, pm, pM)
        pc = np.where(c_major, pM, pm)
        Ia = np.where(c_major, Im, IM)
        Ic = np.where(c_major, IM, Im)
        sigma0 = 1.0 if (i_major, i_mid, i_minor) in _CYCLIC else -1.0
        sigma = np.where(c_major, -sigma0, sigma0)  # parity of the labelling (a, b, c)
        with np.errstate(divide="ignore", invalid="ignore"):
            g_c = pa * pa * ((Ic - Ia) / Ia) + pb * pb * ((Ic - Ib) / Ib)  # 2 H I_c - |Pi|^2
            g_a = pb * pb * ((Ib - Ia) / Ib) + pc * pc * ((Ic - Ia) / Ic)  # |Pi|^2 - 2 H I_a
            amp_a = np.sqrt(g_c / (Ia * (Ic - Ia)))
            amp_b = np.sqrt(g_c / (Ib * (Ic - Ib)))
            amp_c = np.sqrt(g_a / (Ic * (Ic - Ia)))
            m = (Ib - Ia) * g_c / ((Ic - Ib) * g_a)
            m1 = (Ic - Ia) * dist / ((Ic - Ib) * g_a)
            rate = np.sqrt((Ic - Ib) * g_a / (Ia * Ib * Ic))
        separatrix = m1 == 0.0
        s_c = np.sign(pc)
        s_a = np.where(separatrix, np.sign(pa), 1.0)
        sign_nu = sigma * np.sign(Ic - Ia) * s_c * s_a
        nu = sign_nu * rate
        # Degenerate cases: equilibria (nu = 0 or undefined) keep Pi; all moments equal too.
        self.stationary = ~np.isfinite(nu) | (nu == 0.0) | ~np.isfinite(m) | (IM == Im)
        st = self.stationary
        m = np.where(st, 0.0, np.clip(m, 0.0, 1.0))
        m1 = np.where(st, 1.0, np.clip(m1, 0.0, 1.0))
        nu = np.where(st, 0.0, nu)
        # Initial phase: am(tau0) has (sin, cos) proportional to (Omega_b / B, Omega_a / A); the
        # amplitudes are divided out as a ratio so that nothing is 0/0 near the c-axis, and the
        # angle is never formed (near the intermediate axis it sits at pi/2, where F is steep).
        with np.errstate(invalid="ignore"):
            y_ = np.where(st, 0.0, pb * np.sqrt(np.abs(Ic - Ib) / Ib))
            x_ = np.where(st, 1.0, s_a * pa * np.sqrt(np.abs(Ic - Ia) / Ia))
        x_ = np.where((x_ == 0.0) & (y_ == 0.0), 1.0, x_)  # a spin exactly about c: phase 0
        self.tau0 = elliptic_f_sc(y_, x_, m, m1)
        self.nu, self.m, self.m1 = nu, m, m1
        self.amp = (
            np.where(st, 0.0, s_a * amp_a),
            np.where(st, 0.0, amp_b),
            np.where(st, 0.0, s_c * amp_c),
        )
        self.inertia_abc = (Ia, Ib, Ic)
        self.sigma = sigma
        self._pi0 = p
        self._inverse = params.inverse
        self.momentum_norm = np.sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2])

    @property
    def period(self):
        """Period of ``Pi(t)`` [s]: ``4 K(m) / |nu|``; ``inf`` on the separatrix and at rest."""
        k = elliptic_k(self.m1)
        with np.errstate(divide="ignore"):
            return np.where(self.stationary | (self.m1 == 0.0), np.inf, 4.0 * k / np.abs(self.nu))

    def _abc_at(self, t, reduce: bool):
        """``(Pi_a, Pi_b, Pi_c)`` at times ``t`` (broadcast against the batch)."""
        u = self.tau0 + self.nu * t
        if reduce:
            # Reduce modulo the period 4K so accuracy does not decay with |u| (not on the
            # separatrix, which has no period).
            periodic = self.m1 > 0.0
            four_k = np.where(periodic, 4.0 * elliptic_k(self.m1), 1.0)
            u = np.where(periodic, u - four_k * np.round(u / four_k), u)
        sn, cn, dn = jacobi_sn_cn_dn(u, self.m, self.m1)
        Ia, Ib, Ic = self.inertia_abc
        A, B, C = self.amp
        return Ia * A * cn, Ib * B * sn, Ic * C * dn

    def _to_body(self, pa, pb, pc):
        i_major, i_mid, i_minor = self._idx
        out = [None, None, None]
        out[i_major] = np.where(self.c_is_major, pc, pa)
        out[i_mid] = pb
        out[i_minor] = np.where(self.c_is_major, pa, pc)
        # Equilibria keep their initial momentum exactly.
        return tuple(np.where(self.stationary, p0, o) for p0, o in zip(self._pi0, out))

    def momentum_at(self, t, reduce: bool = True):
        """Body angular momentum ``Pi(t)`` (components broadcast over the batch and ``t``)."""
        return self._to_body(*self._abc_at(t, reduce))

    # ------------------------------------------------------------------ attitude
    # Euler angles relative to the fixed spatial momentum (Landau & Lifshitz §37): with the
    # spatial Z axis along pi = R Pi and body z along the extreme axis "a" (which an orbit
    # around "c" never approaches, so the angles are regular), R = Q Rz(phi) Rx(theta) Rz(psi),
    # where theta, psi follow from Pi alone and
    #     dphi/dt = |Pi| (Pi_b^2 / I_b + Pi_c^2 / I_c) / (Pi_b^2 + Pi_c^2).
    # Then R(t + h) = R(t) W(t)^T Rz(dphi) W(t + h), W = Rx(theta) Rz(psi). The phi increment is
    # a smooth integral, done by Gauss-Legendre quadrature on panels of at most
    # _PANEL_PHASE in the elliptic argument u: error far below round-off.
    _NODES, _WEIGHTS = np.polynomial.legendre.leggauss(10)
    _PANEL_PHASE = 0.5

    def _w_quaternion(self, pa, pb, pc):
        """Quaternion of W = Rx(theta) Rz(psi) in the frame (x, y, z) = (b, c, a) or (c, b, a)."""
        cyc = self.sigma > 0  # (a, b, c) cyclic -> (b, c, a) is a right-handed frame
        px = np.where(cyc, pb, pc)
        py = np.where(cyc, pc, pb)
        pz = pa
        rho = np.sqrt(px * px + py * py)
        # half-angle forms of theta = atan2(rho, pz) and psi = atan2(px, py)
        theta = np.arctan2(rho, pz)
        psi = np.arctan2(px, py)
        c1, s1 = np.cos(0.5 * theta), np.sin(0.5 * theta)
        c2, s2 = np.cos(0.5 * psi), np.sin(0.5 * psi)
        return (c1 * c2, s1 * c2, -s1 * s2, c1 * s2)

    def _frame_to_body(self, vx, vy, vz):
        """Map a vector given in the (x, y, z) frame of :meth:`_w_quaternion` to body indices."""
        i_major, i_mid, i_minor = self._idx
        idx_a = np.where(self.c_is_major, i_minor, i_major)
        idx_c = np.where(self.c_is_major, i_major, i_minor)
        cyc = self.sigma > 0
        idx_x = np.where(cyc, i_mid, idx_c)
        idx_y = np.where(cyc, idx_c, i_mid)
        return tuple(vx * (idx_x == i) + vy * (idx_y == i) + vz * (idx_a == i) for i in range(3))

    def _panels(self, h):
        """Quadrature panels per element: at most _PANEL_PHASE in u, and narrower still when the
        orbit passes close to the reference axis "a" (nearly equal I_a, I_b near the
        separatrix), where the integrand has a peak of relative width ``rho``, the least
        distance of ``Pi`` from that axis over ``|Pi|``."""
        Ia, Ib, Ic = self.inertia_abc
        A = self.amp[0]
        norm = np.where(self.momentum_norm > 0.0, self.momentum_norm, 1.0)
        rho2 = np.clip(1.0 - (Ia * A / norm) ** 2, 1e-12, 1.0)
        width = self._PANEL_PHASE * np.minimum(1.0, np.sqrt(rho2))
        return np.maximum(1, np.ceil(np.abs(self.nu) * abs(h) / width)).astype(int)

    def attitude_increment(self, h):
        """Body-frame rotation ``r`` with ``q(t + h) = q(t) * r`` along the exact motion.

        Each element gets its own panel count and its panel sums are accumulated in order, so
        an element's result does not depend on the rest of the batch.
        """
        h = float(h)
        n_panels = np.asarray(self._panels(h))
        tau0 = np.asarray(self.tau0)[..., None]
        nu = np.asarray(self.nu)[..., None]
        m, m1 = np.asarray(self.m)[..., None], np.asarray(self.m1)[..., None]
        Ia, Ib, Ic = (np.asarray(x)[..., None] for x in self.inertia_abc)
        A, B, C = (np.asarray(x)[..., None] for x in self.amp)
        norm = np.asarray(self.momentum_norm)[..., None]
        width = (h / n_panels)[..., None]
        dphi = np.zeros(n_panels.shape)
        for k in range(int(np.max(n_panels))):
            active = k < n_panels
            t = (k + 0.5 + 0.5 * self._NODES) * width  # nodes of panel k, per element
            sn, cn, dn = jacobi_sn_cn_dn(tau0 + nu * t, m, m1)
            pb = Ib * B * sn
            pc = Ic * C * dn
            with np.errstate(invalid="ignore", divide="ignore"):
                rate = norm * (pb * pb / Ib + pc * pc / Ic) / (pb * pb + pc * pc)
            panel = np.sum(rate * (0.5 * width) * self._WEIGHTS, axis=-1)
            dphi = np.where(active, dphi + panel, dphi)
        w0 = self._w_quaternion(*self._abc_at(0.0, reduce=False))
        w1 = self._w_quaternion(*self._abc_at(h, reduce=False))
        z = (np.cos(0.5 * dphi), 0.0 * dphi, 0.0 * dphi, np.sin(0.5 * dphi))
        r = quat_multiply(quat_multiply((w0[0], -w0[1], -w0[2], -w0[3]), z), w1)
        rb = self._frame_to_body(r[1], r[2], r[3])
        r = (r[0],) + rb
        if np.any(self.stationary):
            # Equilibria (Omega parallel to Pi, both constant): a uniform turn about Omega.
            j = self._inverse
            om = [j[i] * self._pi0[i] for i in range(3)]
            om_norm = np.sqrt(om[0] * om[0] + om[1] * om[1] + om[2] * om[2])
            angle = om_norm * h
            with np.errstate(invalid="ignore", divide="ignore"):
                scale = np.where(
                    om_norm > 0.0, np.sin(0.5 * angle) / np.where(om_norm > 0.0, om_norm, 1.0), 0.0
                )
            steady = (np.cos(0.5 * angle), om[0] * scale, om[1] * scale, om[2] * scale)
            r = tuple(np.where(self.stationary, s_, r_) for s_, r_ in zip(steady, r))
        return r

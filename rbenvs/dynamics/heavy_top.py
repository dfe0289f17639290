"""The heavy top on a fixed pivot under gravity, in Lie-Poisson form (docs/physics.md §2).

State layout (components, see :mod:`rbenvs.rotations` for the convention):

* ``(Pi1, Pi2, Pi3)``: body angular momentum about the pivot [kg m^2/s], principal body frame;
* ``(G1, G2, G3)``: ``Gamma = R^T e_z``, the upward vertical seen from the body (unit);
* optionally ``(qw, qx, qy, qz)``: attitude, unit quaternion body -> space, when a scene needs
  the heading (``Gamma`` fixes the attitude up to a turn about the vertical).

``(Pi, Gamma)`` is integrated, never Euler angles: they are singular at the upright state,
exactly where the sleeping top lives. ``dPi/dt = Pi x Omega + M g l Gamma x chi + tau``,
``dGamma/dt = Gamma x Omega`` [MR 15.10.1-2], ``chi`` the unit vector from the pivot to the centre
of mass in the body. An optional viscous spin friction at the pivot adds
``-k (Omega . chi) chi``: it slows the spin about the centre-of-mass axis (and lets a top that
started above the critical spin fall).

Everything here is pure: a frozen parameter object and components in, components out. Each
component is a float (single state) or an array of any batch shape (many states at once).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..contracts import GuardRates
from ..draws import draw
from ..jit import jitable
from ..rotations import (
    atan2,
    expm1,
    quat_conjugate,
    quat_from_two_vectors,
    quat_multiply,
    quat_normalize,
    quat_rate,
    quat_rotate,
    quat_to_euler_zxz,
    sqrt,
)
from .flows import AxisRotation, SymmetricFreeRotation
from .free_body import angular_velocity, rotation_rate
from .state import export_layout, import_layout, start_as_drawn
from .validation import (
    require_finite_nonnegative,
    require_finite_positive,
    require_finite_result,
    require_inertia,
    require_real_vector,
)

__all__ = [
    "HeavyTopParams",
    "HeavyTop",
    "heavy_top_rhs",
    "heavy_top_attitude_rhs",
    "heavy_top_normalize",
    "heavy_top_attitude_normalize",
    "heavy_top_kick",
    "torque_kick",
    "heavy_top_readouts",
    "heavy_top_attitude_readouts",
    "tilt_sides",
    "top_tilt",
    "top_spin",
    "heavy_top_energy",
    "pi_dot_gamma",
    "vertical_norm",
    "precession_rate",
]


# The heavy top's arithmetic as pure functions of (parameters, state[, control, step]): the
# methods of HeavyTop call them on floats or arrays, generated steps and the compiled batch
# kernel (rbenvs.compiled) on floats. ``p`` tuples are built once per system (HeavyTop).
@jitable
def heavy_top_rhs(p, y, u):
    """``dPi/dt = Pi x Omega + M g l Gamma x chi + tau - k (Omega.chi) chi``,
    ``dGamma/dt = Gamma x Omega`` [MR 15.10.1-2]; ``p = (coefficients, inverse, weight, k, chi)``
    (:class:`HeavyTopParams`: ``weight = M g l chi``, ``k`` the spin friction)."""
    c, inv, weight, friction, chi = p
    c1, c2, c3 = c
    j1, j2, j3 = inv
    k1, k2, k3 = weight
    p1, p2, p3, g1, g2, g3 = y[0], y[1], y[2], y[3], y[4], y[5]
    w1, w2, w3 = j1 * p1, j2 * p2, j3 * p3
    d1 = c1 * p2 * p3 + (g2 * k3 - g3 * k2)
    d2 = c2 * p3 * p1 + (g3 * k1 - g1 * k3)
    d3 = c3 * p1 * p2 + (g1 * k2 - g2 * k1)
    if u is not None:
        d1 = d1 + u[0]
        d2 = d2 + u[1]
        d3 = d3 + u[2]
    if friction != 0.0:
        x1, x2, x3 = chi
        f = friction * (w1 * x1 + w2 * x2 + w3 * x3)
        d1, d2, d3 = d1 - f * x1, d2 - f * x2, d3 - f * x3
    return (d1, d2, d3, g2 * w3 - g3 * w2, g3 * w1 - g1 * w3, g1 * w2 - g2 * w1)


@jitable
def heavy_top_attitude_rhs(p, y, u):
    """:func:`heavy_top_rhs` and ``dq/dt = q * (0, Omega) / 2`` for ``y = (Pi, Gamma, q)``."""
    return heavy_top_rhs(p, y, u) + quat_rate((y[6], y[7], y[8], y[9]), angular_velocity(p[1], y))


@jitable
def heavy_top_normalize(p, y):
    """``(Pi, Gamma / |Gamma|)`` (``p`` unused: ``()``)."""
    inv = 1.0 / sqrt(y[3] * y[3] + y[4] * y[4] + y[5] * y[5])
    return (y[0], y[1], y[2], y[3] * inv, y[4] * inv, y[5] * inv)


@jitable
def heavy_top_attitude_normalize(p, y):
    """``(Pi, Gamma / |Gamma|, q / |q|)`` (``p`` unused: ``()``)."""
    return heavy_top_normalize(p, y) + quat_normalize((y[6], y[7], y[8], y[9]))


@jitable
def kick_torque(weight, y, u):
    """The torque the kick holds for its step: gravity ``M g l Gamma x chi`` (``weight = M g l
    chi``) and the control."""
    k1, k2, k3 = weight
    g1, g2, g3 = y[3], y[4], y[5]
    f1, f2, f3 = g2 * k3 - g3 * k2, g3 * k1 - g1 * k3, g1 * k2 - g2 * k1
    if u is not None:
        f1, f2, f3 = f1 + u[0], f2 + u[1], f3 + u[2]
    return f1, f2, f3


@jitable
def torque_kick(p, y, u, h):
    """Exact flow for time ``h`` of the torques with ``Gamma`` held fixed and no spin friction:
    ``Pi += h f`` (:meth:`HeavyTop.kick`; ``p`` as :func:`heavy_top_kick`'s). Arithmetic alone,
    so that a batch loop of it stays in SIMD registers (the friction's ``expm1`` is a call)."""
    f1, f2, f3 = kick_torque(p[0], y, u)
    return (y[0] + h * f1, y[1] + h * f2, y[2] + h * f3) + y[3:]


@jitable
def heavy_top_kick(p, y, u, h):
    """Exact flow for time ``h`` of the torques with ``Gamma`` held fixed (see
    :meth:`HeavyTop.kick`); ``p = (weight, k, chi, inverse)``."""
    weight, friction, chi, inv = p
    f1, f2, f3 = kick_torque(weight, y, u)
    p1, p2, p3 = y[0] + h * f1, y[1] + h * f2, y[2] + h * f3
    if friction != 0.0:
        x1, x2, x3 = chi
        j1, j2, j3 = inv
        c_s = j1 * x1 * x1 + j2 * x2 * x2 + j3 * x3 * x3
        kappa = friction * c_s
        s0 = j1 * y[0] * x1 + j2 * y[1] * x2 + j3 * y[2] * x3
        b = j1 * f1 * x1 + j2 * f2 * x2 + j3 * f3 * x3
        e1 = -expm1(-kappa * h) / kappa  # int_0^h exp(-kappa t) dt
        integral = friction * s0 * e1 + b * (h - e1) / c_s  # k int_0^h s dt
        p1, p2, p3 = p1 - integral * x1, p2 - integral * x2, p3 - integral * x3
    return (p1, p2, p3) + y[3:]


@jitable
def attitude_from_vertical(gamma, heading):
    """A quaternion ``q`` with ``R(q)^T e_z = Gamma`` and the given heading [rad]: the shortest
    turn taking ``Gamma`` to ``e_z``, then a turn by ``heading`` about ``e_z`` (floats or
    arrays)."""
    one = 1.0 + 0.0 * gamma[0]
    zero = 0.0 * gamma[0]
    r = quat_from_two_vectors(gamma, (zero, zero, one))
    half = 0.5 * heading
    turn = (np.cos(half) * one, zero, zero, np.sin(half) * one)
    return quat_normalize(quat_multiply(turn, r))


@jitable
def start_with_attitude(p, y, d):
    """A task's start ``(Pi, Gamma)`` and the attitude with that ``Gamma`` and the heading
    ``2 pi d[0]`` (uniform in ``[0, 2 pi)``: :func:`attitude_from_vertical`)."""
    return y + attitude_from_vertical((y[3], y[4], y[5]), 0.0 + 2.0 * np.pi * d[0])


@jitable
def vertical_norm(y):
    """``|Gamma|``."""
    return sqrt(y[3] * y[3] + y[4] * y[4] + y[5] * y[5])


@jitable
def tilt_sides(chi, y):
    """``(|Gamma x chi|, Gamma . chi)``: the tilt's sine and cosine sides, ``|Gamma|`` times
    ``(sin, cos)`` of the angle between ``chi`` and the upward vertical."""
    x1, x2, x3 = chi
    g1, g2, g3 = y[3], y[4], y[5]
    c1, c2, c3 = g2 * x3 - g3 * x2, g3 * x1 - g1 * x3, g1 * x2 - g2 * x1
    return sqrt(c1 * c1 + c2 * c2 + c3 * c3), g1 * x1 + g2 * x2 + g3 * x3


@jitable
def top_tilt(chi, y):
    """Angle [rad] between ``chi`` and the upward vertical: ``atan2(|Gamma x chi|, Gamma.chi)``."""
    s, c = tilt_sides(chi, y)
    return atan2(s, c)


@jitable
def heavy_top_energy(inv, weight, y):
    """``H = 1/2 Pi.Omega + M g l Gamma.chi`` [J] (zero potential with the axis horizontal)."""
    j1, j2, j3 = inv
    k1, k2, k3 = weight
    kinetic = 0.5 * (j1 * y[0] * y[0] + j2 * y[1] * y[1] + j3 * y[2] * y[2])
    return kinetic + (k1 * y[3] + k2 * y[4] + k3 * y[5])


@jitable
def pi_dot_gamma(y):
    """Casimir ``Pi . Gamma`` [kg m^2/s]."""
    return y[0] * y[3] + y[1] * y[4] + y[2] * y[5]


@jitable
def top_spin(inv, chi, y):
    """``Omega . chi`` [rad/s]."""
    x1, x2, x3 = chi
    j1, j2, j3 = inv
    return j1 * y[0] * x1 + j2 * y[1] * x2 + j3 * y[2] * x3


@jitable
def heavy_top_readouts(p, y, u, fired):
    """``(energy, pi_dot_gamma, vertical_norm, tilt, spin) + extra``; ``p = (inverse, weight,
    chi, extra)``, ``extra`` the constant read-outs (``(critical_spin,)`` of a Lagrange top, or
    ``()``). The control and the event flag play no part."""
    inv, weight, chi, extra = p
    return (
        heavy_top_energy(inv, weight, y),
        pi_dot_gamma(y),
        vertical_norm(y),
        top_tilt(chi, y),
        top_spin(inv, chi, y),
    ) + extra


@jitable
def heavy_top_attitude_readouts(p, y, u, fired):
    """:func:`heavy_top_readouts` and the z-x-z Euler angles of the attitude."""
    return heavy_top_readouts(p, y, u, fired) + quat_to_euler_zxz((y[6], y[7], y[8], y[9]))


@jitable
def precession_rate(p, y):
    """``d(phi)/dt`` [rad/s] of the centre-of-mass axis about the vertical (see
    :meth:`HeavyTop.precession_rate`); ``p = (inverse, chi)``; 0 with the axis on the vertical."""
    inv, x = p
    w = angular_velocity(inv, y)
    n = vertical_norm(y)
    g = (y[3] / n, y[4] / n, y[5] / n)
    cos_t = g[0] * x[0] + g[1] * x[1] + g[2] * x[2]
    w_z = w[0] * g[0] + w[1] * g[1] + w[2] * g[2]
    w_k = w[0] * x[0] + w[1] * x[1] + w[2] * x[2]
    c = (g[1] * x[2] - g[2] * x[1], g[2] * x[0] - g[0] * x[2], g[0] * x[1] - g[1] * x[0])
    sin2 = c[0] * c[0] + c[1] * c[1] + c[2] * c[2]
    if isinstance(sin2, float):
        return (w_z - cos_t * w_k) / sin2 if sin2 > 0.0 else 0.0
    return _rate_arrays(w_z - cos_t * w_k, sin2)


@jitable  # (registered so that compiled code can name it; it only ever runs on arrays)
def _rate_arrays(num, sin2):
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(sin2 > 0.0, num / sin2, 0.0)


@dataclass(frozen=True)
class HeavyTopParams:
    """Physical parameters of a heavy top. Defaults: a Lagrange top (``I1 = I2``, ``chi = e3``).

    * ``inertia``: principal moments ``(I1, I2, I3)`` **about the pivot** [kg m^2]. They must be
      those of a real body: removing the parallel-axis term leaves the inertia about the centre
      of mass ``I - M l^2 (1 - chi chi^T)``, which must be positive semi-definite with
      eigenvalues obeying the triangle inequality.
    * ``mass`` ``M`` [kg], ``length`` ``l`` = pivot to centre of mass [m], ``gravity`` ``g``
      [m/s^2].
    * ``com_direction``: ``chi``, the direction from the pivot to the centre of mass in the body
      frame (any nonzero vector; normalised).
    * ``spin_friction``: ``k`` [N m s] of the pivot's viscous torque ``-k (Omega . chi) chi``.
    """

    inertia: tuple[float, float, float] = (0.45, 0.45, 0.3)
    mass: float = 1.0
    length: float = 0.5
    gravity: float = 9.81
    com_direction: tuple[float, float, float] = (0.0, 0.0, 1.0)
    spin_friction: float = 0.0
    coefficients: tuple[float, float, float] = field(init=False, repr=False)
    inverse: tuple[float, float, float] = field(init=False, repr=False)
    weight: tuple[float, float, float] = field(init=False, repr=False)  # M g l chi [N m]
    symmetry_axis: int | None = field(init=False, repr=False)

    def __post_init__(self):
        i1, i2, i3 = require_inertia("inertia", self.inertia)
        mass = require_finite_positive("mass", self.mass)
        length = require_finite_positive("length", self.length)
        gravity = require_finite_positive("gravity", self.gravity)
        friction = require_finite_nonnegative("spin_friction", self.spin_friction)
        chi = np.asarray(
            require_real_vector(
                "com_direction", self.com_direction, 3, " (a nonzero direction in the body frame)"
            )
        )
        norm = float(np.linalg.norm(chi))
        if not 0.0 < norm < math.inf:
            raise ValueError(
                f"com_direction must be a finite nonzero 3-vector, got {self.com_direction!r}"
            )
        chi = chi / norm
        # products the dynamics forms: refused here, by name, rather than overflowing later
        require_finite_result("mass, length and gravity", mass * length * gravity, "M g l [N m]")
        require_finite_result("mass and length", mass * length * length, "M l^2 [kg m^2]")
        if np.count_nonzero(chi) == 1:  # exactly a body axis: keep the exact unit vector
            chi = np.sign(chi)
        _require_physical_inertia((i1, i2, i3), mass, length, chi)
        chi_t = tuple(float(c) for c in chi)
        set_ = object.__setattr__
        set_(self, "inertia", (i1, i2, i3))
        set_(self, "mass", mass)
        set_(self, "length", length)
        set_(self, "gravity", gravity)
        set_(self, "spin_friction", friction)
        set_(self, "com_direction", chi_t)
        set_(
            self,
            "coefficients",
            ((i2 - i3) / (i2 * i3), (i3 - i1) / (i3 * i1), (i1 - i2) / (i1 * i2)),
        )
        set_(self, "inverse", (1.0 / i1, 1.0 / i2, 1.0 / i3))
        mgl = mass * gravity * length
        set_(self, "weight", tuple(mgl * c for c in chi_t))
        axis = None
        for k in range(3):
            a, b = (k + 1) % 3, (k + 2) % 3
            if (
                chi_t[k] != 0.0
                and chi_t[a] == chi_t[b] == 0.0
                and self.inertia[a] == self.inertia[b]
            ):
                axis = k
        set_(self, "symmetry_axis", axis)

    @property
    def mgl(self) -> float:
        """``M g l`` [N m]: the largest gravity torque (axis horizontal)."""
        return self.mass * self.gravity * self.length

    @property
    def is_lagrange(self) -> bool:
        """Two equal moments and the centre of mass on the third axis: the integrable top."""
        return self.symmetry_axis is not None

    @property
    def transverse_inertia(self) -> float:
        """``I1`` of a Lagrange top (the equal moments); ``nan`` for another top."""
        k = self.symmetry_axis
        return math.nan if k is None else self.inertia[(k + 1) % 3]

    @property
    def axial_inertia(self) -> float:
        """``I3`` of a Lagrange top (about the centre-of-mass axis); ``nan`` for another top."""
        k = self.symmetry_axis
        return math.nan if k is None else self.inertia[k]

    @property
    def critical_spin(self) -> float:
        """``2 sqrt(M g l I1) / I3`` [rad/s] [MR 15.10.1] for a Lagrange top; ``nan`` otherwise."""
        if not self.is_lagrange:
            return math.nan
        return 2.0 * math.sqrt(self.mgl * self.transverse_inertia) / self.axial_inertia


def _require_physical_inertia(inertia, mass, length, chi):
    """Parallel-axis theorem backwards: the inertia about the centre of mass must be a body's."""
    i_pivot = np.diag(inertia)
    i_com = i_pivot - mass * length * length * (np.eye(3) - np.outer(chi, chi))
    ev = np.sort(np.linalg.eigvalsh(i_com))
    slack = 1e-12 * max(inertia)
    if ev[0] < -slack or ev[0] + ev[1] < ev[2] - slack:
        raise ValueError(
            "inertia must be the principal moments about the pivot of a real body: "
            "inertia - mass*length^2*(1 - chi chi^T) (the inertia about the centre of mass) must "
            "have "
            f"eigenvalues >= 0 obeying the triangle inequality; got {ev.tolist()} for "
            f"inertia={tuple(inertia)}, "
            f"mass={mass}, length={length} (the transverse moments about the pivot must be at "
            "least mass*length^2)"
        )


class HeavyTop:
    """Vector field, invariants and exact sub-flows of the heavy top.

    ``attitude=True`` appends the quaternion. Controls ``u`` are body torques
    ``(tau1, tau2, tau3)`` [N m], constant over a step, or ``None`` for zero torque.
    """

    # read-outs that are Casimirs of the Lie-Poisson bracket (kept by the exact sub-flows)
    casimirs = ("pi_dot_gamma", "vertical_norm")

    def __init__(self, params: HeavyTopParams, attitude: bool = False):
        self.params = params
        self.attitude = bool(attitude)
        self.dim = 10 if self.attitude else 6
        self.layout = {"angular_momentum": (0, 3), "vertical": (3, 6)} | (
            {"attitude": (6, 10)} if self.attitude else {}
        )
        vectors, quat = (0, 3), (6 if self.attitude else None)
        k = params.symmetry_axis
        if k is not None:
            # Lagrange top: the free flow of a symmetric body is two commuting rotations, exact.
            free = (
                SymmetricFreeRotation(
                    k, params.inertia[(k + 1) % 3], params.inertia[k], vectors, quat
                ),
            )
        else:
            free = tuple(AxisRotation(i, params.inverse[i], vectors, quat) for i in range(3))
        self._split = (self.kick,) + free
        # the pure forms (rbenvs.contracts.System): the methods below call them too
        rhs_p = (
            params.coefficients,
            params.inverse,
            params.weight,
            params.spin_friction,
            params.com_direction,
        )
        extra = (params.critical_spin,) if params.is_lagrange else ()
        readout_p = (params.inverse, params.weight, params.com_direction, extra)
        if self.attitude:
            self.kernel_rhs = (heavy_top_attitude_rhs, rhs_p)
            self.kernel_normalize = (heavy_top_attitude_normalize, ())
            self.kernel_readouts = (heavy_top_attitude_readouts, readout_p)
        else:
            self.kernel_rhs = (heavy_top_rhs, rhs_p)
            self.kernel_normalize = (heavy_top_normalize, ())
            self.kernel_readouts = (heavy_top_readouts, readout_p)
        self._kick = (params.weight, params.spin_friction, params.com_direction, params.inverse)
        # without spin friction the kick is arithmetic alone (the same operations otherwise)
        self._kick_form = heavy_top_kick if params.spin_friction != 0.0 else torque_kick

    @property
    def readout_names(self) -> tuple:
        """The ``info`` keys of :meth:`readouts`: energy, the Casimirs, tilt and spin; the
        critical spin for a Lagrange top only ([MR 15.10.1] gives no threshold for another top, so
        the key is absent rather than NaN); the Euler angles with the attitude."""
        names = ("energy", "pi_dot_gamma", "vertical_norm", "tilt", "spin")
        if self.params.is_lagrange:
            names += ("critical_spin",)
        if self.attitude:
            names += ("precession_angle", "nutation_angle", "spin_angle")
        return names

    # a smooth system: no events, no switches (rbenvs.contracts.HybridSystem)
    hybrid = False
    # the optional capabilities (rbenvs.contracts.System): exact sub-flows (no closed-form
    # free flow: the exact integrator is the free body's alone)
    provides = frozenset({"split_flows", "kick"})
    kernel_implicit = None
    needs_projection = True  # (Gamma's length, and the quaternion's)

    def readouts(self, y, u=None, fired=False) -> tuple:
        """The read-outs in :attr:`readout_names` order (floats or arrays; ``u`` plays no part)."""
        fn, p = self.kernel_readouts
        return fn(p, tuple(y), u, fired)

    @property
    def start_draw_kinds(self) -> str:
        """The kinds of the numbers the system adds to a task's start (:mod:`rbenvs.draws`): the
        heading where it carries the attitude (one uniform), else none."""
        return "u" if self.attitude else ""

    def start_draws(self, rng):
        return draw(rng, self.start_draw_kinds)

    def complete_initial_state(self, y, d):
        """A task's start ``(Pi, Gamma)``, with the attitude appended where the system carries
        it: the one with this ``Gamma`` and the heading ``2 pi d[0]``, uniform in ``[0, 2 pi)``
        (floats or rows of a batch; :attr:`kernel_complete`)."""
        fn, p = self.kernel_complete
        return fn(p, tuple(y), d)

    @property
    def kernel_complete(self):
        """``(complete, P)``: the pure form of :meth:`complete_initial_state`,
        ``complete(P, y, d) -> y``."""
        return (start_with_attitude if self.attitude else start_as_drawn), ()

    def export_state(self, y) -> dict:
        """``{"angular_momentum": Pi, "vertical": Gamma, "attitude": q (with attitude)}``, float64
        copies."""
        return export_layout(self.layout, y)

    def import_state(self, state: dict) -> tuple:
        """Components from :meth:`export_state`'s dict: ``Gamma`` a unit vector and ``q`` a unit
        quaternion with ``R(q)^T e_z = Gamma`` (within 1e-6)."""
        y, arrays = import_layout(self.layout, self.dim, state)
        g = arrays["vertical"]
        n = float(np.linalg.norm(g))
        if abs(n - 1.0) > 1e-6:
            raise ValueError(
                "state['vertical'] must be a unit vector (|Gamma| = 1 within 1e-6), got |Gamma| = "
                f"{n}"
            )
        if "attitude" in arrays:
            q = arrays["attitude"]
            nq = float(np.linalg.norm(q))
            if abs(nq - 1.0) > 1e-6:
                raise ValueError(
                    "state['attitude'] must be a unit quaternion (|q| = 1 within 1e-6), got |q| = "
                    f"{nq}"
                )
            gz = np.array(quat_rotate(quat_conjugate(tuple(q / nq)), (0.0, 0.0, 1.0)))
            if np.max(np.abs(gz - g)) > 1e-6:
                raise ValueError(
                    "state['vertical'] must equal R(attitude)^T e_z within 1e-6; the attitude "
                    f"gives {gz.tolist()}"
                )
        return y

    def guard_rates(self, region, speed_ceiling: float, dt: float) -> GuardRates:
        """Three rates bound the dynamics: the turn of ``Pi`` and ``Gamma`` about ``Omega``
        (``|Omega|``), gravity's ``omega_g = sqrt(M g l / I_min)`` (the hanging top's pendulum
        frequency, the upright top's growth rate; ``I_min`` is conservative) and the spin
        friction's decay ``kappa = k chi.I^-1 chi``. A scheme of exact sub-flows (the
        splitting) solves the friction exactly in its kick and, for a Lagrange top, the free
        flow exactly: only ``omega_g`` counts then (``|Omega| + omega_g`` for another top).
        Every other scheme resolves ``lambda = |Omega| + omega_g + kappa``."""
        prm = self.params
        omega_g = math.sqrt(prm.mgl / min(prm.inertia))
        x1, x2, x3 = prm.com_direction
        j1, j2, j3 = prm.inverse
        kappa = prm.spin_friction * (j1 * x1 * x1 + j2 * x2 * x2 + j3 * x3 * x3)
        if region.exact_subflows:
            weight, fixed = (0.0 if prm.is_lagrange else 1.0), omega_g
            text = (
                "lambda = omega_g" if prm.is_lagrange else "lambda = |Omega| + omega_g"
            ) + f" (omega_g = sqrt(M g l / I_min) = {omega_g:.6g} rad/s)"
        else:
            weight, fixed = 1.0, omega_g + kappa
            text = (
                f"lambda = |Omega| + omega_g + kappa (omega_g = {omega_g:.6g} rad/s, "
                f"kappa = {kappa:.6g} 1/s)"
            )
        return GuardRates(
            rotation=(rotation_rate, (prm.inverse, weight, fixed)),
            ceiling=weight * speed_ceiling + fixed,
            text=text,
        )

    # ------------------------------------------------------------------ vector field
    def rhs(self, y, u):
        """``dPi/dt = Pi x Omega + M g l Gamma x chi + tau - k (Omega.chi) chi``,
        ``dGamma/dt = Gamma x Omega``, ``dq/dt = q * (0, Omega) / 2`` (:func:`heavy_top_rhs`)."""
        fn, p = self.kernel_rhs
        return fn(p, y, u)

    def normalize(self, y):
        """Project ``Gamma`` back onto the unit sphere, and the quaternion (the projection
        method for the non-geometric integrators, docs/physics.md §4). ``Gamma`` is a direction: its
        length carries no physics, but a drifted length would scale the gravity torque. The
        other Casimir ``Pi.Gamma`` and the energy are not projected: their drift is the
        integrator's error, measured. (The splitting never needs this: its pieces are exact
        rotations.)"""
        fn, p = self.kernel_normalize
        return fn(p, tuple(y))

    # ------------------------------------------------------------------ invariants, read-outs
    def energy(self, y):
        """``H = 1/2 Pi.Omega + M g l Gamma.chi`` [J] (zero potential with the axis horizontal)."""
        return heavy_top_energy(self.params.inverse, self.params.weight, y)

    def pi_dot_gamma(self, y):
        """Casimir ``Pi . Gamma`` [kg m^2/s]: the angular momentum about the vertical."""
        return pi_dot_gamma(y)

    def vertical_norm(self, y):
        """Casimir ``|Gamma|`` (exactly 1 for the true motion; kept at 1 by the splitting's
        exact rotations and by the projection of the other integrators)."""
        return vertical_norm(y)

    def angular_velocity(self, y):
        """Body angular velocity ``Omega = I^-1 Pi`` [rad/s]."""
        return angular_velocity(self.params.inverse, y)

    def spin(self, y):
        """``Omega . chi`` [rad/s]: the rate about the centre-of-mass axis (``Omega3`` of a
        Lagrange top; conserved by it without axial torque or friction)."""
        return top_spin(self.params.inverse, self.params.com_direction, y)

    def tilt(self, y):
        """Angle [rad] between the centre-of-mass axis ``chi`` and the upward vertical: 0
        upright, ``pi/2`` horizontal, ``pi`` hanging. ``atan2(|Gamma x chi|, Gamma . chi)``:
        accurate at both ends, and independent of any drift of ``|Gamma|``."""
        return top_tilt(self.params.com_direction, y)

    def precession_rate(self, y):
        """``d(phi)/dt`` [rad/s]: the rate at which the centre-of-mass axis turns about the
        vertical. With ``omega = phi' z + theta' n + psi' k`` (Euler angles, ``k`` = ``chi`` in
        space), ``omega.z - cos(theta) omega.k = phi' sin^2(theta)``; in the body frame
        ``omega.z = Omega.Gamma`` and ``omega.k = Omega.chi``. With the axis exactly on the
        vertical (``sin(theta) = 0``) the axis has no azimuth to turn (the rate has no limit
        there: it grows like ``|Omega_transverse| / theta``); it is reported as 0 there, a
        finite value a reward can use (the precess task then counts the full rate error)."""
        return precession_rate((self.params.inverse, self.params.com_direction), y)

    def attitude_from_vertical(self, gamma, heading):
        """A quaternion ``q`` with ``R(q)^T e_z = Gamma`` and the given heading [rad]
        (:func:`attitude_from_vertical`)."""
        return attitude_from_vertical(tuple(gamma), heading)

    # ------------------------------------------------------------------ exact pieces
    def kick(self, y, u, h):
        """Exact flow for time ``h`` of the torques with ``Gamma`` held fixed: gravity
        ``M g l Gamma x chi``, the control ``tau`` and the spin friction (:func:`heavy_top_kick`).

        Without friction ``Pi += h f``, ``f = M g l Gamma x chi + tau``. With friction
        ``s = Omega.chi`` obeys ``ds/dt = b - kappa s`` (``b = chi.I^-1 f``,
        ``kappa = k chi.I^-1 chi``), so ``Pi(h) = Pi + h f - k chi int_0^h s`` in closed form.
        Gravity's part keeps ``Pi.Gamma`` (its torque is normal to ``Gamma``).
        """
        return self._kick_form(self._kick, tuple(y), u, h)

    @property
    def kernel_split_flows(self) -> tuple:
        """The pure forms of :meth:`split_flows` (generated flows are made on access, not
        stored: the system pickles); the kick without spin friction where there is none (the
        same operations, without a branch that holds a call)."""
        return ((self._kick_form, self._kick),) + tuple(flow.kernel for flow in self._split[1:])

    def split_flows(self):
        """Pieces for a symmetric (Strang) splitting: the torque kick, then the free flow.

        For a Lagrange top the free flow is exact (:class:`SymmetricFreeRotation`), so the only
        error is the splitting of gravity from the free motion; otherwise it is the three axis
        rotations of the Lie-Poisson splitting. Every piece keeps ``|Gamma|`` and (without
        control and friction) ``Pi.Gamma`` to round-off.
        """
        return self._split

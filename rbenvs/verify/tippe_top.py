"""Tippe-top checks of ``rbenvs verify`` (docs/physics.md §3), per integrator (euler, rk4, dop853),
on random tops, and the ``--sweep`` of the final tilt over ``A/C`` and ``alpha``.

Random tops (``--seed``), every quantity from these ranges:

* radius ``R ~ U(0.01, 0.03)`` m, mass ``m ~ U(0.005, 0.05)`` kg, ``g = 9.81`` m/s^2 (toy tops);
* ``alpha = h/R ~ U(0.1, 0.4)`` (``U(0.1, 0.3)`` below the window, see next);
* ``A/C`` in one of three regimes of the theorem: **below** the window,
  ``A/C ~ U(max(0.55, 1 - 1.5 alpha), 1 - 1.15 alpha)`` (``C <= 2 A``, the model's triangle
  inequality, needs ``A/C >= 0.5``: the range is empty for ``alpha > 0.3``, hence the narrower
  ``alpha``); **inside**, ``A/C = 1 + s alpha``, ``s ~ U(-0.6, 0.6)``; **above**,
  ``A/C = 1 + (1 + s) alpha``, ``s ~ U(0.15, 0.5)`` (a partial inversion to 115-135 degrees);
* ``C = c m R^2``, ``c ~ U(0.38, 0.45)``, at most :func:`ball_bound` (the mass fits in the ball);
* Jellett's integral ``J = k J_c``, ``k ~ U(1.15, 1.3)``, ``J_c = sqrt(m g R^3 C alpha)
  (1 + alpha)^2 / sqrt(0.4 alpha)``: the ``J_min`` of :func:`~rbenvs.oracles.inversion_criterion`
  at ``A/C = 1 + 0.6 alpha``, the largest of the thresholds (``J_min``, ``J_upright``) over the
  inside range, so every top inside the window exceeds both and every top above it exceeds
  ``J_upright``; the upright spin is ``n = J/(R C (1 - alpha))``, ``n sqrt(R/g)`` 4 to 11.
  The ranges keep the top on the table (``N > 0``): faster or lighter-cored tops (``k = 1.5``,
  or ``c = 0.3``, at ``alpha >= 0.3``; measured) hop off it during the climb, which the model
  does not follow (no free flight: a run stops at the first ``N < 0`` and its row FAILs).

Time is measured in ``t_g = sqrt(R/g)`` (39 ms at ``R = 15`` mm), viscous friction by
``mu* = mu sqrt(g R)`` (``mu`` in s/m), so that every range above costs the same number of steps
whatever ``R``.

Checks (one row per integrator and check: the worst of the cases, with its parameters):

* ``Jellett held (<law>)``: the largest ``|J(t) - J(0)|`` over ``[0, T]``, relative to
  ``|L| (R + h)`` (the largest ``J`` the state's momentum allows; ``J`` itself can be near zero),
  for gliding friction (Coulomb ``mu ~ U(0.2, 0.5)``, regularised at the default ``1e-3`` m/s,
  and viscous ``mu* ~ U(0.1, 0.5)``), frictionless, rolling, and a moving table (viscous, the
  table's acceleration ``a_T = 0.3 g (cos(w1 t + p1), sin(w2 t + p2))``, ``w t_g ~ U(0.3, 1)``,
  held over each step at its mid-time). ``J`` is the oracle's :func:`~rbenvs.oracles.jellett` of
  ``L`` and ``k`` built from the simulated attitude and angular velocity. Random states per law:
  tilt ``U(0.2, pi - 0.2)``, uniform azimuth and heading, spin ``U(0.5, 1) n``, a transverse
  angular velocity ``U(0, 0.3)/t_g``, and (gliding) an initial slip ``U(0, 0.5) sqrt(g R)`` of
  random direction. ``T = 40 t_g``, ``10 t_g`` under Coulomb friction (stiff near zero slip: the
  step is then the stability bound) and for dop853 (costly per step). A run stops at the first
  step with ``N < 0`` (about one in ten: the top would hop; the case gives the time); a state
  that hops before its second sample is replaced by a new draw.
* ``energy non-increasing (<law>)``: the largest rise of the energy between two samples
  (``t_g/2`` apart), relative to ``E(0)``: friction dissipates while the table pushes
  (``N >= 0``, checked after every step). ``energy conserved (frictionless | rolling)``:
  ``max |E - E(0)|/E(0)``.
* ``inversion class`` and ``final tilt [deg]`` per regime: upright start (tilt 0.1 rad about a
  horizontal axis, spin ``n``, no slip), viscous friction ``mu* = 0.01/alpha``: the rise slows as
  ``mu* alpha`` falls, a large ``mu*`` makes the climb violent (hops at ``alpha >= 0.3``) and the
  last approach slow (near rolling, which keeps the energy); this settles every range above
  within the horizon. Run until settled: over the last ``25 t_g`` the tilt moves less than 0.05
  degree and the slip speed is below ``3e-5 R n`` (else ``5000 t_g``; the case says which).
  Predicted: :func:`~rbenvs.oracles.inversion_criterion` at the start's ``J`` (classes 0 = none,
  1 = partial, 2 = full) and the tilt of the minimum of ``E*`` (:func:`~rbenvs.oracles.final_tilt`),
  or 0 when the criterion says no inversion (``theta = 0`` is then a local minimum that the top
  keeps, though ``E*`` is lower at ``pi``). Measured: the final tilt and its class (below 30
  degrees none, above 170 full, else partial). Tolerance 0.5 degree: in the last, gliding phase
  the distance to the limit falls with the slip speed; at ``3e-5 R n`` it is below 0.1 degree
  (measured worst over 60 random tops: 0.1; 0.3 at ``1e-4 R n``); rk4's own error on the tilt is
  below 0.01 degree; the rest is margin. Behind the prediction: ``E >= E*(theta)`` at the state's
  ``J``, friction lowers ``E`` and keeps ``J``. Tops per integrator (quick / full): rk4 one /
  two per regime; dop853 one above the window / one per regime (rtol 1e-8: a final tilt needs
  no more); euler one / two inside the window with ``alpha <= 0.3`` (at its affordable step
  euler's outward drift outruns the slow frictional damping of an upright or a partially
  inverted top: see :data:`TIPPE_TOP_SETTINGS`).
* ``Jellett held through an inversion``: the default Leine-Glocker top (spin 150 rad/s, tilt
  0.1 rad, Coulomb ``mu = 0.3``) over 10 s, a whole inversion and more (the random states above
  run 10 to 40 ``t_g``, under a second): ``max |J - J0| / (|L| (R+h))``. rk4 at
  ``max_stable_step`` (measured 1.4e-8; tolerance 1e-7); a simulator at its own step is held to
  that scaled by the order when it declares order 4, else to the physical bound (2%: there is
  no first-order reference run). Not run for euler and dop853 at their settings (the rows above
  hold them to Jellett's integral).
* ``time to pass 90 deg`` (rk4): the default Leine-Glocker top (docs/physics.md §3, spin 150 rad/s,
  tilt 0.1 rad, Coulomb ``mu = 0.3``), ``t90`` (about 6.99 s) at ``h = max_stable_step`` and
  ``h/2``, linear interpolation between steps. rk4 at ``|Omega| h < 0.01`` commits a relative
  error ``(|Omega| h)^5/120 < 1e-12`` per step, ``< 1e-7`` over the ``1.1e5`` steps; the climb
  from 0.1 rad turns a tilt error ``d`` into a delay ``d/(sigma theta)`` (growth rate
  ``sigma ~ 0.5/s``): ``< 1e-5`` s (measured 2e-6 s). Tolerance ``1e-4`` s. Full runs add the
  order: ``log2((t(h) - t(h/2))/(t(h/2) - t(h/4)))``, 4 within 0.5 (measured 4.2).

Integrator settings (:data:`TIPPE_TOP_SETTINGS`) give each scheme's steps and tolerances, from
its order at its step and the worst measured over many seeds (in the comments there).

The components are floats, one state per run: the tippe top's vector field costs ~2.5 us on
floats and ~60 us on numpy arrays of a few states (one numpy call per operation), so a batch
pays only beyond ~25 states of one parameter set, more than any check here runs.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from ..dynamics import TippeTop, TippeTopParams
from ..integrators import get_integrator
from ..oracles import final_tilt, inversion_criterion, jellett
from ..rotations import quat_multiply, quat_rotate
from .common import (
    ENERGY_BOUND,
    MOMENTUM_BOUND,
    ROUND_OFF,
    Check,
    not_applicable,
    reference_scheme,
    scaled_tolerance,
    worst,
)
from .simulator import as_simulators, start

__all__ = [
    "TIPPE_TOP_SETTINGS",
    "TippeSetting",
    "RandomTop",
    "SweepPoint",
    "random_tops",
    "tippe_top_checks",
    "settle",
    "sweep",
    "print_sweep",
    "plot_sweep",
    "SWEEP_ALPHAS",
    "SWEEP_OFFSETS",
    "oracle_jellett",
]

SYSTEM = "tippe_top"
GRAVITY = 9.81
REGIMES = ("below", "inside", "above")
CLASS_CODE = {"no inversion": 0, "partial inversion": 1, "full inversion": 2}
CLASS_BOUNDS = (math.radians(30.0), math.radians(170.0))  # final tilt: none below, full above

START_TILT = 0.1  # rad, the upright starts
MU_STAR = 0.01  # settling runs: viscous mu sqrt(g R) = MU_STAR / alpha
K_RANGE = (1.15, 1.3)  # J / J_c of the random tops
C_RANGE = (0.38, 0.45)  # C / (m R^2) of the random tops (at most ball_bound)
SETTLE_SAMPLE = 0.25  # t_g between tilt samples of a settling run
DOP853_SETTLE_SAMPLE = 1.0  # t_g, dop853's
SETTLE_WINDOW = 25.0  # t_g: settled when, over this window, ...
SETTLE_BAND = math.radians(0.05)  # ... the tilt moves less than this
SETTLE_SLIP = 3e-5  # ... and the slip speed ends below this times R |n|
SETTLE_HORIZON = 5000.0  # t_g: the longest settling run (alpha = 0.1 settles in 2500 to 3000)
FINAL_TILT_TOL = math.radians(0.5)

INVARIANT_HORIZON = 40.0  # t_g
SHORT_HORIZON = 10.0  # t_g: Coulomb friction (stiff near zero slip) and dop853 (costly per step)
DOP853_SLIP = (
    0.1  # x sqrt(g R): dop853's Coulomb regularisation (the others run the default 1e-3 m/s)
)
INVARIANT_SAMPLE = 0.5  # t_g between samples of the invariants
MAX_DRAWS = 5  # states drawn for one that stays on the table past its first sample
T90_TOL = 1e-4  # s
T90_ORDER_TOL = (
    0.5  # on the observed order (measured 4.18: the differences are 2.0e-6 s and 1.1e-7 s)
)


@dataclass(frozen=True)
class TippeSetting:
    """Steps and tolerances of one integrator on the tippe top.

    ``invariant_step``, ``settle_step``: ``|Omega| h`` of the invariants and settling runs (the
    step is also kept below :meth:`~rbenvs.dynamics.TippeTop.max_stable_step`); for dop853, which
    adapts its own step, unused. ``states``: random states per top and law (quick, full);
    ``regimes``: the regimes of the inversion rows (quick, full), one random top each per
    ``inversion_tops``. Tolerances (relative): ``jellett`` on the drift of ``J`` (relative to
    ``|L| (R + h)``), ``energy`` on the conserved energy's drift, ``rise`` on the largest rise of
    a dissipated energy between samples. ``rtol``: dop853's tolerance in the invariant runs
    (``settle_rtol`` in the settling runs: a final tilt needs far less). ``alpha_max``: the
    largest ``alpha`` of the settling runs' tops.
    """

    invariant_step: float
    settle_step: float
    states: tuple[int, int]
    regimes: tuple[tuple[str, ...], tuple[str, ...]]
    inversion_tops: tuple[int, int]
    jellett: float
    energy: float
    rise: float
    rtol: float = 1e-12
    settle_rtol: float = 1e-8
    alpha_max: float = 0.4


# Steps and tolerances. The step of a fixed-step run is ``h = omega_h / Omega_max`` with
# ``Omega_max`` 1.5 times the largest rate the energy allows (:func:`_omega_bound`; 1.2 times
# the spin for the settling runs), and never above ``max_stable_step`` (Coulomb friction near
# zero slip is stiff: there the step is the stability bound, |Omega| h ~ 1e-3). The invariants
# see a small part of a scheme's error at its step (most of it is a phase error along the
# motion); the tolerances stand well above the worst measured over 20 seeds x 2 states per law
# (in brackets), and far below what a wrong force does (tests: a flipped friction raises the
# energy by ~1e-3 of E0 per sample, a contact arm on the wrong side moves J by ~1e-2):
#
# * euler (order 1), omega_h = 1e-2: an error ~ (Omega h) per radian turned, over Omega T ~ 500
#   radians: J 0.1 [1.8e-2], energy 0.04 [6.1e-3] (ENERGY_BOUND), rise per sample 1e-4 [1.8e-6].
#   J's 0.1 is above MOMENTUM_BOUND (2%, rbenvs.verify.common): the worst measured at this step
# comes within 10% of the bound, and a step small enough to hold it with a margin costs 3x.
# Settling:
#   omega_h = 0.03, inside the window and alpha <= 0.3 only. Euler turns every rotating vector
#   outward, a growth rate ~ w^2 h / 2 for a vector turning at w; friction damps the final
#   states slowly. A top that stays upright (below the window; w = |C/A - 1| n, up to 0.8 n)
#   nods ever wider and hops (seed 1: J off by 100% at 13 s); a partially inverted top rolls
#   in a steady precession where friction hardly dissipates (J off by 7x at omega_h = 0.01 and
#   the top hops; by 20% at 0.003, the tilt 5 degrees off after 3000 t_g); inside the window at
#   alpha ~ 0.39 and A/C ~ 0.78 (2 of 30 tops; also at omega_h = 0.01) the climb hops. Below
#   alpha 0.3 inside the window euler settles every top tried (30 of 30; J drifts 2e-3 to 4e-2:
#   the final tilt of a full inversion does not depend on J).
# * rk4 (order 4), omega_h = 0.1: local error (Omega h)^5/120 < 1e-7 per step. J 1e-6 [1.4e-8
#   without table motion, 7.4e-8 with], energy 1e-7 [3.0e-9], rise 1e-8 [0: never rose].
# * dop853 at rtol 1e-12 (atol 1e-14), sampled every t_g/2: 100 x rtol: J and energy 1e-10
#   [1.4e-12, 7.4e-13], rise 1e-11 [0]. Coulomb friction regularised at 0.1 sqrt(g R) (DOP853_SLIP):
#   at 1e-3 m/s the stiffness costs ~4e5 evaluations per 10 t_g. Settling at rtol 1e-8.
TIPPE_TOP_SETTINGS = {
    "euler": TippeSetting(
        invariant_step=1e-2,
        settle_step=0.03,
        states=(1, 2),
        regimes=(("inside",), ("inside",)),
        inversion_tops=(1, 2),
        jellett=0.1,
        energy=0.04,
        rise=1e-4,
        alpha_max=0.3,
    ),
    "rk4": TippeSetting(
        invariant_step=0.1,
        settle_step=0.1,
        states=(2, 4),
        regimes=(REGIMES, REGIMES),
        inversion_tops=(1, 2),
        jellett=1e-6,
        energy=1e-7,
        rise=1e-8,
    ),
    "dop853": TippeSetting(
        invariant_step=0.0,
        settle_step=0.0,
        states=(1, 2),
        regimes=(("above",), REGIMES),
        inversion_tops=(1, 1),
        jellett=1e-10,
        energy=1e-10,
        rise=1e-11,
    ),
}


# ------------------------------------------------------------------------------------------
# random tops


@dataclass(frozen=True)
class RandomTop:
    """One random top (module docstring): geometry, moments, regime and Jellett integral."""

    regime: str
    radius: float
    mass: float
    alpha: float
    c: float  # C / (m R^2)
    gamma: float  # A / C
    k: float  # J / J_c
    gravity: float = GRAVITY

    @property
    def C(self) -> float:
        return self.c * self.mass * self.radius**2

    @property
    def A(self) -> float:
        return self.gamma * self.C

    @property
    def t_g(self) -> float:
        """``sqrt(R/g)`` [s]."""
        return math.sqrt(self.radius / self.gravity)

    @property
    def J_c(self) -> float:
        a = self.alpha
        return (
            math.sqrt(self.mass * self.gravity * self.radius**3 * self.C * a)
            * (1.0 + a) ** 2
            / math.sqrt(0.4 * a)
        )

    @property
    def spin(self) -> float:
        """Upright spin ``n = k J_c / (R C (1 - alpha))`` [rad/s]."""
        return self.k * self.J_c / (self.radius * self.C * (1.0 - self.alpha))

    def params(self, law="viscous", mu=None) -> TippeTopParams:
        """Parameters with ``law`` and ``mu`` (default: the settling runs' viscous
        ``mu* = MU_STAR/alpha``)."""
        if mu is None:
            mu = settling_friction(self.alpha, self.radius, self.gravity)
        return TippeTopParams(
            radius=self.radius,
            mass=self.mass,
            offset=self.alpha,
            inertia=(self.A, self.C),
            gravity=self.gravity,
            friction=mu,
            friction_law=law,
        )

    def describe(self) -> dict:
        return {
            "regime": self.regime,
            "radius": self.radius,
            "mass": self.mass,
            "offset": self.alpha,
            "inertia": [self.A, self.C],
            "gravity": self.gravity,
            "A/C": self.gamma,
            "J/J_c": self.k,
        }


def ball_bound(alpha, gamma) -> float:
    """The largest ``c = C/(m R^2)`` of a mass inside the ball at ``alpha`` and ``A/C = gamma``:
    ``2 A_O + C <= 2 m R^2`` with ``A_O = A + m h^2`` (``sum of the moments about the centre
    = 2 int |r|^2 dm``), i.e. ``c <= 2 (1 - alpha^2) / (2 gamma + 1)``."""
    return 2.0 * (1.0 - alpha * alpha) / (2.0 * gamma + 1.0)


def settling_friction(alpha, radius, gravity=GRAVITY) -> float:
    """Viscous ``mu`` [s/m] of the settling runs: ``mu sqrt(g R) = MU_STAR / alpha``."""
    return MU_STAR / alpha / math.sqrt(gravity * radius)


def _gamma(rng, regime, alpha):
    if regime == "below":
        return float(rng.uniform(max(0.55, 1.0 - 1.5 * alpha), 1.0 - 1.15 * alpha))
    if regime == "inside":
        return 1.0 + float(rng.uniform(-0.6, 0.6)) * alpha
    if regime == "above":
        return 1.0 + (1.0 + float(rng.uniform(0.15, 0.5))) * alpha
    raise ValueError(f"regime must be one of {list(REGIMES)}, got {regime!r}")


def random_tops(rng, n, regime="inside", alpha_max=0.4) -> list[RandomTop]:
    """``n`` tops of one regime from the ranges of the module docstring (``alpha`` at most
    ``alpha_max``)."""
    out = []
    for _ in range(n):
        radius = float(rng.uniform(0.01, 0.03))
        mass = float(rng.uniform(0.005, 0.05))
        alpha = float(rng.uniform(0.1, min(alpha_max, 0.3 if regime == "below" else 0.4)))
        gamma = _gamma(rng, regime, alpha)
        c = min(float(rng.uniform(*C_RANGE)), ball_bound(alpha, gamma))
        k = float(rng.uniform(*K_RANGE))
        out.append(RandomTop(regime, radius, mass, alpha, c, gamma, k))
    return out


# ------------------------------------------------------------------------------------------
# states and measurements


def _tilted_attitude(tilt, azimuth=0.0, heading=0.0):
    """``R = Rz(azimuth) Rx(tilt) Rz(heading)``: the symmetry axis at ``tilt`` from the vertical."""
    qz1 = (math.cos(0.5 * azimuth), 0.0, 0.0, math.sin(0.5 * azimuth))
    qx = (math.cos(0.5 * tilt), math.sin(0.5 * tilt), 0.0, 0.0)
    qz2 = (math.cos(0.5 * heading), 0.0, 0.0, math.sin(0.5 * heading))
    return quat_multiply(quat_multiply(qz1, qx), qz2)


def _attitude_and_rate(system, y):
    a0, a1 = system.layout["attitude"]
    w0, w1 = system.layout["angular_velocity"]
    return tuple(y[a0:a1]), tuple(y[w0:w1])


def oracle_jellett(system, y):
    """Jellett's integral by the oracle (:func:`~rbenvs.oracles.jellett`) from the state's
    attitude and body angular velocity, and the scale ``|L| (R + h)``; floats or arrays."""
    prm = system.params
    big_a, big_c = prm.inertia
    q, w = _attitude_and_rate(system, y)
    L = quat_rotate(q, (big_a * w[0], big_a * w[1], big_c * w[2]))
    k = quat_rotate(q, (0.0 * w[0], 0.0 * w[0], 1.0 + 0.0 * w[0]))
    Lv = np.stack(np.broadcast_arrays(*L), axis=-1)
    kv = np.stack(np.broadcast_arrays(*k), axis=-1)
    ok = np.all(np.isfinite(Lv), axis=-1) & np.all(np.isfinite(kv), axis=-1)
    if not np.all(ok):  # a diverged run: nan where it diverged
        Lv, kv = np.where(ok[..., None], Lv, 0.0), np.where(ok[..., None], kv, 1.0)
    J = np.where(ok, jellett(Lv, kv, prm.radius, prm.offset), np.nan)
    J = float(J) if np.ndim(J) == 0 else J
    scale = np.linalg.norm(Lv, axis=-1) * (prm.radius + prm.height)
    return J, scale


def _step_size(system, name, omega_h, omega):
    """``h = omega_h / omega``, kept below the friction law's stability bound."""
    return min(omega_h / omega, system.max_stable_step(get_integrator(name).region))


# ------------------------------------------------------------------------------------------
# invariants


@dataclass(frozen=True)
class _Variant:
    label: str
    fidelity: str
    law: str | None  # gliding: "coulomb" | "viscous"
    moving: bool = False
    dissipative: bool = False


VARIANTS = (
    _Variant("coulomb", "gliding", "coulomb", dissipative=True),
    _Variant("viscous", "gliding", "viscous", dissipative=True),
    _Variant("frictionless", "frictionless", None),
    _Variant("rolling", "rolling", None),
    _Variant("moving table", "gliding", "viscous", moving=True),
)


def _random_states(rng, top, system, n, slip):
    """``n`` random states (module docstring) as a list of component tuples, and their
    descriptions for a replay."""
    out, cases = [], []
    t_g = top.t_g
    for _ in range(n):
        tilt = float(rng.uniform(0.2, math.pi - 0.2))
        azimuth, heading = (float(v) for v in rng.uniform(0.0, 2.0 * math.pi, 2))
        spin = float(rng.uniform(0.5, 1.0)) * top.spin
        w_perp = float(rng.uniform(0.0, 0.3)) / t_g
        beta = float(rng.uniform(0.0, 2.0 * math.pi))
        w = (w_perp * math.cos(beta), w_perp * math.sin(beta), spin)
        q = _tilted_attitude(tilt, azimuth, heading)
        v = None
        slip_v = (0.0, 0.0)
        if slip and system.fidelity != "rolling":
            speed = float(rng.uniform(0.0, 0.5)) * math.sqrt(top.gravity * top.radius)
            d = float(rng.uniform(0.0, 2.0 * math.pi))
            slip_v = (speed * math.cos(d), speed * math.sin(d))
            v0 = system.no_slip_velocity(q, w)
            v = (v0[0] + slip_v[0], v0[1] + slip_v[1])
        out.append(system.state((0.0, 0.0), q, w, v))
        cases.append(
            {"attitude": [float(c) for c in q], "angular_velocity": list(w), "slip": list(slip_v)}
        )
    return out, cases


def _table_motion(rng, top):
    """A function ``t -> u`` for the moving table (module docstring) and its description."""
    a0 = 0.3 * top.gravity
    w1, w2 = (float(v) / top.t_g for v in rng.uniform(0.3, 1.0, 2))
    p1, p2 = (float(v) for v in rng.uniform(0.0, 2.0 * math.pi, 2))

    def u_of(t, mu):
        return (a0 * math.cos(w1 * t + p1), a0 * math.sin(w2 * t + p2), mu, 0.0, 0.0, 0.0)

    return u_of, {"table acceleration": a0, "w": [w1, w2], "phase": [p1, p2]}


def _omega_bound(system, y):
    """An upper bound of ``|Omega|`` while the energy does not grow: all of the energy above the
    lowest potential as rotation about the smaller moment."""
    prm = system.params
    floor = prm.mass * prm.gravity * (prm.radius - prm.height)
    e = np.max(np.asarray(system.energy(y)))
    return math.sqrt(2.0 * max(float(e) - floor, 0.0) / min(prm.inertia))


def _run_invariants(system, sim, setting, y, horizon, u_of):
    """Integrate the state ``y`` (floats) over ``horizon`` [s], sampling every
    ``INVARIANT_SAMPLE t_g``, until the end or the first sample where ``N < 0`` (the top would
    leave the table: the model has no free flight, and friction stops dissipating there).
    Returns arrays over the samples before lift-off of ``J``, the ``J`` scale, the energy and
    ``N/(m g)``, the step, the time of lift-off (``None``: none), and ``omega h`` of the run with
    its number of steps (a simulator's tolerances are scaled to them)."""
    prm = system.params
    t_g = math.sqrt(prm.radius / prm.gravity)
    sample = INVARIANT_SAMPLE * t_g
    omega = 1.5 * _omega_bound(system, y)
    if sim.dt is not None:  # a simulator's own step: samples every whole number of its steps
        h = sim.dt
        every = max(1, int(round(sample / h)))
    elif sim.integrator.name == "dop853":
        every, h = 1, sample
    else:
        h = _step_size(system, sim.integrator.name, setting.invariant_step, omega)
        every = max(1, int(math.ceil(sample / h)))
        h = sample / every
    run = start(sim, system, y)
    n_samples = int(math.ceil(horizon / (h * every)))
    mu = prm.friction
    weight = prm.mass * prm.gravity
    js, scales, energies, normals = [], [], [], []
    lift_off = None
    t = 0.0
    for k in range(n_samples + 1):
        normal = float(system.contact_forces(y, u_of(t, mu) if u_of else None)[0]) / weight
        if k:
            for _ in range(every):
                # the table's acceleration, held over the step, taken at its middle
                u = u_of(t + 0.5 * h, mu) if u_of else None
                y = run.step(u, h)
                t += h
                # N after every step of a fixed-step scheme (dop853: at the samples)
                n_step = float(system.contact_forces(y, u_of(t, mu) if u_of else None)[0]) / weight
                normal = n_step if not n_step >= 0.0 else min(normal, n_step)  # a nan is kept
                if not normal >= 0.0:
                    break
        if not normal >= 0.0:  # lift-off (or a non-finite state, which the others record as nan)
            lift_off = t
            if math.isfinite(normal):
                break
        J, scale = oracle_jellett(system, y)
        js.append(J)
        scales.append(scale)
        energies.append(float(system.energy(y)))
        normals.append(normal)
        if lift_off is not None:
            break
    steps = int(round(t / h))
    return (
        np.array(js),
        np.array(scales),
        np.array(energies),
        np.array(normals),
        h,
        lift_off,
        (omega * h, steps),
    )


def _invariant_rows(sim, setting, tops, rng, n_states, system_class, progress):
    name = sim.name
    dop853 = sim.dt is None and sim.integrator.name == "dop853"
    rows: dict[str, list[Check]] = {}

    def add(check):
        rows.setdefault(check.check, []).append(check)

    def tolerance(tol, run, bound):
        """The setting's tolerance; for a simulator at its own step, scaled to it, at most
        ``bound``."""
        return (
            tol
            if sim.dt is None
            else scaled_tolerance(tol, run[0], setting.invariant_step, sim.order, run[1], bound)
        )

    for top in tops:
        for variant in VARIANTS:
            mu = None
            if variant.law == "coulomb":
                mu = float(rng.uniform(0.2, 0.5))
            elif variant.law == "viscous":
                mu = float(rng.uniform(0.1, 0.5)) / math.sqrt(top.gravity * top.radius)
            params = top.params(variant.law or "viscous", mu if mu is not None else 0.0)
            if dop853 and variant.law == "coulomb":  # ~50x less stiff near zero slip
                params = dataclasses.replace(
                    params, slip_regularization=DOP853_SLIP * math.sqrt(top.gravity * top.radius)
                )
            system = system_class(params, variant.fidelity)
            u_of, motion = _table_motion(rng, top) if variant.moving else (None, {})
            horizon = (
                SHORT_HORIZON if dop853 or variant.law == "coulomb" else INVARIANT_HORIZON
            ) * top.t_g
            for n in range(n_states):
                try:
                    for _ in range(
                        MAX_DRAWS
                    ):  # a state that lifts off before its second sample is drawn again
                        (y,), (desc,) = _random_states(
                            rng, top, system, 1, slip=variant.fidelity == "gliding"
                        )
                        js, scales, energies, normals, h, lift_off, run = _run_invariants(
                            system, sim, setting, y, horizon, u_of
                        )
                        if len(js) >= 2:
                            break
                except (
                    NotImplementedError
                ) as exc:  # not modelled: n/a rows (the states drawn as for the others)
                    for _ in range(n + 1, n_states):
                        _random_states(rng, top, system, 1, slip=variant.fidelity == "gliding")
                    for row in not_applicable(
                        SYSTEM, name, _variant_rows(variant), f"{variant.label}: {exc}"
                    ):
                        add(row)
                    break
                case = (
                    top.describe()
                    | {
                        "fidelity": variant.fidelity,
                        "friction_law": variant.law,
                        "friction": params.friction,
                        "h": h,
                        "T": horizon,
                    }
                    | desc
                    | motion
                )
                case["min N/(m g)"] = float(np.min(normals)) if len(normals) else math.nan
                case["lift-off at"] = lift_off
                if len(js) < 2:  # MAX_DRAWS states in a row lifted off at once: a FAIL row (nan)
                    js = scales = energies = np.full(2, math.nan)
                drift = float(np.max(np.abs(js - js[0])) / scales[0])
                jellett_row, energy_row = _variant_rows(variant) + (
                    (None,) if variant.moving else ()
                )
                add(
                    Check(
                        SYSTEM,
                        name,
                        jellett_row,
                        0.0,
                        drift,
                        tolerance(setting.jellett, run, MOMENTUM_BOUND),
                        case=case,
                    )
                )
                if variant.dissipative:
                    rise = float(
                        np.max(np.append(np.diff(energies), 0.0)) / energies[0]
                    )  # nan stays nan
                    add(
                        Check(
                            SYSTEM,
                            name,
                            energy_row,
                            0.0,
                            rise,
                            tolerance(setting.rise, run, ENERGY_BOUND),
                            case=case,
                        )
                    )
                elif not variant.moving:
                    add(
                        Check(
                            SYSTEM,
                            name,
                            energy_row,
                            0.0,
                            float(np.max(np.abs(energies - energies[0])) / energies[0]),
                            tolerance(setting.energy, run, ENERGY_BOUND),
                            case=case,
                        )
                    )
        if progress:
            progress()
    return rows


def _variant_rows(variant) -> tuple[str, ...]:
    """The names of a friction law's rows: Jellett's and (but on the moving table) the energy's."""
    rows = (f"Jellett held ({variant.label}): max |dJ| / (|L| (R+h))",)
    if variant.dissipative:
        rows += (f"energy non-increasing ({variant.label}): max rise / E0",)
    elif not variant.moving:
        rows += (f"energy conserved ({variant.label}): max |dE| / E0",)
    return rows


# ------------------------------------------------------------------------------------------
# settling


@dataclass
class Settled:
    """The end of a settling run: ``tilt`` [rad] at the end (``nan`` after a lift-off), whether
    it ``settled`` (else the horizon or a lift-off ended it), the time ``t`` [s], ``min N/(m g)``
    (sampled), the relative ``J`` drift, the step, the time ``t90`` [s] of passing 90 degrees and
    of the ``lift_off`` (``N < 0``: the model has no free flight), ``None`` if none."""

    tilt: float
    settled: bool
    t: float
    min_normal: float
    jellett_drift: float
    h: float
    t90: float | None = None
    lift_off: float | None = None
    tilts: list = field(default_factory=list, repr=False)


def upright_start(system, spin, tilt=START_TILT):
    """Tilted by ``tilt`` about the space x axis, spinning at ``spin`` about the symmetry axis,
    the contact point at rest."""
    return system.state((0.0, 0.0), _tilted_attitude(tilt), (0.0, 0.0, spin))


def settle(
    system, integ, spin, omega_h=0.1, rtol=1e-8, horizon=SETTLE_HORIZON, record=False
) -> Settled:
    """Run the upright start of ``system`` at ``spin`` until settled (module docstring) or
    ``horizon`` t_g. ``integ``: an rbenvs integrator (name) or a simulator (at its own step);
    ``omega_h``: ``|Omega| h`` of a fixed-step scheme; ``rtol``: dop853's (one ``solve_ivp`` call
    per sample, every ``DOP853_SETTLE_SAMPLE t_g``: each call costs a set-up)."""
    prm = system.params
    t_g = math.sqrt(prm.radius / prm.gravity)
    y = upright_start(system, spin)
    J0, scale = oracle_jellett(system, y)
    (sim,) = as_simulators([integ])
    dop853 = sim.dt is None and sim.integrator.name == "dop853"
    sample_tg = DOP853_SETTLE_SAMPLE if dop853 else SETTLE_SAMPLE
    sample = sample_tg * t_g
    if dop853:
        sim = as_simulators([get_integrator("dop853", rtol=rtol, atol=rtol * 1e-3)])[0]
        every, h = 1, sample
    elif sim.dt is not None:  # a simulator's own step: whole steps per sample
        h = sim.dt
        every = max(1, int(round(sample / h)))
        sample = every * h
        sample_tg = sample / t_g
    else:
        h = _step_size(system, sim.integrator.name, omega_h, 1.2 * abs(spin))
        every = max(1, int(math.ceil(sample / h)))
        h = sample / every
    run = start(sim, system, y)
    per_window = int(round(SETTLE_WINDOW / sample_tg))
    n_samples = int(math.ceil(horizon / sample_tg))
    weight = prm.mass * prm.gravity
    tilts = [system.tilt(y)]
    min_n = float(system.contact_forces(y)[0]) / weight
    settled = False
    t90 = lift_off = None
    k = 0
    for k in range(1, n_samples + 1):
        for _ in range(every):
            y = run.step(None, h)
        tilt = system.tilt(y)
        if t90 is None and tilt > 0.5 * math.pi:
            t90 = k * sample
        tilts.append(tilt)
        n_now = float(system.contact_forces(y)[0]) / weight
        min_n = n_now if not n_now >= 0.0 else min(min_n, n_now)  # a nan is kept
        if not min_n >= 0.0:  # the top would leave the table (or the state is not finite): stop
            lift_off = k * sample
            break
        if k % per_window == 0:
            last = tilts[-per_window - 1 :]
            if max(last) - min(last) < SETTLE_BAND and system.slip_speed(
                y
            ) < SETTLE_SLIP * prm.radius * abs(spin):
                settled = True
                break
    J1, _ = oracle_jellett(system, y)
    return Settled(
        float(tilts[-1]) if lift_off is None else math.nan,
        settled,
        k * sample,
        min_n,
        float(abs(J1 - J0) / scale),
        h,
        t90,
        lift_off,
        tilts if record else [],
    )


def prediction(params: TippeTopParams, J: float):
    """``(class label, predicted final tilt [rad])``: the criterion at ``J``, and the minimum of
    ``E*`` (:func:`~rbenvs.oracles.final_tilt`), or 0 when the criterion says no inversion."""
    A, C = params.inertia
    args = (params.mass, params.gravity, params.radius)
    crit = inversion_criterion(A, C, params.offset, *args, J=J)
    if crit.classification == "no inversion":
        return crit.classification, 0.0
    return crit.classification, final_tilt(J, *args, params.offset, A, C)


def measured_class(tilt: float) -> str:
    """The class of a final tilt [rad]: below 30 degrees none, above 170 full, else partial."""
    if not math.isfinite(tilt):
        return "lift-off or diverged"
    if tilt < CLASS_BOUNDS[0]:
        return "no inversion"
    if tilt > CLASS_BOUNDS[1]:
        return "full inversion"
    return "partial inversion"


def _inversion_rows(sim, setting, tops, system_class, progress):
    name = sim.name
    rows: dict[str, list[Check]] = {}
    for top in tops:
        params = top.params()
        system = system_class(params, "gliding")
        y0 = upright_start(system, top.spin)
        J0 = float(oracle_jellett(system, y0)[0])
        label, tilt = prediction(params, J0)
        what = {
            "below": "A/C < 1 - alpha",
            "inside": "1 - alpha < A/C < 1 + alpha",
            "above": "A/C > 1 + alpha",
        }[top.regime]
        names = (
            f"inversion class, {what} (0 none, 1 partial, 2 full)",
            f"final tilt [deg] = argmin E*, {what}",
        )
        try:
            res = settle(system, sim, top.spin, setting.settle_step, setting.settle_rtol)
        except NotImplementedError as exc:
            na = not_applicable(
                SYSTEM, name, names, f"viscous friction (the settling runs'): {exc}"
            )
            rows.setdefault(f"c{top.regime}", []).append(na[0])
            rows.setdefault(f"t{top.regime}", []).append(na[1])
            continue
        got = measured_class(res.tilt)
        case = top.describe() | {
            "friction_law": "viscous",
            "friction": params.friction,
            "spin": top.spin,
            "start tilt": START_TILT,
            "J": J0,
            "predicted": label,
            "simulated": got,
            "settled": res.settled,
            "t": res.t,
            "h": res.h,
            "min N/(m g)": res.min_normal,
            "lift-off at": res.lift_off,
            "J drift": res.jellett_drift,
        }
        rows.setdefault(f"c{top.regime}", []).append(
            Check(
                SYSTEM,
                name,
                names[0],
                CLASS_CODE[label],
                CLASS_CODE.get(got, math.nan),
                0.0,
                case=case,
            )
        )
        rows.setdefault(f"t{top.regime}", []).append(
            Check(
                SYSTEM,
                name,
                names[1],
                math.degrees(tilt),
                math.degrees(res.tilt),
                math.degrees(FINAL_TILT_TOL),
                case=case,
            )
        )
        if progress:
            progress()
    return rows


# ------------------------------------------------------------------------------------------
# time to pass 90 degrees


T90_ROW = "time to pass 90 deg [s], default top: t90(h) against t90(h/2)"


def leine_glocker_t90(h_factor=1.0, spin=150.0, system_class=TippeTop):
    """``(t90 [s], h)``: the default top, Coulomb ``mu = 0.3``, from tilt 0.1 rad at ``spin``,
    rk4 at ``h = h_factor * max_stable_step``; ``t90`` by linear interpolation."""
    system = system_class(TippeTopParams(), "gliding")
    integ = get_integrator("rk4")
    h = h_factor * system.max_stable_step(get_integrator("rk4").region)
    y = upright_start(system, spin)
    prev = system.tilt(y)
    t = 0.0
    half = 0.5 * math.pi
    while t < 30.0:
        y = integ.step(system, y, None, h)
        t += h
        tilt = system.tilt(y)
        if tilt > half:
            return t - h * (tilt - half) / (tilt - prev), h
        prev = tilt
    return math.nan, h


def _t90_rows(order=True, system_class=TippeTop):
    """``t90`` at ``h`` against ``h/2``; with ``order``, also the order of convergence from
    ``h``, ``h/2``, ``h/4``: ``log2((t(h) - t(h/2)) / (t(h/2) - t(h/4)))``, 4 for rk4."""
    t_h, h = leine_glocker_t90(1.0, system_class=system_class)
    t_h2, _ = leine_glocker_t90(0.5, system_class=system_class)
    case = {k: v for k, v in TippeTopParams().__dict__.items()} | {
        "spin": 150.0,
        "start tilt": START_TILT,
        "h": h,
        "t90(h)": t_h,
        "t90(h/2)": t_h2,
    }
    rows = [Check(SYSTEM, "rk4", T90_ROW, t_h2, t_h, T90_TOL, case=case)]
    if order:
        t_h4, _ = leine_glocker_t90(0.25, system_class=system_class)
        ratio = (t_h - t_h2) / (t_h2 - t_h4) if t_h2 != t_h4 else math.nan
        measured = math.log2(ratio) if ratio > 0 else math.nan
        rows.append(
            Check(
                SYSTEM,
                "rk4",
                "order of convergence of t90 from h, h/2, h/4",
                4.0,
                measured,
                T90_ORDER_TOL,
                case=case | {"t90(h/4)": t_h4},
            )
        )
    return rows


# ------------------------------------------------------------------------------------------
# Jellett's integral through an inversion

INVERSION_SPIN = 150.0  # rad/s: the default top's, as for t90
INVERSION_HORIZON = 10.0  # s: past the inversion (t90 ~ 7 s in rbenvs' model)
INVERSION_SAMPLE = 0.05  # s between samples of J
INVERSION_ROW = (
    f"Jellett held through an inversion (default top, {INVERSION_SPIN:g} rad/s, coulomb, "
    f"{INVERSION_HORIZON:g} s): max |dJ| / (|L| (R+h))"
)
# rk4 at max_stable_step (h = 6.3e-5 s, |Omega| h ~ 0.01; 1.6e5 steps): measured 1.4e-8 (quick
# and full run the same case)
INVERSION_JELLETT = 1e-7


def _inversion_jellett_row(sim, system_class=TippeTop) -> Check:
    """Jellett's integral over a whole inversion of the default (Leine-Glocker) top under
    Coulomb friction, from tilt 0.1 rad at 150 rad/s: ``max |J(t) - J(0)| / (|L| (R+h))``.
    rbenvs' rk4 runs at ``max_stable_step``; a simulator at its own ``dt``, held to rk4's
    tolerance scaled by the order when its declared order is 4, else to the physical bound
    (:data:`~rbenvs.verify.common.MOMENTUM_BOUND`: there is no first-order reference run)."""
    system = system_class(TippeTopParams(), "gliding")
    rk4_h = system.max_stable_step(get_integrator("rk4").region)
    h = rk4_h if sim.dt is None else sim.dt
    every = max(1, int(round(INVERSION_SAMPLE / h)))
    n_samples = int(math.ceil(INVERSION_HORIZON / (h * every)))
    y = upright_start(system, INVERSION_SPIN)
    J0, scale = oracle_jellett(system, y)
    run = start(sim, system, y)
    drift = 0.0
    tilts = []
    for _ in range(n_samples):
        for _ in range(every):
            y = run.step(None, h)
        J, _ = oracle_jellett(system, y)
        drift = max(drift, abs(J - J0) / scale) if math.isfinite(J) else math.nan
        tilts.append(float(system.tilt(y)))
        if not math.isfinite(drift):
            break
    steps = n_samples * every
    if sim.dt is None:
        tol = INVERSION_JELLETT
    elif reference_scheme(sim.order) == "rk4":
        omega = INVERSION_SPIN
        tol = scaled_tolerance(
            INVERSION_JELLETT, omega * h, omega * rk4_h, sim.order, steps, MOMENTUM_BOUND
        )
    else:
        tol = MOMENTUM_BOUND + ROUND_OFF * math.sqrt(steps)
    case = {
        k: v
        for k, v in TippeTopParams().__dict__.items()
        if k in ("radius", "mass", "offset", "inertia", "friction")
    }
    case |= {
        "spin": INVERSION_SPIN,
        "start tilt": START_TILT,
        "h": h,
        "T": INVERSION_HORIZON,
        "max tilt [deg]": math.degrees(max(tilts)) if tilts else math.nan,
    }
    return Check(SYSTEM, sim.name, INVERSION_ROW, 0.0, drift, tol, case=case)


# ------------------------------------------------------------------------------------------
# hops (free flight)

HOP_CASE = {"spin": 2000.0, "friction": 1.0, "tilt": 0.1, "seconds": 0.3}
HOP_JELLETT_TOL = 1e-7  # relative; rk4 at the automatic step keeps it to ~1e-9 over 0.3 s
IMPACT_TOL = 1e-8  # relative; E_before - E_after cancels ~8 digits of E


def _hop_rows(system_class=TippeTop):
    """A fast top (2000 rad/s, mu = 1) hops hundreds of times: Jellett's integral kept, the
    energy never rising in a control period; and the plastic impact's energy loss
    ``lambda^2 M_zz / 2`` against the energy read-out, on random touchdowns."""
    from gymnasium.utils import seeding

    from ..contracts import StepResult
    from ..core.step import Engine
    from ..envs import TippeTopEnv
    from ..envs.base import compiled_backend

    case = dict(HOP_CASE)
    # the rolling start (its centre of mass moving at R n sin(theta)) and the stability bound's
    # steps: the case as measured (the system under test below is built with that bound)
    env = TippeTopEnv(
        spin=case["spin"],
        friction=case["friction"],
        tilt=case["tilt"],
        free_flight=True,
        max_speed=40.0,
        start="rolling",
        friction_bound="stability",
    )
    # the env's model with the system under test (a mutant in the tests), run by the step core
    # the env runs (its hybrid layer makes the switches between internal steps)
    engine = Engine(
        dataclasses.replace(env.model, system=system_class(env.params, "gliding", flight=True)),
        backend=compiled_backend,
    )
    y = tuple(float(c) for c in engine.model.initial_state(seeding.np_random(0)[0]))
    _, info = engine.reset_one(y)
    j0, e0 = info["jellett"], info["energy"]
    dj, rise = 0.0, -math.inf
    energy = e0
    plain = engine.plain
    for _ in range(round(case["seconds"] / env.dt)):
        result = StepResult._make(engine.step_one(y, [0.0, 0.0], plain))
        y, terminated, info, plain = result.y, result.terminated, result.info, result.plain
        dj = max(dj, abs(info["jellett"] - j0))
        rise = max(rise, info["energy"] - energy)
        energy = info["energy"]
        if terminated:
            dj = rise = math.nan
            break
    case["hops"] = info["hops"]
    rows = [
        Check(
            SYSTEM,
            "rk4",
            f"hops ({case['hops']}): Jellett held, max |dJ| / |J|",
            0.0,
            dj / abs(j0),
            HOP_JELLETT_TOL,
            case=case,
        ),
        Check(
            SYSTEM,
            "rk4",
            "hops: energy never rises in a control period, max rise / E0",
            0.0,
            max(rise, 0.0) / e0,
            1e-13,
            case=case,
        ),
    ]
    system = engine.system
    rng = np.random.default_rng(0)
    worst_loss = 0.0
    for _ in range(20):
        y = _touchdown_state(system, rng)
        after, lam = system.impact(y)
        rm = system.frame(y)
        r = system.contact_arm(rm[6], rm[7], rm[8])
        t = (r[1] * rm[8] - r[2] * rm[7], r[2] * rm[6] - r[0] * rm[8], r[0] * rm[7] - r[1] * rm[6])
        big_a, big_c = system.params.inertia
        m_zz = 1.0 / system.params.mass + (t[0] ** 2 + t[1] ** 2) / big_a + t[2] ** 2 / big_c
        loss = system.energy(y) - system.energy(after)
        expected = 0.5 * lam * lam * m_zz
        worst_loss = max(worst_loss, abs(loss / expected - 1.0) if expected > 0.0 else math.inf)
    rows.append(
        Check(
            SYSTEM,
            "rk4",
            "plastic impact: energy loss / (lambda^2 M_zz / 2) - 1, 20 touchdowns",
            0.0,
            worst_loss,
            IMPACT_TOL,
        )
    )
    return rows


def _touchdown_state(system, rng):
    """A flight state at the table, its contact point moving down."""
    prm = system.params
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w = tuple(rng.normal(size=3) * np.array([20.0, 20.0, 300.0]))
    y = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0) + tuple(q) + w + (0.0, 0.0)
    y = y[:2] + (prm.radius - prm.height * system.frame(y)[8],) + y[3:]  # gap 0
    wanted = -abs(system.gap_rate(y)) - 0.05  # the gap closing
    return y[:5] + (y[5] + wanted - system.gap_rate(y),) + y[6:]


# ------------------------------------------------------------------------------------------
# all rows


def tippe_top_checks(
    integrators, seed=0, quick=False, system_class=TippeTop, progress=None, t90=True, regimes=None
) -> list[Check]:
    """The tippe-top rows for each of ``integrators``: rbenvs integrator names in
    :data:`TIPPE_TOP_SETTINGS` (others are left out), or
    :class:`~rbenvs.verify.simulator.Simulator` objects at their own step, on the random tops of
    their :func:`~rbenvs.verify.common.reference_scheme` and held to its settings scaled to
    their step (rows of rbenvs' own models, the hops and ``t90``, read n/a for them).
    ``system_class(params, fidelity)`` builds the simulated system (tests pass broken ones);
    ``regimes`` overrides the settings' regimes of the inversion rows; ``t90``: whether rk4 runs
    the default top's long runs, the time-to-90-degrees row and Jellett's integral through an
    inversion (a simulator at its own step runs the latter whatever ``t90``)."""
    checks: list[Check] = []
    mode = 0 if quick else 1
    for sim in as_simulators(integrators):
        if sim.dt is None:
            name = sim.integrator.name
            if name not in TIPPE_TOP_SETTINGS:
                continue
            setting = TIPPE_TOP_SETTINGS[name]
            if name == "dop853":
                sim = as_simulators(
                    [get_integrator(name, rtol=setting.rtol, atol=setting.rtol * 1e-2)]
                )[0]
        else:
            name = reference_scheme(sim.order)
            setting = TIPPE_TOP_SETTINGS[name]
        rng = np.random.default_rng([seed, 3, list(TIPPE_TOP_SETTINGS).index(name)])
        rows = _invariant_rows(
            sim,
            setting,
            random_tops(rng, 1, "inside"),
            rng,
            setting.states[mode],
            system_class,
            progress,
        )
        for regime in setting.regimes[mode] if regimes is None else regimes:
            tops = random_tops(
                np.random.default_rng([seed, 4, REGIMES.index(regime)]),
                setting.inversion_tops[mode],
                regime,
                setting.alpha_max,
            )
            rows |= _inversion_rows(sim, setting, tops, system_class, progress)
        checks.extend(worst(c) for c in rows.values())
        if sim.dt is not None or (name == "rk4" and t90):
            try:
                checks.append(_inversion_jellett_row(sim, system_class))
            except NotImplementedError as exc:
                checks.extend(not_applicable(SYSTEM, sim.name, [INVERSION_ROW], str(exc)))
        if sim.dt is not None:
            own = [
                "hops: Jellett held, max |dJ| / |J|",
                "hops: energy never rises in a control period, max rise / E0",
                "plastic impact: energy loss / (lambda^2 M_zz / 2) - 1, 20 touchdowns",
            ]
            if name == "rk4" and t90:
                own.insert(0, T90_ROW)
            checks.extend(
                not_applicable(
                    SYSTEM,
                    sim.name,
                    own,
                    "a row of rbenvs' own model (its free flight, its rk4's convergence)",
                )
            )
            continue
        if name == "rk4" and t90:
            checks.extend(_t90_rows(order=not quick, system_class=system_class))
            if progress:
                progress()
        if name == "rk4":
            checks.extend(_hop_rows(system_class))
            if progress:
                progress()
    return checks


def progress_total(integrators, quick=False, t90=True) -> int:
    mode = 0 if quick else 1
    total = 0
    for name in integrators:
        if name in TIPPE_TOP_SETTINGS:
            s = TIPPE_TOP_SETTINGS[name]
            total += (
                1
                + len(s.regimes[mode]) * s.inversion_tops[mode]
                + (1 if name == "rk4" and t90 else 0)
            )
            total += 1 if name == "rk4" else 0  # the hop rows
    return total


# ------------------------------------------------------------------------------------------
# the sweep

SWEEP_ALPHAS = (0.1, 0.2, 0.3)
# A/C = 1 + s alpha: two below the window, four inside, two above. At s = 0.9 (inside) the
# row's J is below J_min: the criterion says partial inversion, to ~148 degrees.
SWEEP_OFFSETS = (-1.5, -1.2, -0.6, 0.0, 0.6, 0.9, 1.2, 1.5)
SWEEP_QUICK = ((0.2,), (-1.5, 0.0, 1.5))


@dataclass
class SweepPoint:
    """One grid point: the top (``alpha``, ``gamma = A/C``, ``C``, ``radius``, ``mass``), its
    ``J`` and ``spin``, the prediction and the simulation (tilts in degrees)."""

    alpha: float
    gamma: float
    C: float
    radius: float
    mass: float
    J: float
    spin: float
    predicted_class: str
    predicted_tilt: float  # deg
    simulated_tilt: float  # deg
    settled: bool
    t: float
    min_normal: float

    @property
    def difference(self) -> float:
        return abs(self.simulated_tilt - self.predicted_tilt)

    @property
    def passed(self) -> bool:
        return bool(
            math.isfinite(self.difference)
            and self.difference <= math.degrees(FINAL_TILT_TOL)
            and measured_class(math.radians(self.simulated_tilt)) == self.predicted_class
        )


def sweep(
    alphas=SWEEP_ALPHAS,
    offsets=SWEEP_OFFSETS,
    integrator="rk4",
    k=1.3,
    c=0.4,
    radius=0.015,
    mass=0.006,
    progress=None,
    system_class=TippeTop,
) -> list[SweepPoint]:
    """The final tilt over a grid of ``A/C = 1 + s alpha`` (``s`` in ``offsets``) and ``alpha``.

    Every point is the same toy top (``radius``, ``mass``, ``C = c m R^2``; the defaults those of
    Leine and Glocker's top, with ``c = 0.4``) with its own ``A``, spun upright (tilt 0.1 rad) at
    one spin per ``alpha``: ``J = k J_c`` (module docstring), so the points inside the window with
    ``|s| <= 0.6`` exceed both thresholds, those above exceed ``J_upright``, and at ``s = 0.9``
    ``J < J_min`` (a partial inversion inside the window). Viscous friction
    ``mu* = MU_STAR/alpha``; ``integrator`` (rk4) at its settling step until settled (module
    docstring). Each point is its own parameter set: one run each. Returns the points in grid
    order; a point passes when the simulated class matches the predicted one and the tilts agree
    within ``FINAL_TILT_TOL``."""
    integ = get_integrator(integrator)
    setting = TIPPE_TOP_SETTINGS[integ.name]
    out = []
    for alpha in alphas:
        for s in offsets:
            top = RandomTop("sweep", radius, mass, alpha, c, 1.0 + s * alpha, k)
            params = top.params()
            system = system_class(params, "gliding")
            J0 = float(oracle_jellett(system, upright_start(system, top.spin))[0])
            label, tilt = prediction(params, J0)
            res = settle(system, integ, top.spin, setting.settle_step, setting.settle_rtol)
            out.append(
                SweepPoint(
                    alpha,
                    top.gamma,
                    top.C,
                    radius,
                    mass,
                    J0,
                    top.spin,
                    label,
                    math.degrees(tilt),
                    math.degrees(res.tilt),
                    res.settled,
                    res.t,
                    res.min_normal,
                )
            )
            if progress:
                progress()
    return out


def print_sweep(points, file=None):
    import sys

    file = sys.stdout if file is None else file
    rows = [
        (
            "alpha",
            "A/C",
            "J [kg m^2/s]",
            "spin",
            "predicted",
            "predicted [deg]",
            "simulated [deg]",
            "|diff| [deg]",
            "settled at [s]",
            "result",
        )
    ]
    for p in points:
        rows.append(
            (
                f"{p.alpha:.2f}",
                f"{p.gamma:.3f}",
                f"{p.J:.3e}",
                f"{p.spin:.0f}",
                p.predicted_class,
                f"{p.predicted_tilt:.2f}",
                f"{p.simulated_tilt:.2f}",
                f"{p.difference:.3f}",
                f"{p.t:.1f}" if p.settled else f"> {p.t:.0f}",
                "PASS" if p.passed else "FAIL",
            )
        )
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    for n, r in enumerate(rows):
        print("  ".join(x.ljust(w) for x, w in zip(r, widths)).rstrip(), file=file)
        if n == 0:
            print("  ".join("-" * w for w in widths), file=file)
    failed = sum(not p.passed for p in points)
    print(
        f"\n{len(points) - failed} passed, {failed} failed (tolerance "
        f"{math.degrees(FINAL_TILT_TOL):.1f} deg)",
        file=file,
    )


def plot_sweep(points, path):
    """Predicted (lines, on a fine grid of ``A/C`` at each row's ``J``) and simulated (markers)
    final tilt against ``A/C``, one colour per ``alpha``, the window ``1 +- alpha`` shaded. Needs
    matplotlib (the ``plot`` extra):
    ``RuntimeError`` with a message if it is missing."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise RuntimeError("--plot needs matplotlib: pip install 'rbenvs[plot]'") from None
    fig, ax = plt.subplots(figsize=(7, 4.5))
    alphas = sorted({p.alpha for p in points})
    for i, alpha in enumerate(alphas):
        pts = sorted((p for p in points if p.alpha == alpha), key=lambda p: p.gamma)
        color = f"C{i}"
        g = [p.gamma for p in pts]
        ax.axvspan(1 - alpha, 1 + alpha, color=color, alpha=0.06)
        # the prediction on a fine grid of A/C at the row's J (the same top but for A)
        p0 = pts[0]
        lo, hi = min(g[0], 1 - 1.5 * alpha), max(g[-1], 1 + 1.5 * alpha)
        fine = np.linspace(max(lo, 0.5 + 1e-9), hi, 600)
        pred = [
            math.degrees(
                prediction(
                    TippeTopParams(
                        radius=p0.radius, mass=p0.mass, offset=alpha, inertia=(x * p0.C, p0.C)
                    ),
                    p0.J,
                )[1]
            )
            for x in fine
        ]
        ax.plot(
            fine, pred, "-", color=color, lw=1.2, label=f"alpha = {alpha:g}: argmin E* (predicted)"
        )
        ax.plot(
            g,
            [p.simulated_tilt for p in pts],
            "o",
            color=color,
            mfc="none",
            label=f"alpha = {alpha:g}: simulated",
        )
    ax.set_xlabel("A/C")
    ax.set_ylabel("final tilt [deg]")
    ax.set_ylim(-5, 185)
    ax.set_title("Tippe top: final tilt, predicted against simulated")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)

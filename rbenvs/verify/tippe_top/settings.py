"""The tippe top's verify settings per integrator, the random tops and the states' measurements."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...dynamics import TippeTopParams
from ...integrators import get_integrator
from ...oracles import jellett
from ...rotations import quat_multiply, quat_rotate

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

"""The heavy top's verify settings per integrator and the random tops they run on."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...dynamics import HeavyTopParams
from ..common import (
    ANGLE_BOUND,
)

SYSTEM = "heavy_top"
GRAVITY = 9.81
START_TILT = 1e-3  # rad, the upright runs
FALL_TILT = 0.1  # rad: past it the top has fallen
HORIZON = 50.0  # t_g, the upright runs (see the module docstring)
BRACKET = (1.0, 3.0)  # x sqrt(M g l A)/C, the bisection's first bracket (the theorem says 2)
BISECTION_WIDTH = 1e-3  # relative width of the final bracket
ABOVE_CRITICAL = 1.2  # x critical: the upright top stays up
STABLE_BOUND = ANGLE_BOUND  # rad (1e-2): the upright top at ABOVE_CRITICAL stays below it
NUTATION_TOL = 5.0  # x eps, the fast-top formulas' relative tolerance
INVARIANT_HORIZON = 20.0  # t_g
# the small fast tops (module docstring): ranges of the mass [kg], the pivot-to-centre length [m],
# the disc's radius / length and its axial moment / that of a thin disc; tops (quick, full)
SMALL_MASS = (0.02, 0.1)
SMALL_LENGTH = (0.015, 0.025)
SMALL_RADIUS = (0.9, 1.1)
SMALL_AXIAL = (0.9, 0.98)
SMALL_TOP_CASES = (1, 3)
SMALL_BELOW = 0.8  # x critical: the small top falls


@dataclass(frozen=True)
class TopSetting:
    """Steps and scheme tolerances of one integrator on the heavy top.

    ``*_step``: ``omega h`` of a run (``omega`` its fastest body rate); for ``dop853`` the
    sampling interval ``omega dt`` (the scheme adapts its own step). ``batch``: spins per
    bisection run (1: plain bisection on floats, the cheapest for a fixed-step scheme).
    ``periods``: precession periods held. ``nods``: nutation periods of the fast top.
    Tolerances of the scheme's own error at these steps: ``held`` [rad] on ``max |tilt -
    alpha|``, ``rate`` (relative) on the regular precession rate, ``energy`` and ``casimir``
    on the relative drifts; ``nutation_drift`` times Euler's outward drift of the axis over
    one nod, relative to the amplitude, ``D = omega^2 h T_n cos(alpha) / (4 eps)``, is added
    to the fast top's ``5 eps`` (at most ``RATE_TOL``). Every tolerance here is at most the
    row's physical bound of :mod:`rbenvs.verify.common`.
    """

    upright_step: float
    precession_step: float
    nutation_step: float
    invariant_step: float
    batch: int
    periods: int
    nods: int
    held: float
    rate: float
    nutation_drift: float
    energy: float
    casimir: float | None  # None: kept to round-off


# Steps and tolerances, from the orders (docs/physics.md §4) at the worst of the ranges above (the
# measured worsts over 100 random tops, seeds 1, 11 and 12, in brackets):
#
# * euler (order 1) turns every rotation outward by sqrt(1 + (omega h)^2) per step: over omega T
#   radians the log of an amplitude grows by E = (omega h)(omega T)/2. Upright runs: omega T
#   <= 400, E <= 0.6 at omega h = 3e-3 (the tilt grows 1.8x at most: a stable top stays far
#   below the 0.1 rad of a fall, and the growth rate at 0.5 x critical is off by < 0.1%). Regular
#   precession, 2 periods: omega T <= 200, E <= 0.03 at 3e-4: held to 1e-2 rad (ANGLE_BOUND)
#   [3.7e-3], rate to 1e-2 [4.3e-4]. Invariants: omega T <= 200, E <= 0.05 at 5e-4: energy 3e-2
#   [3.8e-3], Pi.Gamma 2e-2 (MOMENTUM_BOUND) [8.6e-3].
#   The fast top (3 nods, omega h = 1e-4): the axis drifts by D (TopSetting) of the amplitude
#   per nod, D <= 0.6; the nod heights cancel it to ~3.5% of D (measured at the worst of the
#   ranges), so 0.1 D is added to the tolerance, at most RATE_TOL (2%: 0.1 D reaches 6% at the
#   worst corner of the ranges, where the measured 3.5% of D is 2.1%).
# * rk4 (order 4): (omega h)^4 = 1e-4 per radian of rotation, mostly a phase error that the
#   tilt does not see; the local error (omega h)^5/120 summed over the <= 5000 steps of a run
#   bounds the rest by 4e-4: held 5e-5 [5.9e-6], rate 5e-6 [3.9e-7], energy 1e-6 [7.1e-8],
#   Pi.Gamma 5e-6 [5.9e-7].
# * splitting (order 2): the only error is splitting gravity from the (exact) free flow, an
#   O((h/t_g)^2) perturbation of the Hamiltonian that stays bounded: h/t_g <= 0.057 at
#   omega h = 0.05, so 3e-3 on the tilt [2.1e-4] and the rate [2.6e-4], 1e-3 on the energy
#   [4.9e-5]; Pi.Gamma and |Gamma| to round-off.
# * dop853 (rtol 1e-12 per step, omega T <= 500 radians): 1e-10 [9.5e-13].
HEAVY_TOP_SETTINGS = {
    "euler": TopSetting(
        upright_step=3e-3,
        precession_step=3e-4,
        nutation_step=1e-4,
        invariant_step=5e-4,
        batch=1,
        periods=2,
        nods=3,
        held=1e-2,
        rate=1e-2,
        nutation_drift=0.1,
        energy=3e-2,
        casimir=2e-2,
    ),
    "rk4": TopSetting(
        upright_step=0.1,
        precession_step=0.1,
        nutation_step=0.1,
        invariant_step=0.1,
        batch=1,
        periods=5,
        nods=10,
        held=5e-5,
        rate=5e-6,
        nutation_drift=0.0,
        energy=1e-6,
        casimir=5e-6,
    ),
    "splitting": TopSetting(
        upright_step=0.05,
        precession_step=0.05,
        nutation_step=0.05,
        invariant_step=0.05,
        batch=1,
        periods=5,
        nods=10,
        held=3e-3,
        rate=3e-3,
        nutation_drift=0.0,
        energy=1e-3,
        casimir=None,
    ),
    "dop853": TopSetting(
        upright_step=2.0,
        precession_step=1.0,
        nutation_step=0.25,
        invariant_step=2.0,
        batch=63,
        periods=5,
        nods=10,
        held=1e-10,
        rate=1e-10,
        nutation_drift=0.0,
        energy=1e-10,
        casimir=1e-10,
    ),
}

# Sampling of the fixed-step runs, as omega dt: the tilt moves on the nutation time ~ 1/(r omega).
SAMPLE = {"upright": 0.5, "precession": 0.25, "nutation": 0.05, "invariants": 1.0}


# ------------------------------------------------------------------------------------------
# cases


@dataclass(frozen=True)
class _Lagrange:
    """A Lagrange top's parameters and the scales the upright runs use."""

    params: HeavyTopParams

    @property
    def A(self) -> float:
        return self.params.inertia[0]

    @property
    def C(self) -> float:
        return self.params.inertia[2]

    @property
    def t_g(self) -> float:
        """Gravity time ``sqrt(A/(M g l))`` [s]."""
        return math.sqrt(self.A / self.params.mgl)

    @property
    def spin_scale(self) -> float:
        """``sqrt(M g l A)/C`` [rad/s]: half the critical spin of the theorem."""
        return math.sqrt(self.params.mgl * self.A) / self.C

    def oracle_args(self):
        p = self.params
        return self.A, self.C, p.mass, p.length, p.gravity

    def describe(self) -> dict:
        p = self.params
        return {
            "inertia": list(p.inertia),
            "mass": p.mass,
            "length": p.length,
            "gravity": p.gravity,
        }


@dataclass(frozen=True)
class _Top(_Lagrange):
    precession_tilt: float
    precession_factor: float  # n / n_min
    nutation_tilt: float
    nutation_eps: float
    gamma0: tuple  # invariants run: unit vertical
    omega_dir: tuple  # and the direction and size of Omega, x sqrt(M g l A)/C
    omega_scale: float


def random_tops(rng, n) -> list[HeavyTopParams]:
    """``n`` Lagrange tops from the ranges of the module docstring."""
    return [t.params for t in _random_cases(rng, n)]


def _random_cases(rng, n) -> list[_Top]:
    out = []
    for _ in range(n):
        mass = float(rng.uniform(0.5, 2.0))
        length = float(rng.uniform(0.05, 0.5))
        ml2 = mass * length**2
        a_g = float(rng.uniform(1.0, 3.0)) * ml2
        c_g = float(rng.uniform(1.0, 2.0)) * a_g
        params = HeavyTopParams(
            inertia=(a_g + ml2, a_g + ml2, c_g), mass=mass, length=length, gravity=GRAVITY
        )
        gamma = rng.standard_normal(3)
        direction = rng.standard_normal(3)
        out.append(
            _Top(
                params=params,
                precession_tilt=float(rng.uniform(0.2, 1.2)),
                precession_factor=float(rng.uniform(1.1, 1.5)),
                nutation_tilt=float(rng.uniform(0.2, 1.2)),
                nutation_eps=float(math.exp(rng.uniform(math.log(5e-4), math.log(2e-3)))),
                gamma0=tuple((gamma / np.linalg.norm(gamma)).tolist()),
                omega_dir=tuple((direction / np.linalg.norm(direction)).tolist()),
                omega_scale=float(rng.uniform(1.0, 4.0)),
            )
        )
    return out


def _random_small_tops(rng, n) -> list[_Lagrange]:
    """``n`` small fast tops (module docstring): a thin disc of radius ``rho = s l`` on a stem,
    the pivot at the stem's tip ``l`` below the disc's centre."""
    out = []
    for _ in range(n):
        mass = float(rng.uniform(*SMALL_MASS))
        length = float(rng.uniform(*SMALL_LENGTH))
        rho = float(rng.uniform(*SMALL_RADIUS)) * length
        a_g = mass * rho**2 / 4.0
        c_g = float(rng.uniform(*SMALL_AXIAL)) * mass * rho**2 / 2.0
        params = HeavyTopParams(
            inertia=(a_g + mass * length**2, a_g + mass * length**2, c_g),
            mass=mass,
            length=length,
            gravity=GRAVITY,
        )
        out.append(_Lagrange(params))
    return out


def _lagrange_state(top: _Lagrange, tilt, spin, precession=0.0):
    """``(Pi, Gamma)`` with the axis at ``tilt`` from the vertical, spin ``n`` about ``chi`` and
    precession rate ``p``: ``Omega = p Gamma + (n - p cos(tilt)) chi``, ``Gamma = (sin, 0, cos)``.
    Floats or arrays."""
    s, c = np.sin(tilt), np.cos(tilt)
    state = np.broadcast_arrays(
        top.A * precession * s, 0.0 * s, top.C * np.asarray(spin, dtype=float), s, 0.0 * s, c
    )
    if state[0].shape == ():
        return tuple(float(v) for v in state)
    return tuple(np.array(v, dtype=float) for v in state)

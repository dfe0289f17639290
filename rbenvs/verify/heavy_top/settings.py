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

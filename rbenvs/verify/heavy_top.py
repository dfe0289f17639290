"""Heavy-top checks of ``rbenvs verify`` (docs/physics.md §2), per integrator, on random Lagrange
tops.

Every top is a Lagrange top (``I1 = I2 = A`` and ``I3 = C`` about the pivot, centre of mass on
the symmetry axis ``chi = e3``) drawn from these ranges (``--seed``):

* mass ``M ~ U(0.5, 2)`` kg, pivot-to-centre-of-mass length ``l ~ U(0.05, 0.5)`` m,
  ``g = 9.81`` m/s^2;
* transverse inertia about the centre of mass ``A_G ~ U(1, 3) M l^2`` and axial
  ``C_G ~ U(1, 2) A_G`` (oblate bodies, from a sphere to a thin disc: real tops);
* about the pivot ``A = A_G + M l^2``, ``C = C_G``; so ``r = C/A`` lies in ``(0.5, 1.5)``.

Why these ranges: the checks below are scale-free in the gravity time ``t_g = sqrt(A/(M g l))``
(the tilt of a Lagrange top obeys an equation with the coefficients ``C n/A`` and ``M g l/A``
alone), but the body-frame rates, which set the step, are the spin ``n ~ 2/(r t_g)`` at the
threshold: a slender top (``r << 1``) needs ``1/r`` times more steps, ``1/r^2`` with Euler. The
range keeps every integrator within the time of the command.

Small fast tops (``n_small`` of them; ``--quick`` 1, full 3, :data:`SMALL_TOP_CASES`), toy tops
at whose rates a step of 1e-3 s matters: a thin disc of radius ``rho = s l``, ``s ~ U(0.9,
1.1)``, on a stem, the pivot at its tip ``l ~ U(1.5, 2.5)`` cm below the disc's centre, mass
``M ~ U(20, 100)`` g, ``A_G = M rho^2/4``, ``C_G = c M rho^2/2`` with ``c ~ U(0.9, 0.98)`` (the
stem's share of the axial moment neglected, and kept below a flat disc's ``2 A_G``). So ``C/A``
lies in ``(0.3, 0.46)`` and the critical spin ``4 sqrt(g/l) sqrt(s^2/4 + 1)/(c s^2)`` in
``(75, 155)`` rad/s. Rows: the critical spin by bisection, the tilt at 1.2 x critical and the
growth rate at 0.8 x critical, as for the tops above (:func:`threshold_checks`). At 1.2 x
critical the transverse components of ``Omega`` turn in the body at ``(1 - C/A) n ~ 80`` rad/s:
a scheme that turns rotating vectors outward by ``sqrt(1 + (w h)^2)`` per step (explicit
Euler) makes a stable top fall at ``h = 1e-3`` s (the tilt grows by ``exp((w h)^2 T/(2 h))``,
``e^4`` to ``e^18`` over ``50 t_g``: past the 1e-2 rad bound from 1e-3), where the tops above,
slower in the body, do not show it.

Each run's step is ``h = (omega h)/omega`` with ``omega`` the run's fastest body rate (the
initial ``|Omega|``, plus ``2/t_g`` where the top may fall) and ``omega h`` from
:data:`HEAVY_TOP_SETTINGS`; ``dop853`` is adaptive (``rtol = 1e-12``) and is only sampled.
One row per (integrator, check): the worst of the random cases (the one closest to, or
farthest beyond, its tolerance), with its parameters for a replay.

Checks:

* ``critical spin by bisection``: start upright (``Pi = C n e3``) with a ``1e-3`` rad tilt;
  the top *falls* if its tilt passes ``0.1`` rad within ``50 t_g``. Bisection (for ``dop853``,
  whose cost is per call, a multisection over 63 spins at once) of the spin between
  ``1`` and ``3 sqrt(M g l A)/C`` until the bracket is 0.1% of the spin; predicted:
  :func:`~rbenvs.oracles.critical_spin`, tolerance 1% relative. The horizon: just below the
  threshold, ``n = n_c (1 - delta)``, the tilt grows like ``exp(sigma t)`` with
  ``sigma t_g = sqrt(1 - (n/n_c)^2) ~ sqrt(2 delta)`` (the roots of [MR 15.10.16]: the same for
  every ``C/A``), so from ``1e-3`` to ``0.1`` rad it needs ``ln(100)/sigma`` plus
  the slower nonlinear part: 31 t_g at ``delta = 0.5%``, 43 t_g at ``0.2%``, 49 t_g at
  ``0.15%``. And a top with ``delta < 0.125%`` never passes ``0.1`` rad at all: its orbit from
  the upright state turns at ``cos(theta_max) = 2 (n/n_c)^2 - 1``, ``theta_max ~ sqrt(8 delta)``.
  So ``50 t_g`` puts the bisection ``0.1-0.2%`` below ``n_c``: well inside 1%, and any error of
  the simulator's gravity, inertia or spin coupling larger than that shows.
* ``upright stable at 1.2 x critical``: max tilt over ``50 t_g`` from a ``1e-3`` rad tilt
  (theorem: bounded; the row passes below ``1e-2``).
* ``upright growth rate at 0.5 x critical``: from a ``1e-8`` rad tilt, the exponential rate of
  the tilt fitted while it grows from ``1e-6`` to ``1e-4`` rad (the decaying mode is then
  ``1e-4`` of the growing one, and the motion still linear), against ``max Re`` of
  :func:`~rbenvs.oracles.upright_eigenvalues`, 2% relative.
* ``regular precession held``: tilt ``alpha ~ U(0.2, 1.2)``, spin ``n = k n_min``,
  ``k ~ U(1.1, 1.5)`` (``n_min = 2 sqrt(A M g l cos(alpha))/C``: the least spin with a real
  root), started on the slow root ``p`` of :func:`~rbenvs.oracles.regular_precession_rates`
  (``Omega = p Gamma + (n - p cos(alpha)) chi``). Over :data:`HEAVY_TOP_SETTINGS` ``periods``
  precession periods: ``max |tilt - alpha|`` (predicted 0) and the mean of
  ``precession_rate`` against ``p``, with tolerances from the scheme's order at its step.
* ``fast top``: released at ``alpha ~ U(0.2, 1.2)`` with ``Omega = n chi`` and
  ``eps = A M g l/(C n)^2`` log-uniform in ``(5e-4, 2e-3)``, over ``nods`` nutation periods:
  the nutation amplitude (the largest height of a nod above the mean of the cusps either side
  of it: for the exact motion ``beta - alpha``, the cusps lying at ``alpha``; for Euler, whose
  axis drifts outward at ``omega^2 h sin(2 alpha)/4`` per second, the drift cancels to first
  order; negative if the axis first rises instead of falling), the
  period (between the first and last maxima, each refined by a parabola through three
  samples) and the mean precession rate (``phi`` from the trapezoid of ``precession_rate``, from
  the release to the last cusp, where ``phi' = 0``), against
  :func:`~rbenvs.oracles.fast_top_nutation`. Relative tolerance ``5 eps``: the formulas are the
  first terms in ``eps``; the next are ``3 eps cos(alpha)`` for the amplitude (the cubic's root
  and ``arccos`` to second order), ``2 eps cos(alpha)`` for the period (the small-oscillation
  frequency ``C n/A (1 - 2 eps cos(alpha))``) and 1 to 1.5 ``eps`` for the mean rate (measured
  with dop853), so ``5 eps`` leaves ``2 eps`` to the integrator and the peak interpolation.
  Euler's tolerances add its own error at its step (``nutation_drift``), at most ``RATE_TOL``
  (2%, :mod:`rbenvs.verify.common`: what a first-order scheme may add is bounded by what the
  behaviour rows allow a rate, whatever its step).
* invariants with zero torque, from a random state (``Gamma`` uniform on the sphere,
  ``Omega`` of random direction and ``|Omega| ~ U(1, 4) sqrt(M g l A)/C``) over ``20 t_g``:
  the energy drift (relative to ``1/2 Pi.Omega + M g l``), the ``Pi.Gamma`` drift (relative to
  ``|Pi|``) and ``| |Gamma| - 1 |``, all as the max over the run. The splitting keeps both
  Casimirs to round-off (its pieces are exact rotations and a kick normal to ``Gamma``):
  tolerance ``ROUND_OFF sqrt(steps)``; the others project ``Gamma`` back to unit length after
  each step, so ``|Gamma|`` is at round-off for them too, while their energy and ``Pi.Gamma``
  drift by the order of the scheme at its step (:data:`HEAVY_TOP_SETTINGS`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..dynamics import HeavyTop, HeavyTopParams
from ..oracles import (
    critical_spin,
    fast_top_nutation,
    regular_precession_rates,
    upright_eigenvalues,
)
from .common import (
    ANGLE_BOUND,
    ENERGY_BOUND,
    MOMENTUM_BOUND,
    RATE_TOL,
    ROUND_OFF,
    Check,
    not_applicable,
    reference_scheme,
    scaled_tolerance,
    worst,
)
from .protocol import batched
from .simulator import advance, as_simulators, start

__all__ = ["HEAVY_TOP_SETTINGS", "SMALL_TOP_CASES", "TopSetting", "heavy_top_checks", "random_tops"]

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


# ------------------------------------------------------------------------------------------
# running


def _run(system, sim, y, horizon, omega, omega_h, sample, observe):
    """Simulate ``y`` over ``horizon`` [s] with ``h = omega_h/omega`` (for dop853: the sampling
    interval; a simulator with its own ``dt``: that step, over whole samples past ``horizon``),
    calling ``observe(t, y)`` at ``t = 0`` and every ``sample/(omega h)`` steps (a whole number of
    samples: their spacing is uniform). ``observe`` returns True to stop early.
    Returns ``(h, steps)``."""
    if sim.dt is not None:
        h = sim.dt
        every = max(1, int(round(sample / (omega * h))))
        steps = max(1, int(math.ceil(horizon / (h * every)))) * every
    else:
        every = 1 if sim.integrator.name == "dop853" else max(1, int(round(sample / omega_h)))
        h = omega_h / omega
        n_samples = max(1, int(math.ceil(horizon / (h * every))))
        steps = n_samples * every
        h = horizon / steps
    if observe(0.0, y):
        return h, 0
    run = start(sim, system, y)
    for k in range(every, steps + 1, every):
        y = advance(run, every, None, h)
        if observe(k * h, y):
            return h, k
    return h, steps


def _tolerance(sim, tolerance, reference_step, omega, h, steps, bound):
    """A row's scheme tolerance: the setting's for rbenvs' own integrator at its step; for a
    simulator at its own ``dt``, the reference scheme's scaled to ``omega dt``, at most the row's
    physical ``bound`` (:func:`~rbenvs.verify.common.scaled_tolerance`)."""
    if sim.dt is None:
        return tolerance
    return scaled_tolerance(tolerance, omega * h, reference_step, sim.order, steps, bound)


def _refined_extrema(t, x, sign=1.0):
    """Interior local maxima (``sign = -1``: minima) of uniformly sampled ``x``, each refined by
    the parabola through its three samples: ``(times, values)``."""
    x = sign * np.asarray(x)
    t = np.asarray(t)
    if len(x) < 3:
        return np.array([]), np.array([])
    i = np.nonzero((x[1:-1] > x[:-2]) & (x[1:-1] >= x[2:]))[0] + 1
    a, b, c = x[i - 1], x[i], x[i + 1]
    den = a - 2.0 * b + c
    off = np.where(den != 0.0, 0.5 * (a - c) / np.where(den != 0.0, den, 1.0), 0.0)
    dt = t[1] - t[0]
    return t[i] + off * dt, sign * (b - 0.25 * (a - c) * off)


# ------------------------------------------------------------------------------------------
# the checks


def _falls(system, sim, setting, top, spins):
    """Whether the upright top, tilted by START_TILT, passes FALL_TILT within HORIZON t_g, for
    each spin (a float, or an array run as one batch)."""
    y = _lagrange_state(top, START_TILT, spins)
    fell = np.zeros(np.shape(spins), dtype=bool)

    def observe(t, y):
        nonlocal fell
        fell = fell | (np.asarray(system.tilt(y)) > FALL_TILT)
        return bool(np.all(fell))

    omega = float(np.max(spins)) + 2.0 / top.t_g
    _run(system, sim, y, HORIZON * top.t_g, omega, setting.upright_step, SAMPLE["upright"], observe)
    return fell


def _bisect_critical_spin(system, sim, setting, top):
    """The spin where the upright top stops falling, bracketed to BISECTION_WIDTH; nan if the
    first bracket does not hold it (the low end stands or the high end falls)."""
    lo, hi = (f * top.spin_scale for f in BRACKET)
    k = setting.batch if batched(sim) else 1
    ends = (
        _falls(system, sim, setting, top, np.array([lo, hi]))
        if k > 1
        else np.array(
            [_falls(system, sim, setting, top, lo), _falls(system, sim, setting, top, hi)]
        )
    )
    if not ends[0] or ends[1]:
        return math.nan, {
            "bracket": [lo, hi],
            "low end falls": bool(ends[0]),
            "high end falls": bool(ends[1]),
        }
    runs = 2
    while hi - lo > BISECTION_WIDTH * lo:
        grid = lo + (hi - lo) * np.arange(1, k + 1) / (k + 1)
        fell = np.atleast_1d(_falls(system, sim, setting, top, grid if k > 1 else float(grid[0])))
        runs += 1
        stands = np.nonzero(~fell)[0]
        first = int(stands[0]) if len(stands) else k  # the first spin that does not fall
        lo, hi = (grid[first - 1] if first > 0 else lo), (grid[first] if first < k else hi)
    omega_h = setting.upright_step if sim.dt is None else (hi + 2.0 / top.t_g) * sim.dt
    return 0.5 * (lo + hi), {"bracket": [float(lo), float(hi)], "runs": runs, "omega h": omega_h}


def _upright_max_tilt(system, sim, setting, top, spin):
    y = _lagrange_state(top, START_TILT, spin)
    worst = 0.0

    def observe(t, y):
        nonlocal worst
        worst = max(worst, float(system.tilt(y)))
        return False

    h, _ = _run(
        system,
        sim,
        y,
        HORIZON * top.t_g,
        spin + 2.0 / top.t_g,
        setting.upright_step,
        SAMPLE["upright"],
        observe,
    )
    return worst, h


def _upright_growth_rate(system, sim, setting, top, spin):
    """Rate of exp growth of the tilt from 1e-8 rad, fitted between 1e-6 and 1e-4 rad."""
    y = _lagrange_state(top, 1e-8, spin)
    ts, tilts = [], []

    def observe(t, y):
        tilt = float(system.tilt(y))
        ts.append(t)
        tilts.append(tilt)
        return tilt > 1e-4

    # the fit window lasts ln(100)/sigma ~ 5 t_g: dop853, sampled at its call interval, is
    # called 4x as often here as in the other upright runs (~30 samples in the window)
    omega_h = (
        setting.upright_step / 4.0
        if sim.dt is None and sim.integrator.name == "dop853"
        else setting.upright_step
    )
    h, _ = _run(
        system, sim, y, HORIZON * top.t_g, spin + 2.0 / top.t_g, omega_h, SAMPLE["upright"], observe
    )
    ts, tilts = np.array(ts), np.array(tilts)
    sel = (tilts >= 1e-6) & (tilts <= 1e-4)
    if sel.sum() < 5:
        return math.nan, h
    return float(np.polyfit(ts[sel], np.log(tilts[sel]), 1)[0]), h


def _recorder(system):
    """Lists of times, tilts and precession rates, and the callback of :func:`_run` that fills
    them."""
    ts, tilts, rates = [], [], []

    def observe(t, y):
        ts.append(t)
        tilts.append(float(system.tilt(y)))
        rates.append(float(system.precession_rate(y)))
        return False

    return ts, tilts, rates, observe


def _regular_precession(system, sim, setting, top):
    alpha = top.precession_tilt
    A, C = top.A, top.C
    mgl = top.params.mgl
    n = top.precession_factor * 2.0 * math.sqrt(A * mgl * math.cos(alpha)) / C
    p = regular_precession_rates(*top.oracle_args(), n, alpha).slow
    y = _lagrange_state(top, alpha, n, p)
    ts, tilts, rates, observe = _recorder(system)

    horizon = setting.periods * 2.0 * math.pi / abs(p)
    omega = math.hypot(n, p * math.sin(alpha))
    h, steps = _run(
        system, sim, y, horizon, omega, setting.precession_step, SAMPLE["precession"], observe
    )
    ts, tilts, rates = np.array(ts), np.array(tilts), np.array(rates)
    held = float(np.max(np.abs(tilts - alpha)))
    mean_rate = float(np.trapezoid(rates, ts) / ts[-1])
    case = top.describe() | {
        "tilt": alpha,
        "spin": n,
        "precession_rate": p,
        "periods": setting.periods,
        "h": h,
        "T": horizon,
    }
    tolerances = tuple(
        _tolerance(sim, tol, setting.precession_step, omega, h, steps, bound)
        for tol, bound in ((setting.held, ANGLE_BOUND), (setting.rate, RATE_TOL))
    )
    return p, held, mean_rate, case, tolerances


def _fast_top(system, sim, setting, top):
    alpha, eps = top.nutation_tilt, top.nutation_eps
    A, C = top.A, top.C
    n = math.sqrt(A * top.params.mgl / eps) / C
    oracle = fast_top_nutation(*top.oracle_args(), n, alpha)
    y = _lagrange_state(top, alpha, n)
    ts, tilts, rates, observe = _recorder(system)

    nod = 2.0 * math.pi * A / (C * n)  # the nutation time scale C n / A of the top
    horizon = (setting.nods + 0.25) * nod
    h, steps = _run(system, sim, y, horizon, n, setting.nutation_step, SAMPLE["nutation"], observe)
    ts, tilts, rates = np.array(ts), np.array(tilts), np.array(rates)
    t_max, v_max = _refined_extrema(ts, tilts)
    t_min, v_min = _refined_extrema(ts, tilts, -1.0)
    # Released at rest, a heavy top first falls: its first turn is a maximum of the tilt. A
    # top whose axis rises first (gravity pulling up) gets a negative amplitude.
    sign = -1.0 if len(t_min) and (not len(t_max) or t_min[0] < t_max[0]) else 1.0
    t_min, v_min = (
        np.concatenate([[0.0], t_min]),
        np.concatenate([[alpha], v_min]),
    )  # released at a cusp
    case = top.describe() | {
        "tilt": alpha,
        "spin": n,
        "eps": eps,
        "nods": setting.nods,
        "h": h,
        "T": horizon,
    }
    nods = min(len(t_max), len(t_min) - 1)
    if nods < 2:
        return oracle, (math.nan, math.nan, math.nan), case
    heights = v_max[:nods] - 0.5 * (v_min[:nods] + v_min[1 : nods + 1])
    amplitude = sign * float(np.max(heights))
    period = float((t_max[nods - 1] - t_max[0]) / (nods - 1))
    phi = np.concatenate([[0.0], np.cumsum(0.5 * (rates[1:] + rates[:-1]) * np.diff(ts))])
    t_end = t_min[nods]
    mean_rate = float(np.interp(t_end, ts, phi) / t_end)
    return oracle, (amplitude, period, mean_rate), case


def _invariants(system, sim, setting, top):
    gamma = np.array(top.gamma0)
    omega0 = np.array(top.omega_dir) * top.omega_scale * top.spin_scale
    pi0 = np.array(top.params.inertia) * omega0
    y = tuple(float(v) for v in pi0) + tuple(float(v) for v in gamma)
    e0 = system.energy(y)
    c0 = system.pi_dot_gamma(y)
    e_scale = 0.5 * float(np.dot(pi0, omega0)) + top.params.mgl
    p_scale = float(np.linalg.norm(pi0))
    worst = [0.0, 0.0, 0.0]

    def observe(t, y):
        worst[0] = max(worst[0], abs(system.energy(y) - e0) / e_scale)
        worst[1] = max(worst[1], abs(system.pi_dot_gamma(y) - c0) / p_scale)
        worst[2] = max(worst[2], abs(system.vertical_norm(y) - 1.0))
        return False

    horizon = INVARIANT_HORIZON * top.t_g
    omega = float(np.linalg.norm(omega0)) + 2.0 / top.t_g
    h, steps = _run(
        system, sim, y, horizon, omega, setting.invariant_step, SAMPLE["invariants"], observe
    )
    case = top.describe() | {"pi0": pi0.tolist(), "gamma0": gamma.tolist(), "h": h, "T": horizon}
    return worst, steps, case, omega


def heavy_top_checks(
    integrators, seed=0, n_tops=3, system_class=HeavyTop, progress=None, n_small=0
) -> list[Check]:
    """The heavy-top rows for each of ``integrators``: rbenvs integrator names (left out where
    the top does not offer what they need, as for ``exact``) or
    :class:`~rbenvs.verify.simulator.Simulator` objects at their own step, held to the settings
    of :func:`~rbenvs.verify.common.reference_scheme` scaled to it. ``system_class`` builds the
    system from the parameters (tests pass a deliberately broken one); ``n_small`` small fast
    tops add their threshold rows (``rbenvs verify``: :data:`SMALL_TOP_CASES`)."""
    tops = _random_cases(np.random.default_rng([seed, 2]), n_tops)
    small = _random_small_tops(np.random.default_rng([seed, 3]), n_small)
    checks: list[Check] = []
    for sim in as_simulators(integrators):
        if sim.dt is None:
            integ = sim.integrator
            if integ.name not in HEAVY_TOP_SETTINGS or not integ.supports(
                system_class((tops or small)[0].params)
            ):
                continue
            setting = HEAVY_TOP_SETTINGS[integ.name]
        else:
            setting = HEAVY_TOP_SETTINGS[reference_scheme(sim.order)]
        rows: dict[str, list[Check]] = {}

        def add(check):  # (called within this iteration: its own rows)
            rows.setdefault(check.check, []).append(check)  # noqa: B023

        try:
            for top in tops:
                checks_for_top(system_class(top.params), sim, setting, top, add)
                if progress:
                    progress()
            for top in small:
                threshold_checks(system_class(top.params), sim, setting, top, add)
                if progress:
                    progress()
        except NotImplementedError as exc:
            checks.extend(
                not_applicable(SYSTEM, sim.name, ROWS + (SMALL_ROWS if small else ()), str(exc))
            )
            continue
        checks.extend(worst(c) for c in rows.values())
    return checks


ROWS = (
    "critical spin by bisection [rad/s]",
    "upright at 1.2 x critical: max tilt [rad] from 1e-3",
    "upright at 0.5 x critical: growth rate [1/s]",
    "regular precession held: max |tilt - alpha| [rad]",
    "regular precession: mean rate [rad/s]",
    "fast top: nutation amplitude [rad]",
    "fast top: nutation period [s]",
    "fast top: mean precession rate [rad/s]",
    "energy drift (rel.)",
    "Pi.Gamma drift (rel. to |Pi|)",
    "| |Gamma| - 1 |",
)
SMALL_ROWS = (
    "small fast top: critical spin by bisection [rad/s]",
    f"small fast top at {ABOVE_CRITICAL:g} x critical: max tilt [rad] from 1e-3",
    f"small fast top at {SMALL_BELOW:g} x critical: growth rate [1/s]",
)


def threshold_checks(system, sim, setting, top, add, rows=SMALL_ROWS, slow=SMALL_BELOW):
    """The threshold's rows (``rows``: their names): the critical spin by bisection, stable at
    1.2 x critical (max tilt), unstable at ``slow`` x critical (the growth rate of the theorem's
    eigenvalue). A small fast top's by default."""
    name = sim.name
    base = top.describe()
    n_c = critical_spin(*top.oracle_args())
    measured, info = _bisect_critical_spin(system, sim, setting, top)
    add(
        Check(
            SYSTEM,
            name,
            rows[0],
            n_c,
            measured,
            0.01,
            relative=True,
            case=base
            | info
            | {"start tilt": START_TILT, "fall tilt": FALL_TILT, "T": HORIZON * top.t_g},
        )
    )
    spin = ABOVE_CRITICAL * n_c
    worst_tilt, h = _upright_max_tilt(system, sim, setting, top, spin)
    add(
        Check(
            SYSTEM,
            name,
            rows[1],
            0.0,
            worst_tilt,
            STABLE_BOUND,
            case=base | {"spin": spin, "h": h, "T": HORIZON * top.t_g},
        )
    )
    spin = slow * n_c
    sigma = float(np.max(upright_eigenvalues(*top.oracle_args(), spin).real))
    rate, h = _upright_growth_rate(system, sim, setting, top, spin)
    add(
        Check(
            SYSTEM,
            name,
            rows[2],
            sigma,
            rate,
            0.02,
            relative=True,
            case=base | {"spin": spin, "h": h},
        )
    )


def checks_for_top(system, sim, setting, top, add):
    name = sim.name
    threshold_checks(system, sim, setting, top, add, rows=ROWS[:3], slow=0.5)

    p, held, mean_rate, case, (tol_held, tol_rate) = _regular_precession(system, sim, setting, top)
    add(Check(SYSTEM, name, ROWS[3], 0.0, held, tol_held, case=case))
    add(Check(SYSTEM, name, ROWS[4], p, mean_rate, tol_rate, relative=True, case=case))

    oracle, (amplitude, period, rate), case = _fast_top(system, sim, setting, top)
    eps, n, h = oracle.expansion_parameter, case["spin"], case["h"]
    drift = (n * h) * (n * oracle.period) * math.cos(case["tilt"]) / (4.0 * eps)
    # the formulas' 5 eps, plus a first-order scheme's drift: at most what a rate may be off by
    tol = NUTATION_TOL * eps + min(setting.nutation_drift * drift, RATE_TOL)
    add(
        Check(
            SYSTEM, name, ROWS[5], oracle.angle_amplitude, amplitude, tol, relative=True, case=case
        )
    )
    add(Check(SYSTEM, name, ROWS[6], oracle.period, period, tol, relative=True, case=case))
    add(
        Check(
            SYSTEM, name, ROWS[7], oracle.mean_precession_rate, rate, tol, relative=True, case=case
        )
    )

    (d_energy, d_casimir, d_norm), steps, case, omega = _invariants(system, sim, setting, top)
    round_off = ROUND_OFF * steps**0.5
    tol_energy = _tolerance(
        sim, setting.energy, setting.invariant_step, omega, case["h"], steps, ENERGY_BOUND
    )
    if sim.dt is None:
        tol_casimir, tol_norm = (
            (round_off if setting.casimir is None else setting.casimir),
            round_off,
        )
    else:  # |Gamma| is a Casimir as Pi.Gamma is: a simulator that does not keep it is held alike
        tol_casimir = tol_norm = _tolerance(
            sim, setting.casimir, setting.invariant_step, omega, case["h"], steps, MOMENTUM_BOUND
        )
    add(Check(SYSTEM, name, ROWS[8], 0.0, d_energy, tol_energy, case=case))
    add(Check(SYSTEM, name, ROWS[9], 0.0, d_casimir, tol_casimir, case=case))
    add(Check(SYSTEM, name, ROWS[10], 0.0, d_norm, tol_norm, case=case))

"""Every integrator's verify settings, per system, in one place: the steps each runs at and the
tolerances each is held to (a new scheme adds its rows here; `rbenvs verify`
reports a registered scheme without them). The reasons for each figure stand beside it.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "FREE_BODY_SETTINGS",
    "FAST_TUMBLE_SETTINGS",
    "TopSetting",
    "HEAVY_TOP_SETTINGS",
    "REGIMES",
    "TippeSetting",
    "TIPPE_TOP_SETTINGS",
]


# ------------------------------------------------------------------------------------------
# the free body (rbenvs.verify.free_body)

# Step sizes per integrator (s) for |Omega| ~ 1 rad/s, and the accuracy each is held to over
# the exact-solution horizon. The tolerances follow the order: error ~ (|Omega| h)^p |Omega| T.
FREE_BODY_SETTINGS = {
    #            h      exact-solution tol  invariant tol
    "euler": (2e-4, 2e-2, 2e-2),  # first order: ~ |Omega|^2 h T = 2e-3..1e-2
    "rk4": (2e-2, 1e-6, 1e-7),  # (|Omega| h)^4 |Omega| T ~ 2e-6 * 10 / 30 (small constant)
    "splitting": (5e-3, 1e-3, 1e-4),  # (|Omega| h)^2 |Omega| T ~ 2.5e-4; |Pi| exact
    "exact": (0.1, 1e-11, 1e-12),  # round-off
    "dop853": (1.0, 1e-9, 1e-10),  # rtol 1e-12 per unit time
}


FAST_TUMBLE_SETTINGS = {
    #            omega h  exact tol  invariant tol
    "euler": (5e-4, 2e-2, 2e-2),
    "rk4": (2e-2, 1e-7, 1e-8),
    "splitting": (1e-2, 1e-2, 1e-4),
    "exact": (0.1, 1e-9, 1e-12),
    "dop853": (1.0, 1e-9, 1e-10),
}


# ------------------------------------------------------------------------------------------
# the heavy top (rbenvs.verify.heavy_top)


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


# ------------------------------------------------------------------------------------------
# the tippe top (rbenvs.verify.tippe_top)

REGIMES = ("below", "inside", "above")


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
#   J's 0.1 is above MOMENTUM_BOUND (2%, rbenvs.verify.common): at this step the worst comes
#   within 10% of the bound, and a step that holds it with a margin costs three times as much.
# Settling:
#   omega_h = 0.03, inside the window and alpha <= 0.3 only. Euler turns every rotating vector
#   outward, a growth rate ~ w^2 h / 2 for a vector turning at w, faster than friction damps
#   the final states: a top below the window (w = |C/A - 1| n, up to 0.8 n) nods ever wider and
#   hops, a partially inverted one precesses where friction hardly dissipates, and near alpha
#   0.4 the climb itself hops. Inside the window at alpha <= 0.3 euler settles every top tried
#   (J drifts, but the final tilt of a full inversion does not depend on J).
# * rk4 (order 4), omega_h = 0.1: local error (Omega h)^5/120 < 1e-7 per step. J 1e-6 [1.4e-8
#   without table motion, 7.4e-8 with], energy 1e-7 [3.0e-9], rise 1e-8 [0: never rose].
# * dop853 at rtol 1e-12 (atol 1e-14), sampled every t_g/2: 100 x rtol: J and energy 1e-10
#   [1.4e-12, 7.4e-13], rise 1e-11 [0]. Coulomb friction regularised at 0.1 sqrt(g R) (DOP853_SLIP):
#   a sharper one is stiff enough to cost dop853 far more evaluations. Settling at rtol 1e-8.
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

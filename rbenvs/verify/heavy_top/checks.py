"""The heavy top's rows: the critical spin, the upright top's growth, regular precession, the
fast top, the invariants and the small fast tops' thresholds."""

from __future__ import annotations

import math

import numpy as np

from ...dynamics import HeavyTop
from ...oracles import (
    critical_spin,
    fast_top_nutation,
    regular_precession_rates,
    upright_eigenvalues,
)
from ..common import (
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
from ..protocol import batched
from ..settings import HEAVY_TOP_SETTINGS
from ..simulator import advance, as_simulators, start
from .settings import (
    ABOVE_CRITICAL,
    BISECTION_WIDTH,
    BRACKET,
    FALL_TILT,
    HORIZON,
    INVARIANT_HORIZON,
    NUTATION_TOL,
    SAMPLE,
    SMALL_BELOW,
    STABLE_BOUND,
    START_TILT,
    SYSTEM,
    _lagrange_state,
    _random_cases,
    _random_small_tops,
)

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

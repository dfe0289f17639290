"""The inversion rows: settling runs against the inversion criterion, the time to pass 90
degrees, and Jellett's integral through an inversion."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ...dynamics import TippeTop, TippeTopParams
from ...integrators import get_integrator
from ...oracles import final_tilt, inversion_criterion
from ..common import (
    MOMENTUM_BOUND,
    ROUND_OFF,
    Check,
    not_applicable,
    reference_scheme,
    scaled_tolerance,
)
from ..simulator import as_simulators, start
from .settings import (
    CLASS_BOUNDS,
    CLASS_CODE,
    DOP853_SETTLE_SAMPLE,
    FINAL_TILT_TOL,
    SETTLE_BAND,
    SETTLE_HORIZON,
    SETTLE_SAMPLE,
    SETTLE_SLIP,
    SETTLE_WINDOW,
    START_TILT,
    SYSTEM,
    T90_ORDER_TOL,
    T90_TOL,
    _step_size,
    _tilted_attitude,
    oracle_jellett,
)

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
    y = upright_start(system, spin)
    J0, scale = oracle_jellett(system, y)
    sampling = _settle_sampling(system, integ, spin, omega_h, rtol)
    end = _settle_run(system, start(sampling.sim, system, y), y, sampling, spin, horizon)
    J1, _ = oracle_jellett(system, end.y)
    return Settled(
        float(end.tilts[-1]) if end.lift_off is None else math.nan,
        end.settled,
        end.samples * sampling.sample,
        end.min_normal,
        float(abs(J1 - J0) / scale),
        sampling.h,
        end.t90,
        end.lift_off,
        end.tilts if record else [],
    )


@dataclass(frozen=True)
class _Sampling:
    """How a settling run steps: ``sim`` takes ``every`` steps of ``h`` [s] per sample, every
    ``sample`` [s] (``sample_tg`` t_g)."""

    sim: object
    h: float
    every: int
    sample: float
    sample_tg: float


@dataclass(frozen=True)
class _SettleEnd:
    """Where a settling run stopped: the state ``y`` after ``samples`` samples, the tilts sampled,
    the lowest ``N/(m g)``, whether it settled, and the times of passing 90 degrees and of the
    lift-off (``None``: none)."""

    y: tuple
    samples: int
    tilts: list
    min_normal: float
    settled: bool
    t90: float | None
    lift_off: float | None


def _settle_sampling(system, integ, spin, omega_h, rtol) -> _Sampling:
    """The simulator and steps of a settling run (:func:`settle`'s arguments): dop853 one call a
    sample, a simulator at its own step whole steps a sample, a fixed-step scheme at ``omega_h``
    (the sample a whole number of its steps)."""
    prm = system.params
    t_g = math.sqrt(prm.radius / prm.gravity)
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
    return _Sampling(sim, h, every, sample, sample_tg)


def _settle_run(system, run, y, sampling, spin, horizon) -> _SettleEnd:
    """Step ``run`` from ``y``, sample by sample, until settled, a lift-off (``N < 0``, or a state
    that is not finite) or ``horizon`` t_g."""
    prm = system.params
    per_window = int(round(SETTLE_WINDOW / sampling.sample_tg))
    n_samples = int(math.ceil(horizon / sampling.sample_tg))
    weight = prm.mass * prm.gravity
    tilts = [system.tilt(y)]
    min_n = float(system.contact_forces(y)[0]) / weight
    settled = False
    t90 = lift_off = None
    k = 0
    for k in range(1, n_samples + 1):
        for _ in range(sampling.every):
            y = run.step(None, sampling.h)
        tilt = system.tilt(y)
        if t90 is None and tilt > 0.5 * math.pi:
            t90 = k * sampling.sample
        tilts.append(tilt)
        n_now = float(system.contact_forces(y)[0]) / weight
        min_n = n_now if not n_now >= 0.0 else min(min_n, n_now)  # a nan is kept
        if not min_n >= 0.0:  # the top would leave the table (or the state is not finite): stop
            lift_off = k * sampling.sample
            break
        if k % per_window == 0 and _window_settled(system, y, tilts[-per_window - 1 :], spin):
            settled = True
            break
    return _SettleEnd(y, k, tilts, min_n, settled, t90, lift_off)


def _window_settled(system, y, last, spin) -> bool:
    """Whether the tilts ``last`` of a window stay within ``SETTLE_BAND`` and the contact point
    at ``y`` barely slips."""
    calm = max(last) - min(last) < SETTLE_BAND
    return calm and system.slip_speed(y) < SETTLE_SLIP * system.params.radius * abs(spin)


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


# the inversion rows' name of each regime of A/C
_REGIME_RANGES = {
    "below": "A/C < 1 - alpha",
    "inside": "1 - alpha < A/C < 1 + alpha",
    "above": "A/C > 1 + alpha",
}


def _inversion_rows(sim, setting, tops, system_class, progress):
    """The class and final-tilt rows of a settling run of each of ``tops``, by row (``c`` and
    ``t`` with the regime); ``progress`` called once a run."""
    rows: dict[str, list[Check]] = {}
    for top in tops:
        ran, (class_row, tilt_row) = _top_inversion_checks(sim, setting, top, system_class)
        rows.setdefault(f"c{top.regime}", []).append(class_row)
        rows.setdefault(f"t{top.regime}", []).append(tilt_row)
        if ran and progress:  # (a run the simulator declines counts none)
            progress()
    return rows


def _top_inversion_checks(sim, setting, top, system_class) -> tuple[bool, tuple[Check, Check]]:
    """``(ran, (class row, final-tilt row))`` of ``top``'s settling run against the criterion's
    prediction; the rows n/a (``ran`` false) where the simulator does not model the run."""
    params = top.params()
    system = system_class(params, "gliding")
    J0 = float(oracle_jellett(system, upright_start(system, top.spin))[0])
    label, tilt = prediction(params, J0)
    what = _REGIME_RANGES[top.regime]
    names = (
        f"inversion class, {what} (0 none, 1 partial, 2 full)",
        f"final tilt [deg] = argmin E*, {what}",
    )
    try:
        res = settle(system, sim, top.spin, setting.settle_step, setting.settle_rtol)
    except NotImplementedError as exc:
        reason = f"viscous friction (the settling runs'): {exc}"
        class_na, tilt_na = not_applicable(SYSTEM, sim.name, names, reason)
        return False, (class_na, tilt_na)
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
    class_row = Check(
        SYSTEM, sim.name, names[0], CLASS_CODE[label], CLASS_CODE.get(got, math.nan), 0.0, case=case
    )
    tilt_row = Check(
        SYSTEM,
        sim.name,
        names[1],
        math.degrees(tilt),
        math.degrees(res.tilt),
        math.degrees(FINAL_TILT_TOL),
        case=case,
    )
    return True, (class_row, tilt_row)


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

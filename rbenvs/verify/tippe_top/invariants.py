"""The invariant rows: energy, Jellett's integral and the constraint kept along random states'
runs."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..common import (
    ENERGY_BOUND,
    MOMENTUM_BOUND,
    Check,
    not_applicable,
    scaled_tolerance,
)
from ..simulator import start
from .settings import (
    DOP853_SLIP,
    INVARIANT_HORIZON,
    INVARIANT_SAMPLE,
    MAX_DRAWS,
    SHORT_HORIZON,
    SYSTEM,
    _step_size,
    _tilted_attitude,
    oracle_jellett,
)

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
    samples = tuple(np.array(v) for v in (js, scales, energies, normals))
    return (*samples, h, lift_off, (omega * h, int(round(t / h))))


def _invariant_rows(sim, setting, tops, rng, n_states, system_class, progress):
    """The invariant rows of every variant (:data:`VARIANTS`) on each of ``tops``, by row name,
    ``n_states`` random states each; ``progress`` called once a top."""
    rows: dict[str, list[Check]] = {}
    for top in tops:
        for variant in VARIANTS:
            for check in _variant_checks(sim, setting, top, variant, rng, n_states, system_class):
                rows.setdefault(check.check, []).append(check)
        if progress:
            progress()
    return rows


def _is_dop853(sim) -> bool:
    """Whether ``sim`` is rbenvs' dop853 at its verify settings."""
    return sim.dt is None and sim.integrator.name == "dop853"


def _variant_system(sim, top, variant, rng, system_class):
    """``(params, system)`` of ``top`` under ``variant``, its friction coefficient drawn."""
    mu = None
    if variant.law == "coulomb":
        mu = float(rng.uniform(0.2, 0.5))
    elif variant.law == "viscous":
        mu = float(rng.uniform(0.1, 0.5)) / math.sqrt(top.gravity * top.radius)
    params = top.params(variant.law or "viscous", mu if mu is not None else 0.0)
    if _is_dop853(sim) and variant.law == "coulomb":  # ~50x less stiff near zero slip
        params = dataclasses.replace(
            params, slip_regularization=DOP853_SLIP * math.sqrt(top.gravity * top.radius)
        )
    return params, system_class(params, variant.fidelity)


def _variant_checks(sim, setting, top, variant, rng, n_states, system_class) -> list[Check]:
    """The rows of ``variant`` on ``top``, in order: those of ``n_states`` random states, or its
    n/a rows where the simulator does not model it."""
    params, system = _variant_system(sim, top, variant, rng, system_class)
    u_of, motion = _table_motion(rng, top) if variant.moving else (None, {})
    short = _is_dop853(sim) or variant.law == "coulomb"
    horizon = (SHORT_HORIZON if short else INVARIANT_HORIZON) * top.t_g
    slip = variant.fidelity == "gliding"
    out: list[Check] = []
    for n in range(n_states):
        try:
            desc, result = _draw_run(sim, setting, rng, top, system, slip, horizon, u_of)
        except NotImplementedError as exc:
            # not modelled: n/a rows, the remaining states drawn as for the others (the draws
            # that follow stay the same)
            for _ in range(n + 1, n_states):
                _random_states(rng, top, system, 1, slip=slip)
            out.extend(
                not_applicable(SYSTEM, sim.name, _variant_rows(variant), f"{variant.label}: {exc}")
            )
            break
        case = _invariant_case(top, variant, params, horizon, desc | motion, result)
        out.extend(_state_checks(sim, setting, variant, case, result))
    return out


def _draw_run(sim, setting, rng, top, system, slip, horizon, u_of):
    """A random state's description and its run (:func:`_run_invariants`); a state that lifts off
    before its second sample is drawn again, up to ``MAX_DRAWS`` times."""
    for _ in range(MAX_DRAWS):
        (y,), (desc,) = _random_states(rng, top, system, 1, slip=slip)
        result = _run_invariants(system, sim, setting, y, horizon, u_of)
        if len(result[0]) >= 2:
            break
    return desc, result


def _invariant_case(top, variant, params, horizon, start, result) -> dict:
    """The case of a run: the top, the variant, the step and horizon, the ``start`` (the state's
    and the table's description), the lowest normal force and the lift-off."""
    _, _, _, normals, h, lift_off, _ = result
    case = (
        top.describe()
        | {
            "fidelity": variant.fidelity,
            "friction_law": variant.law,
            "friction": params.friction,
            "h": h,
            "T": horizon,
        }
        | start
    )
    case["min N/(m g)"] = float(np.min(normals)) if len(normals) else math.nan
    case["lift-off at"] = lift_off
    return case


def _state_checks(sim, setting, variant, case, result) -> list[Check]:
    """One state's rows of ``variant``: Jellett's drift, and the energy's rise (dissipative) or
    drift (conservative; none on the moving table, which works on the top)."""
    js, scales, energies, _, _, _, run = result
    if len(js) < 2:  # MAX_DRAWS states in a row lifted off at once: a FAIL row (nan)
        js = scales = energies = np.full(2, math.nan)
    drift = float(np.max(np.abs(js - js[0])) / scales[0])
    jellett_row, energy_row = _variant_rows(variant) + ((None,) if variant.moving else ())
    out = [
        Check(
            SYSTEM,
            sim.name,
            jellett_row,
            0.0,
            drift,
            _tolerance(sim, setting, setting.jellett, run, MOMENTUM_BOUND),
            case=case,
        )
    ]
    if variant.dissipative:
        rise = float(np.max(np.append(np.diff(energies), 0.0)) / energies[0])  # nan stays nan
        tol = _tolerance(sim, setting, setting.rise, run, ENERGY_BOUND)
        out.append(Check(SYSTEM, sim.name, energy_row, 0.0, rise, tol, case=case))
    elif not variant.moving:
        change = float(np.max(np.abs(energies - energies[0])) / energies[0])
        tol = _tolerance(sim, setting, setting.energy, run, ENERGY_BOUND)
        out.append(Check(SYSTEM, sim.name, energy_row, 0.0, change, tol, case=case))
    return out


def _tolerance(sim, setting, tol, run, bound):
    """The setting's tolerance ``tol``; for a simulator at its own step, scaled to it (``run``:
    ``omega h`` and the number of steps), at most ``bound``."""
    if sim.dt is None:
        return tol
    return scaled_tolerance(tol, run[0], setting.invariant_step, sim.order, run[1], bound)


def _variant_rows(variant) -> tuple[str, ...]:
    """The names of a friction law's rows: Jellett's and (but on the moving table) the energy's."""
    rows = (f"Jellett held ({variant.label}): max |dJ| / (|L| (R+h))",)
    if variant.dissipative:
        rows += (f"energy non-increasing ({variant.label}): max rise / E0",)
    elif not variant.moving:
        rows += (f"energy conserved ({variant.label}): max |dE| / E0",)
    return rows

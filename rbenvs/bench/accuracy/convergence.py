"""The cases and the measurements of ``rbenvs bench accuracy``: each integrator's error against a
reference, its order, its invariants' drift and its cost, per system."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ...integrators import get_integrator
from ...integrators.reference import REFERENCE, Dop853
from ..throughput import timed

FIT_FLOOR = {"exact": 1e-12, "dop853": 1e-10}  # by the reference's kind
FIT_CEILING = 1e-2
DIVERGED = 1.0  # relative drift past which a long run stops
TARGET = 1e-6  # scenes: worst relative state error over an episode
TIPPE_HORIZON = 1.0  # s, the tippe-top scenes' checked horizon
SCENE_SEEDS = 3
MAX_SUBSTEPS = 64
SAVING = 0.8  # a scene that meets the target changes only for a pair costing less than this share


@dataclass(frozen=True)
class Case:
    """One system with its start states, horizon, step grids and drift runs."""

    key: str
    label: str
    integrators: tuple[str, ...]
    horizon: float  # T [s] of the error
    grid: tuple[float, ...]  # steps h [s]
    euler_grid: tuple[float, ...]  # euler needs far smaller steps for the same error
    drift_h: float
    long_steps: dict  # per integrator, (quick, full)
    batched: bool  # states as arrays (else float by float)


CASES = (
    Case(
        "free_body",
        "free body (2, 1.5, 1), |Omega| = 1 rad/s",
        ("euler", "rk4", "splitting", "exact", "dop853"),
        10.0,
        tuple(0.2 / 2**k for k in range(6)),
        tuple(0.0125 / 2**k for k in range(6)),
        0.05,
        {
            "euler": (10**4, 10**6),
            "rk4": (10**4, 10**6),
            "splitting": (10**4, 10**6),
            "exact": (2000, 10**5),
            "dop853": (10**3, 10**4),
        },
        True,
    ),
    Case(
        "heavy_top",
        "Lagrange top, |Omega| 5-20 rad/s",
        ("euler", "rk4", "splitting", "dop853"),
        2.0,
        tuple(0.02 / 2**k for k in range(6)),
        tuple(5e-5 / 2**k for k in range(4)),
        0.02,
        {
            "euler": (10**4, 10**5),
            "rk4": (10**4, 10**5),
            "splitting": (10**4, 10**5),
            "dop853": (10**3, 10**3),
        },
        True,
    ),
    Case(
        "tippe_top",
        "tippe top, viscous friction 3 s/m, 150 rad/s",
        ("euler", "rk4"),
        0.2,
        tuple(1e-3 / 2**k for k in range(5)),
        tuple(1e-5 / 2**k for k in range(4)),
        0.01 / 15,
        {"euler": (10**4, 10**5), "rk4": (10**4, 10**5)},
        False,
    ),
    Case(
        "tippe_frictionless",
        "tippe top, frictionless, 150 rad/s",
        ("euler", "rk4"),
        0.2,
        tuple(1e-3 / 2**k for k in range(5)),
        tuple(1e-5 / 2**k for k in range(4)),
        0.01 / 15,
        {"euler": (10**4, 10**5), "rk4": (10**4, 10**5)},
        False,
    ),
)
QUICK_POINTS = 4  # grid points per integrator with --quick


# ------------------------------------------------------------------------------------ setup
def _setup(key):
    """``(system, y0, invariants)``: the system, the start states as a tuple of ``(n,)`` arrays,
    and ``{name: (function, scale)}`` with the scale of each invariant's relative drift."""
    rng = np.random.default_rng(0)
    if key == "free_body":
        from ...dynamics import FreeBody, FreeBodyParams

        inertia = np.array([2.0, 1.5, 1.0])
        system = FreeBody(FreeBodyParams(tuple(inertia)))
        omega = rng.standard_normal((3, 8))
        y0 = tuple(omega / np.linalg.norm(omega, axis=0) * inertia[:, None])
        inv = {
            "energy": (system.energy, system.energy(y0)),
            "|Pi|": (system.momentum_norm, system.momentum_norm(y0)),
        }
        return system, y0, inv
    if key == "heavy_top":
        from ...dynamics import HeavyTop, HeavyTopParams

        prm = HeavyTopParams()
        system = HeavyTop(prm)
        a, c = prm.inertia[0], prm.inertia[2]
        gamma = rng.standard_normal((3, 8))
        gamma /= np.linalg.norm(gamma, axis=0)
        omega = rng.standard_normal((3, 8))
        omega *= (
            rng.uniform(1.0, 4.0, 8) * math.sqrt(prm.mgl * a) / c / np.linalg.norm(omega, axis=0)
        )
        y0 = tuple(omega * np.array(prm.inertia)[:, None]) + tuple(gamma)
        pi_norm = np.linalg.norm(np.array(y0[:3]), axis=0)
        kinetic = system.energy(y0[:3] + (0.0 * gamma[0],) * 3)  # Gamma = 0: no potential
        inv = {
            "energy": (system.energy, kinetic + prm.mgl),
            "Pi.Gamma": (system.pi_dot_gamma, pi_norm),
            "|Gamma|": (system.vertical_norm, 1.0),
        }
        return system, y0, inv
    # the tippe top: the tippe_viscous scene's reset states
    from ...envs import TippeTopEnv
    from ...verify.tippe_top import oracle_jellett

    fidelity = "frictionless" if key == "tippe_frictionless" else "gliding"
    states = []
    for seed in range(4):
        env = TippeTopEnv(friction_law="viscous", friction=3.0, fidelity=fidelity)
        env.reset(seed=seed)
        states.append(env.state_components)
    system = env.system
    y0 = tuple(np.array(c) for c in zip(*states))
    inv = {"jellett": (lambda y: oracle_jellett(system, y)[0], oracle_jellett(system, y0)[1])}
    if fidelity == "frictionless":
        inv = {"energy": (system.energy, system.energy(y0))} | inv
    return system, y0, inv


def _state(y0, i):
    return tuple(float(c[i]) for c in y0)


def _n_states(y0):
    return len(y0[0])


def _blocks(system, key):
    return [
        (a, b)
        for name, (a, b) in system.layout.items()
        if not (key.startswith("tippe") and name == "position")
    ]


def _block_error(system, key, y, ref, y0):
    """Worst over states and blocks of ``|y_b - ref_b| / max(|ref_b|, |y0_b|)``; a block that is
    zero in the start and the reference (a tippe top's ``v_G`` from rest without friction) counts
    0 where the state keeps it zero too, and ``inf`` where it does not."""
    y, ref, y0 = (np.array(v, dtype=float) for v in (y, ref, y0))
    err = 0.0
    for a, b in _blocks(system, key):
        scale = np.maximum(np.linalg.norm(ref[a:b], axis=0), np.linalg.norm(y0[a:b], axis=0))
        diff = np.linalg.norm(y[a:b] - ref[a:b], axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            e = np.where(
                scale > 0.0,
                diff / np.where(scale > 0.0, scale, 1.0),
                np.where(diff == 0.0, 0.0, np.inf),
            )
        err = max(err, float(np.max(np.where(np.isfinite(e), e, np.inf))))
    return err


CHECK = Dop853(rtol=1e-12, atol=1e-14)  # the reference's own error, estimated


def _reference(case, system, y0, integ=REFERENCE):
    """The state at ``T`` by the case's reference: exact for the free body, else DOP853."""
    if case.key == "free_body" and integ is REFERENCE:
        from ...oracles import exact_solution

        return tuple(exact_solution(system.params.inertia, np.array(y0), case.horizon))
    if case.batched:
        return integ.step(system, y0, None, case.horizon)
    out = [integ.step(system, _state(y0, i), None, case.horizon) for i in range(_n_states(y0))]
    return tuple(np.array(c) for c in zip(*out))


def _integrate(case, system, integ, y0, h, n):
    if case.batched:
        y = y0
        for _ in range(n):
            y = integ.step(system, y, None, h)
        return y
    out = []
    for i in range(_n_states(y0)):
        y = _state(y0, i)
        for _ in range(n):
            y = integ.step(system, y, None, h)
        out.append(y)
    return tuple(np.array(c) for c in zip(*out))


def _cost(system, integ, y0, h, min_time):
    """Seconds per step of one state on floats (best of 3) and rhs evaluations per step."""
    y = _state(y0, 0)
    seconds = timed(lambda: integ.step(system, y, None, h), min_time, 3)
    return seconds, int(integ.step_counted(system, y, None, h)[1])


def fit_order(hs, errors, floor, ceiling=FIT_CEILING):
    """Least-squares slope of ``log(error)`` against ``log(h)`` over the points with
    ``floor < error < ceiling``; ``None`` with fewer than 3 such points."""
    pts = [(h, e) for h, e in zip(hs, errors) if math.isfinite(e) and floor < e < ceiling]
    if len(pts) < 3:
        return None
    x, y = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    return float(np.polyfit(x, y, 1)[0])


def convergence(case, name, quick=False, min_time=0.05, progress=None, setup=None):
    """Error at ``T``, cost and fitted order of one integrator on one case."""
    system, y0, _ = setup or _setup(case.key)
    integ = get_integrator(name)
    ref = _reference(case, system, y0)
    grid = case.euler_grid if name == "euler" else case.grid
    if quick:
        grid = grid[:QUICK_POINTS]
    points = []
    for h in grid:
        n = int(round(case.horizon / h))
        with np.errstate(all="ignore"):
            y = _integrate(case, system, integ, y0, case.horizon / n, n)
        seconds, evals = _cost(system, integ, y0, case.horizon / n, min_time)
        points.append(
            {
                "h": case.horizon / n,
                "steps": n,
                "error": _block_error(system, case.key, y, ref, y0),
                "seconds_per_step": seconds,
                "rhs_per_step": evals,
                "seconds_per_simulated_second": seconds * n / case.horizon,
            }
        )
        if progress:
            progress()
    floor = FIT_FLOOR["exact" if case.key == "free_body" else "dop853"]
    order = (
        None
        if name in ("exact", "dop853")
        else fit_order([p["h"] for p in points], [p["error"] for p in points], floor)
    )
    return {
        "case": case.key,
        "integrator": name,
        "declared_order": integ.order,
        "order": order,
        "points": points,
    }


def drift(case, name, steps, setup=None, short=1000, samples=1000):
    """Largest relative change of each invariant over the first ``short`` steps and over
    ``steps`` steps at ``case.drift_h``; stops where it passes :data:`DIVERGED` or goes
    non-finite."""
    system, y0, invariants = setup or _setup(case.key)
    integ = get_integrator(name)
    h = case.drift_h
    start = {k: np.asarray(f(y0), dtype=float) for k, (f, _) in invariants.items()}
    every = max(1, steps // samples)
    checkpoints = sorted({k for k in range(every, steps + 1, every)} | {min(short, steps), steps})
    worst = {k: 0.0 for k in invariants}
    at_short = None
    diverged = None
    if case.batched:
        states = [y0]
    else:
        states = [_state(y0, i) for i in range(_n_states(y0))]
    done = 0
    t0 = time.perf_counter()
    with np.errstate(all="ignore"):
        for stop in checkpoints:
            for _ in range(stop - done):
                states = [integ.step(system, y, None, h) for y in states]
            done = stop
            y = states[0] if case.batched else tuple(np.array(c) for c in zip(*states))
            for k, (f, scale) in invariants.items():
                d = np.abs(np.asarray(f(y), dtype=float) - start[k]) / scale
                d = float(np.max(np.where(np.isfinite(d), d, np.inf)))
                worst[k] = max(worst[k], d)
            if done == min(short, steps):
                at_short = dict(worst)
            if max(worst.values()) > DIVERGED:
                diverged = done
                break
    elapsed = time.perf_counter() - t0
    return {
        "case": case.key,
        "integrator": name,
        "h": h,
        "short_steps": min(short, steps),
        "long_steps": steps,
        "drift_short": at_short,
        "drift_long": worst,
        "diverged_at": diverged,
        "seconds": elapsed,
    }

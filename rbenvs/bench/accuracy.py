"""``rbenvs bench accuracy``: speed against accuracy, per system and integrator, in one run.

Cases (one panel each in the figure; ``--system`` picks them):

* ``free_body``: the default body ``I = (2, 1.5, 1)`` kg m^2, 8 states of random direction with
  ``|Omega| = 1`` rad/s (seed 0). Reference: the exact elliptic solution
  (:func:`rbenvs.oracles.exact_solution`, one evaluation at ``T`` from the start).
* ``heavy_top``: the default Lagrange top (``I = (0.45, 0.45, 0.3)`` about the pivot, 1 kg,
  0.5 m), 8 states: ``Gamma`` uniform on the sphere, ``Omega`` of random direction with
  ``|Omega| ~ U(1, 4) sqrt(M g l A)/C`` (5 to 20 rad/s; the ranges of ``rbenvs verify``).
* ``tippe_top``: the ``tippe_viscous`` scene (Leine-Glocker top, viscous friction 3 s/m,
  150 rad/s at 0.1 rad tilt; its reset states for seeds 0-3). Viscous friction because it is
  not stiff: under the default regularised Coulomb law every explicit step is pinned to the
  stability bound (``|Omega| h ~ 1e-2``), where no order can be read.
* ``tippe_frictionless``: the same states at the ``frictionless`` fidelity (energy conserved).

The references of the last three: scipy's DOP853 at ``rtol = 1e-13``, ``atol = 1e-15``
(:data:`REFERENCE`; the registry's ``dop853`` runs at ``rtol = 1e-12``), one solve from the
start to ``T``; ``ref. check`` in the output is its distance from the same solve at
``rtol = 1e-12``, which bounds what the orders are read above.

Measured per case and integrator:

* ``error``: after ``T`` (:data:`CASES`), the worst over the states and the named blocks of the
  state (``system.layout``; the tippe top's horizontal position is left out: it does not feed
  back into the motion) of ``|y_b - ref_b| / max(|ref_b|, |y0_b|)``, on a grid of steps ``h``.
* ``order``: the slope of ``log(error)`` against ``log(h)`` (least squares) over the grid points
  whose error lies in ``(FIT_FLOOR, FIT_CEILING)``: above the reference's error and in the
  asymptotic range. ``exact`` is at round-off at every ``h``: no order is fitted.
* ``cost``: seconds per step of one state on plain floats (as a single env steps it; best of
  several timings, this machine), and rhs evaluations per step from ``step_counted``
  (``dop853``: the real count of that step; ``splitting`` and ``exact`` evaluate exact flows,
  no rhs). The figure plots the error against the seconds per simulated second
  (``cost / h``).
* ``drift``: each invariant's largest change from its start over the first ``1e3`` steps and
  over a long run (``long`` steps, printed) at the case's ``drift h`` (the envs' own step), all
  states batched as arrays (the tippe top as floats, state by state: cheaper below ~25 states).
  Relative to: the energy ``E0`` (the heavy top: ``|kinetic| + M g l``), ``|Pi0|`` for ``|Pi|``
  and ``Pi.Gamma``, 1 for ``|Gamma|``, ``|L| (R + h)`` for Jellett's integral. A run that
  passes a drift of 1 (100%) or goes non-finite stops there: ``diverged at step k``.

MuJoCo (``--mujoco``, on when the ``mujoco`` extra is installed): the free-body case as a
free-floating body with the same principal moments and zero gravity, under MuJoCo's ``Euler``,
``RK4``, ``implicit`` and ``implicitfast`` integrators, on the same grids and states
(:func:`mujoco_free_body`; its long run is 1e5 steps, state by state).

``--quick`` runs shorter grids and long runs (CI); ``--json PATH`` writes every figure;
``--tolerance`` runs only the table of ``tolerance=`` (:mod:`rbenvs.bench.tolerance`);
``--roundoff`` only the roundoff floor near the free body's intermediate axis
(:mod:`rbenvs.bench.roundoff`); ``--floor`` only ``tolerance_check`` on that floor
(:mod:`rbenvs.bench.floor`);
``--plot PATH.png`` draws the work-precision figure (needs matplotlib, the ``plot`` extra).

Scenes (``--scenes``, on by default, off with ``--quick``): for every scene in
``configs/scenes``, each integrator the env takes (but ``dop853``, the reference) at
``substeps = 1, 2, 4, ...`` (the scene's ``dt`` kept: it is the control period, part of the
task): the env itself is stepped (``env.unwrapped.step``, past any termination) with the same
seeded random actions as an env built with the reference integrator, from the scene's reset
states (seeds 0 to 2); error = the worst over the episode and the seeds of the per-block
relative error (relative to the block's largest norm along the reference). Cost = one env
step, measured. :data:`TARGET` is the accuracy asked for; the cheapest pair meeting it is the
recommendation (a scene that already meets it changes only for a pair at most :data:`SAVING`
of its cost: smaller savings are within the timing noise). The tippe top's scenes are checked over
their first :data:`TIPPE_HORIZON` seconds (their reference costs ~10 s per simulated second under
Coulomb friction).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
import warnings
from dataclasses import dataclass

import numpy as np

from ..extras import ArgumentParser, require
from ..integrators import get_integrator
from ..integrators.reference import REFERENCE, Dop853
from ..progress import Progress
from ..render.common import plot_unavailable
from .throughput import episode_stepper, timed

__all__ = [
    "CASES",
    "REFERENCE",
    "TARGET",
    "Case",
    "run",
    "run_scenes",
    "fit_order",
    "convergence",
    "drift",
    "mujoco_free_body",
    "print_report",
    "print_scenes",
    "plot",
    "main",
]

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
        from ..dynamics import FreeBody, FreeBodyParams

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
        from ..dynamics import HeavyTop, HeavyTopParams

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
    from ..envs import TippeTopEnv
    from ..verify.tippe_top import oracle_jellett

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
        from ..oracles import exact_solution

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


def run(systems=None, quick=False, progress=None, min_time=None, mujoco=True) -> dict:
    """Convergence and drift of every case in ``systems`` (default all); with ``mujoco`` (and
    the package installed) MuJoCo's integrators on the free body too."""
    cases = [c for c in CASES if systems is None or c.key in systems]
    min_time = (0.02 if quick else 0.1) if min_time is None else min_time
    result = {"cases": {}, "convergence": [], "drift": []}
    for case in cases:
        setup = _setup(case.key)
        system, y0, _ = setup
        ref = _reference(case, system, y0)
        if case.key == "free_body":
            check = None  # the exact solution: nothing to check it against but round-off
        else:
            check = _block_error(system, case.key, _reference(case, system, y0, CHECK), ref, y0)
        result["cases"][case.key] = {
            "label": case.label,
            "horizon": case.horizon,
            "states": _n_states(y0),
            "drift_h": case.drift_h,
            "reference": "exact elliptic solution"
            if case.key == "free_body"
            else f"dop853 rtol={REFERENCE.rtol:g} atol={REFERENCE.atol:g}",
            "reference_check": check,
        }
        for name in case.integrators:
            result["convergence"].append(
                convergence(
                    case, name, quick=quick, min_time=min_time, progress=progress, setup=setup
                )
            )
            result["drift"].append(
                drift(case, name, case.long_steps[name][0 if quick else 1], setup=setup)
            )
            if progress:
                progress()
        if case.key == "free_body" and mujoco:
            conv, drifts = mujoco_free_body(quick=quick, min_time=min_time)
            result["convergence"] += conv
            result["drift"] += drifts
    return result


# ------------------------------------------------------------------------------------ MuJoCo
MUJOCO_INTEGRATORS = {
    "Euler": 1,
    "RK4": 4,
    "implicit": 1,
    "implicitfast": 1,
}  # MuJoCo's, with their orders


def mujoco_free_body(quick=False, min_time=0.1):
    """The free-body case in MuJoCo (the ``mujoco`` extra): a free-floating body with the same
    principal moments and zero gravity, the same start states (``Omega = I^-1 Pi`` as the free
    joint's body-frame angular velocity), each MuJoCo integrator on the same grid; ``Pi = I
    Omega`` at ``T`` against the exact solution, and the energy and ``|Pi|`` drift at the case's
    ``drift h`` over 1e3 steps and 1e5 (1e4 with ``quick``). Empty if mujoco is not installed."""
    try:
        import mujoco
    except ImportError:
        return [], []
    from ..oracles import exact_solution

    case = CASES[0]
    system, y0, invariants = _setup(case.key)
    inertia = np.array(system.params.inertia)
    pi0 = np.array(y0)
    ref = np.array(exact_solution(tuple(inertia), pi0, case.horizon))

    def model(integrator, h):
        xml = (
            f'<mujoco><option gravity="0 0 0" integrator="{integrator}" '
            f'timestep="{float(h)!r}"/><worldbody><body><freejoint/>'
            f'<inertial pos="0 0 0" mass="1" diaginertia="{float(inertia[0])!r} '
            f'{float(inertia[1])!r} {float(inertia[2])!r}"/></body></worldbody></mujoco>'
        )
        m = mujoco.MjModel.from_xml_string(xml)
        return m, mujoco.MjData(m)

    def start(m, d, i):
        mujoco.mj_resetData(m, d)
        d.qvel[3:6] = pi0[:, i] / inertia

    conv, drifts = [], []
    for name, order in MUJOCO_INTEGRATORS.items():
        grid = case.euler_grid if order == 1 else case.grid
        grid = grid[:QUICK_POINTS] if quick else grid
        points = []
        for h in grid:
            n = int(round(case.horizon / h))
            m, d = model(name, case.horizon / n)
            out = []
            for i in range(pi0.shape[1]):
                start(m, d, i)
                for _ in range(n):
                    mujoco.mj_step(m, d)
                out.append(d.qvel[3:6] * inertia)
            y = np.array(out).T
            start(m, d, 0)
            seconds = timed(lambda: mujoco.mj_step(m, d), min_time, 3)
            err = float(np.max(np.linalg.norm(y - ref, axis=0) / np.linalg.norm(pi0, axis=0)))
            points.append(
                {
                    "h": case.horizon / n,
                    "steps": n,
                    "error": err,
                    "seconds_per_step": seconds,
                    "rhs_per_step": None,
                    "seconds_per_simulated_second": seconds * n / case.horizon,
                }
            )
        fitted = fit_order(
            [p["h"] for p in points], [p["error"] for p in points], FIT_FLOOR["exact"]
        )
        conv.append(
            {
                "case": case.key,
                "integrator": f"mujoco {name}",
                "declared_order": order,
                "order": fitted,
                "points": points,
            }
        )
        steps = 10**4 if quick else 10**5
        m, d = model(name, case.drift_h)
        short, long_, diverged = {k: 0.0 for k in invariants}, {k: 0.0 for k in invariants}, None
        every = max(1, steps // 100)
        for i in range(pi0.shape[1]):
            start(m, d, i)
            for k in range(1, steps + 1):
                mujoco.mj_step(m, d)
                if k % every and k != 1000:
                    continue
                for key, (f, scale) in invariants.items():
                    change = abs(
                        float(f(tuple(d.qvel[3:6] * inertia))) - float(f(tuple(pi0[:, i])))
                    ) / float(np.asarray(scale)[i])
                    change = change if math.isfinite(change) else math.inf
                    long_[key] = max(long_[key], change)
                    if k <= 1000:
                        short[key] = max(short[key], change)
                if (
                    max(long_.values()) > DIVERGED
                ):  # (MuJoCo resets an unstable state: stop at the first sign)
                    diverged = k if diverged is None else min(diverged, k)
                    break
        drifts.append(
            {
                "case": case.key,
                "integrator": f"mujoco {name}",
                "h": case.drift_h,
                "short_steps": 1000,
                "long_steps": steps,
                "drift_short": None if diverged is not None and diverged < 1000 else short,
                "drift_long": long_,
                "diverged_at": diverged,
                "seconds": None,
            }
        )
    return conv, drifts


def progress_total(systems=None, quick=False):
    total = 0
    for case in CASES:
        if systems is None or case.key in systems:
            for name in case.integrators:
                grid = case.euler_grid if name == "euler" else case.grid
                total += (min(len(grid), QUICK_POINTS) if quick else len(grid)) + 1
    return total


# ------------------------------------------------------------------------------------ scenes
def _scene_run(scene, integrator, substeps, seed, actions, horizon_steps):
    """States (per block) along ``horizon_steps`` env steps under ``actions``, from ``seed``."""
    env = scene.make(
        integrator=integrator, substeps=substeps, tolerance=None
    ).unwrapped  # (fixed steps: unchecked)
    env.reset(seed=seed)
    names = [
        k
        for k in env.get_state()
        if not (scene.env_id.startswith("rbenvs/TippeTop") and k == "position")
    ]
    out = {k: [env.get_state()[k]] for k in names}
    failed = False
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for a in actions[:horizon_steps]:
            _, _, _, _, info = env.step(a)
            if info.get("numerical_failure") or info.get("terminal_reason") == "lift_off":
                failed = True
                break
            st = env.get_state()
            for k in names:
                out[k].append(st[k])
    env.close()
    return {k: np.array(v) for k, v in out.items()}, failed


def _scene_error(run, ref):
    err = 0.0
    for k, r in ref.items():
        x = run[k]
        n = min(len(x), len(r))
        scale = float(np.max(np.linalg.norm(r, axis=1)))
        err = max(err, float(np.max(np.linalg.norm(x[:n] - r[:n], axis=1))) / scale)
    return err


def _scene_cost(scene, integrator, substeps, min_time):
    """Seconds per env step (the unwrapped env, zero action, reset when an episode ends)."""
    env = scene.make(integrator=integrator, substeps=substeps, tolerance=None)
    env.reset(seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t = timed(
            episode_stepper(env, np.zeros(env.action_space.shape, dtype=np.float32)), min_time, 3
        )
    env.close()
    return t


def run_scenes(
    names=None, target=TARGET, seeds=SCENE_SEEDS, min_time=0.1, progress=None
) -> list[dict]:
    """Per scene: each integrator's error over an episode at ``substeps = 1, 2, 4, ...`` until
    it meets ``target`` (at most :data:`MAX_SUBSTEPS`), its cost per env step, and the cheapest
    integrator and substeps that meet it."""
    from ..scenes import list_scenes, load_scene

    rows = []
    for name in names or list_scenes():
        scene = load_scene(name)
        probe = scene.make().unwrapped
        dt, current = probe.dt, (probe.integrator.name, probe.substeps)
        episode = scene.make().spec.max_episode_steps
        tippe = scene.env_id.startswith("rbenvs/TippeTop")
        steps = min(episode, int(round(TIPPE_HORIZON / dt))) if tippe else episode
        rng = np.random.default_rng(0)
        space = probe.action_space
        actions = [rng.uniform(space.low, space.high).astype(np.float32) for _ in range(steps)]
        refs = [_scene_run(scene, REFERENCE, 1, seed, actions, steps)[0] for seed in range(seeds)]
        candidates = []
        ladder = [2**k for k in range(int(math.log2(MAX_SUBSTEPS)) + 1)]
        if (
            tippe
        ):  # the env takes max(substeps, its own rule's count): only counts above the rule matter
            probe.reset(seed=0)
            n0 = probe.internal_steps(
                probe.state_components, (0.0, 0.0, probe.params.friction, 0.0, 0.0, 0.0)
            )
            ladder = [1] + [k for k in (2**j for j in range(1, 9)) if k >= 2 * n0]
        for integ in (i for i in probe.integrators if i != "dop853"):
            for substeps in ladder:
                errs = []
                for seed in range(seeds):
                    run_, failed = _scene_run(scene, integ, substeps, seed, actions, steps)
                    errs.append(math.inf if failed else _scene_error(run_, refs[seed]))
                err = max(errs)
                cost = _scene_cost(scene, integ, substeps, min_time)
                candidates.append(
                    {
                        "integrator": integ,
                        "substeps": substeps,
                        "error": err,
                        "step_us": cost * 1e6,
                        "meets": err <= target,
                    }
                )
                cheapest = min((c["step_us"] for c in candidates if c["meets"]), default=math.inf)
                # more substeps only cost more: stop once the target is met or this costs more
                # than a pair that meets it
                if err <= target or cost * 1e6 > cheapest:
                    break
            if progress:
                progress()
        meeting = [c for c in candidates if c["meets"]]
        best = min(meeting, key=lambda c: c["step_us"]) if meeting else None
        cur = next((c for c in candidates if (c["integrator"], c["substeps"]) == current), None)
        if cur is not None and cur["meets"] and best["step_us"] > SAVING * cur["step_us"]:
            best = cur  # a saving within the timing noise is no reason to change a scene
        rows.append(
            {
                "scene": name,
                "id": scene.env_id,
                "dt": dt,
                "steps": steps,
                "episode_steps": episode,
                "current": {"integrator": current[0], "substeps": current[1]},
                "current_error": None if cur is None else cur["error"],
                "candidates": candidates,
                "recommended": None
                if best is None
                else {"integrator": best["integrator"], "substeps": best["substeps"]},
                "target": target,
            }
        )
    return rows


def _tippe_main(args) -> int:
    """``--tippe``: :mod:`rbenvs.bench.tippe_accuracy` (``--quick``, ``--json``, ``--plot`` and
    ``--mujoco`` as for the other cases)."""
    from . import tippe_accuracy

    if args.plot and plot_unavailable("rbenvs bench accuracy"):
        return 2
    bar = Progress(
        tippe_accuracy.progress_total(args.quick), not args.no_progress, "bench accuracy --tippe"
    )
    result = tippe_accuracy.run(quick=args.quick, progress=bar.update, mujoco=args.mujoco)
    bar.close()
    tippe_accuracy.print_report(result)
    if args.plot:
        tippe_accuracy.plot(result, args.plot)
        print(f"\nplot written to {args.plot}")
    _write_json(args.json, result)
    return 0


# ------------------------------------------------------------------------------------ output
def _g(x, fmt=".1e"):
    return "-" if x is None else format(x, fmt)


def print_report(result, file=None):
    file = sys.stdout if file is None else file
    for key, info in result["cases"].items():
        chk = (
            ""
            if info["reference_check"] is None
            else f"; ref. check (rtol 1e-12 vs 1e-13): {info['reference_check']:.1e}"
        )
        print(
            f"\n{key}: {info['label']}; {info['states']} states; error after T = "
            f"{info['horizon']:g} s against the {info['reference']}{chk}",
            file=file,
        )
        print(
            f"{'integrator':<10} {'order':>6} {'declared':>8} {'rhs/step':>8} {'us/step':>8}  "
            "error at h = ...",
            file=file,
        )
        for c in (c for c in result["convergence"] if c["case"] == key):
            pts = c["points"]
            order = (
                "round-off"
                if c["integrator"] == "exact" and max(p["error"] for p in pts) < 1e-12
                else _g(c["order"], ".2f")
            )
            rhs = "adaptive" if c["integrator"] == "dop853" else _g(pts[0]["rhs_per_step"], "d")
            us = min(p["seconds_per_step"] for p in pts) * 1e6
            errs = "  ".join(f"{p['h']:.2e}:{p['error']:.1e}" for p in pts)
            print(
                f"{c['integrator']:<10} {order:>6} {c['declared_order']:>8} {rhs:>8} {us:>8.2f}  "
                f"{errs}",
                file=file,
            )
        _print_mujoco_ratios([c for c in result["convergence"] if c["case"] == key], file)
        drifts = [d for d in result["drift"] if d["case"] == key]
        names = list(drifts[0]["drift_long"])
        print(
            f"drift at h = {info['drift_h']:.4g} s (largest relative change from the start)",
            file=file,
        )
        head = "  ".join(f"{n + ' 1e3':>13} {n + ' long':>14}" for n in names)
        print(f"{'integrator':<10} {'long steps':>10}  {head}  note", file=file)
        for d in drifts:
            cols = "  ".join(
                f"{_g(d['drift_short'][n]) if d['drift_short'] else '-':>13} "
                f"{_g(d['drift_long'][n]):>14}"
                for n in names
            )
            note = f"diverged at step {d['diverged_at']}" if d["diverged_at"] else ""
            print(f"{d['integrator']:<10} {d['long_steps']:>10.0e}  {cols}  {note}", file=file)
    if result.get("scenes"):
        print_scenes(result["scenes"], file=file)


# accuracies at which the cheapest rbenvs and MuJoCo schemes are compared (relative error at T)
COST_TARGETS = (1e-3, 1e-6, 1e-9)


def cheapest(convergence_rows, tol):
    """``(integrator, seconds per simulated second)`` of the cheapest grid point with error
    ``<= tol`` among ``convergence_rows``; ``None`` if none reaches it."""
    best = None
    for c in convergence_rows:
        for p in c["points"]:
            if p["error"] <= tol and (best is None or p["seconds_per_simulated_second"] < best[1]):
                best = (c["integrator"], p["seconds_per_simulated_second"])
    return best


def _print_mujoco_ratios(rows, file):
    """With MuJoCo lines: the cost of reaching each accuracy, ours against MuJoCo's (same run)."""
    theirs = [c for c in rows if c["integrator"].startswith("mujoco")]
    if not theirs:
        return
    ours = [c for c in rows if not c["integrator"].startswith("mujoco")]
    print(
        "cost to reach a relative error at T (CPU s per simulated s, the cheapest grid point of "
        "each side):",
        file=file,
    )
    for tol in COST_TARGETS:
        a, b = cheapest(ours, tol), cheapest(theirs, tol)
        if a is None or b is None:
            print(
                f"  error <= {tol:.0e}: rbenvs {a[0] if a else 'none'}, MuJoCo "
                f"{b[0] if b else 'none on the grid'}",
                file=file,
            )
            continue
        print(
            f"  error <= {tol:.0e}: rbenvs {a[0]} {a[1]:.2e} s, MuJoCo {b[0][7:]} {b[1]:.2e} s: "
            f"MuJoCo / rbenvs = {b[1] / a[1]:.1f}",
            file=file,
        )


def print_scenes(rows, file=None):
    file = sys.stdout if file is None else file
    target = rows[0]["target"]
    print(
        f"\nscenes: worst relative state error over an episode (random actions, {SCENE_SEEDS} "
        "seeds) against dop853 at rtol 1e-13; "
        f"target {target:g}; cost = one env step (us); tippe top: first {TIPPE_HORIZON:g} s",
        file=file,
    )
    print(
        f"{'scene':<20} {'dt':>6} {'current':<14} {'error':>8} {'us':>7}   {'recommended':<14} "
        f"{'error':>8} {'us':>7}   candidates (integrator x substeps: error)",
        file=file,
    )
    for r in rows:
        cur = r["current"]
        cur_c = next(
            (
                c
                for c in r["candidates"]
                if (c["integrator"], c["substeps"]) == (cur["integrator"], cur["substeps"])
            ),
            None,
        )
        rec = r["recommended"]
        rec_c = (
            None
            if rec is None
            else next(
                c
                for c in r["candidates"]
                if (c["integrator"], c["substeps"]) == (rec["integrator"], rec["substeps"])
            )
        )
        cand = ", ".join(
            f"{c['integrator']}x{c['substeps']}:{c['error']:.0e}" for c in r["candidates"]
        )
        print(
            f"{r['scene']:<20} {r['dt']:>6g} {cur['integrator'] + ' x' + str(cur['substeps']):<14} "
            f"{_g(None if cur_c is None else cur_c['error']):>8} "
            f"{_g(None if cur_c is None else cur_c['step_us'], '.1f'):>7}   "
            f"{'none' if rec is None else rec['integrator'] + ' x' + str(rec['substeps']):<14} "
            f"{_g(None if rec_c is None else rec_c['error']):>8} "
            f"{_g(None if rec_c is None else rec_c['step_us'], '.1f'):>7}   {cand}",
            file=file,
        )


def plot(result, path):
    """Work-precision figure: error after ``T`` against seconds per simulated second, one line
    per integrator, one panel per case. Needs matplotlib (``RuntimeError`` otherwise)."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise RuntimeError("--plot needs matplotlib: pip install 'rbenvs[plot]'") from None
    keys = list(result["cases"])
    fig, axes = plt.subplots(1, len(keys), figsize=(4.2 * len(keys), 4.0), squeeze=False)
    colors = {
        "euler": "C0",
        "rk4": "C1",
        "splitting": "C2",
        "exact": "C3",
        "dop853": "C4",
        "mujoco Euler": "C5",
        "mujoco RK4": "C6",
        "mujoco implicit": "C7",
        "mujoco implicitfast": "C8",
    }
    for ax, key in zip(axes[0], keys):
        for c in (c for c in result["convergence"] if c["case"] == key):
            pts = c["points"]
            x = [p["seconds_per_simulated_second"] for p in pts]
            y = [max(p["error"], 1e-17) for p in pts]
            label = c["integrator"] + ("" if c["order"] is None else f" (order {c['order']:.2f})")
            style = "s--" if c["integrator"].startswith("mujoco") else "o-"
            ax.loglog(x, y, style, color=colors.get(c["integrator"]), label=label, ms=3)
        info = result["cases"][key]
        ax.set_title(f"{key} (T = {info['horizon']:g} s)", fontsize=9)
        ax.set_xlabel("CPU seconds per simulated second (one state)")
        ax.set_ylabel("relative error after T")
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle("rbenvs bench accuracy: work-precision", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _table(args, flag: str, total: int, run_table, print_table) -> int:
    """One of the single-table modes (``--roundoff``, ``--floor``, ``--tolerance``): ``run_table
    (progress=...)`` under a progress bar of ``total`` ticks, printed by ``print_table`` and
    written as ``--json``; exit status 0."""
    bar = Progress(total, not args.no_progress, f"bench accuracy {flag}")
    result = run_table(progress=bar.update)
    bar.close()
    print_table(result)
    _write_json(args.json, result)
    return 0


def _write_json(path, result) -> None:
    """Every figure of ``result`` as JSON at ``path`` (``--json``; nothing where ``path`` is
    None)."""
    if path:
        with open(path, "w") as f:
            json.dump(result, f, indent=1, default=float)


def _tolerance_cases():
    from .tolerance import TOLERANCE_CASES

    return TOLERANCE_CASES


def main(argv=None) -> int:
    keys = [c.key for c in CASES]
    parser = ArgumentParser(
        prog="rbenvs bench accuracy",
        description=(
            "Error, invariant drift, cost and order of every integrator on every system; a "
            "recommended integrator per scene."
        ),
    )
    parser.add_argument(
        "--quick",
        action="store_true",
        help="short grids and long runs of 1e4 steps; no scenes (CI)",
    )
    parser.add_argument("--json", metavar="PATH", help="also write every figure as JSON")
    parser.add_argument(
        "--plot",
        metavar="PATH",
        help="draw the work-precision figure to this PNG (needs matplotlib)",
    )
    parser.add_argument(
        "--system",
        action="append",
        choices=keys,
        help="restrict to these cases (repeatable; default all)",
    )
    parser.add_argument(
        "--scenes",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="the per-scene recommendation (default: on, off with --quick)",
    )
    parser.add_argument(
        "--mujoco",
        action=argparse.BooleanOptionalAction,
        default=True,
        help=(
            "MuJoCo's integrators on the free body when mujoco is installed (the mujoco extra; "
            "default: on)"
        ),
    )
    parser.add_argument(
        "--tolerance",
        action="store_true",
        help="only the tolerance= table (rbenvs.bench.tolerance): per extreme and requested "
        "tolerance 1e-3, 1e-6, 1e-9, the error "
        "achieved against the reference, the steps taken, and the cheapest fixed substeps meeting "
        "it",
    )
    parser.add_argument(
        "--case",
        action="append",
        metavar="KEY",
        help="with --tolerance: only these cases' rows (repeatable; default all): "
        + ", ".join(c.key for c in _tolerance_cases())
        + ", and scene:NAME for each shipped scene",
    )
    parser.add_argument(
        "--roundoff",
        action="store_true",
        help="only the roundoff table (rbenvs.bench.roundoff): two rk4 runs at 200 and 400 "
        "substeps near the free body's "
        "intermediate axis, summed plainly and with compensation (a tolerance's), apart and "
        "against the exact solution",
    )
    parser.add_argument(
        "--floor",
        action="store_true",
        help="only the float64 floor table (rbenvs.bench.floor): tolerance_check=True from "
        "0.0001-0.01 rad/s off "
        "the free body's intermediate axis at 1e-8 to 1e-12, every period returned against "
        "mpmath's Taylor solution (needs mpmath)",
    )
    parser.add_argument(
        "--tippe",
        action="store_true",
        help="only the tippe top's work-precision against MuJoCo (rbenvs.bench.tippe_accuracy): "
        "t90 against the slip regularisation, "
        "every scheme, step and fidelity level and MuJoCo's integrators and cones at several dt, "
        "cost per simulated second "
        "against Jellett drift and the t90 error",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress on stderr")
    args = parser.parse_args(argv)
    if args.case and not args.tolerance:
        parser.error("--case selects rows of the --tolerance table: pass --tolerance")
    if args.tippe:
        return _tippe_main(args)
    if args.roundoff:
        from .roundoff import OFF, STARTS, print_roundoff, run_roundoff

        return _table(args, "--roundoff", len(OFF) * 2 * STARTS, run_roundoff, print_roundoff)
    if args.floor:
        from .floor import OFF, TOLERANCES, print_floor, run_floor

        require("reference")  # mpmath, the reference: say so before the run, not after it
        return _table(args, "--floor", len(OFF) * len(TOLERANCES), run_floor, print_floor)
    if args.tolerance:
        from .tolerance import all_cases, print_tolerance, run_tolerance

        require("cli")  # the scenes' rows read the scenes' YAML
        everything = all_cases()
        known = [c.key for c in everything]
        for key in args.case or ():
            if key not in known:
                parser.error(f"--case {key!r}: not a case of the --tolerance table; one of {known}")
        cases = [c for c in everything if not args.case or c.key in args.case]
        return _table(
            args,
            "--tolerance",
            sum(len(c.tolerances) for c in cases),
            lambda progress: run_tolerance(keys=args.case, progress=progress),
            print_tolerance,
        )
    if args.plot and plot_unavailable(
        "rbenvs bench accuracy"
    ):  # fail before the long run, not after it
        return 2
    scenes = (not args.quick) if args.scenes is None else args.scenes
    if scenes:
        require("cli")  # the scenes are YAML: say so before the long run, not after it
    bar = Progress(progress_total(args.system, args.quick), not args.no_progress, "bench accuracy")
    result = run(systems=args.system, quick=args.quick, progress=bar.update, mujoco=args.mujoco)
    bar.close()
    if scenes:
        result["scenes"] = run_scenes()
    result["settings"] = {
        "quick": args.quick,
        "target": TARGET,
        "fit_range": [FIT_FLOOR, FIT_CEILING],
    }
    print_report(result)
    if args.plot:
        plot(result, args.plot)
        print(f"\nplot written to {args.plot}")
    _write_json(args.json, result)
    return 0

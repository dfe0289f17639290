"""MuJoCo's integrators on the free body, measured beside ours in the same run."""

from __future__ import annotations

import math

import numpy as np

from ..throughput import timed
from .convergence import CASES, DIVERGED, FIT_FLOOR, QUICK_POINTS, _setup, fit_order

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
    from ...oracles import exact_solution

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

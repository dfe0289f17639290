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
    body = _MujocoFreeBody(mujoco)
    conv, drifts = [], []
    for name, order in MUJOCO_INTEGRATORS.items():
        conv.append(body.convergence(name, order, quick, min_time))
        drifts.append(body.drift(name, quick))
    return conv, drifts


class _MujocoFreeBody:
    """The free-body case (``CASES[0]``) as a MuJoCo model: its start states, the exact
    solution at the horizon, and the runs measured against them."""

    def __init__(self, mujoco):
        from ...oracles import exact_solution

        self.mujoco = mujoco
        self.case = CASES[0]
        system, y0, self.invariants = _setup(self.case.key)
        self.inertia = np.array(system.params.inertia)
        self.pi0 = np.array(y0)
        self.ref = np.array(exact_solution(tuple(self.inertia), self.pi0, self.case.horizon))

    def model(self, integrator, h):
        """A free body with the case's principal moments, no gravity, ``integrator`` at step
        ``h``: ``(MjModel, MjData)``."""
        inertia = self.inertia
        xml = (
            f'<mujoco><option gravity="0 0 0" integrator="{integrator}" '
            f'timestep="{float(h)!r}"/><worldbody><body><freejoint/>'
            f'<inertial pos="0 0 0" mass="1" diaginertia="{float(inertia[0])!r} '
            f'{float(inertia[1])!r} {float(inertia[2])!r}"/></body></worldbody></mujoco>'
        )
        m = self.mujoco.MjModel.from_xml_string(xml)
        return m, self.mujoco.MjData(m)

    def start(self, m, d, i):
        """Reset ``d`` to start ``i``: ``Omega = I^-1 Pi`` as the body-frame angular velocity."""
        self.mujoco.mj_resetData(m, d)
        d.qvel[3:6] = self.pi0[:, i] / self.inertia

    def convergence(self, name, order, quick, min_time) -> dict:
        """Integrator ``name``'s error at the horizon over the case's grid (the Euler grid for
        first-order schemes) and its fitted order."""
        case = self.case
        grid = case.euler_grid if order == 1 else case.grid
        grid = grid[:QUICK_POINTS] if quick else grid
        points = [self.point(name, h, min_time) for h in grid]
        fitted = fit_order(
            [p["h"] for p in points], [p["error"] for p in points], FIT_FLOOR["exact"]
        )
        return {
            "case": case.key,
            "integrator": f"mujoco {name}",
            "declared_order": order,
            "order": fitted,
            "points": points,
        }

    def point(self, name, h, min_time) -> dict:
        """One grid point: every start run to the horizon at the step nearest ``h`` that divides
        it, the worst relative error of ``Pi`` there, and the seconds a step."""
        mujoco, inertia, pi0, horizon = self.mujoco, self.inertia, self.pi0, self.case.horizon
        n = int(round(horizon / h))
        m, d = self.model(name, horizon / n)
        out = []
        for i in range(pi0.shape[1]):
            self.start(m, d, i)
            for _ in range(n):
                mujoco.mj_step(m, d)
            out.append(d.qvel[3:6] * inertia)
        y = np.array(out).T
        self.start(m, d, 0)
        seconds = timed(lambda: mujoco.mj_step(m, d), min_time, 3)
        err = float(np.max(np.linalg.norm(y - self.ref, axis=0) / np.linalg.norm(pi0, axis=0)))
        return {
            "h": horizon / n,
            "steps": n,
            "error": err,
            "seconds_per_step": seconds,
            "rhs_per_step": None,
            "seconds_per_simulated_second": seconds * n / horizon,
        }

    def drift(self, name, quick) -> dict:
        """Integrator ``name``'s invariant drift at the case's ``drift h``: the worst over the
        starts within 1e3 steps and within 1e5 (1e4 with ``quick``), and the first step where
        it diverged."""
        case = self.case
        steps = 10**4 if quick else 10**5
        m, d = self.model(name, case.drift_h)
        short = {k: 0.0 for k in self.invariants}
        long_ = {k: 0.0 for k in self.invariants}
        diverged = None
        for i in range(self.pi0.shape[1]):
            k = self.drift_of_start(m, d, i, steps, short, long_)
            if k is not None:
                diverged = k if diverged is None else min(diverged, k)
        return {
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

    def drift_of_start(self, m, d, i, steps, short, long_):
        """Start ``i`` run ``steps`` steps, its drift read every hundredth of them and at step
        1000, folded into ``short`` (up to step 1000) and ``long_``; the step where it diverged,
        or ``None``."""
        mujoco, inertia, pi0 = self.mujoco, self.inertia, self.pi0
        every = max(1, steps // 100)
        self.start(m, d, i)
        for k in range(1, steps + 1):
            mujoco.mj_step(m, d)
            if k % every and k != 1000:
                continue
            for key, (f, scale) in self.invariants.items():
                change = abs(
                    float(f(tuple(d.qvel[3:6] * inertia))) - float(f(tuple(pi0[:, i])))
                ) / float(np.asarray(scale)[i])
                change = change if math.isfinite(change) else math.inf
                long_[key] = max(long_[key], change)
                if k <= 1000:
                    short[key] = max(short[key], change)
            # MuJoCo resets an unstable state: stop at the first sign
            if max(long_.values()) > DIVERGED:
                return k
        return None


def progress_total(systems=None, quick=False):
    total = 0
    for case in CASES:
        if systems is None or case.key in systems:
            for name in case.integrators:
                grid = case.euler_grid if name == "euler" else case.grid
                total += (min(len(grid), QUICK_POINTS) if quick else len(grid)) + 1
    return total

"""``rbenvs bench accuracy --floor``: ``tolerance_check=True`` where float64's roundoff sets the
floor, near the free body's separatrix (docs/accuracy.md, "Roundoff").

Near the intermediate axis the motion amplifies the roundoff of every passage by the saddle, and
from a start close enough to the separatrix no step count holds a tight tolerance in float64. The
check must then end the episode, saying so, and never return a period outside the tolerance:
the companion's estimate counts the steps' error, and the episode ends where it passes the
tolerance, before the roundoff does (:mod:`rbenvs.stepsize.controller`). For the default-like body
``INERTIA`` at ``SPIN`` rad/s about its intermediate axis and ``OFF`` rad/s about the others
(the third at 0.7 of it) and each tolerance of ``TOLERANCES``, one episode of ``PERIODS`` periods,
compared on every period it returns with mpmath's Taylor-series solution
(:func:`rbenvs.oracles.taylor_solution`, 32 digits; float64's elliptic solution is not exact enough
here: it needs mpmath, the ``reference`` extra).

Columns: ``end`` the period the episode ended at (a numerical failure) or ``-`` (ran its
horizon); ``worst / tol`` the largest relative error over the periods returned over the
tolerance (``<= 1``: within); ``estimate / error`` the smallest ratio of the reported global
error estimate to the error over the periods whose error is above 1e-13 (``< 1``: the estimate
was below the error there); ``steps`` every internal step (the main run's and the companion's).
"""

from __future__ import annotations

import warnings

import numpy as np

__all__ = ["INERTIA", "SPIN", "OFF", "TOLERANCES", "PERIODS", "run_floor", "print_floor"]

INERTIA = (2.0, 1.5, 1.0)
SPIN = 5.0  # |Omega| about the intermediate axis [rad/s]
OFF = (1e-4, 3e-4, 1e-3, 1e-2)  # the start's Omega_1 [rad/s] (Omega_3 = 0.7 of it)
TOLERANCES = (
    1e-8,
    1e-9,
    1e-10,
    1e-11,
    1e-12,
)  # (down to rbenvs.stepsize.controller.TOLERANCE_FLOOR)
PERIODS = 400  # the free body's episode (20 s)
# an error below this is roundoff of the comparison itself, not of the run (the estimate/error
# column)
ERROR_FLOOR = 1e-13


def _episode(w, tol, reference):
    from ..envs import FreeRigidBodyEnv
    from ..stepsize.controller import companion_steps

    with warnings.catch_warnings():
        warnings.simplefilter(
            "ignore"
        )  # (the unstable-motion warning, the ended episode's: measured here)
        env = FreeRigidBodyEnv(
            inertia=INERTIA,
            axis=0,
            max_torque=0.0,
            integrator="rk4",
            max_angular_velocity=10.0 * SPIN,
            tolerance=tol,
            tolerance_horizon=PERIODS,
            tolerance_check=True,
        )
        env.reset(seed=0, options={"state": {"angular_momentum": np.array(INERTIA) * np.array(w)}})
        a = np.zeros(env.action_space.shape, np.float32)
        worst, ratio, steps, end = 0.0, np.inf, 0, None
        for k in range(PERIODS):
            _, _, terminated, _, info = env.step(a)
            n = int(round(env.dt / info["internal_step"]))
            steps += n + companion_steps(n)
            if terminated:
                end = k + 1
                break
            err = float(
                np.linalg.norm(np.subtract(env.state_components, reference[k]))
                / np.linalg.norm(reference[k])
            )
            worst = max(worst, err)
            if err > ERROR_FLOOR:
                ratio = min(ratio, info["global_error_estimate"] / err)
    return {"end": end, "worst": worst, "ratio": ratio, "steps": steps}


def run_floor(progress=None) -> dict:
    """Every row (see the module):
    ``{"rows": [{"off", "tolerance", "end", "worst", "ratio", "steps"}]}``."""
    from ..oracles import taylor_solution

    rows = []
    for off in OFF:
        w = (off, SPIN, 0.7 * off)
        reference = taylor_solution(
            INERTIA, np.array(INERTIA) * np.array(w), [0.05 * (k + 1) for k in range(PERIODS)]
        )
        for tol in TOLERANCES:
            rows.append({"off": off, "tolerance": tol, **_episode(w, tol, reference)})
            if progress:
                progress()
    return {"rows": rows}


def print_floor(result, file=None) -> None:
    rows = result["rows"]
    print(
        f"tolerance_check near the separatrix: body {INERTIA}, {SPIN:g} rad/s about the "
        f"intermediate axis, {PERIODS} periods, rk4; "
        "error against mpmath's Taylor solution (32 digits) on every period returned",
        file=file,
    )
    print(
        f"{'off axis':>9} {'tolerance':>10} {'end':>5} {'worst / tol':>12} "
        f"{'estimate / error':>17} {'steps':>9}",
        file=file,
    )
    for r in rows:
        end = "-" if r["end"] is None else str(r["end"])
        ratio = "-" if not np.isfinite(r["ratio"]) else f"{r['ratio']:.2f}"
        print(
            f"{r['off']:>9g} {r['tolerance']:>10g} {end:>5} {r['worst'] / r['tolerance']:>12.2f} "
            f"{ratio:>17} {r['steps']:>9}",
            file=file,
        )
    outside = [r for r in rows if r["worst"] > r["tolerance"]]
    print(
        f"within the tolerance on every period returned: {len(rows) - len(outside)} of {len(rows)}"
        + "".join(
            f"; outside: {r['off']:g} off at {r['tolerance']:g}, {r['worst'] / r['tolerance']:.2f} "
            "times"
            for r in outside
        ),
        file=file,
    )

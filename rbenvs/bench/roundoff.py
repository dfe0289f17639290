"""``rbenvs bench accuracy --roundoff``: the roundoff floor near the free body's intermediate axis,
summed plainly and with compensation (docs/accuracy.md, "Roundoff").

Near the separatrix the motion amplifies every rounding, and two rk4 runs whose steps' own
error is far below either's differ by the roundoff alone. Per distance of the start from the
intermediate axis (``OFF``, rad/s, at ``SPIN`` rad/s about it) and per start (``STARTS`` near each,
the roundoff being chaotic: a start one ulp away changes it severalfold), the default-like body
``INERTIA`` runs ``PERIODS`` periods at ``COARSE`` and at ``FINE`` substeps a period:

* ``plain``: fixed substeps without a tolerance (the steps sum plainly);
* ``compensated``: the same with ``tolerance=1e-3``, whose guard asks for fewer steps than the
  substeps, so the counts are the same, and whose steps sum with compensation carried from
  period to period (:class:`rbenvs.core.step.Engine`).

Columns: the largest relative difference of the two runs over the periods (min to max over the
starts), and the run at ``FINE`` substeps against the exact solution
(:func:`rbenvs.oracles.exact_solution`), the same way.
"""

from __future__ import annotations

import warnings

import numpy as np

__all__ = [
    "INERTIA",
    "SPIN",
    "OFF",
    "STARTS",
    "PERIODS",
    "COARSE",
    "FINE",
    "run_roundoff",
    "print_roundoff",
]

INERTIA = (2.0, 1.5, 1.0)
SPIN = 5.0  # |Omega| about the intermediate axis [rad/s]
OFF = (0.5, 0.1, 0.01, 0.001)  # the start's Omega_1 [rad/s] (Omega_3 = 0.7 of it)
STARTS = 8  # per distance: Omega_1 and Omega_3 scaled by 1 + 0.01 k and 1 + 0.013 k
PERIODS = 400  # the free body's episode (20 s)
COARSE, FINE = 200, 400  # substeps a period: rk4's own error far below the roundoff at both
COMPENSATED_TOLERANCE = 1e-3  # a tolerance whose counts stay at the substeps


def _run(w, substeps: int, tolerance):
    from ..envs import FreeRigidBodyEnv

    with warnings.catch_warnings():
        warnings.simplefilter(
            "ignore"
        )  # (the unstable-motion warning: this is the motion measured)
        env = FreeRigidBodyEnv(
            inertia=INERTIA,
            axis=0,
            max_torque=0.0,
            integrator="rk4",
            max_angular_velocity=10.0 * SPIN,
            substeps=substeps,
            tolerance=tolerance,
        )
    env.reset(seed=0, options={"state": {"angular_momentum": np.array(INERTIA) * np.array(w)}})
    a = np.zeros(env.action_space.shape, np.float32)
    out = []
    for _ in range(PERIODS):
        _, _, _, _, info = env.step(a)
        if info["internal_step"] != env.dt / substeps:
            raise RuntimeError(
                f"the guard took {env.dt / info['internal_step']:.0f} steps, not the {substeps} "
                "substeps"
            )
        out.append(env.state_components)
    return np.array(out), env.dt


def run_roundoff(progress=None) -> dict:
    """Every row (see the module):
    ``{"rows": [{"off", "mode", "apart": [...], "exact": [...]}]}``."""
    from ..oracles import exact_solution

    rows = []
    for off in OFF:
        starts = [(off * (1 + 0.01 * k), SPIN, 0.7 * off * (1 + 0.013 * k)) for k in range(STARTS)]
        exact = {}
        for mode, tolerance in (("plain", None), ("compensated", COMPENSATED_TOLERANCE)):
            apart, to_exact = [], []
            for w in starts:
                (coarse, dt), (fine, _) = _run(w, COARSE, tolerance), _run(w, FINE, tolerance)
                scale = np.linalg.norm(fine, axis=1)
                apart.append(float(np.max(np.linalg.norm(coarse - fine, axis=1) / scale)))
                if w not in exact:
                    pi0 = np.array(INERTIA) * np.array(w)
                    exact[w] = np.array(
                        [exact_solution(INERTIA, pi0, (k + 1) * dt) for k in range(PERIODS)]
                    )
                to_exact.append(float(np.max(np.linalg.norm(exact[w] - fine, axis=1) / scale)))
                if progress:
                    progress()
            rows.append({"off": off, "mode": mode, "apart": apart, "exact": to_exact})
    return {"rows": rows}


def print_roundoff(result, file=None) -> None:
    print(
        f"roundoff near the intermediate axis: body {INERTIA}, {SPIN:g} rad/s, {PERIODS} periods, "
        f"rk4; {STARTS} starts per distance "
        "(min to max); plain: fixed substeps, no tolerance; compensated: "
        f"tolerance={COMPENSATED_TOLERANCE:g} (its counts are the substeps)",
        file=file,
    )
    print(
        f"{'off axis':>9} {'sum':>12} {f'{COARSE} vs {FINE} substeps':>22} "
        f"{f'{FINE} vs exact':>22}",
        file=file,
    )
    for r in result["rows"]:
        span = lambda v: f"{min(v):.1e} to {max(v):.1e}"  # noqa: E731
        print(
            f"{r['off']:>9g} {r['mode']:>12} {span(r['apart']):>22} {span(r['exact']):>22}",
            file=file,
        )

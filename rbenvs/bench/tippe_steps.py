"""``python -m rbenvs.bench.tippe_steps``: what the tippe top's internal step count buys.

One inversion per row, from a named start (``start=``, docs/physics.md §3) at tilt 0.1 rad: the
time to pass 90 degrees (linear in the tilt within the period that crosses, as
tests/test_tippe_starts.py measures it), its error against the converged value of the same model
(rk4 at ``--reference`` steps a period; ``--reference dop853``: the env's dop853, slow), Jellett's
largest relative drift, the largest energy rise between periods, the least normal force over
``m g``, the internal steps a period and the wall time per simulated 10 ms of a single env
(compiled where numba is installed). Counts are fixed (``guard="off"``), ``guard`` (the env's
default guard) or ``tight`` (the count a guard with the friction's tight stability bound would
take at the start: ``dt lambda_d / 2.785`` with ``lambda_d`` at the actual normal force and
mobility, :func:`rbenvs.dynamics.tippe_top.implicit_forms`' ``rate``, rk4's whole real-axis
interval, no margin; and at least the guard's spin bound) or ``accuracy`` (the env's guard with
``friction_bound="accuracy"``).

It measures what the guard's bound is for: near zero slip the regularised friction relaxes the
slip at ``lambda_d`` (about 6000/s for the default top) and the slow motion depends on how the
slip lags the forcing; the count at which a scheme reproduces the converged time to 90 degrees
is what the table shows, per start, spin sign and friction law.

:func:`sweep_table` (``rbenvs bench accuracy --tippe-sweep``): the env's default guard on
the 15 tops of :data:`SWEEP` (the tops the accuracy bound is held over, tests/test_tippe_stiff.py)
against rk4 at ``SWEEP_REFERENCE`` fixed steps a period: per top the time to 90 degrees, its
error, Jellett's largest drift per simulated second up to 90 degrees and the mean steps a period
(docs/accuracy.md, "Stiff friction").
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..extras import ArgumentParser

__all__ = [
    "inversion",
    "rows",
    "table",
    "main",
    "make_env",
    "scheme",
    "SWEEP",
    "to_ninety",
    "sweep_table",
]

ID = "rbenvs/TippeTop-v0"
RK4_REAL_INTERVAL = 2.785  # rk4's stability interval on the negative real axis


def scheme(name):
    from ..integrators.rosenbrock import Ros2, Ros34pw2

    return {"ros2": Ros2(), "ros34pw2": Ros34pw2()}.get(name, name)


def make_env(
    start,
    spin,
    law,
    integrator,
    substeps,
    guard,
    compiled,
    max_periods,
    friction_bound="stability",
    **options,
):
    import gymnasium as gym

    import rbenvs  # noqa: F401  (registers the ids)

    options.setdefault("friction", {"coulomb": 0.3, "viscous": 30.0}[law])
    return gym.make(
        ID,
        start=start,
        spin=spin,
        tilt=0.1,
        friction_law=law,
        integrator=scheme(integrator),
        substeps=substeps,
        guard=guard,
        compiled=compiled,
        max_episode_steps=max_periods + 1,
        friction_bound=friction_bound,
        **options,
    ).unwrapped


# The sweep of tops the accuracy bound holds (issue 44, item 5): alpha 0.1-0.3, A/C = 1 + f alpha
# across the inversion band (1 - alpha < A/C < 1 + alpha; the lowest f per alpha the lowest whose
# top passes 90 degrees within about 27 s at 150 rad/s), C = SWEEP_C, the default start
SWEEP = (
    [(0.1, f) for f in (-0.5, -0.25, 0.0, 0.5, 0.9)]
    + [(0.2, f) for f in (-0.7, -0.5, 0.0, 0.5, 0.9)]
    + [(0.3, f) for f in (-0.8, -0.5, 0.0, 0.5, 0.9)]
)
SWEEP_C = 7e-7  # kg m^2
SWEEP_REFERENCE = 2560  # rk4 steps a period of the converged value


def to_ninety(alpha, f, **options) -> tuple:
    """The top ``(alpha, A/C = 1 + f alpha)`` from the default start (seed 0) under zero action,
    up to the period that passes 90 degrees: ``(t90, Jellett's largest relative drift, steps a
    period)``, ``t90`` interpolated linearly in the period that crosses; ``options``: more env
    keywords. ``RuntimeError`` where the episode ends first or the top does not pass 90 degrees
    in 5000 periods."""
    import gymnasium as gym

    import rbenvs  # noqa: F401  (registers the ids)

    c = SWEEP_C
    env = gym.make(
        ID, offset=alpha, inertia=((1.0 + f * alpha) * c, c), max_episode_steps=5000, **options
    ).unwrapped
    _, info = env.reset(seed=0)
    a = np.zeros(env.action_space.shape, np.float32)
    j0, tilt, drift, steps = info["jellett"], info["tilt"], 0.0, []
    for k in range(1, 5001):
        _, _, terminated, _, info = env.step(a)
        if terminated:
            raise RuntimeError(f"the top {alpha}, {1 + f * alpha} ended: {info['terminal_reason']}")
        steps.append(env.dt / info["internal_step"])
        drift = max(drift, abs(info["jellett"] - j0) / abs(j0))
        if info["tilt"] > math.pi / 2:
            t90 = (k - 1 + (math.pi / 2 - tilt) / (info["tilt"] - tilt)) * env.dt
            return t90, drift, float(np.mean(steps))
        tilt = info["tilt"]
    raise RuntimeError(f"the top {alpha}, {1 + f * alpha} did not pass 90 degrees in 5000 periods")


def sweep_table() -> str:
    """The table of ``rbenvs bench accuracy --tippe-sweep`` (module docstring)."""
    lines = [
        f"{len(SWEEP)} tops (A/C = 1 + f alpha, C = {SWEEP_C:g} kg m^2, the default start, zero "
        f"action): the default guard against rk4 at {SWEEP_REFERENCE} fixed steps a period, up "
        "to 90 degrees",
        "| alpha | A/C | t90 [s] | t90 error [s] | Jellett drift per s | steps a period |",
        "|---|---|---|---|---|---|",
    ]
    worst = []
    for alpha, f in SWEEP:
        t90, drift, steps = to_ninety(alpha, f)
        t90_ref, _, _ = to_ninety(alpha, f, guard="off", substeps=SWEEP_REFERENCE)
        error, rate = abs(t90 - t90_ref), drift / t90
        worst.append((error, rate, steps, f"{alpha}, {1 + f * alpha:.3f}"))
        lines.append(
            f"| {alpha} | {1 + f * alpha:.3f} | {t90:.6f} | {error:.1e} | {rate:.2e} | "
            f"{steps:.0f} |"
        )
    e, r = max(worst), max(worst, key=lambda x: x[1])
    lines.append(
        f"largest t90 error {e[0]:.1e} s (alpha, A/C = {e[3]}), largest Jellett drift "
        f"{r[1]:.2e} per s ({r[3]}); {min(w[2] for w in worst):.0f}-"
        f"{max(w[2] for w in worst):.0f} steps a period"
    )
    return "\n".join(lines)


def tight_count(start, spin, law="coulomb") -> int:
    """The count a guard with the tight friction bound would take at the start: rk4's whole
    real-axis interval over the tight rate, and the spin bound (``SPIN_STEP`` rad of ``max(|Omega|,
    omega_g)`` a step) the guard keeps for every scheme."""
    from ..dynamics.tippe_top import SPIN_STEP, tippe_rotation_rate

    env = make_env(start, spin, law, "rk4", 1, "off", False, 1)
    env.reset(seed=0)
    system, y = env.system, env.state_components
    rate = system.implicit.rate(system.form_params, y, None)
    spin_rate = tippe_rotation_rate(
        (system.layout["angular_velocity"][0], env.params.gravity_rate()), y
    )
    return max(
        1, math.ceil(env.dt * rate / RK4_REAL_INTERVAL), math.ceil(env.dt * spin_rate / SPIN_STEP)
    )


def inversion(
    start="rest",
    spin=180.0,
    substeps=None,
    integrator="rk4",
    law="coulomb",
    compiled="auto",
    max_periods=2000,
    friction_bound="stability",
    timing_repeats=0,
    **options,
) -> dict:
    """One inversion: ``substeps`` a count (fixed, guard off), ``None`` (the env's guard) or
    ``"tight"`` (:func:`tight_count`); ``"accuracy"``: the env's guard with
    ``friction_bound="accuracy"``; ``options``: more env keywords (``friction``, ...). Returns
    ``t90`` [s] (``nan``: no inversion, with
    ``ended`` saying why), ``drift``, ``rise`` [J], ``least_normal`` [m g], ``steps`` (mean
    internal steps a period), ``periods`` (control periods run) and ``us_per_period`` (wall time
    per control period of that run, its read-outs included). With ``timing_repeats = k > 0`` the
    same periods are run again ``k`` times from the same reset, nothing but ``env.step`` in the
    loop, and ``us_per_period_best`` is the best of them (the env's own step path alone)."""
    if substeps == "tight":
        substeps = tight_count(start, spin, law)
    if substeps == "accuracy":
        substeps, friction_bound = None, "accuracy"
    guard = "subdivide" if substeps is None else "off"
    env = make_env(
        start,
        spin,
        law,
        integrator,
        substeps or 1,
        guard,
        compiled,
        max_periods,
        friction_bound,
        **options,
    )
    action = np.zeros(env.action_space.shape, dtype=np.float32)
    env.reset(seed=0)
    env.step(action)  # (builds the compiled step outside the timing)
    out = _until_ninety(env, action, max_periods)
    if timing_repeats:
        out["us_per_period_best"] = _best_replay(env, action, out["periods"], timing_repeats)
    return out


def _until_ninety(env, action, max_periods) -> dict:
    """From ``reset(seed=0)``, ``action`` each period until the tilt passes 90 degrees (``t90``
    linear in the tilt within that period), the episode ends or ``max_periods`` pass: the
    measurements of :func:`inversion` but ``us_per_period_best``."""
    _, info = env.reset(seed=0)
    j0, e_prev, prev = info["jellett"], info["energy"], info["tilt"]
    drift = rise = 0.0
    least = math.inf
    steps = 0
    t90, ended = math.nan, "no inversion"
    weight = env.params.mass * env.params.gravity
    clock = time.perf_counter()
    k = 0
    for k in range(1, max_periods + 1):
        _, _, terminated, truncated, info = env.step(action)
        steps += round(env.dt / info["internal_step"])
        if terminated or truncated or info["numerical_failure"]:
            ended = info.get("terminal_reason") or (
                "numerical failure" if info["numerical_failure"] else "truncated"
            )
            break
        drift = max(drift, abs(info["jellett"] - j0) / abs(j0))
        rise = max(rise, info["energy"] - e_prev)
        e_prev = info["energy"]
        least = min(least, info["normal_force"] / weight)
        if info["tilt"] > math.pi / 2:
            t90, ended = (k - 1 + (math.pi / 2 - prev) / (info["tilt"] - prev)) * env.dt, None
            break
        prev = info["tilt"]
    wall = time.perf_counter() - clock
    return {
        "t90": t90,
        "ended": ended,
        "drift": drift,
        "rise": rise,
        "least_normal": least,
        "steps": steps / k,
        "periods": k,
        "us_per_period": 1e6 * wall / k,
    }


def _best_replay(env, action, periods, repeats) -> float:
    """The best over ``repeats`` of the wall time per period [us] of ``periods`` periods from
    ``reset(seed=0)``, nothing but ``env.step`` in the loop."""
    best = math.inf
    for _ in range(repeats):
        env.reset(seed=0)
        clock = time.perf_counter()
        for _ in range(periods):
            env.step(action)
        best = min(best, time.perf_counter() - clock)
    return 1e6 * best / periods


def rows(starts, laws, counts, schemes, reference=640) -> list[dict]:
    """Every (start, spin, law) with its converged time to 90 degrees and each (scheme, count)."""
    out = []
    for start, spin in starts:
        for law in laws:
            ref = inversion(
                start,
                spin,
                reference if reference != "dop853" else 1,
                "rk4" if reference != "dop853" else "dop853",
                law,
            )
            for scheme in schemes:
                for count in counts:
                    r = inversion(start, spin, count, scheme, law)
                    r.update(
                        start=start,
                        spin=spin,
                        law=law,
                        scheme=scheme,
                        count=count,
                        error=abs(r["t90"] - ref["t90"]),
                        reference=ref["t90"],
                    )
                    out.append(r)
    return out


def table(results) -> str:
    lines = [
        "| start | spin [rad/s] | law | scheme | count | steps/period | t90 [s] | error [s] | "
        "Jellett drift | energy rise [J] | min N / mg | us / 10 ms |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        t90 = f"{r['t90']:.9f}" if r["ended"] is None else f"n/a ({r['ended']})"
        err = f"{r['error']:.1e}" if r["ended"] is None else "n/a"
        lines.append(
            f"| {r['start']} | {r['spin']:g} | {r['law']} | {r['scheme']} | "
            f"{r['count'] if r['count'] is not None else 'guard'} | {r['steps']:.1f} | "
            f"{t90} | {err} | {r['drift']:.1e} | {r['rise']:.1e} | {r['least_normal']:.3f} | "
            f"{r['us_per_period']:.0f} |"
        )
    return "\n".join(lines)


def _count(text):
    if text in ("guard", "tight", "accuracy"):
        return None if text == "guard" else text
    return int(text)


def main(argv=None) -> int:
    parser = ArgumentParser(
        prog="python -m rbenvs.bench.tippe_steps", description=__doc__.splitlines()[0]
    )
    parser.add_argument(
        "--starts",
        default="rest:180,rolling:150,vertical:180",
        help="start:spin,... (a negative spin turns the other way)",
    )
    parser.add_argument("--laws", default="coulomb", help="coulomb,viscous")
    parser.add_argument(
        "--counts",
        default="guard,tight,40,80,160",
        help=(
            "internal steps a period: numbers, guard, tight, accuracy (the guard with "
            "friction_bound='accuracy')"
        ),
    )
    parser.add_argument("--schemes", default="rk4", help="rk4,euler,ros2,ros34pw2")
    parser.add_argument(
        "--reference", default="640", help="rk4 steps a period of the converged value, or dop853"
    )
    a = parser.parse_args(argv)
    starts = [(s.split(":")[0], float(s.split(":")[1])) for s in a.starts.split(",")]
    reference = a.reference if a.reference == "dop853" else int(a.reference)
    print(
        table(
            rows(
                starts,
                a.laws.split(","),
                [_count(c) for c in a.counts.split(",")],
                a.schemes.split(","),
                reference,
            )
        )
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

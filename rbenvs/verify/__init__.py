"""``rbenvs verify``: simulate what the theorems speak of and compare with the oracles.

Each check prints one row (system, integrator, check, predicted, measured, tolerance,
PASS/FAIL); the command exits non-zero on any FAIL. Cases are drawn at random from documented
ranges with a seed (``--seed``), never hand-picked; a failing row carries its parameters so it
can be replayed. The oracles (:mod:`rbenvs.oracles`) give the predictions only: what is
measured comes from the simulation.

Systems (``--system``, repeatable; default all):

* ``free_body``: :mod:`rbenvs.verify.free_body` (docs/physics.md §1): exact solution, invariants,
  axis stability and growth rate, torque balance; a fast tumble (30 rad/s) against the exact
  solution and its invariants; and, for the schemes ``tolerance=`` takes,
  :mod:`rbenvs.verify.tolerance`: the error of an episode run with a tolerance and the global
  error estimate's bound on it, against the exact solution;
* ``heavy_top``: :mod:`rbenvs.verify.heavy_top` (docs/physics.md §2): critical spin by bisection,
  upright stable above / unstable below with the growth rate, regular precession held, fast
  top nutation, invariants; the threshold of small fast tops (critical spin ~100 rad/s). Not for
  ``exact`` (the heavy top has no exact flow).
* ``tippe_top``: :mod:`rbenvs.verify.tippe_top` (docs/physics.md §3): Jellett's integral held under
  Coulomb and viscous friction, without friction, rolling and on a moving table; the energy
  non-increasing under friction and conserved without; inversion where the criterion says and
  the final tilt at the minimum of ``E*``, for tops below, inside and above the window
  ``1 - alpha < A/C < 1 + alpha``; the time to pass 90 degrees converged in the step (rk4).
  For euler, rk4 and dop853 (the tippe top has no splitting or exact flow).

``--simulator SPEC`` (repeatable) runs the same checks on another engine through the
:class:`~rbenvs.verify.simulator.Simulator` contract:
``mujoco[:integrator=RK4+implicitfast,dt=1e-3,...]`` (:mod:`rbenvs.verify.mujoco_adapter`, the
``mujoco`` extra), ``rbenvs[:integrator=rk4,dt=...]`` or a user's step function
``module:function[,dt=...,order=...]``; rows an engine cannot run read n/a, tolerances are scaled to
its step (docs/verification.md, "Any simulator"), and ``--comparison`` prints one table with a
column per simulator. :func:`rbenvs.testing.verify` is the same for a user's test suite.

``--sweep`` (with ``--system tippe_top`` or alone) runs, instead of the checks, the sweep of the
tippe top's final tilt over a grid of ``A/C`` (below, inside and above the window) and
``alpha`` (:func:`rbenvs.verify.tippe_top.sweep`): a table of the predicted class and final tilt
against the simulated one (``--quick``: 3 points); ``--plot PATH`` also draws it (needs
matplotlib: the ``plot`` extra).
"""

from __future__ import annotations

import json
import math
import sys
from dataclasses import asdict

from ..integrators import INTEGRATORS, get_integrator
from ..progress import Progress
from ..render.common import plot_unavailable
from . import tippe_top as _tippe
from .common import ROUND_OFF, Check, reference_scheme
from .free_body import FAST_TUMBLE_BODIES, FREE_BODY_SETTINGS, free_body_checks
from .heavy_top import HEAVY_TOP_SETTINGS, SMALL_TOP_CASES, heavy_top_checks
from .simulator import parse_simulator
from .tippe_top import TIPPE_TOP_SETTINGS, tippe_top_checks
from .tolerance import tolerance_checks, tolerance_integrators

__all__ = [
    "Check",
    "ROUND_OFF",
    "FREE_BODY_SETTINGS",
    "HEAVY_TOP_SETTINGS",
    "TIPPE_TOP_SETTINGS",
    "SYSTEMS",
    "free_body_checks",
    "heavy_top_checks",
    "tippe_top_checks",
    "run_sweep",
    "run_checks",
    "print_table",
    "main",
]

SYSTEMS = ("free_body", "heavy_top", "tippe_top")

# random cases per system: (quick, full)
FREE_BODY_CASES = (2, 8)
TOLERANCE_CASES = (2, 6)  # free bodies run with tolerance= (rbenvs.verify.tolerance)
HEAVY_TOP_CASES = (1, 6)


def run_checks(
    systems=SYSTEMS, integrators=None, quick=False, seed=0, show_progress=True, simulators=None
) -> list[Check]:
    """Every check of ``systems`` for ``integrators`` (default: all registered), in that order;
    or, given ``simulators`` (:class:`~rbenvs.verify.simulator.Simulator` objects), for those:
    each at its own step, the rows it cannot run reading n/a."""
    if simulators is not None:
        return _run_simulators(systems, list(simulators), quick, seed, show_progress)
    integrators = list(integrators or INTEGRATORS)
    for name in integrators:
        get_integrator(name)  # ValueError naming the integrator if unknown
    unknown = [s for s in systems if s not in SYSTEMS]
    if unknown:
        raise ValueError(f"system must be one of {list(SYSTEMS)}, got {unknown[0]!r}")
    fb = [n for n in integrators if n in FREE_BODY_SETTINGS] if "free_body" in systems else []
    ht = [n for n in integrators if n in HEAVY_TOP_SETTINGS] if "heavy_top" in systems else []
    tt = [n for n in integrators if n in TIPPE_TOP_SETTINGS] if "tippe_top" in systems else []
    unverified = _unverified(systems, integrators)
    n_fb, n_fast = FREE_BODY_CASES[0 if quick else 1], FAST_TUMBLE_BODIES[0 if quick else 1]
    n_ht, n_small = HEAVY_TOP_CASES[0 if quick else 1], SMALL_TOP_CASES[0 if quick else 1]
    n_tol = TOLERANCE_CASES[0 if quick else 1]
    total = (
        len(fb) * (n_fb + 1 + n_fast)
        + len(tolerance_integrators(fb)) * n_tol * 3
        + len(ht) * (n_ht + n_small)
        + _tippe.progress_total(tt, quick=quick)
    )
    progress = Progress(total=total, enabled=show_progress, desc="verify")
    checks = list(unverified)
    if fb:
        checks += free_body_checks(
            fb, seed=seed, n_cases=n_fb, progress=progress.update, n_fast=n_fast
        )
        checks += tolerance_checks(fb, seed=seed, n_cases=n_tol, progress=progress.update)
    if ht:
        checks += heavy_top_checks(
            ht, seed=seed, n_tops=n_ht, progress=progress.update, n_small=n_small
        )
    if tt:
        checks += tippe_top_checks(tt, seed=seed, quick=quick, progress=progress.update)
    progress.close()
    return checks


def _run_simulators(systems, sims, quick, seed, show_progress) -> list[Check]:
    unknown = [s for s in systems if s not in SYSTEMS]
    if unknown:
        raise ValueError(f"system must be one of {list(SYSTEMS)}, got {unknown[0]!r}")
    n_fb, n_fast = FREE_BODY_CASES[0 if quick else 1], FAST_TUMBLE_BODIES[0 if quick else 1]
    n_ht, n_small = HEAVY_TOP_CASES[0 if quick else 1], SMALL_TOP_CASES[0 if quick else 1]
    own = [s.integrator.name if s.dt is None else reference_scheme(s.order) for s in sims]
    total = len(sims) * (
        (n_fb + 1 + n_fast) * ("free_body" in systems) + (n_ht + n_small) * ("heavy_top" in systems)
    )
    total += _tippe.progress_total(own, quick=quick) if "tippe_top" in systems else 0
    progress = Progress(total=total, enabled=show_progress, desc="verify")
    checks: list[Check] = []
    # one simulator at a time, each from the same seed: every simulator meets the same random
    # bodies and starts, so that a comparison's columns are the same cases
    for system, family in (
        (
            "free_body",
            lambda sim: free_body_checks(
                [sim], seed=seed, n_cases=n_fb, progress=progress.update, n_fast=n_fast
            ),
        ),
        (
            "heavy_top",
            lambda sim: heavy_top_checks(
                [sim], seed=seed, n_tops=n_ht, progress=progress.update, n_small=n_small
            ),
        ),
        (
            "tippe_top",
            lambda sim: tippe_top_checks([sim], seed=seed, quick=quick, progress=progress.update),
        ),
    ):
        if system in systems:
            for sim in sims:
                checks += family(sim)
    progress.close()
    return checks


def _unverified(systems, integrators) -> list[Check]:
    """A FAIL row for every integrator that a system supports but that has no verification
    settings for it: a new scheme is reported as unverified, never silently skipped."""
    from ..dynamics import FreeBody, HeavyTop, TippeTop

    rows = []
    tables = {
        "free_body": (FreeBody, FREE_BODY_SETTINGS),
        "heavy_top": (HeavyTop, HEAVY_TOP_SETTINGS),
        "tippe_top": (TippeTop, TIPPE_TOP_SETTINGS),
    }
    for system in systems:
        system_class, settings = tables[system]
        for name in integrators:
            integ = get_integrator(name)
            if name not in settings and set(integ.requires) <= system_class.provides:
                rows.append(
                    Check(
                        system,
                        name,
                        f"verification settings for {name!r} (none: add its row to the {system} "
                        "table of rbenvs/verify/settings.py)",
                        0.0,
                        math.nan,
                        0.0,
                    )
                )
    return rows


def run_sweep(quick=False, show_progress=True):
    """The tippe top's final-tilt sweep (:func:`rbenvs.verify.tippe_top.sweep`); ``quick``: 3
    points."""
    alphas, offsets = _tippe.SWEEP_QUICK if quick else (_tippe.SWEEP_ALPHAS, _tippe.SWEEP_OFFSETS)
    progress = Progress(total=len(alphas) * len(offsets), enabled=show_progress, desc="sweep")
    points = _tippe.sweep(alphas, offsets, progress=progress.update)
    progress.close()
    return points


def _fmt(x):
    return f"{x:.3e}" if (x != 0 and (abs(x) < 1e-3 or abs(x) >= 1e4)) else f"{x:.4f}"


def print_table(checks, file=None):
    file = sys.stdout if file is None else file
    rows = [("system", "integrator", "check", "predicted", "measured", "tolerance", "result")]
    for c in checks:
        if not c.applies:
            rows.append((c.system, c.integrator, c.check, "-", "-", "-", f"n/a ({c.reason})"))
            continue
        tol = f"{c.tolerance:.0e}" + (" rel" if c.relative else "")
        rows.append(
            (c.system, c.integrator, c.check, _fmt(c.predicted), _fmt(c.measured), tol, c.result)
        )
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    for n, r in enumerate(rows):
        print("  ".join(x.ljust(w) for x, w in zip(r, widths)).rstrip(), file=file)
        if n == 0:
            print("  ".join("-" * w for w in widths), file=file)
    failed = [c for c in checks if not c.passed]
    na = sum(not c.applies for c in checks)
    print(
        f"\n{len(checks) - len(failed) - na} passed, {len(failed)} failed"
        + (f", {na} n/a" if na else ""),
        file=file,
    )
    for c in failed:
        print(f"FAILED {c.system}/{c.integrator}/{c.check}: replay with {c.case}", file=file)


def _parser():
    from ..extras import ArgumentParser  # (suggests the closest choice)

    parser = ArgumentParser(
        prog="rbenvs verify",
        description="Simulate what the theorems speak of and compare with the oracles.",
    )
    parser.add_argument("--quick", action="store_true", help="fewer random cases, for CI")
    parser.add_argument(
        "--seed", type=int, default=0, help="seed of the random cases (default: %(default)s)"
    )
    parser.add_argument(
        "--system",
        action="append",
        choices=SYSTEMS,
        help="restrict to these systems (repeatable; default all)",
    )
    parser.add_argument(
        "--integrator", action="append", help="restrict to these integrators (repeatable)"
    )
    parser.add_argument(
        "--simulator",
        action="append",
        metavar="SPEC",
        help="run the checks on another simulator at its own step (repeatable): "
        "mujoco[:integrator=RK4+implicitfast,dt=1e-3,...], "
        "rbenvs[:integrator=rk4,dt=1e-3] or module:function[,dt=1e-3,order=1] "
        "(docs/verification.md)",
    )
    parser.add_argument(
        "--comparison",
        action="store_true",
        help="with --simulator: print, instead of the rows, one Markdown table "
        "(a row per check, a column per simulator) "
        "and exit 0 whatever it shows: a report, not a gate (--docs PAGE writes it into the page)",
    )
    parser.add_argument("--json", metavar="PATH", help="also write a machine-readable report")
    parser.add_argument("--no-progress", action="store_true", help="no progress on stderr")
    parser.add_argument(
        "--sweep",
        action="store_true",
        help="instead of the checks: the tippe top's final tilt over a grid of A/C and alpha, "
        "predicted against simulated",
    )
    parser.add_argument(
        "--plot",
        metavar="PATH",
        help="with --sweep: also draw the sweep to this PNG (needs matplotlib)",
    )
    return parser


def main(argv=None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    if args.plot and not args.sweep:
        parser.error("--plot needs --sweep")
    if args.sweep:
        if args.system and args.system != ["tippe_top"]:
            parser.error("--sweep is the tippe top's: use it alone or with --system tippe_top")
        if args.integrator:
            parser.error("--sweep runs rk4 only: leave out --integrator")
        return _sweep_main(args)
    if args.comparison and not args.simulator:
        parser.error("--comparison needs --simulator")
    if args.simulator and args.integrator:
        parser.error(
            "--integrator picks rbenvs' integrators: with --simulator name them as "
            "rbenvs:integrator=NAME"
        )
    sims = (
        [sim for spec in args.simulator for sim in parse_simulator(spec)]
        if args.simulator
        else None
    )
    checks = run_checks(
        systems=tuple(args.system or SYSTEMS),
        integrators=args.integrator,
        quick=args.quick,
        seed=args.seed,
        show_progress=not args.no_progress,
        simulators=sims,
    )
    if args.json:
        with open(args.json, "w") as f:
            json.dump(
                [asdict(c) | {"passed": c.passed, "result": c.result} for c in checks], f, indent=1
            )
    if args.comparison:
        from .comparison import comparison_table

        print("\n".join(comparison_table(checks)))
        return 0
    print_table(checks)
    return 0 if all(c.passed for c in checks) else 1


def _sweep_main(args) -> int:
    if args.plot and plot_unavailable("rbenvs verify"):  # fail before the long run, not after it
        return 2
    points = run_sweep(quick=args.quick, show_progress=not args.no_progress)
    _tippe.print_sweep(points)
    if args.plot:
        _tippe.plot_sweep(points, args.plot)
        print(f"plot written to {args.plot}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump([asdict(p) | {"passed": p.passed} for p in points], f, indent=1)
    return 0 if all(p.passed for p in points) else 1

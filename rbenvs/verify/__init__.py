"""``rbenvs verify``: simulate what the theorems speak of and compare with the oracles.

Each check prints one row (system, integrator, check, predicted, measured, tolerance,
PASS/FAIL); the command exits non-zero on any FAIL. Cases are drawn at random from documented
ranges with a seed (``--seed``), never hand-picked; a failing row carries its parameters so it
can be replayed. The oracles (:mod:`rbenvs.oracles`) give the predictions only: what is
measured comes from the simulation.

Systems (``--system``, repeatable; default all):

* ``free_body``: :mod:`rbenvs.verify.free_body` (physics.md §1): exact solution, invariants,
  axis stability and growth rate, torque balance;
* ``heavy_top``: :mod:`rbenvs.verify.heavy_top` (physics.md §2): critical spin by bisection,
  upright stable above / unstable below with the growth rate, regular precession held, fast
  top nutation, invariants. Not for ``exact`` (the heavy top has no exact flow).
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import asdict

from ..integrators import INTEGRATORS, get_integrator
from .common import ROUND_OFF, Check
from .free_body import FREE_BODY_SETTINGS, free_body_checks
from .heavy_top import HEAVY_TOP_SETTINGS, heavy_top_checks

__all__ = [
    "Check",
    "ROUND_OFF",
    "FREE_BODY_SETTINGS",
    "HEAVY_TOP_SETTINGS",
    "SYSTEMS",
    "free_body_checks",
    "heavy_top_checks",
    "run_checks",
    "print_table",
    "main",
]

SYSTEMS = ("free_body", "heavy_top")

# random cases per system: (quick, full)
FREE_BODY_CASES = (2, 8)
HEAVY_TOP_CASES = (1, 6)


def run_checks(systems=SYSTEMS, integrators=None, quick=False, seed=0, show_progress=True) -> list[Check]:
    """Every check of ``systems`` for ``integrators`` (default: all registered), in that order."""
    integrators = list(integrators or INTEGRATORS)
    for name in integrators:
        get_integrator(name)  # ValueError naming the integrator if unknown
    unknown = [s for s in systems if s not in SYSTEMS]
    if unknown:
        raise ValueError(f"system must be one of {list(SYSTEMS)}, got {unknown[0]!r}")
    fb = [n for n in integrators if n in FREE_BODY_SETTINGS] if "free_body" in systems else []
    ht = [n for n in integrators if n in HEAVY_TOP_SETTINGS] if "heavy_top" in systems else []
    n_fb = FREE_BODY_CASES[0 if quick else 1]
    n_ht = HEAVY_TOP_CASES[0 if quick else 1]
    progress = _Progress(total=len(fb) * (n_fb + 1) + len(ht) * n_ht, enabled=show_progress)
    checks = []
    if fb:
        checks += free_body_checks(fb, seed=seed, n_cases=n_fb, progress=progress.update)
    if ht:
        checks += heavy_top_checks(ht, seed=seed, n_tops=n_ht, progress=progress.update)
    progress.close()
    return checks


class _Progress:
    """tqdm when installed (the cli extra), otherwise silent."""

    def __init__(self, total, enabled):
        self.bar = None
        if enabled:
            try:
                from tqdm import tqdm

                self.bar = tqdm(total=total, desc="verify", file=sys.stderr, leave=False)
            except ImportError:
                pass

    def update(self):
        if self.bar is not None:
            self.bar.update()

    def close(self):
        if self.bar is not None:
            self.bar.close()


def _fmt(x):
    return f"{x:.3e}" if (x != 0 and (abs(x) < 1e-3 or abs(x) >= 1e4)) else f"{x:.4f}"


def print_table(checks, file=None):
    file = sys.stdout if file is None else file
    rows = [("system", "integrator", "check", "predicted", "measured", "tolerance", "result")]
    for c in checks:
        tol = f"{c.tolerance:.0e}" + (" rel" if c.relative else "")
        rows.append((c.system, c.integrator, c.check, _fmt(c.predicted), _fmt(c.measured), tol, "PASS" if c.passed else "FAIL"))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    for n, r in enumerate(rows):
        print("  ".join(x.ljust(w) for x, w in zip(r, widths)).rstrip(), file=file)
        if n == 0:
            print("  ".join("-" * w for w in widths), file=file)
    failed = [c for c in checks if not c.passed]
    print(f"\n{len(checks) - len(failed)} passed, {len(failed)} failed", file=file)
    for c in failed:
        print(f"FAILED {c.system}/{c.integrator}/{c.check}: replay with {c.case}", file=file)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="rbenvs verify", description="Simulate what the theorems speak of and compare with the oracles.")
    parser.add_argument("--quick", action="store_true", help="fewer random cases (under a minute, for CI)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--system", action="append", choices=SYSTEMS, help="restrict to these systems (repeatable; default all)")
    parser.add_argument("--integrator", action="append", help="restrict to these integrators (repeatable)")
    parser.add_argument("--json", metavar="PATH", help="also write a machine-readable report")
    parser.add_argument("--no-progress", action="store_true")
    args = parser.parse_args(argv)
    checks = run_checks(systems=tuple(args.system or SYSTEMS), integrators=args.integrator, quick=args.quick, seed=args.seed,
                        show_progress=not args.no_progress)
    print_table(checks)
    if args.json:
        with open(args.json, "w") as f:
            json.dump([asdict(c) | {"passed": c.passed} for c in checks], f, indent=1)
    return 0 if all(c.passed for c in checks) else 1

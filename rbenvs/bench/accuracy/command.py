"""``rbenvs bench accuracy``'s command line."""

from __future__ import annotations

import argparse

from ...extras import ArgumentParser, require
from ...progress import Progress
from ...render.common import plot_unavailable
from .convergence import CASES, FIT_CEILING, FIT_FLOOR, TARGET
from .measure import run
from .mujoco import progress_total
from .report import _write_json, plot, print_report
from .scenes import _tippe_main, run_scenes


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


def _tolerance_cases():
    from ..tolerance import TOLERANCE_CASES

    return TOLERANCE_CASES


def _parser() -> ArgumentParser:
    """The command's options, in the order ``--help`` lists them."""
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
    _add_single_table_options(parser)
    parser.add_argument("--no-progress", action="store_true", help="no progress on stderr")
    return parser


def _add_single_table_options(parser) -> None:
    """The options that run one table alone: ``--tolerance`` (with ``--case``), ``--roundoff``,
    ``--floor`` and ``--tippe``."""
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
        "--tippe-sweep",
        action="store_true",
        help="only the tippe top's accuracy bound over the 15 tops it is held over "
        "(rbenvs.bench.tippe_steps.SWEEP): per top the time to 90 degrees and its error against "
        "rk4 at 2560 steps a period, Jellett's drift per second and the steps a period",
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


def _roundoff_main(args) -> int:
    """``--roundoff``: :mod:`rbenvs.bench.roundoff`'s table."""
    from ..roundoff import OFF, STARTS, print_roundoff, run_roundoff

    return _table(args, "--roundoff", len(OFF) * 2 * STARTS, run_roundoff, print_roundoff)


def _floor_main(args) -> int:
    """``--floor``: :mod:`rbenvs.bench.floor`'s table."""
    from ..floor import OFF, TOLERANCES, print_floor, run_floor

    require("reference")  # mpmath, the reference: say so before the run, not after it
    return _table(args, "--floor", len(OFF) * len(TOLERANCES), run_floor, print_floor)


def _tolerance_main(args, parser) -> int:
    """``--tolerance``: :mod:`rbenvs.bench.tolerance`'s table, its rows chosen by ``--case``
    (an unknown key is a usage error, before the run)."""
    from ..tolerance import all_cases, print_tolerance, run_tolerance

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


def _full_main(args) -> int:
    """The whole bench: every case's convergence and drift (:func:`.measure.run`), the scenes'
    recommendation unless ``--no-scenes`` (off by default with ``--quick``), the report, the
    plot and the JSON."""
    if args.plot and plot_unavailable("rbenvs bench accuracy"):
        return 2  # fail before the long run, not after it
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


def main(argv=None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    if args.case and not args.tolerance:
        parser.error("--case selects rows of the --tolerance table: pass --tolerance")
    if args.tippe_sweep:
        from ..tippe_steps import sweep_table

        print(sweep_table())
        return 0
    if args.tippe:
        return _tippe_main(args)
    if args.roundoff:
        return _roundoff_main(args)
    if args.floor:
        return _floor_main(args)
    if args.tolerance:
        return _tolerance_main(args, parser)
    return _full_main(args)

"""``rbenvs bench throughput``'s command line: the tables it runs and prints."""

from __future__ import annotations

import json
from dataclasses import dataclass

from ...compiled import available
from ...extras import ArgumentParser
from ...progress import Progress
from .runs import (
    CHECK_NUM_ENVS,
    CHECK_SETTINGS,
    LARGEST,
    SCALING_SIZES,
    SIZES,
    SYSTEMS,
    compiled_speedup,
    print_check,
    run_check,
    run_sb3,
    run_scaling,
    run_single,
    run_vector,
)
from .tasks import (
    QUICK_NUM_ENVS,
    QUICK_SLOW_NUM_ENVS,
    QUICK_SLOW_STEP_S,
    TASK_NUM_ENVS,
    _matches,
    print_tasks,
    run_tasks,
    task_settings,
)

TABLES = ("tasks", "integrators", "scaling", "sb3", "check")
QUICK_TABLES = (
    "tasks",
    "sb3",
)  # --quick: a smoke run (the kernels' compilation is most of it)


_FREE = SYSTEMS[0][0]


@dataclass(frozen=True)
class _Plan:
    """What one run measures: the rows ``--tables`` and ``--only`` select, and the timing
    settings ``--quick`` picks."""

    quick: bool
    num_envs: int
    sizes: tuple
    min_time: float
    budget: float
    settings: list
    notes: list
    systems: tuple
    do_scaling: bool
    do_sb3: bool
    checks: tuple


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    plan = _plan(args, _tables(args))
    bar = Progress(_progress_total(plan), not args.no_progress, "bench throughput")
    results = _run(plan, bar.update)
    bar.close()
    _print_results(results)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1)
    return 0


def _parser() -> ArgumentParser:
    parser = ArgumentParser(
        prog="rbenvs bench throughput",
        description="Env-steps per second against Pendulum-v1 and CartPole-v1's native vector env: "
        "every (id, task) and named scene, with the compiled kernel's time beside (the gap to the "
        "limit), then per integrator.",
    )
    parser.add_argument("--json", metavar="PATH", help="also write the figures as JSON")
    parser.add_argument(
        "--quick",
        action="store_true",
        help=f"shorter timings: the task table at N = {QUICK_NUM_ENVS} "
        f"(slow settings at {QUICK_SLOW_NUM_ENVS}) "
        "and the SB3 rows by default; an integrator table asked for with --tables at sizes 1 and "
        "256; never the scaling table",
    )
    parser.add_argument(
        "--num-envs",
        type=int,
        metavar="N",
        help=(
            f"task table: sub-envs of the vector env (default: {TASK_NUM_ENVS}, "
            f"{QUICK_NUM_ENVS} with --quick)"
        ),
    )
    parser.add_argument(
        "--only",
        metavar="SUBSTRING",
        help="only the rows whose id, task, scene name or integrator contains SUBSTRING (any case)",
    )
    parser.add_argument(
        "--tables",
        metavar="LIST",
        help=(
            f"comma-separated tables to run, of {', '.join(TABLES)} "
            f"(default: all; with --quick: {','.join(QUICK_TABLES)})"
        ),
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress on stderr")
    return parser


def _tables(args) -> list[str]:
    """The tables ``--tables`` names (default: all, or :data:`QUICK_TABLES` with ``--quick``)."""
    tables = [
        t.strip()
        for t in (args.tables or ",".join(QUICK_TABLES if args.quick else TABLES)).split(",")
        if t.strip()
    ]
    unknown = [t for t in tables if t not in TABLES]
    if unknown:
        raise ValueError(f"--tables: unknown table {unknown[0]!r}; choose from {', '.join(TABLES)}")
    return tables


def _plan(args, tables: list[str]) -> _Plan:
    """The rows of ``tables`` that ``--only`` keeps, and the timings; a ``ValueError`` where
    no row is left."""
    if args.num_envs is not None and args.num_envs < 1:
        raise ValueError(f"--num-envs must be >= 1, got {args.num_envs}")
    only = args.only
    # the other tables, filtered by --only on id or integrator
    systems = tuple((i, tuple(x for x in ints if _matches(only, i, x))) for i, ints in SYSTEMS)
    systems = tuple((i, ints) for i, ints in systems if ints) if "integrators" in tables else ()
    do_scaling = "scaling" in tables and not args.quick and _matches(only, _FREE, "rk4")
    do_sb3 = "sb3" in tables and _matches(only, _FREE, "rk4")
    settings, notes = task_settings(only) if "tasks" in tables else ([], [])
    checks = (
        tuple(c for c in CHECK_SETTINGS if _matches(only, c[0], c[1] or "", c[2] or ""))
        if "check" in tables
        else ()
    )
    if not (settings or systems or do_scaling or do_sb3 or checks):
        raise ValueError(f"--only {only!r} matches no row of the tables {', '.join(tables)}")
    return _Plan(
        quick=args.quick,
        num_envs=args.num_envs or (QUICK_NUM_ENVS if args.quick else TASK_NUM_ENVS),
        sizes=(1, 256) if args.quick else SIZES,
        min_time=0.05 if args.quick else 0.2,
        budget=0.2 if args.quick else 1.0,
        settings=settings,
        notes=notes,
        systems=systems,
        do_scaling=do_scaling,
        do_sb3=do_sb3,
        checks=checks,
    )


def _progress_total(plan: _Plan) -> int:
    """How many times the tables of ``plan`` call ``progress()``."""
    sizes, systems = plan.sizes, plan.systems
    n_tasks = 4 * len(plan.settings)
    n_single = sum(len(i) for _, i in systems)
    combos_extra = (
        (2 if available() else 1) if any(i == _FREE and "rk4" in ints for i, ints in systems) else 0
    )
    n_vector = sum(
        1 for _, ints in systems for i in ints for n in sizes if n <= LARGEST.get(i, max(sizes))
    ) + combos_extra * len(sizes)
    n_scaling = (2 if available() else 1) * len(SCALING_SIZES) if plan.do_scaling else 0
    n_check = (3 + 3 * len(CHECK_NUM_ENVS)) * len(plan.checks)
    return n_tasks + n_single + n_vector + n_scaling + n_check


def _run(plan: _Plan, progress) -> dict:
    """Every table of ``plan`` in turn, as the JSON holds them (an empty list for one not run)."""
    results = {"tasks": _run_task_table(plan, progress), "task_notes": plan.notes}
    systems, sizes, min_time = plan.systems, plan.sizes, plan.min_time
    legacy_budget = plan.budget if plan.quick else None  # the full run: every round, no budget
    results["single"] = (
        run_single(systems, min_time=min_time, progress=progress, budget=legacy_budget)
        if systems
        else []
    )
    results["vector"] = (
        run_vector(systems, sizes=sizes, min_time=min_time, progress=progress, budget=legacy_budget)
        if systems
        else []
    )
    results["scaling"] = (
        run_scaling(min_time=min_time, progress=progress) if plan.do_scaling else []
    )
    results["sb3"] = run_sb3(sizes=(16, 256), min_time=min_time) if plan.do_sb3 else []
    results["check"] = (
        run_check(plan.checks, min_time=min_time, budget=plan.budget, progress=progress)
        if plan.checks
        else []
    )
    return results


def _run_task_table(plan: _Plan, progress) -> list[dict]:
    if not plan.settings:
        return []
    # --quick: a smoke run, its figures rough
    quick = plan.quick
    tasks, _ = run_tasks(
        plan.settings,
        num_envs=plan.num_envs,
        min_time=0.02 if quick else plan.min_time,
        repeat=2 if quick else 3,
        budget=plan.budget,
        slow_step_s=QUICK_SLOW_STEP_S if quick else None,
        slow_num_envs=QUICK_SLOW_NUM_ENVS if quick else None,
        progress=progress,
    )
    return tasks


def _print_results(results: dict) -> None:
    if results["tasks"]:
        print_tasks(results["tasks"], results["task_notes"])
    elif results["task_notes"]:
        print("\n".join(results["task_notes"]))
    _print_single(results["single"])
    _print_vector(results["vector"])
    _print_speedup(compiled_speedup(results["vector"]))
    _print_scaling(results["scaling"])
    _print_sb3(results["sb3"])
    if results["check"]:
        print_check(results["check"])


def _print_single(rows: list[dict]) -> None:
    if not rows:
        return
    print("\nsingle env: one step of gymnasium.make(id) against Pendulum-v1, same run (us)")
    print(f"{'id':<26} {'integrator':<10} {'ours':>9} {'Pendulum':>9} {'ratio':>7}")
    for r in rows:
        print(
            f"{r['id']:<26} {r['integrator']:<10} {r['step_us']:>9.2f} "
            f"{r['pendulum_step_us']:>9.2f} {r['ratio_to_pendulum']:>7.3f}"
        )


def _print_vector(rows: list[dict]) -> None:
    if not rows:
        return
    print(
        "\nvector env (vector_entry_point, zero action) against CartPole-v1's native vector "
        "env, same run"
    )
    print(
        f"{'id':<26} {'integrator':<16} {'path':<9} {'num_envs':>8} {'env-steps/s':>13} "
        f"{'ns/env':>9} {'CartPole/s':>13} {'ratio':>8}"
    )
    for r in rows:
        print(
            f"{r['id']:<26} {r['integrator']:<16} {r['path']:<9} {r['num_envs']:>8d} "
            f"{r['env_steps_per_s']:>13.4g} {r['ns_per_env_step']:>9.1f} "
            f"{r['cartpole_env_steps_per_s']:>13.4g} {r['ratio_to_cartpole']:>8.3f}"
        )


def _print_speedup(paths: list[tuple[int, float]]) -> None:
    if not paths:
        return
    print("\ncompiled step against the numpy path of the same env (free body, rk4), same run")
    for n, ratio in paths:
        print(f"  num_envs {n:>5d}: {ratio:.2f}x")


def _print_scaling(rows: list[dict]) -> None:
    if not rows:
        return
    print(
        "\nscaling: the free body with rk4, time per env-step against num_envs, and the arrays "
        "one step moves"
    )
    print(f"{'path':<9} {'num_envs':>8} {'ns/env':>9} {'bytes/env':>10} {'MB/step':>9}")
    for r in rows:
        print(
            f"{r['path']:<9} {r['num_envs']:>8d} {r['ns_per_env_step']:>9.1f} "
            f"{r['bytes_per_env_step']:>10.0f} {r['megabytes_per_step']:>9.3f}"
        )


def _print_sb3(rows: list[dict]) -> None:
    if not rows:
        return
    print(
        "\nstable-baselines3 VecEnv.step: the native adapter (rbenvs.vector.sb3) against "
        "DummyVecEnv, same run"
    )
    print(f"{'id':<26} {'num_envs':>8} {'native/s':>12} {'Dummy/s':>12} {'ratio':>8}")
    for r in rows:
        print(
            f"{r['id']:<26} {r['num_envs']:>8d} {r['sb3_native_env_steps_per_s']:>12.4g} "
            f"{r['sb3_dummy_env_steps_per_s']:>12.4g} {r['ratio']:>8.2f}"
        )

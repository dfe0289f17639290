"""The ``rbenvs`` command line (also ``python -m rbenvs``).

* ``rbenvs list``: every registered id with its tasks, ``max_episode_steps`` and reward threshold.
* ``rbenvs scenes``: the named scenes under ``configs/scenes`` (shipped as ``rbenvs.configs``;
  ``$RBENVS_CONFIGS`` replaces them, see :func:`rbenvs.configs.configs_root`).
* ``rbenvs run [--scene NAME ...] [--episodes N] [--seed S]``: the analytic baselines. Runs scenes
  (by default the headline scene of each system) with their analytic controller and with no
  control, and prints an episode summary per scene (return, success, the task's final
  measure, and the invariants at start and end).
* ``rbenvs verify [--quick] [--json PATH] [--seed S] [--system NAME] [--sweep [--plot PNG]]``:
  simulator against the oracles (:mod:`rbenvs.verify`); exits non-zero on any failure.
  ``--simulator SPEC`` (repeatable) runs the same checks on another engine (``mujoco[:...]``,
  ``rbenvs[:...]`` or a user's ``module:function``), ``--comparison`` prints them as one table.
* ``rbenvs cache info`` / ``rbenvs cache clear [--stale]``: the compiled kernels kept on disk
  (:mod:`rbenvs.kernel_cache`): the folder, its kernels per environment, deleting them.
* ``rbenvs warmup [--system NAME ...]``: compiles what each system's default single env and
  vector env run into that cache ahead (container images, CI caches).
* ``rbenvs bench fidelity``: the tippe top's fidelity levels, each against gliding friction.
* ``rbenvs bench throughput [--quick] [--json PATH] [--num-envs N] [--only TEXT] [--tables LIST]``:
  env-steps per second of every task and scene, single and vector (random actions, restarts
  included), against
  Pendulum-v1 and CartPole-v1's native vector env, with the compiled kernel's own time.
* ``rbenvs bench startup [--system NAME] [--repeat N]``: seconds from a fresh process to its first
  step, cold and warm kernel cache, single env and vector env, against Pendulum-v1, CartPole-v1's
  vector env and MuJoCo; ``AsyncVectorEnv(context="spawn")``'s reset.
* ``rbenvs bench threads [--num-envs N] [--threads LIST]``: the vector env's rate with
  ``num_threads`` 1, 2 and every core, against CartPole-v1's vector env, and whether the bits agree.
* ``rbenvs bench costs [--skip-tests]``: what the README's two commands cost here (the venv,
  the main job, the test suite's wall and CPU time, ``verify --quick``; :mod:`rbenvs.bench.costs`).
* ``rbenvs bench render [--frames N]``: milliseconds per ``rgb_array`` frame, beside
  ``Pendulum-v1``'s (:mod:`rbenvs.bench.render`).
* ``rbenvs bench accuracy [--quick] [--json PATH] [--plot PNG] [--system NAME] [--tippe]
  [--tippe-sweep]``: error, order, invariant drift and cost of every integrator on every system,
  and a recommended integrator per scene (:mod:`rbenvs.bench.accuracy`).
* ``rbenvs plot [WHAT ...] [--out DIR] [--quick]``: PNG figures (:mod:`rbenvs.plotting`; needs
  the ``plot`` extra): ``free_body``, ``heavy_top``, ``tippe_top``, ``frames`` (one rendered
  frame per system) or ``all`` (the default; the pictures under ``docs/``).

Every command takes ``--docs PAGE``: its output is written into the page's block for the same
command line (:mod:`rbenvs.docblocks`). A command that needs an extra it lacks (``scenes``, ``run``
and the scenes of ``bench accuracy`` need ``cli``, for PyYAML; ``plot`` needs ``plot``) says which
in one line and exits with status 2, as does bad input such as an unknown scene
(:func:`rbenvs.extras.run_command`).
"""

from __future__ import annotations

import argparse
import importlib
import sys

import numpy as np

__all__ = ["main"]


def _cmd_list(args) -> int:
    import gymnasium as gym

    import rbenvs

    rows = [("id", "tasks", "max_episode_steps", "reward_threshold")]
    for env_id in rbenvs.ENVIRONMENTS:
        spec = gym.spec(env_id)
        cls = spec.entry_point
        if isinstance(cls, str):
            mod, name = cls.split(":")
            cls = getattr(__import__(mod, fromlist=[name]), name)
        rows.append(
            (env_id, ", ".join(cls.tasks), str(spec.max_episode_steps), str(spec.reward_threshold))
        )
    _print_table(rows)
    return 0


def _cmd_scenes(args) -> int:
    from .extras import require
    from .scenes import list_scenes, load_scene, no_scenes_found

    require("cli")
    if not list_scenes():
        raise ValueError(no_scenes_found())
    rows = [("scene", "id", "task", "description")]
    for name in list_scenes():
        s = load_scene(name)
        rows.append((name, s.env_id, str(s.kwargs.get("task", "")), s.description))
    _print_table(rows)
    return 0


def run_episode(env, policy, seed):
    """One episode; returns (return, first info, last info, steps)."""
    obs, info0 = env.reset(seed=seed)
    total, steps, done, info = 0.0, 0, False, info0
    while not done:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        total += reward
        steps += 1
        done = terminated or truncated
    return total, info0, info, steps


# rbenvs run's scenes: per system, the one where control matters (unstable without it).
MAIN_SCENES = ("default", "top_upright", "tippe_hold")


def _cmd_run(args) -> int:
    from .extras import require
    from .progress import Progress
    from .scenes import load_scene

    require("cli")
    scenes = [load_scene(name) for name in (args.scene or MAIN_SCENES)]  # fail before running any
    progress = Progress(
        2 * args.episodes * len(scenes), enabled=not args.no_progress, desc="rbenvs run: episodes"
    )
    for n, scene in enumerate(scenes):
        if n:
            print()
        _run_scene(scene, args, progress)
    progress.close()
    return 0


def _run_scene(scene, args, progress) -> None:
    from .controllers import ZeroController, controller_for

    env = scene.make()
    measure = (
        env.unwrapped.task.final_measure
    )  # the metric or read-out that summarises an episode's end
    print(f"scene {scene.name!r}: {scene.description}")
    print(f"  {scene.env_id} {scene.kwargs}")
    print(
        f"  dt = {env.unwrapped.dt} s, {env.spec.max_episode_steps} steps, integrator "
        f"{env.unwrapped.integrator.name}, {args.episodes} episodes from seed {args.seed}\n"
    )
    invariants = env.unwrapped.invariants
    rows = [
        ("controller", "return", "success", f"final {measure}")
        + tuple(f"{k} start -> end" for k in invariants)
        + ("steps",)
    ]
    # With zero torque the invariants must hold (up to the integrator's drift): a quick check.
    for label, make in (("analytic", controller_for), ("zero torque", ZeroController)):
        policy = make(env)
        results = []
        for k in range(args.episodes):
            results.append(run_episode(env, policy, args.seed + k))
            progress.update()
        ret = np.array([r[0] for r in results])
        succ = np.mean([r[2]["is_success"] for r in results])
        fin = np.mean([r[2][measure] for r in results])
        changes = []
        for key in invariants:
            v0 = np.mean([r[1][key] for r in results])
            v1 = np.mean([r[2][key] for r in results])
            rel = f" ({(v1 - v0) / abs(v0):+.1e})" if v0 != 0 else ""
            changes.append(f"{v0:.7g} -> {v1:.7g}{rel}")
        steps = np.mean([r[3] for r in results])
        rows.append(
            (
                f"{label} ({type(policy).__name__})",
                f"{ret.mean():.2f} +- {ret.std():.2f}",
                f"{succ:.0%}",
                f"{fin:.4f}",
                *changes,
                f"{steps:.0f}",
            )
        )
    _print_table(rows)
    env.close()


# The systems' ids by the names --system takes (those of rbenvs verify)
SYSTEM_IDS = {
    "free_body": "rbenvs/FreeRigidBody-v0",
    "heavy_top": "rbenvs/LagrangeTop-v0",
    "tippe_top": "rbenvs/TippeTop-v0",
}


def _cmd_cache(args) -> int:
    from . import kernel_cache

    if args.action == "clear":
        n = kernel_cache.clear(stale_only=args.stale)
        print(
            f"deleted {n} kernel file{'s' if n != 1 else ''}"
            + (" of other environments" if args.stale else "")
            + f" under {kernel_cache.cache_root()}"
        )
        return 0
    info = kernel_cache.info()
    if info["root"] is None:
        print(
            f"the kernel cache is off (${kernel_cache.CACHE_VARIABLE} is empty): kernels are "
            "compiled in memory in every process"
        )
        return 0
    print(f"root: {info['root']} (${kernel_cache.CACHE_VARIABLE} overrides)")
    print(f"this environment: {info['current'] or '(numba not installed: nothing is compiled)'}")
    if not info["folders"]:
        print("no kernels cached yet")
        return 0
    rows = [("environment", "kernel files", "MB", "")]
    for f in info["folders"]:
        rows.append(
            (
                f["name"],
                str(f["files"]),
                f"{f['bytes'] / 1e6:.1f}",
                "current" if f["name"] == info["current"] else "stale",
            )
        )
    _print_table(rows)
    return 0


def _cmd_warmup(args) -> int:
    """Compile (or load) what each system's default single env and vector env run: its first
    steps, as a user's first process would take them."""
    import rbenvs  # noqa: F401  (registers the ids)

    from . import kernel_cache
    from .jit import available
    from .progress import Progress

    if not available():
        print(
            "numba is not installed (or RBENVS_COMPILED=0): the envs run on numpy, nothing to "
            "compile; install the fast extra"
        )
        return 0
    systems = args.system or list(SYSTEM_IDS)
    progress = Progress(2 * len(systems), enabled=not args.no_progress, desc="rbenvs warmup")
    rows = [("system", "env", "compiled", "loaded", "s", "kernels (s each)")]
    for name in systems:
        for kind in ("single", "vector"):
            rows.append(_warmup_row(name, kind))
            progress.update()
    progress.close()
    _print_table(rows)
    print(
        "(a kernel already made in this process, by an earlier row, is neither compiled nor loaded "
        "again)"
    )
    folder = kernel_cache.kernel_folder()
    print(
        f"kernels in {folder}"
        if folder is not None
        else "the kernel cache is off: nothing was kept"
    )
    return 0


def _warmup_row(name, kind) -> tuple:
    """Take one env's first steps and return its warmup table row: kernels compiled and loaded
    on the way, seconds, and each new kernel's own compile time."""
    import time

    from . import kernel_cache

    before, first, t = (
        kernel_cache.stats(),
        len(kernel_cache.kernels()),
        time.perf_counter(),
    )
    env = _make_warmup_env(name, kind)
    env.reset(seed=0)
    env.step(env.action_space.sample())
    if kind == "vector":  # (float64 actions, a controller's or numpy's: a kernel of their own)
        env.step(np.zeros(env.action_space.shape))
    env.close()
    after = kernel_cache.stats()
    each = ", ".join(
        f"{label} {seconds:.1f}" for label, _, _, seconds in kernel_cache.kernels()[first:]
    )
    return (
        name,
        kind,
        str(after["compiled"] - before["compiled"]),
        str(after["loaded"] - before["loaded"]),
        f"{time.perf_counter() - t:.1f}",
        each,
    )


def _make_warmup_env(name, kind):
    """The system's default single env, or its vector env of two (the shape users start with)."""
    import gymnasium as gym

    if kind == "single":
        return gym.make(SYSTEM_IDS[name])
    return gym.make_vec(SYSTEM_IDS[name], num_envs=2, vectorization_mode="vector_entry_point")


def _cmd_bench_fidelity(args) -> int:
    from .bench.fidelity import main as bench_main

    return bench_main(progress=not args.no_progress, quick=args.quick)


PLOT_CHOICES = ("free_body", "heavy_top", "tippe_top", "frames", "all")


def _cmd_plot(args) -> int:
    import os

    from .render.common import require_matplotlib

    what = args.what or ["all"]
    unknown = [w for w in what if w not in PLOT_CHOICES]
    if unknown:
        raise ValueError(
            f"plot: unknown figure {unknown[0]!r}; choose from {', '.join(PLOT_CHOICES)}"
        )
    require_matplotlib()  # before any simulation: ImportError naming the plot extra
    from . import plotting

    names = PLOT_CHOICES[:-1] if "all" in what else tuple(dict.fromkeys(what))
    os.makedirs(args.out, exist_ok=True)
    # --quick: short runs for a smoke test (the tippe top with viscous friction, 10 s)
    quick = {
        "free_body": dict(max_time=20.0),
        "heavy_top": dict(duration=1.0),
        "tippe_top": dict(duration=10.0, friction_law="viscous"),
    }
    for name in names:
        if name == "frames":
            for path in plotting.render_frames(args.out):
                print(f"wrote {path}")
            continue
        func, filename, describe = plotting.PLOTS[name]
        figures = {} if describe is not None else None  # (what the docs' captions state)
        path = func(
            os.path.join(args.out, filename),
            **(quick[name] if args.quick else {}),
            **({"figures": figures} if figures is not None else {}),
        )
        print(f"wrote {path}")
        if describe is not None:
            print(describe(figures))
    return 0


def _print_table(rows) -> None:
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    for n, row in enumerate(rows):
        print("  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip())
        if n == 0:
            print("  ".join("-" * w for w in widths))


def build_parser() -> argparse.ArgumentParser:
    from .extras import ArgumentParser  # (suggests the closest choice)

    parser = ArgumentParser(
        prog="rbenvs",
        description="Rotating rigid body environments: list, run, check.",
        epilog="Every command also takes --docs PAGE: it runs as usual and writes what it "
        "printed into the block of "
        "PAGE that names the same command line (<!-- rbenvs:output COMMAND -->; docs/ are written "
        "this way).",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    # The order of these calls is the order --help lists the sub-commands in.
    sub.add_parser("list", help="registered environment ids").set_defaults(func=_cmd_list)
    sub.add_parser("scenes", help="named scenes in configs/scenes").set_defaults(func=_cmd_scenes)
    _add_run_parser(sub)
    _add_verify_headline_parsers(sub)
    _add_cache_parser(sub)
    _add_warmup_parser(sub)
    _add_bench_parsers(sub)
    _add_plot_parser(sub)
    return parser


def _add_run_parser(sub) -> None:
    """Add ``rbenvs run``: the analytic baselines on named scenes."""
    run = sub.add_parser(
        "run",
        help="the analytic baselines: scenes with their analytic controller and with no control "
        "(the main job, "
        "training, is rbenvs-train: make run)",
    )
    run.add_argument(
        "--scene",
        action="extend",
        nargs="+",
        metavar="NAME",
        help=(
            f"scene names or YAML paths, several or repeated (default: {' and '.join(MAIN_SCENES)})"
        ),
    )
    run.add_argument(
        "--episodes", type=int, default=3, help="episodes per controller (default: %(default)s)"
    )
    run.add_argument(
        "--seed", type=int, default=0, help="seed of the first episode (default: %(default)s)"
    )
    run.add_argument("--no-progress", action="store_true", help="no progress bar")
    run.set_defaults(func=_cmd_run)


def _add_verify_headline_parsers(sub) -> None:
    """Add ``verify`` and ``headline`` for --help only: their own modules parse their options."""
    # `verify` has its own parser (rbenvs.verify.main); main() hands it the rest of the line.
    sub.add_parser(
        "verify", help="check the simulator against the analytic oracles (see rbenvs verify --help)"
    )
    # `headline` too (rbenvs.headline.main).
    sub.add_parser(
        "headline",
        help=(
            "the README's headline figures from the measuring commands' records "
            "(see rbenvs headline --help)"
        ),
    )


def _add_cache_parser(sub) -> None:
    """Add ``rbenvs cache info|clear``: the compiled kernels kept on disk."""
    cache = sub.add_parser(
        "cache", help="the compiled kernels kept on disk: where, how many, and clearing them"
    )
    cache.add_argument(
        "action",
        choices=("info", "clear"),
        help="info: the folder and its kernels; clear: delete them",
    )
    cache.add_argument(
        "--stale",
        action="store_true",
        help=(
            "with clear: only the kernels of other environments (rbenvs, numba, Python versions "
            "or CPUs)"
        ),
    )
    cache.set_defaults(func=_cmd_cache)


def _add_warmup_parser(sub) -> None:
    """Add ``rbenvs warmup``: compile the default envs' kernels into the cache ahead."""
    warmup = sub.add_parser(
        "warmup",
        help="compile the default envs' kernels ahead into the cache (container images, CI caches)",
    )
    warmup.add_argument(
        "--system",
        action="append",
        choices=tuple(SYSTEM_IDS),
        help="restrict to these systems (repeatable; default all)",
    )
    warmup.add_argument("--no-progress", action="store_true", help="no progress bar")
    warmup.set_defaults(func=_cmd_warmup)


def _add_bench_parsers(sub) -> None:
    """Add ``rbenvs bench`` and its benchmarks; only ``fidelity`` is parsed here."""
    bench = sub.add_parser(
        "bench", help="benchmarks (each prints the peer measured in the same run)"
    )
    bench_sub = bench.add_subparsers(dest="bench", required=True)
    fidelity = bench_sub.add_parser(
        "fidelity", help="tippe top: cost of each fidelity level against gliding"
    )
    fidelity.add_argument("--no-progress", action="store_true", help="no progress bar")
    fidelity.add_argument(
        "--quick", action="store_true", help="each figure from one call (noisy: a smoke run)"
    )
    fidelity.set_defaults(func=_cmd_bench_fidelity)
    _add_bench_own_parsers(bench_sub)


def _add_bench_own_parsers(bench_sub) -> None:
    """Add the benchmarks with a parser of their own (listed in _OWN_PARSERS), for --help only."""
    # `bench throughput` has its own parser (rbenvs.bench.throughput.main); main() hands it the
    # rest.
    bench_sub.add_parser(
        "throughput",
        help="env-steps/s against Pendulum-v1 and CartPole-v1's vector env (see its --help)",
    )
    # `bench startup` too (rbenvs.bench.startup.main).
    bench_sub.add_parser(
        "startup",
        help=(
            "seconds from a fresh process to its first step, cold and warm kernel cache, against "
            "Pendulum-v1 and MuJoCo (see its --help)"
        ),
    )
    # `bench threads` too (rbenvs.bench.threads.main).
    bench_sub.add_parser(
        "threads",
        help=(
            "the vector env's rate with num_threads 1, 2 and every core, against CartPole-v1's "
            "vector env (see its --help)"
        ),
    )
    # `bench costs` too (rbenvs.bench.costs.main).
    bench_sub.add_parser(
        "costs",
        help=(
            "the README's costs measured here: venv size, main job, test suite (wall and CPU), "
            "verify --quick (see its --help)"
        ),
    )
    # `bench render` too (rbenvs.bench.render.main).
    bench_sub.add_parser(
        "render",
        help=(
            "milliseconds per rgb_array frame of every system, against Pendulum-v1's "
            "(see its --help)"
        ),
    )
    # `bench accuracy` too (rbenvs.bench.accuracy.main).
    bench_sub.add_parser(
        "accuracy",
        help=(
            "error, order, drift and cost per integrator and system; a step per scene "
            "(see its --help)"
        ),
    )


def _add_plot_parser(sub) -> None:
    """Add ``rbenvs plot``: PNG figures against the oracles, and rendered frames."""
    plot = sub.add_parser(
        "plot",
        help=(
            "PNG figures of the three systems against their oracles, and rendered frames "
            "(plot extra)"
        ),
    )
    plot.add_argument(
        "what",
        nargs="*",
        metavar="WHAT",
        help=f"figures to draw, of {', '.join(PLOT_CHOICES)} (default: all)",
    )
    plot.add_argument(
        "--out",
        default="plots",
        help=(
            "output folder (default: %(default)s in the current folder; the figures of docs/ "
            "come from --out docs)"
        ),
    )
    plot.add_argument(
        "--quick",
        action="store_true",
        help="short simulations (a smoke test; not the committed pictures)",
    )
    plot.set_defaults(func=_cmd_plot)


def main(argv=None) -> int:
    """The command line; a missing extra or bad input is one line on stderr and exit status 2
    (:func:`rbenvs.extras.run_command`)."""
    from .extras import run_command

    argv = sys.argv[1:] if argv is None else list(argv)
    return run_command("rbenvs", _main, argv)


_OWN_PARSERS = (
    (("verify",), ".verify"),
    (("headline",), ".headline"),
    *(
        (("bench", name), f".bench.{name}")
        for name in ("throughput", "startup", "threads", "costs", "render", "accuracy")
    ),
)


def _main(argv) -> int:
    for (
        prefix,
        module,
    ) in _OWN_PARSERS:  # commands with a parser of their own get the rest of the line
        if tuple(argv[: len(prefix)]) == prefix:
            return importlib.import_module(module, __package__).main(argv[len(prefix) :])
    args = build_parser().parse_args(argv)
    if getattr(args, "episodes", 1) < 1:
        print("rbenvs: --episodes must be >= 1", file=sys.stderr)
        return 2
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())

"""Command line: ``rbenvs-train``, ``rbenvs-eval`` and ``rbenvs-results``.

* ``rbenvs-train --algo ppo --scene default``: train (progress bar, seed, checkpoints), then
  evaluate the agent beside the scene's analytic controller and zero action.
* ``rbenvs-eval --scene default --agent runs/ppo/model.zip --agent analytic --agent zero``.
* ``rbenvs-sweep --algo ppo --scene default``: a hyperparameter search on Ray Tune (search space
  ``configs/agents/sweeps/<algo>.yml``, :mod:`rbenvs_agents.sweep`), the best configuration
  per scene printed and written in the zoo's format.
* ``rbenvs-results``: the README's results table: every (scene, algorithm) of
  ``configs/agents/results.yml`` trained on several seeds, with the analytic controller and
  zero action evaluated the same way (:mod:`rbenvs_agents.grid`); ``--backend ray`` runs its
  cells as Ray tasks (:mod:`rbenvs_agents.backends`).

Each needs the ``agents`` extra (stable-baselines3, torch; ``rbenvs-eval`` of ``analytic`` and
``zero`` alone needs only ``cli``); ``rbenvs-sweep`` and ``rbenvs-results --backend ray`` need
the ``ray`` extra too. A missing extra, an unknown scene or another bad input is one
line on stderr and exit status 2, as for ``rbenvs`` (:func:`rbenvs.extras.run_command`).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from rbenvs.extras import ArgumentParser, require, run_command

__all__ = ["train_main", "eval_main", "results_main", "sweep_main"]

BASELINES = ("analytic", "zero")  # the agents that are not SB3 models


def _scene(name):
    from rbenvs.scenes import load_scene

    return load_scene(name)


def _policy_factory(agent: str, algo_hint: str | None = None):
    """``analytic``, ``zero`` or a path to an SB3 ``model.zip`` (its ``run.json`` names the
    algorithm)."""
    from .evaluate import analytic_policy, sb3_policy, zero_policy

    if agent == "analytic":
        return analytic_policy
    if agent == "zero":
        return zero_policy
    path = Path(agent)
    if not path.is_file():
        raise ValueError(
            f"agent must be 'analytic', 'zero' or a path to a model.zip, got {agent!r}"
        )
    algo, normalization = algo_hint, None
    meta = path.with_name("run.json")
    if meta.is_file():
        run = json.loads(meta.read_text())
        algo = algo or run["algo"]
        normalization = run.get(
            "obs_normalization"
        )  # (normalize_obs: the policy's frozen statistics)
    if algo is None:
        raise ValueError(
            f"cannot tell the algorithm of {agent}: no run.json beside it; pass --algo"
        )
    from .train import algorithm_class

    model = algorithm_class(algo).load(path, device="cpu")
    return lambda env: sb3_policy(model, normalization)


def _table(rows, header):
    widths = [max(len(str(r[i])) for r in [header] + rows) for i in range(len(header))]
    lines = [
        "  ".join(str(c).ljust(w) for c, w in zip(header, widths)).rstrip(),
        "  ".join("-" * w for w in widths),
    ]
    lines += ["  ".join(str(c).ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows]
    return "\n".join(lines)


def _eval_rows(scene, named_factories, episodes, seeds):
    from .evaluate import evaluate, summarize

    rows, records = [], []
    for label, factory in named_factories:
        evals = [evaluate(factory, scene, episodes=episodes, seed=s) for s in seeds]
        summary = summarize(evals)
        records.append({"agent": label} | summary | {"per_seed": [e.as_dict() for e in evals]})
        rows.append(
            (
                label,
                f"{summary['return_mean']:.2f} +- {summary['return_std']:.2f}",
                f"{summary['success_mean']:.0%}",
            )
        )
    return rows, records


def train_main(argv=None) -> int:
    return run_command("rbenvs-train", _train, argv)


def _train(argv) -> int:
    from .config import ALGORITHMS

    p = ArgumentParser(
        prog="rbenvs-train",
        description=(
            "Train an SB3 agent on a scene, then evaluate it against the analytic controller."
        ),
    )
    p.add_argument("--algo", choices=ALGORITHMS, default="ppo")
    p.add_argument(
        "--scene",
        default="default",
        help="scene name (configs/scenes) or YAML path (default: %(default)s)",
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--timesteps",
        type=int,
        default=None,
        help="training budget (default: configs/agents/<algo>.yml)",
    )
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        help="run directory (default: runs/<algo>-<scene>-seed<seed>)",
    )
    p.add_argument("--checkpoint-every", type=int, default=None, metavar="STEPS")
    p.add_argument("--eval-episodes", type=int, default=10)
    p.add_argument(
        "--eval-seeds",
        type=int,
        nargs="+",
        default=[100, 101, 102],
        help="evaluation seeds (default: %(default)s)",
    )
    p.add_argument("--no-compare", action="store_true", help="skip the evaluation")
    p.add_argument(
        "--tensorboard",
        type=Path,
        default=None,
        metavar="DIR",
        help=(
            "also write TensorBoard logs into DIR (the tensorboard extra; view with: "
            "tensorboard --logdir DIR)"
        ),
    )
    p.add_argument("--no-progress", action="store_true")
    args = p.parse_args(argv)
    require("agents")  # (train() asks for the tensorboard extra itself, before it builds anything)
    scene = _scene(args.scene)
    out = args.out or Path("runs") / f"{args.algo}-{scene.name}-seed{args.seed}"
    from .evaluate import analytic_policy, sb3_policy, zero_policy
    from .train import train

    model, info = train(
        args.algo,
        scene,
        seed=args.seed,
        timesteps=args.timesteps,
        out_dir=out,
        progress=not args.no_progress,
        checkpoint_every=args.checkpoint_every,
        tensorboard=args.tensorboard,
    )
    print(
        f"trained {args.algo} on '{scene.name}' for {info['timesteps']} steps in "
        f"{info['wall_time_s']:.1f} s -> {out / 'model.zip'}"
    )
    if "tensorboard" in info:
        print(
            f"TensorBoard logs in {info['tensorboard']} (tensorboard --logdir {args.tensorboard})"
        )
    if not args.no_compare:
        rows, records = _eval_rows(
            scene,
            [
                (
                    f"{args.algo} (seed {args.seed})",
                    lambda env: sb3_policy(model, info.get("obs_normalization")),
                ),
                ("analytic", analytic_policy),
                ("zero action", zero_policy),
            ],
            args.eval_episodes,
            args.eval_seeds,
        )
        print(
            f"\nevaluation on '{scene.name}' ({scene.description}), "
            f"{args.eval_episodes} episodes x "
            f"seeds {args.eval_seeds}:"
        )
        print(_table(rows, ("agent", "return (mean +- std over seeds)", "success")))
        # the run's record keeps its evaluation: a finished run can be compared without rerunning
        info["evaluation"] = {
            "episodes": args.eval_episodes,
            "seeds": list(args.eval_seeds),
            "results": records,
        }
        (out / "run.json").write_text(json.dumps(info, indent=2, default=str))
        print(f"evaluation written to {out / 'run.json'}")
    return 0


def eval_main(argv=None) -> int:
    return run_command("rbenvs-eval", _eval, argv)


def _eval(argv) -> int:
    p = ArgumentParser(
        prog="rbenvs-eval", description="Evaluate agents and analytic controllers on a scene."
    )
    p.add_argument("--scene", default="default")
    p.add_argument(
        "--agent",
        action="extend",
        nargs="+",
        required=True,
        help="'analytic', 'zero' or model.zip paths, several or repeated",
    )
    p.add_argument("--algo", default=None, help="algorithm of a model.zip without run.json")
    p.add_argument("--episodes", type=int, default=10)
    p.add_argument("--seeds", type=int, nargs="+", default=[100, 101, 102])
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    require("cli" if set(args.agent) <= set(BASELINES) else "agents")
    scene = _scene(args.scene)
    rows, records = _eval_rows(
        scene, [(a, _policy_factory(a, args.algo)) for a in args.agent], args.episodes, args.seeds
    )
    if args.json:
        print(json.dumps({"scene": scene.name, "results": records}, indent=2))
    else:
        print(_table(rows, ("agent", "return (mean +- std over seeds)", "success")))
    return 0


def results_main(argv=None) -> int:
    return run_command("rbenvs-results", _results, argv)


def _results(argv) -> int:
    p = ArgumentParser(
        prog="rbenvs-results",
        description=(
            "The README's results table: train and evaluate every (scene, algorithm) of "
            "configs/agents/results.yml."
        ),
    )
    p.add_argument("--seeds", type=int, default=None, help="seeds per (scene, agent) (default: 3)")
    p.add_argument(
        "--quick",
        action="store_true",
        help="1/20 of each budget, 1 seed, 2 episodes: a smoke run of the whole grid",
    )
    p.add_argument("--json", type=Path, default=None, help="also write the records here")
    p.add_argument(
        "--from-json",
        type=Path,
        default=None,
        metavar="PATH",
        help=(
            "print the table of a finished run's records (its --json) without training: the "
            "docs' table is written this way"
        ),
    )
    p.add_argument(
        "--scene",
        action="append",
        default=None,
        metavar="NAME",
        help=(
            "run only this scene of results.yml, repeatable (default: every scene); the grid's "
            "other rows are left out"
        ),
    )
    p.add_argument(
        "--records",
        type=Path,
        default=None,
        metavar="PATH",
        help="keep every finished cell in this JSON Lines file as it finishes, and run only the "
        "cells it does not hold yet: "
        "a stopped run resumes where it stopped (rbenvs_agents.records)",
    )
    p.add_argument("--no-progress", action="store_true")
    p.add_argument(
        "--backend",
        choices=("serial", "ray"),
        default="serial",
        help=(
            "serial: one cell after another here (default); ray: one Ray task per (scene, agent, "
            "seed), the ray extra"
        ),
    )
    p.add_argument(
        "--address",
        default=None,
        help="--backend ray: join this Ray cluster (default: start a local one for the command)",
    )
    p.add_argument(
        "--num-cpus",
        type=int,
        default=None,
        help="--backend ray: CPUs of the local cluster (default: every core)",
    )
    args = p.parse_args(argv)
    if args.from_json is not None:
        # (a finished run's table: nothing runs, so an option of a run would be silently ignored)
        given = [
            flag
            for flag, on in (
                ("--json", args.json),
                ("--quick", args.quick),
                ("--seeds", args.seeds is not None),
                ("--scene", args.scene is not None),
                ("--records", args.records is not None),
                ("--backend", args.backend != "serial"),
                ("--address", args.address is not None),
                ("--num-cpus", args.num_cpus is not None),
            )
            if on
        ]
        if given:
            p.error(f"--from-json prints a finished run's table: leave out {', '.join(given)}")
        from .grid import grid_cost, grid_table

        records = json.loads(args.from_json.read_text())
        n_seeds = max(r["seeds"] for r in records)
        print(grid_table(records, n_seeds))
        print()
        print(grid_cost(records, n_seeds))
        return 0
    require("agents")
    if args.backend == "ray":
        require("ray")
    elif args.address is not None or args.num_cpus is not None:
        raise ValueError("--address and --num-cpus need --backend ray")
    from .backends import RayBackend, SerialBackend
    from .grid import grid_cells, grid_cost, grid_records, grid_table

    seeds = [0] if args.quick else list(range(3 if args.seeds is None else args.seeds))
    cells = grid_cells(seeds, quick=args.quick, only=args.scene)
    backend = (
        RayBackend(args.address, args.num_cpus)
        if args.backend == "ray"
        else SerialBackend(progress=not args.no_progress)
    )
    if args.records is None:
        results = backend.run(cells)
    else:
        from .records import CellRecords

        kept = CellRecords(args.records)
        results = [kept.get(cell) for cell in cells]
        todo = [cell for cell, result in zip(cells, results) if result is None]
        print(
            f"rbenvs-results: {len(cells) - len(todo)} of {len(cells)} cells from {args.records}; "
            f"running {len(todo)}",
            file=sys.stderr,
        )
        ran = iter(backend.run(todo, on_result=kept.add))
        results = [result if result is not None else next(ran) for result in results]
    records = grid_records(results)
    print(grid_table(records, len(seeds)))
    print()
    print(grid_cost(records, len(seeds)))
    if args.json:
        args.json.write_text(json.dumps(records, indent=2))
    return 0


def sweep_main(argv=None) -> int:
    return run_command("rbenvs-sweep", _sweep, argv)


def _sweep(argv) -> int:
    from .config import ALGORITHMS

    p = ArgumentParser(
        prog="rbenvs-sweep",
        description=(
            "Hyperparameter search on Ray Tune (Optuna's sampler): the best configuration per "
            "scene, in the zoo's format."
        ),
    )
    p.add_argument("--algo", choices=ALGORITHMS, default="ppo")
    p.add_argument(
        "--scene",
        action="append",
        default=None,
        help="scene to search on, repeatable (default: default)",
    )
    p.add_argument(
        "--trials",
        type=int,
        default=None,
        help="trials per scene (default: configs/agents/sweeps/<algo>.yml)",
    )
    p.add_argument(
        "--timesteps",
        type=int,
        default=None,
        help="training budget of a trial (default: the sweep file's)",
    )
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        help="the zoo-format file of the best configurations (default: runs/sweep-<algo>.yml)",
    )
    p.add_argument(
        "--seed", type=int, default=0, help="seed of Optuna's sampler (default: %(default)s)"
    )
    p.add_argument(
        "--address",
        default=None,
        help="join this Ray cluster (default: start a local one for the command)",
    )
    p.add_argument(
        "--num-cpus", type=int, default=None, help="CPUs of the local cluster (default: every core)"
    )
    p.add_argument(
        "--storage",
        type=Path,
        default=None,
        help=(
            "Tune's folder for its records: one every node reaches, on a cluster of several "
            "machines (default: tune/ beside --out)"
        ),
    )
    args = p.parse_args(argv)
    require("agents")
    require("ray")
    from .sweep import load_sweep, run_sweep, zoo_config

    spec = load_sweep(args.algo, trials=args.trials, timesteps=args.timesteps)
    scenes = [_scene(name) for name in (args.scene or ["default"])]
    out = args.out or Path("runs") / f"sweep-{args.algo}.yml"
    results = []
    for scene in scenes:
        result = run_sweep(
            spec,
            scene,
            args.storage or out.parent / "tune",
            address=args.address,
            num_cpus=args.num_cpus,
            seed=args.seed,
        )
        results.append(result)
        names = list(spec.space)
        rows = [
            (
                *(_flat(t.hyperparams, n) for n in names),
                f"{t.return_mean:.1f}",
                f"{t.success_mean:.0%}",
                f"{t.wall_time_s:.0f} s",
            )
            for t in sorted(result.trials, key=lambda t: -t.return_mean)
        ]
        print(f"\n{args.algo.upper()} on '{scene.name}': {len(result.trials)} trials, best first")
        print(_table(rows, (*names, "return", "success", "training")))
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(zoo_config(results))
    print(f"\nbest configuration per scene written to {out} (rl-baselines3-zoo format)")
    return 0


def _flat(hyperparams: dict, name: str):
    """A searched value by its sweep name (``policy_kwargs.net_arch``)."""
    outer, _, inner = name.partition(".")
    value = hyperparams[outer][inner] if inner else hyperparams[outer]
    return f"{value:.3g}" if isinstance(value, float) else value


if __name__ == "__main__":
    sys.exit(train_main())

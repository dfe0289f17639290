"""The results grid of ``rbenvs-results``: its cells, one cell's run, its table.

A *cell* is one (scene, agent, seed) of ``configs/agents/results.yml``: a baseline (zero action,
the analytic controller) evaluated, or an algorithm trained on the seed and then evaluated.
:func:`run_cell` runs one, and is the only code that does: the serial backend calls it cell
after cell, the Ray backend in one Ray task per cell (:mod:`rbenvs_agents.backends`), a sweep's
trials call it too (:mod:`rbenvs_agents.sweep`). A cell's numbers depend on the cell alone (its
training seed, budget and hyperparameters, its evaluation seed, one torch thread), never on
where or after what it runs, so every backend prints the same table; only the measured wall
times differ.

:func:`grid_cells` reads the grid and checks every scene and configuration before the first
(long) training run; :func:`grid_records` summarises the results per (scene, agent) in the
grid's order, and :func:`grid_table` prints them as the README's table.

**Robustness.** A scene of the grid may carry ``robustness: {train: RANGES, heldout: RANGES}``
(``param_ranges`` of the env, :mod:`rbenvs.envs.options`). Each of its algorithms is then
trained twice per seed, on the scene's parameters (``training: nominal``) and with ``train``
drawn at every reset (``training: randomized``); every agent of the scene, the analytic
controller and zero action included, is evaluated on the scene's parameters and on
``heldout``, whose box must lie outside the training box (:func:`heldout_outside`): every
held-out episode's parameters are ones neither agent trained on. Evaluations with the same
options and evaluation seed see the same episodes (same drawn parameters, same starts), so the
learned agents and the analytic controller (built, like the agent, knowing only the scene's
parameters) are compared on the very same held-out episodes.

**Throughput.** Each cell measures three rates: the scene's env alone
(:func:`rbenvs_agents.evaluate.env_throughput`, random actions, after an untimed warm-up that
also builds the compiled step the evaluations use), the evaluation loop with the policy's
inference, and training (env steps over ``learn``'s wall time; learned agents only; the first
training of a scene in a process includes building the vector env's compiled step, seconds,
which a full budget amortizes). They are measured on whatever machine runs the cell, with
whatever else runs there.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

from .evaluate import Evaluation

__all__ = [
    "BASELINES",
    "Cell",
    "CellResult",
    "run_cell",
    "grid_cells",
    "grid_records",
    "grid_table",
    "grid_cost",
    "heldout_outside",
    "ranges_box",
]

# the agents that are evaluated without training, by their label in the table
BASELINES = ("zero action", "analytic")
EVAL_SEED_OFFSET = 100  # cell seed s is evaluated with evaluation seed 100 + s
NOMINAL, HELDOUT = "nominal", "held-out"  # the evaluations of a cell


@dataclass(frozen=True)
class Cell:
    """One agent on one scene and one seed. ``agent`` is a label of :data:`BASELINES` or an
    algorithm (``ppo``); ``timesteps`` (None: the configured budget) and ``hyperparams``
    (overrides of ``configs/agents/<algo>.yml``) apply to algorithms only. ``train_ranges``:
    the ``param_ranges`` the algorithm trains with (None: the scene's parameters);
    ``heldout``: the ``param_ranges`` of a second evaluation (None: the scene's only)."""

    scene: object  # an rbenvs.scenes.Scene: plain data, sent to whichever process runs the cell
    agent: str
    seed: int
    episodes: int
    eval_seed: int
    timesteps: int | None = None
    hyperparams: dict = field(default_factory=dict)
    train_ranges: dict | None = None
    heldout: dict | None = None

    @property
    def learned(self) -> bool:
        return self.agent not in BASELINES

    @property
    def training(self) -> str:
        """``nominal`` or ``randomized`` for an algorithm, ``-`` for a baseline."""
        return "-" if not self.learned else ("randomized" if self.train_ranges else NOMINAL)

    @property
    def label(self) -> str:
        """The agent's name in the table: the baseline's label, the algorithm in capitals
        (``PPO (randomized)`` when it trained with ``train_ranges``)."""
        if not self.learned:
            return self.agent
        return self.agent.upper() + (" (randomized)" if self.train_ranges else "")


@dataclass(frozen=True)
class CellResult:
    cell: Cell
    evaluation: Evaluation  # on the scene's parameters
    timesteps: int  # training steps (0 for a baseline)
    wall_time_s: float  # training wall time (0.0 for a baseline)
    heldout: Evaluation | None = None  # on cell.heldout's parameters
    env_steps_per_s: float = 0.0  # the env alone
    train_steps_per_s: float = 0.0  # during training (0.0 for a baseline)

    def evaluations(self) -> dict:
        """``{NOMINAL: evaluation, HELDOUT: heldout}`` (the latter when there is one)."""
        return {NOMINAL: self.evaluation} | (
            {HELDOUT: self.heldout} if self.heldout is not None else {}
        )


def run_cell(cell: Cell, progress: bool = False) -> CellResult:
    """Train the cell's algorithm (if it has one) and evaluate its agent on the scene's
    parameters (and the held-out ones): the grid's one unit."""
    from .evaluate import analytic_policy, env_throughput, evaluate, sb3_policy, zero_policy

    timesteps, wall, train_rate = 0, 0.0, 0.0
    if not cell.learned:
        factory = {"zero action": zero_policy, "analytic": analytic_policy}[cell.agent]
    else:
        from .train import train

        start = time.perf_counter()
        overrides = {"param_ranges": cell.train_ranges} if cell.train_ranges else None
        model, info = train(
            cell.agent,
            cell.scene,
            seed=cell.seed,
            timesteps=cell.timesteps,
            progress=progress,
            env_overrides=overrides,
            **cell.hyperparams,
        )
        wall = time.perf_counter() - start
        timesteps, train_rate = info["timesteps"], info["steps_per_s"]

        def factory(env):
            return sb3_policy(model, info.get("obs_normalization"))

    # the env alone first: its untimed warm-up builds the compiled step the evaluations then use,
    # so that no compilation lands in the timed loops
    env_rate = env_throughput(cell.scene, seed=cell.eval_seed)
    nominal = evaluate(factory, cell.scene, episodes=cell.episodes, seed=cell.eval_seed)
    heldout = None
    if cell.heldout is not None:
        heldout = evaluate(
            factory,
            cell.scene,
            episodes=cell.episodes,
            seed=cell.eval_seed,
            env_overrides={"param_ranges": cell.heldout},
        )
    return CellResult(cell, nominal, timesteps, wall, heldout, env_rate, train_rate)


def ranges_box(scene, ranges: dict | None) -> dict:
    """``{keyword: (lo tuple, hi tuple)}`` over every randomizable keyword of ``scene``'s env:
    the validated ``ranges`` (``param_ranges``), the scene's value (a point) elsewhere."""
    env = scene.make(**({"param_ranges": ranges} if ranges else {})).unwrapped
    validated = env.param_ranges
    box = {}
    for name in type(env).randomizable:
        if validated is not None and name in validated.names:
            box[name] = validated.bounds[name]
        else:
            value = env._kwargs[name]
            v = (
                tuple(float(c) for c in value)
                if isinstance(value, (tuple, list))
                else (float(value),)
            )
            box[name] = (v, v)
    env.close()
    return box


def heldout_outside(scene, train: dict | None, heldout: dict) -> None:
    """Refuse held-out ranges that meet the training box: some component of some keyword must
    have its held-out interval apart from its training interval (then no held-out draw lies in
    the training box, nor at the scene's parameters when the training box holds them, which
    is checked too). ``ValueError`` names the scene."""
    for label, ranges in (("the scene's parameters", None), ("the training ranges", train)):
        a, b = ranges_box(scene, ranges), ranges_box(scene, heldout)
        apart = any(
            hi_a < lo_b or hi_b < lo_a
            for name in a
            for lo_a, hi_a, lo_b, hi_b in zip(*a[name], *b[name])
        )
        if not apart:
            raise ValueError(
                f"scene {scene.name!r}: robustness.heldout {heldout!r} meets {label} "
                f"({train!r}): a "
                "held-out range must "
                f"lie outside them in at least one parameter"
            )


def in_box(params: dict, box: dict) -> bool:
    """Whether one episode's drawn ``params`` (``info["params"]``) lie in ``box``
    (:func:`ranges_box`)."""
    import numpy as np

    for name, (lo, hi) in box.items():
        if name in params:
            v = np.atleast_1d(np.asarray(params[name], dtype=float))
            if np.any(v < np.asarray(lo)) or np.any(v > np.asarray(hi)):
                return False
    return True


def grid_cells(seeds, quick: bool = False, only=None) -> list[Cell]:
    """The cells of ``configs/agents/results.yml`` for training seeds ``seeds``, scene by scene:
    the baselines, then each algorithm, each on every seed, then (with ``robustness:``) each
    algorithm trained with randomization. ``quick``: 1/20 of each budget (at least 1000 steps,
    and 1000 past ``learning_starts``) and 2 evaluation episodes. ``only``: the scenes of the grid
    to run (None: all). Every scene, configuration and range is loaded and checked here, so a bad
    one is reported before anything runs."""
    import yaml

    from rbenvs.scenes import load_scene

    from .config import agent_config, configs_dir

    grid = yaml.safe_load((configs_dir() / "results.yml").read_text())
    runs = grid["runs"]
    if only:
        unknown = sorted(set(only) - {entry["scene"] for entry in runs})
        if unknown:
            raise ValueError(
                f"--scene: not in results.yml: {unknown} (its scenes: "
                f"{[entry['scene'] for entry in runs]})"
            )
        runs = [entry for entry in runs if entry["scene"] in set(only)]
    scenes = [load_scene(entry["scene"]) for entry in runs]
    cells = []
    for entry, scene in zip(runs, scenes):
        episodes = 2 if quick else int(entry.get("eval_episodes", 10))
        robust = entry.get("robustness") or {}
        if robust and set(robust) != {"train", "heldout"}:
            raise ValueError(
                f"results.yml, scene {scene.name!r}: robustness must have exactly 'train' and "
                f"'heldout' (param_ranges), got {sorted(robust)}"
            )
        train_ranges, heldout = robust.get("train"), robust.get("heldout")
        if robust:
            heldout_outside(scene, train_ranges, heldout)
        budgets = {}
        for agent in entry["algos"]:
            config = agent_config(agent, scene.env_id, scene.name)
            # (quick: past learning_starts, so that an off-policy algorithm makes some updates)
            starts = int(config.hyperparams.get("learning_starts", 0))
            budgets[agent] = (
                max(1000, config.n_timesteps // 20, starts + 1000 if starts else 0)
                if quick
                else None
            )
        for agent in (*BASELINES, *entry["algos"]):
            cells += [
                Cell(
                    scene,
                    agent,
                    s,
                    episodes,
                    EVAL_SEED_OFFSET + s,
                    budgets.get(agent),
                    heldout=heldout,
                )
                for s in seeds
            ]
        if robust:
            for agent in entry["algos"]:
                cells += [
                    Cell(
                        scene,
                        agent,
                        s,
                        episodes,
                        EVAL_SEED_OFFSET + s,
                        budgets[agent],
                        train_ranges=train_ranges,
                        heldout=heldout,
                    )
                    for s in seeds
                ]
    return cells


def _ranges_text(ranges: dict | None) -> str:
    if not ranges:
        return ""
    return ", ".join(f"{k}: {v}" for k, v in ranges.items())


def grid_records(results: list[CellResult]) -> list[dict]:
    """One record per (scene, agent, evaluation), in the order of first appearance, the
    evaluations on the scene's parameters first: the summary over its seeds
    (:func:`rbenvs_agents.evaluate.summarize`), the training steps, the mean training wall time
    per seed, the three throughputs (means over seeds) and, for a held-out evaluation, the
    ranges trained on and evaluated on."""
    from .evaluate import summarize

    groups: dict[tuple, list[tuple[CellResult, Evaluation]]] = {}
    for kind in (NOMINAL, HELDOUT):
        for result in results:
            evaluation = result.evaluations().get(kind)
            if evaluation is not None:
                groups.setdefault((kind, result.cell.scene.name, result.cell.label), []).append(
                    (result, evaluation)
                )
    records = []
    for (kind, _, _), group in groups.items():
        cell = group[0][0].cell
        scene = cell.scene
        walls = [r.wall_time_s for r, _ in group]

        def mean(values):
            return sum(values) / len(values)

        record = {
            "scene": scene.name,
            "env_id": scene.env_id,
            "task": scene.kwargs.get("task", ""),
            "agent": cell.label,
            "training": cell.training,
            "evaluation": kind,
            "timesteps": group[-1][0].timesteps,
            "wall_time_s": mean(walls),
        }
        record |= summarize([e for _, e in group])
        record |= {
            "env_steps_per_s": mean([r.env_steps_per_s for r, _ in group]),
            "policy_steps_per_s": mean([e.steps_per_s for _, e in group]),
            "train_steps_per_s": mean([r.train_steps_per_s for r, _ in group]),
        }
        if kind == HELDOUT:
            record |= {"train_ranges": cell.train_ranges, "heldout_ranges": cell.heldout}
        records.append(record)
    return records


def _rate(value) -> str:
    return "-" if not value or not math.isfinite(value) else f"{value:,.0f}"


def grid_table(records: list[dict], n_seeds: int) -> str:
    """The README's results table (markdown) of :func:`grid_records`: the evaluations on each
    scene's parameters with three throughput columns (env steps per second: the env alone with
    random actions, with the policy's inference, during training), then, when there are
    held-out evaluations, the robustness table. Records without a throughput (an older run's)
    show ``-`` there."""
    header = (
        "env",
        "task (scene)",
        "agent",
        "training steps",
        "wall time / seed",
        f"return (mean +- std, {n_seeds} seeds)",
        "success",
        "env steps/s",
        "with policy steps/s",
        "training steps/s",
    )
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    nominal = [r for r in records if r.get("evaluation", NOMINAL) == NOMINAL]
    heldout = [r for r in records if r.get("evaluation", NOMINAL) == HELDOUT]
    for r in nominal:
        steps, wall = r["timesteps"], r["wall_time_s"]
        row = (
            r["env_id"].split("/")[-1],
            f"{r['task']} ({r['scene']})",
            r["agent"],
            f"{steps:,}" if steps else "-",
            f"{wall:.0f} s" if wall else "-",
            f"{r['return_mean']:.1f} +- {r['return_std']:.1f}",
            f"{r['success_mean']:.0%}",
            _rate(r.get("env_steps_per_s")),
            _rate(r.get("policy_steps_per_s")),
            _rate(r.get("train_steps_per_s")),
        )
        lines.append("| " + " | ".join(row) + " |")
    if heldout:
        lines += [
            "",
            "Robustness: every agent on held-out parameters, outside every training range (the "
            f"same episodes for every agent of a scene; {n_seeds} seeds):",
            "",
        ]
        header = (
            "env",
            "task (scene)",
            "held-out parameters",
            "agent",
            "trained on",
            f"return (mean +- std, {n_seeds} seeds)",
            "success",
        )
        lines += ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        for r in heldout:
            trained = {
                "nominal": "scene's parameters",
                "randomized": _ranges_text(r.get("train_ranges")),
                "-": "-",
            }[r.get("training", "-")]
            row = (
                r["env_id"].split("/")[-1],
                f"{r['task']} ({r['scene']})",
                _ranges_text(r.get("heldout_ranges")),
                r["agent"],
                trained,
                f"{r['return_mean']:.1f} +- {r['return_std']:.1f}",
                f"{r['success_mean']:.0%}",
            )
            lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


COST_CPUS = (1, 2, 4, 16)  # the free CPUs grid_cost spreads the run's training time over


def grid_cost(records: list[dict], n_seeds: int) -> str:
    """What the run's training cost, from its records (:func:`grid_records`): the trained
    rows' wall time per seed times ``n_seeds``, in all, the longest row's seed, and that work
    spread over ``COST_CPUS`` free CPUs (``max(total / k, longest)``: no cluster start, no
    compilation, no evaluation counted; a lower bound of a run's wall time). The wall times are
    the run's own, under whatever load it met."""
    trained = [
        r
        for r in records
        if r.get("evaluation", NOMINAL) == NOMINAL and r.get("timesteps") and r.get("wall_time_s")
    ]
    if not trained:
        return "Training cost: no trained rows in these records."
    total = sum(r["wall_time_s"] for r in trained) * n_seeds
    longest = max(trained, key=lambda r: r["wall_time_s"])
    spread = ", ".join(
        f"{k} CPU{'s' if k > 1 else ''} {_duration(max(total / k, longest['wall_time_s']))}"
        for k in COST_CPUS
    )
    rows = (
        f"{len(trained)} row{'s' if len(trained) > 1 else ''} x "
        f"{n_seeds} seed{'s' if n_seeds > 1 else ''}"
    )
    return (
        f"Training cost (this run's wall times): {len(trained) * n_seeds} trained "
        f"cell{'s' if len(trained) * n_seeds > 1 else ''} ({rows}), "
        f"{_duration(total)} in all; the longest, {longest['agent']} on {longest['scene']}, "
        f"{longest['wall_time_s']:.0f} s a seed. "
        f"Spread over free CPUs (training only, a lower bound): {spread}."
    )


def _duration(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"

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
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from .evaluate import Evaluation

__all__ = ["BASELINES", "Cell", "CellResult", "run_cell", "grid_cells", "grid_records", "grid_table"]

# the agents that are evaluated without training, by their label in the table
BASELINES = ("zero action", "analytic")
EVAL_SEED_OFFSET = 100  # cell seed s is evaluated with evaluation seed 100 + s


@dataclass(frozen=True)
class Cell:
    """One agent on one scene and one seed. ``agent`` is a label of :data:`BASELINES` or an
    algorithm (``ppo``); ``timesteps`` (None: the configured budget) and ``hyperparams``
    (overrides of ``configs/agents/<algo>.yml``) apply to algorithms only."""

    scene: object  # an rbenvs.scenes.Scene: plain data, sent to whichever process runs the cell
    agent: str
    seed: int
    episodes: int
    eval_seed: int
    timesteps: int | None = None
    hyperparams: dict = field(default_factory=dict)

    @property
    def learned(self) -> bool:
        return self.agent not in BASELINES

    @property
    def label(self) -> str:
        """The agent's name in the table: the baseline's label, the algorithm in capitals."""
        return self.agent if not self.learned else self.agent.upper()


@dataclass(frozen=True)
class CellResult:
    cell: Cell
    evaluation: Evaluation
    timesteps: int  # training steps (0 for a baseline)
    wall_time_s: float  # training wall time (0.0 for a baseline)


def run_cell(cell: Cell, progress: bool = False) -> CellResult:
    """Train the cell's algorithm (if it has one) and evaluate its agent: the grid's one unit."""
    from .evaluate import analytic_policy, evaluate, sb3_policy, zero_policy

    if not cell.learned:
        factory = {"zero action": zero_policy, "analytic": analytic_policy}[cell.agent]
        return CellResult(cell, evaluate(factory, cell.scene, episodes=cell.episodes, seed=cell.eval_seed), 0, 0.0)
    from .train import train

    start = time.perf_counter()
    model, info = train(cell.agent, cell.scene, seed=cell.seed, timesteps=cell.timesteps, progress=progress, **cell.hyperparams)
    wall = time.perf_counter() - start
    evaluation = evaluate(lambda env: sb3_policy(model), cell.scene, episodes=cell.episodes, seed=cell.eval_seed)
    return CellResult(cell, evaluation, info["timesteps"], wall)


def grid_cells(seeds, quick: bool = False) -> list[Cell]:
    """The cells of ``configs/agents/results.yml`` for training seeds ``seeds``, scene by scene:
    the baselines, then each algorithm, each on every seed. ``quick``: 1/20 of each budget (at
    least 1000 steps) and 2 evaluation episodes. Every scene and configuration is loaded here,
    so a bad one is reported before anything runs."""
    import yaml

    from rbenvs.scenes import load_scene

    from .config import agent_config, configs_dir

    grid = yaml.safe_load((configs_dir() / "results.yml").read_text())
    scenes = [load_scene(entry["scene"]) for entry in grid["runs"]]
    cells = []
    for entry, scene in zip(grid["runs"], scenes):
        episodes = 2 if quick else int(entry.get("eval_episodes", 10))
        for agent in (*BASELINES, *entry["algos"]):
            budget = None
            if agent not in BASELINES:
                config = agent_config(agent, scene.env_id, scene.name)
                budget = max(1000, config.n_timesteps // 20) if quick else None
            cells += [Cell(scene, agent, s, episodes, EVAL_SEED_OFFSET + s, budget) for s in seeds]
    return cells


def grid_records(results: list[CellResult]) -> list[dict]:
    """One record per (scene, agent), in the order of first appearance: the summary over its
    seeds (:func:`rbenvs_agents.evaluate.summarize`), the training steps and the mean training
    wall time per seed."""
    from .evaluate import summarize

    groups: dict[tuple, list[CellResult]] = {}
    for result in results:
        groups.setdefault((result.cell.scene.name, result.cell.agent), []).append(result)
    records = []
    for group in groups.values():
        scene = group[0].cell.scene
        walls = [r.wall_time_s for r in group]
        records.append({"scene": scene.name, "env_id": scene.env_id, "task": scene.kwargs.get("task", ""), "agent": group[0].cell.label,
                        "timesteps": group[-1].timesteps, "wall_time_s": sum(walls) / len(walls)} | summarize([r.evaluation for r in group]))
    return records


def grid_table(records: list[dict], n_seeds: int) -> str:
    """The README's results table (markdown) of :func:`grid_records`."""
    header = ("env", "task (scene)", "agent", "training steps", "wall time / seed", f"return (mean +- std, {n_seeds} seeds)", "success")
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for r in records:
        steps, wall = r["timesteps"], r["wall_time_s"]
        row = (r["env_id"].split("/")[-1], f"{r['task']} ({r['scene']})", r["agent"], f"{steps:,}" if steps else "-",
               f"{wall:.0f} s" if wall else "-", f"{r['return_mean']:.1f} +- {r['return_std']:.1f}", f"{r['success_mean']:.0%}")
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)

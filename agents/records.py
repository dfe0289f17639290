"""A results run's finished cells, kept on disk: ``rbenvs-results --records PATH``.

The grid is hours of work on a small machine (180 cells at 3 seeds: about three hours on two
cores), and until now its results lived in the one process that waited for them: a run
stopped one cell before its end left nothing. With ``--records PATH`` every cell's result is
appended to a JSON Lines file the moment it finishes (one line, flushed and synced), under the
cell's key; a run given a file that holds some of its cells runs only the others, and its table
is the one an unbroken run prints (a cell's numbers depend on the cell alone:
:mod:`rbenvs_agents.grid`). So a run can stop anywhere (a lost node, a closed session) and go on
later, on this machine or another one.

The key (:func:`cell_key`) is the cell as configured: the scene (name, env id and keywords), the
agent, the training and evaluation seeds, the episodes, the ranges, and for an algorithm its
merged configuration (budget, vector envs, hyperparameters, reward scaling) as
``configs/agents/<algo>.yml`` gives it when the run starts. A changed configuration is a new key,
so a stale result is never reused; it stays in the file, unused.
"""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path

from .evaluate import Evaluation
from .grid import Cell, CellResult

__all__ = ["CellRecords", "cell_key", "result_data", "result_from_data"]


def _plain(value):
    """JSON for what the records hold: numpy arrays and scalars as lists and numbers."""
    tolist = getattr(value, "tolist", None)
    if tolist is not None:
        return tolist()
    raise TypeError(f"not JSON: {type(value).__name__}")


def cell_key(cell: Cell) -> str:
    """The cell as configured, one canonical JSON text (see the module's docstring)."""
    scene = cell.scene
    key = {
        "scene": scene.name,
        "env_id": scene.env_id,
        "kwargs": scene.kwargs,
        "agent": cell.agent,
        "seed": cell.seed,
        "episodes": cell.episodes,
        "eval_seed": cell.eval_seed,
        "timesteps": cell.timesteps,
        "hyperparams": cell.hyperparams,
        "train_ranges": cell.train_ranges,
        "heldout": cell.heldout,
    }
    if cell.learned:
        from .config import agent_config

        key["config"] = dataclasses.asdict(
            agent_config(cell.agent, scene.env_id, scene.name, **cell.hyperparams)
        )
        if not key["config"][
            "normalize_obs"
        ]:  # (absent when off: the keys written before the flag stay valid)
            del key["config"]["normalize_obs"]
    return json.dumps(key, sort_keys=True, default=_plain)


def _evaluation_data(evaluation: Evaluation | None):
    if evaluation is None:
        return None
    return {
        "returns": list(evaluation.returns),
        "successes": list(evaluation.successes),
        "lengths": list(evaluation.lengths),
        "params": [dict(p) for p in evaluation.params],
        "starts": [list(s) for s in evaluation.starts],
        "steps_per_s": evaluation.steps_per_s,
    }


def _evaluation(data) -> Evaluation | None:
    if data is None:
        return None
    return Evaluation(
        tuple(float(r) for r in data["returns"]),
        tuple(bool(s) for s in data["successes"]),
        tuple(int(n) for n in data["lengths"]),
        tuple(dict(p) for p in data["params"]),
        tuple(tuple(float(c) for c in s) for s in data["starts"]),
        float(data["steps_per_s"]),
    )


def result_data(result: CellResult) -> dict:
    """A cell's result as JSON data (the cell itself is its key)."""
    return {
        "evaluation": _evaluation_data(result.evaluation),
        "heldout": _evaluation_data(result.heldout),
        "timesteps": int(result.timesteps),
        "wall_time_s": float(result.wall_time_s),
        "env_steps_per_s": float(result.env_steps_per_s),
        "train_steps_per_s": float(result.train_steps_per_s),
    }


def result_from_data(cell: Cell, data: dict) -> CellResult:
    """The :class:`CellResult` of ``cell`` from :func:`result_data`'s output."""
    return CellResult(
        cell,
        _evaluation(data["evaluation"]),
        int(data["timesteps"]),
        float(data["wall_time_s"]),
        _evaluation(data["heldout"]),
        float(data["env_steps_per_s"]),
        float(data["train_steps_per_s"]),
    )


class CellRecords:
    """The JSON Lines file of a run's finished cells: ``{"key": cell_key, "result": result_data}``
    a line. A line cut short (the process stopped while writing it) is ignored; a later result
    of the same key replaces an earlier one."""

    def __init__(self, path):
        self.path = Path(path)
        self._data: dict[str, dict] = {}
        if self.path.exists():
            for line in self.path.read_text().splitlines():
                try:
                    entry = json.loads(line)
                except json.JSONDecodeError:
                    continue
                if isinstance(entry, dict) and "key" in entry and "result" in entry:
                    self._data[entry["key"]] = entry["result"]

    def __len__(self) -> int:
        return len(self._data)

    def get(self, cell: Cell) -> CellResult | None:
        """The recorded result of ``cell``, or None."""
        data = self._data.get(cell_key(cell))
        return None if data is None else result_from_data(cell, data)

    def add(self, result: CellResult) -> None:
        """Append ``result`` (flushed and synced: it survives the process)."""
        key, data = cell_key(result.cell), result_data(result)
        line = json.dumps({"key": key, "result": data}, default=_plain)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with self.path.open("a") as f:
            f.write(line + "\n")
            f.flush()
            os.fsync(f.fileno())
        self._data[key] = data

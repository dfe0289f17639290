"""The results grid's robustness block and throughput columns (rbenvs_agents.grid), and the
hyperparameter files the grid trains with: held-out evaluations draw parameters outside every
training range, every agent of a scene (learned or analytic) sees the same episodes, the three
throughput columns are measured and positive, and every block of configs/agents/*.yml builds
its algorithm (tiny budgets throughout)."""

import json

import numpy as np
import pytest
import yaml

pytest.importorskip("stable_baselines3")

import rbenvs_agents.config as config  # noqa: E402
from rbenvs.scenes import load_scene  # noqa: E402
from rbenvs_agents.grid import (
    HELDOUT,
    NOMINAL,
    Cell,
    grid_cells,
    grid_records,
    grid_table,
    heldout_outside,
    in_box,  # noqa: E402
    ranges_box,
    run_cell,
)
from rbenvs_agents.train import algorithm_class, train  # noqa: E402

TRAIN = {"inertia": 0.1, "max_torque": 0.25}
HELD = {"inertia": 0.1, "max_torque": [0.10, 0.14]}
TINY = {"n_steps": 64, "batch_size": 64}  # PPO: one rollout of 8 x 64 steps


def _grid(tmp_path, monkeypatch, text):
    for algo in ("ppo", "sac", "td3"):
        (tmp_path / f"{algo}.yml").write_text((config.configs_dir() / f"{algo}.yml").read_text())
    (tmp_path / "results.yml").write_text(text)
    monkeypatch.setattr(config, "configs_dir", lambda: tmp_path)


@pytest.fixture(scope="module")
def robust_results():
    """A robustness grid of one scene, run cell by cell: the baselines, PPO on the scene's
    parameters and PPO with randomization, one seed, 3 episodes, 512 training steps."""
    scene = load_scene("default")
    cells = [
        Cell(
            scene,
            agent,
            0,
            3,
            100,
            None if agent in ("zero action", "analytic") else 512,
            dict(TINY),
            ranges,
            HELD,
        )
        for agent, ranges in (
            ("zero action", None),
            ("analytic", None),
            ("ppo", None),
            ("ppo", TRAIN),
        )
    ]
    return [run_cell(cell) for cell in cells]


def test_heldout_evaluation_draws_parameters_outside_the_training_ranges(robust_results):
    scene = load_scene("default")
    train_box, held_box = ranges_box(scene, TRAIN), ranges_box(scene, HELD)
    nominal_box = ranges_box(scene, None)
    assert np.allclose(train_box["max_torque"], ((0.15,), (0.25,))) and nominal_box[
        "max_torque"
    ] == ((0.2,), (0.2,))
    for result in robust_results:
        held = result.heldout
        assert held is not None and len(held.params) == 3
        for params in held.params:
            assert set(params) == {"inertia", "max_torque"}
            assert (
                in_box(params, held_box)
                and not in_box(params, train_box)
                and not in_box(params, nominal_box)
            )
            assert 0.10 <= params["max_torque"] <= 0.14
        # the scene's own evaluation draws nothing
        assert result.evaluation.params == ({}, {}, {})
    # the held-out episodes differ from one another (drawn per reset)
    torques = [p["max_torque"] for p in robust_results[0].heldout.params]
    assert len(set(torques)) == 3


def test_randomized_training_draws_from_its_ranges():
    model, info = train(
        "ppo",
        load_scene("default"),
        seed=0,
        timesteps=512,
        progress=False,
        env_overrides={"param_ranges": TRAIN},
        **TINY,
    )
    assert info["env_kwargs"]["param_ranges"] == TRAIN and info["steps_per_s"] > 0
    # the training env was built with the ranges: each sub-env draws at each reset, inside the box
    venv = model.get_env()
    assert venv.num_envs == 8 and np.allclose(
        venv.venv._ranges.bounds["max_torque"], ((0.15,), (0.25,))
    )


def test_heldout_ranges_that_meet_the_training_box_are_refused():
    scene = load_scene("default")
    heldout_outside(scene, TRAIN, HELD)  # apart in max_torque: accepted
    with pytest.raises(ValueError, match="meets the training ranges"):
        heldout_outside(scene, TRAIN, {"max_torque": [0.12, 0.16]})  # overlaps 0.15-0.25
    with pytest.raises(ValueError, match="meets the scene's parameters"):
        heldout_outside(scene, None, {"max_torque": [0.1, 0.3]})  # holds the scene's 0.2


def test_analytic_controller_and_agents_see_the_same_episodes(robust_results):
    by_label = {r.cell.label: r for r in robust_results}
    assert set(by_label) == {"zero action", "analytic", "PPO", "PPO (randomized)"}
    analytic = by_label["analytic"]
    for label, result in by_label.items():
        for kind in (NOMINAL, HELDOUT):
            mine, theirs = result.evaluations()[kind], analytic.evaluations()[kind]
            assert mine.starts == theirs.starts, (label, kind)
            assert mine.params == theirs.params, (label, kind)
        assert len(result.heldout.params) == 3 and all(result.heldout.params)  # drawn, not empty
    # ... and the evaluations are not all alike: the analytic controller holds the spin, zero action
    # does not
    assert (
        analytic.evaluation.success_rate == 1.0
        and by_label["zero action"].evaluation.return_mean < analytic.evaluation.return_mean
    )


def test_throughput_columns_are_measured_and_positive(robust_results):
    records = grid_records(robust_results)
    assert [(r["agent"], r["evaluation"]) for r in records] == [
        (a, kind)
        for kind in (NOMINAL, HELDOUT)
        for a in ("zero action", "analytic", "PPO", "PPO (randomized)")
    ]
    for r in records:
        assert r["env_steps_per_s"] > 0 and r["policy_steps_per_s"] > 0
        learned = r["agent"].startswith("PPO")
        assert (r["train_steps_per_s"] > 0) == learned and r["training"] == (
            "-" if not learned else "randomized" if "random" in r["agent"] else "nominal"
        )
    table = grid_table(records, 1).splitlines()
    assert table[0].endswith("| env steps/s | with policy steps/s | training steps/s |")
    rows = [line.split(" | ") for line in table[2:6]]
    for row, r in zip(rows, records[:4]):
        cols = [c.strip(" |") for c in row]
        assert float(cols[7].replace(",", "")) == pytest.approx(r["env_steps_per_s"], abs=0.5)
        assert float(cols[8].replace(",", "")) == pytest.approx(r["policy_steps_per_s"], abs=0.5)
        assert cols[9] == ("-" if not r["train_steps_per_s"] else f"{r['train_steps_per_s']:,.0f}")
    # the robustness table: one row per agent, held-out ranges and the training ranges named
    held_rows = [line for line in table if "max_torque: [0.1, 0.14]" in line]
    assert len(held_rows) == 4 and any(
        "inertia: 0.1, max_torque: 0.25" in line and "PPO (randomized)" in line
        for line in held_rows
    )


def test_grid_cost_sums_the_trained_rows_and_spreads_them_over_cpus():
    """The cost line: trained rows on the scene's parameters only (a held-out evaluation of the
    same agent is no second training, a baseline none), mean seed times the seeds, the longest
    row named, and ``max(total / k, longest)`` over k free CPUs."""
    from rbenvs_agents.grid import grid_cost

    def rec(agent, wall, steps=1000, evaluation=NOMINAL):
        return {
            "scene": "s",
            "agent": agent,
            "timesteps": steps,
            "wall_time_s": wall,
            "evaluation": evaluation,
        }

    records = [
        rec("zero action", 0.0, steps=0),
        rec("PPO", 100.0),
        rec("SAC", 300.0),
        rec("SAC", 300.0, evaluation=HELDOUT),
    ]
    line = grid_cost(records, 3)
    assert "6 trained cells (2 rows x 3 seeds), 20 min in all" in line  # (100 + 300) x 3 = 1200 s
    assert "the longest, SAC on s, 300 s a seed" in line
    assert (
        "1 CPU 20 min, 2 CPUs 10 min, 4 CPUs 5 min, 16 CPUs 5 min" in line
    )  # (300 s: the longest)
    assert (
        grid_cost([rec("zero action", 0.0, steps=0)], 3)
        == "Training cost: no trained rows in these records."
    )


def test_grid_cells_train_each_algorithm_twice_with_robustness(tmp_path, monkeypatch):
    _grid(
        tmp_path,
        monkeypatch,
        "runs:\n  - scene: default\n    algos: [ppo]\n    robustness:\n"
        f"      train: {json.dumps(TRAIN)}\n      heldout: {json.dumps(HELD)}\n  - scene: "
        "spin_major\n    algos: []\n",
    )
    cells = grid_cells([0, 1], quick=True)
    labels = [(c.scene.name, c.label, c.seed) for c in cells]
    assert labels == [
        ("default", a, s)
        for a in ("zero action", "analytic", "PPO", "PPO (randomized)")
        for s in (0, 1)
    ] + [("spin_major", a, s) for a in ("zero action", "analytic") for s in (0, 1)]
    assert all(c.heldout == HELD for c in cells[:8]) and all(c.heldout is None for c in cells[8:])
    assert [c.train_ranges for c in cells[:8]] == [None] * 6 + [TRAIN] * 2
    _grid(
        tmp_path,
        monkeypatch,
        "runs:\n  - scene: default\n    algos: [ppo]\n    robustness:\n"
        f"      train: {json.dumps(TRAIN)}\n      heldout: {{max_torque: [0.2, 0.3]}}\n",
    )
    with pytest.raises(ValueError, match="scene 'default': robustness.heldout"):
        grid_cells([0], quick=True)


def test_the_shipped_grid_has_learned_agents_and_a_robustness_block_on_every_system_and_task():
    import gymnasium as gym

    import rbenvs

    grid = yaml.safe_load((config.configs_dir() / "results.yml").read_text())
    learned = set()
    for entry in grid["runs"]:
        scene = load_scene(entry["scene"])
        if entry["algos"]:
            assert set(entry["algos"]) >= {"ppo", "sac"} and set(entry["robustness"]) == {
                "train",
                "heldout",
            }, scene.name
            heldout_outside(scene, entry["robustness"]["train"], entry["robustness"]["heldout"])
            learned.add((scene.env_id, scene.kwargs["task"]))
    every = set()
    for env_id in rbenvs.ENVIRONMENTS:
        module, name = gym.spec(env_id).entry_point.split(":")
        every |= {
            (env_id, task) for task in getattr(__import__(module, fromlist=[name]), name).tasks
        }
    assert learned == every


@pytest.mark.parametrize("algo", ["ppo", "sac", "td3"])
def test_every_block_of_the_hyperparameter_files_builds_its_algorithm(algo):
    """For the zoo: each env id's block is complete (merged through the anchor), holds only
    keys the zoo reserves or the algorithm takes, and no rbenvs-only key; for rbenvs-train:
    each `scenes:` override names a scene of its block's env, and the merged configuration of
    every scene of the grid builds the algorithm on the scene's env."""
    import inspect

    data = yaml.safe_load((config.configs_dir() / f"{algo}.yml").read_text())
    cls = algorithm_class(algo)
    takes = set(inspect.signature(cls.__init__).parameters) - {"self", "env"}
    zoo_reserved = {
        "n_timesteps",
        "n_envs",
        "policy",
        "normalize",
        "env_wrapper",
        "callback",
        "frame_stack",
        "policy_kwargs",
    }
    for key, block in data.items():
        if key in ("default", "scenes"):
            continue
        assert key.startswith("rbenvs/") and "n_timesteps" in block and "policy" in block, key
        assert set(block) <= zoo_reserved | takes, (key, set(block) - zoo_reserved - takes)
    for scene_name, block in (data.get("scenes") or {}).items():
        scene = load_scene(scene_name)
        assert set(block) <= zoo_reserved | takes | {
            "eval_episodes",
            "normalize_reward",
            "normalize_obs",
        }, (scene_name, set(block) - zoo_reserved - takes)
    grid = yaml.safe_load((config.configs_dir() / "results.yml").read_text())
    from stable_baselines3.common.env_util import make_vec_env

    for entry in grid["runs"]:
        if algo not in entry["algos"] and algo != "td3":
            continue
        scene = load_scene(entry["scene"])
        cfg = config.agent_config(algo, scene.env_id, scene.name)
        venv = make_vec_env(lambda: scene.make(), n_envs=1, seed=0)
        hyper = dict(cfg.hyperparams) | ({"buffer_size": 1000} if algo != "ppo" else {})
        model = cls(cfg.policy, venv, policy_kwargs=cfg.policy_kwargs or None, **hyper)
        assert model.gamma == cfg.hyperparams.get("gamma", model.gamma)
        venv.close()


def test_results_command_runs_only_the_named_scenes(tmp_path, monkeypatch, capsys):
    from rbenvs_agents.cli import results_main

    _grid(
        tmp_path,
        monkeypatch,
        "runs:\n  - scene: spin_major\n    algos: []\n  - scene: top_sleeping\n    algos: []\n",
    )
    assert (
        results_main(
            [
                "--quick",
                "--no-progress",
                "--scene",
                "top_sleeping",
                "--json",
                str(tmp_path / "r.json"),
            ]
        )
        == 0
    )
    records = json.loads((tmp_path / "r.json").read_text())
    assert [(r["scene"], r["agent"]) for r in records] == [
        ("top_sleeping", "zero action"),
        ("top_sleeping", "analytic"),
    ]
    assert all(
        r["env_steps_per_s"] > 0 and r["policy_steps_per_s"] > 0 and r["train_steps_per_s"] == 0
        for r in records
    )
    capsys.readouterr()
    assert results_main(["--quick", "--scene", "nowhere"]) == 2
    assert "--scene: not in results.yml: ['nowhere']" in capsys.readouterr().err


def test_cell_records_keep_a_result_as_it_was(robust_results, tmp_path):
    """``--records``: every result written and read back gives the same records and table
    (returns, successes, drawn parameters, starts, throughputs)."""
    from rbenvs_agents.records import CellRecords, result_data

    store = CellRecords(tmp_path / "cells.jsonl")
    for result in robust_results:
        store.add(result)
    again = CellRecords(tmp_path / "cells.jsonl")
    loaded = [again.get(result.cell) for result in robust_results]
    assert len(again) == len(robust_results) and all(r is not None for r in loaded)
    assert [result_data(r) for r in loaded] == json.loads(
        json.dumps([result_data(r) for r in robust_results])
    )
    assert grid_records(loaded) == grid_records(robust_results)


def test_results_command_resumes_from_its_records(tmp_path, monkeypatch, capsys):
    """A run with ``--records`` keeps each finished cell; a second run over the same file runs
    nothing and prints the same table; a file cut short (its last line half written) runs
    only the cells it lacks."""
    import rbenvs_agents.backends as backends
    from rbenvs_agents.cli import results_main

    _grid(tmp_path, monkeypatch, "runs:\n  - scene: spin_major\n    algos: []\n")
    ran, real = [], backends.run_cell
    monkeypatch.setattr(
        backends, "run_cell", lambda cell, progress=False: ran.append(cell) or real(cell, progress)
    )
    path = tmp_path / "cells.jsonl"
    args = ["--quick", "--no-progress", "--records", str(path)]
    assert results_main(args + ["--json", str(tmp_path / "a.json")]) == 0
    assert [c.agent for c in ran] == ["zero action", "analytic"] and len(
        path.read_text().splitlines()
    ) == 2
    ran.clear()
    assert results_main(args + ["--json", str(tmp_path / "b.json")]) == 0
    assert ran == []
    first, second = (json.loads((tmp_path / name).read_text()) for name in ("a.json", "b.json"))
    assert first == second
    lines = path.read_text().splitlines()
    path.write_text(
        lines[0] + "\n" + lines[1][: len(lines[1]) // 2]
    )  # stopped while writing the second
    assert results_main(args + ["--json", str(tmp_path / "c.json")]) == 0
    assert [c.agent for c in ran] == ["analytic"]
    assert json.loads((tmp_path / "c.json").read_text())[0] == first[0]
    assert "1 of 2 cells from" in capsys.readouterr().err


def test_a_changed_configuration_is_a_new_cell_key(tmp_path, monkeypatch):
    from rbenvs_agents.records import cell_key

    cell = Cell(load_scene("default"), "ppo", 0, 2, 100)
    before = cell_key(cell)
    _grid(tmp_path, monkeypatch, "runs: []\n")
    assert cell_key(cell) == before  # the same files: the same key
    text = (tmp_path / "ppo.yml").read_text().replace("n_timesteps: 500000", "n_timesteps: 400000")
    (tmp_path / "ppo.yml").write_text(text)
    assert cell_key(cell) != before
    assert cell_key(Cell(load_scene("default"), "zero action", 0, 2, 100)) != cell_key(
        Cell(load_scene("default"), "zero action", 1, 2, 101)
    )


def test_normalize_obs_enters_the_cell_key_only_when_on():
    """``normalize_obs`` is in a learned cell's key where it is on (the top_precess and tippe_hold
    PPO cells) and absent where it is off, so the keys written before the flag existed, those of
    the published records (docs/results.cells.jsonl), still name their cells."""
    from rbenvs_agents.records import cell_key

    off = json.loads(cell_key(Cell(load_scene("default"), "ppo", 0, 2, 100)))["config"]
    on = json.loads(cell_key(Cell(load_scene("top_precess"), "ppo", 0, 2, 100)))["config"]
    assert "normalize_obs" not in off and off["normalize_reward"] is False
    assert on["normalize_obs"] is True

    from pathlib import Path

    from rbenvs import ENVIRONMENTS
    from rbenvs_agents.grid import grid_cells

    # the published records hold every cell of the grid as configured now (docs/agents.md's
    # table is made from them), 3 seeds
    published = {
        json.loads(line)["key"]
        for line in (Path(__file__).resolve().parents[1] / "docs" / "results.cells.jsonl")
        .read_text()
        .splitlines()
    }
    cells = grid_cells([0, 1, 2])
    assert len(cells) >= 3 * len(ENVIRONMENTS)
    assert all(cell_key(c) in published for c in cells)

"""Scale-out on Ray (the ``ray`` extra): the results grid as Ray tasks gives the serial run's
numbers, a sweep of 8 trials on Tune writes a zoo-format best configuration, and RLlib PPO
trains on the native vector env of a runner that never imported rbenvs.

Each test starts an embedded local cluster of 2 CPUs and stops it. Skipped where Ray is not
installed: the ``ray`` extra is not in ``dev`` (RLlib pins an older gymnasium), so the main test
run skips this module and ``make test-ray`` (.ci/run's second job) runs it in a venv of its own,
with ``pytest -m ray``. About 3 minutes on 2 cores, most of it numba compiling the kernels again
in every Ray worker."""

import json
import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.ray
pytest.importorskip(
    "ray", reason="the ray extra is not installed: pip install 'rbenvs[ray]' (make test-ray)"
)
pytest.importorskip(
    "optuna", reason="the ray extra is not installed: pip install 'rbenvs[ray]' (make test-ray)"
)
pytest.importorskip("stable_baselines3")

import yaml  # noqa: E402

from rbenvs.configs import configs_root  # noqa: E402
from rbenvs.scenes import load_scene  # noqa: E402

SCENE = "top_upright"  # the heavy top below its critical spin: a cheap step and a learnable task


@pytest.fixture
def tiny_configs(tmp_path, monkeypatch):
    """$RBENVS_CONFIGS at a copy of the shipped configs with a one-scene grid, PPO's budget on the
    heavy top cut to one rollout (8 sub-envs x 256 steps) and an 8-trial sweep of that budget."""
    root = tmp_path / "configs"
    shutil.copytree(configs_root(), root, ignore=shutil.ignore_patterns("*.py", "__pycache__"))
    ppo = yaml.safe_load((root / "agents" / "ppo.yml").read_text())
    ppo["rbenvs/LagrangeTop-v0"]["n_timesteps"] = 2048
    (root / "agents" / "ppo.yml").write_text(yaml.safe_dump(ppo))
    (root / "agents" / "results.yml").write_text(
        f"runs:\n  - scene: {SCENE}\n    algos: [ppo]\n    eval_episodes: 2\n"
    )
    sweep = yaml.safe_load((root / "agents" / "sweeps" / "ppo.yml").read_text())
    (root / "agents" / "sweeps" / "ppo.yml").write_text(
        yaml.safe_dump(sweep | {"trials": 8, "timesteps": 2048, "eval_episodes": 1})
    )
    monkeypatch.setenv("RBENVS_CONFIGS", str(root))
    return root


MEASURED = (
    "wall_time_s",
    "env_steps_per_s",
    "policy_steps_per_s",
    "train_steps_per_s",
)  # timings: differ run to run


def _without_wall_times(records):
    return [{k: v for k, v in r.items() if k not in MEASURED} for r in records]


def test_the_ray_backend_prints_the_serial_table(tiny_configs, tmp_path, capsys):
    """rbenvs-results --backend ray (its own embedded cluster, started and stopped by the command)
    gives the serial backend's records and table: the same numbers, wall times aside."""
    from rbenvs_agents.cli import results_main

    assert (
        results_main(["--seeds", "2", "--no-progress", "--json", str(tmp_path / "serial.json")])
        == 0
    )
    serial_table = capsys.readouterr().out
    command = Path(sys.executable).with_name("rbenvs-results")
    out = subprocess.run(
        [
            command,
            "--seeds",
            "2",
            "--backend",
            "ray",
            "--num-cpus",
            "2",
            "--json",
            tmp_path / "ray.json",
        ],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=tmp_path,
        env=os.environ | {"RBENVS_CONFIGS": str(tiny_configs)},
    )
    assert out.returncode == 0, out.stderr
    serial, parallel = (
        json.loads((tmp_path / f"{name}.json").read_text()) for name in ("serial", "ray")
    )
    assert [r["agent"] for r in serial] == ["zero action", "analytic", "PPO"] and serial[2][
        "seeds"
    ] == 2
    assert _without_wall_times(parallel) == _without_wall_times(serial)
    assert parallel[2]["wall_time_s"] > 0

    def masked(table):
        # the wall time, the three throughput columns (the table's last three) and the cost line
        # under the table (from the wall times) are measured
        table = re.sub(r"\| \d+ s \|", "| (wall) |", table)
        table = re.sub(
            r"^Training cost \(this run's wall times\): .*$",
            "Training cost (measured)",
            table,
            flags=re.M,
        )
        return re.sub(r"((?: \| (?:[\d,]+|-)){3}) \|$", " | (rates) |", table, flags=re.M)

    assert masked(out.stdout) == masked(serial_table)
    # the command stopped its cluster: no Ray session is left in this process either
    import ray

    assert not ray.is_initialized()


def test_the_workers_get_one_numba_thread_the_configs_and_the_commands_priority(tiny_configs):
    from rbenvs_agents.cluster import ray_cluster

    def worker_view():
        import numba

        from rbenvs.configs import configs_root

        return (
            os.environ.get("NUMBA_NUM_THREADS"),
            numba.config.NUMBA_NUM_THREADS,
            str(configs_root()),
            os.nice(0),
        )

    with ray_cluster(num_cpus=2) as ray:
        assert ray.get(ray.remote(num_cpus=1)(worker_view).remote()) == (
            "1",
            1,
            str(tiny_configs),
            os.nice(0),
        )
    assert not ray.is_initialized()


def test_bad_cluster_arguments_are_one_line(capsys):
    from rbenvs_agents.cli import results_main

    assert results_main(["--quick", "--address", "auto"]) == 2
    assert (
        capsys.readouterr().err
        == "rbenvs-results: error: --address and --num-cpus need --backend ray\n"
    )
    assert (
        results_main(["--quick", "--backend", "ray", "--address", "auto", "--num-cpus", "2"]) == 2
    )
    assert "--num-cpus sizes the embedded local cluster" in capsys.readouterr().err


def test_a_sweep_of_8_trials_writes_the_best_configuration_in_the_zoo_format(
    tiny_configs, tmp_path, capsys
):
    from rbenvs_agents.cli import sweep_main
    from rbenvs_agents.config import agent_config

    out = tmp_path / "best.yml"
    assert (
        sweep_main(["--algo", "ppo", "--scene", SCENE, "--num-cpus", "2", "--out", str(out)]) == 0
    )
    text = capsys.readouterr().out
    table = (
        text[text.index(f"PPO on '{SCENE}': 8 trials, best first") :].split("\n\n")[0].splitlines()
    )
    assert len(table) == 1 + 2 + 8  # title, header, rule, a row per trial
    returns = [float(line.split()[-4]) for line in table[3:]]
    assert returns == sorted(returns, reverse=True) and all(math.isfinite(r) for r in returns)
    assert f"best configuration per scene written to {out}" in text
    assert (tmp_path / "tune" / f"ppo-{SCENE}").is_dir()  # Tune's records, beside the file

    best = yaml.safe_load(out.read_text())
    block, found = best["rbenvs/LagrangeTop-v0"], best["scenes"][SCENE]
    # the env's complete block (as the zoo reads it), the best trial's values in it
    assert {
        "policy",
        "n_timesteps",
        "n_envs",
        "policy_kwargs",
        "n_steps",
        "gamma",
        "learning_rate",
        "batch_size",
    } <= set(block)
    assert set(found) == {"learning_rate", "gamma", "n_steps", "batch_size", "policy_kwargs"}
    assert all(block[k] == v for k, v in found.items())
    assert 1e-4 <= found["learning_rate"] <= 3e-3 and found["policy_kwargs"]["net_arch"] in (
        [64, 64],
        [128, 128],
    )
    assert f"# {SCENE} (rbenvs/LagrangeTop-v0): return {returns[0]:.1f}" in out.read_text()
    # rbenvs reads the written file as it reads its own: the scene's values win
    (tiny_configs / "agents" / "ppo.yml").write_text(out.read_text())
    config = agent_config("ppo", "rbenvs/LagrangeTop-v0", SCENE)
    assert (
        config.hyperparams["learning_rate"] == found["learning_rate"]
        and config.policy_kwargs == found["policy_kwargs"]
    )


def test_rllib_ppo_trains_on_the_native_vector_env_of_a_remote_runner():
    """A few PPO iterations, sampled by one env-runner actor (a process that never imported
    rbenvs) stepping one LagrangeTopVectorEnv of 4 sub-envs: no error, env steps counted, finite
    losses."""
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig

    from rbenvs_agents.cluster import ray_cluster
    from rbenvs_agents.rllib import iteration_summary, ppo_config

    with ray_cluster(num_cpus=2):
        config = (
            ppo_config(load_scene(SCENE), num_env_runners=1, num_envs_per_env_runner=4)
            .training(train_batch_size_per_learner=256, minibatch_size=64, num_epochs=1)
            .rl_module(model_config=DefaultModelConfig(fcnet_hiddens=[32, 32]))
        )
        algo = config.build_algo()
        try:
            envs = algo.env_runner_group.foreach_env_runner(
                lambda runner: type(runner.env.unwrapped).__name__, local_env_runner=False
            )
            assert envs == ["LagrangeTopVectorEnv"]
            steps = []
            for _ in range(3):
                summary = iteration_summary(algo.train())
                assert all(
                    math.isfinite(summary[k]) for k in ("total_loss", "policy_loss", "vf_loss")
                ), summary
                steps.append(summary["env_steps"])
        finally:
            algo.stop()
    assert 256 <= steps[0] < steps[1] < steps[2] and steps[2] >= 3 * 256


def test_the_env_creator_registers_the_ids_in_a_fresh_process():
    """RLlib's runners call the creator where rbenvs was never imported (gymnasium's registry is
    per process): it imports rbenvs itself, and makes the vector env when RLlib asks for one."""
    code = (
        "import gymnasium as gym\n"
        "assert 'rbenvs/TippeTop-v0' not in gym.registry\n"
        "from rbenvs_agents.rllib import env_creator\n"
        "venv = env_creator({'env_id': 'rbenvs/TippeTop-v0', 'task': 'hold', 'num_envs': 3})\n"
        "env = env_creator({'env_id': 'rbenvs/TippeTop-v0', 'task': 'hold'})\n"
        "print(type(venv).__name__, venv.num_envs, venv.max_episode_steps, "
        "type(env.unwrapped).__name__)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["TippeTopVectorEnv", "3", "2500", "TippeTopEnv"]

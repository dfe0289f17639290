"""Baseline agents (rbenvs_agents): configuration, smoke training of every algorithm on every
env (CI's smoke run), evaluation of learned and analytic policies, the command line."""

import json
import math

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from rbenvs.scenes import load_scene  # noqa: E402
from rbenvs_agents.cli import eval_main, train_main  # noqa: E402
from rbenvs_agents.config import agent_config  # noqa: E402
from rbenvs_agents.evaluate import analytic_policy, evaluate, summarize, zero_policy  # noqa: E402
from rbenvs_agents.train import train  # noqa: E402

SMOKE_SCENES = ("default", "top_upright", "tippe_hold")


def test_config_precedence_default_env_scene_override():
    base = agent_config("ppo", "rbenvs/Unknown-v0")  # only the default block applies
    env = agent_config("ppo", "rbenvs/FreeRigidBody-v0", "default")
    assert base.n_timesteps == 200000 and env.n_timesteps == 500000  # the env's block wins
    assert env.n_envs == 8 and env.hyperparams["gamma"] == 0.98
    over = agent_config("ppo", "rbenvs/FreeRigidBody-v0", "default", n_timesteps=123, gamma=0.9)
    assert over.n_timesteps == 123 and over.hyperparams["gamma"] == 0.9
    assert env.policy_kwargs == {"net_arch": [64, 64]}
    for reserved in ("n_timesteps", "n_envs", "policy", "policy_kwargs", "eval_episodes"):
        assert reserved not in env.hyperparams


def test_config_errors_name_the_problem():
    with pytest.raises(ValueError, match="algo"):
        agent_config("a2c", "rbenvs/FreeRigidBody-v0")
    with pytest.raises(ValueError, match="n_timesteps"):
        agent_config("ppo", "rbenvs/FreeRigidBody-v0", n_timesteps=0)


@pytest.mark.parametrize("scene_name", SMOKE_SCENES)
@pytest.mark.parametrize("algo", ["ppo", "sac", "td3"])
def test_smoke_training_of_every_algorithm_on_every_env(algo, scene_name, tmp_path):
    scene = load_scene(scene_name)
    # a few thousand env steps where a step is cheap; the tippe top's step costs ~100x more, and an
    # off-policy algorithm's gradient step (one per env step after learning_starts) ~50x an env step
    steps = 300 if scene.env_id == "rbenvs/TippeTop-v0" or algo != "ppo" else 2000
    extra = {} if algo == "ppo" else {"learning_starts": 100}
    model, info = train(
        algo, scene, seed=0, timesteps=steps, out_dir=tmp_path, progress=False, **extra
    )
    assert info["timesteps"] == steps and info["wall_time_s"] > 0
    assert (tmp_path / "model.zip").is_file()
    assert json.loads((tmp_path / "run.json").read_text())["algo"] == algo
    env = scene.make()
    obs, _ = env.reset(seed=0)
    action, _ = model.predict(obs, deterministic=True)
    assert env.action_space.contains(action.astype(np.float32))


def test_zero_action_reproduces_the_theorems():
    """Stable axes and a sleeping top succeed without control; the intermediate axis and a slow
    top do not; the analytic controllers succeed on the unstable ones."""
    for name, zero_succeeds in (
        ("spin_major", True),
        ("spin_minor", True),
        ("top_sleeping", True),
        ("default", False),
        ("top_upright", False),
    ):
        scene = load_scene(name)
        zero = evaluate(zero_policy, scene, episodes=3, seed=7)
        assert zero.success_rate == (1.0 if zero_succeeds else 0.0), name
        if not zero_succeeds:
            assert evaluate(analytic_policy, scene, episodes=3, seed=7).success_rate == 1.0, name


def test_evaluation_is_seeded_and_summarized_across_seeds():
    scene = load_scene("default")
    a = evaluate(analytic_policy, scene, episodes=2, seed=3)
    b = evaluate(analytic_policy, scene, episodes=2, seed=3)
    assert a == b and len(a.returns) == 2 and all(n == 400 for n in a.lengths)
    s = summarize([a, evaluate(analytic_policy, scene, episodes=2, seed=4)])
    assert s["seeds"] == 2 and s["success_mean"] == 1.0 and s["return_std"] >= 0.0


def test_train_and_eval_commands(tmp_path, capsys):
    out = tmp_path / "run"
    assert (
        train_main(
            [
                "--algo",
                "ppo",
                "--scene",
                "top_upright",
                "--timesteps",
                "512",
                "--out",
                str(out),
                "--eval-episodes",
                "1",
                "--no-progress",
            ]
        )
        == 0
    )
    text = capsys.readouterr().out
    assert "analytic" in text and "zero action" in text and "ppo (seed 0)" in text
    # the evaluation is kept in run.json, and the command says where
    assert f"evaluation written to {out / 'run.json'}" in text
    run = json.loads((out / "run.json").read_text())
    assert (
        run["algo"] == "ppo"
        and run["evaluation"]["seeds"] == [100, 101, 102]
        and run["evaluation"]["episodes"] == 1
    )
    assert [r["agent"] for r in run["evaluation"]["results"]] == [
        "ppo (seed 0)",
        "analytic",
        "zero action",
    ]
    assert all(
        len(r["per_seed"]) == 3 and math.isfinite(r["return_mean"])
        for r in run["evaluation"]["results"]
    )
    assert (
        eval_main(
            [
                "--scene",
                "top_upright",
                "--agent",
                str(out / "model.zip"),
                "--agent",
                "zero",
                "--episodes",
                "1",
                "--seeds",
                "0",
                "--json",
            ]
        )
        == 0
    )
    records = json.loads(capsys.readouterr().out)["results"]
    assert [r["agent"] for r in records] == [str(out / "model.zip"), "zero"]
    # several agents after one flag, as the synopsis shows them
    assert (
        eval_main(
            [
                "--scene",
                "top_upright",
                "--agent",
                "analytic",
                "zero",
                "--episodes",
                "1",
                "--seeds",
                "0",
                "--json",
            ]
        )
        == 0
    )
    assert [r["agent"] for r in json.loads(capsys.readouterr().out)["results"]] == [
        "analytic",
        "zero",
    ]
    # a bad agent is one line and exit status 2, like an unknown scene (rbenvs.extras.run_command)
    assert eval_main(["--scene", "top_upright", "--agent", str(tmp_path / "missing.zip")]) == 2
    err = capsys.readouterr().err
    assert (
        err.startswith("rbenvs-eval: error: agent must be")
        and "model.zip" in err
        and err.count("\n") == 1
    )


def test_results_command_prints_the_table_of_its_grid(tmp_path, monkeypatch, capsys):
    """rbenvs-results on a one-scene grid (--quick: a twentieth of the budget, one seed)."""
    import shutil

    import rbenvs_agents.config as config
    from rbenvs_agents.cli import results_main

    shutil.copy(config.configs_dir() / "ppo.yml", tmp_path / "ppo.yml")
    (tmp_path / "results.yml").write_text("runs:\n  - scene: top_sleeping\n    algos: [ppo]\n")
    monkeypatch.setattr(config, "configs_dir", lambda: tmp_path)
    assert results_main(["--quick", "--no-progress", "--json", str(tmp_path / "r.json")]) == 0
    table, cost = capsys.readouterr().out.strip().split("\n\n")
    lines = table.splitlines()
    assert (
        lines[0].startswith("| env | task (scene) | agent |") and len(lines) == 2 + 3
    )  # header, rule, 3 agents
    assert (
        cost.startswith("Training cost") and "1 trained cell" in cost
    )  # the run's cost line under its table
    records = json.loads((tmp_path / "r.json").read_text())
    assert [r["agent"] for r in records] == ["zero action", "analytic", "PPO"]
    assert (
        records[2]["timesteps"] == 5000 and records[0]["success_mean"] == 1.0
    )  # zero action: a sleeping top


def test_normalize_reward_scales_rewards_only(tmp_path):
    """``normalize_reward: true`` trains on VecNormalize's scaled rewards; the observations stay
    the env's own, so the saved policy acts on the plain env with no statistics."""
    from stable_baselines3.common.vec_env import VecNormalize

    cfg = agent_config("ppo", "rbenvs/FreeRigidBody-v0", "default", normalize_reward=True)
    assert cfg.normalize_reward is True and "normalize_reward" not in cfg.hyperparams
    assert agent_config("ppo", "rbenvs/FreeRigidBody-v0", "default").normalize_reward is False
    with pytest.raises(ValueError, match="normalize_reward must be true or false"):
        agent_config("ppo", "rbenvs/FreeRigidBody-v0", normalize_reward="yes")
    model, _ = train(
        "ppo",
        load_scene("default"),
        seed=0,
        timesteps=512,
        progress=False,
        normalize_reward=True,
        n_steps=64,
        batch_size=64,
    )
    venv = model.get_env()
    assert (
        isinstance(venv, VecNormalize)
        and venv.norm_reward
        and not venv.norm_obs
        and venv.gamma == 0.98
    )
    obs = venv.reset()
    assert np.array_equal(obs, venv.get_original_obs())  # observations pass through unchanged


def test_normalize_obs_standardises_observations_and_the_policy_carries_the_statistics(tmp_path):
    """``normalize_obs: true`` trains on VecNormalize's standardised observations; the statistics
    at the end of training are recorded (``info`` and ``run.json``: ``obs_normalization``) and the
    policy applies them, frozen: its action on a raw observation is the model's action on that
    observation standardised as VecNormalize does (here and after loading from disk)."""
    from stable_baselines3.common.vec_env import VecNormalize

    from rbenvs_agents.cli import _policy_factory
    from rbenvs_agents.evaluate import sb3_policy

    assert agent_config("ppo", "rbenvs/LagrangeTop-v0", "top_precess").normalize_obs is True
    assert agent_config("ppo", "rbenvs/FreeRigidBody-v0", "default").normalize_obs is False
    with pytest.raises(ValueError, match="normalize_obs must be true or false"):
        agent_config("ppo", "rbenvs/FreeRigidBody-v0", normalize_obs=1)
    model, info = train(
        "ppo",
        load_scene("top_upright"),
        seed=0,
        timesteps=512,
        progress=False,
        normalize_obs=True,
        n_steps=64,
        batch_size=64,
        out_dir=tmp_path / "run",
    )
    venv = model.get_env()
    assert isinstance(venv, VecNormalize) and venv.norm_obs and not venv.norm_reward
    norm = info["obs_normalization"]
    assert np.array_equal(norm["mean"], venv.obs_rms.mean) and np.array_equal(
        norm["var"], venv.obs_rms.var
    )
    assert json.loads((tmp_path / "run" / "run.json").read_text())["obs_normalization"] == norm
    env = load_scene("top_upright").make()
    obs, _ = env.reset(seed=3)
    expected, _ = model.predict(
        venv.normalize_obs(obs[None].astype(np.float64))[0].astype(np.float32), deterministic=True
    )
    assert np.array_equal(sb3_policy(model, norm).predict(obs), expected)
    loaded = _policy_factory(str(tmp_path / "run" / "model.zip"))(env)
    assert np.array_equal(loaded.predict(obs), expected)
    assert not np.array_equal(
        sb3_policy(model).predict(obs), expected
    )  # (raw observations act otherwise)

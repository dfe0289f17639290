"""The ecosystem's tools on the envs, without glue: rl-baselines3-zoo trains every env from the
shipped hyperparameter files, gymnasium's RecordVideo records an episode of every env, and
``rbenvs-train --tensorboard`` writes TensorBoard logs (the ``zoo``, ``video`` and
``tensorboard`` extras, all in ``dev``)."""

import gc
import importlib.util
import math
import os
import pathlib
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

import rbenvs

ROOT = pathlib.Path(__file__).resolve().parents[1]
ENV_IDS = list(rbenvs.ENVIRONMENTS)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_rl_zoo3_trains_every_env_from_the_shipped_config(env_id, tmp_path):
    """The zoo's own command line, as the README gives it, with our ppo.yml unchanged (a few
    hundred steps: two PPO updates on two sub-envs); the model it saves acts in the env."""
    # located, not imported: importing rl_zoo3 patches gymnasium's TimeLimit for the whole
    # process (rl_zoo3.gym_patches adds info["TimeLimit.truncated"]), which other tests in this
    # worker would then see; the zoo runs in its own process below
    if importlib.util.find_spec("rl_zoo3") is None:
        pytest.skip("rl_zoo3 is not installed (the zoo extra)")
    yaml = pytest.importorskip("yaml")
    from stable_baselines3 import PPO

    cmd = [
        sys.executable,
        "-m",
        "rl_zoo3.train",
        "--algo",
        "ppo",
        "--env",
        env_id,
        "--gym-packages",
        "rbenvs",
        "--conf-file",
        str(ROOT / "configs" / "agents" / "ppo.yml"),
        "-n",
        "256",
        "--eval-freq",
        "-1",
        "--seed",
        "0",
        "--log-folder",
        str(tmp_path),
        "--hyperparams",
        "n_envs:2",
        "n_steps:64",
        "batch_size:64",
        # the float path: 256 steps cost less than compiling the period (seconds, per env)
        "--env-kwargs",
        "compiled:False",
    ]
    done = subprocess.run(
        cmd,
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
        env=os.environ | {"PYTHONUNBUFFERED": "1", "OMP_NUM_THREADS": "1"},
    )  # (torch's threads against xdist's workers: 2x slower)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    name = env_id.replace("/", "-")
    (run,) = (tmp_path / "ppo").glob(f"{name}_*")
    # the zoo read our block: the env's budget and the defaults merged into it by the anchor
    saved = yaml.safe_load(
        (run / name / "config.yml")
        .read_text()
        .replace("!!python/object/apply:collections.OrderedDict", "")
    )
    saved = dict(saved[0]) if isinstance(saved, list) else saved
    ours = yaml.safe_load((ROOT / "configs" / "agents" / "ppo.yml").read_text())[env_id]
    assert saved["gamma"] == ours["gamma"] == 0.98 and saved["n_timesteps"] == ours["n_timesteps"]
    assert saved["policy"] == "MlpPolicy" and saved["n_envs"] == 2  # (the command line's override)
    updates = [int(line.split("|")[2]) for line in done.stdout.splitlines() if "n_updates" in line]
    assert updates and updates[-1] >= 1, done.stdout[
        -2000:
    ]  # PPO did update (10 epochs per rollout)
    model = PPO.load(run / f"{name}.zip", device="cpu")
    env = gym.make(env_id)
    obs, _ = env.reset(seed=1)
    action, _ = model.predict(obs, deterministic=True)
    assert env.action_space.contains(action.astype(env.action_space.dtype))
    env.step(action)
    env.close()


def _frames(path):
    """Every frame of the file, decoded by ffmpeg (imageio-ffmpeg, which moviepy writes with): its
    own count, not one derived from duration x fps."""
    import imageio_ffmpeg

    reader = imageio_ffmpeg.read_frames(str(path))
    meta = reader.__next__()
    width, height = meta["size"]
    frames = [np.frombuffer(raw, np.uint8).reshape(height, width, 3) for raw in reader]
    reader.close()
    return frames, (width, height)


# moviepy's ffmpeg writer (RecordVideo's) leaves its subprocess's pipes to the garbage collector:
# collected at the end of the test (below), their ResourceWarning is moviepy's, not ours
@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_record_video_records_an_episode_of_every_env(env_id, tmp_path):
    """RecordVideo over ``render_mode="rgb_array"``: one mp4 per episode, one frame recorded per
    observation (the reset's and each step's), at the env's frame size and frame rate
    (``render_fps`` = 1/dt); the frames change."""
    pytest.importorskip("moviepy")
    from gymnasium.wrappers import RecordVideo

    steps = 12
    folder = (
        tmp_path / "videos"
    )  # (a new folder: RecordVideo warns when it writes into an existing one)
    env = RecordVideo(
        gym.make(env_id, render_mode="rgb_array", max_episode_steps=steps),
        str(folder),
        name_prefix="episode",
        episode_trigger=lambda episode: True,
        disable_logger=True,
    )
    env.reset(seed=0)
    size = env.render().shape  # (height, width, 3)
    for _step in range(steps - 1):
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        assert not (terminated or truncated)
    assert len(env.recorded_frames) == steps  # the reset's frame and one per step so far
    _, _, terminated, truncated, _ = env.step(env.action_space.sample())
    assert truncated
    env.close()  # writes the file
    gc.collect()  # (the writer's pipes, here rather than in a later test)
    (video,) = folder.glob("episode-episode-0.mp4")
    frames, (width, height) = _frames(video)
    assert (height, width) == size[:2]
    # steps + 1 frames were handed to moviepy; it samples the clip at t = k / fps for t < N / fps,
    # which in floating point can drop the last frame (it does at 50 and 100 fps, not at 20)
    assert len(frames) in (steps, steps + 1)
    assert any(
        np.abs(frames[0].astype(int) - f.astype(int)).mean() > 0.01 for f in frames[1:]
    )  # the body moves


def test_rbenvs_train_writes_tensorboard_logs(tmp_path):
    """``train(..., tensorboard=DIR)`` (the ``--tensorboard`` flag): SB3's scalars land in one run
    folder under DIR, finite; two PPO updates on the free body's native vector env."""
    pytest.importorskip("tensorboard")
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    from rbenvs.scenes import load_scene
    from rbenvs_agents.train import train

    model, info = train(
        "ppo",
        load_scene("default"),
        seed=0,
        timesteps=256,
        out_dir=tmp_path / "run",
        progress=False,
        tensorboard=tmp_path / "tb",
        n_envs=2,
        n_steps=64,
        batch_size=64,
    )
    logdir = pathlib.Path(info["tensorboard"])
    assert logdir.parent == tmp_path / "tb" and logdir.name.startswith("ppo-default-seed0")
    events = EventAccumulator(str(logdir))
    events.Reload()
    tags = events.Tags()["scalars"]
    for tag in ("train/value_loss", "train/policy_gradient_loss", "time/fps"):
        assert tag in tags, tags
        assert all(math.isfinite(e.value) for e in events.Scalars(tag))


def test_rbenvs_train_tensorboard_flag(tmp_path):
    from rbenvs_agents.cli import train_main

    out = tmp_path / "run"
    assert (
        train_main(
            [
                "--algo",
                "ppo",
                "--scene",
                "default",
                "--timesteps",
                "64",
                "--out",
                str(out),
                "--no-compare",
                "--no-progress",
                "--tensorboard",
                str(tmp_path / "tb"),
            ]
        )
        == 0
    )
    assert list((tmp_path / "tb").glob("ppo-default-seed0_*/events.out.tfevents.*"))


def test_scene_overrides_are_a_top_level_block_the_zoo_never_reads(tmp_path, monkeypatch):
    """``scenes: {<scene>: {...}}`` overrides a scene's block for rbenvs-train; the env blocks
    stay complete for the zoo."""
    pytest.importorskip("yaml")
    from rbenvs_agents.config import agent_config

    (tmp_path / "agents").mkdir()
    (tmp_path / "agents" / "ppo.yml").write_text(
        "default: &default\n  policy: MlpPolicy\n  n_timesteps: 100\n  gamma: 0.9\n"
        "  policy_kwargs: {net_arch: [8]}\n"
        "rbenvs/FreeRigidBody-v0:\n  <<: *default\n  n_timesteps: 200\n"
        "scenes:\n  reorient:\n    gamma: 0.5\n"
    )
    monkeypatch.setenv("RBENVS_CONFIGS", str(tmp_path))
    plain = agent_config("ppo", "rbenvs/FreeRigidBody-v0", "default")
    scene = agent_config("ppo", "rbenvs/FreeRigidBody-v0", "reorient")
    other = agent_config("ppo", "rbenvs/LagrangeTop-v0", "top_upright")
    assert (plain.n_timesteps, plain.hyperparams["gamma"]) == (200, 0.9)
    assert (scene.n_timesteps, scene.hyperparams["gamma"]) == (200, 0.5)
    assert (other.n_timesteps, other.hyperparams["gamma"], other.policy_kwargs) == (
        100,
        0.9,
        {"net_arch": [8]},
    )


def test_rbenvs_results_prints_a_finished_runs_table_from_its_json(tmp_path, capsys):
    """``--from-json``: the table of a run's records (``--json``) without training, as the
    docs' block is written; each record one row, in order."""
    import json

    from rbenvs_agents.cli import results_main

    records = [
        {
            "scene": "default",
            "env_id": "rbenvs/FreeRigidBody-v0",
            "task": "spin",
            "agent": "zero action",
            "timesteps": 0,
            "wall_time_s": 0.0,
            "seeds": 3,
            "return_mean": 150.14,
            "return_std": 42.04,
            "success_mean": 1 / 30,
            "success_std": 0.05,
        },
        {
            "scene": "top_upright",
            "env_id": "rbenvs/LagrangeTop-v0",
            "task": "upright",
            "agent": "PPO",
            "timesteps": 100000,
            "wall_time_s": 17.2,
            "seeds": 3,
            "return_mean": 499.93,
            "return_std": 0.01,
            "success_mean": 1.0,
            "success_std": 0.0,
        },
    ]
    path = tmp_path / "results.json"
    path.write_text(json.dumps(records))
    assert results_main(["--from-json", str(path)]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert (
        lines[0].endswith(
            "| return (mean +- std, 3 seeds) | success | env steps/s | with policy steps/s | "
            "training steps/s |"
        )
        and len(lines) == 6
    )
    # (records of a run from before the throughput columns show "-" there)
    assert (
        lines[2]
        == "| FreeRigidBody-v0 | spin (default) | zero action | - | - | 150.1 +- 42.0 | 3% | "
        "- | - | - |"
    )
    assert (
        lines[3]
        == "| LagrangeTop-v0 | upright (top_upright) | PPO | 100,000 | 17 s | 499.9 +- 0.0 | "
        "100% | - | - | - |"
    )
    # under the table, the run's training cost (the trained row's seeds)
    assert lines[4] == "" and lines[5].startswith(
        "Training cost (this run's wall times): 3 trained cells (1 row x 3 seeds), 52 s in all;"
    )
    # an option of a run is refused, naming it, not silently ignored (nothing runs)
    for extra in (
        ["--quick"],
        ["--seeds", "3"],
        ["--backend", "ray"],
        ["--num-cpus", "2"],
        ["--address", "auto"],
    ):
        with pytest.raises(SystemExit):
            results_main(["--from-json", str(path), *extra])
        assert f"leave out {extra[0]}" in capsys.readouterr().err


def test_an_id_with_its_module_steps_from_a_script_that_never_imports_rbenvs(tmp_path):
    """gymnasium's ``"module:id"`` form: a fresh process that imports only gymnasium makes and
    steps the tippe top (and a vector env), rbenvs imported by gymnasium itself."""
    code = (
        "import sys\n"
        "import gymnasium as gym\n"
        "import numpy as np\n"
        "assert 'rbenvs' not in sys.modules\n"
        "try:\n"
        "    gym.make('rbenvs/TippeTop-v0')\n"
        "    raise SystemExit('made without its module')\n"
        "except gym.error.NamespaceNotFound:\n"
        "    pass\n"
        "env = gym.make('rbenvs:rbenvs/TippeTop-v0')\n"
        "env.reset(seed=0)\n"
        "obs, *_ = env.step(np.zeros(env.action_space.shape, np.float32))\n"
        "venv = gym.make_vec('rbenvs:rbenvs/FreeRigidBody-v0', num_envs=2, "
        "vectorization_mode='vector_entry_point')\n"
        "venv.reset(seed=0)\n"
        "vobs, *_ = venv.step(np.zeros(venv.action_space.shape, np.float32))\n"
        "print(obs.shape, vobs.shape, 'rbenvs' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["(8,)", "(2,", "3)", "True"], (
        out.stdout
    )  # (the tippe top's 8 observations, 2 free bodies' 3)

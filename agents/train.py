"""Training stable-baselines3 agents on rbenvs scenes, on the native vector env.

``train(algo, scene, seed)`` builds the scene's batched vector env through the SB3 adapter
(:mod:`rbenvs.vector.sb3`; one batched physics call per step for all sub-envs; with
``n_envs: 1``, SB3's ``DummyVecEnv`` of one single env, whose float path is faster), the
algorithm with the hyperparameters of ``configs/agents/<algo>.yml``, and learns for the
configured budget with a progress bar and optional checkpoints. The run directory receives
``model.zip`` and ``run.json`` (configuration, seed, steps, wall time).
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict
from pathlib import Path

from rbenvs.extras import require

from .config import agent_config

__all__ = ["train", "algorithm_class"]


def algorithm_class(algo: str):
    from stable_baselines3 import PPO, SAC, TD3

    return {"ppo": PPO, "sac": SAC, "td3": TD3}[algo]


def _progress_callback(total: int, label: str, enabled: bool):
    from stable_baselines3.common.callbacks import BaseCallback

    from rbenvs.progress import Progress

    class ProgressBar(BaseCallback):
        """A bar over env steps (SB3's own bar needs `rich`, which the agents extra omits)."""

        def _on_training_start(self):
            self.bar, self.done = Progress(total, enabled, label), 0

        def _on_step(self):
            # (rollouts may overshoot the budget: the bar stops at it)
            n = min(self.training_env.num_envs, total - self.done)
            self.bar.update(n)
            self.done += n
            return True

        def _on_training_end(self):
            self.bar.close()

    return ProgressBar()


def train(
    algo: str,
    scene,
    seed: int = 0,
    timesteps: int | None = None,
    out_dir=None,
    progress: bool = True,
    checkpoint_every: int | None = None,
    device: str = "cpu",
    tensorboard=None,
    env_overrides=None,
    **overrides,
):
    """Train ``algo`` on ``scene`` (an :class:`rbenvs.scenes.Scene`); returns ``(model, info)``
    with ``info`` the run record (also written to ``out_dir/run.json`` with ``model.zip``).
    ``env_overrides``: env keywords over the scene's (``{"param_ranges": {...}}`` trains with
    domain randomization). ``info["steps_per_s"]`` is the measured training throughput: env
    steps over the wall time of ``learn`` (rollouts, updates and all).
    ``tensorboard``: a folder for SB3's TensorBoard logs (the ``tensorboard`` extra), one run
    folder ``<algo>-<scene>-seed<seed>_N`` inside it."""
    import torch
    from stable_baselines3.common.callbacks import CallbackList, CheckpointCallback

    from rbenvs.vector.sb3 import make_sb3_vec_env

    if tensorboard is not None:
        require("tensorboard")  # before the envs are built, not after
    cfg = agent_config(algo, scene.env_id, scene.name, **overrides)
    total = int(timesteps if timesteps is not None else cfg.n_timesteps)
    torch.set_num_threads(1)  # small MLPs: threads cost more than they give on 2 cores
    env_kwargs = dict(scene.kwargs) | dict(env_overrides or {})
    if cfg.n_envs == 1:
        # one env: the single env's float path beats a batch of one (numpy's per-call cost
        # dominates arrays of length 1; about 10x on the tippe top)
        from stable_baselines3.common.env_util import make_vec_env

        venv = make_vec_env(lambda: scene.make(**dict(env_overrides or {})), n_envs=1, seed=seed)
    else:
        venv = make_sb3_vec_env(scene.env_id, cfg.n_envs, seed=seed, **env_kwargs)
    if cfg.normalize_reward or cfg.normalize_obs:
        from stable_baselines3.common.vec_env import VecNormalize

        # without normalize_obs the policy sees the env's own observations, in training and after;
        # with it, the final statistics go with the policy (info["obs_normalization"])
        venv = VecNormalize(
            venv,
            norm_obs=cfg.normalize_obs,
            norm_reward=cfg.normalize_reward,
            gamma=float(cfg.hyperparams.get("gamma", 0.99)),
        )
    cls = algorithm_class(algo)
    model = cls(
        cfg.policy,
        venv,
        seed=seed,
        device=device,
        policy_kwargs=cfg.policy_kwargs or None,
        verbose=0,
        tensorboard_log=None if tensorboard is None else str(tensorboard),
        **cfg.hyperparams,
    )
    callbacks = [_progress_callback(total, f"{algo} {scene.name} seed {seed}", progress)]
    out = Path(out_dir) if out_dir is not None else None
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        if checkpoint_every:
            callbacks.append(
                CheckpointCallback(
                    max(1, checkpoint_every // cfg.n_envs),
                    str(out / "checkpoints"),
                    name_prefix=algo,
                )
            )
    start = time.perf_counter()
    model.learn(
        total, callback=CallbackList(callbacks), tb_log_name=f"{algo}-{scene.name}-seed{seed}"
    )
    wall = time.perf_counter() - start
    info = {
        "algo": algo,
        "scene": scene.name,
        "env_id": scene.env_id,
        "env_kwargs": env_kwargs,
        "seed": seed,
        "timesteps": total,
        "wall_time_s": wall,
        "steps_per_s": model.num_timesteps
        / wall,  # (a rollout may overshoot the budget: the steps taken)
        "config": asdict(cfg),
    }
    if cfg.normalize_obs:
        info["obs_normalization"] = {
            "mean": venv.obs_rms.mean.tolist(),
            "var": venv.obs_rms.var.tolist(),
            "epsilon": float(venv.epsilon),
            "clip": float(venv.clip_obs),
        }
    if tensorboard is not None:
        info["tensorboard"] = model.logger.dir  # the run's own folder of event files
    if out is not None:
        model.save(out / "model.zip")
        (out / "run.json").write_text(json.dumps(info, indent=2, default=str))
    venv.close()
    return model, info

"""RLlib on the native vector envs: PPO whose env runners step one rbenvs vector env each.

RLlib's env runners make their envs with ``gymnasium.make_vec``. With
``gym_env_vectorize_mode=gymnasium.VectorizeMode.VECTOR_ENTRY_POINT`` a runner's
``num_envs_per_env_runner`` sub-envs are one :mod:`rbenvs.vector` env (one batched, compiled
step for all of them) instead of that many single envs stepped one after another.

RLlib takes an env by a name of Ray's own registry (:data:`ENV_NAME`, registered to
:func:`env_creator` by :func:`ppo_config`), and calls the creator in each runner's own process,
where the gymnasium registry of the driver does not exist (RLlib warns of it): the creator
imports rbenvs, which registers the ids, before it makes the env. Its ``config`` is RLlib's
``env_config``: ``env_id`` and the env's keyword arguments (a scene's), plus the ``num_envs``
RLlib adds for a vector env.

    with ray_cluster(num_cpus=2):                    # rbenvs_agents.cluster: NUMBA_NUM_THREADS=1
    per worker
        algo = ppo_config(load_scene("top_upright")).build_algo()
        for _ in range(10):
            result = algo.train()

``python -m rbenvs_agents.rllib --scene top_upright --iterations 10`` does that and prints each
iteration's env steps, episode return and losses.
"""

from __future__ import annotations

import math
import sys

__all__ = ["ENV_NAME", "env_creator", "ppo_config", "iteration_summary", "main"]

ENV_NAME = "rbenvs"  # the name of env_creator in Ray's registry: env_config's env_id says which env


def env_creator(config):
    """RLlib's env creator: a single env of ``config["env_id"]``, or its native vector env of
    ``config["num_envs"]`` sub-envs; the other keys are the env's keyword arguments."""
    import gymnasium as gym

    import rbenvs  # noqa: F401  (registers the ids in this worker's gymnasium registry)

    kwargs = dict(config)
    env_id = kwargs.pop("env_id")
    num_envs = kwargs.pop("num_envs", None)
    if num_envs is None:
        return gym.make(env_id, **kwargs)
    return gym.make_vec(
        env_id, num_envs=num_envs, vectorization_mode=gym.VectorizeMode.VECTOR_ENTRY_POINT, **kwargs
    )


def ppo_config(scene, num_env_runners: int = 1, num_envs_per_env_runner: int = 8, seed: int = 0):
    """RLlib's ``PPOConfig`` for ``scene`` (an :class:`rbenvs.scenes.Scene`) on its native vector
    env: ``num_env_runners`` runner actors (0: sample in this process), each stepping one vector
    env of ``num_envs_per_env_runner`` sub-envs. Change the rest as for any ``PPOConfig``
    (``.training(lr=...)``)."""
    import gymnasium as gym
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.tune.registry import register_env

    register_env(ENV_NAME, env_creator)
    return (
        PPOConfig()
        .environment(env=ENV_NAME, env_config={"env_id": scene.env_id, **scene.kwargs})
        .env_runners(
            num_env_runners=num_env_runners,
            num_envs_per_env_runner=num_envs_per_env_runner,
            gym_env_vectorize_mode=gym.VectorizeMode.VECTOR_ENTRY_POINT,
        )
        .debugging(seed=seed)
    )


def iteration_summary(result: dict) -> dict:
    """The numbers of one ``algo.train()`` result this module reports: env steps sampled so far,
    the mean return of the episodes finished (NaN before the first) and the learner's losses."""
    runners, learner = result["env_runners"], result["learners"]["default_policy"]
    return {
        "env_steps": int(runners["num_env_steps_sampled_lifetime"]),
        "episode_return_mean": float(runners.get("episode_return_mean", math.nan)),
        "total_loss": float(learner["total_loss"]),
        "policy_loss": float(learner["policy_loss"]),
        "vf_loss": float(learner["vf_loss"]),
    }


def main(argv=None) -> int:
    from rbenvs.extras import require, run_command

    def body(argv):
        from rbenvs.extras import ArgumentParser

        p = ArgumentParser(
            prog="python -m rbenvs_agents.rllib",
            description="RLlib PPO on a scene's native vector env (the ray extra).",
        )
        p.add_argument("--scene", default="default")
        p.add_argument("--iterations", type=int, default=10)
        p.add_argument("--num-env-runners", type=int, default=1)
        p.add_argument(
            "--num-envs", type=int, default=8, help="sub-envs of each runner's vector env"
        )
        p.add_argument(
            "--train-batch-size",
            type=int,
            default=None,
            help="env steps per iteration (default: RLlib's, 4000)",
        )
        p.add_argument(
            "--num-epochs",
            type=int,
            default=None,
            help="passes over each batch (default: RLlib's, 30)",
        )
        p.add_argument("--seed", type=int, default=0)
        p.add_argument(
            "--address", default=None, help="join this Ray cluster (default: start a local one)"
        )
        p.add_argument(
            "--num-cpus",
            type=int,
            default=None,
            help="CPUs of the local cluster (default: every core)",
        )
        args = p.parse_args(argv)
        require("ray")
        from rbenvs.scenes import load_scene

        from .cluster import ray_cluster

        scene = load_scene(args.scene)
        with ray_cluster(args.address, args.num_cpus):
            config = ppo_config(scene, args.num_env_runners, args.num_envs, args.seed)
            if args.train_batch_size is not None:
                config = config.training(train_batch_size_per_learner=args.train_batch_size)
            if args.num_epochs is not None:
                config = config.training(num_epochs=args.num_epochs)
            algo = config.build_algo()
            try:
                for i in range(args.iterations):
                    s = iteration_summary(algo.train())
                    print(
                        f"iteration {i + 1}: {s['env_steps']} env steps, episode return "
                        f"{s['episode_return_mean']:.1f}, "
                        f"loss {s['total_loss']:.3g} (policy {s['policy_loss']:.3g}, value "
                        f"{s['vf_loss']:.3g})",
                        flush=True,
                    )
            finally:
                algo.stop()
        return 0

    return run_command("rbenvs_agents.rllib", body, argv)


if __name__ == "__main__":
    sys.exit(main())

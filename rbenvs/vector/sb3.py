"""stable-baselines3 on rbenvs' native vector envs (needs stable-baselines3: the ``agents`` extra).

SB3 takes its own ``VecEnv``, not a gymnasium ``VectorEnv``. :class:`SB3VecEnv` adapts an
rbenvs vector env (built with ``autoreset_mode="SameStep"``, SB3's semantics) so that SB3's
algorithms step all sub-environments in one batched call instead of a Python loop over single
envs (``DummyVecEnv``):

* ``step_wait`` returns ``(obs, rewards, dones, infos)`` with ``dones = terminated | truncated``;
  a sub-env whose episode ended is already reset, its last observation is in
  ``infos[i]["terminal_observation"]`` and ``infos[i]["TimeLimit.truncated"]`` says whether the
  time limit (and not the task) ended it — what SB3 uses to bootstrap the value.
* ``infos[i]`` is filled (every key of the env's info, as Python scalars) only for sub-envs
  whose episode ended in that step; the others get an empty dict. Building 4096 dicts of ten
  entries every step would cost more than the physics; pass ``info_keys`` to have some keys on
  every step.
* ``reset()`` uses the seeds given with ``seed()`` (SB3's convention: sub-env ``i`` gets
  ``seed + i``) once, then continues each sub-env's own generator.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env.base_vec_env import (
    VecEnv,
)  # the agents extra (this module is imported on demand)

__all__ = ["SB3VecEnv", "make_sb3_vec_env"]


class SB3VecEnv(VecEnv):
    """An SB3 ``VecEnv`` over an rbenvs vector env in ``SameStep`` autoreset mode."""

    def __init__(self, venv, info_keys=()):
        venv = getattr(venv, "unwrapped", venv)
        if venv.metadata.get("autoreset_mode") is not AutoresetMode.SAME_STEP:
            raise ValueError(
                "SB3VecEnv needs a vector env made with autoreset_mode='SameStep' (SB3 resets in "
                "the ending step)"
            )
        self.venv = venv
        self.info_keys = tuple(info_keys)
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self._actions = None

    def reset(self):
        seed = self._seeds if any(s is not None for s in self._seeds) else None
        obs, _ = self.venv.reset(seed=seed)
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions):
        self._actions = np.asarray(actions)

    def step_wait(self):
        obs, rewards, terminated, truncated, info = self.venv.step(self._actions)
        dones = terminated | truncated
        infos = [{} for _ in range(self.num_envs)]
        for key in self.info_keys:
            values = info[key]
            for i in range(self.num_envs):
                infos[i][key] = values[i].item() if hasattr(values[i], "item") else values[i]
        done_idx = np.flatnonzero(dones)
        if len(done_idx):
            final_info = info["final_info"]
            for i in done_idx:
                entry = infos[i]
                for key, values in final_info.items():
                    if not key.startswith("_"):
                        v = values[i]
                        entry[key] = v.item() if hasattr(v, "item") else v
                entry["terminal_observation"] = info["final_obs"][i]
                entry["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
        return obs, rewards.astype(np.float32), dones, infos

    def close(self):
        self.venv.close()

    def get_attr(self, attr_name, indices=None):
        """Every sub-env shares one configuration: the vector env's attribute, once per index."""
        value = getattr(self.venv, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name, value, indices=None):
        raise AttributeError(
            "SB3VecEnv: sub-environments share one configuration; set attributes on the vector env "
            "itself"
        )

    def env_method(self, method_name, *method_args, indices=None, **method_kwargs):
        """The vector env's method (the sub-envs share one configuration), once per index."""
        method = getattr(self.venv, method_name)
        return [method(*method_args, **method_kwargs) for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class, indices=None):
        return [False for _ in self._get_indices(indices)]

    def _get_indices(self, indices):
        if indices is None:
            return range(self.num_envs)
        if isinstance(indices, int):
            return [indices]
        return indices


def make_sb3_vec_env(
    env_id: str, num_envs: int, seed: int | None = None, info_keys=(), **kwargs
) -> SB3VecEnv:
    """``SB3VecEnv`` over ``gymnasium.make_vec(env_id, num_envs, vector_entry_point, SameStep)``."""
    import rbenvs  # noqa: F401  (registers the ids)

    venv = gym.make_vec(
        env_id,
        num_envs=num_envs,
        vectorization_mode="vector_entry_point",
        autoreset_mode="SameStep",
        **kwargs,
    )
    env = SB3VecEnv(venv, info_keys=info_keys)
    if seed is not None:
        env.seed(seed)
    return env

"""Agent hyperparameters: ``configs/agents/<algo>.yml``, the rl-baselines3-zoo layout.

One file per algorithm, in the zoo's own format so that ``python -m rl_zoo3.train --conf-file``
reads it unchanged: top-level keys are env ids, each a complete block (the files merge their
``default:`` block into each through a YAML anchor, ``<<: *default``); an env id without a block
takes ``default:``. A scene may override its env's block under a top-level
``scenes: {<scene>: {...}}`` (an rbenvs extension: the zoo looks up env ids only, so it never
sees it). Values are structured (numbers, strings naming SB3 things, lists, mappings), never
code. Reserved keys:

* ``n_timesteps``: the training budget (env steps over all sub-envs);
* ``n_envs``: sub-environments of the native vector env (SB3 adapter);
* ``policy``: SB3 policy name (``MlpPolicy``);
* ``policy_kwargs``: a mapping (``net_arch: [64, 64]``);
* ``eval_episodes``: episodes per evaluation seed (rbenvs only: the zoo would pass it to the
  algorithm, so the shipped files leave it out);
* ``normalize_reward``: train on rewards scaled by SB3's ``VecNormalize`` (``norm_obs=False``,
  the running standard deviation of the discounted return; observations stay raw, so the
  trained policy acts on the env as it is, with no statistics to carry). rbenvs only, like
  ``eval_episodes``: the shipped files set it in ``scenes:`` blocks, which the zoo never reads.
* ``normalize_obs``: train on observations standardised by ``VecNormalize``'s running mean and
  variance (clipped at 10 standard deviations); the statistics at the end of training are kept
  with the policy (``run.json``'s ``obs_normalization``; :func:`rbenvs_agents.evaluate.sb3_policy`)
  and applied, frozen, wherever it acts. For observations of very different scales (a top's
  spin of 20 rad/s beside the unit vertical). rbenvs only, like ``normalize_reward``.

Every other key goes to the algorithm's constructor (``learning_rate``, ``gamma``, ...).
Precedence: ``default`` (when the env id has no block) < env id < scene < explicit overrides.

The files ship with the package (``rbenvs.configs``); ``$RBENVS_CONFIGS`` replaces them with a
folder of your own (see :func:`rbenvs.configs.configs_root`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from rbenvs.configs import configs_root
from rbenvs.extras import require

__all__ = ["ALGORITHMS", "AgentConfig", "agent_config", "configs_dir"]

ALGORITHMS = ("ppo", "sac", "td3")
RESERVED = (
    "n_timesteps",
    "n_envs",
    "policy",
    "policy_kwargs",
    "eval_episodes",
    "normalize_reward",
    "normalize_obs",
)


def configs_dir():
    """The folder of the hyperparameter files: ``agents/`` of
    :func:`rbenvs.configs.configs_root`."""
    return configs_root() / "agents"


@dataclass(frozen=True)
class AgentConfig:
    algo: str
    env_id: str
    scene: str | None
    n_timesteps: int
    n_envs: int = 1
    policy: str = "MlpPolicy"
    policy_kwargs: dict = field(default_factory=dict)
    eval_episodes: int = 10
    hyperparams: dict = field(default_factory=dict)
    normalize_reward: bool = False
    normalize_obs: bool = False


def agent_config(algo: str, env_id: str, scene: str | None = None, **overrides) -> AgentConfig:
    """The merged configuration of ``algo`` for ``env_id`` (and ``scene``)."""
    require("cli")
    import yaml

    if algo not in ALGORITHMS:
        raise ValueError(f"algo must be one of {list(ALGORITHMS)}, got {algo!r}")
    path = configs_dir() / f"{algo}.yml"
    if not path.is_file():
        raise ValueError(f"no hyperparameters for {algo!r}: {path} is missing")
    data = yaml.safe_load(path.read_text()) or {}
    if not isinstance(data, dict) or not isinstance(data.get("default", {}), dict):
        raise ValueError(f"{path} must be a mapping with a 'default:' block")
    merged: dict = {}
    # as the zoo reads it: the env's block if there is one, else default's
    env_block = data.get(env_id) or data.get("default", {}) or {}
    scene_block = (data.get("scenes", {}) or {}).get(scene, {}) if scene else {}
    for block in (env_block, scene_block, overrides):
        for key, value in block.items():
            if key == "policy_kwargs":
                merged[key] = dict(merged.get(key, {})) | dict(value or {})
            else:
                merged[key] = value
    if "n_timesteps" not in merged:
        raise ValueError(
            f"{path}: no n_timesteps for {env_id!r} (set it in 'default:' or the env's block)"
        )
    n_timesteps = int(merged.pop("n_timesteps"))
    if n_timesteps < 1:
        raise ValueError(f"n_timesteps must be >= 1, got {n_timesteps}")
    n_envs = int(merged.pop("n_envs", 1))
    if n_envs < 1:
        raise ValueError(f"n_envs must be >= 1, got {n_envs}")
    return AgentConfig(
        algo=algo,
        env_id=env_id,
        scene=scene,
        n_timesteps=n_timesteps,
        n_envs=n_envs,
        policy=str(merged.pop("policy", "MlpPolicy")),
        policy_kwargs=dict(merged.pop("policy_kwargs", {}) or {}),
        eval_episodes=int(merged.pop("eval_episodes", 10)),
        normalize_reward=_flag("normalize_reward", merged.pop("normalize_reward", False)),
        normalize_obs=_flag("normalize_obs", merged.pop("normalize_obs", False)),
        hyperparams=merged,
    )


def _flag(name: str, value) -> bool:
    if not isinstance(value, bool):
        raise ValueError(f"{name} must be true or false, got {value!r}")
    return value

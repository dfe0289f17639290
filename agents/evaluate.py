"""Evaluation shared by learned agents and analytic controllers.

A *policy* is anything with ``predict(obs) -> action`` (numpy in, numpy out). Learned agents
(SB3 models, deterministic actions), the analytic controller of the scene's task
(``rbenvs.controllers.controller_for``) and zero action are evaluated the same way: episodes
on a single env of the scene, seeded ``seed * 1000 + episode``, reporting the return and the
task's success measure (``info["is_success"]`` at the episode's end).

Each evaluation also keeps what makes two evaluations comparable episode by episode: the
drawn parameters of each episode (``info["params"]`` at reset, with ``param_ranges``) and its
first observation; two policies evaluated with the same scene, options and seed see the same
episodes (the env draws parameters and start before any action). ``steps_per_s`` is the
measured throughput of the evaluation loop, env steps with the policy's inference in the loop;
:func:`env_throughput` measures the env alone.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field

import numpy as np

__all__ = [
    "Evaluation",
    "evaluate",
    "env_throughput",
    "analytic_policy",
    "zero_policy",
    "sb3_policy",
    "summarize",
]


@dataclass(frozen=True)
class Evaluation:
    """One policy on one scene over ``episodes`` episodes of one evaluation seed."""

    returns: tuple[float, ...]
    successes: tuple[bool, ...]
    lengths: tuple[int, ...]
    # per episode: the drawn parameters ({} without param_ranges) and the first observation
    params: tuple[dict, ...] = ()
    starts: tuple[tuple[float, ...], ...] = ()
    # env steps per second of the loop, the policy's inference included (measured: not compared)
    steps_per_s: float = field(default=0.0, compare=False)

    @property
    def return_mean(self) -> float:
        return float(np.mean(self.returns))

    @property
    def success_rate(self) -> float:
        return float(np.mean(self.successes))

    def as_dict(self) -> dict:
        out = asdict(self) | {"return_mean": self.return_mean, "success_rate": self.success_rate}
        out["params"] = [dict(p) for p in self.params]
        out["starts"] = [list(s) for s in self.starts]
        return out


def _plain(params: dict) -> dict:
    """``info["params"]`` as plain numbers (vector keywords as tuples): comparable and
    JSON-ready."""
    return {
        k: tuple(float(c) for c in np.atleast_1d(v)) if np.ndim(v) else float(v)
        for k, v in params.items()
    }


class _Controller:
    """An analytic controller (``controller(obs) -> action``) as a policy."""

    def __init__(self, controller):
        self.controller = controller

    def predict(self, obs):
        return np.asarray(self.controller(obs), dtype=np.float32)


def analytic_policy(env):
    from rbenvs.controllers import controller_for

    return _Controller(controller_for(env))


def zero_policy(env):
    from rbenvs.controllers import ZeroController

    return _Controller(ZeroController(env))


class _SB3:
    def __init__(self, model, normalization=None):
        self.model = model
        self.scale = None
        if (
            normalization is not None
        ):  # VecNormalize's standardisation, frozen at the end of training
            self.mean = np.asarray(normalization["mean"], dtype=np.float64)
            self.scale = np.sqrt(
                np.asarray(normalization["var"], dtype=np.float64) + float(normalization["epsilon"])
            )
            self.clip = float(normalization["clip"])

    def predict(self, obs):
        if self.scale is not None:
            obs = np.clip(
                (np.asarray(obs, dtype=np.float64) - self.mean) / self.scale, -self.clip, self.clip
            ).astype(np.float32)
        action, _ = self.model.predict(obs, deterministic=True)
        return action


def sb3_policy(model, normalization=None):
    """A trained SB3 model as a policy (deterministic actions); ``normalization``: the
    ``obs_normalization`` its training recorded (``normalize_obs``), applied to every
    observation as ``VecNormalize`` did, or ``None``."""
    return _SB3(model, normalization)


def evaluate(
    policy_factory, scene, episodes: int = 10, seed: int = 0, env_overrides=None
) -> Evaluation:
    """Run ``episodes`` episodes of ``scene`` (an :class:`rbenvs.scenes.Scene`) with the policy
    ``policy_factory(env)`` builds."""
    env = scene.make(**(env_overrides or {}))
    policy = policy_factory(env)
    returns, successes, lengths, params, starts = [], [], [], [], []
    start = time.perf_counter()
    for episode in range(episodes):
        obs, info = env.reset(seed=seed * 1000 + episode)
        params.append(_plain(info.get("params", {})))
        starts.append(tuple(float(x) for x in obs))
        total, steps, done = 0.0, 0, False
        while not done:
            obs, reward, terminated, truncated, info = env.step(policy.predict(obs))
            total += float(reward)
            steps += 1
            done = terminated or truncated
        returns.append(total)
        successes.append(bool(info.get("is_success", False)))
        lengths.append(steps)
    wall = time.perf_counter() - start
    env.close()
    return Evaluation(
        tuple(returns),
        tuple(successes),
        tuple(lengths),
        tuple(params),
        tuple(starts),
        sum(lengths) / wall,
    )


def env_throughput(
    scene, seconds: float = 0.5, max_steps: int = 20000, seed: int = 0, env_overrides=None
) -> float:
    """Env steps per second of the single env of ``scene`` alone: uniform random actions drawn
    beforehand (no policy in the loop), restarts included, for about ``seconds`` (or
    ``max_steps`` steps), after 64 untimed steps."""
    env = scene.make(**(env_overrides or {}))
    env.action_space.seed(seed)
    rng = np.random.default_rng(seed)
    actions = rng.uniform(-1.0, 1.0, (1024, *env.action_space.shape)).astype(np.float32)
    env.reset(seed=seed)
    for a in actions[:64]:  # warm-up, not timed: a compiled step is built on the first steps
        _, _, terminated, truncated, _ = env.step(a)
        if terminated or truncated:
            env.reset(seed=seed)
    env.reset(seed=seed)
    steps, episode = 0, 0
    start = time.perf_counter()
    while True:
        for _ in range(64):
            _, _, terminated, truncated, _ = env.step(actions[steps % len(actions)])
            steps += 1
            if terminated or truncated:
                episode += 1
                env.reset(seed=seed + episode)
        wall = time.perf_counter() - start
        if wall >= seconds or steps >= max_steps:
            break
    env.close()
    return steps / wall


def summarize(evaluations) -> dict:
    """Across seeds: mean and standard deviation of the per-seed mean return and success rate."""
    means = np.array([e.return_mean for e in evaluations])
    rates = np.array([e.success_rate for e in evaluations])
    return {
        "seeds": len(evaluations),
        "return_mean": float(means.mean()),
        "return_std": float(means.std()),
        "success_mean": float(rates.mean()),
        "success_std": float(rates.std()),
    }

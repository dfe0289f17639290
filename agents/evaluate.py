"""Evaluation shared by learned agents and analytic controllers.

A *policy* is anything with ``predict(obs) -> action`` (numpy in, numpy out). Learned agents
(SB3 models, deterministic actions), the analytic controller of the scene's task
(``rbenvs.controllers.controller_for``) and zero action are evaluated the same way: episodes
on a single env of the scene, seeded ``seed * 1000 + episode``, reporting the return and the
task's success measure (``info["is_success"]`` at the episode's end).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

__all__ = ["Evaluation", "evaluate", "analytic_policy", "zero_policy", "sb3_policy", "summarize"]


@dataclass(frozen=True)
class Evaluation:
    """One policy on one scene over ``episodes`` episodes of one evaluation seed."""

    returns: tuple[float, ...]
    successes: tuple[bool, ...]
    lengths: tuple[int, ...]

    @property
    def return_mean(self) -> float:
        return float(np.mean(self.returns))

    @property
    def success_rate(self) -> float:
        return float(np.mean(self.successes))

    def as_dict(self) -> dict:
        return asdict(self) | {"return_mean": self.return_mean, "success_rate": self.success_rate}


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
    def __init__(self, model):
        self.model = model

    def predict(self, obs):
        action, _ = self.model.predict(obs, deterministic=True)
        return action


def sb3_policy(model):
    return _SB3(model)


def evaluate(policy_factory, scene, episodes: int = 10, seed: int = 0, env_overrides=None) -> Evaluation:
    """Run ``episodes`` episodes of ``scene`` (an :class:`rbenvs.scenes.Scene`) with the policy
    ``policy_factory(env)`` builds."""
    env = scene.make(**(env_overrides or {}))
    policy = policy_factory(env)
    returns, successes, lengths = [], [], []
    for episode in range(episodes):
        obs, info = env.reset(seed=seed * 1000 + episode)
        total, steps, done = 0.0, 0, False
        while not done:
            obs, reward, terminated, truncated, info = env.step(policy.predict(obs))
            total += float(reward)
            steps += 1
            done = terminated or truncated
        returns.append(total)
        successes.append(bool(info.get("is_success", False)))
        lengths.append(steps)
    env.close()
    return Evaluation(tuple(returns), tuple(successes), tuple(lengths))


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

import gymnasium as gym
import pytest

import rbenvs

ENV_IDS = sorted(rbenvs.ENVIRONMENTS)


def env_class(env_id):
    spec = gym.spec(env_id)
    ep = spec.entry_point
    if isinstance(ep, str):
        mod, name = ep.split(":")
        ep = getattr(__import__(mod, fromlist=[name]), name)
    return ep


def all_variants():
    """(env_id, task, integrator) for every registered id, task and integrator."""
    out = []
    for env_id in ENV_IDS:
        cls = env_class(env_id)
        for task in cls.tasks:
            for integ in cls.integrators:
                out.append(pytest.param(env_id, task, integ, id=f"{env_id}-{task}-{integ}"))
    return out

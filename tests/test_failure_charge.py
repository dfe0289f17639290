"""The failure charge: an episode that ends without success carries, in its last reward,
``max_episode_steps`` times the task's least reward where negative (rbenvs.core.model.Model), on
the single env, the vector env's numpy path and its compiled path alike; a success is not
charged; the least reward is a true lower bound of every step's reward inside the bounds."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import rbenvs  # noqa: F401  (registers the ids)
from rbenvs.controllers import controller_for
from rbenvs.vector import vector_class

FB, HT, TT = "rbenvs/FreeRigidBody-v0", "rbenvs/LagrangeTop-v0", "rbenvs/TippeTop-v0"

# (id, kwargs, the charge docs/environments.md states, its formula from the task's reward)
DEFAULTS = [
    (FB, dict(), -404.0, lambda e: -(1.0 + 0.01) * 400),
    (
        FB,
        dict(task="detumble"),
        -6932.0,
        lambda e: -(math.sqrt(3.0) * 10.0 / e.task.spin_rate + 0.01) * 400,
    ),
    (
        FB,
        dict(task="reorient"),
        -1097.0,
        lambda e: -(1.0 + 0.1 * math.sqrt(3.0) * 10.0 / e.task.spin_rate + 0.01) * 400,
    ),
    (HT, dict(), 0.0, lambda e: min(0.0, math.cos(e.task.tilt_limit) - e.task.control_cost) * 500),
    (HT, dict(task="precess"), -505.0, lambda e: -(1.0 + 0.01) * 500),
    (TT, dict(), -2525.0, lambda e: -(1.0 + 0.01) * 2500),
    (TT, dict(task="hold"), -25.0, lambda e: -0.01 * 2500),
]


@pytest.mark.parametrize("env_id,kwargs,documented,formula", DEFAULTS)
def test_charge_at_the_defaults_is_the_documented_one(env_id, kwargs, documented, formula):
    env = gym.make(env_id, **kwargs).unwrapped
    charge = env.model.failure_charge
    assert charge == pytest.approx(formula(env), rel=1e-12)
    assert round(charge) == documented  # (docs/environments.md rounds to the unit)
    assert env.model.episode_steps == gym.spec(env_id).max_episode_steps


@pytest.mark.parametrize(
    "env_id,kwargs",
    [
        (FB, dict(task="detumble")),
        (FB, dict(task="reorient")),
        (HT, dict(task="precess")),
        (TT, dict()),
    ],
)
def test_least_reward_bounds_every_uncharged_step(env_id, kwargs):
    """Random actions on 64 sub-envs for 60 periods: every reward of a step that was not a
    failed end lies at or above the task's least reward (the floor the charge is made of)."""
    single = gym.make(env_id, **kwargs).unwrapped
    floor = single.task.reward_floor(single.system, single.model.observation_high)
    venv = vector_class(type(single))(num_envs=64, **kwargs)
    venv.reset(seed=1)
    rng = np.random.default_rng(2)
    seen = []
    for _ in range(60):
        actions = rng.choice([-1.0, 1.0], size=venv.action_space.shape).astype(np.float32)
        _, reward, terminated, _, info = venv.step(actions)
        charged = terminated & ~np.asarray(info["is_success"], dtype=bool)
        seen.append(reward[~charged])
    seen = np.concatenate(seen)
    assert seen.size > 0 and seen.min() >= floor


def _fall_run(kwargs, compiled):
    """The heavy top at 0.5 x critical spin under zero action: it falls (a failed end)."""
    single = gym.make(HT, **kwargs)
    single.reset(seed=3)
    rewards, infos = [], []
    while True:
        _, r, te, tr, info = single.step(np.zeros(single.action_space.shape, np.float32))
        rewards.append(r)
        infos.append(info)
        if te or tr:
            break
    venv = vector_class(type(single.unwrapped))(num_envs=2, compiled=compiled, **kwargs)
    venv.reset(seed=[3, 4])
    vr = []
    for _ in rewards:
        _, r, te, _, _ = venv.step(np.zeros(venv.action_space.shape, np.float32))
        vr.append(r[0])
    return single.unwrapped, rewards, infos, vr, venv


@pytest.mark.parametrize("compiled", [False, True])
def test_failed_end_is_charged_alike_on_every_path(compiled):
    # a tilt limit past 90 deg makes the upright task's least reward negative: a charge to see
    kwargs = dict(task="upright", tilt_limit=2.0)
    env, rewards, infos, vector_rewards, venv = _fall_run(kwargs, compiled)
    if compiled:
        assert venv.compiled
    last = infos[-1]
    assert last["terminal_reason"] == "task" and last["is_success"] is False
    charge = env.model.failure_charge
    assert (
        charge == pytest.approx((math.cos(2.0) - env.task.control_cost) * 500, rel=1e-12)
        and charge < -200.0
    )
    assert (
        -1.0 <= rewards[-1] - charge <= math.cos(2.0) + 1e-12
    )  # the step's own cos(tilt), past the limit
    assert all(r > -1.0 for r in rewards[:-1])  # no other step is charged
    assert vector_rewards == rewards  # bit for bit, the charge included


def test_success_is_not_charged():
    """Detumble under its damping controller ends in success: its last reward is the task's own
    (-|Omega| / spin_rate - control_cost mean(u^2), near 0), not charged."""
    env = gym.make(FB, task="detumble")
    obs, _ = env.reset(seed=0)
    controller = controller_for(env.unwrapped)
    while True:
        obs, r, te, tr, info = env.step(controller(obs))
        if te or tr:
            break
    assert te and info["is_success"] is True and info["terminal_reason"] == "task"
    assert -0.02 < r <= 0.0


def test_failed_end_is_charged_once_with_param_ranges():
    """With ``param_ranges`` the vector env steps each sub-env by its episode's own engine (the
    single env's step, charged there): the batch's bookkeeping must not charge it again."""
    kwargs = dict(task="upright", tilt_limit=2.0, param_ranges={"gravity": (9.7, 9.9)})
    single = gym.make(HT, **kwargs)
    single.reset(seed=3)
    rewards = []
    while True:
        _, r, te, tr, _ = single.step(np.zeros(single.action_space.shape, np.float32))
        rewards.append(r)
        if te or tr:
            break
    assert te and rewards[-1] < -200.0  # charged (about (cos 2 - 0.01) x 500)
    venv = vector_class(type(single.unwrapped))(num_envs=2, **kwargs)
    venv.reset(seed=[3, 4])
    vector_rewards = [
        venv.step(np.zeros(venv.action_space.shape, np.float32))[1][0] for _ in rewards
    ]
    assert vector_rewards == rewards

"""One conformance suite over every registered id, task and integrator."""

import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from conftest import ENV_IDS, all_variants, unchecked
from gymnasium.utils.env_checker import check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

VARIANTS = all_variants()


@pytest.mark.parametrize("env_id,task,integrator", VARIANTS)
def test_check_env_gymnasium_and_sb3(env_id, task, integrator):
    env = gym.make(env_id, task=task, integrator=integrator, **unchecked(integrator))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped, skip_render_check=True)
        sb3_check_env(env.unwrapped, warn=True)


@pytest.mark.parametrize("env_id,task,integrator", VARIANTS)
def test_step_types_and_info(env_id, task, integrator):
    env = gym.make(env_id, task=task, integrator=integrator, **unchecked(integrator))
    obs, info = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    for _ in range(5):
        obs, r, te, tr, info = env.step(env.action_space.sample())
        assert type(r) is float and type(te) is bool and type(tr) is bool
        assert obs.dtype == np.float32 and env.observation_space.contains(obs)
        for key in env.unwrapped.invariants + ("numerical_failure", "is_success"):
            assert key in info
        assert np.isfinite(info["energy"]) and info["numerical_failure"] is False
        # (error_estimate is None where nothing is estimated: tolerance=None, a scheme without an
        # error constant)
    assert all(
        type(v) in (float, bool, int, str) or (k == "error_estimate" and v is None)
        for k, v in info.items()
    ), {k: type(v) for k, v in info.items()}


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_registered_with_time_limit_and_dt(env_id):
    env = gym.make(env_id)
    assert env.spec.max_episode_steps is not None and env.spec.max_episode_steps > 0
    assert env.unwrapped.dt > 0
    assert env.action_space.dtype == np.float32
    assert np.all(env.action_space.low == -1) and np.all(env.action_space.high == 1)
    assert np.all(np.isfinite(env.observation_space.low)) and np.all(
        np.isfinite(env.observation_space.high)
    )


@pytest.mark.parametrize("env_id,task", sorted({(v.values[0], v.values[1]) for v in VARIANTS}))
def test_seeded_determinism(env_id, task):
    def rollout(seed):
        env = gym.make(env_id, task=task)
        env.action_space.seed(seed)
        obs, _ = env.reset(seed=seed)
        out = [obs]
        for _ in range(20):
            out.append(env.step(env.action_space.sample())[0])
        return np.array(out)

    a, b, c = rollout(1), rollout(1), rollout(2)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


@pytest.mark.parametrize("env_id,task", sorted({(v.values[0], v.values[1]) for v in VARIANTS}))
def test_pickle_roundtrip_continues_identically(env_id, task):
    env = gym.make(env_id, task=task)
    env.reset(seed=0)
    env.step(env.action_space.sample())
    clone = pickle.loads(pickle.dumps(env))
    action = np.full(env.action_space.shape, 0.3, dtype=np.float32)
    assert np.array_equal(env.step(action)[0], clone.step(action)[0])


@pytest.mark.parametrize("env_id,task,integrator", VARIANTS)
def test_state_roundtrip_bit_for_bit(env_id, task, integrator):
    env = gym.make(env_id, task=task, integrator=integrator, **unchecked(integrator)).unwrapped
    env.reset(seed=5)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (6,) + env.action_space.shape).astype(np.float32)
    env.step(actions[0])
    state = env.get_state()
    first = [env.step(a)[0] for a in actions[1:]]
    env.reset(seed=99, options={"state": state})
    second = [env.step(a)[0] for a in actions[1:]]
    assert np.array_equal(np.array(first), np.array(second))
    # get_state returns copies: mutating them changes nothing
    s = env.get_state()
    for v in s.values():
        v[...] = np.nan
    assert all(np.all(np.isfinite(v)) for v in env.get_state().values())

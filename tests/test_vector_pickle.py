"""A vector env pickles and deep-copies on every path (compiled, numpy, the generator tables of
restarts and noise, a tolerance and its check, param_ranges), its compiled parts made again on
loading, and the copy goes on bit for bit with the original."""

import copy
import pickle

import numpy as np
import pytest
from conftest import FREE, LAGRANGE, TIPPE, make_vec, same

CASES = [
    (FREE, {}),
    (FREE, {"compiled": False}),
    (FREE, {"observation_noise": 0.01, "action_delay": 2}),
    (FREE, {"tolerance": 1e-6, "tolerance_check": True}),
    (LAGRANGE, {}),
    (LAGRANGE, {"integrator": "rk4", "tolerance": 1e-6}),
    (LAGRANGE, {"task": "upright", "tilt_limit": 2.0, "param_ranges": {"gravity": (9.7, 9.9)}}),
    (TIPPE, {}),
    (TIPPE, {"compiled": False, "autoreset_mode": "same_step"}),
]


@pytest.mark.filterwarnings("ignore::UserWarning")
@pytest.mark.parametrize(
    "env_id, kwargs",
    CASES,
    ids=[f"{e.split('/')[1]}-{'-'.join(map(str, k)) or 'default'}" for e, k in CASES],
)
def test_a_pickled_or_copied_vector_env_goes_on_bit_for_bit(env_id, kwargs):
    kwargs = dict(kwargs)
    if kwargs.get("autoreset_mode") == "same_step":
        from gymnasium.vector import AutoresetMode

        kwargs["autoreset_mode"] = AutoresetMode.SAME_STEP
    # short episodes: restarts after the copy (the tippe top on numpy, 0.1 s a step: shorter still)
    limit, before, after = (
        (8, 10, 20) if env_id == TIPPE and kwargs.get("compiled") is False else (50, 30, 90)
    )
    env = make_vec(env_id, 4, max_episode_steps=limit, **kwargs)
    rng = np.random.default_rng(7)
    env.reset(seed=11)

    def actions():
        return rng.uniform(-1.5, 1.5, env.action_space.shape).astype(env.action_space.dtype)

    for _ in range(before):
        env.step(actions())
    copies = [pickle.loads(pickle.dumps(env)), copy.deepcopy(env)]
    for c in copies:
        assert c.compiled == env.compiled and (c.compiled_path.whole is None) == (
            env.compiled_path.whole is None
        )
    # past the episodes' ends, where the restarts draw from the generator tables made again
    # around the copied generators
    for _ in range(after):
        a = actions()
        out = env.step(a)
        for c in copies:
            other = c.step(a)
            assert all(same(x, y) for x, y in zip(out[:4], other[:4]))
            assert same(out[4], other[4])
    # and a reset of the copy draws what the original's draws
    assert all(same(x, y) for x, y in zip(env.reset(seed=3)[0], copies[0].reset(seed=3)[0]))


def test_a_pickled_numpy_path_env_with_observation_noise_goes_on_bit_for_bit():
    """Without the compiled step there is no noise table: the copy must come back without one
    too (it came back as ``False`` and failed at its first step)."""
    env = make_vec(FREE, 4, max_episode_steps=10, compiled=False, observation_noise=0.01)
    env.reset(seed=3)
    copy = pickle.loads(pickle.dumps(env))
    a = np.full(env.action_space.shape, 0.3, dtype=np.float32)
    for _ in range(12):
        assert all(same(x, y) for x, y in zip(env.step(a)[:4], copy.step(a)[:4]))


def test_a_pickled_or_copied_env_keeps_its_shared_info_masks_read_only():
    # info's masks are arrays the env shares between steps (read-only, so that a caller writing
    # into one cannot change the next step's info); pickle gives arrays back writable
    env = make_vec(FREE, 4)
    _, info = env.reset(seed=0)
    masks = [k for k, v in info.items() if k.startswith("_") and isinstance(v, np.ndarray)]
    assert masks and not any(info[k].flags.writeable for k in masks)
    for other in (pickle.loads(pickle.dumps(env)), copy.deepcopy(env)):
        _, info = other.reset(seed=0)
        assert not any(info[k].flags.writeable for k in masks)
        info = other.step(np.zeros((4, 3), dtype=np.float32))[4]
        assert not any(info[k].flags.writeable for k in masks)

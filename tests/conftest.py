import os
from pathlib import Path

# The test run's compiled kernels in a cache of its own (rbenvs.kernel_cache), shared by the
# xdist workers (each loads what another compiled) and kept between runs of this checkout; a
# clean clone starts it empty. Set before rbenvs compiles anything; RBENVS_CACHE_DIR overrides.
os.environ.setdefault(
    "RBENVS_CACHE_DIR", str(Path(__file__).resolve().parent.parent / ".rbenvs-cache")
)

from dataclasses import dataclass

import gymnasium as gym
import numpy as np
import pytest

import rbenvs
from rbenvs import vector
from rbenvs.dynamics.contact import FrictionLaw

ENV_IDS = sorted(rbenvs.ENVIRONMENTS)


def env_class(env_id):
    spec = gym.spec(env_id)
    ep = spec.entry_point
    if isinstance(ep, str):
        mod, name = ep.split(":")
        ep = getattr(__import__(mod, fromlist=[name]), name)
    return ep


def unchecked(integrator) -> dict:
    """``tolerance=None`` for euler, which the default accuracy refuses (its error is in the
    amplitude); nothing for the other schemes (their default)."""
    return {"tolerance": None} if integrator == "euler" else {}


def all_variants():
    """(env_id, task, integrator) for every registered id, task and integrator."""
    out = []
    for env_id in ENV_IDS:
        cls = env_class(env_id)
        for task in cls.tasks:
            for integ in cls.integrators:
                out.append(pytest.param(env_id, task, integ, id=f"{env_id}-{task}-{integ}"))
    return out


# ---------------------------------------------------------------- vector env = single envs
# Shared by tests/test_vector.py and tests/test_compiled.py.
FREE, LAGRANGE, TIPPE = "rbenvs/FreeRigidBody-v0", "rbenvs/LagrangeTop-v0", "rbenvs/TippeTop-v0"
VECTOR_CLASS = {
    FREE: vector.FreeRigidBodyVectorEnv,
    LAGRANGE: vector.LagrangeTopVectorEnv,
    TIPPE: vector.TippeTopVectorEnv,
}
# the tippe top's read-outs that depend on the last control period, not on the state alone
TIPPE_CONTROL_READOUTS = {"normal_force", "internal_step"}


def make_vec(env_id, n, **kwargs):
    return gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)


def make_singles(env_id, n, **kwargs):
    return [gym.make(env_id, **kwargs) for _ in range(n)]


def same(a, b):
    """Bit-for-bit equality of two numbers or arrays (NaN equal to NaN), and of info values:
    dicts, ``None`` and object arrays (final observations and infos) element by element."""
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if a is None or b is None:
        return a is b
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype == object or b.dtype == object:
        return a.shape == b.shape and all(same(x, y) for x, y in zip(a.ravel(), b.ravel()))
    return np.array_equal(a, b, equal_nan=a.dtype.kind in "fc" and b.dtype.kind in "fc")


def same_state(a, b):
    return set(a) == set(b) and all(np.array_equal(a[k], b[k]) for k in a)


def random_actions(rng, space, scale=2.0):
    """Actions in [-scale, scale]: many outside the action space (clipped by the envs)."""
    return rng.uniform(-scale, scale, space.shape).astype(np.float32)


def check_info_row(vinfo, i, single_info, skip=()):
    """Every key of the single env's info equals row ``i`` of the vector info, bit for bit."""
    for key, value in single_info.items():
        if key in skip:
            continue
        if key == "terminal_reason":
            assert vinfo["_terminal_reason"][i] and vinfo["terminal_reason"][i] == value, (key, i)
            continue
        if (
            key == "error_estimate" and value is None
        ):  # (not estimated: the vector env's NaN, its mask false)
            assert np.isnan(vinfo[key][i]) and not vinfo["_" + key][i], (key, i, vinfo[key][i])
            continue
        if isinstance(value, dict):  # a nested dict (the drawn "params"): gymnasium's nested masks
            assert key in vinfo and vinfo["_" + key][i], (key, i)
            check_info_row(vinfo[key], i, value)
            continue
        assert key in vinfo and vinfo["_" + key][i], (key, i)
        assert same(vinfo[key][i], value), (key, i, vinfo[key][i], value)
    if "terminal_reason" not in single_info and "terminal_reason" in vinfo:
        assert vinfo["terminal_reason"][i] == "", i


def lockstep(env_id, n, seed, steps, mode, max_steps, kwargs, action_scale=2.0, vector_kwargs=None):
    """Run a vector env and ``n`` single envs on the float path side by side; assert sub-env ``i``
    equals single env ``i`` (seeded ``seed + i``) bit for bit. Returns (#terminations, #truncations,
    infos).
    ``vector_kwargs``: arguments of the vector env alone (``compiled``)."""
    venv = make_vec(
        env_id,
        n,
        max_episode_steps=max_steps,
        autoreset_mode=mode,
        **kwargs,
        **(vector_kwargs or {}),
    )
    # the reference is the float path (a compiled single env would share a kernel bug)
    singles = make_singles(env_id, n, max_episode_steps=max_steps, compiled=False, **kwargs)
    reset_skip = ()  # every info key, the tippe top's control-dependent read-outs included
    rng = np.random.default_rng(seed)
    obs, info = venv.reset(seed=seed)
    assert obs.dtype == np.float32 and obs.shape == venv.observation_space.shape
    for i, env in enumerate(singles):
        o, inf = env.reset(seed=seed + i)
        assert same(obs[i], o)
        check_info_row(info, i, inf)
    prev_done = np.zeros(n, dtype=bool)
    n_term = n_trunc = 0
    infos = [info]
    for t in range(steps):
        a = random_actions(rng, venv.action_space, action_scale)
        obs, reward, terminated, truncated, info = venv.step(a)
        infos.append(info)
        assert (
            obs.dtype == np.float32
            and reward.dtype == np.float64
            and terminated.dtype == bool
            and truncated.dtype == bool
        )
        assert (
            obs.shape == venv.observation_space.shape
            and reward.shape == terminated.shape == truncated.shape == (n,)
        )
        for i, env in enumerate(singles):
            if mode == "NextStep" and prev_done[i]:
                # the step after a done resets the sub-env: first obs, reward 0, no flags
                o, inf = env.reset()
                assert (
                    same(obs[i], o) and reward[i] == 0.0 and not terminated[i] and not truncated[i]
                ), (t, i)
                check_info_row(info, i, inf, skip=reset_skip)
                continue
            o, r, te, tr, inf = env.step(a[i])
            assert reward[i] == r and terminated[i] == te and truncated[i] == tr, (
                t,
                i,
                reward[i],
                r,
            )
            n_term += te
            n_trunc += tr
            if mode == "SameStep" and (te or tr):
                assert info["_final_obs"][i] and info["_final_info"][i]
                assert same(np.asarray(info["final_obs"][i], dtype=np.float32), o), (t, i)
                check_info_row(info["final_info"], i, inf)
                o, inf = env.reset()
                skip = reset_skip
            else:
                if mode == "SameStep" and "_final_obs" in info:
                    assert not info["_final_obs"][i] and info["final_obs"][i] is None
                skip = ()
            assert same(obs[i], o), (t, i, obs[i], o)
            check_info_row(info, i, inf, skip=skip)
        prev_done = terminated | truncated
    venv.close()
    return n_term, n_trunc, infos


# ---------------------------------------------------------------- the tests' own formulas
def rotation(q):
    """Body-to-space rotation matrix of the quaternion ``q = (w, x, y, z)`` (the tests' own
    formula, independent of rbenvs.rotations)."""
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


@dataclass(frozen=True)
class HalfViscous(FrictionLaw):
    """A friction law defined outside the package, by its methods alone (no pure functions):
    viscous at half the coefficient (tests/test_contact.py, tests/test_tippe_top_pure.py)."""

    name = "half_viscous"

    def coefficient(self, mu, s1, s2, s3, eps):
        return -0.5 * mu

    def stiffness(self, mu, normal, mobility, eps):
        return 0.5 * mu * normal * mobility

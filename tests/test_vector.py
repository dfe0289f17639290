"""Native batched vector envs (rbenvs.vector), the SB3 adapter over them and the throughput bench.

The module docstring of :mod:`rbenvs.vector` is the spec: sub-env ``i`` of a vector env follows
bit for bit the trajectory of a single env seeded ``seed + i`` and stepped with the same actions
(``dop853`` to its tolerance only), in both autoreset modes, with gymnasium's vector conventions
for seeding, info and state access.
"""

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from conftest import (
    ENV_IDS,
    FREE,
    LAGRANGE,
    TIPPE,
    TIPPE_CONTROL_READOUTS,
    VECTOR_CLASS,
    check_info_row,
    lockstep,
    make_singles,
    make_vec,
    random_actions,
    same,
    same_state,
)
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

import rbenvs
from rbenvs.envs import NumericalFailureWarning
from rbenvs.jit import available as compiled_available


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_make_vec_returns_the_native_vector_env(env_id):
    n = 3
    venv = make_vec(env_id, n)
    single = gym.make(env_id)
    assert gym.spec(env_id).vector_entry_point == rbenvs.ENVIRONMENTS[env_id]["vector_entry_point"]
    assert type(venv) is VECTOR_CLASS[env_id] and venv.unwrapped is venv
    assert isinstance(venv, gym.vector.VectorEnv) and venv.num_envs == n
    assert venv.single_observation_space == single.observation_space
    assert venv.single_action_space == single.action_space
    assert venv.observation_space == batch_space(single.observation_space, n)
    assert venv.action_space == batch_space(single.action_space, n)
    assert venv.observation_space.shape == (n,) + single.observation_space.shape
    # truncation from the registration, done by the vector env itself (no TimeLimit wrapper)
    assert venv.max_episode_steps == gym.spec(env_id).max_episode_steps
    assert venv.dt == single.unwrapped.dt
    assert venv.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
    for mode in ("SameStep", AutoresetMode.SAME_STEP):
        assert (
            make_vec(env_id, 2, autoreset_mode=mode).metadata["autoreset_mode"]
            is AutoresetMode.SAME_STEP
        )
    assert (
        make_vec(env_id, 2, autoreset_mode="NextStep").metadata["autoreset_mode"]
        is AutoresetMode.NEXT_STEP
    )
    for bad in ("Disabled", AutoresetMode.DISABLED, "junk", 3):
        with pytest.raises(ValueError, match="autoreset_mode"):
            make_vec(env_id, 2, autoreset_mode=bad)
    # the single env's keyword arguments pass through (and are validated by it)
    assert make_vec(env_id, 2, max_episode_steps=7).max_episode_steps == 7
    with pytest.raises(ValueError):
        make_vec(env_id, 2, task="no-such-task")
    for bad_n in (0, -1):
        with pytest.raises(ValueError, match="num_envs"):
            make_vec(env_id, bad_n)


def test_step_and_get_state_before_reset_raise():
    venv = make_vec(FREE, 2)
    with pytest.raises(RuntimeError, match="reset"):
        venv.step(np.zeros((2, 3), dtype=np.float32))
    with pytest.raises(RuntimeError, match="reset"):
        venv.get_state()


# ----------------------------------------------------------------------------------- 2. equivalence

# (id, kwargs, max_episode_steps, steps): small max_episode_steps so that every run passes
# several episode ends; some settings also terminate (tilt_limit, observation bounds).
EQUIVALENCE = [
    (FREE, dict(integrator="rk4"), 5, 17),
    (FREE, dict(integrator="euler", tolerance=None, task="detumble", spin_rate=0.3), 6, 17),
    (FREE, dict(integrator="splitting", task="reorient"), 5, 17),
    (FREE, dict(integrator="exact", task="reorient", max_torque=0.5), 5, 17),
    (FREE, dict(integrator="exact", actuated=(True, False, True), axis="major"), 5, 17),
    (
        FREE,
        dict(integrator="rk4", max_angular_velocity=1.6, max_torque=5.0),
        40,
        40,
    ),  # observation_limit
    (LAGRANGE, dict(), 5, 17),  # splitting, upright
    (
        LAGRANGE,
        dict(integrator="rk4", tilt_limit=0.06, max_torque=0.05, spin=0.0),
        25,
        45,
    ),  # task terminations
    (LAGRANGE, dict(integrator="rk4", task="precess", attitude=True), 5, 17),
    (
        LAGRANGE,
        dict(
            integrator="euler", tolerance=None, axial_torque=True, spin=(5.0, 15.0), attitude=True
        ),
        5,
        17,
    ),
    (
        LAGRANGE,
        dict(integrator="splitting", task="precess", spin=(20.0, 30.0), spin_friction=0.01),
        5,
        17,
    ),
    (
        LAGRANGE,
        dict(
            integrator="rk4",
            inertia=(0.5, 0.45, 0.3),
            com_direction=(0.1, 0.0, 1.0),
            spin=(0.0, 3.0),
        ),
        5,
        17,
    ),
    (TIPPE, dict(fidelity="frictionless", spin=(100.0, 200.0)), 4, 10),
    (TIPPE, dict(fidelity="rolling", task="hold", torque_action=True), 4, 10),
    (TIPPE, dict(friction_law="viscous", integrator="euler", tolerance=None), 4, 10),
    # default gliding (regularised Coulomb, rk4); the spin range makes the internal step counts
    # differ
    (TIPPE, dict(spin=(100.0, 200.0)), 3, 7),
    (TIPPE, dict(spin=(120.0, 160.0), friction_action=True, torque_action=True), 3, 5),
]


def _variant_id(v):
    env_id, kwargs, m, steps = v
    return env_id.split("/")[1] + "-" + ",".join(f"{k}={val}" for k, val in kwargs.items())


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
@pytest.mark.parametrize("variant", EQUIVALENCE, ids=[_variant_id(v) for v in EQUIVALENCE])
def test_sub_envs_equal_single_envs_bit_for_bit(variant, mode):
    env_id, kwargs, max_steps, steps = variant
    n_term, n_trunc, infos = lockstep(env_id, 3, 11, steps, mode, max_steps, kwargs)
    assert n_term + n_trunc >= 3  # several episode ends were crossed
    if env_id == TIPPE and kwargs.get("spin") == (100.0, 200.0) and "fidelity" not in kwargs:
        # the automatic internal step differed between the sub-envs in the same batched call
        assert any(len(set(info["internal_step"].tolist())) > 1 for info in infos[1:])


def test_equivalence_covers_terminations_and_observation_limits():
    """The equivalence runs above do cross terminations of both kinds, not only truncations."""
    n_term, _, infos = lockstep(
        LAGRANGE,
        3,
        12,
        45,
        "SameStep",
        25,
        dict(integrator="rk4", tilt_limit=0.06, max_torque=0.05, spin=0.0),
    )
    reasons = {
        r for info in infos if "final_info" in info for r in info["final_info"]["terminal_reason"]
    }
    assert n_term >= 3 and "task" in reasons
    n_term, _, infos = lockstep(
        FREE,
        3,
        11,
        40,
        "NextStep",
        40,
        dict(integrator="rk4", max_angular_velocity=1.6, max_torque=5.0),
    )
    reasons = {r for info in infos if "terminal_reason" in info for r in info["terminal_reason"]}
    assert n_term >= 1 and "observation_limit" in reasons


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
def test_tippe_top_autoreset_info_equals_reset_info(mode):
    n, seed, m = 2, 4, 2
    venv = make_vec(TIPPE, n, max_episode_steps=m, autoreset_mode=mode, fidelity="rolling")
    singles = make_singles(TIPPE, n, max_episode_steps=m, fidelity="rolling")
    venv.reset(seed=seed)
    for i, env in enumerate(singles):
        env.reset(seed=seed + i)
    a = np.full(venv.action_space.shape, 0.7, dtype=np.float32)
    steps = m + (1 if mode == "NextStep" else 0)
    for _ in range(steps):
        obs, *_, info = venv.step(a)
    for i, env in enumerate(singles):
        o, inf = env.reset()
        assert same(obs[i], o)
        for key in sorted(TIPPE_CONTROL_READOUTS):
            assert same(info[key][i], inf[key]), (key, info[key][i], inf[key])


@pytest.mark.parametrize("n_ending", [1, 2])
def test_same_step_final_obs_is_a_1d_array_of_float32_observations(n_ending):
    """Both sub-envs truncate at step 2 (``n_ending == 2``), or only sub-env 0 (sub-env 1 was
    reset one step later, ``n_ending == 1``): final_obs holds one float32 observation per ended
    sub-env."""
    venv = make_vec(FREE, 2, autoreset_mode="SameStep", max_episode_steps=2)
    venv.reset(seed=0)
    zero = np.zeros((2, 3), dtype=np.float32)
    if n_ending == 1:
        venv.step(zero)
        venv.reset(options={"reset_mask": np.array([False, True])})
    for _ in range(2 if n_ending == 2 else 1):
        _, _, _, tr, info = venv.step(zero)
    assert tr.sum() == n_ending
    final = info["final_obs"]
    assert final.shape == (2,) and final.dtype == object
    for i in np.flatnonzero(tr):
        assert (
            isinstance(final[i], np.ndarray)
            and final[i].dtype == np.float32
            and final[i].shape == (3,)
        )


def test_sb3_ppo_across_simultaneous_time_limits():
    from stable_baselines3 import PPO

    from rbenvs.vector.sb3 import make_sb3_vec_env

    venv = make_sb3_vec_env(FREE, 2, seed=0, max_episode_steps=8)
    PPO("MlpPolicy", venv, n_steps=32, batch_size=64, n_epochs=1, device="cpu", seed=0).learn(64)


DOP853 = [
    (FREE, dict(integrator="dop853", task="reorient")),
    (LAGRANGE, dict(integrator="dop853")),
    (TIPPE, dict(integrator="dop853", fidelity="frictionless", spin=(100.0, 200.0))),
]


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
@pytest.mark.parametrize("env_id,kwargs", DOP853, ids=[e.split("/")[1] for e, _ in DOP853])
def test_dop853_sub_envs_agree_within_tolerance(env_id, kwargs, mode):
    n, seed, m, steps = 3, 5, 3, 7
    venv = make_vec(env_id, n, max_episode_steps=m, autoreset_mode=mode, **kwargs)
    singles = make_singles(env_id, n, max_episode_steps=m, **kwargs)
    rng = np.random.default_rng(seed)
    obs, _ = venv.reset(seed=seed)
    for i, env in enumerate(singles):
        assert same(obs[i], env.reset(seed=seed + i)[0])  # the draws are exact
    prev_done = np.zeros(n, dtype=bool)
    for _ in range(steps):
        a = random_actions(rng, venv.action_space)
        obs, reward, terminated, truncated, info = venv.step(a)
        for i, env in enumerate(singles):
            if mode == "NextStep" and prev_done[i]:
                assert same(obs[i], env.reset()[0]) and reward[i] == 0.0
                continue
            o, r, te, tr, inf = env.step(a[i])
            assert terminated[i] == te and truncated[i] == tr
            assert reward[i] == pytest.approx(r, rel=1e-9, abs=1e-12)
            if te or tr:
                if mode == "SameStep":
                    np.testing.assert_allclose(
                        np.asarray(info["final_obs"][i], dtype=np.float32), o, rtol=1e-6, atol=1e-7
                    )
                    o = env.reset()[0]
                    assert same(obs[i], o)
                    continue
            np.testing.assert_allclose(obs[i], o, rtol=1e-6, atol=1e-7)
            assert info["energy"][i] == pytest.approx(inf["energy"], rel=1e-9, abs=1e-15)
        prev_done = terminated | truncated


# ----------------------------------------------------------------------------------- 3. seeding


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_seeding(env_id):
    kwargs = dict(fidelity="frictionless") if env_id == TIPPE else {}
    n, s = 4, 123
    a = make_vec(env_id, n, **kwargs)
    b = make_vec(env_id, n, **kwargs)
    obs_a, info_a = a.reset(seed=s)
    obs_b, info_b = b.reset(seed=[s + i for i in range(n)])
    assert same(obs_a, obs_b) and same_state(a.get_state(), b.get_state())
    assert all(same(info_a[k], info_b[k]) for k in info_a)
    # numpy integer seeds too
    assert same(b.reset(seed=np.int64(s))[0], obs_a)
    # different seeds give different starts (sub-env to sub-env, and run to run)
    assert not any(np.array_equal(obs_a[i], obs_a[j]) for i in range(n) for j in range(i))
    obs_c, _ = b.reset(seed=s + 100)
    assert not any(np.array_equal(obs_a[i], obs_c[i]) for i in range(n))
    with pytest.raises(ValueError, match="seed"):
        a.reset(seed=[1, 2])
    # reset() without a seed continues each sub-env's generator, as a single env's reset()
    singles = make_singles(env_id, n, **kwargs)
    a.reset(seed=s)
    for i, env in enumerate(singles):
        env.reset(seed=s + i)
    for _ in range(2):
        obs, _ = a.reset()
        for i, env in enumerate(singles):
            assert same(obs[i], env.reset()[0])
    # an unseeded first reset draws from fresh entropy: two vector envs differ
    assert not np.array_equal(
        make_vec(env_id, n, **kwargs).reset()[0], make_vec(env_id, n, **kwargs).reset()[0]
    )


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_reset_mask_resets_only_the_masked_sub_envs(env_id):
    kwargs = dict(fidelity="frictionless") if env_id == TIPPE else {}
    n, s, m = 4, 9, 6
    venv = make_vec(env_id, n, max_episode_steps=m, **kwargs)
    singles = make_singles(env_id, n, max_episode_steps=m, **kwargs)
    venv.reset(seed=s)
    for i, env in enumerate(singles):
        env.reset(seed=s + i)
    rng = np.random.default_rng(0)
    for _ in range(3):
        a = random_actions(rng, venv.action_space)
        venv.step(a)
        for i, env in enumerate(singles):
            env.step(a[i])
    before = venv.get_state()
    mask = np.array([True, False, True, False])
    obs, info = venv.reset(options={"reset_mask": mask})
    after = venv.get_state()
    for i, env in enumerate(singles):
        if mask[i]:
            o = env.reset()[0]  # continues the sub-env's generator
            assert same(obs[i], o)
            assert not all(np.array_equal(before[k][i], after[k][i]) for k in before)
        else:
            assert all(np.array_equal(before[k][i], after[k][i]) for k in before)
    # the kept sub-envs keep their episode (and its step count): they truncate at step m of it,
    # 3 steps earlier than the reset ones; all still equal their single envs (NextStep autoreset)
    prev_done = np.zeros(n, dtype=bool)
    for t in range(m):
        a = random_actions(rng, venv.action_space)
        obs, r, te, tr, _ = venv.step(a)
        for i, env in enumerate(singles):
            if prev_done[i]:
                assert same(obs[i], env.reset()[0]) and r[i] == 0.0
                continue
            o, sr, ste, stru, _ = env.step(a[i])
            assert same(obs[i], o) and r[i] == sr and te[i] == ste and tr[i] == stru
        assert not te.any()
        expected = ~mask if t == m - 4 else (mask if t == m - 1 else np.zeros(n, dtype=bool))
        assert np.array_equal(tr, expected), t
        prev_done = te | tr
    # a masked reset with a seed reseeds the masked sub-envs only, with seed + i
    before = venv.get_state()
    obs, _ = venv.reset(seed=50, options={"reset_mask": mask})
    for i in range(n):
        if mask[i]:
            assert same(obs[i], gym.make(env_id, **kwargs).reset(seed=50 + i)[0])
        else:
            assert all(np.array_equal(before[k][i], venv.get_state()[k][i]) for k in before)
    for bad in (np.ones(n - 1, dtype=bool), np.ones(n, dtype=int), np.ones((n, 1), dtype=bool)):
        with pytest.raises(ValueError, match="reset_mask"):
            venv.reset(options={"reset_mask": bad})
    with pytest.raises(ValueError, match="unknown"):
        venv.reset(options={"no_such_option": 1})


# ----------------------------------------------------------------------------------- 4. state
# access

STATE_CASES = [
    (FREE, dict(task="spin")),
    (FREE, dict(task="reorient")),
    (LAGRANGE, dict()),
    (LAGRANGE, dict(attitude=True, integrator="rk4")),
    (TIPPE, dict(fidelity="frictionless")),
    (TIPPE, dict(fidelity="rolling")),
    (TIPPE, dict(spin=(100.0, 200.0))),  # gliding
]


@pytest.mark.parametrize(
    "env_id,kwargs", STATE_CASES, ids=[f"{e.split('/')[1]}-{k}" for e, k in STATE_CASES]
)
def test_get_state_shapes_and_round_trip(env_id, kwargs):
    n, steps = 3, 3
    venv = make_vec(env_id, n, **kwargs)
    venv.reset(seed=21)
    rng = np.random.default_rng(1)
    venv.step(random_actions(rng, venv.action_space))
    state = venv.get_state()
    single = gym.make(env_id, **kwargs).unwrapped
    single.reset(seed=0)
    single_state = single.get_state()
    assert set(state) == set(single_state)
    for k, v in state.items():
        assert v.dtype == np.float64 and v.shape == (n,) + single_state[k].shape, k
    # copies: editing them does not touch the env
    state_copy = {k: v.copy() for k, v in state.items()}
    next(iter(state.values()))[:] = 123.0
    assert same_state(venv.get_state(), state_copy)
    state = state_copy
    actions = [random_actions(rng, venv.action_space) for _ in range(steps)]
    run1 = [venv.step(a)[:4] for a in actions]
    obs0, _ = venv.reset(options={"state": state})
    assert same_state(venv.get_state(), state)
    run2 = [venv.step(a)[:4] for a in actions]
    for x, y in zip(run1, run2):
        assert all(same(p, q) for p, q in zip(x, y))
    # each row is the single env started there
    for i in range(n):
        o, _ = single.reset(options={"state": {k: v[i] for k, v in state.items()}})
        assert same(o, obs0[i])
        for a, (obs, r, te, _tr) in zip(actions, run2):
            so, sr, ste, _, _ = single.step(a[i])
            assert same(so, obs[i]) and sr == r[i] and ste == te[i]


def _bad_rows(env_id, state):
    """(bad state, message pattern): one bad row each (row 1), plus wrong leading lengths."""
    out = []
    short = {k: v[:-1] for k, v in state.items()}
    out.append((short, "leading axis of length num_envs"))
    out.append(({k: v[0] for k, v in state.items()}, "leading axis"))  # unbatched
    missing = dict(state)
    missing.pop(sorted(state)[0])
    out.append((missing, "missing"))
    nan = {k: v.copy() for k, v in state.items()}
    first = sorted(state)[0]
    nan[first][1, 0] = np.nan
    out.append((nan, "must be finite"))
    if env_id == TIPPE:
        bad = {k: v.copy() for k, v in state.items()}
        bad["position"][1, 2] += 1e-3
        out.append((bad, "contact height"))
        bad = {k: v.copy() for k, v in state.items()}
        bad["velocity"][1, 2] += 1e-3
        out.append((bad, "vertical velocity the contact constraint gives"))
        bad = {k: v.copy() for k, v in state.items()}
        bad["attitude"][1] *= 1.01
        out.append((bad, "unit quaternion"))
    if env_id == LAGRANGE:
        bad = {k: v.copy() for k, v in state.items()}
        bad["vertical"][1] *= 1.01
        out.append((bad, "unit vector"))
    if env_id == FREE:
        bad = {k: v.copy() for k, v in state.items()}
        bad["attitude"][1] *= 1.01
        out.append((bad, "unit quaternion"))
    return out


@pytest.mark.parametrize(
    "env_id,kwargs",
    [(FREE, dict(task="reorient")), (LAGRANGE, dict()), (TIPPE, dict(fidelity="frictionless"))],
)
def test_bad_state_rows_are_refused_and_change_nothing(env_id, kwargs):
    venv = make_vec(env_id, 4, **kwargs)
    venv.reset(seed=2)
    venv.step(np.zeros(venv.action_space.shape, dtype=np.float32))
    state = venv.get_state()
    for bad, pattern in _bad_rows(env_id, state):
        with pytest.raises(ValueError, match=pattern):
            venv.reset(options={"state": bad})
        assert same_state(venv.get_state(), state)
    with pytest.raises(ValueError, match="dict"):
        venv.reset(options={"state": [1.0, 2.0]})
    # a bad row outside the reset mask is not looked at
    bad = {k: v.copy() for k, v in state.items()}
    name = {FREE: "attitude", LAGRANGE: "vertical", TIPPE: "attitude"}[env_id]
    bad[name][1] *= 1.5
    venv.reset(options={"state": bad, "reset_mask": np.array([True, False, True, True])})
    assert same_state(venv.get_state(), state)


# ----------------------------------------------------------------------------------- 5. info


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_info_arrays_and_masks(env_id):
    kwargs = dict(fidelity="frictionless") if env_id == TIPPE else {}
    n = 3
    venv = make_vec(env_id, n, **kwargs)
    single = gym.make(env_id, **kwargs)
    _, sinfo = single.reset(seed=0)
    _, info = venv.reset(seed=0)
    infos = [info, venv.step(np.zeros(venv.action_space.shape, dtype=np.float32))[4]]
    for info in infos:
        keys = {k for k in info if not k.startswith("_")}
        assert keys == set(sinfo)  # nothing ended: no terminal_reason
        for key in keys:
            assert isinstance(info[key], np.ndarray) and info[key].shape == (n,), key
            mask = info["_" + key]
            # (error_estimate where not estimated, the single env's None: NaN, its mask false)
            assert (
                mask.dtype == bool
                and mask.shape == (n,)
                and mask.all() == (key != "error_estimate" or sinfo[key] is not None)
            ), key
        assert info["numerical_failure"].dtype == bool and not info["numerical_failure"].any()
        assert info["is_success"].dtype == bool
    # the info arrays are not views of the state: editing them changes nothing
    state = venv.get_state()
    for key in infos[1]:
        if not key.startswith("_") and infos[1][key].flags.writeable:
            infos[1][key][...] = 0
    assert same_state(venv.get_state(), state)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_info_readouts_false_keeps_the_task_metrics_and_the_trajectory(env_id):
    kwargs = dict(fidelity="frictionless") if env_id == TIPPE else {}
    n = 3
    full = make_vec(env_id, n, max_episode_steps=3, **kwargs)
    lean = make_vec(env_id, n, max_episode_steps=3, info_readouts=False, **kwargs)
    single = gym.make(env_id, **kwargs).unwrapped
    _, info_full = full.reset(seed=4)
    _, info_lean = lean.reset(seed=4)
    single.reset(seed=4)
    metrics = set(single.task.metric_names)
    readouts = set(info_full) - set(info_lean)
    assert {k for k in info_lean if not k.startswith("_")} == metrics | {
        "numerical_failure",
        "error_estimate",
    }
    assert readouts and "energy" in readouts and not readouts & metrics
    rng = np.random.default_rng(0)
    for _ in range(5):
        a = random_actions(rng, full.action_space)
        x, y = full.step(a), lean.step(a)
        assert all(same(p, q) for p, q in zip(x[:4], y[:4]))
        assert all(same(y[4][k], x[4][k]) for k in y[4] if not k.startswith("_") and k in metrics)


@pytest.mark.parametrize("compiled", [False, "auto"])
def test_terminal_reason_task_and_truncation(compiled):
    n = 6
    venv = make_vec(LAGRANGE, n, tilt_limit=0.06, max_episode_steps=22, compiled=compiled)
    venv.reset(seed=3)
    seen_task = seen_trunc = False
    for _ in range(25):
        _, _, te, tr, info = venv.step(np.zeros((n, 2), dtype=np.float32))
        if te.any() or tr.any():
            reason, mask = info["terminal_reason"], info["_terminal_reason"]
            assert reason.shape == mask.shape == (n,) and mask.dtype == bool
            assert np.all(mask[te]) and not np.any(mask & ~(te | tr))
            assert all(reason[i] == "task" for i in np.flatnonzero(te))
            assert all(reason[i] == "" for i in np.flatnonzero(~te))  # truncation, or going on
            assert all(info["is_success"][i] == False for i in np.flatnonzero(te))  # noqa: E712 (fell over)
            seen_task |= te.any()
            seen_trunc |= (tr & ~te).any()
        else:  # (a restarting sub-env's discarded period ends nothing: no key)
            assert "terminal_reason" not in info
    assert seen_task and seen_trunc


def test_terminal_reason_observation_limit_clips_the_observation():
    n = 3
    venv = make_vec(
        TIPPE, n, fidelity="frictionless", torque_action=True, max_angular_velocity=160.0
    )
    venv.reset(seed=0)
    a = np.zeros((n, 5), dtype=np.float32)
    a[1, 4] = 1.0  # spin up sub-env 1 only (143 rad/s^2): past 160 rad/s within ~0.1 s
    for _ in range(30):
        obs, r, te, tr, info = venv.step(a)
        if te.any():
            break
    assert np.array_equal(te, [False, True, False]) and not tr.any()
    assert list(info["terminal_reason"]) == ["", "observation_limit", ""] and np.array_equal(
        info["_terminal_reason"], te
    )
    assert venv.observation_space.contains(obs) and np.max(np.abs(obs[1, 3:6])) == pytest.approx(
        160.0
    )
    assert info["spin"][1] > 160.0 and np.all(np.abs(info["spin"][[0, 2]]) < 160.0)


def test_terminal_reason_lift_off():
    """At 300 rad/s the default top from the rolling start lifts off around 1.95 s (step ~195):
    started a few steps before (from a single env's run), sub-env 0 lifts off exactly when the
    single env does; sub-env 1 (an ordinary start) goes on."""
    single = gym.make(TIPPE, spin=300.0, start="rolling").unwrapped
    single.reset(seed=0)
    zero = np.zeros(2, dtype=np.float32)
    states, outs = [], []
    while True:
        states.append(single.get_state())
        outs.append(single.step(zero))
        if outs[-1][2]:
            break
    k = len(outs)
    assert 150 < k < 250 and outs[-1][4]["terminal_reason"] == "lift_off"
    back = 3
    venv = make_vec(TIPPE, 2, spin=300.0, autoreset_mode="SameStep", start="rolling")
    venv.reset(seed=5)
    start = {key: np.stack([states[k - back][key], venv.get_state()[key][1]]) for key in states[0]}
    venv.reset(options={"state": start})
    for j in range(back):
        obs, r, te, tr, info = venv.step(np.zeros((2, 2), dtype=np.float32))
        o, sr, ste, _, sinfo = outs[k - back + j]
        assert r[0] == sr and te[0] == ste and not te[1] and not tr.any()
        if j < back - 1:
            assert (
                same(obs[0], o) and "terminal_reason" not in info and not info["lifted_off"].any()
            )
    assert np.array_equal(te, [True, False])
    assert same(np.asarray(info["final_obs"][0], dtype=np.float32), o)
    final = info["final_info"]
    assert (
        final["terminal_reason"][0] == "lift_off"
        and final["_terminal_reason"][0]
        and final["terminal_reason"][1] == ""
    )
    assert final["lifted_off"][0] and not final["lifted_off"][1]
    assert final["normal_force"][0] < 0.0 < final["normal_force"][1]
    assert same(final["tilt"][0], sinfo["tilt"]) and same(
        final["normal_force"][0], sinfo["normal_force"]
    )
    # reset in the same step: the new episode's flag is clear
    assert not info["lifted_off"].any() and info["terminal_reason"][0] == ""


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(fidelity="frictionless"),
        dict(),
        dict(integrator="euler", tolerance=None, fidelity="rolling"),
    ],
    ids=["frictionless", "gliding", "euler-rolling"],
)
def test_numerical_failure_ends_only_the_failing_sub_env(kwargs):
    """Sub-env 1 reset to a spin of 1e37 rad/s (inside bounds raised to float32's; a torque that
    could get there in a step is refused at construction): its guard asks for 1e36 internal
    steps, more than MAX_INTERNAL_STEPS, so its period is refused and its state goes
    non-finite: its episode ends with reward 0, the last finite state and observation kept, one
    NumericalFailureWarning; sub-envs 0 and 2 go on exactly as single envs."""
    n, seed = 3, 0
    kwargs = dict(kwargs, torque_action=True, max_angular_velocity=3e38, max_speed=3e38)
    venv = make_vec(TIPPE, n, **kwargs)
    singles = make_singles(TIPPE, n, **kwargs)
    venv.reset(seed=seed)
    for i, env in enumerate(singles):
        env.reset(seed=seed + i)
    zero = np.zeros((n, 5), dtype=np.float32)
    venv.step(zero)
    for env in singles:
        env.step(zero[0])
    system = singles[1].unwrapped.system
    fast = system.export_state(
        system.state((0.0, 0.0), (math.cos(0.05), math.sin(0.05), 0.0, 0.0), (0.0, 0.0, 1e37))
    )
    state = venv.get_state()
    for key, value in fast.items():
        state[key][1] = value
    last_obs, _ = venv.reset(options={"state": state, "reset_mask": np.array([False, True, False])})
    singles[1].reset(options={"state": fast})
    last = venv.get_state()
    a = zero.copy()
    a[1, 4] = 1.0
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        obs, r, te, tr, info = venv.step(a)
    failures = [w for w in caught if issubclass(w.category, NumericalFailureWarning)]
    assert (
        len(failures) == 1
        and "[1]" in str(failures[0].message)
        and "non-finite" in str(failures[0].message)
    )
    # reward 0 and the failure charge (rbenvs.core.model.Model)
    assert (
        np.array_equal(te, [False, True, False])
        and not tr.any()
        and r[1] == singles[1].unwrapped.model.failure_charge < 0.0
    )
    assert (
        np.array_equal(info["numerical_failure"], [False, True, False])
        and info["_numerical_failure"].all()
    )
    assert list(info["terminal_reason"]) == ["", "numerical_failure", ""]
    assert same(obs[1], last_obs[1])
    now = venv.get_state()
    assert all(np.array_equal(now[k][1], last[k][1]) and np.all(np.isfinite(now[k])) for k in now)
    assert all(
        np.all(np.isfinite(info[k])) for k in ("energy", "jellett", "tilt", "slip_speed", "spin")
    )
    # the single env fails alike; the others are unaffected
    for i, env in enumerate(singles):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NumericalFailureWarning)
            o, sr, ste, _, sinfo = env.step(a[i])
        assert same(obs[i], o) and r[i] == sr and te[i] == ste
        check_info_row(info, i, sinfo)
    # NextStep: the failed sub-env starts over, the others continue
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        obs, r, te, tr, info = venv.step(a)
    assert not [w for w in caught if issubclass(w.category, NumericalFailureWarning)]
    assert (
        same(obs[1], singles[1].reset()[0])
        and r[1] == 0.0
        and not te.any()
        and not info["numerical_failure"].any()
    )
    for i in (0, 2):
        o, sr, *_ = singles[i].step(a[i])
        assert same(obs[i], o) and r[i] == sr


def test_numerical_failure_of_euler_with_a_huge_dt():
    """Explicit Euler on the heavy top with a control period of 5 s (and observation bounds near
    float32's limit) overflows after a few steps (guard="off": unguarded); whichever sub-env
    fails keeps its last state."""
    n = 3
    kwargs = dict(
        inertia=(0.5, 0.45, 0.3),
        spin=(40.0, 60.0),
        integrator="euler",
        tolerance=None,
        dt=5.0,
        substeps=7,
        tilt_limit=math.pi,
        max_angular_velocity=3e38,
        guard="off",
    )
    venv = make_vec(LAGRANGE, n, **kwargs)
    singles = make_singles(LAGRANGE, n, **kwargs)
    venv.reset(seed=1)
    for i, env in enumerate(singles):
        env.reset(seed=1 + i)
    failed_seen = False
    zero = np.zeros((n, 2), dtype=np.float32)
    for _ in range(20):
        last = venv.get_state()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            obs, r, te, tr, info = venv.step(zero)
        fails = [w for w in caught if issubclass(w.category, NumericalFailureWarning)]
        for i, env in enumerate(singles):  # every sub-env, failing or not, as its single env
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", NumericalFailureWarning)
                o, sr, ste, _, sinfo = env.step(zero[i])
            assert same(obs[i], o) and r[i] == sr and te[i] == ste
            check_info_row(info, i, sinfo)
        failed = info["numerical_failure"]
        if failed.any():
            assert len(fails) == 1
            assert (
                np.all(te[failed])
                and np.all(r[failed] == venv.unwrapped.engine.failure_charge)
                and not tr.any()
            )  # 0 + the charge
            assert all(
                info["terminal_reason"][i] == "numerical_failure" for i in np.flatnonzero(failed)
            )
            now = venv.get_state()
            for k in now:
                assert np.all(np.isfinite(now[k])) and np.array_equal(
                    now[k][failed], last[k][failed]
                )
            assert (
                np.max(np.abs(last["angular_momentum"][failed])) > 1e3
            )  # it had blown up: not the start
            failed_seen = True
            break
        assert not fails and not te.any()
    assert failed_seen


# ----------------------------------------------------------------------------------- 6. actions


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_bad_actions_raise_and_change_nothing(env_id):
    kwargs = dict(fidelity="frictionless") if env_id == TIPPE else {}
    n = 3
    venv = make_vec(env_id, n, max_episode_steps=4, **kwargs)
    twin = make_vec(env_id, n, max_episode_steps=4, **kwargs)
    venv.reset(seed=8)
    twin.reset(seed=8)
    k = venv.single_action_space.shape[0]
    for shape in ((n - 1, k), (k,), (n, k + 1), (n * k,), (n, k, 1)):
        with pytest.raises(ValueError, match="shape"):
            venv.step(np.zeros(shape, dtype=np.float32))
    rng = np.random.default_rng(3)
    for t in range(6):  # across an episode end: the step counters are untouched too
        before = venv.get_state()
        for bad in (np.nan, np.inf, -np.inf):
            a = random_actions(rng, venv.action_space)
            a[t % n, t % k] = bad
            with pytest.raises(ValueError, match="finite"):
                venv.step(a)
            assert same_state(venv.get_state(), before)
        a = random_actions(rng, venv.action_space)
        x, y = venv.step(a), twin.step(a)
        assert all(same(p, q) for p, q in zip(x[:4], y[:4]))
    # clipping: out-of-range actions act as the nearest in-range ones
    a = random_actions(rng, venv.action_space, scale=5.0)
    x, y = venv.step(a), twin.step(np.clip(a, -1.0, 1.0))
    assert all(same(p, q) for p, q in zip(x[:4], y[:4]))
    # float64 actions (and lists) are accepted
    x, y = venv.step(a.astype(np.float64).tolist()), twin.step(a)
    assert all(same(p, q) for p, q in zip(x[:4], y[:4]))


# ----------------------------------------------------------------------------------- 7. SB3

import stable_baselines3  # noqa: E402, F401  (the agents extra, part of dev: missing it must fail, not skip)


def _sb3():
    from rbenvs.vector.sb3 import SB3VecEnv, make_sb3_vec_env

    return SB3VecEnv, make_sb3_vec_env


@pytest.mark.parametrize("env_id", [FREE, LAGRANGE])
def test_sb3_ppo_learns_on_the_native_vector_env(env_id):
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecEnv

    _, make_sb3_vec_env = _sb3()
    venv = make_sb3_vec_env(env_id, 4, seed=0)
    assert isinstance(venv, VecEnv) and venv.num_envs == 4
    assert venv.observation_space == gym.make(env_id).observation_space
    obs = venv.reset()
    assert (
        isinstance(obs, np.ndarray)
        and obs.shape == (4,) + venv.observation_space.shape
        and obs.dtype == np.float32
    )
    venv.step_async(np.stack([venv.action_space.sample() for _ in range(4)]))
    obs, rewards, dones, infos = venv.step_wait()
    assert obs.shape == (4,) + venv.observation_space.shape and all(
        venv.observation_space.contains(o) for o in obs
    )
    assert rewards.shape == (4,) and rewards.dtype == np.float32
    assert dones.shape == (4,) and dones.dtype == bool
    assert isinstance(infos, list) and len(infos) == 4 and all(isinstance(i, dict) for i in infos)
    assert (
        venv.get_attr("dt") == [venv.venv.dt] * 4
        and venv.env_is_wrapped(gym.Wrapper) == [False] * 4
    )
    model = PPO("MlpPolicy", venv, n_steps=32, batch_size=64, n_epochs=1, device="cpu", seed=0)
    model.learn(256)
    assert model.num_timesteps >= 256
    action, _ = model.predict(venv.reset(), deterministic=True)
    assert action.shape == (4,) + venv.action_space.shape
    venv.close()


def test_sb3_step_wait_dones_terminal_observation_and_time_limit():
    """LagrangeTop with a tight tilt limit and 22 steps: some sub-envs fall (terminated), the
    rest hit the time limit (truncated); each ended sub-env's infos carry its last observation,
    equal to the single env's, and TimeLimit.truncated tells the two apart."""
    _, make_sb3_vec_env = _sb3()
    n, seed, m = 6, 3, 22
    kwargs = dict(tilt_limit=0.06, max_episode_steps=m)
    venv = make_sb3_vec_env(LAGRANGE, n, seed=seed, **kwargs)
    singles = make_singles(LAGRANGE, n, **kwargs)
    obs = venv.reset()
    for i, env in enumerate(singles):
        assert same(obs[i], env.reset(seed=seed + i)[0])
    n_term = n_trunc = 0
    zero = np.zeros((n, 2), dtype=np.float32)
    for _ in range(m + 3):
        venv.step_async(zero)
        obs, rewards, dones, infos = venv.step_wait()
        for i, env in enumerate(singles):
            o, r, te, tr, sinfo = env.step(zero[i])
            assert dones[i] == (te or tr) and rewards[i] == np.float32(r)
            if dones[i]:
                assert same(np.asarray(infos[i]["terminal_observation"], dtype=np.float32), o)
                assert infos[i]["TimeLimit.truncated"] == (tr and not te)
                assert infos[i]["energy"] == sinfo["energy"] and infos[i][
                    "terminal_reason"
                ] == sinfo.get("terminal_reason", "")
                n_term += te
                n_trunc += tr and not te
                o = env.reset()[0]
            else:
                assert infos[i] == {}
            assert same(obs[i], o)
    assert n_term >= 2 and n_trunc >= 2
    # a second reset() does not reuse the seeds: it continues each generator
    obs = venv.reset()
    for i, env in enumerate(singles):
        assert same(obs[i], env.reset()[0])


def test_sb3_info_keys_on_every_step():
    _, make_sb3_vec_env = _sb3()
    venv = make_sb3_vec_env(FREE, 3, seed=0, info_keys=("energy",))
    venv.reset()
    venv.step_async(np.zeros((3, 3), dtype=np.float32))
    _, _, dones, infos = venv.step_wait()
    assert not dones.any() and all(
        set(i) == {"energy"} and isinstance(i["energy"], float) for i in infos
    )


def test_sb3_adapter_refuses_next_step_vector_envs():
    SB3VecEnv, _ = _sb3()
    with pytest.raises(ValueError, match="SameStep"):
        SB3VecEnv(make_vec(FREE, 2))
    assert SB3VecEnv(make_vec(FREE, 2, autoreset_mode="SameStep")).num_envs == 2


def test_sb3_vec_monitor_episode_returns():
    from stable_baselines3.common.vec_env import VecMonitor

    _, make_sb3_vec_env = _sb3()
    n, m, seed = 3, 5, 7
    venv = VecMonitor(make_sb3_vec_env(FREE, n, seed=seed, max_episode_steps=m))
    singles = make_singles(FREE, n, max_episode_steps=m)
    for i, env in enumerate(singles):
        env.reset(seed=seed + i)
    venv.reset()
    rng = np.random.default_rng(0)
    returns32 = np.zeros(n, dtype=np.float32)
    returns64 = np.zeros(n)
    episodes = 0
    for _ in range(3 * m):
        a = rng.uniform(-2.0, 2.0, (n,) + venv.action_space.shape).astype(np.float32)
        venv.step_async(a)
        _, rewards, dones, infos = venv.step_wait()
        returns32 += rewards
        for i, env in enumerate(singles):
            returns64[i] += env.step(a[i])[1]
        for i in np.flatnonzero(dones):
            ep = infos[i]["episode"]
            assert ep["l"] == m and ep["r"] == returns32[i]
            assert ep["r"] == pytest.approx(returns64[i], rel=1e-6)
            returns32[i] = returns64[i] = 0.0
            singles[i].reset()
            episodes += 1
    assert episodes == 3 * n


# ----------------------------------------------------------------------------------- 8. bench


def test_bench_throughput_smoke():
    from rbenvs.bench.throughput import run_single, run_vector

    systems = ((FREE, ("rk4",)),)
    rows = run_vector(systems=systems, sizes=(1, 16), min_time=0.01, repeat=1)
    measured = [(r["id"], r["integrator"], r["num_envs"]) for r in rows]
    assert (FREE, "rk4", 1) in measured and (FREE, "rk4", 16) in measured
    assert all(
        r["id"] == FREE and r["integrator"].startswith("rk4") and r["num_envs"] in (1, 16)
        for r in rows
    )
    for r in rows:
        assert (
            r["env_steps_per_s"] > 0
            and r["cartpole_env_steps_per_s"] > 0
            and r["ns_per_env_step"] > 0
        )
        assert r["ratio_to_cartpole"] == pytest.approx(
            r["env_steps_per_s"] / r["cartpole_env_steps_per_s"], rel=1e-12
        )
        assert r["ns_per_env_step"] * r["env_steps_per_s"] == pytest.approx(1e9, rel=1e-12)
    # one CartPole figure per size, shared by every row of that size
    assert len({(r["num_envs"], r["cartpole_env_steps_per_s"]) for r in rows}) == 2
    from rbenvs.bench.throughput import compiled_speedup, run_scaling
    from rbenvs.compiled import available

    # the default rows take the path the env takes; with numba the numpy path is measured too
    paths = {(r["integrator"], r["path"]) for r in rows}
    if available():
        assert paths == {("rk4", "compiled"), ("rk4", "numpy"), ("rk4, lean info", "compiled")}
        speedup = compiled_speedup(rows)
        assert [n for n, _ in speedup] == [1, 16] and all(x > 0 for _, x in speedup)
    else:
        assert paths == {("rk4", "numpy"), ("rk4, lean info", "numpy")}
    scaling = run_scaling(sizes=(1, 4), min_time=0.01, repeat=1)
    assert [(r["path"], r["num_envs"]) for r in scaling] == [
        (p, n) for p in (["compiled"] if available() else []) + ["numpy"] for n in (1, 4)
    ]
    for r in scaling:
        # state in and out (2 x 24), a float32 action and observation (12 + 12), reward (8),
        # two flags (2) and the info arrays: at least 82 bytes per env
        assert r["ns_per_env_step"] > 0 and r["bytes_per_env_step"] >= 82
        assert r["megabytes_per_step"] == pytest.approx(
            r["bytes_per_env_step"] * r["num_envs"] / 1e6
        )
    rows = run_single(systems=systems, min_time=0.01, repeat=1)
    assert [(r["id"], r["integrator"]) for r in rows] == [(FREE, "rk4")]
    for r in rows:
        assert r["step_us"] > 0 and r["pendulum_step_us"] > 0
        assert r["ratio_to_pendulum"] == pytest.approx(
            r["step_us"] / r["pendulum_step_us"], rel=1e-12
        )


def test_bench_sb3_rows_compare_the_adapter_with_dummy_vec_env():
    from rbenvs.bench.throughput import run_sb3

    rows = run_sb3(sizes=(4,), min_time=0.01, repeat=1)
    assert len(rows) == 1 and rows[0]["num_envs"] == 4
    r = rows[0]
    assert r["sb3_native_env_steps_per_s"] > 0 and r["sb3_dummy_env_steps_per_s"] > 0
    assert r["ratio"] == pytest.approx(
        r["sb3_native_env_steps_per_s"] / r["sb3_dummy_env_steps_per_s"], rel=1e-12
    )


START_CASES = [
    (FREE, dict(task="spin")),
    (FREE, dict(task="detumble")),
    (FREE, dict(task="reorient")),
    (LAGRANGE, dict(task="upright", spin=(2.0, 8.0))),
    (LAGRANGE, dict(task="precess", spin=(15.0, 25.0), perturbation=0.2, attitude=True)),
    (
        LAGRANGE,
        dict(
            inertia=(0.5, 0.45, 0.3),
            com_direction=(0.3, -0.2, 1.0),
            spin=(-4.0, 4.0),
            attitude=True,
        ),
    ),
    (TIPPE, dict(task="invert", spin=(100.0, 200.0), tilt=(0.0, 0.5))),
    (TIPPE, dict(task="hold", fidelity="rolling", spin=(100.0, 200.0))),
    (TIPPE, dict(free_flight=True, spin=(100.0, 200.0))),
    (TIPPE, dict(start="rest", spin=(100.0, 200.0), tilt=(0.0, 0.5))),
    (TIPPE, dict(start="vertical", free_flight=True, spin=(100.0, 200.0))),
]


@pytest.mark.parametrize("compiled", ["auto", False], ids=["draws-auto", "draws-python"])
@pytest.mark.parametrize(
    "env_id,kwargs",
    START_CASES,
    ids=lambda v: v if isinstance(v, str) else ",".join(f"{k}={x}" for k, x in v.items()),
)
def test_batched_starts_equal_single_env_starts_bit_for_bit(env_id, kwargs, compiled):
    """Every task and system draws its starts in two stages: 64 sub-envs reset at once (the
    arithmetic on the batch) equal 64 single envs seeded alike, bit for bit, twice in a row;
    the generator calls compiled (``GeneratorTable``, where numba is installed) or in Python."""
    n = 64
    venv = make_vec(env_id, n, compiled=compiled, **kwargs)
    singles = make_singles(env_id, n, **kwargs)
    venv.reset(seed=7)
    assert (venv.unwrapped.starts.table is not None) == (
        compiled == "auto" and compiled_available()
    )
    for i, env in enumerate(singles):
        env.reset(seed=7 + i)
    for _ in range(2):
        state = venv.get_state()
        for i, env in enumerate(singles):
            single = env.unwrapped.get_state()
            assert all(np.array_equal(state[k][i], single[k]) for k in single), i
        venv.reset()
        for env in singles:
            env.reset()


def test_elapsed_steps_spread_the_time_limits():
    """``reset(options={"elapsed_steps": k})`` starts each sub-env's episode clock at ``k_i``:
    sub-env ``i`` is truncated after ``max_episode_steps - k_i`` steps; bad values are refused."""
    venv = make_vec(FREE, 4, max_episode_steps=5)
    venv.reset(seed=0, options={"elapsed_steps": np.array([0, 1, 3, 4])})
    first_truncation = [None] * 4
    for t in range(1, 7):
        truncated = venv.step(np.zeros((4, 3), dtype=np.float32))[3]
        for i in np.flatnonzero(truncated):
            if first_truncation[i] is None:
                first_truncation[i] = t
    assert first_truncation == [5, 4, 2, 1]
    for bad in (
        np.array([0, 1, 2, 5]),
        np.array([-1, 0, 0, 0]),
        np.array([0.0, 1.0, 2.0, 3.0]),
        np.array([0, 1]),
    ):
        with pytest.raises(ValueError, match="elapsed_steps"):
            venv.reset(options={"elapsed_steps": bad})
    with pytest.raises(ValueError, match="needs a time limit"):
        make_vec(FREE, 2, max_episode_steps=None).reset(
            options={"elapsed_steps": np.zeros(2, dtype=int)}
        )

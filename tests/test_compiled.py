"""The compiled batch step (rbenvs.compiled): the same functions as the single env, compiled.

Where numba is installed (the ``fast`` extra, part of ``dev``) the free-body vector env steps
through one compiled kernel; these tests hold it to the single env and to the numpy path bit
for bit, through resets, terminations, observation limits and numerical failures, and check
which settings take it and that the others say why they do not.
"""

import warnings

import gymnasium as gym
import numpy as np
import pytest
from conftest import FREE, LAGRANGE, TIPPE, lockstep, make_singles, make_vec, same

from rbenvs import compiled, vector
from rbenvs.envs import NumericalFailureWarning

# (numba is in the dev extra, so CI runs these; RBENVS_COMPILED=0 runs the rest on numpy)
needs_numba = pytest.mark.skipif(
    not compiled.available(),
    reason="the compiled path needs the 'fast' extra (numba) and RBENVS_COMPILED unset",
)


# free-body settings with a compiled step (spin and detumble, euler and rk4, substeps > 1,
# partial actuation, the observation limit) as (kwargs, max_episode_steps, steps)
COMPILED = [
    (dict(), 5, 17),
    (
        dict(
            integrator="euler",
            tolerance=None,
            substeps=4,
            max_angular_velocity=3.0,
            task="detumble",
            spin_rate=0.3,
        ),
        6,
        17,
    ),
    (dict(integrator="rk4", substeps=3, actuated=(True, False, True), axis="major"), 5, 17),
    (
        dict(
            integrator="euler", tolerance=None, substeps=4, max_angular_velocity=3.0, axis="minor"
        ),
        7,
        30,
    ),
    (dict(integrator="rk4", max_angular_velocity=1.6, max_torque=5.0), 40, 40),  # observation_limit
    (
        dict(integrator="euler", tolerance=None),
        5,
        17,
    ),  # guarded: the guard's check runs, every period fits
    # guarded, and the flip about the intermediate axis needs subdivided periods: those run
    # on numpy, the others compiled (see test_guarded_periods_switch_paths)
    (dict(integrator="euler", tolerance=None, spin_rate=1.8, perturbation=0.5), 120, 120),
]


def _ids(cases):
    return [",".join(f"{k}={v}" for k, v in kw.items()) or "default" for kw, _, _ in cases]


@pytest.mark.parametrize("task", ["spin", "detumble"])
def test_single_env_generated_finish_equals_the_methods(task):
    """The single env's generated read-out function (rbenvs.compiled.state_finish) gives the
    observation, bound flag, reward, termination and info of the engine's component methods,
    for states inside and outside the observation bounds (where the observation is clipped)."""
    env = gym.make(FREE, task=task, max_angular_velocity=2.0).unwrapped
    env.reset(seed=0)
    engine = env.engine
    finish, po, pe, pr = engine.finish_one
    rng = np.random.default_rng(5)
    outside = 0
    for _ in range(300):
        y = tuple(float(v) for v in rng.normal(0.0, 2.5, 3))
        u = [float(v) for v in rng.uniform(-1.0, 1.0, 3)]
        obs, over, reward, terminated, info = finish(y, u, po, pe, pr, engine.h)
        want_obs, want_over = engine.observe(y)
        want_reward, want_terminated, metrics = engine.evaluate(y, u)
        want_info = engine.info_one(y, u, False, engine.h, metrics, failed=False)
        assert obs.dtype == np.float32 and same(obs, want_obs) and over == want_over
        assert type(reward) is float and reward == want_reward and terminated is want_terminated
        assert list(info) == list(want_info) and all(
            type(info[k]) is type(want_info[k]) and info[k] == want_info[k] for k in info
        )
        outside += over
    assert 50 < outside < 250


@needs_numba
@pytest.mark.parametrize("kwargs,max_steps,steps", COMPILED, ids=_ids(COMPILED))
def test_compiled_settings_take_the_kernel(kwargs, max_steps, steps):
    venv = vector.FreeRigidBodyVectorEnv(num_envs=2, **kwargs)
    assert venv.compiled
    assert not vector.FreeRigidBodyVectorEnv(num_envs=2, compiled=False, **kwargs).compiled


@needs_numba
@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
@pytest.mark.parametrize("kwargs,max_steps,steps", COMPILED, ids=_ids(COMPILED))
def test_compiled_sub_envs_equal_single_envs_bit_for_bit(kwargs, max_steps, steps, mode):
    n_term, n_trunc, _ = lockstep(
        FREE, 3, 11, steps, mode, max_steps, kwargs, vector_kwargs=dict(compiled=True)
    )
    assert n_term + n_trunc >= 3


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
@pytest.mark.parametrize("kwargs,max_steps,steps", COMPILED, ids=_ids(COMPILED))
def test_numpy_path_sub_envs_equal_single_envs_bit_for_bit(kwargs, max_steps, steps, mode):
    """The numpy path of the same settings (where numba is missing, this is the one that runs)."""
    n_term, n_trunc, _ = lockstep(
        FREE, 3, 11, steps, mode, max_steps, kwargs, vector_kwargs=dict(compiled=False)
    )
    assert n_term + n_trunc >= 3


@needs_numba
def test_guarded_periods_subdivide_inside_the_kernel():
    """A guarded env's kernel counts each sub-env's internal steps itself: the periods its guard
    leaves at ``substeps`` and the ones it subdivides (here the flip about the intermediate
    axis) both occur in this run, all compiled (the numpy period never runs), each sub-env
    with its own ``internal_step`` (and the lockstep test above holds the same setting to
    single envs bit for bit)."""
    venv = vector.FreeRigidBodyVectorEnv(
        num_envs=3, integrator="euler", tolerance=None, spin_rate=1.8, perturbation=0.5
    )
    numpy_periods = 0
    numpy_advance = venv.engine.advance

    def counted(*args):
        nonlocal numpy_periods
        numpy_periods += 1
        return numpy_advance(*args)

    venv.engine.advance = counted
    venv.reset(seed=11)
    rng = np.random.default_rng(0)
    subdivided = mixed = 0
    for _ in range(120):
        info = venv.step(rng.uniform(-1.0, 1.0, (3, 3)).astype(np.float32))[4]
        h = info["internal_step"]
        subdivided += bool((h < venv.engine.h).any())
        mixed += len(set(h.tolist())) > 1
    assert numpy_periods == 0
    assert 5 < subdivided < 115 and mixed > 0, (subdivided, mixed)


@needs_numba
def test_guard_refuse_raises_from_the_compiled_path_and_changes_nothing():
    """guard='refuse': a period the guard would subdivide raises (naming substeps) instead of
    running, compiled or not; the states stay as they were."""
    kwargs = dict(
        integrator="euler",
        tolerance=None,
        guard="refuse",
        task="detumble",
        spin_rate=3.0,
        max_angular_velocity=20.0,
    )
    venv = vector.FreeRigidBodyVectorEnv(num_envs=4, **kwargs)
    assert venv.compiled
    venv.reset(seed=0)
    before = venv.get_state()
    with pytest.raises(ValueError, match="guard='refuse'.*substeps"):
        venv.step(np.zeros((4, 3), dtype=np.float32))
    after = venv.get_state()
    assert all(np.array_equal(before[k], after[k]) for k in before)


@needs_numba
def test_compiled_equals_numpy_path_on_a_large_batch():
    """4096 sub-envs, 300 steps of random actions (many out of range): observations, rewards,
    flags, every info array and the final state agree bit for bit, dtypes included."""
    n = 4096
    kwargs = dict(max_episode_steps=120, max_angular_velocity=1.6, max_torque=5.0)
    fast = vector.FreeRigidBodyVectorEnv(num_envs=n, **kwargs)
    slow = vector.FreeRigidBodyVectorEnv(num_envs=n, compiled=False, **kwargs)
    assert fast.compiled and not slow.compiled
    fast.reset(seed=3)
    slow.reset(seed=3)
    rng = np.random.default_rng(0)
    ended = 0
    for _ in range(300):
        a = rng.uniform(-1.0, 1.5, (n, 3)).astype(np.float32)  # biased: the spin grows
        out_f, out_s = fast.step(a), slow.step(a)
        for x, y in zip(out_f[:4], out_s[:4]):
            assert x.dtype == y.dtype and same(x, y)
        info_f, info_s = out_f[4], out_s[4]
        assert list(info_f) == list(info_s)
        for key in info_f:
            assert info_f[key].dtype == info_s[key].dtype and np.array_equal(
                info_f[key], info_s[key]
            ), key
        ended += int(out_f[2].sum())
    assert ended > 100  # observation limits were crossed, not only time limits
    s_f, s_s = fast.get_state(), slow.get_state()
    assert all(np.array_equal(s_f[k], s_s[k]) for k in s_f)


@needs_numba
def test_non_finite_states_take_the_numerical_failure_path():
    """Sub-env 1 reset to a spin of 1e38 rad/s (inside bounds raised to float32's; a torque
    large enough to get there in a step is refused at construction) overflows inside the
    kernel with the guard off (the gyroscopic term squares 1e38 twice per RK4 step): the step
    falls back to the numpy failure path (one warning, last finite state kept, reward 0 and the
    failure charge) and
    every sub-env still equals its single env."""
    n = 3
    kwargs = dict(max_angular_velocity=3e38, guard="off")
    venv = make_vec(FREE, n, compiled=True, **kwargs)
    assert venv.unwrapped.compiled
    singles = make_singles(FREE, n, **kwargs)
    venv.reset(seed=0)
    for i, env in enumerate(singles):
        env.reset(seed=i)
    a = np.zeros((n, 3), dtype=np.float32)
    venv.step(a)
    for env in singles:
        env.step(a[0])
    fast = {"angular_momentum": np.array([2e38, 1.5e38, 1e38])}  # Omega = 1e38 rad/s per axis
    state = venv.get_state()
    state["angular_momentum"][1] = fast["angular_momentum"]
    venv.reset(options={"state": state, "reset_mask": np.array([False, True, False])})
    singles[1].reset(options={"state": fast})
    last = venv.get_state()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        obs, r, te, tr, info = venv.step(a)
    assert len([w for w in caught if issubclass(w.category, NumericalFailureWarning)]) == 1
    # reward 0 and the failure charge (rbenvs.core.model.Model)
    assert (
        np.array_equal(te, [False, True, False])
        and r[1] == venv.unwrapped.engine.failure_charge == -404.0
    )
    assert list(info["terminal_reason"]) == ["", "numerical_failure", ""]
    now = venv.get_state()
    assert np.array_equal(now["angular_momentum"][1], last["angular_momentum"][1])
    for i, env in enumerate(singles):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NumericalFailureWarning)
            o, sr, ste, _, _ = env.step(a[i])
        assert same(obs[i], o) and r[i] == sr and te[i] == ste
    # the next step resets the failed sub-env and runs compiled again
    obs, r, te, tr, info = venv.step(np.zeros((n, 3), dtype=np.float32))
    assert not te.any() and not info["numerical_failure"].any()


# settings of other systems and tasks with a compiled step since issue 17 (reorient's attitude,
# the splitting's exact flows, the heavy top with Gamma's projection, its tasks, friction, a
# general top, guarded euler) as (id, kwargs, max_episode_steps, steps)
COMPILED_MORE = [
    (FREE, dict(task="reorient"), 5, 17),
    (FREE, dict(task="reorient", integrator="euler", tolerance=None, substeps=3), 5, 17),
    (FREE, dict(task="reorient", integrator="splitting", max_torque=0.5), 5, 17),
    (FREE, dict(integrator="splitting", actuated=(True, False, True), axis="major"), 5, 17),
    (LAGRANGE, dict(), 5, 17),  # splitting, upright
    (
        LAGRANGE,
        dict(integrator="rk4", tilt_limit=0.06, max_torque=0.05, spin=0.0),
        25,
        45,
    ),  # task terminations
    (LAGRANGE, dict(integrator="rk4", task="precess", attitude=True), 5, 17),
    (LAGRANGE, dict(task="precess", target_rate=2.0), 5, 17),
    (
        LAGRANGE,
        dict(
            integrator="euler", tolerance=None, axial_torque=True, spin=(5.0, 15.0), attitude=True
        ),
        5,
        17,
    ),  # guarded
    (
        LAGRANGE,
        dict(integrator="splitting", task="precess", spin=(20.0, 30.0), spin_friction=0.01),
        5,
        17,
    ),
    (
        LAGRANGE,
        dict(
            integrator="splitting",
            inertia=(0.5, 0.45, 0.3),
            com_direction=(0.1, 0.0, 1.0),
            spin=(0.0, 3.0),
            attitude=True,
        ),
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
            spin_friction=0.02,
        ),
        5,
        17,
    ),
    # the tippe top: every fidelity and law, the guard's own count per sub-env, actions on the
    # friction and a torque, the lift-off ending episodes, free flight with hops
    (
        TIPPE,
        dict(spin=(100.0, 200.0), start="rolling", friction_bound="stability"),
        3,
        7,
    ),  # -v0's defaults before issue 18
    (TIPPE, dict(fidelity="frictionless", spin=(100.0, 200.0)), 4, 10),
    (TIPPE, dict(fidelity="rolling", task="hold", torque_action=True), 4, 10),
    (TIPPE, dict(friction_law="viscous", integrator="euler", tolerance=None), 4, 10),
    (TIPPE, dict(spin=(120.0, 160.0), friction_action=True, torque_action=True), 3, 5),
    (
        TIPPE,
        dict(spin=2000.0, max_speed=50.0, start="rolling"),
        20,
        20,
    ),  # lift-off ends the episodes
    (
        TIPPE,
        dict(free_flight=True, spin=2000.0, max_speed=50.0, start="rolling"),
        20,
        20,
    ),  # hops (from about the 13th period)
    (
        TIPPE,
        dict(
            free_flight=True,
            fidelity="frictionless",
            spin=(1500.0, 2500.0),
            max_speed=60.0,
            friction_law="viscous",
            start="rolling",
        ),
        6,
        12,
    ),
    (
        TIPPE,
        dict(start="vertical", free_flight=True, spin=(150.0, 180.0)),
        4,
        10,
    ),  # both start flags, restarts in the kernel
]


def _ids_more(cases):
    return [
        env_id.split("/")[1] + "-" + (",".join(f"{k}={v}" for k, v in kw.items()) or "default")
        for env_id, kw, _, _ in cases
    ]


@needs_numba
@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
@pytest.mark.parametrize(
    "env_id,kwargs,max_steps,steps", COMPILED_MORE, ids=_ids_more(COMPILED_MORE)
)
def test_more_compiled_settings_equal_single_envs_bit_for_bit(
    env_id, kwargs, max_steps, steps, mode
):
    """Every newly compiled setting takes the kernel, and its sub-envs follow single envs bit
    for bit (observations, rewards, flags, every info value) across episode ends."""
    assert make_vec(env_id, 2, **kwargs).unwrapped.compiled
    n_term, n_trunc, _ = lockstep(
        env_id, 3, 11, steps, mode, max_steps, kwargs, vector_kwargs=dict(compiled=True)
    )
    assert n_term + n_trunc >= 3


@needs_numba
@pytest.mark.parametrize(
    "env_id,kwargs,max_steps,steps", COMPILED_MORE, ids=_ids_more(COMPILED_MORE)
)
def test_more_compiled_settings_equal_the_numpy_path(env_id, kwargs, max_steps, steps):
    """Compiled and numpy paths of the same vector env on 64 sub-envs with random actions: every
    output, info array (dtype included) and the final state agree bit for bit."""
    n = 64
    fast = make_vec(env_id, n, max_episode_steps=max_steps, compiled=True, **kwargs)
    slow = make_vec(env_id, n, max_episode_steps=max_steps, compiled=False, **kwargs)
    fast.reset(seed=5)
    slow.reset(seed=5)
    rng = np.random.default_rng(2)
    for _ in range(steps):
        a = rng.uniform(-1.5, 1.5, fast.action_space.shape).astype(np.float32)
        out_f, out_s = fast.step(a), slow.step(a)
        for x, y in zip(out_f[:4], out_s[:4]):
            assert x.dtype == y.dtype and same(x, y)
        assert list(out_f[4]) == list(out_s[4])
        for key, value in out_f[4].items():
            other = out_s[4][key]
            if value.dtype.kind in "OU":  # terminal reasons
                assert list(value) == list(other), key
            else:
                assert value.dtype == other.dtype and same(value, other), key
    s_f, s_s = fast.unwrapped.get_state(), slow.unwrapped.get_state()
    assert all(np.array_equal(s_f[k], s_s[k]) for k in s_f)


@needs_numba
@pytest.mark.parametrize(
    "env_id,kwargs",
    [
        (FREE, dict(integrator="exact")),  # elliptic functions: no pure form
        (FREE, dict(integrator="dop853")),  # an adaptive solve
        (LAGRANGE, dict(integrator="dop853")),
        (TIPPE, dict(integrator="dop853")),
    ],
)
def test_settings_without_a_kernel_run_on_numpy_and_say_why(env_id, kwargs):
    assert not make_vec(env_id, 2, **kwargs).unwrapped.compiled
    with pytest.raises(ValueError, match="compiled=True but .*has no compiled step"):
        make_vec(env_id, 2, compiled=True, **kwargs)


def test_disabled_by_the_environment_variable(monkeypatch):
    monkeypatch.setenv(compiled.DISABLE_VARIABLE, "0")
    assert not compiled.available()
    assert not vector.FreeRigidBodyVectorEnv(num_envs=2).compiled
    with pytest.raises(ValueError, match="numba is not installed .* RBENVS_COMPILED=0"):
        vector.FreeRigidBodyVectorEnv(num_envs=2, compiled=True)


def test_compiled_argument_is_validated():
    with pytest.raises(ValueError, match="compiled must be True, False or 'auto'"):
        vector.FreeRigidBodyVectorEnv(num_envs=2, compiled="yes")


@needs_numba
def test_kernels_are_shared_by_envs_of_one_layout():
    a = vector.FreeRigidBodyVectorEnv(num_envs=2, inertia=(3.0, 2.0, 1.5))
    b = vector.FreeRigidBodyVectorEnv(num_envs=8, spin_rate=0.5, axis="major")
    assert (
        a.compiled_path.batch.kernel is b.compiled_path.batch.kernel
    )  # parameters are arguments, not constants


def test_jitable_functions_stay_plain_python():
    """The marker changes nothing on the single-env path: the functions are the originals."""
    from rbenvs.dynamics.free_body import euler_rhs

    gym.make(FREE).reset(seed=0)
    assert type(euler_rhs).__name__ == "function"
    assert euler_rhs((1.0, 2.0, 3.0), (1.0, 1.0, 1.0), None) == (1.0, 2.0, 3.0)


# ----------------------------------------------------------------- the single env, compiled
SINGLE = [
    (FREE, dict(), 40, 90),
    (FREE, dict(task="detumble", integrator="euler", tolerance=None, substeps=3), 40, 90),
    (FREE, dict(task="reorient"), 30, 90),
    (
        FREE,
        dict(integrator="euler", tolerance=None, spin_rate=1.8, perturbation=0.5),
        120,
        120,
    ),  # subdivided periods
    (
        FREE,
        dict(integrator="rk4", max_angular_velocity=1.6, max_torque=5.0),
        40,
        60,
    ),  # observation limit
    (LAGRANGE, dict(), 40, 90),
    (LAGRANGE, dict(integrator="rk4", tilt_limit=0.06, max_torque=0.05, spin=0.0), 25, 60),
    (LAGRANGE, dict(integrator="rk4", task="precess", attitude=True), 30, 90),
    (
        LAGRANGE,
        dict(
            integrator="euler", tolerance=None, axial_torque=True, spin=(5.0, 15.0), attitude=True
        ),
        30,
        60,
    ),
    (
        LAGRANGE,
        dict(
            integrator="splitting",
            inertia=(0.5, 0.45, 0.3),
            com_direction=(0.1, 0.0, 1.0),
            spin=(0.0, 3.0),
            spin_friction=0.02,
        ),
        30,
        60,
    ),
    (TIPPE, dict(), 30, 40),
    (TIPPE, dict(fidelity="rolling", task="hold", torque_action=True), 10, 30),
    (
        TIPPE,
        dict(friction_law="viscous", integrator="euler", tolerance=None, friction_action=True),
        10,
        30,
    ),
    (
        TIPPE,
        dict(spin=2000.0, max_speed=50.0, start="rolling"),
        30,
        40,
    ),  # lift-off ends the episodes
    (TIPPE, dict(free_flight=True, spin=2000.0, max_speed=50.0, start="rolling"), 30, 40),  # hops
    (TIPPE, dict(start="rest", spin=180.0), 30, 40),
    (TIPPE, dict(start="vertical", free_flight=True), 30, 40),
]


@needs_numba
@pytest.mark.parametrize("env_id,kwargs,max_steps,steps", SINGLE, ids=_ids_more(SINGLE))
def test_single_env_compiled_step_equals_the_float_path(env_id, kwargs, max_steps, steps):
    """``compiled=True`` runs each step as one compiled call; ``compiled=False`` the float path.
    Observations, rewards, flags, every info value (with its Python type) and the states agree
    bit for bit, through terminations, truncations and resets."""
    fast = gym.make(env_id, compiled=True, max_episode_steps=max_steps, **kwargs)
    slow = gym.make(env_id, compiled=False, max_episode_steps=max_steps, **kwargs)
    o_f, i_f = fast.reset(seed=4)
    o_s, i_s = slow.reset(seed=4)
    assert same(o_f, o_s) and i_f == i_s
    rng = np.random.default_rng(3)
    ends = 0
    for _ in range(steps):
        a = rng.uniform(-1.5, 1.5, fast.action_space.shape).astype(np.float32)
        out_f, out_s = fast.step(a), slow.step(a)
        assert out_f[0].dtype == np.float32 and same(out_f[0], out_s[0])
        assert type(out_f[1]) is float and out_f[1:4] == out_s[1:4]
        assert list(out_f[4]) == list(out_s[4])
        assert all(
            type(out_f[4][k]) is type(v) and same(out_f[4][k], v)
            for k, v in out_s[4].items()
            if k != "terminal_reason"
        )
        assert out_f[4].get("terminal_reason") == out_s[4].get("terminal_reason")
        assert fast.unwrapped.state_components == slow.unwrapped.state_components
        if out_f[2] or out_f[3]:
            ends += 1
            assert same(fast.reset()[0], slow.reset()[0])
    assert ends >= 1
    assert fast.unwrapped.compiled and not slow.unwrapped.compiled


@needs_numba
def test_single_env_compiled_refusal_and_failure_as_the_float_path():
    """guard='refuse' raises from the compiled step naming the count, the state unchanged; a
    state that overflows ends the episode as a numerical failure with the last finite state."""
    kwargs = dict(
        integrator="euler",
        tolerance=None,
        guard="refuse",
        task="detumble",
        spin_rate=6.0,
        max_angular_velocity=20.0,
    )
    for compiled_ in (True, False):
        env = gym.make(FREE, compiled=compiled_, **kwargs)
        env.reset(seed=0)
        before = env.unwrapped.state_components
        with pytest.raises(ValueError, match="guard='refuse'.*substeps"):
            env.step(np.zeros(3, dtype=np.float32))
        assert env.unwrapped.state_components == before
    results = []
    for compiled_ in (True, False):
        env = gym.make(FREE, compiled=compiled_, max_angular_velocity=3e38, guard="off")
        env.reset(options={"state": {"angular_momentum": np.array([2e38, 1.5e38, 1e38])}})
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            obs, r, te, tr, info = env.step(np.zeros(3, dtype=np.float32))
        assert any(issubclass(w.category, NumericalFailureWarning) for w in caught)
        results.append(
            (
                obs,
                r,
                te,
                info["terminal_reason"],
                info["numerical_failure"],
                env.unwrapped.state_components,
            )
        )
    assert same(results[0][0], results[1][0]) and results[0][1:] == results[1][1:]
    assert (
        results[0][1] == env.unwrapped.model.failure_charge == -404.0
        and results[0][3] == "numerical_failure"
    )  # 0 + the charge


def test_single_env_compiled_argument():
    """``compiled`` takes True, False or 'auto'; True without a compiled step says why."""
    with pytest.raises(ValueError, match="compiled must be True, False or 'auto'"):
        gym.make(FREE, compiled="yes")
    env = gym.make(FREE, compiled=False)
    env.reset(seed=0)
    env.step(np.zeros(3, dtype=np.float32))
    assert not env.unwrapped.compiled
    with pytest.raises(
        ValueError, match="compiled=True but .*no compiled step|compiled=True but numba"
    ):
        gym.make(FREE, integrator="exact", compiled=True)


@needs_numba
def test_compiled_tippe_top_crosses_lift_offs_and_hops():
    """The tippe-top settings above do exercise the kernel's event and switches: without free
    flight lift-offs end episodes (``terminal_reason == "lift_off"``, ``lifted_off`` set); with
    it the tops hop (``hops`` counts, ``airborne`` is seen) and no episode ends at a lift-off."""
    venv = make_vec(
        TIPPE, 4, spin=2000.0, max_speed=50.0, max_episode_steps=20, compiled=True, start="rolling"
    )
    assert venv.unwrapped.compiled
    venv.reset(seed=0)
    reasons = set()
    for _ in range(20):
        info = venv.step(np.zeros((4, 2), dtype=np.float32))[4]
        reasons |= set(info.get("terminal_reason", []))
    assert "lift_off" in reasons
    venv = make_vec(
        TIPPE,
        4,
        free_flight=True,
        spin=2000.0,
        max_speed=50.0,
        max_episode_steps=40,
        compiled=True,
        start="rolling",
    )
    venv.reset(seed=0)
    airborne = hops = 0
    for _ in range(20):  # (the first hop comes near period 13)
        info = venv.step(np.zeros((4, 2), dtype=np.float32))[4]
        airborne += int(info["airborne"].sum())
        hops = max(hops, int(info["hops"].max()))
        assert "lift_off" not in set(info.get("terminal_reason", []))
    assert airborne > 0 and hops >= 3, (airborne, hops)


# ------------------------------------------------------------------ the whole vector step compiled
# settings whose whole vector step is compiled, restarts drawn by the rows kernel (the lockstep
# tests above cover every system through restarts; these add float64 and float32 actions in
# turn and the state after, against the numpy path)
WHOLE_STEP = [
    (FREE, dict(task="reorient")),
    (LAGRANGE, dict(attitude=True)),
    (TIPPE, dict(free_flight=True, max_torque=1e-4, friction_range=(0.1, 0.4))),
]


@pytest.mark.parametrize(
    "env_id,tasks",
    [
        (FREE, ("spin", "detumble", "reorient")),
        (LAGRANGE, ("upright", "precess")),
        (TIPPE, ("invert", "hold")),
    ],
)
def test_every_task_has_pure_starts_and_actuators(env_id, tasks):
    """Every (system, task) declares the pure start and actuator the compiled restarts need, and
    they give the methods' values (a start drawn from one generator, floats and a batch)."""
    for task in tasks:
        for extra in ({}, {"attitude": True} if env_id == LAGRANGE else {}):
            env = gym.make(env_id, task=task, **extra).unwrapped
            model = env.model
            start, p = model.kernel_start()
            d = model.split_draws(np.random.default_rng(4).random(len(model.draw_kinds)))
            assert start(p, tuple(np.concatenate(d))) == model.initial_from_draws(*d)
            rows = np.random.default_rng(5).random((len(model.draw_kinds), 3))
            batch = start(p, tuple(rows))
            for i in range(3):
                one = start(p, tuple(rows[:, i].tolist()))
                assert all(np.float64(b[i]) == o for b, o in zip(batch, one))
            assert model.kernel_control[0](
                model.kernel_control[1], (0.0,) * model.actuator.size
            ) == model.actuator.control((0.0,) * model.actuator.size)


def _same_outputs(a, b, where):
    if isinstance(a, dict):
        assert list(a) == list(b), where
        for k in a:
            _same_outputs(a[k], b[k], f"{where} {k}")
    elif isinstance(a, (tuple, list)):
        for x, y in zip(a, b):
            _same_outputs(x, y, where)
    else:
        x, y = np.asarray(a), np.asarray(b)
        if x.dtype == object:
            for p, q in zip(x.ravel(), y.ravel()):
                _same_outputs(p, q, where)
        else:
            assert x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes(), where


@needs_numba
@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
@pytest.mark.parametrize(
    "env_id,kwargs",
    WHOLE_STEP,
    ids=[
        f"{e.split('/')[1]}-{','.join(f'{k}={v}' for k, v in kw.items()) or 'default'}"
        for e, kw in WHOLE_STEP
    ],
)
def test_the_whole_vector_step_compiled_equals_the_numpy_path_through_restarts(
    env_id, kwargs, mode
):
    """The vector step as one compiled call (actions checked, clipped and mapped; the period;
    the finish; the episode clocks; restarts drawn from each sub-env's own generator and
    finished inside the kernel) equals the numpy path bit for bit, every output and info key,
    with a time limit of 7 steps so that every sub-env restarts three times (actions beyond
    the bounds: clipping counts)."""
    envs = [
        make_vec(env_id, 6, max_episode_steps=7, autoreset_mode=mode, compiled=c, **kwargs)
        for c in (False, True)
    ]
    step = envs[1].unwrapped.compiled_path.whole
    assert step is not None and step.restarts
    _same_outputs(envs[0].reset(seed=5), envs[1].reset(seed=5), "reset")
    rng = np.random.default_rng(0)
    for t in range(25):
        a = rng.uniform(-1.3, 1.3, envs[0].action_space.shape).astype(
            np.float32 if t % 2 else np.float64
        )
        _same_outputs(envs[0].step(a), envs[1].step(a), f"step {t}")
    _same_outputs(envs[0].unwrapped.get_state(), envs[1].unwrapped.get_state(), "state")


@needs_numba
def test_the_compiled_step_keeps_the_controls_for_rendering():
    """The compiled step keeps the actions, not the controls: a frame of the tippe top (whose
    scene draws the table's acceleration) is the same as the numpy path's."""
    envs = [make_vec(TIPPE, 2, compiled=c, render_mode="rgb_array") for c in (False, True)]
    for env in envs:
        env.reset(seed=1)
        env.step(np.array([[0.7, -0.4], [-2.0, 0.3]], dtype=np.float32))
    frames = [env.render() for env in envs]
    assert all(np.array_equal(p, q) for p, q in zip(*frames))


@pytest.mark.parametrize(
    "env_id,kwargs",
    [
        (FREE, dict()),
        (FREE, dict(actuated=(False, True, True))),
        (LAGRANGE, dict()),
        (LAGRANGE, dict(axial_torque=True)),
        (TIPPE, dict()),
        (TIPPE, dict(friction_range=(0.1, 0.5), max_torque=1e-4)),
    ],
)
def test_actuators_pure_forms_are_their_formulas(env_id, kwargs):
    """Each actuator's pure form (what the single env, the numpy batch and the compiled step
    run) gives its documented controls: the free body's torque ``max_torque a`` on the actuated
    axes, the heavy top's ``max_torque sum_j a_j d_j``, the tippe top's table acceleration, the
    friction coefficient affine in its entry and the body torque; floats and arrays alike."""
    env = gym.make(env_id, **kwargs).unwrapped
    act = env.model.actuator
    rng = np.random.default_rng(2)
    a = tuple(rng.uniform(-1.0, 1.0, act.size).tolist())
    u_norm, u = act.control(a)
    if env_id == FREE:
        full = np.zeros(3)
        full[list(act.axes)] = a
        assert np.allclose(u_norm, full, rtol=0, atol=0) and np.allclose(
            u, act.max_torque * full, rtol=1e-15
        )
    elif env_id == LAGRANGE:
        assert u_norm == a and np.allclose(
            u, act.max_torque * np.asarray(a) @ np.asarray(act.directions), rtol=1e-14, atol=1e-15
        )
    else:
        acc = act.max_table_acceleration
        assert u[:2] == (acc * a[0], acc * a[1])
        if act.friction_range is None:
            assert u[2] == act.friction and u[3:] == (0.0, 0.0, 0.0)
        else:
            lo, hi = act.friction_range
            assert u[2] == pytest.approx(lo + (a[2] + 1.0) / 2.0 * (hi - lo), rel=1e-15)
            assert np.allclose(u[3:], act.max_torque * np.asarray(a[3:]), rtol=1e-15)
    rows = tuple(np.array([x, -x]) for x in a)  # a batch: the same values per row
    un_b, u_b = act.control(rows)
    assert all(np.asarray(p)[0] == q for p, q in zip(np.broadcast_arrays(*un_b), u_norm))
    assert all(np.broadcast_to(p, (2,))[0] == q for p, q in zip(u_b, u))


@needs_numba
def test_compiled_code_runs_the_scalar_form_for_a_bool():
    """rbenvs.jit.scalar_form: compiled code calls the declared one-state form where the first
    argument is a bool (a probe whose form is told apart from its own body: 2.0 against 1.0),
    and a form declared after the function was registered is refused."""
    import numba

    from rbenvs import jit

    def probe(cond):
        if isinstance(cond, bool):
            return 1.0 if cond else 0.0
        return float(cond.all())

    jit.jitable(probe)

    @jit.scalar_form(probe)
    def _probe_one(cond):
        return 2.0 if cond else 0.0

    jit.register_all()
    assert numba.njit(lambda c: probe(c))(True) == 2.0
    assert probe(True) == 1.0  # (Python keeps the function itself)
    with pytest.raises(RuntimeError, match="registered with numba before"):
        jit.scalar_form(probe)(_probe_one)

"""Every keyword of every env, against a table of bad values: each case is either a documented
valid value (the env then runs with finite info) or an error at construction that names the
keyword. Actions and reset states of the wrong type are refused alike by the single and the
vector env."""

import inspect
import math
import warnings

import gymnasium as gym
import numpy as np
import pytest

from rbenvs.envs import FreeRigidBodyEnv, LagrangeTopEnv, TippeTopEnv
from rbenvs.envs.base import MAX_INTERNAL_STEPS

TASKS = {
    FreeRigidBodyEnv: ("spin", "detumble", "reorient"),
    LagrangeTopEnv: ("upright", "precess"),
    TippeTopEnv: ("invert", "hold"),
}
IDS = {
    FreeRigidBodyEnv: "rbenvs/FreeRigidBody-v0",
    LagrangeTopEnv: "rbenvs/LagrangeTop-v0",
    TippeTopEnv: "rbenvs/TippeTop-v0",
}

# The bad values of the table, each tried on every keyword of every env and task.
CASES = {
    "nan": math.nan,
    "inf": math.inf,
    "negative": -1.0,
    "zero": 0.0,
    "string": "abc",
    "bool_string": "False",
    "none": None,
    "wrong_length": (1.0, 2.0, 3.0, 4.0, 5.0),  # no vector keyword has 5 entries
    "huge": 1e300,
    "huge_int": 10**9,
    "wrong_type": object(),
    "complex": 1j,
}

# The cases that are documented valid values (the docstrings' Arguments); every other case must
# be refused at construction with the keyword's name. Keyed by (env class, keyword): the cases,
# or a dict task -> cases where it depends on the task.
VALID = {
    (FreeRigidBodyEnv, "perturbation"): {"zero"},  # an exact principal-axis spin
    (FreeRigidBodyEnv, "max_torque"): {"zero"},  # no actuator (the body turns freely)
    (FreeRigidBodyEnv, "control_cost"): {
        "zero",
        "huge_int",
    },  # a weight >= 0 whose rewards float32 holds
    (FreeRigidBodyEnv, "max_angular_velocity"): {"huge_int"},  # any bound up to float32's
    (FreeRigidBodyEnv, "render_mode"): {"none"},
    (LagrangeTopEnv, "spin"): {
        "upright": {"negative", "zero", "none"},
        "precess": {"none"},
    },  # precess needs [T 3.82] real
    (LagrangeTopEnv, "perturbation"): {"zero"},
    (LagrangeTopEnv, "target_rate"): {
        "negative",
        "none",
    },  # a retrograde forced precession; None: [T 3.82]
    (LagrangeTopEnv, "tilt_limit"): {"none"},
    (LagrangeTopEnv, "max_torque"): {"zero"},
    (LagrangeTopEnv, "spin_friction"): {
        "zero"
    },  # at most I_chi / dt: no spin stopped within a step
    (LagrangeTopEnv, "control_cost"): {"zero", "huge_int"},
    (LagrangeTopEnv, "max_angular_velocity"): {"huge_int"},
    (LagrangeTopEnv, "render_mode"): {"none"},
    (TippeTopEnv, "friction"): {"zero"},
    # (slip_regularization: below max_speed, else Coulomb friction fades to nothing: huge refused)
    (TippeTopEnv, "spin"): {"negative", "zero"},  # spun the other way, or not at all
    (TippeTopEnv, "tilt"): {"zero"},
    (TippeTopEnv, "max_table_acceleration"): {"zero"},
    (TippeTopEnv, "friction_range"): {"zero"},
    (TippeTopEnv, "max_torque"): {
        "zero",
        "huge",
        "huge_int",
    },  # unused without torque_action: any finite value >= 0
    (TippeTopEnv, "control_cost"): {"zero", "huge_int"},
    (TippeTopEnv, "max_angular_velocity"): {"none", "huge_int"},
    (TippeTopEnv, "max_speed"): {"huge_int"},
    (TippeTopEnv, "render_mode"): {"none"},
    (TippeTopEnv, "start"): {"none"},  # None: "rest", or "rolling" with fidelity="rolling"
    (TippeTopEnv, "stem"): {"none"},  # None: no stem (the sphere alone)
}
# tolerance: "default" (the default accuracy), None (unchecked) or in (0, 1); tolerance_horizon:
# None (the registered episode), or a whole number of periods >= 1 with a tolerance (the default
# takes one: a huge whole horizon is valid), for every env
for _cls in TASKS:
    VALID[(_cls, "tolerance")] = {"none"}
    VALID[(_cls, "tolerance_horizon")] = {"none", "huge_int"}
# the robustness options (rbenvs.envs.options), the same on every env: None (the default) for
# each; a standard deviation of noise or bias is any finite number >= 0
for _cls in TASKS:
    VALID[(_cls, "param_ranges")] = {"none"}
    VALID[(_cls, "observation_noise")] = {
        "zero",
        "none",
    }  # (at most the observation's bounds: huge refused)
    VALID[(_cls, "observation_bias")] = {"zero", "none"}


def keywords(cls):
    return [name for name in inspect.signature(cls.__init__).parameters if name != "self"]


def valid(cls, keyword, task, case) -> bool:
    entry = VALID.get((cls, keyword), set())
    if isinstance(entry, dict):
        entry = entry.get(task, set())
    return case in entry


GRID = [
    pytest.param(cls, task, keyword, case, id=f"{cls.__name__}-{task}-{keyword}-{case}")
    for cls, tasks in TASKS.items()
    for keyword in keywords(cls)
    for task in (tasks if keyword != "task" else tasks[:1])
    for case in CASES
]


@pytest.mark.parametrize("cls,task,keyword,case", GRID)
def test_every_keyword_is_valid_or_refused_by_name(cls, task, keyword, case):
    kwargs = {keyword: CASES[case]} if keyword == "task" else {"task": task, keyword: CASES[case]}
    if not valid(cls, keyword, task, case):
        with pytest.raises((ValueError, TypeError)) as err:
            cls(**kwargs)
        assert keyword in str(err.value), str(err.value)
        return
    env = cls(**kwargs)
    env.reset(seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no numerical failure, no other warning
        for a in (np.zeros, np.ones, lambda s, dtype: -np.ones(s, dtype)):
            _, r, _, _, info = env.step(a(env.action_space.shape, dtype=np.float32))
            assert math.isfinite(r) and info["numerical_failure"] is False
            assert all(
                math.isfinite(v) for v in info.values() if not isinstance(v, str) and v is not None
            ), info


def test_the_grid_covers_every_keyword():
    """Each env's keywords are all in the grid, and the table names no keyword that is gone."""
    covered = {(p.values[0], p.values[2]) for p in GRID}
    assert covered == {(cls, kw) for cls in TASKS for kw in keywords(cls)}
    assert set(VALID) <= covered


# ----------------------------------------------------------------- the named cases
@pytest.mark.parametrize(
    "cls,kwargs,name",
    [
        (TippeTopEnv, dict(free_flight="False"), "free_flight"),  # read as True before
        (TippeTopEnv, dict(friction_action=1), "friction_action"),
        (TippeTopEnv, dict(torque_action="yes"), "torque_action"),
        (LagrangeTopEnv, dict(attitude=0), "attitude"),
        (LagrangeTopEnv, dict(axial_torque="True"), "axial_torque"),
        (FreeRigidBodyEnv, dict(actuated="abc"), "actuated"),  # enabled three axes before
        (FreeRigidBodyEnv, dict(actuated=(1, 0, 0)), "actuated"),
        (FreeRigidBodyEnv, dict(actuated=(True, False)), "actuated"),
        (FreeRigidBodyEnv, dict(task="spin", target_attitude=math.nan), "target_attitude"),
        (LagrangeTopEnv, dict(task="upright", target_tilt="abc"), "target_tilt"),
        (LagrangeTopEnv, dict(task="upright", target_rate=math.inf), "target_rate"),
        (FreeRigidBodyEnv, dict(substeps=10**9), "substeps"),
        (FreeRigidBodyEnv, dict(substeps=MAX_INTERNAL_STEPS + 1), "substeps"),
        (FreeRigidBodyEnv, dict(dt=1e300), "dt"),
        (LagrangeTopEnv, dict(dt=1e300), "dt"),
        (TippeTopEnv, dict(dt=1e300), "dt"),
        (TippeTopEnv, dict(mass=1e300), "mass"),
        (TippeTopEnv, dict(gravity=1e300), "gravity"),
        (TippeTopEnv, dict(gravity=1e300, fidelity="frictionless"), "gravity"),
        (TippeTopEnv, dict(friction=1e300), "friction"),
        (TippeTopEnv, dict(spin=1e300), "spin"),
        (LagrangeTopEnv, dict(length=1e300), "length"),  # an OverflowError before
        (LagrangeTopEnv, dict(gravity=1e300), "gravity"),  # blamed max_angular_velocity before
        (LagrangeTopEnv, dict(spin=1e300), "spin"),
        (
            LagrangeTopEnv,
            dict(com_direction="abc"),
            "com_direction",
        ),  # "could not convert string to float"
        (LagrangeTopEnv, dict(spin_friction=1e300, integrator="rk4"), "spin_friction"),
    ],
)
def test_named_bad_values_are_refused_at_construction(cls, kwargs, name):
    with pytest.raises((ValueError, TypeError)) as err:
        cls(**kwargs)
    assert name in str(err.value)


def test_a_sphere_detumbles():
    """The axis a task does not use is not resolved: equal moments make 'intermediate' ambiguous
    for the spin task only."""
    env = FreeRigidBodyEnv(inertia=(1.0, 1.0, 1.0), task="detumble")
    env.reset(seed=0)
    assert env.step(np.zeros(3, dtype=np.float32))[4]["numerical_failure"] is False
    FreeRigidBodyEnv(inertia=(1.0, 1.0, 1.0), task="reorient")
    with pytest.raises(ValueError, match="axis"):
        FreeRigidBodyEnv(inertia=(1.0, 1.0, 1.0), task="spin")
    with pytest.raises(ValueError, match="axis"):
        FreeRigidBodyEnv(inertia=(1.0, 1.0, 1.0), task="detumble", axis="middle")  # still checked


def test_flags_take_numpy_bools():
    env = TippeTopEnv(free_flight=np.True_, torque_action=np.False_)
    assert env.free_flight is True and env.torque_action is False
    assert FreeRigidBodyEnv(actuated=np.array([True, False, True])).actuated == (True, False, True)


# ----------------------------------------------------------------- actions and reset states
BAD_ACTIONS = {
    "complex": lambda k: np.full(k, 0.5 + 0.5j),
    "complex_list": lambda k: [0.5 + 0.0j] * k,
    "strings": lambda k: ["0.5"] * k,
    "string": lambda k: "abc",
    "dict": lambda k: {"a": 0.5},
    "object": lambda k: object(),
    "object_array": lambda k: np.array([0.5] * (k - 1) + [None], dtype=object),
    "bools": lambda k: np.ones(k, dtype=bool),
}


@pytest.mark.parametrize("cls", list(TASKS))
@pytest.mark.parametrize("kind", list(BAD_ACTIONS))
def test_mistyped_actions_raise_type_error_single_and_vector(cls, kind):
    env = cls()
    env.reset(seed=0)
    before = env.get_state()
    k = env.action_space.shape[0]
    with pytest.raises(TypeError, match="action"):
        env.step(BAD_ACTIONS[kind](k))
    assert all(np.array_equal(before[n], v) for n, v in env.get_state().items())
    venv = gym.make_vec(IDS[cls], num_envs=2, vectorization_mode="vector_entry_point")
    venv.reset(seed=0)
    bad = BAD_ACTIONS[kind](k)
    batch = [bad, bad] if not isinstance(bad, np.ndarray) else np.stack([bad, bad])
    with pytest.raises(TypeError, match="action"):
        venv.step(batch)


@pytest.mark.parametrize("cls", list(TASKS))
def test_integer_actions_are_real_numbers(cls):
    """Integers are real numbers: an int action array is an action (clipped like any other)."""
    env = cls()
    env.reset(seed=0)
    a = np.zeros(env.action_space.shape, dtype=np.int64)
    assert env.step(a)[4]["numerical_failure"] is False


BAD_ENTRIES = {
    "complex": lambda v: v.astype(complex),
    "strings": lambda v: [str(x) for x in v],
    "dict": lambda v: {"x": 1.0},
    "object": lambda v: object(),
}


@pytest.mark.parametrize("cls", list(TASKS))
@pytest.mark.parametrize("kind", list(BAD_ENTRIES))
def test_mistyped_reset_states_raise_type_error_single_and_vector(cls, kind):
    env = cls()
    env.reset(seed=0)
    state = env.get_state()
    name = next(iter(state))
    bad = dict(state, **{name: BAD_ENTRIES[kind](state[name])})
    with pytest.raises(TypeError, match="state"):
        env.reset(options={"state": bad})
    venv = gym.make_vec(IDS[cls], num_envs=2, vectorization_mode="vector_entry_point")
    venv.reset(seed=0)
    vstate = venv.unwrapped.get_state()
    entry = BAD_ENTRIES[kind](vstate[name][0])
    vbad = dict(vstate, **{name: [entry, entry]})
    with pytest.raises(TypeError, match="state"):
        venv.reset(options={"state": vbad})


# ----------------------------------------------------------------- finite info, both checkers
CHECKED_CONFIGS = [
    pytest.param(LagrangeTopEnv, dict(inertia=(0.5, 0.45, 0.3)), id="asymmetric-top"),
    pytest.param(LagrangeTopEnv, dict(com_direction=(0.1, 0.0, 1.0)), id="off-axis-top"),
    pytest.param(
        LagrangeTopEnv,
        dict(inertia=(0.5, 0.45, 0.3), com_direction=(0.3, -0.2, 1.0), spin=(-4.0, 4.0)),
        id="general-top",
    ),
    pytest.param(
        LagrangeTopEnv,
        dict(inertia=(0.5, 0.45, 0.3), integrator="rk4", attitude=True),
        id="asymmetric-top-rk4-attitude",
    ),
    pytest.param(LagrangeTopEnv, dict(task="precess"), id="precess"),
    pytest.param(
        FreeRigidBodyEnv, dict(inertia=(1.0, 1.0, 1.0), task="detumble"), id="sphere-detumble"
    ),
    *[
        pytest.param(
            TippeTopEnv, dict(fidelity=f, free_flight=ff), id=f"tippe-{f}{'-flight' if ff else ''}"
        )
        for f in ("gliding", "frictionless", "rolling")
        for ff in (False, True)
        if not (f == "rolling" and ff)
    ],
]


@pytest.mark.parametrize("cls,kwargs", CHECKED_CONFIGS)
def test_both_checkers_pass_and_info_is_finite(cls, kwargs):
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = cls(**kwargs)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env, skip_render_check=True)
        sb3_check_env(env, warn=True)
    env.action_space.seed(0)
    _, info = env.reset(seed=1)
    for _ in range(30):
        assert all(
            math.isfinite(v) for v in info.values() if not isinstance(v, str) and v is not None
        ), info
        _, _, te, tr, info = env.step(env.action_space.sample())
        if te or tr:
            break


def test_precess_at_tilt_zero_has_a_finite_precession_rate():
    """The axis exactly on the vertical has no azimuth to turn: rate 0 (documented), so the
    reward counts the full rate error and every info value is finite; the checkers pass on the
    env reset there."""
    from gymnasium.utils.env_checker import check_env

    env = LagrangeTopEnv(task="precess")
    env.reset(seed=0)
    spin = 2.0 * env.critical_spin
    upright = {
        "angular_momentum": np.array([0.0, 0.0, 0.3 * spin]),
        "vertical": np.array([0.0, 0.0, 1.0]),
    }
    _, info = env.reset(options={"state": upright})
    assert info["precession_rate"] == 0.0 and info["tilt_error"] == pytest.approx(0.5)
    assert all(math.isfinite(v) for v in info.values() if v is not None)
    _, r, te, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert te and info["terminal_reason"] == "task"  # 0.5 rad from the target: past tilt_limit
    assert math.isfinite(r) and all(
        math.isfinite(v) for k, v in info.items() if k != "terminal_reason" and v is not None
    )
    # the batch computes the same value (0) where sin(tilt) = 0
    y = tuple(np.array([c, c]) for c in (0.0, 0.0, 0.3 * spin, 0.0, 0.0, 1.0))
    assert np.array_equal(env.system.precession_rate(y), [0.0, 0.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env, skip_render_check=True)


@pytest.mark.parametrize(
    "env_id, misspelled, meant",
    [
        ("rbenvs/FreeRigidBody-v0", "integrater", "integrator"),
        ("rbenvs/LagrangeTop-v0", "tilt_limt", "tilt_limit"),
        ("rbenvs/TippeTop-v0", "fidelty", "fidelity"),
    ],
)
def test_a_misspelled_keyword_is_answered_with_the_closest_one(env_id, misspelled, meant):
    """Each env names itself, the closest valid keyword and where the full list is; so does each
    vector env (whose keywords are its own and the single env's)."""
    cls = gym.spec(env_id).entry_point.split(":")[1]
    with pytest.raises(
        TypeError,
        match=(
            rf"{cls} got an unexpected keyword argument '{misspelled}'; "
            rf"did you mean '{meant}'\? \(every keyword: help\(rbenvs.envs.{cls}\)"
        ),
    ):
        gym.make(env_id, **{misspelled: 1})
    with pytest.raises(
        TypeError,
        match=(
            rf"{cls.replace('Env', 'VectorEnv')} got an unexpected keyword argument 'num_thread'; "
            r"did you mean 'num_threads'\?"
        ),
    ):
        gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", num_thread=2)
    with pytest.raises(
        TypeError,
        match=rf"got an unexpected keyword argument '{misspelled}'; did you mean '{meant}'\?",
    ):
        gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", **{misspelled: 1})
    with pytest.raises(
        TypeError, match=r"got an unexpected keyword argument 'zzzz' \(every keyword"
    ):  # (nothing close: no guess)
        gym.make(env_id, zzzz=1)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (
            dict(task="detumbel"),
            "task must be one of .* got 'detumbel'; did you mean 'detumble'\\?",
        ),
        (dict(integrator="RK4"), "integrator must be one of .* got 'RK4'; did you mean 'rk4'\\?"),
        (
            dict(guard="subdivid"),
            "guard must be one of .* got 'subdivid'; did you mean 'subdivide'\\?",
        ),
    ],
)
def test_a_misspelled_choice_is_answered_with_the_closest_one(kwargs, message):
    with pytest.raises(ValueError, match=message):
        FreeRigidBodyEnv(**kwargs)


@pytest.mark.parametrize(
    "cls, kwargs, message",
    [
        (
            FreeRigidBodyEnv,
            dict(control_cost=1e300),
            r"control_cost=1e\+300 makes the least reward of a step .* beyond float32's range",
        ),
        (
            TippeTopEnv,
            dict(observation_noise=1e300),
            r"observation_noise must be at most the observation's bound in every component",
        ),
        (
            LagrangeTopEnv,
            dict(observation_bias=1e300),
            r"observation_bias must be at most the observation's bound in every component",
        ),
        (
            LagrangeTopEnv,
            dict(spin_friction=1e300),
            r"spin_friction must be at most I_chi / dt = 15 N m s",
        ),
        (
            TippeTopEnv,
            dict(slip_regularization=1e300),
            r"slip_regularization must be below max_speed = 5.0 m/s",
        ),
    ],
    ids=[
        "control_cost",
        "observation_noise",
        "observation_bias",
        "spin_friction",
        "slip_regularization",
    ],
)
def test_values_that_would_hide_the_physics_are_refused_with_the_rule(cls, kwargs, message):
    """Rewards beyond float32 (-inf in a replay buffer), noise or bias wider than the
    observation's bounds (observations pinned to them), a pivot friction that stops the spin
    within a step, a slip regularization above every allowed slip speed (friction off)."""
    with pytest.raises(ValueError, match=message):
        cls(**kwargs)


def test_a_keyword_the_options_do_not_use_does_not_veto_the_body():
    """A light tippe top (6 mg, A = 8e-10 kg m^2) without the torque action: max_torque's
    default would change its spin by thousands of rad/s a step, but with torque_action=False it
    acts on nothing, so the body is accepted (the value is still validated for type and
    finiteness); with the torque action it is refused, naming max_torque."""
    light = dict(mass=6e-6, inertia=(8e-10, 7e-10))
    env = TippeTopEnv(**light)
    env.reset(seed=0)
    _, r, _, _, info = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
    assert math.isfinite(r) and info["numerical_failure"] is False
    with pytest.raises(ValueError, match="max_torque"):
        TippeTopEnv(**light, torque_action=True)
    with pytest.raises(ValueError, match="max_torque"):
        TippeTopEnv(**light, max_torque=math.nan)


@pytest.mark.parametrize("cls", list(TASKS))
def test_the_shared_keywords_are_in_every_signature_and_docstring(cls):
    """The keywords every env takes (rbenvs.envs.shared) appear in the signature users see,
    keyword-only, at the env's own default where it names one, and in its docstring."""
    from rbenvs.envs.shared import SHARED_OPTIONS

    params = inspect.signature(cls.__init__).parameters
    for option in SHARED_OPTIONS:
        p = params[option.name]
        assert p.kind is inspect.Parameter.KEYWORD_ONLY
        assert p.default == cls.shared_defaults.get(option.name, option.default)
        assert f"``{option.name}=" in cls.__doc__
    assert "options" not in params

"""The robustness options (rbenvs.envs.options): domain randomization (``param_ranges``), sensor
noise (``observation_noise``, ``observation_bias``) and actuator delay (``action_delay``).

Statistical tests use fixed seeds and bounds at a false-failure rate below 1e-6 for a correct
implementation: a standard normal exceeds 5.3 in magnitude with probability 1.2e-7; a
chi-square with ``nu >= 900`` degrees of freedom leaves ``nu +- 5.3 sqrt(2 nu)`` with
probability below 6e-7 (its skewness ``sqrt(8 / nu)`` moves the 5.3-sigma quantile by at most
``(skewness / 6)(5.3^2 - 1) = 0.42`` sigma, Cornish-Fisher: P(N > 4.88) = 5.3e-7)."""

import math

import gymnasium as gym
import numpy as np
import pytest
from conftest import FREE, LAGRANGE, TIPPE, lockstep, make_vec

from rbenvs.envs import FreeRigidBodyEnv, LagrangeTopEnv, TippeTopEnv
from rbenvs.envs.options import MAX_ACTION_DELAY, NOISE_BLOCK
from rbenvs.oracles.heavy_top import critical_spin

Z = 5.3  # two-sided normal bound: P(|N(0, 1)| > 5.3) = 1.2e-7

# A Lagrange top whose every corner is a real body (the inertia about the centre of mass obeys
# the triangle inequality at I1 = 0.44, M l^2 = 1.05 * 0.51^2, I3 = 0.31) and whose critical
# spin ranges over 8.7-11.3 rad/s across the box.
TOP_RANGES = {
    "inertia": ((0.44, 0.44, 0.29), (0.46, 0.46, 0.31)),
    "mass": (0.95, 1.05),
    "length": (0.49, 0.51),
    "gravity": (9.0, 10.5),
}


def zero(env):
    return np.zeros(env.action_space.shape, dtype=np.float32)


# ----------------------------------------------------------------------------- param_ranges
def test_two_seeds_draw_different_parameters_and_a_seed_the_same():
    env = LagrangeTopEnv(param_ranges=TOP_RANGES)
    a = env.reset(seed=1)[1]["params"]
    b = env.reset(seed=2)[1]["params"]
    c = LagrangeTopEnv(param_ranges=TOP_RANGES).reset(seed=1)[1]["params"]
    assert set(a) == set(TOP_RANGES)
    assert all(np.all(a[k] != b[k]) for k in a)  # continuous draws: equal with probability 0
    assert all(np.array_equal(a[k], c[k]) for k in a)
    # the drawn values are the episode's: the system's parameters and the info's critical spin
    env.reset(seed=1)
    p = env.unwrapped.params
    assert (
        p.inertia == tuple(a["inertia"])
        and p.mass == a["mass"]
        and p.length == a["length"]
        and p.gravity == a["gravity"]
    )


def test_draws_cover_each_range_and_keep_a_symmetric_top_symmetric():
    env = LagrangeTopEnv(param_ranges=dict(TOP_RANGES, spin_friction=(0.0, 0.01)), spin=(5.0, 16.0))
    draws = [env.reset(seed=s)[1]["params"] for s in range(400)]
    for name, (lo, hi) in dict(TOP_RANGES, spin_friction=(0.0, 0.01)).items():
        v = np.array([d[name] for d in draws])
        lo, hi = np.asarray(lo), np.asarray(hi)
        assert np.all(v >= lo) and np.all(v < hi), name
        # U(lo, hi): 400 draws leave no gap of 5 % of the range at either end (P = 2 (0.95)^400 <
        # 1e-8)
        width = hi - lo
        assert np.all(v.min(axis=0) < lo + 0.05 * width + (width == 0)) and np.all(
            v.max(axis=0) > hi - 0.05 * width
        ), name
    inertia = np.array([d["inertia"] for d in draws])
    assert np.array_equal(inertia[:, 0], inertia[:, 1])  # I1 = I2 share one draw: a Lagrange top
    assert not np.array_equal(inertia[:, 0] - 0.44, (inertia[:, 2] - 0.29))  # I3 drawn on its own


def test_relative_spread_bounds_every_component():
    env = FreeRigidBodyEnv(param_ranges={"inertia": 0.1, "max_torque": 0.5})
    for s in range(50):
        p = env.reset(seed=s)[1]["params"]
        assert np.all(np.abs(p["inertia"] / np.array([2.0, 1.5, 1.0]) - 1.0) <= 0.1 + 1e-15)
        assert abs(p["max_torque"] / 0.2 - 1.0) <= 0.5 + 1e-15
        assert env.unwrapped.actuator.max_torque == p["max_torque"]


def test_default_is_the_constructors_parameters():
    """Without param_ranges nothing is drawn for parameters: the same starts as before, no
    ``params`` key."""
    obs, info = LagrangeTopEnv().reset(seed=5)
    assert "params" not in info
    ref = LagrangeTopEnv(param_ranges={"mass": (1.0, 1.0)})  # a range of one point draws one number
    o2, info2 = ref.reset(seed=5)
    assert info2["params"] == {"mass": 1.0}
    assert not np.array_equal(o2, obs)  # (the draw came first: the start's numbers moved on)


def test_zero_action_keeps_a_top_up_exactly_above_its_drawn_critical_spin():
    """The heavy top stability theorem [MR 15.10.1], per episode: the critical spin
    2 sqrt(M g l I1) / I3 of the drawn parameters (checked against rbenvs.oracles) decides
    whether the uncontrolled top stays within tilt_limit = pi/4 for the 10 s episode.

    Episodes within 10 % of the threshold are left out: at spin f * critical with f <= 0.9 the
    released top's turning point (cos = 2 f^2 - 1 from near upright) is >= 0.90 rad > pi/4 and
    the tilt grows at sqrt(M g l / I1 (1 - f^2)) >= 1.9 1/s, so a top falls within 10 s unless
    its initial tilt U(0, 0.05) is below 1e-9 (probability 2e-8); at f >= 1.1 it nods below
    0.2 rad (tests/test_lagrange_top_env.py)."""
    env = gym.make(LAGRANGE, param_ranges=TOP_RANGES, spin=(5.0, 16.0))
    outcomes = []
    for seed in range(30):
        obs, info = env.reset(seed=seed)
        p = info["params"]
        crit = critical_spin(p["inertia"][0], p["inertia"][2], p["mass"], p["length"], p["gravity"])
        assert (
            info["critical_spin"] == pytest.approx(crit, rel=1e-14)
            and env.unwrapped.critical_spin == info["critical_spin"]
        )
        spin = info["spin"]
        k, te, tr = 0, False, False
        while not (te or tr):
            _, _, te, tr, step_info = env.step(zero(env))
            k += 1
        if abs(spin / crit - 1.0) < 0.1:
            continue
        stayed = tr and not te and k == 500
        assert stayed == (spin > crit), (seed, spin, crit, k, step_info.get("terminal_reason"))
        outcomes.append(stayed)
    # both sides of the threshold were tested, with parameters that differ per episode
    assert sum(outcomes) >= 5 and len(outcomes) - sum(outcomes) >= 5


def test_the_tippe_tops_jellett_integral_follows_its_drawn_parameters():
    """Upright at the start (tilt 0): Jellett's integral is R C spin (1 - alpha) [T 3.106] of
    the episode's drawn radius, axial moment and offset (rbenvs.oracles), not the keywords'."""
    from rbenvs.oracles.tippe_top import jellett_upright

    env = TippeTopEnv(
        param_ranges={"radius": 0.1, "offset": (0.15, 0.25), "inertia": 0.05},
        tilt=0.0,
        spin=150.0,
        compiled=False,
    )
    values = set()
    for seed in range(5):
        info = env.reset(seed=seed)[1]
        p = info["params"]
        want = jellett_upright(p["inertia"][1], p["radius"], p["offset"], 150.0)
        assert info["jellett"] == pytest.approx(want, rel=1e-12)
        values.add(info["jellett"])
    assert len(values) == 5


@pytest.mark.parametrize(
    "cls,ranges,match",
    [
        (LagrangeTopEnv, [("mass", 1.0)], "param_ranges must be None or a dict"),
        (LagrangeTopEnv, {"dt": 0.1}, "param_ranges keys must be among"),
        (LagrangeTopEnv, {}, "at least one"),
        (
            LagrangeTopEnv,
            {"mass": 1.0},
            r"param_ranges\['mass'\]: a relative spread must lie in \[0, 1\)",
        ),
        (LagrangeTopEnv, {"mass": -0.1}, "relative spread"),
        (LagrangeTopEnv, {"mass": (2.0, 1.0)}, "lo <= hi"),
        (LagrangeTopEnv, {"mass": (math.nan, 1.0)}, "finite"),
        (LagrangeTopEnv, {"mass": "abc"}, r"param_ranges\['mass'\]"),
        (
            LagrangeTopEnv,
            {"inertia": (0.4, 0.5)},
            r"param_ranges\['inertia'\]: lo must be a vector of 3 numbers",
        ),
        (LagrangeTopEnv, {"mass": (-1.0, 1.0)}, "mass must be finite and > 0"),  # positive masses
        # the inertia about the centre of mass must be a body's at the corner I1 = 0.4, M = 1.2
        (
            LagrangeTopEnv,
            {"mass": 0.2, "inertia": ((0.4, 0.4, 0.28), (0.5, 0.5, 0.32))},
            "triangle inequality",
        ),
        (
            FreeRigidBodyEnv,
            {"inertia": ((2.0, 1.5, 1.0), (2.0, 1.5, 3.6))},
            "triangle inequality I1 \\+ I2 >= I3",
        ),
        # the named intermediate axis changes inside the box: the structure changes
        (FreeRigidBodyEnv, {"inertia": ((2.0, 1.5, 1.0), (2.0, 2.5, 1.0))}, "structure changes"),
        (TippeTopEnv, {"inertia": ((8e-7, 7e-7), (8e-7, 2e-6))}, "C <= 2 A"),
        (TippeTopEnv, {"offset": (0.5, 1.0)}, "offset"),
        (
            FreeRigidBodyEnv,
            {"max_torque": (0.0, 1e6)},
            "max_torque is too large",
        ),  # the actuator's authority
    ],
)
def test_invalid_ranges_are_refused_at_construction(cls, ranges, match):
    with pytest.raises((ValueError, TypeError), match=match) as err:
        cls(param_ranges=ranges)
    assert "param_ranges" in str(err.value)


def test_compiled_true_is_refused_with_param_ranges():
    with pytest.raises(ValueError, match="compiled=True cannot be had with param_ranges"):
        FreeRigidBodyEnv(param_ranges={"inertia": 0.1}, compiled=True)
    with pytest.raises(ValueError, match="compiled=True cannot be had with param_ranges"):
        make_vec(FREE, 2, param_ranges={"inertia": 0.1}, compiled=True)
    venv = make_vec(FREE, 2, param_ranges={"inertia": 0.1})  # "auto": the float path per sub-env
    assert venv.unwrapped.compiled is False
    env = FreeRigidBodyEnv(param_ranges={"inertia": 0.1})
    env.reset(seed=0)
    env.step(zero(env))
    assert env.compiled is False


# ----------------------------------------------------------------------------- observation noise
def noise_samples(env, steps, seed=0):
    """``(noisy - noiseless)`` per observation of one long episode (float64), and the noiseless."""
    obs, _ = env.reset(seed=seed)
    dev, clean = (
        [obs.astype(np.float64) - env.unwrapped.noiseless_observation],
        [env.unwrapped.noiseless_observation],
    )
    for _ in range(steps):
        obs, _, te, tr, _ = env.step(zero(env))
        assert not (te or tr)
        dev.append(obs.astype(np.float64) - env.unwrapped.noiseless_observation)
        clean.append(env.unwrapped.noiseless_observation)
    return np.array(dev), np.array(clean)


def test_observation_noise_has_the_stated_standard_deviation():
    """Per-component standard deviations (rad/s) on the free body's spin (observations of
    order 1, far inside the +-10 bound: no clipping). Over nu = 3 x 2001 normalised deviations
    z: sum z^2 is chi-square(nu) (bound nu +- 5.3 sqrt(2 nu): the standard deviation within
    4.8 %), mean and lag-one correlation within 5.3 / sqrt(nu) of zero (independent, centred).
    The float32 observation rounds by at most 6e-8 of |obs| <= 1.1: 1e-5 of the smallest std."""
    std = np.array([0.01, 0.05, 0.2])
    env = FreeRigidBodyEnv(observation_noise=std, compiled=False)
    dev, clean = noise_samples(env, 2000)
    assert np.abs(clean).max() + Z * std.max() < 10.0  # never clipped
    z = dev / std
    nu = z.size
    assert abs(np.sum(z * z) - nu) < Z * math.sqrt(2 * nu)
    assert abs(z.mean()) < Z / math.sqrt(nu)
    lag = np.sum(z[1:] * z[:-1])
    assert abs(lag) < Z * math.sqrt(z[1:].size)
    for j in range(3):  # each component its own std (chi-square(2001): within 17 %)
        m = z[:, j].size
        assert abs(np.sum(z[:, j] ** 2) - m) < Z * math.sqrt(2 * m), j


def test_observation_bias_is_constant_per_episode_with_the_stated_spread():
    """``observation_bias=b``: the deviation's mean over an episode is the episode's bias
    (its noise averages out: the spread within an episode is the noise's); over 300 episodes
    the means m (noise 0.01, 50 steps: variance b^2 + 0.01^2 / 51) give
    sum m^2 / (b^2 + 0.01^2 / 51) ~ chi-square(3 x 300)."""
    b, s = 0.05, 0.01
    env = FreeRigidBodyEnv(observation_noise=s, observation_bias=b, compiled=False)
    means = []
    for seed in range(300):
        dev, _ = noise_samples(env, 50, seed=seed)
        means.append(dev.mean(axis=0))
        z = (dev - dev.mean(axis=0)) / s  # within the episode: the noise alone (45900 values
        assert np.all(np.abs(z) < 7.0)  # in all: P(some |N(0, 1)| > 7) = 45900 x 2.6e-12 = 1.2e-7)
    m = np.array(means)
    nu, var = m.size, b * b + s * s / 51
    assert abs(np.sum(m * m) / var - nu) < Z * math.sqrt(2 * nu)


def test_noise_never_reaches_the_physics_or_the_reward():
    """The same seed and actions with and without noise: the states, rewards and info agree bit
    for bit within the episode (the noise stream's key is drawn after the start)."""
    quiet, noisy = (
        LagrangeTopEnv(compiled=False),
        LagrangeTopEnv(observation_noise=0.3, observation_bias=0.1, compiled=False),
    )
    o1, i1 = quiet.reset(seed=4)
    o2, i2 = noisy.reset(seed=4)
    assert (
        i1 == i2 and np.array_equal(o1, noisy.noiseless_observation) and not np.array_equal(o1, o2)
    )
    rng = np.random.default_rng(0)
    for _ in range(100):
        a = rng.uniform(-1, 1, 2).astype(np.float32)
        r1 = quiet.step(a)
        r2 = noisy.step(a)
        assert quiet.state_components == noisy.state_components
        assert r1[1:] == r2[1:] and np.array_equal(r1[0], noisy.noiseless_observation)


def test_noisy_observations_stay_in_the_observation_space():
    env = gym.make(
        LAGRANGE, observation_noise=0.5, compiled=False
    )  # Gamma's components are bound by 1: clipped there
    obs, _ = env.reset(seed=0)
    for _ in range(20):
        assert env.observation_space.contains(obs)
        obs = env.step(zero(env))[0]
    assert np.max(np.abs(obs[:3])) == 1.0


# ----------------------------------------------------------------------------- action delay
@pytest.mark.parametrize("k", [1, 3])
def test_an_action_first_acts_k_periods_later(k):
    """A torque impulse at step 0, zeros after: with ``action_delay=k`` the trajectory is the
    zero-action one for steps 0..k-1 and leaves it at step k exactly; in general the delayed
    env equals the undelayed one fed ``k`` zero actions first, bit for bit."""
    rng = np.random.default_rng(1)
    actions = [np.ones(2, dtype=np.float32)] + [np.zeros(2, dtype=np.float32)] * 10
    delayed, free, ref = (
        LagrangeTopEnv(action_delay=k, compiled=False),
        LagrangeTopEnv(compiled=False),
        LagrangeTopEnv(compiled=False),
    )
    delayed.reset(seed=0)
    free.reset(seed=0)
    for t, a in enumerate(actions):
        delayed.step(a)
        free.step(np.zeros(2, dtype=np.float32))
        assert (delayed.state_components == free.state_components) == (t < k), t
    actions = rng.uniform(-1.5, 1.5, (60, 2)).astype(np.float32)
    delayed.reset(seed=3)
    ref.reset(seed=3)
    fed = [np.zeros(2, dtype=np.float32)] * k + list(actions)
    for t in range(60):
        o1, r1, te1, tr1, i1 = delayed.step(actions[t])
        o2, r2, te2, tr2, i2 = ref.step(fed[t])
        assert np.array_equal(o1, o2) and r1 == r2 and te1 == te2 and i1 == i2, t
        if te1:
            break


def test_a_reset_empties_the_queue():
    env = LagrangeTopEnv(action_delay=2, compiled=False)
    env.reset(seed=0)
    env.step(np.ones(2, dtype=np.float32))
    env.step(np.ones(2, dtype=np.float32))
    env.reset(seed=0)
    ref = LagrangeTopEnv(compiled=False)
    ref.reset(seed=0)
    env.step(np.ones(2, dtype=np.float32))
    ref.step(np.zeros(2, dtype=np.float32))
    assert env.state_components == ref.state_components


def test_a_delayed_action_is_still_checked_at_once():
    env = LagrangeTopEnv(action_delay=2)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([np.nan, 0.0], dtype=np.float32))


@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(observation_noise=-0.1), "observation_noise must be finite and >= 0"),
        (dict(observation_noise=math.nan), "observation_noise"),
        (dict(observation_noise=(0.1, 0.1)), "observation_noise must be a number or 6 numbers"),
        (dict(observation_noise="0.1"), "observation_noise"),
        (dict(observation_bias=-1.0), "observation_bias must be finite and >= 0"),
        (dict(action_delay=-1), "action_delay must be an integer"),
        (dict(action_delay=1.5), "action_delay must be an integer"),
        (dict(action_delay=True), "action_delay"),
        (dict(action_delay=MAX_ACTION_DELAY + 1), "action_delay must be an integer in"),
    ],
)
def test_invalid_noise_and_delay_are_refused(kwargs, match):
    with pytest.raises((ValueError, TypeError), match=match):
        LagrangeTopEnv(**kwargs)


# ----------------------------------------------------------------------------- vector envs
ALL_OPTIONS = {
    FREE: dict(
        param_ranges={"inertia": 0.1, "max_torque": 0.5},
        observation_noise=(0.01, 0.05, 0.1),
        observation_bias=0.01,
        action_delay=2,
    ),
    LAGRANGE: dict(
        param_ranges=TOP_RANGES,
        spin=(5.0, 16.0),
        observation_noise=0.02,
        observation_bias=0.01,
        action_delay=1,
    ),
    TIPPE: dict(
        param_ranges={"radius": 0.1, "friction": (0.2, 0.4), "inertia": 0.05},
        observation_noise=0.5,
        action_delay=3,
    ),
}


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
@pytest.mark.parametrize("env_id", [FREE, LAGRANGE, TIPPE])
def test_vector_sub_env_i_is_the_single_env_seeded_s_plus_i_with_every_option(env_id, mode):
    """Episodes longer than a noise block (NOISE_BLOCK observations) and shorter ones: each
    sub-env's parameters, starts, noise and queue are the single env's, bit for bit."""
    steps, max_steps = (90, 70) if env_id != TIPPE else (40, 15)
    assert env_id == TIPPE or max_steps > NOISE_BLOCK
    n_term, n_trunc, infos = lockstep(
        env_id, 3, 7, steps, mode, max_steps, ALL_OPTIONS[env_id], action_scale=1.5
    )
    assert n_term + n_trunc > 0  # episodes ended and new ones (new parameters, new streams) began
    assert infos[0]["_params"].all() and set(infos[0]["params"]) >= set(
        ALL_OPTIONS[env_id]["param_ranges"]
    )


@pytest.mark.parametrize("env_id,compiled", [(FREE, False), (LAGRANGE, False), (LAGRANGE, "auto")])
def test_vector_noise_and_delay_on_the_batched_paths(env_id, compiled):
    """Without param_ranges the batch keeps its batched step (numpy, or the whole step compiled:
    the options act on its actions and observations) and draws its noise in blocks: still bit
    for bit the single env."""
    kwargs = {k: v for k, v in ALL_OPTIONS[env_id].items() if k != "param_ranges"}
    lockstep(env_id, 3, 11, 90, "NextStep", 70, kwargs, vector_kwargs={"compiled": compiled})


def test_vector_noise_without_numba_draws_blocks(monkeypatch):
    """Without numba (RBENVS_COMPILED=0) each sub-env draws its noise in blocks of NOISE_BLOCK
    observations; episodes longer than a block refill it: still the single env's numbers."""
    monkeypatch.setenv("RBENVS_COMPILED", "0")
    kwargs = dict(observation_noise=(0.01, 0.05, 0.1), observation_bias=0.01, action_delay=2)
    venv = make_vec(FREE, 2, **kwargs)
    assert venv.unwrapped._realism_batch.table is None and not venv.unwrapped.compiled
    lockstep(FREE, 3, 5, 2 * NOISE_BLOCK + 20, "SameStep", NOISE_BLOCK + 30, kwargs)


def test_a_scene_file_carries_the_options_and_evaluation_holds_parameters_out(tmp_path):
    """A scene (YAML, as rbenvs-train and rbenvs-eval take) with every option; evaluation on
    parameters outside the training ranges through ``env_overrides``: the analytic controller,
    built from the keywords' (nominal) parameters, still holds the randomized tops up."""
    from rbenvs.scenes import load_scene
    from rbenvs_agents.evaluate import analytic_policy, evaluate

    path = tmp_path / "top_robust.yml"
    path.write_text(
        "id: rbenvs/LagrangeTop-v0\n"
        "kwargs:\n"
        "  task: upright\n"
        "  spin: [0.0, 9.5]\n"
        "  param_ranges: {mass: 0.05, inertia: [[0.44, 0.44, 0.29], [0.46, 0.46, 0.31]]}\n"
        "  observation_noise: 0.002\n"
        "  action_delay: 1\n"
    )
    scene = load_scene(str(path))
    env = scene.make()
    assert (
        env.unwrapped.param_ranges.names == ("inertia", "mass") and env.unwrapped.realism.delay == 1
    )
    held_out = {"param_ranges": {"mass": (1.06, 1.1), "length": (0.51, 0.52)}}
    result = evaluate(analytic_policy, scene, episodes=3, seed=0, env_overrides=held_out)
    assert result.success_rate == 1.0 and result.lengths == (500, 500, 500)


# (a tolerance on the intermediate-axis scene: its UnstableMotionWarning is expected, and asserted
# where it is the subject, tests/test_tolerance.py)
UNSTABLE_MOTION = pytest.mark.filterwarnings(
    "ignore::rbenvs.stepsize.controller.UnstableMotionWarning"
)


@UNSTABLE_MOTION
@pytest.mark.parametrize("compiled", [False, "auto"])
def test_tolerance_with_noise_and_delay_keeps_the_lockstep_and_its_estimate(compiled):
    """tolerance= (its internal steps and info["error_estimate"]) beside action_delay and
    observation noise: the estimate is of the period that ran, under the delayed action that
    acted, in the vector env as in the single env, bit for bit."""
    kwargs = dict(
        integrator="rk4",
        tolerance=1e-6,
        observation_noise=0.01,
        action_delay=2,
        spin_rate=20.0,
        max_angular_velocity=100.0,
    )
    _, _, infos = lockstep(
        FREE, 3, 5, 40, "NextStep", 30, kwargs, vector_kwargs={"compiled": compiled}
    )
    assert all("error_estimate" in info for info in infos)
    assert max(float(np.max(info["error_estimate"])) for info in infos) > 0.0


@UNSTABLE_MOTION
@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
@pytest.mark.parametrize(
    "env_id,extra",
    [
        (FREE, {}),
        (FREE, {"tolerance_check": True}),
        (LAGRANGE, {"tolerance_check": True}),
        (TIPPE, {}),
    ],
    ids=["free_body", "free_body-check", "top-check", "tippe"],
)
def test_tolerance_with_param_ranges_steps_each_sub_env_as_its_single_env(env_id, extra, mode):
    """tolerance= with param_ranges in the vector env: each sub-env's period is estimated (and,
    with tolerance_check, checked by its own companion) on its episode's drawn model, as its
    single env's is: every info key (the estimates, the drawn parameters) bit for bit, through
    episode ends and restarts with new parameters."""
    ranges = {
        FREE: {"inertia": 0.1},
        LAGRANGE: {"mass": 0.05},
        TIPPE: {"radius": 0.1, "friction": (0.2, 0.4)},
    }[env_id]
    kwargs = dict(integrator="rk4", tolerance=1e-6, param_ranges=ranges, **extra)
    if env_id == LAGRANGE:
        kwargs["spin"] = (5.0, 16.0)
    steps, max_steps = (40, 15) if env_id != TIPPE else (12, 5)
    n_term, n_trunc, infos = lockstep(
        env_id, 3, 7, steps, mode, max_steps, kwargs, action_scale=1.5
    )
    assert n_term + n_trunc >= 3  # episodes ended and new ones (new parameters) began
    assert max(float(np.max(info["error_estimate"])) for info in infos) > 0.0
    if extra:
        assert max(float(np.max(info["global_error_estimate"])) for info in infos) > 0.0

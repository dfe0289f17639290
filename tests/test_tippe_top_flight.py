"""Free flight of the tippe top (``free_flight=True``): hops, touchdowns and the impact law.

Oracles: the plastic impact against an independent mobility-matrix computation (energy loss
``lambda^2 M_zz / 2``, Jellett unchanged); ballistic flight against ``z0 + v t - g t^2 / 2``
with a torque-free symmetric rotation; long fast runs that never gain energy and keep
Jellett's integral to the integrator's accuracy (4th order through the hops); the hopping model
against the contact-only model up to its first lift-off; vector env against single env.
"""

import math

import gymnasium as gym
import numpy as np
import pytest
from conftest import rotation  # the body-to-space matrix, the tests' own formula

import rbenvs  # noqa: F401  (registers the ids)
from rbenvs.dynamics import TippeTop, TippeTopParams
from rbenvs.dynamics.tippe_top import TOUCHDOWN_TOL
from rbenvs.envs import TippeTopEnv

ZERO = np.zeros(2, dtype=np.float32)

# The hops these tests exercise come from the rolling start (the contact point at rest, so the
# centre of mass moves at about R n sin(theta)); they were measured with the stability bound's
# steps (the order test counts substeps against it). The defaults (start="rest",
# friction_bound="accuracy") have their own tests (tests/test_tippe_starts.py, test_tippe_stiff.py).
ROLLING = dict(start="rolling", friction_bound="stability")


def run(env, steps, seed=1):
    """Zero-action run from a seeded reset: lists of infos (reset included) and observations."""
    obs, info = env.reset(seed=seed)
    infos, observations = run_from_state(env, steps)
    return [info] + infos, [obs] + observations


def run_from_state(env, steps):
    """Zero-action run from the env's current state (no reset)."""
    infos, observations = [], []
    for _ in range(steps):
        obs, _, terminated, truncated, info = env.step(ZERO)
        infos.append(info)
        observations.append(obs)
        if terminated or truncated:
            break
    return infos, observations


# ---------------------------------------------------------------------------- the impact law
def random_touchdown(system, rng):
    """A state in flight with the sphere at the table and its contact point moving down."""
    prm = system.params
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w = rng.normal(size=3) * np.array([20.0, 20.0, 300.0])
    v = rng.normal(size=3) * 0.2
    y = (0.0, 0.0, 0.0) + tuple(v) + tuple(q) + tuple(w) + (0.0, 0.0)
    rm = rotation(q)
    z = prm.radius - prm.height * rm[2, 2]  # gap = 0
    y = y[:2] + (z,) + y[3:]
    if system.gap_rate(y) >= 0.0:  # make it approach: v_z below the constraint's
        y = y[:5] + (y[5] - 2.0 * system.gap_rate(y) - 0.05,) + y[6:]
    return y


def test_impact_is_plastic_dissipative_and_keeps_jellett():
    system = TippeTop(TippeTopParams(), "gliding", flight=True)
    prm = system.params
    big_a, big_c = prm.inertia
    inertia = np.diag([big_a, big_a, big_c])
    rng = np.random.default_rng(0)
    for _ in range(25):
        y = random_touchdown(system, rng)
        assert system.gap(y) == pytest.approx(0.0, abs=1e-17) and system.gap_rate(y) < 0.0
        after, lam = system.impact(y)
        # independent: space-frame mobility of the contact point along z
        R = rotation(y[6:10])
        k, zhat = R[:, 2], np.array([0.0, 0.0, 1.0])
        r = prm.height * k - prm.radius * zhat  # P - G
        i_space_inv = R @ np.linalg.inv(inertia) @ R.T
        rxz = np.cross(r, zhat)
        m_zz = 1.0 / prm.mass + rxz @ i_space_inv @ rxz
        w_space = R @ np.array(y[10:13])
        v_pz = y[5] + np.cross(w_space, r)[2]
        assert lam == pytest.approx(-v_pz / m_zz, rel=1e-12)
        assert lam > 0.0
        # plastic: the contact point stops moving vertically; the state is on the table
        w_after = R @ np.array(after[10:13])
        assert after[5] + np.cross(w_after, r)[2] == pytest.approx(
            0.0, abs=1e-15 * (1.0 + abs(v_pz))
        )
        assert after[13] == 1.0 and system.gap(after) == pytest.approx(0.0, abs=1e-17)
        # horizontal velocity untouched (frictionless impact), vertical by lambda / m
        assert after[3:5] == y[3:5]
        assert after[5] == pytest.approx(y[5] + lam / prm.mass, rel=1e-14)
        # energy drops by lambda^2 M_zz / 2 (checked to the cancellation of E_before - E_after)
        e0, e1 = system.energy(y), system.energy(after)
        assert e1 < e0
        assert e0 - e1 == pytest.approx(0.5 * lam * lam * m_zz, rel=1e-8)
        # Jellett's integral: an impulse at the contact point has no moment about r
        assert system.jellett(after) == pytest.approx(system.jellett(y), rel=1e-14)


def test_impact_of_a_separating_state_gives_no_impulse():
    system = TippeTop(TippeTopParams(), "gliding", flight=True)
    y = random_touchdown(system, np.random.default_rng(1))
    leaving = y[:5] + (y[5] - 2.0 * system.gap_rate(y),) + y[6:]  # contact point moving up
    assert system.gap_rate(leaving) > 0.0
    after, lam = system.impact(leaving)
    assert lam == 0.0 and after[10:13] == leaving[10:13]


# ---------------------------------------------------------------------------- flight itself
@pytest.mark.parametrize("fidelity", ["gliding", "frictionless"])
def test_flight_is_ballistic_and_torque_free(fidelity):
    env = TippeTopEnv(free_flight=True, fidelity=fidelity, spin=200.0, tilt=0.3)
    env.reset(seed=0)
    state = env.get_state()
    z0, vz0 = state["position"][2] + 0.05, 0.4
    state["position"][2] = z0
    state["velocity"][2] = vz0
    _, info = env.reset(options={"state": state})
    assert info["airborne"] is True and info["normal_force"] == 0.0
    assert info["gap"] == pytest.approx(0.05, rel=1e-12)
    prm = env.params
    inertia = np.array([*prm.inertia[:1] * 2, prm.inertia[1]])
    s0 = env.get_state()
    L0 = rotation(s0["attitude"]) @ (inertia * s0["angular_velocity"])
    e0, j0 = info["energy"], info["jellett"]
    g = prm.gravity
    for n in range(1, 11):  # 0.1 s: still in the air (lands after about 0.13 s)
        _, _, terminated, _, info = env.step(ZERO)
        assert not terminated and info["airborne"] is True and info["hops"] == 0
        s = env.get_state()
        t = n * env.dt
        # RK4 integrates a quadratic in t exactly: the parabola to round-off
        assert s["position"][2] == pytest.approx(z0 + vz0 * t - 0.5 * g * t * t, abs=1e-15)
        np.testing.assert_allclose(
            s["position"][:2], s0["position"][:2] + s0["velocity"][:2] * t, atol=1e-15
        )
        np.testing.assert_array_equal(s["velocity"][:2], s0["velocity"][:2])
        assert s["angular_velocity"][2] == s0["angular_velocity"][2]  # symmetric, torque-free
        L = rotation(s["attitude"]) @ (inertia * s["angular_velocity"])
        np.testing.assert_allclose(L, L0, rtol=0, atol=1e-10 * np.linalg.norm(L0))
        assert info["energy"] == pytest.approx(e0, rel=1e-10)
        assert info["jellett"] == pytest.approx(j0, rel=1e-10)


@pytest.mark.parametrize("integrator", ["rk4", "dop853"])
def test_a_dropped_top_lands_plastically_and_stays_on_the_table(integrator):
    env = TippeTopEnv(
        free_flight=True, fidelity="frictionless", spin=200.0, tilt=0.3, integrator=integrator
    )
    env.reset(seed=0)
    state = env.get_state()
    state["position"][2] += 0.01
    _, info = env.reset(options={"state": state})
    e_drop, j0 = info["energy"], info["jellett"]
    infos, _ = run_from_state(env, 20)
    landed = [i for i in infos if not i["airborne"]]
    assert landed, "the top must land within 0.2 s (free fall of 1 cm takes 45 ms)"
    # the landing dissipates; after it the frictionless contact conserves the energy
    assert landed[0]["energy"] < e_drop
    assert all(i["gap"] >= -TOUCHDOWN_TOL * env.params.radius for i in infos)
    assert all(abs(i["jellett"] - j0) <= 1e-9 * abs(j0) for i in infos)
    after = [i["energy"] for i in infos[infos.index(landed[0]) :] if not i["airborne"]]
    assert max(after) - min(after) <= 1e-9 * after[0]


# ---------------------------------------------------------------------------- long fast runs
@pytest.mark.parametrize(
    "spin, friction, tilt, steps, min_hops",
    [
        (
            180.0,
            0.3,
            0.1,
            900,
            1,
        ),  # docs/physics.md's Leine-Glocker scene: hops near 80 deg, inverts
        (1000.0, 1.0, 0.01, 300, 10),
        (2000.0, 0.3, 0.1, 200, 100),
        (5000.0, 1.0, 0.1, 150, 100),
    ],
)
def test_fast_tops_hop_without_nan_penetration_or_energy_gain(
    spin, friction, tilt, steps, min_hops
):
    """The issue's must-show, with hops modelled: thousands of rad/s, mu up to 1, default dt."""
    env = TippeTopEnv(
        spin=spin,
        friction=friction,
        tilt=tilt,
        free_flight=True,
        max_speed=max(5.0, 0.02 * spin),
        **ROLLING,
    )
    infos, observations = run(env, steps)
    assert all(np.all(np.isfinite(o)) for o in observations)
    assert not any(i["numerical_failure"] for i in infos)
    assert infos[-1]["hops"] >= min_hops  # flight is exercised
    energy = np.array([i["energy"] for i in infos])
    # never a gain: each control period ends with no more energy than it began with, up to the
    # round-off of E itself summed over its internal steps (< 1e-13 E)
    assert np.max(np.diff(energy)) <= 1e-13 * energy[0]
    jellett = np.array([i["jellett"] for i in infos])
    assert np.max(np.abs(jellett - jellett[0])) <= 1e-7 * abs(jellett[0])  # rk4 at this step
    assert min(i["gap"] for i in infos) >= -TOUCHDOWN_TOL * env.params.radius
    if spin == 180.0:
        assert infos[-1]["tilt"] > math.radians(150.0) and infos[-1]["is_success"]


def test_jellett_error_through_hops_converges_at_fourth_order():
    drifts, steps = [], []
    for substeps in (1, 1000, 2000):  # the automatic rule asks for 534 at this spin and friction
        env = TippeTopEnv(
            spin=2000.0,
            friction=1.0,
            tilt=0.1,
            free_flight=True,
            substeps=substeps,
            max_speed=40.0,
            **ROLLING,
        )
        infos, _ = run(env, 40)
        assert infos[-1]["hops"] >= 50
        drifts.append(abs(infos[-1]["jellett"] - infos[0]["jellett"]))
        steps.append(infos[-1]["internal_step"])
    orders = [
        math.log(drifts[i] / drifts[i + 1]) / math.log(steps[i] / steps[i + 1]) for i in range(2)
    ]
    assert min(orders) > 3.5, orders


def test_hopping_model_follows_the_contact_model_until_its_lift_off():
    """Before its first lift-off the hopping model is the contact model, rounded differently
    (its state carries z and v_z): the two differ by no more than the contact model differs
    from itself when its initial spin is changed by 4 ulp (a round-off-seeded reference, since
    the rising top amplifies round-off)."""
    kwargs = dict(spin=1000.0, friction=1.0, tilt=0.01, max_speed=40.0, **ROLLING)
    plain, flying, nudged = (
        TippeTopEnv(**kwargs),
        TippeTopEnv(free_flight=True, **kwargs),
        TippeTopEnv(**kwargs),
    )
    plain.reset(seed=1)
    flying.reset(seed=1)
    state = plain.get_state()
    eps = np.finfo(float).eps
    state["angular_velocity"] *= 1.0 + 4.0 * eps
    state["velocity"][2] *= 1.0 + 4.0 * eps  # the constraint's v_z, linear in the spin
    nudged.reset(options={"state": state})
    keys = ("energy", "jellett", "tilt", "normal_force", "slip_speed")
    spread = dict.fromkeys(keys, 0.0)
    for k in range(300):
        a, b, c = plain.step(ZERO), flying.step(ZERO), nudged.step(ZERO)
        if a[2]:
            break
        for key in keys:
            ref = a[4][key]
            spread[key] = max(spread[key], abs(c[4][key] - ref))
            assert abs(b[4][key] - ref) <= 2.0 * spread[key] + 16.0 * eps * abs(ref), (k, key)
    # the contact-only model ends with lift-off; the hopping one lifts off in the same period
    assert a[2] and a[4]["lifted_off"] and a[4].get("terminal_reason") == "lift_off"
    assert b[4]["hops"] == 1 and not b[2]
    assert k > 50  # a real stretch of shared motion was compared


# ---------------------------------------------------------------------------- API
def test_vector_env_matches_single_envs_through_hops():
    kwargs = dict(
        spin=2000.0, friction=0.3, tilt=(0.01, 0.1), free_flight=True, max_speed=40.0, **ROLLING
    )
    venv = gym.make_vec(
        "rbenvs/TippeTop-v0", num_envs=3, vectorization_mode="vector_entry_point", **kwargs
    )
    singles = [TippeTopEnv(**kwargs) for _ in range(3)]
    venv.reset(seed=5)
    for i, env in enumerate(singles):
        env.reset(seed=5 + i)
    rng = np.random.default_rng(0)
    for _ in range(25):
        actions = rng.uniform(-1, 1, size=(3, 2)).astype(np.float32)
        obs, rew, term, trunc, info = venv.step(actions)
        for i, env in enumerate(singles):
            o, r, t, _, inf = env.step(actions[i])
            np.testing.assert_array_equal(obs[i], o)
            assert rew[i] == r and term[i] == t
            assert info["hops"][i] == inf["hops"] and info["airborne"][i] == inf["airborne"]
    batched = venv.unwrapped.get_state()
    for i, env in enumerate(singles):
        for key, value in env.get_state().items():
            np.testing.assert_array_equal(batched[key][i], value)
    assert np.all(info["hops"] > 0)


def test_state_in_flight_round_trips_and_penetration_is_refused():
    env = TippeTopEnv(spin=2000.0, friction=1.0, tilt=0.1, free_flight=True, max_speed=40.0)
    env.reset(seed=1)
    for _ in range(200):
        _, _, _, _, info = env.step(ZERO)
        if info["airborne"]:
            break
    assert info["airborne"], "expected to catch the top in the air within 2 s"
    state = env.get_state()
    other = TippeTopEnv(spin=2000.0, friction=1.0, tilt=0.1, free_flight=True, max_speed=40.0)
    _, info2 = other.reset(options={"state": state})
    assert info2["airborne"] is True and info2["hops"] == 0  # the count starts afresh
    for _ in range(5):
        a, b = env.step(ZERO), other.step(ZERO)
        np.testing.assert_array_equal(a[0], b[0])
    sunk = env.get_state()
    sunk["position"][2] -= 1e-6 + info["gap"]
    with pytest.raises(ValueError, match="into the table"):
        other.reset(options={"state": sunk})


def test_free_flight_needs_a_sliding_fidelity():
    with pytest.raises(ValueError, match="free_flight"):
        TippeTopEnv(free_flight=True, fidelity="rolling")
    with pytest.raises(ValueError, match="flight"):
        TippeTop(TippeTopParams(), "rolling", flight=True)


@pytest.mark.parametrize(
    "task, integrator", [("invert", "rk4"), ("hold", "rk4"), ("invert", "euler")]
)
def test_check_env_with_free_flight(task, integrator):
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = TippeTopEnv(task=task, integrator=integrator, free_flight=True)
    check_env(env, skip_render_check=True)
    sb3_check_env(TippeTopEnv(task=task, integrator=integrator, free_flight=True), warn=True)


def test_euler_hops_too():
    env = TippeTopEnv(
        spin=2000.0,
        friction=0.3,
        tilt=0.1,
        free_flight=True,
        integrator="euler",
        max_speed=40.0,
        **ROLLING,
    )
    infos, observations = run(env, 20)
    assert all(np.all(np.isfinite(o)) for o in observations)
    assert infos[-1]["hops"] > 0
    # explicit Euler itself gains energy in free rotation (O(h) per unit time): bounded, not
    # monotone
    energy = np.array([i["energy"] for i in infos])
    assert np.max(np.abs(energy - energy[0])) < 1e-4 * energy[0]

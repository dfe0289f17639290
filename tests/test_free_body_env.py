"""FreeRigidBody-v0 specifics: validation, state dict, bad input, actuation, theorems at env
level."""

import math

import gymnasium as gym
import numpy as np
import pytest

from rbenvs.controllers import ZeroController, controller_for
from rbenvs.envs import FreeRigidBodyEnv, NumericalFailureWarning
from rbenvs.integrators import RK4

ID = "rbenvs/FreeRigidBody-v0"


@pytest.mark.parametrize(
    "kwargs,name",
    [
        (dict(inertia=(1.0, 1.0, -1.0)), "inertia"),
        (dict(inertia=(1.0, 1.0, 3.0)), "inertia"),  # violates I1 + I2 >= I3
        (dict(inertia=(1.0, float("nan"), 1.0)), "inertia"),
        (dict(inertia=(1.0, 2.0)), "inertia"),
        (dict(dt=0.0), "dt"),
        (dict(dt=-0.1), "dt"),
        (dict(dt=float("inf")), "dt"),
        (dict(max_torque=-1.0), "max_torque"),
        (dict(max_torque=float("nan")), "max_torque"),
        (dict(substeps=0), "substeps"),
        (dict(substeps=2.5), "substeps"),
        (dict(substeps=True), "substeps"),
        (dict(integrator="leapfrog"), "integrator"),
        (dict(task="hover"), "task"),
        (dict(axis="middle"), "axis"),
        (dict(axis=3), "axis"),
        (dict(inertia=(1.0, 1.0, 1.5), axis="intermediate"), "axis"),
        (dict(actuated=(False, False, False)), "actuated"),
        (dict(actuated=(True, True)), "actuated"),
        (dict(spin_rate=0.0), "spin_rate"),
        (dict(perturbation=4.0), "perturbation"),
        (dict(control_cost=-1.0), "control_cost"),
        (dict(max_angular_velocity=0.0), "max_angular_velocity"),
        (dict(max_angular_velocity=1e300), "max_angular_velocity"),
        (dict(task="reorient", target_attitude=(1.0, 1.0, 0.0, 0.0)), "target_attitude"),
        (dict(render_mode="video"), "render_mode"),
    ],
)
def test_bad_parameters_name_parameter(kwargs, name):
    with pytest.raises(ValueError, match=name):
        FreeRigidBodyEnv(**kwargs)


def test_flat_plate_and_equal_moments_are_legal():
    FreeRigidBodyEnv(inertia=(1.0, 2.0, 3.0), axis="minor")  # I1 + I2 = I3: a flat plate
    FreeRigidBodyEnv(inertia=(1.0, 1.0, 1.0), axis=0)


def test_axis_names_follow_the_moments():
    env = FreeRigidBodyEnv(inertia=(1.0, 3.0, 2.0), axis="major")
    assert env.axis == 1
    assert FreeRigidBodyEnv(inertia=(1.0, 3.0, 2.0), axis="intermediate").axis == 2
    assert FreeRigidBodyEnv(inertia=(1.0, 3.0, 2.0), axis="minor").axis == 0


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_action_raises_and_keeps_state(bad):
    env = FreeRigidBodyEnv()
    env.reset(seed=0)
    before = env.get_state()
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([0.0, bad, 0.0], dtype=np.float32))
    after = env.get_state()
    assert all(np.array_equal(before[k], after[k]) for k in before)


def test_wrong_action_shape_raises():
    env = FreeRigidBodyEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(2, dtype=np.float32))


def test_out_of_range_actions_are_clipped():
    a = FreeRigidBodyEnv()
    b = FreeRigidBodyEnv()
    a.reset(seed=1)
    b.reset(seed=1)
    oa = a.step(np.array([5.0, -7.0, 0.5], dtype=np.float32))[0]
    ob = b.step(np.array([1.0, -1.0, 0.5], dtype=np.float32))[0]
    assert np.array_equal(oa, ob)


def test_actuation_mask_shapes_and_routes_torque():
    env = FreeRigidBodyEnv(
        actuated=(False, True, False), task="detumble", max_torque=1.0, integrator="exact"
    )
    assert env.action_space.shape == (1,)
    env.reset(seed=0, options={"state": {"angular_momentum": np.zeros(3)}})
    env.step(np.array([1.0], dtype=np.float32))
    pi = env.get_state()["angular_momentum"]
    # From rest, torque on axis 1 only: Pi = (0, tau dt, 0) exactly (no gyroscopic coupling).
    assert pi[0] == 0.0 and pi[2] == 0.0
    assert pi[1] == pytest.approx(1.0 * env.dt, rel=1e-14)


@pytest.mark.parametrize(
    "state,match",
    [
        ({"angular_momentum": np.zeros(3), "spin": np.zeros(1)}, "unknown"),
        ({}, "missing"),
        ({"angular_momentum": np.zeros(4)}, "shape"),
        ({"angular_momentum": np.array([0.0, np.nan, 0.0])}, "finite"),
        ("not a dict", "dict"),
    ],
)
def test_bad_state_dicts(state, match):
    env = FreeRigidBodyEnv()
    with pytest.raises(ValueError, match=match):
        env.reset(options={"state": state})


def test_attitude_state_requires_unit_quaternion():
    env = FreeRigidBodyEnv(task="reorient")
    assert set(env.reset(seed=0)[0].shape) == {7}
    assert set(env.get_state()) == {"angular_momentum", "attitude"}
    with pytest.raises(ValueError, match="unit quaternion"):
        env.reset(
            options={
                "state": {"angular_momentum": np.zeros(3), "attitude": np.array([2.0, 0, 0, 0])}
            }
        )
    with pytest.raises(ValueError, match="missing"):
        env.reset(options={"state": {"angular_momentum": np.zeros(3)}})


def test_only_reorient_carries_attitude():
    assert set(FreeRigidBodyEnv(task="spin").system.layout) == {"angular_momentum"}
    assert set(FreeRigidBodyEnv(task="detumble").system.layout) == {"angular_momentum"}
    assert FreeRigidBodyEnv(task="reorient").system.attitude


def test_unknown_reset_option_raises():
    with pytest.raises(ValueError, match="reset options"):
        FreeRigidBodyEnv().reset(options={"stat": {}})


class _BlowsUpOnThirdCall(RK4):
    """RK4 that returns NaN from its third step on: stands in for any scheme that diverges."""

    def step(self, system, y, u, h):
        self.calls.append(1)
        y = super().step(system, y, u, h)
        return tuple(float("nan") for _ in y) if len(self.calls) >= 3 else y


def test_numerical_failure_ends_episode_with_last_finite_state():
    integ = _BlowsUpOnThirdCall()
    object.__setattr__(integ, "calls", [])
    env = FreeRigidBodyEnv(integrator=integ)
    env.reset(seed=0)
    zero = np.zeros(3, dtype=np.float32)
    env.step(zero)
    obs_ok, *_ = env.step(zero)
    last = env.get_state()
    with pytest.warns(NumericalFailureWarning, match="non-finite"):
        obs, r, te, tr, info = env.step(zero)
    assert (
        info["numerical_failure"] is True and te and info["terminal_reason"] == "numerical_failure"
    )
    assert r == env.model.failure_charge == -404.0 and np.array_equal(
        obs, obs_ok
    )  # reward 0 and the failure charge
    assert np.array_equal(env.get_state()["angular_momentum"], last["angular_momentum"])
    assert np.isfinite(info["energy"])


def test_observation_limit_terminates_with_clipped_observation():
    # the strongest actuator allowed with this bound: full torque moves Omega by
    # 40 sqrt(3) 0.05 = 3.46 rad/s a step (the box is 4 wide), out of the box within a few steps
    env = FreeRigidBodyEnv(task="detumble", max_torque=40.0, max_angular_velocity=2.0)
    env.reset(seed=0)
    for _ in range(100):
        obs, r, te, tr, info = env.step(np.ones(3, dtype=np.float32))
        if te:
            break
    assert te and info["terminal_reason"] == "observation_limit"
    assert env.observation_space.contains(obs) and np.max(np.abs(obs)) == pytest.approx(2.0)


def test_info_invariants_match_state():
    env = FreeRigidBodyEnv(inertia=(3.0, 2.0, 1.5))
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.zeros(3, dtype=np.float32))
    pi = env.get_state()["angular_momentum"]
    assert info["momentum_norm"] == pytest.approx(np.linalg.norm(pi), rel=1e-15)
    assert info["energy"] == pytest.approx(
        0.5 * np.sum(pi**2 / np.array([3.0, 2.0, 1.5])), rel=1e-15
    )


def run(env, policy, seed):
    obs, _ = env.reset(seed=seed)
    total, done = 0.0, False
    while not done:
        obs, r, te, tr, info = env.step(policy(obs))
        total += r
        done = te or tr
    return total, info


@pytest.mark.parametrize("axis,stable", [("major", True), ("intermediate", False), ("minor", True)])
def test_zero_torque_reproduces_the_stability_theorem(axis, stable):
    env = gym.make(ID, task="spin", axis=axis)
    finals = [run(env, ZeroController(env), seed)[1]["alignment"] for seed in range(3)]
    if stable:
        assert min(finals) > math.cos(0.06)  # initial tilt <= 0.05 rad stays bounded
    else:
        assert max(finals) < 0.5  # the flip happened within 20 s


@pytest.mark.parametrize(
    "scene",
    [
        dict(task="spin"),
        dict(task="spin", actuated=(True, False, False)),
        dict(task="detumble"),
        dict(task="reorient"),
    ],
)
def test_analytic_controllers_succeed(scene):
    env = gym.make(ID, **scene)
    infos = [run(env, controller_for(env), seed)[1] for seed in range(3)]
    assert all(info["is_success"] for info in infos)

"""LagrangeTop-v0 specifics: validation, actuation, info, state dict, starting states, the
stability theorem and conservation at env level, the analytic controllers, numerical failure.

(The generic conformance checks -- check_env, seeding, pickling, the state round trip for every
task x integrator -- live in tests/test_envs.py.)
"""

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest

from rbenvs.controllers import PrecessionTracking, UprightLQR, controller_for
from rbenvs.envs import LagrangeTopEnv, NumericalFailureWarning
from rbenvs.oracles.heavy_top import critical_spin, regular_precession_rates

ID = "rbenvs/LagrangeTop-v0"
NAN, INF = float("nan"), float("inf")

# The documented defaults (class docstring, "Arguments"): a Lagrange top, moments about the pivot.
A0, C0, M0, L0, G0 = 0.45, 0.3, 1.0, 0.5, 9.81
CRIT0 = 2.0 * math.sqrt(M0 * G0 * L0 * A0) / C0  # [MR 15.10.1]; 9.90 rad/s, as documented

# A general (non-Lagrange) top with its centre of mass off every principal axis. Physical: the
# inertia about the centre of mass, inertia - M l^2 (1 - chi chi^T), is checked by the env.
GENERAL = dict(inertia=(0.5, 0.45, 0.3), com_direction=(0.3, -0.2, 1.0))


def zeros(env):
    return np.zeros(env.action_space.shape, dtype=np.float32)


def zero_policy(env):
    return lambda obs: zeros(env)


def flat(state):
    """State dict -> the flat component tuple (layout order: angular_momentum, vertical,
    attitude)."""
    return tuple(
        float(x)
        for name in ("angular_momentum", "vertical", "attitude")
        if name in state
        for x in state[name]
    )


def quat_mul(p, q):
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return np.array(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ]
    )


def vertical_of(q):
    """``R(q)^T e_z`` (third row of the body-to-space rotation matrix of the unit quaternion q)."""
    w, x, y, z = q
    return np.array([2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)])


def tilted_state(inertia, spin, tilt):
    """``Omega = spin e3`` (chi = e3), the vertical tilted by ``tilt`` from e3 in the e1-e3
    plane."""
    return {
        "angular_momentum": np.array([0.0, 0.0, inertia[2] * spin]),
        "vertical": np.array([math.sin(tilt), 0.0, math.cos(tilt)]),
    }


def released_top_max_tilt(A, C, mgl, spin, tilt0):
    """Largest tilt of a Lagrange top released at ``tilt0`` with ``Omega = spin chi`` (no
    precession, no nutation rate), from the three conserved quantities: with ``u = cos(tilt)``,
    ``u'^2 = (u0 - u) [beta (1 - u^2) - a^2 (u0 - u)]``, ``a = C n / A``, ``beta = 2 M g l / A``;
    the other turning point is the root of ``beta u^2 - a^2 u + a^2 u0 - beta = 0`` below ``u0``.
    Above the critical spin and ``u0 -> 1`` it tends to 1 (the sleeping top stays up)."""
    a2, beta, u0 = (C * spin / A) ** 2, 2.0 * mgl / A, math.cos(tilt0)
    u1 = (a2 - math.sqrt(a2 * a2 - 4.0 * beta * (a2 * u0 - beta))) / (2.0 * beta)
    return math.acos(max(-1.0, min(1.0, u1)))


def run(env, policy, seed=None, options=None, steps=None):
    """One episode (or ``steps`` steps). Returns (steps taken, total reward, infos incl. reset)."""
    obs, info = env.reset(seed=seed, options=options)
    infos, total, k = [info], 0.0, 0
    while True:
        obs, r, te, tr, info = env.step(policy(obs))
        total += r
        k += 1
        infos.append(info)
        if te or tr or (steps is not None and k >= steps):
            return k, total, infos, te, tr


# ---------------------------------------------------------------------------------- 1. validation


@pytest.mark.parametrize(
    "kwargs,name",
    [
        # physical parameters
        (dict(inertia=(0.45, 0.45, NAN)), "inertia"),
        (dict(inertia=(0.45, INF, 0.3)), "inertia"),
        (dict(inertia=(0.45, -0.45, 0.3)), "inertia"),
        (dict(inertia=(0.45, 0.45)), "inertia"),
        (dict(inertia="heavy"), "inertia"),
        (
            dict(inertia=(0.2, 0.2, 0.3)),
            "inertia",
        ),  # transverse moments below M l^2 = 0.25: no real body
        (dict(inertia=(0.45, 0.45, 1.0)), "inertia"),  # violates the triangle inequality
        (dict(mass=0.0), "mass"),
        (dict(mass=-1.0), "mass"),
        (dict(mass=NAN), "mass"),
        (dict(mass="1"), "mass"),
        (dict(length=-0.5), "length"),
        (dict(length=INF), "length"),
        (dict(gravity=0.0), "gravity"),
        (dict(gravity=NAN), "gravity"),
        (dict(com_direction=(0.0, 0.0, 0.0)), "com_direction"),
        (dict(com_direction=(0.0, 1.0)), "com_direction"),
        (dict(com_direction=(0.0, NAN, 1.0)), "com_direction"),
        (dict(spin_friction=-0.1), "spin_friction"),
        (dict(spin_friction=NAN), "spin_friction"),
        # task and its parameters
        (dict(task="hover"), "task"),
        (dict(task="precess", inertia=(0.5, 0.45, 0.3)), "precess"),  # unequal transverse moments
        (
            dict(task="precess", com_direction=(0.1, 0.0, 1.0)),
            "precess",
        ),  # com off the symmetry axis
        (dict(spin=NAN), "spin"),
        (dict(spin=INF), "spin"),
        (dict(spin=(3.0, 1.0)), "spin"),  # low > high
        (dict(spin=(1.0, NAN)), "spin"),
        (dict(spin=(-INF, 1.0)), "spin"),
        (dict(spin=(1.0, 2.0, 3.0)), "spin"),
        (dict(spin="fast"), "spin"),
        (dict(spin=True), "spin"),
        (dict(perturbation=-0.1), "perturbation"),
        (dict(perturbation=NAN), "perturbation"),
        (dict(perturbation=math.pi / 4), "perturbation"),  # == default upright tilt_limit
        (dict(perturbation=0.3, tilt_limit=0.2), "perturbation"),
        (dict(task="precess", perturbation=0.3), "perturbation"),  # == default precess tilt_limit
        (dict(tilt_limit=0.0), "tilt_limit"),
        (dict(tilt_limit=-1.0), "tilt_limit"),
        (dict(tilt_limit=NAN), "tilt_limit"),
        (dict(tilt_limit=INF), "tilt_limit"),
        (dict(tilt_limit=math.pi + 1e-9), "tilt_limit"),
        (dict(task="precess", target_tilt=0.3), "target_tilt"),  # == tilt_limit: open interval
        (dict(task="precess", target_tilt=0.2), "target_tilt"),
        (dict(task="precess", target_tilt=math.pi - 0.3), "target_tilt"),
        (dict(task="precess", target_tilt=3.0), "target_tilt"),
        (dict(task="precess", target_tilt=NAN), "target_tilt"),
        (dict(task="precess", tilt_limit=1.0, target_tilt=2.5), "target_tilt"),
        # (I3 n)^2 <= 4 I1 M g l cos(0.5): |n| <= 9.28 rad/s has no torque-free regular precession
        (dict(task="precess", spin=5.0), "spin"),
        (dict(task="precess", spin=(5.0, 30.0)), "spin"),
        (dict(task="precess", spin=(-30.0, 30.0)), "spin"),  # both senses: crosses zero
        (dict(task="precess", target_rate=0.0), "target_rate"),
        (dict(task="precess", target_rate=NAN), "target_rate"),
        (dict(task="precess", target_rate=INF), "target_rate"),
        # numerics and actuation
        (dict(dt=0.0), "dt"),
        (dict(dt=-0.02), "dt"),
        (dict(dt=NAN), "dt"),
        (dict(dt=INF), "dt"),
        (dict(substeps=0), "substeps"),
        (dict(substeps=1.5), "substeps"),
        (dict(substeps=True), "substeps"),
        (dict(integrator="leapfrog"), "integrator"),
        (dict(max_torque=-1.0), "max_torque"),
        (dict(max_torque=NAN), "max_torque"),
        (dict(max_torque=INF), "max_torque"),
        (dict(control_cost=-0.01), "control_cost"),
        (dict(control_cost=NAN), "control_cost"),
        (dict(max_angular_velocity=0.0), "max_angular_velocity"),
        (dict(max_angular_velocity=NAN), "max_angular_velocity"),
        (dict(max_angular_velocity=1e300), "max_angular_velocity"),  # beyond float32 observations
        # below the initial angular speed: 0.5 critical = 4.95 rad/s, a spin range's largest |n|,
        # the precession's |n| + 2 |p*| (21.56 rad/s at the defaults; 19.81 + 3 with target_rate
        # 1.5)
        (dict(max_angular_velocity=4.0), "max_angular_velocity"),
        (dict(spin=(-20.0, 5.0), max_angular_velocity=10.0), "max_angular_velocity"),
        (dict(task="precess", max_angular_velocity=20.0), "max_angular_velocity"),
        (dict(task="precess", target_rate=1.5, max_angular_velocity=22.0), "max_angular_velocity"),
        (dict(render_mode="video"), "render_mode"),
    ],
)
def test_bad_parameters_name_parameter(kwargs, name):
    with pytest.raises(ValueError, match=name):
        LagrangeTopEnv(**kwargs)


def test_exact_integrator_is_refused_for_the_heavy_top():
    # The docstring: "exact does not exist for the heavy top". Refused at construction, naming it.
    try:
        env = LagrangeTopEnv(integrator="exact")
    except ValueError as err:
        assert "exact" in str(err) and "integrator" in str(err)
        return
    env.reset(seed=0)
    env.step(zeros(env))  # what a user gets instead of the ValueError
    pytest.fail("integrator='exact' was accepted")


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(perturbation=0.0),
        dict(tilt_limit=math.pi, perturbation=3.0),  # tilt_limit = pi is allowed
        dict(task="precess", spin=5.0, target_rate=1.0),  # a forced rate needs no fast spin
        dict(task="precess", spin=(-30.0, -25.0)),  # spin of one sign, either sense
        dict(task="precess", target_tilt=2.0),  # centre of mass below the pivot: rates always real
        dict(task="precess", target_tilt=0.5, spin=9.3),  # just above the 9.2785 rad/s threshold
        dict(max_torque=0.0),
        dict(
            inertia=(0.45, 0.45, 0.3), com_direction=(0.1, 0.0, 1.0)
        ),  # not a Lagrange top: fine upright
        dict(spin=(-3.0, 4.0)),
    ],
)
def test_legal_edge_parameters(kwargs):
    env = LagrangeTopEnv(**kwargs)
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs) and np.isfinite(info["energy"])


# ---------------------------------------------------------------------------------- 2. actions


def one_step_reference(env, state, tau):
    """The env's own integrator, applied by hand with the torque ``tau`` over one control period."""
    u = env.unwrapped
    y, h = flat(state), u.dt / u.substeps
    for _ in range(u.substeps):
        y = u.integrator.step(u.system, y, tuple(float(t) for t in tau), h)
    return np.array(y)


@pytest.mark.parametrize("axial", [False, True])
def test_action_shape_and_torque_on_body_axes_for_a_lagrange_top(axial):
    env = LagrangeTopEnv(max_torque=1.5, axial_torque=axial, spin=3.0, substeps=2)
    assert env.action_space.shape == ((3,) if axial else (2,))
    a = np.array([0.25, -0.75, 0.5][: env.action_space.shape[0]], dtype=np.float32)
    e1, e2, e3 = np.eye(3)
    tau = 1.5 * (a[0] * e1 + a[1] * e2 + (a[2] * e3 if axial else 0.0))
    env.reset(seed=4)
    start = env.get_state()
    env.step(a)
    got = np.array(flat(env.get_state()))
    want = one_step_reference(env, start, tau)
    # Same scheme, same state: only the order of the torque sum differs (round-off, |tau| dt ~
    # 0.03).
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-14)
    # ...and the torque mattered far beyond that tolerance.
    assert np.max(np.abs(got - one_step_reference(env, start, np.zeros(3)))) > 1e-3


@pytest.mark.parametrize("axial", [False, True])
def test_torque_directions_and_action_mapping_for_a_tilted_com(axial):
    env = LagrangeTopEnv(**GENERAL, spin=3.0, max_torque=1.5, axial_torque=axial)
    chi = np.array(GENERAL["com_direction"]) / np.linalg.norm(GENERAL["com_direction"])
    np.testing.assert_allclose(env.params.com_direction, chi, rtol=0, atol=1e-15)
    dirs = np.array(env.torque_directions)
    assert dirs.shape == ((3, 3) if axial else (2, 3)) and env.action_space.shape == (len(dirs),)
    t1, t2 = dirs[0], dirs[1]
    # (t1, t2, chi) right-handed and orthonormal: t1, t2 span exactly the plane normal to chi
    np.testing.assert_allclose(
        np.array([t1, t2, chi]) @ np.array([t1, t2, chi]).T, np.eye(3), atol=1e-15
    )
    np.testing.assert_allclose(np.cross(t1, t2), chi, atol=1e-15)
    if axial:
        np.testing.assert_allclose(dirs[2], chi, atol=1e-15)
    a = np.array([-0.5, 0.75, -1.0][: len(dirs)], dtype=np.float32)
    tau = 1.5 * (a[0] * t1 + a[1] * t2 + (a[2] * chi if axial else 0.0))
    env.reset(seed=7)
    start = env.get_state()
    # the upright start of a general top spins about chi: Omega = n chi (Pi = I n chi)
    np.testing.assert_allclose(
        start["angular_momentum"] / np.array(GENERAL["inertia"]), 3.0 * chi, rtol=1e-15, atol=1e-15
    )
    env.step(a)
    got = np.array(flat(env.get_state()))
    np.testing.assert_allclose(got, one_step_reference(env, start, tau), rtol=0, atol=1e-14)
    assert np.max(np.abs(got - one_step_reference(env, start, np.zeros(3)))) > 1e-3


@pytest.mark.parametrize("axial", [False, True])
def test_out_of_range_actions_are_clipped(axial):
    a, b = LagrangeTopEnv(axial_torque=axial), LagrangeTopEnv(axial_torque=axial)
    big = np.array([5.0, -7.0, 0.5][: a.action_space.shape[0]], dtype=np.float32)
    unit = np.array([1.0, -1.0, 0.5][: a.action_space.shape[0]], dtype=np.float32)
    a.reset(seed=1)
    b.reset(seed=1)
    ra = a.step(big)
    rb = b.step(unit)
    assert (
        np.array_equal(ra[0], rb[0]) and ra[1] == rb[1]
    )  # state and reward (the effort uses the clipped u)
    assert all(np.array_equal(a.get_state()[k], b.get_state()[k]) for k in a.get_state())


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("index", [0, 1])
def test_non_finite_action_raises_and_keeps_state(bad, index):
    env, twin = LagrangeTopEnv(), LagrangeTopEnv()
    env.reset(seed=0)
    twin.reset(seed=0)
    before = env.get_state()
    action = np.array([0.3, -0.2], dtype=np.float32)
    action[index] = bad
    with pytest.raises(ValueError, match="finite"):
        env.step(action)
    after = env.get_state()
    assert all(np.array_equal(before[k], after[k]) for k in before)
    # the env goes on exactly as one that never saw the bad action
    ok = np.array([0.3, -0.2], dtype=np.float32)
    assert np.array_equal(env.step(ok)[0], twin.step(ok)[0])


def test_wrong_action_shape_raises():
    env = LagrangeTopEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(3, dtype=np.float32))
    env = LagrangeTopEnv(axial_torque=True)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(2, dtype=np.float32))


@pytest.mark.parametrize("task", ["upright", "precess"])
def test_reward_formula_uses_the_clipped_action(task):
    cost = 0.2
    env = LagrangeTopEnv(task=task, control_cost=cost, perturbation=0.2)
    env.reset(seed=3)
    rng = np.random.default_rng(0)
    for _ in range(10):
        a = rng.uniform(-2.0, 2.0, 2).astype(np.float32)  # about half the entries out of range
        _, r, te, _, info = env.step(a)
        effort = np.mean(np.clip(a.astype(np.float64), -1.0, 1.0) ** 2)
        if task == "upright":
            want = math.cos(info["tilt"]) - cost * effort
        else:
            p, target = info["precession_rate"], info["target_precession_rate"]
            want = (
                1.0
                - abs(info["tilt"] - 0.5) / 0.3
                - min(abs(p - target) / abs(target), 1.0)
                - cost * effort
            )
        assert type(r) is float and r == pytest.approx(want, abs=1e-12)
        assert not te


# ---------------------------------------------------------------------------------- 3. info

BASE_KEYS = {
    "energy",
    "pi_dot_gamma",
    "vertical_norm",
    "tilt",
    "spin",
    "critical_spin",
    "internal_step",
    "is_success",
    "numerical_failure",
}
PRECESS_KEYS = {"precession_rate", "target_precession_rate", "tilt_error"}
ATTITUDE_KEYS = {"precession_angle", "nutation_angle", "spin_angle"}


@pytest.mark.parametrize("task", ["upright", "precess"])
@pytest.mark.parametrize("attitude", [False, True])
def test_info_keys_and_python_types(task, attitude):
    env = gym.make(ID, task=task, attitude=attitude)
    want = (
        BASE_KEYS
        | (PRECESS_KEYS if task == "precess" else set())
        | (ATTITUDE_KEYS if attitude else set())
    )
    env.action_space.seed(0)
    _, info = env.reset(seed=0)
    infos = [info] + [env.step(env.action_space.sample())[4] for _ in range(5)]
    for info in infos:
        assert set(info) == want | {
            "error_estimate"
        }  # no episode ends in 5 steps: no terminal_reason
        for key, value in info.items():
            if key == "error_estimate":  # (the default splitting: not estimated)
                assert value is None
                continue
            expected = bool if key in ("is_success", "numerical_failure") else float
            assert type(value) is expected, (key, type(value))


def check_readouts_against_state(env, info):
    """The info read-outs recomputed from get_state() and the documented formulas."""
    p = env.params
    s = env.get_state()
    pi, g = s["angular_momentum"], s["vertical"]
    inertia, chi, mgl = (
        np.array(p.inertia),
        np.array(p.com_direction),
        p.mass * p.gravity * p.length,
    )
    omega = pi / inertia
    energy = 0.5 * pi @ omega + mgl * g @ chi
    assert info["energy"] == pytest.approx(energy, rel=1e-14, abs=1e-14 * abs(mgl))
    assert info["pi_dot_gamma"] == pytest.approx(pi @ g, rel=1e-14, abs=1e-15 * np.linalg.norm(pi))
    assert info["vertical_norm"] == pytest.approx(np.linalg.norm(g), rel=1e-15)
    tilt = math.atan2(np.linalg.norm(np.cross(g, chi)), g @ chi)
    assert info["tilt"] == pytest.approx(tilt, rel=1e-13, abs=1e-15)
    assert info["spin"] == pytest.approx(omega @ chi, rel=1e-14, abs=1e-15 * np.linalg.norm(omega))


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(),
        dict(task="precess", attitude=True),
        dict(**GENERAL, spin=(-4.0, 4.0)),
        dict(inertia=(0.3, 0.45, 0.45), com_direction=(1.0, 0.0, 0.0), spin=6.0),
    ],
)
def test_info_values_match_the_state(kwargs):
    env = LagrangeTopEnv(**kwargs)
    env.action_space.seed(1)
    _, info = env.reset(seed=2)
    check_readouts_against_state(env, info)
    for _ in range(20):
        _, _, te, _, info = env.step(env.action_space.sample())
        check_readouts_against_state(env, info)
        assert not te
    if env.task.name == "upright":
        assert info["is_success"] == (info["tilt"] < 0.05)


@pytest.mark.parametrize(
    "inertia,mass,length,gravity,com,axis",
    [
        ((A0, A0, C0), M0, L0, G0, (0.0, 0.0, 1.0), 2),
        ((0.6, 0.6, 0.4), 1.2, 0.4, 9.0, (0.0, 0.0, 1.0), 2),
        ((0.3, 0.45, 0.45), M0, L0, G0, (1.0, 0.0, 0.0), 0),  # symmetry axis e1
        ((0.5, 0.2, 0.5), 0.8, 0.6, 3.7, (0.0, -1.0, 0.0), 1),  # symmetry axis -e2
    ],
)
def test_critical_spin_of_lagrange_tops(inertia, mass, length, gravity, com, axis):
    env = LagrangeTopEnv(
        inertia=inertia, mass=mass, length=length, gravity=gravity, com_direction=com, spin=1.0
    )
    i1 = inertia[(axis + 1) % 3]
    want = 2.0 * math.sqrt(mass * gravity * length * i1) / inertia[axis]
    assert want == pytest.approx(
        critical_spin(i1, inertia[axis], mass, length, gravity), rel=1e-15
    )  # the oracle agrees
    _, info = env.reset(seed=0)
    assert (
        info["critical_spin"] == pytest.approx(want, rel=1e-14)
        and env.critical_spin == info["critical_spin"]
    )
    if (inertia, mass, length, gravity) == ((A0, A0, C0), M0, L0, G0):
        assert info["critical_spin"] == pytest.approx(9.90, abs=0.005)  # the documented figure


@pytest.mark.parametrize(
    "kwargs",
    [
        GENERAL,
        dict(inertia=(0.45, 0.45, 0.3), com_direction=(0.1, 0.0, 1.0)),
        dict(inertia=(0.5, 0.45, 0.3)),
    ],
)
def test_critical_spin_is_absent_for_a_general_top(kwargs):
    # [MR 15.10.1] gives a threshold for a Lagrange top only: no key rather than a NaN in info
    env = LagrangeTopEnv(**kwargs)
    _, info = env.reset(seed=0)
    assert "critical_spin" not in info and math.isnan(env.critical_spin)
    assert all(
        math.isfinite(v) for v in info.values() if v is not None
    )  # (error_estimate: None, the splitting's)
    assert info["spin"] == 0.0  # default spin of a top that is not a Lagrange top: 0


def test_precess_info_metrics():
    env = LagrangeTopEnv(task="precess", perturbation=0.2, spin=(15.0, 25.0))
    env.action_space.seed(0)
    _, info = env.reset(seed=0)
    infos = [info] + [env.step(env.action_space.sample())[4] for _ in range(10)]
    for info in infos:
        assert info["tilt_error"] == pytest.approx(abs(info["tilt"] - 0.5), rel=1e-15, abs=1e-16)
        slow = regular_precession_rates(
            A0, C0, M0, L0, G0, info["spin"], 0.5
        ).slow  # at the current spin
        assert info["target_precession_rate"] == pytest.approx(slow, rel=1e-13)
        assert info["is_success"] == (
            info["tilt_error"] < 0.02 and abs(info["precession_rate"] / slow - 1.0) < 0.1
        )
    env = LagrangeTopEnv(task="precess", target_rate=-1.25)
    assert env.reset(seed=0)[1]["target_precession_rate"] == -1.25


def test_steady_precession_readouts_from_the_attitude():
    """perturbation=0: the start is the regular precession at the target tilt and slow rate, so
    (with the accurate dop853) the tilt and the precession rate stay constant, the Euler angle
    phi advances at the target rate, and the nutation angle equals the tilt (chi = e3)."""
    env = LagrangeTopEnv(
        task="precess", perturbation=0.0, attitude=True, integrator="dop853", max_torque=0.0
    )
    k, _, infos, te, _ = run(env, zero_policy(env), seed=3, steps=50)
    target = infos[0]["target_precession_rate"]
    phi = np.unwrap([i["precession_angle"] for i in infos])
    t = env.dt * np.arange(len(phi))
    slope, _ = np.polyfit(t, phi, 1)
    # dop853 at rtol 1e-12 over 1 s: the steady motion is kept to ~1e-13 (measured 2e-14).
    assert slope == pytest.approx(target, rel=1e-9)
    assert np.max(np.abs(phi - phi[0] - target * t)) < 1e-9
    for info in infos:
        assert info["precession_rate"] == pytest.approx(target, rel=1e-9)
        assert info["tilt"] == pytest.approx(0.5, abs=1e-9)
        assert info["nutation_angle"] == pytest.approx(info["tilt"], abs=1e-12)
        assert info["spin"] == pytest.approx(2.0 * CRIT0, rel=1e-12)


def test_nutation_angle_is_the_tilt_and_attitude_follows_the_vertical():
    env = LagrangeTopEnv(attitude=True, spin=(-8.0, 8.0), perturbation=0.4)
    env.action_space.seed(5)
    for seed in range(3):
        _, info = env.reset(seed=seed)
        for _ in range(100):
            s = env.get_state()
            np.testing.assert_allclose(vertical_of(s["attitude"]), s["vertical"], atol=1e-12)
            assert info["nutation_angle"] == pytest.approx(info["tilt"], abs=1e-12)
            _, _, te, _, info = env.step(env.action_space.sample())
            if te:
                break


# ---------------------------------------------------------------------------------- 4. state dict


def attitude_env_state(seed=0):
    env = LagrangeTopEnv(attitude=True)
    env.reset(seed=seed)
    env.step(np.array([0.4, -0.3], dtype=np.float32))
    return env, env.get_state()


def test_attitude_state_names_shapes_and_round_trip():
    env, s = attitude_env_state()
    assert set(s) == {"angular_momentum", "vertical", "attitude"}
    assert {k: v.shape for k, v in s.items()} == {
        "angular_momentum": (3,),
        "vertical": (3,),
        "attitude": (4,),
    }
    assert all(v.dtype == np.float64 for v in s.values())
    assert np.linalg.norm(s["attitude"]) == pytest.approx(1.0, abs=1e-14)
    np.testing.assert_allclose(vertical_of(s["attitude"]), s["vertical"], atol=1e-14)
    env.reset(options={"state": s})
    assert all(np.array_equal(env.get_state()[k], s[k]) for k in s)
    plain = LagrangeTopEnv()
    plain.reset(seed=0)
    assert set(plain.get_state()) == {"angular_momentum", "vertical"}


def test_heading_about_the_vertical_is_free():
    env, s = attitude_env_state()
    b = 1.1  # turn about the space vertical: R -> Rz(b) R keeps R^T e_z
    q = quat_mul((math.cos(b / 2), 0.0, 0.0, math.sin(b / 2)), s["attitude"])
    _, info = env.reset(options={"state": dict(s, attitude=q)})
    assert np.array_equal(env.get_state()["attitude"], q)
    assert info["tilt"] == pytest.approx(math.acos(s["vertical"][2]), abs=1e-12)


def _modified(s, **changes):
    out = {k: v.copy() for k, v in s.items()}
    out.update(changes)
    return out


@pytest.mark.parametrize(
    "change,match",
    [
        (lambda s: _modified(s, vertical=1.01 * s["vertical"]), "unit vector"),
        (
            lambda s: _modified(s, vertical=(1.0 + 2e-6) * s["vertical"]),
            "unit vector",
        ),  # just outside 1e-6
        (lambda s: _modified(s, attitude=1.01 * s["attitude"]), "unit quaternion"),
        (lambda s: _modified(s, attitude=(1.0 + 2e-6) * s["attitude"]), "unit quaternion"),
        # turned about a body axis: the attitude no longer carries this vertical
        (
            lambda s: _modified(
                s, attitude=quat_mul(s["attitude"], (math.cos(0.05), math.sin(0.05), 0.0, 0.0))
            ),
            r"R\(attitude\)\^T e_z",
        ),
        (
            lambda s: _modified(
                s, vertical=np.array([0.0, 0.0, 1.0]), attitude=np.array([0.0, 1.0, 0.0, 0.0])
            ),
            r"R\(attitude\)\^T e_z",
        ),
        (lambda s: {k: v for k, v in s.items() if k != "attitude"}, "missing"),
        (lambda s: {k: v for k, v in s.items() if k != "vertical"}, "missing"),
        (lambda s: _modified(s, spin=np.zeros(1)), "unknown"),
        (lambda s: _modified(s, vertical=np.array([0.0, 0.0, 1.0, 0.0])), "shape"),
        (lambda s: _modified(s, attitude=np.array([1.0, 0.0, 0.0])), "shape"),
        (lambda s: _modified(s, angular_momentum=np.zeros((1, 3))), "shape"),
        (lambda s: _modified(s, angular_momentum=np.array([0.0, np.nan, 1.0])), "finite"),
        (lambda s: _modified(s, vertical=np.array([0.0, 0.0, np.inf])), "finite"),
        (lambda s: _modified(s, attitude=np.array([np.nan, 0.0, 0.0, 0.0])), "finite"),
        (lambda s: [s["angular_momentum"], s["vertical"], s["attitude"]], "dict"),
    ],
)
def test_bad_state_dicts_raise_and_name_the_problem(change, match):
    env, s = attitude_env_state()
    with pytest.raises(ValueError, match=match):
        env.reset(options={"state": change(s)})
    # a failed reset leaves the previous state alone
    assert all(np.array_equal(env.get_state()[k], s[k]) for k in s)


def test_unit_tolerances_accept_round_off():
    env, s = attitude_env_state()
    _, info = env.reset(
        options={
            "state": _modified(
                s, vertical=(1.0 + 5e-7) * s["vertical"], attitude=(1.0 - 5e-7) * s["attitude"]
            )
        }
    )
    # documented "within 1e-6": accepted as given (the read-outs see the unprojected Gamma)
    assert info["vertical_norm"] == pytest.approx(1.0 + 5e-7, rel=1e-15)
    assert np.array_equal(env.get_state()["vertical"], (1.0 + 5e-7) * s["vertical"])


def test_state_without_attitude_refuses_one():
    env = LagrangeTopEnv()
    with pytest.raises(ValueError, match="unknown"):
        env.reset(
            options={
                "state": {
                    "angular_momentum": np.zeros(3),
                    "vertical": np.array([0.0, 0.0, 1.0]),
                    "attitude": np.array([1.0, 0, 0, 0]),
                }
            }
        )
    with pytest.raises(ValueError, match="unit vector"):
        env.reset(options={"state": {"angular_momentum": np.zeros(3), "vertical": np.zeros(3)}})


def test_unknown_reset_option_raises():
    with pytest.raises(ValueError, match="reset options"):
        LagrangeTopEnv().reset(options={"stat": {}})


# ---------------------------------------------------------------------------------- 5. starting
# states

SEEDS = range(200)


def test_upright_start_tilt_spin_range_and_axis():
    pert = 0.1
    env = LagrangeTopEnv(spin=(3.0, 7.0), perturbation=pert)
    tilts, spins = [], []
    for seed in SEEDS:
        _, info = env.reset(seed=seed)
        s = env.get_state()
        tilts.append(info["tilt"])
        spins.append(info["spin"])
        assert s["angular_momentum"][0] == 0.0 and s["angular_momentum"][1] == 0.0  # Omega = n e3
        assert s["angular_momentum"][2] / C0 == pytest.approx(info["spin"], rel=1e-15)
    tilts, spins = np.array(tilts), np.array(spins)
    assert tilts.max() <= pert + 1e-15 and tilts.min() >= 0.0
    assert spins.min() >= 3.0 and spins.max() <= 7.0
    # U(0, 0.1) and U(3, 7) over 200 draws: each end is approached (a miss has probability < 1e-11)
    assert tilts.max() > 0.9 * pert and tilts.min() < 0.1 * pert
    assert spins.min() < 3.5 and spins.max() > 6.5


def test_fixed_spin_and_default_spins():
    assert all(
        LagrangeTopEnv(spin=4.25).reset(seed=s)[1]["spin"] == pytest.approx(4.25, rel=1e-15)
        for s in range(5)
    )
    _, info = LagrangeTopEnv().reset(seed=0)
    assert info["spin"] == pytest.approx(0.5 * CRIT0, rel=1e-14)
    _, info = LagrangeTopEnv(task="precess").reset(seed=0)
    assert info["spin"] == pytest.approx(2.0 * CRIT0, rel=1e-14)
    # another Lagrange top: the defaults follow its own critical spin
    kw = dict(inertia=(0.6, 0.6, 0.4), mass=1.2, length=0.4, gravity=9.0)
    crit = 2.0 * math.sqrt(1.2 * 9.0 * 0.4 * 0.6) / 0.4
    assert LagrangeTopEnv(**kw).reset(seed=0)[1]["spin"] == pytest.approx(0.5 * crit, rel=1e-14)
    assert LagrangeTopEnv(**kw, task="precess").reset(seed=0)[1]["spin"] == pytest.approx(
        2.0 * crit, rel=1e-14
    )


@pytest.mark.parametrize(
    "target_tilt,spin", [(0.5, None), (0.8, (12.0, 30.0)), (2.0, (-25.0, -10.0))]
)
def test_precess_start_tilt_and_torque_free_rate(target_tilt, spin):
    pert = 0.2
    env = LagrangeTopEnv(task="precess", perturbation=pert, target_tilt=target_tilt, spin=spin)
    low, high = (2.0 * CRIT0, 2.0 * CRIT0) if spin is None else spin
    offsets = []
    for seed in range(100):
        _, info = env.reset(seed=seed)
        offsets.append(info["tilt"] - target_tilt)
        assert low <= info["spin"] <= high or info["spin"] == pytest.approx(low, rel=1e-14)
        # Omega = p* Gamma + (n - p* cos(tilt)) chi: the precession rate is p* at any tilt
        assert info["precession_rate"] == pytest.approx(info["target_precession_rate"], rel=1e-12)
    offsets = np.array(offsets)
    assert np.max(np.abs(offsets)) <= pert + 1e-12
    assert offsets.min() < -0.8 * pert and offsets.max() > 0.8 * pert  # U(-0.2, 0.2), 100 draws


@pytest.mark.parametrize("target_tilt,spin", [(0.5, None), (0.8, 15.0), (1.2, -12.0), (2.0, 25.0)])
def test_precess_start_on_target_is_the_slow_regular_precession(target_tilt, spin):
    env = LagrangeTopEnv(task="precess", perturbation=0.0, target_tilt=target_tilt, spin=spin)
    n = 2.0 * CRIT0 if spin is None else spin
    slow, fast = regular_precession_rates(A0, C0, M0, L0, G0, n, target_tilt)
    for seed in range(5):
        _, info = env.reset(seed=seed)
        assert info["tilt"] == pytest.approx(target_tilt, abs=1e-14)
        assert info["spin"] == pytest.approx(n, rel=1e-14)
        assert info["precession_rate"] == pytest.approx(slow, rel=1e-12)
        assert info["target_precession_rate"] == pytest.approx(slow, rel=1e-13)
        # the slow root of A cos(a) p^2 - C n p + M g l = 0 [T 3.82], and the smaller in size
        resid = A0 * math.cos(target_tilt) * slow**2 - C0 * n * slow + M0 * G0 * L0
        assert abs(resid) < 1e-12 * (C0 * abs(n * slow) + M0 * G0 * L0)
        assert abs(slow) < abs(fast)


def test_precess_start_with_forced_rate():
    env = LagrangeTopEnv(task="precess", target_rate=1.5, perturbation=0.1)
    for seed in range(10):
        _, info = env.reset(seed=seed)
        assert info["target_precession_rate"] == 1.5
        assert info["precession_rate"] == pytest.approx(1.5, rel=1e-12)
        assert info["spin"] == pytest.approx(2.0 * CRIT0, rel=1e-14)


def test_attitude_start_matches_vertical_and_headings_vary():
    """q has R(q)^T e_z = Gamma, so q * conj(q_s), with q_s the shortest turn taking Gamma to e_z,
    is a turn about the vertical: the heading, drawn uniformly (the docstring), not a function of
    Gamma."""
    env = LagrangeTopEnv(attitude=True, task="precess")
    headings = []
    for seed in range(50):
        env.reset(seed=seed)
        s = env.get_state()
        g, q = s["vertical"], s["attitude"]
        np.testing.assert_allclose(vertical_of(q), g, atol=1e-14)
        q_s = np.array([1.0 + g[2], g[1], -g[0], 0.0])
        q_s /= np.linalg.norm(q_s)
        turn = quat_mul(q, q_s * np.array([1.0, -1.0, -1.0, -1.0]))
        assert abs(turn[1]) < 1e-14 and abs(turn[2]) < 1e-14
        headings.append(2.0 * math.atan2(turn[3], turn[0]))
    # U(0, 2 pi) over 50 draws: the headings cover the circle (a gap > pi/2 has probability < 1e-5)
    h = np.sort(np.mod(headings, 2.0 * np.pi))
    assert np.max(np.diff(np.concatenate([h, [h[0] + 2.0 * np.pi]]))) < 0.5 * np.pi


# ---------------------------------------------------------------------------------- 6. zero torque


@pytest.mark.parametrize("seed", range(3))
def test_zero_torque_below_critical_spin_falls(seed):
    env = gym.make(ID)  # default: half the critical spin
    k, _, infos, te, tr = run(env, zero_policy(env), seed=seed)
    assert te and not tr and k < 500
    assert infos[-1]["terminal_reason"] == "task" and infos[-1]["tilt"] > math.pi / 4
    assert all("terminal_reason" not in i for i in infos[:-1])


@pytest.mark.parametrize("frac", [0.9, 1.1, 1.5, 2.0])
def test_zero_torque_matches_the_released_top_turning_point(frac):
    """From tilt 0.05 with Omega = n chi the top nods between 0.05 and the turning point fixed by
    the conserved energy, Pi.Gamma and spin: above the critical spin it stays within it (< 0.2 rad),
    below (0.9 critical: turning point 0.91 rad > pi/4) it falls and the episode ends."""
    n = frac * CRIT0
    env = gym.make(ID, spin=n)
    tilt0 = 0.05
    k, _, infos, te, tr = run(
        env, zero_policy(env), options={"state": tilted_state((A0, A0, C0), n, tilt0)}
    )
    tilt_max = released_top_max_tilt(A0, C0, M0 * G0 * L0, n, tilt0)
    if frac < 1.0:
        assert tilt_max > math.pi / 4
        assert te and infos[-1]["terminal_reason"] == "task"
        return
    assert tilt_max < 0.2
    assert k == 500 and tr and not te
    tilts = np.array([i["tilt"] for i in infos])
    # Sampled every 0.02 s over ~10+ nutation periods, integrated at h = 0.02: the observed peak
    # is below the turning point by the O(h^2) splitting error (measured 1.8e-4 rad at 1.1
    # critical, 16x smaller with 4 substeps) -- never above it by more than that.
    assert tilts.max() < 0.2
    assert abs(tilts.max() - tilt_max) < 5e-4
    assert tilts.min() == pytest.approx(tilt0, abs=5e-4)  # back to the cusps at the release tilt


def max_rel_errors(env, infos):
    e0, c0 = infos[0]["energy"], infos[0]["pi_dot_gamma"]
    de = np.array([abs(i["energy"] - e0) / abs(e0) for i in infos])
    dc = max(abs(i["pi_dot_gamma"] - c0) / abs(c0) for i in infos)
    dn = max(abs(i["vertical_norm"] - 1.0) for i in infos)
    return de, dc, dn


CONSERVATION_SCENES = [
    pytest.param(dict(spin=1.5 * CRIT0, perturbation=0.3), id="sleeping-lagrange"),
    pytest.param(
        dict(**GENERAL, spin=15.0, perturbation=0.3, tilt_limit=math.pi), id="general-top"
    ),
    pytest.param(dict(task="precess", perturbation=0.2), id="precess"),
]


@pytest.mark.parametrize("scene", CONSERVATION_SCENES)
def test_splitting_keeps_casimirs_to_round_off_and_energy_bounded(scene):
    env = LagrangeTopEnv(**scene, max_torque=0.0)
    # 5000 steps (100 s) on the unwrapped env
    k, _, infos, te, _ = run(env, zero_policy(env), seed=2, steps=5000)
    assert k == 5000 and not te
    de, dc, dn = max_rel_errors(env, infos)
    # Every piece of the splitting is an exact rotation or a kick normal to Gamma: the Casimirs
    # keep to round-off, a few eps per step at most (measured <= 1e-14 over 500 steps).
    assert dc < 1e-12 and dn < 1e-12
    # Energy: a symplectic scheme's error oscillates, it does not drift. The worst error in the
    # second 50 s equals the first's (measured ratio 1.000; rk4 drifts: ratio 1.9-2.0).
    assert de[1:].max() > 0.0
    assert de[2501:].max() <= 1.05 * de[1:2501].max()


@pytest.mark.parametrize("scene", CONSERVATION_SCENES[:2])
def test_splitting_energy_error_is_second_order(scene):
    """Halving the step (substeps=2, same control period) cuts the worst energy error over an
    episode by 4: it is the O(h^2) truncation error of the splitting, nothing else (measured
    3.99 and 3.95)."""
    errs = []
    for substeps in (1, 2):
        env = gym.make(ID, **scene, substeps=substeps, max_torque=0.0)
        k, _, infos, _, tr = run(env, zero_policy(env), seed=2)
        assert k == 500 and tr
        errs.append(max_rel_errors(env, infos)[0].max())
    assert 3.6 < errs[0] / errs[1] < 4.4


# ---------------------------------------------------------------------------------- 7. controllers


def random_tops(count, seed=0):
    """Physical Lagrange tops: inertia about the pivot from the inertia about the centre of mass
    (transverse A_G, axial C_G <= 2 A_G: a real body) plus M l^2 on the transverse axes, and a
    spin below the critical one. Spins up to 0.85 critical: the zero-torque turning point (cos =
    2 f^2 - 1 from near upright) lies far beyond pi/4 and the instability grows at >= 1.8 1/s."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        mass, length = rng.uniform(0.5, 1.5), rng.uniform(0.3, 0.6)
        a_g = rng.uniform(0.1, 0.3)
        c_g = rng.uniform(0.3, 1.9) * a_g
        a = a_g + mass * length**2
        crit = critical_spin(a, c_g, mass, length, G0)
        yield (
            dict(
                inertia=(a, a, c_g), mass=mass, length=length, spin=rng.uniform(0.05, 0.85) * crit
            ),
            crit,
        )


@pytest.mark.parametrize("case", range(6))
def test_upright_lqr_holds_tops_below_critical_spin(case):
    kwargs, crit = list(random_tops(6))[case]
    env = gym.make(ID, **kwargs)
    lqr = controller_for(env)
    assert isinstance(lqr, UprightLQR)
    assert 0.0 < kwargs["spin"] < crit
    for seed in (2 * case, 2 * case + 1):  # a different start tilt and azimuth per episode
        k, _, infos, te, tr = run(env, lqr, seed=seed)
        tilts = np.array([i["tilt"] for i in infos])
        assert k == 500 and tr and not te
        assert tilts[-1] < 1e-3
        # the start tilt (<= perturbation 0.05) is the largest: the torque acts within the first
        # step (measured: no overshoot at all); allow 1e-3 rad for one step's fall under gravity
        assert tilts.max() <= min(tilts[0], 0.05) + 1e-3
        assert infos[-1]["is_success"]
        k0, _, infos0, te0, _ = run(env, zero_policy(env), seed=seed)
        assert te0 and k0 < 500 and infos0[-1]["terminal_reason"] == "task"


@pytest.mark.parametrize("friction", [0.01, 0.05])
def test_upright_lqr_with_axial_torque_keeps_the_spin_against_friction(friction):
    env = gym.make(ID, spin_friction=friction, axial_torque=True)
    k, _, infos, _, tr = run(env, controller_for(env), seed=0)
    spins = np.array([i["spin"] for i in infos])
    assert k == 500 and tr
    assert np.max(np.abs(spins / spins[0] - 1.0)) < 1e-3  # measured 4e-8
    assert infos[-1]["tilt"] < 1e-3
    # without the axial actuator the friction's decay exp(-k t / I3) shows (28% at k = 0.01)
    env = gym.make(ID, spin_friction=friction)
    _, _, infos, _, _ = run(env, controller_for(env), seed=0)
    decay = 1.0 - infos[-1]["spin"] / infos[0]["spin"]
    assert decay == pytest.approx(-math.expm1(-friction * 10.0 / C0), rel=1e-6)


def test_precession_tracking_beats_zero_torque():
    env = gym.make(ID, task="precess", perturbation=0.2)
    assert isinstance(controller_for(env), PrecessionTracking)
    tracked = [run(env, controller_for(env), seed=s)[1] for s in range(4)]
    free = [run(env, zero_policy(env), seed=s)[1] for s in range(4)]
    assert np.mean(tracked) > np.mean(free)  # measured 449 vs 365


@pytest.mark.parametrize("seed", range(2))
def test_precession_tracking_holds_a_forced_rate(seed):
    env = gym.make(ID, task="precess", target_rate=1.5)  # the torque-free rate is 0.876 rad/s
    k, _, infos, _, tr = run(env, controller_for(env), seed=seed)
    assert k == 500 and tr
    final = infos[-1]
    assert abs(final["tilt"] - 0.5) < 0.01  # measured 0.0027
    assert final["precession_rate"] == pytest.approx(1.5, rel=0.02)  # measured 1.491
    # zero torque cannot: the top precesses at its own rate
    _, _, infos0, _, _ = run(env, zero_policy(env), seed=seed)
    assert abs(infos0[-1]["precession_rate"] / 1.5 - 1.0) > 0.5


# ---------------------------------------------------------------------------------- 8. non-finite
# state


def test_observation_limit_terminates_with_clipped_observation():
    env = LagrangeTopEnv(spin=5.0, axial_torque=True, max_angular_velocity=6.0)
    env.reset(seed=0)
    for _ in range(100):
        obs, r, te, tr, info = env.step(np.array([0.0, 0.0, 1.0], dtype=np.float32))  # spin up
        if te:
            break
    assert te and info["terminal_reason"] == "observation_limit"
    assert (
        info["spin"] > 6.0 and env.observation_space.contains(obs) and obs[5] == pytest.approx(6.0)
    )


def test_euler_blow_up_ends_episode_with_last_finite_state():
    # Forward Euler at h |Omega| >> 1 (dt = 5 s, 7 substeps, spin 50 rad/s) on a general top:
    # the gyroscopic term grows doubly exponentially inside one control period, from finite to
    # overflow before the observation bound can catch it (max_angular_velocity near float32 max).
    # guard="off": the default guarded stepping would subdivide the period and stay finite.
    inertia = (0.5, 0.45, 0.3)
    env = LagrangeTopEnv(
        inertia=inertia,
        spin=50.0,
        integrator="euler",
        tolerance=None,
        dt=5.0,
        substeps=7,
        tilt_limit=math.pi,
        max_angular_velocity=3e38,
        guard="off",
    )
    obs, _ = env.reset(options={"state": tilted_state(inertia, 50.0, 0.05)})
    for _ in range(20):
        last, last_obs = env.get_state(), obs
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            obs, r, te, tr, info = env.step(zeros(env))
        if te:
            break
        assert not caught
    assert [w.category for w in caught] == [NumericalFailureWarning]
    assert "non-finite" in str(caught[0].message)
    assert (
        te
        and not tr
        and info["numerical_failure"] is True
        and info["terminal_reason"] == "numerical_failure"
    )
    assert r == env.model.failure_charge == -505.0 and np.array_equal(
        obs, last_obs
    )  # reward 0 and the failure charge
    now = env.get_state()
    assert all(np.array_equal(now[k], last[k]) and np.all(np.isfinite(now[k])) for k in now)
    assert np.isfinite(info["energy"]) and info["energy"] == pytest.approx(
        env.system.energy(flat(now)), rel=1e-15
    )
    assert (
        np.max(np.abs(last["angular_momentum"])) > 1e3
    )  # it had blown up before failing: not the start


@pytest.mark.parametrize("limit", [0.06, 0.3, math.pi / 4, 1.5, 3.0, math.pi])
def test_upright_decisions_equal_the_tilt_comparisons(limit):
    """The upright task decides ``tilt > tilt_limit`` and ``tilt < success_tilt`` from the tilt's
    sides (no atan2): the same decisions as comparing the angle (top_tilt), from random
    verticals, starts 1e-9 rad either side of each boundary, exactly upright and hanging."""
    from rbenvs.dynamics.heavy_top import top_tilt
    from rbenvs.tasks.heavy_top import UprightTask

    env = LagrangeTopEnv(tilt_limit=limit, perturbation=min(0.05, limit / 2))
    task, system = env.unwrapped.task, env.unwrapped.system
    chi = system.params.com_direction
    rng = np.random.default_rng(7)
    success = task.success_tilt
    checked = 0

    def vertical(theta, phi):  # the vertical at tilt theta from chi = e3
        return (math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta))

    gammas = [tuple(g / np.linalg.norm(g)) for g in rng.standard_normal((3000, 3))]
    gammas += [
        vertical(b + d, rng.uniform(0, 2 * math.pi))
        for b in (limit, success)
        for d in (-1e-9, 1e-9)
        if 0 < b + d < math.pi
    ]
    for g in gammas:
        y = (0.3, -0.2, 0.5, *map(float, g))
        _, terminated, metrics = task.evaluate(system, y, (0.0, 0.0))
        tilt = top_tilt(chi, y)
        assert terminated == (tilt > limit) and metrics["is_success"] == (tilt < success), (
            tilt,
            limit,
        )
        checked += 1
    assert checked > 3000 and isinstance(task, UprightTask)
    up, down = (0.0, 0.0, 1.0, 0.0, 0.0, 1.0), (0.0, 0.0, 1.0, 0.0, 0.0, -1.0)
    assert task.evaluate(system, up, (0.0, 0.0))[1:] == (False, {"is_success": True})
    assert task.evaluate(system, down, (0.0, 0.0))[1:] == (limit < math.pi, {"is_success": False})

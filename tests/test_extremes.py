"""Extremes (docs/physics.md §4) and guarded stepping for all three environments.

Requirement everywhere: no NaN or inf ever reaches an observation, the invariants stay within
the bound stated (and justified) at each test, and every refusal is a ``ValueError`` naming the
parameter. Oracles: the stability functions of euler and rk4 on an exact linear rotation (the
symmetric free body), the exact elliptic flow and DOP853 at rtol 1e-12, equilibria that must
stay put to the last bit, Jellett's integral for the tippe top. The guard's tests run
unchecked (``tolerance=None``): the default accuracy at the extremes is
tests/test_default_accuracy.py's.
"""

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest

import rbenvs  # noqa: F401  (registers the ids)
from rbenvs.dynamics import FreeBody, FreeBodyParams
from rbenvs.envs import FreeRigidBodyEnv, LagrangeTopEnv, NumericalFailureWarning, TippeTopEnv
from rbenvs.envs.base import MAX_INTERNAL_STEPS
from rbenvs.integrators import get_integrator

EPS = np.finfo(float).eps


def zeros(env):
    return np.zeros(env.action_space.shape, dtype=np.float32)


def same(a, b):
    return np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True)


def step_all(env, steps, action=None, through_task_end=False):
    """Zero-action steps; every observation must be finite. Returns the infos. Stops at the
    episode's end, or (``through_task_end``) goes on past a task's success (the env allows it)."""
    a = zeros(env) if action is None else action
    infos = []
    for _ in range(steps):
        obs, r, te, tr, info = env.step(a)
        assert np.all(np.isfinite(obs)) and math.isfinite(r)
        infos.append(info)
        if te and not (through_task_end and info["terminal_reason"] == "task"):
            break
    return infos


# ----------------------------------------------------------------- 1. the documented bounds
def rotation_factor(name, x):
    """One step of ``name`` on the symmetric free body ``I = (1, 1, 1/2)``, ``Pi3 = x / h``:
    ``(Pi1, Pi2)`` turns at exactly ``lambda = (I1 - I3)/(I1 I3) Pi3 = x / h`` (docs/physics.md §1),
    a linear rotation with eigenvalues ``+-i lambda``. Returns the complex step factor."""
    system = FreeBody(FreeBodyParams((1.0, 1.0, 0.5)))
    h = 0.01
    y = get_integrator(name).step(system, (1.0, 0.0, x / h), None, h)
    return complex(y[0], y[1])  # (Pi1 + i Pi2) rotates as exp(-i lambda t) or its conjugate


def test_stability_functions_behind_the_bounds():
    """rk4's factor is R(ix) = 1 + ix + (ix)^2/2 + (ix)^3/6 + (ix)^4/24: |R| = 1 at the edge of
    its stability interval x = 2 sqrt(2), < 1 inside, > 1 outside. At the guard's x = 1 the
    amplitude error is 0.61 % and the phase error 0.56 % (the docstrings' figures). Euler's factor
    is 1 + ix: |R| = sqrt(1 + x^2) > 1 for every x (no stability interval; 0.5 % at 0.1)."""
    for x in (0.1, 0.5, 1.0, 2.0, 2.8, 2.9):
        r = rotation_factor("rk4", x)
        poly = abs(sum((1j * x) ** k / math.factorial(k) for k in range(5)))
        assert abs(r) == pytest.approx(poly, rel=1e-12)
        assert (abs(r) <= 1.0) == (x <= 2.0 * math.sqrt(2.0))
    r1 = rotation_factor("rk4", 1.0)
    assert 1.0 - abs(r1) == pytest.approx(0.0061, abs=1e-4)
    assert 1.0 - abs(math.atan2(r1.imag, r1.real)) == pytest.approx(0.0056, abs=1e-4)
    edge = 2.0 * math.sqrt(2.0)
    assert abs(rotation_factor("rk4", edge)) == pytest.approx(1.0, abs=1e-12)
    for x in (1e-3, 0.1, 1.0):
        assert abs(rotation_factor("euler", x)) == pytest.approx(math.sqrt(1.0 + x * x), rel=1e-14)
    assert abs(rotation_factor("euler", 0.1)) - 1.0 < 0.005


def test_rk4_growth_per_step_inside_its_bound_on_random_bodies():
    """Off a steady spin the free body is nonlinear; rk4 at |Omega| h <= 1 still never grows
    |Pi| by more than 1e-5 per step (bound used by the long rk4 runs below)."""
    rk4 = get_integrator("rk4")
    rng = np.random.default_rng(7)
    worst = 0.0
    for _ in range(500):
        inertia = np.sort(rng.uniform(0.2, 2.0, 3))
        if inertia[0] + inertia[1] < inertia[2]:
            continue
        system = FreeBody(FreeBodyParams(tuple(inertia)))
        y = tuple(rng.normal(size=3) * 10.0 ** rng.uniform(-2, 4))
        h = rng.uniform(0.0, 1.0) / np.linalg.norm(np.array(y) / inertia)
        worst = max(
            worst,
            system.momentum_norm(rk4.step(system, y, None, h)) / system.momentum_norm(y) - 1.0,
        )
    assert worst < 1e-5


# ----------------------------------------------------------------- 2. guarded stepping
def expected_steps(dt, rate, bound, growth=math.inf, substeps=1):
    n = max(substeps, math.ceil(dt * rate / bound))
    if growth != math.inf:
        n = max(n, math.ceil((dt * rate) ** 2 / growth))
    return n


@pytest.mark.parametrize(
    "integrator,bound,growth",
    [("rk4", 1.0, math.inf), ("euler", 0.1, 0.02), ("splitting", 1.0, math.inf)],
)
def test_free_body_subdivides_by_the_documented_rule(integrator, bound, growth):
    env = FreeRigidBodyEnv(
        integrator=integrator,
        tolerance=None,
        spin_rate=300.0,
        axis="minor",
        max_angular_velocity=1e4,
        dt=0.01,
    )
    env.reset(seed=0)
    speed = np.linalg.norm(env.system.angular_velocity(env._y))
    n = expected_steps(0.01, speed, bound, growth)
    assert n > 1
    info = env.step(zeros(env))[4]
    assert info["internal_step"] == 0.01 / n and info["numerical_failure"] is False


@pytest.mark.parametrize("integrator", ["exact", "dop853"])
def test_free_body_exact_and_adaptive_are_never_subdivided(integrator):
    env = FreeRigidBodyEnv(
        integrator=integrator,
        tolerance=None,
        spin_rate=1e4,
        axis="major",
        max_angular_velocity=3e4,
        dt=0.05,
    )
    env.reset(seed=0)
    assert env.step(zeros(env))[4]["internal_step"] == 0.05


@pytest.mark.parametrize(
    "kwargs,rate",
    [
        (dict(integrator="rk4", spin=60.0), "spin+g"),
        (dict(integrator="euler", tolerance=None, spin=20.0), "spin+g"),
        (dict(integrator="splitting", spin=60.0, dt=0.5), "g"),  # Lagrange top: gravity alone
        (dict(integrator="splitting", inertia=(0.5, 0.45, 0.3), spin=60.0), "spin+g"),
        (dict(integrator="rk4", spin=30.0, spin_friction=5.0), "spin+g+kappa"),
    ],
)
def test_heavy_top_subdivides_by_the_documented_rule(kwargs, rate):
    env = LagrangeTopEnv(
        max_angular_velocity=1e3, **({"tolerance": None} | kwargs)
    )  # (the guard alone: unchecked)
    env.reset(seed=0)
    prm = env.params
    omega_g = math.sqrt(prm.mgl / min(prm.inertia))
    kappa = prm.spin_friction * sum(c * c / i for c, i in zip(prm.com_direction, prm.inertia))
    w = math.sqrt(sum(c * c for c in env.system.angular_velocity(env._y)))
    lam = {"spin+g": w + omega_g, "g": omega_g, "spin+g+kappa": w + omega_g + kappa}[rate]
    bound, growth = {"rk4": (1.0, math.inf), "euler": (0.1, 0.02), "splitting": (1.0, math.inf)}[
        kwargs["integrator"]
    ]
    dt = kwargs.get("dt", 0.02)
    n = expected_steps(dt, lam, bound, growth)
    assert n > 1
    assert env.step(zeros(env))[4]["internal_step"] == dt / n


@pytest.mark.parametrize(
    "make",
    [
        lambda g, n=1: FreeRigidBodyEnv(
            spin_rate=100.0, max_angular_velocity=1e3, guard=g, substeps=n
        ),
        lambda g, n=1: LagrangeTopEnv(
            integrator="rk4", spin=100.0, max_angular_velocity=1e3, guard=g, substeps=n
        ),
        lambda g, n=1: TippeTopEnv(
            guard=g, substeps=n
        ),  # the default top needs ~160 steps per period
    ],
    ids=["free", "lagrange", "tippe"],
)
def test_refuse_raises_naming_substeps_and_keeps_the_state(make):
    env = make("refuse")
    env.reset(seed=0)
    before = env.get_state()
    with pytest.raises(ValueError, match="substeps") as err:
        env.step(zeros(env))
    assert "guard='subdivide'" in str(err.value) and "internal steps" in str(err.value)
    assert all(same(before[k], v) for k, v in env.get_state().items())
    # enough substeps: accepted, and the same steps as the subdivided env
    n = int(str(err.value).split(" needs ")[1].split()[0])
    ok, sub = make("refuse", n), make("subdivide")
    ok.reset(seed=0), sub.reset(seed=0)
    assert same(ok.step(zeros(ok))[0], sub.step(zeros(sub))[0])


@pytest.mark.parametrize("cls", [FreeRigidBodyEnv, LagrangeTopEnv, TippeTopEnv])
@pytest.mark.parametrize("bad", ["auto", None, 1])
def test_unknown_guard_is_refused(cls, bad):
    with pytest.raises(ValueError, match="guard"):
        cls(guard=bad)


def test_guard_off_exposes_the_numerical_failure_path():
    """guard='off' takes substeps steps whatever |Omega| h: forward Euler at dt = 5 s (7
    substeps) and 50 rad/s overflows (a numerical failure, last finite state kept, finite
    observation); the guarded env needs (5 * 50)^2 / 0.02 > MAX_INTERNAL_STEPS steps: a start
    there is refused at construction (naming dt), and a state reached there (here: reset to
    it) is refused as a numerical failure, before integrating; at dt = 0.05 s the guarded
    euler stays finite."""
    with pytest.raises(ValueError, match="dt=5.0 s cannot be resolved"):
        FreeRigidBodyEnv(
            integrator="euler",
            tolerance=None,
            spin_rate=50.0,
            dt=5.0,
            substeps=7,
            max_angular_velocity=3e38,
        )
    fast = FreeRigidBodyEnv(
        integrator="euler",
        tolerance=None,
        spin_rate=50.0,
        dt=5.0,
        substeps=7,
        max_angular_velocity=3e38,
        guard="off",
    )
    fast.reset(seed=0)
    start = fast.get_state()  # a spin at 50 rad/s
    for guard in ("off", "subdivide"):
        env = FreeRigidBodyEnv(
            integrator="euler",
            tolerance=None,
            spin_rate=1.0,
            dt=5.0,
            substeps=7,
            max_angular_velocity=3e38,
            guard=guard,
        )
        obs0, _ = env.reset(seed=0, options={"state": start})
        last = env.get_state()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            infos = step_all(env, 20)
        assert [w.category for w in caught] == [NumericalFailureWarning]
        assert infos[-1]["terminal_reason"] == "numerical_failure" and math.isfinite(
            infos[-1]["energy"]
        )
        if guard == "subdivide":
            assert len(infos) == 1 and infos[0]["internal_step"] == 5.0 / (MAX_INTERNAL_STEPS + 1)
            assert all(same(last[k], v) for k, v in env.get_state().items())
    env = FreeRigidBodyEnv(
        integrator="euler",
        tolerance=None,
        spin_rate=50.0,
        axis="major",
        dt=0.05,
        max_angular_velocity=200.0,
    )
    env.reset(seed=0)
    infos = step_all(env, 20)
    assert len(infos) == 20 and not any(i["numerical_failure"] for i in infos)


def test_stepping_past_an_observation_limit_stays_guarded():
    """The default rk4 env runs unchecked because no state inside the bounds can trip the
    guard (sqrt(3) * 10 * 0.05 = 0.87 <= 1); a step that ends outside them switches the check
    back on until the next reset. (Start near the bounds, Omega = (9, 9, 9), and push outwards
    with the strongest torque allowed, a change of one box width, 20 rad/s, per period.)"""
    env = FreeRigidBodyEnv(task="detumble", inertia=(1.0, 1.0, 1.0), max_torque=230.0)
    env.reset(seed=0, options={"state": {"angular_momentum": np.array([9.0, 9.0, 9.0])}})
    info = env.step(np.ones(3, dtype=np.float32))[4]
    assert info["terminal_reason"] == "observation_limit"
    speed = float(np.linalg.norm(env.system.angular_velocity(env._y)))
    assert speed * 0.05 > 1.0
    info = env.step(zeros(env))[4]
    assert info["internal_step"] == 0.05 / math.ceil(0.05 * speed)
    env.reset(seed=0)
    assert env.step(zeros(env))[4]["internal_step"] == 0.05


@pytest.mark.parametrize(
    "env_id,kwargs,k",
    [
        (
            "rbenvs/FreeRigidBody-v0",
            dict(task="detumble", spin_rate=30.0, max_angular_velocity=200.0),
            3,
        ),
        (
            "rbenvs/FreeRigidBody-v0",
            dict(
                task="detumble",
                integrator="euler",
                tolerance=None,
                spin_rate=3.0,
                max_angular_velocity=20.0,
            ),
            3,
        ),
        (
            "rbenvs/LagrangeTop-v0",
            dict(
                integrator="rk4", spin=(10.0, 80.0), max_angular_velocity=300.0, tilt_limit=math.pi
            ),
            2,
        ),
    ],
)
def test_vector_env_equals_single_envs_under_guarded_stepping(env_id, kwargs, k):
    """Sub-envs need different step counts (1 to 3 per period): each takes exactly its single
    env's steps, bit for bit."""
    n, seed = 5, 3
    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    singles = [gym.make(env_id, **kwargs) for _ in range(n)]
    venv.reset(seed=seed)
    for i, env in enumerate(singles):
        env.reset(seed=seed + i)
    rng = np.random.default_rng(0)
    counts = set()
    for _ in range(15):
        a = rng.uniform(-1, 1, (n, k)).astype(np.float32)
        obs, r, te, tr, info = venv.step(a)
        for i, env in enumerate(singles):
            o, sr, ste, _, sinfo = env.step(a[i])
            assert same(obs[i], o) and r[i] == sr and te[i] == ste
            assert same(info["internal_step"][i], sinfo["internal_step"])
            counts.add(round(env.unwrapped.dt / sinfo["internal_step"]))
            if ste:
                env.reset()
    assert len(counts) > 1  # the batch really mixed step counts


# ----------------------------------------------------------------- 3. free body extremes
def run_free(integrator, spin, axis, dt, steps, inertia=(2.0, 1.5, 1.0)):
    env = FreeRigidBodyEnv(
        inertia=inertia,
        integrator=integrator,
        tolerance=None,
        spin_rate=spin,
        axis=axis,
        perturbation=0.3,
        dt=dt,
        max_angular_velocity=3 * spin,
    )
    _, info0 = env.reset(seed=0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        infos = step_all(env, steps)
    return env, info0, infos, caught


@pytest.mark.parametrize("axis", ["major", "intermediate", "minor"])
@pytest.mark.parametrize("integrator", ["exact", "splitting", "rk4"])
def test_spin_1e4_rad_per_s(integrator, axis):
    """|Omega| = 1e4 rad/s, dt = 0.01 s (100 rad per period), 20 periods, no torque.
    Bounds: exact keeps |Pi| and H to 1e-11 (round-off in the elliptic evaluation at 100 rad
    per call, against DOP853 below); splitting keeps |Pi| to round-off (exact rotations: 50 eps
    per step) and H inside its hard range [|Pi|^2/(2 I_max), |Pi|^2/(2 I_min)]; guarded rk4 grows
    |Pi| by < 1e-5 per step (test above) and, stable, loses at most the 0.61 % per step of a
    rotation at the bound (|R(i)|, test above)."""
    env, info0, infos, caught = run_free(integrator, 1e4, axis, 0.01, 20)
    assert not caught and len(infos) == 20
    c0, e0 = info0["momentum_norm"], info0["energy"]
    steps = sum(round(0.01 / i["internal_step"]) for i in infos)
    for info in infos:
        c, e = info["momentum_norm"], info["energy"]
        if integrator == "exact":
            assert abs(c / c0 - 1) < 1e-11 and abs(e / e0 - 1) < 1e-11
        elif integrator == "splitting":
            assert abs(c / c0 - 1) < 50 * EPS * steps
            assert c * c / 4.0 * (1 - 1e-12) <= e <= c * c / 2.0 * (1 + 1e-12)
        else:
            assert (1 - 0.0061) ** steps <= c / c0 < 1.0 + 1e-5 * steps
    if integrator == "exact":  # against the reference over one period
        y0 = env._y
        env.step(zeros(env))
        ref = get_integrator("dop853").step(env.system, y0, None, 0.01)
        assert np.max(np.abs(np.subtract(env._y, ref))) < 1e-10 * c0


def test_euler_at_1e4_rad_per_s_is_a_numerical_failure_or_within_its_growth_bound():
    """Euler cannot follow 1e4 rad/s at dt = 0.01 s: (100)^2 / 0.02 = 5e5 steps per period,
    below MAX_INTERNAL_STEPS, each growing |Pi| by sqrt(1 + (h|Omega|)^2): the documented
    per-period growth exp(|Omega|^2 h dt / 2) <= exp(0.01), with |Omega| at most |Pi|/I_min.
    At dt = 0.05 s it would need 1.25e7 steps: such a start is refused at construction (naming
    dt), and such a state reached later (here: reset to it) is a numerical failure, the state
    kept."""
    env = FreeRigidBodyEnv(
        integrator="euler",
        tolerance=None,
        spin_rate=1e4,
        axis="minor",
        perturbation=0.3,
        dt=0.01,
        max_angular_velocity=3e4,
    )
    _, info0 = env.reset(seed=0)
    speed = math.sqrt(sum(c * c for c in env.system.angular_velocity(env._y)))
    infos = step_all(env, 1)
    info = infos[0]
    h = info["internal_step"]
    assert (
        round(0.01 / h) == math.ceil((0.01 * speed) ** 2 / 0.02) and not info["numerical_failure"]
    )
    c0, c1 = info0["momentum_norm"], info["momentum_norm"]
    w_max = c1 / 1.0  # I_min = 1
    assert 1.0 - 1e-12 <= c1 / c0 <= math.exp(w_max * w_max * h * 0.01 / 2)
    with pytest.raises(ValueError, match="dt=0.05 s cannot be resolved"):
        run_free("euler", 1e4, "minor", 0.05, 1)
    start = env.get_state()  # about 1e4 rad/s
    env = FreeRigidBodyEnv(
        integrator="euler",
        tolerance=None,
        spin_rate=1.0,
        axis="minor",
        dt=0.05,
        max_angular_velocity=3e4,
    )
    _, info0 = env.reset(seed=0, options={"state": start})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        infos = step_all(env, 1)
    assert [w.category for w in caught] == [NumericalFailureWarning] and infos[0][
        "numerical_failure"
    ] is True
    assert infos[0]["momentum_norm"] == info0["momentum_norm"]


@pytest.mark.parametrize(
    "inertia",
    [(1.5, 1.5 * (1 + 1e-12), 1.0), (1.5, 1.5, 1.0), (1.0, 1.0, 1.0), (2.0, 1.0 + 1e-12, 1.0)],
)
@pytest.mark.parametrize("integrator", ["exact", "splitting", "rk4"])
def test_equal_and_nearly_equal_moments(inertia, integrator):
    """Moments equal to 1e-12 relative and exactly equal (elliptic modulus 0 or 1): every
    integrator against DOP853 at rtol 1e-12 over 1 s (20 periods of 0.05 s, spin 3 rad/s,
    tilted 0.3 rad from axis 0). Bounds: exact 1e-10 relative (round-off, docs/physics.md §4);
    splitting and rk4 their global error at |Omega| h = 0.15: C (|Omega| h)^p |Omega| t with
    p = 2 and 4, i.e. 5e-2 and 1e-3."""
    env = FreeRigidBodyEnv(
        inertia=inertia,
        integrator=integrator,
        tolerance=None,
        axis=0,
        spin_rate=3.0,
        perturbation=0.3,
        max_angular_velocity=20.0,
    )
    env.reset(seed=1)
    y0 = env._y
    step_all(env, 20)
    ref = get_integrator("dop853").step(env.system, y0, None, 1.0)
    c0 = env.system.momentum_norm(y0)
    err = np.max(np.abs(np.subtract(env._y, ref))) / c0
    assert err < {"exact": 1e-10, "splitting": 5e-2, "rk4": 1e-3}[integrator]
    assert (
        abs(env.system.momentum_norm(env._y) / c0 - 1)
        < {"exact": 1e-12, "splitting": 1e-14, "rk4": 1e-4}[integrator]
    )


def separatrix_state(offset):
    """Pi on the separatrix |Pi|^2 = 2 H I2 of I = (2, 1.5, 1): Pi1^2 (1/I1 - 1/I2) =
    Pi3^2 (1/I2 - 1/I3) gives Pi1 = sqrt(2) Pi3; ``offset`` moves Pi2 off the unstable point."""
    return {"angular_momentum": np.array([math.sqrt(2.0), offset, 1.0])}


@pytest.mark.parametrize("offset", [0.0, 1e-12, -1e-12])
@pytest.mark.parametrize("integrator", ["exact", "splitting", "rk4", "euler"])
def test_on_and_near_the_separatrix(integrator, offset):
    """The heteroclinic orbit takes infinitely long to reach the intermediate axis; the elliptic
    parameter is 1 - 1e-24 or 1 exactly. 200 periods (10 s): finite, |Pi| and H within the
    integrator's bound (exact: 1e-12 against the initial values; splitting: |Pi| to 200 * 50 eps,
    H in its hard range; rk4 at |Omega| h = 0.07: 1e-6; euler: nondecreasing |Pi| with per-step
    growth sqrt(1 + (h |Omega|)^2) <= 1 + 1.3e-3 at |Omega| <= 1.02). Exact against DOP853 over
    the first second: 1e-10 (away from the separatrix states are resolved to round-off, here the
    AGM from the complementary parameter keeps it)."""
    env = FreeRigidBodyEnv(integrator=integrator, tolerance=None, max_angular_velocity=20.0)
    env.reset(options={"state": separatrix_state(offset)})
    y0 = env._y
    c0, e0 = env.system.momentum_norm(y0), env.system.energy(y0)
    assert abs(c0 * c0 - 2.0 * e0 * 1.5) < 4 * EPS * c0 * c0  # on the separatrix (to round-off)
    infos = step_all(env, 200)
    assert len(infos) == 200 and not any(i["numerical_failure"] for i in infos)
    cs = np.array([c0] + [i["momentum_norm"] for i in infos])
    es = np.array([e0] + [i["energy"] for i in infos])
    if integrator == "exact":
        assert np.max(np.abs(cs / c0 - 1)) < 1e-12 and np.max(np.abs(es / e0 - 1)) < 1e-12
        env.reset(options={"state": separatrix_state(offset)})
        step_all(env, 20)
        ref = get_integrator("dop853").step(env.system, y0, None, 1.0)
        assert np.max(np.abs(np.subtract(env._y, ref))) < 1e-10 * c0
    elif integrator == "splitting":
        assert np.max(np.abs(cs / c0 - 1)) < 200 * 50 * EPS
        assert np.all(cs * cs / 4.0 * (1 - 1e-12) <= es) and np.all(
            es <= cs * cs / 2.0 * (1 + 1e-12)
        )
    elif integrator == "rk4":
        assert np.max(np.abs(cs / c0 - 1)) < 1e-6 and np.max(np.abs(es / e0 - 1)) < 1e-6
    else:
        assert np.all(np.diff(cs) >= -4 * EPS * cs[1:])
        assert np.all(
            cs[1:] / cs[:-1] <= math.sqrt(1 + (0.05 * 1.02 * cs.max() / c0) ** 2) + 4 * EPS
        )


@pytest.mark.parametrize("dt", [1e-6, 1e-3, 0.05, 1.0])
@pytest.mark.parametrize("integrator", ["euler", "rk4", "splitting", "exact"])
def test_free_body_dt_range(integrator, dt):
    """dt from 1e-6 s to 1 s (the largest value the docs state as tested), spin 5 rad/s about
    the intermediate axis: 10 periods, finite, |Pi| drift within the scheme's bound per step
    (euler: its per-period growth exp(0.01); the others 1e-6, far above round-off), the step
    count the documented rule's. rk4 at dt = 1 s runs at the bound |Omega| h = 1: its |Pi|
    within [(1 - 0.0061)^steps, 1 + 1e-5 steps] (the two tests of section 1)."""
    env = FreeRigidBodyEnv(
        integrator=integrator, tolerance=None, spin_rate=5.0, dt=dt, max_angular_velocity=50.0
    )
    _, info0 = env.reset(seed=0)
    infos = step_all(env, 10)
    assert len(infos) == 10
    c = np.array([i["momentum_norm"] for i in infos]) / info0["momentum_norm"]
    steps = sum(round(dt / i["internal_step"]) for i in infos)
    if integrator == "euler":
        assert np.all(c >= 1 - 1e-12) and c[-1] <= math.exp(0.01 * 1.01) ** 10
    elif integrator == "rk4" and dt == 1.0:
        assert (1 - 0.0061) ** steps <= c.min() and c.max() < 1 + 1e-5 * steps
    else:
        assert np.all(np.abs(c - 1) < 1e-6)
    assert infos[0]["internal_step"] == dt / expected_steps(
        dt,
        5.0,
        *{"euler": (0.1, 0.02), "rk4": (1.0,), "splitting": (1.0,), "exact": (math.inf,)}[
            integrator
        ],
    )


@pytest.mark.slow
def test_a_million_steps_of_the_free_body():
    """1e6 control periods of the default intermediate-axis scene with the splitting (50 000 s,
    about 8 000 flips): |Pi| to round-off (a random walk of about 1e3 eps) and the energy error
    bounded, never above its largest value in the first 1e4 steps times 1.5 (docs/physics.md §4:
    the symmetric Lie-Poisson splitting keeps the energy error bounded forever)."""
    env = FreeRigidBodyEnv(integrator="splitting")
    _, info0 = env.reset(seed=0)
    c0, e0 = info0["momentum_norm"], info0["energy"]
    step, system = env.step, env.system
    a = zeros(env)
    early, worst = 0.0, 0.0
    for k in range(1_000_000):
        obs, _, te, _, info = step(a)
        if k % 1000 == 0:
            assert np.all(np.isfinite(obs)) and not te
            err = abs(system.energy(env._y) / e0 - 1)
            if k < 10_000:
                early = max(early, err)
            worst = max(worst, err)
    assert np.all(np.isfinite(obs)) and not te
    assert abs(info["momentum_norm"] / c0 - 1) < 1e-12
    assert worst <= 1.5 * early and early > 0.0


# ----------------------------------------------------------------- 4. heavy top extremes
def top_state(gamma, pi):
    return {"angular_momentum": np.array(pi, dtype=float), "vertical": np.array(gamma, dtype=float)}


@pytest.mark.parametrize("integrator", ["euler", "rk4", "splitting", "dop853"])
@pytest.mark.parametrize("tilt", [0.0, math.pi])
@pytest.mark.parametrize("spin", [0.0, 5.0, 1e4])
def test_heavy_top_upright_and_hanging_are_equilibria(integrator, tilt, spin):
    """Gamma = +-chi with Pi = I3 n chi is an equilibrium (Pi x Omega = 0, Gamma x chi = 0,
    Gamma x Omega = 0), upright (unstable below the critical spin, 9.90 rad/s) or hanging: the
    state must stay put bit for bit at every spin up to 1e4 rad/s, with the step count the
    guard's, tilt reading exactly 0 or pi and no NaN in the observation (the precession rate,
    undefined there, is info only)."""
    dt = 0.02
    env = LagrangeTopEnv(
        integrator=integrator,
        tolerance=None,
        tilt_limit=math.pi,
        max_angular_velocity=2e4,
        spin=min(spin, 9.0),
    )
    pi = (0.0, 0.0, 0.3 * spin)
    env.reset(options={"state": top_state((0.0, 0.0, math.cos(tilt)), pi)})
    y0 = env._y
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        infos = step_all(env, 3)
    assert same(env._y, y0)
    assert infos[-1]["tilt"] == tilt
    if (
        integrator == "euler" and spin == 1e4
    ):  # (0.02 * 1e4)^2 / 0.02 = 2e6 steps: refused, state kept
        assert [w.category for w in caught] == [NumericalFailureWarning] and infos[-1][
            "numerical_failure"
        ]
        assert infos[-1]["internal_step"] == dt / (MAX_INTERNAL_STEPS + 1)
        return
    assert len(infos) == 3 and not caught
    if integrator != "dop853":
        rate = {"splitting": 0.0}.get(integrator, spin) + math.sqrt(env.params.mgl / 0.3)
        bound, growth = {
            "rk4": (1.0, math.inf),
            "euler": (0.1, 0.02),
            "splitting": (1.0, math.inf),
        }[integrator]
        assert infos[-1]["internal_step"] == dt / expected_steps(dt, rate, bound, growth)


@pytest.mark.parametrize("integrator", ["rk4", "splitting"])
@pytest.mark.parametrize("tilt", [1e-12, math.pi - 1e-12])
def test_heavy_top_within_1e_12_of_upright_and_hanging(integrator, tilt):
    """1e-12 rad off the equilibria at 3x the critical spin (upright: stable) and hanging: 2 s,
    the tilt stays within 1e-9 rad of it (linear stability: bounded oscillation of the initial
    size times a modest factor), energy and Pi.Gamma within 1e-9 relative (rk4's drift at
    |Omega| h = 0.6 over 100 steps; the splitting keeps Pi.Gamma to round-off)."""
    spin = 3.0 * 9.90
    env = LagrangeTopEnv(integrator=integrator, tolerance=None, tilt_limit=math.pi, spin=spin)
    g = (math.sin(tilt), 0.0, math.cos(tilt))
    _, info0 = env.reset(options={"state": top_state(g, (0.0, 0.0, 0.3 * spin))})
    infos = step_all(env, 100)
    assert len(infos) == 100
    for info in infos:
        assert abs(info["tilt"] - tilt) < 1e-9
        assert abs(info["energy"] - info0["energy"]) < 1e-9 * abs(info0["energy"])
        assert abs(info["pi_dot_gamma"] - info0["pi_dot_gamma"]) < 1e-9 * abs(info0["pi_dot_gamma"])


@pytest.mark.parametrize("dt", [1e-6, 0.02, 1.0])
@pytest.mark.parametrize("integrator", ["euler", "rk4", "splitting"])
def test_heavy_top_dt_range(integrator, dt):
    """dt 1e-6 s to 1 s, the default falling top (0.5x critical spin, tilt 0.05): finite for 5
    periods with the guard's steps; |Gamma| exactly kept (projection or exact rotations: 4 eps)."""
    env = LagrangeTopEnv(integrator=integrator, tolerance=None, dt=dt, tilt_limit=math.pi)
    env.reset(seed=0)
    infos = step_all(env, 5)
    for info in infos:
        assert abs(info["vertical_norm"] - 1.0) < 4 * EPS and info["internal_step"] <= dt
        assert not info["numerical_failure"]


# ----------------------------------------------------------------- 5. tippe top extremes
def jellett_drift(infos, info0):
    j0 = info0["jellett"]
    return max(abs(i["jellett"] / j0 - 1) for i in infos)


def test_tippe_top_tilt_zero_and_zero_slip():
    """Tilt exactly 0 with the contact point at rest (zero slip: the Coulomb law at its
    regularised point). The sleeping top is an equilibrium: k stays vertical to round-off,
    the slip stays below 1e-9 m/s, Jellett's integral to 1e-12; 20 periods."""
    env = TippeTopEnv(tilt=0.0)
    obs, info0 = env.reset(seed=0)
    assert info0["tilt"] == 0.0 and info0["slip_speed"] < 1e-15
    infos = step_all(env, 20)
    assert len(infos) == 20
    for info in infos:
        assert info["tilt"] < 1e-9 and info["slip_speed"] < 1e-9 and info["normal_force"] > 0.0
    assert jellett_drift(infos, info0) < 1e-12


def inverted_state(spin):
    """Standing on the stem (theta = pi): G above the centre, at a + h; k = -z (quaternion a
    half turn about x); omega = spin k; the contact point at rest, so v_G = 0."""
    a, h = 0.015, 0.003
    return {
        "position": np.array([0.0, 0.0, a + h]),
        "velocity": np.zeros(3),
        "attitude": np.array([0.0, 1.0, 0.0, 0.0]),
        "angular_velocity": np.array([0.0, 0.0, spin]),
    }


@pytest.mark.parametrize("fidelity", ["gliding", "frictionless", "rolling"])
def test_tippe_top_at_tilt_pi(fidelity):
    """The inverted top spinning on its stem, reached through reset(options={"state"}): an
    equilibrium (stable for J large, docs/physics.md §3): 20 periods, tilt within 1e-9 of pi,
    Jellett to 1e-12, positive normal force m g (no acceleration of G: N = m g to 1e-9)."""
    env = TippeTopEnv(task="hold", fidelity=fidelity)
    _, info0 = env.reset(options={"state": inverted_state(150.0)})
    assert info0["tilt"] == pytest.approx(math.pi, abs=1e-15)
    infos = step_all(env, 20, through_task_end=True)  # hold ends past 90 deg: at once
    assert len(infos) == 20 and all(i["terminal_reason"] == "task" for i in infos)
    for info in infos:
        assert abs(info["tilt"] - math.pi) < 1e-9
        assert info["normal_force"] == pytest.approx(0.006 * 9.81, rel=1e-9)
    assert jellett_drift(infos, info0) < 1e-12


def test_tippe_top_vanishing_normal_force_lifts_off_or_flies():
    """N -> 0: at 1000 rad/s the top's normal force reaches zero within a fraction of a second.
    Contact-only: the episode ends with terminal_reason 'lift_off' (N < 0 at the last internal
    step, finite observation); free flight: hops with the sphere never below the table by more
    than the touchdown tolerance and no energy gain in any period (plastic impact)."""
    # the rolling start (G moving at R n sin(theta)): its normal force vanishes within 60 periods
    env = TippeTopEnv(
        spin=1000.0, tilt=0.3, max_angular_velocity=3000.0, max_speed=50.0, start="rolling"
    )
    env.reset(seed=0)
    infos = step_all(env, 60)
    assert infos[-1]["terminal_reason"] == "lift_off" and infos[-1]["normal_force"] < 0.0
    from rbenvs.dynamics.tippe_top import TOUCHDOWN_TOL

    env = TippeTopEnv(
        spin=1000.0,
        tilt=0.3,
        max_angular_velocity=3000.0,
        max_speed=50.0,
        free_flight=True,
        start="rolling",
    )
    _, info0 = env.reset(seed=0)
    infos = step_all(env, 60)
    assert len(infos) == 60 and infos[-1]["hops"] > 0
    energies = [info0["energy"]] + [i["energy"] for i in infos]
    assert all(b <= a * (1 + 1e-9) for a, b in zip(energies, energies[1:]))
    assert all(i["gap"] >= -TOUCHDOWN_TOL and i["normal_force"] >= 0.0 for i in infos)


@pytest.mark.parametrize("dt", [1e-6, 1.0])
def test_tippe_top_dt_range(dt):
    """dt 1e-6 s (one internal step) and 1 s (the guard takes ~16 000 internal steps: the
    friction bound h_f ~ 6e-5 s): finite, Jellett to its rk4 accuracy (1e-9 relative), the
    reported internal step within the friction and spin bounds. The stability bound's steps,
    whose rule this checks (the default accuracy bound takes about half as many: Jellett to
    1.4e-8 over these 2 s at dt = 1, measured; its own tests: tests/test_tippe_stiff.py)."""
    env = TippeTopEnv(dt=dt, friction_bound="stability")
    _, info0 = env.reset(seed=0)
    infos = step_all(env, 2 if dt == 1.0 else 20)
    assert not any(i["numerical_failure"] or i["lifted_off"] for i in infos)
    assert jellett_drift(infos, info0) < 1e-9
    h = infos[0]["internal_step"]
    assert h <= dt and h * 150.0 * 1.01 <= 0.1 + 1e-12
    assert h <= env.system.max_stable_step(
        get_integrator("rk4"), normal_force=info0["normal_force"]
    )

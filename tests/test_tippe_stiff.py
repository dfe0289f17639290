"""The tippe top's stiff friction: the law's slope, the contact mobility along the slip, the tight
stiffness rate against the vector field's own Jacobian, the W-matrix solve of a linearly implicit
step, and the Rosenbrock-W scheme ROS2 (rbenvs.integrators.rosenbrock) checked as every scheme is:
its stability function, its fitted order, Jellett's integral, the energy, the time to 90 degrees
against the converged value, and its compiled step against the float path bit for bit."""

import math

import gymnasium as gym
import numpy as np
import pytest

import rbenvs  # noqa: F401  (registers the ids)
from rbenvs.bench.tippe_steps import SWEEP, to_ninety
from rbenvs.dynamics.contact import FRICTION_LAWS
from rbenvs.dynamics.tippe_top import contact_arm, tangential_mobility, tippe_frame
from rbenvs.integrators.rosenbrock import ROS2_GAMMA, Ros2, Ros34pw2, transformed

ID = "rbenvs/TippeTop-v0"


@pytest.mark.parametrize("law", sorted(FRICTION_LAWS))
def test_friction_slope_is_the_derivative_of_the_force(law):
    """``dF/ds = k I + slope s s^T`` for ``F = k(s) s`` (per unit normal force), against central
    differences, at slips from far below to far above the regularisation."""
    f = FRICTION_LAWS[law]
    mu, eps = 0.3, 1e-3
    rng = np.random.default_rng(1)
    for scale in (1e-5, 1e-3, 0.3):
        s = rng.normal(size=3) * scale
        k, sl = f.coefficient(mu, *s, eps), f.slope(mu, *s, eps)
        analytic = k * np.eye(3) + sl * np.outer(s, s)
        d = 1e-6 * max(scale, eps)
        numeric = np.empty((3, 3))
        for j in range(3):
            e = np.zeros(3)
            e[j] = d
            fp, fm = (
                f.coefficient(mu, *(s + e), eps) * (s + e),
                f.coefficient(mu, *(s - e), eps) * (s - e),
            )
            numeric[:, j] = (fp - fm) / (2 * d)
        assert np.allclose(analytic, numeric, rtol=1e-7, atol=1e-9 * np.abs(analytic).max())
        assert np.all(np.linalg.eigvalsh(analytic) <= 0.0)  # friction only dissipates


def _mobility(p, gamma):
    """``M = 1/m + [r x]^T I^-1 [r x]`` (dense) and the projector on the table's plane."""
    _, _, m, _, big_a, big_c = p[:6]
    r = np.array(contact_arm(p, *gamma))
    rx = np.array([[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]])
    mob = np.eye(3) / m + rx.T @ np.diag([1 / big_a, 1 / big_a, 1 / big_c]) @ rx
    proj = np.eye(3) - np.outer(gamma, gamma)
    return mob, proj


def test_tangential_mobility_is_the_largest_eigenvalue_along_the_table():
    env = gym.make(ID).unwrapped
    p = env.system.form_params
    a, h, m, big_a = p[0], p[1], p[2], p[4]
    rng = np.random.default_rng(2)
    for theta in (0.0, 1e-9, 0.1, 1.0, math.pi / 2, 2.5, math.pi - 1e-9, math.pi):
        phi = rng.uniform(0, 2 * math.pi)
        gamma = np.array(
            [math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)]
        )
        mob, proj = _mobility(p, gamma)
        q, top = tangential_mobility(p, *gamma)
        assert np.allclose(
            np.array(q).reshape(3, 3), proj @ mob @ proj, rtol=0, atol=1e-12 * np.abs(mob).max()
        )
        assert top == pytest.approx(np.linalg.eigvalsh(proj @ mob @ proj).max(), rel=1e-12)
    # upright (r along the axis): every slip direction sees 1/m + (a - h)^2 / A
    assert tangential_mobility(p, 0.0, 0.0, 1.0)[1] == pytest.approx(
        1 / m + (a - h) ** 2 / big_a, rel=1e-14
    )
    # the old guard's bound (1/m + (a + h)^2 / min(A, C)) lies above it everywhere
    assert tangential_mobility(p, 0.0, 0.0, -1.0)[1] < env.params.contact_mobility()


def _states(start, spin, periods):
    env = gym.make(
        ID, start=start, spin=spin, tilt=0.1, max_episode_steps=5000, compiled=False
    ).unwrapped
    env.reset(seed=0)
    out = []
    action = np.zeros(env.action_space.shape, dtype=np.float32)
    for k in range(max(periods) + 1):
        if k in periods:
            out.append(env.state_components)
        env.step(action)
    return env.system, out


def _jacobian(system, y):
    y = np.array(y)
    jac = np.empty((y.size, y.size))
    for i in range(y.size):
        d = 1e-7 * max(1.0, abs(y[i]))
        yp, ym = y.copy(), y.copy()
        yp[i] += d
        ym[i] -= d
        jac[:, i] = (
            np.array(system.rhs(tuple(yp), None)) - np.array(system.rhs(tuple(ym), None))
        ) / (2 * d)
    return jac


@pytest.mark.parametrize(
    "start,spin,periods",
    [("rolling", 150.0, (0, 100)), ("rest", 180.0, (0, 40, 230)), ("vertical", 180.0, (0, 120))],
)
def test_tight_rate_bounds_the_stiffest_eigenvalue_of_the_vector_field(start, spin, periods):
    """The tight rate (the law's stiffness at the actual normal force and the largest mobility
    along the table) is never below the stiffest decay rate of the vector field's Jacobian
    (central differences), is within 1 % of it near zero slip (rolling), and the guard's rate
    (twice max(m g, N), mobility bound 1/m + (a + h)^2 / min(A, C)) is 3.6 times it there."""
    system, states = _states(start, spin, periods)
    p = system.form_params
    for y in states:
        stiffest = -np.linalg.eigvals(_jacobian(system, y)).real.min()
        tight = system.implicit.rate(p, y, None)
        assert tight >= stiffest * (1 - 1e-4)  # (1e-4: the differences' error)
        if system.slip_speed(y) < 1e-6:  # zero slip: the bound is the rate
            assert tight <= 1.01 * stiffest
            assert system.forms.friction_rate(p, y, None) / tight == pytest.approx(3.62, abs=0.02)


@pytest.mark.parametrize(
    "start,period,gh", [("rolling", 100, 1e-4), ("rest", 40, 1e-3), ("vertical", 120, 1e-2)]
)
def test_w_matrix_solve_matches_the_dense_matrix(start, period, gh):
    """``solve(factor(y, g), x)`` is ``(I - g J)^-1 x`` with ``J`` the Jacobian of the friction's
    contribution with the normal force and ``B`` frozen at ``y`` (dense, central differences of
    the slip), for ``g`` from well below to far above the relaxation time."""
    system, (y,) = _states(start, 180.0, (period,))
    p = system.form_params
    forms = system.implicit
    wf0 = forms.factor(p, y, None, 1.0)
    n = system.constraint_normal_force(y, None)
    law = system.friction

    def slip(z):  # the tangential slip (projected on the frozen plane), body frame
        rm = tippe_frame(*z[4:8])
        w = z[8:11]
        r = contact_arm(p, rm[6], rm[7], rm[8])
        v = np.array([z[2], z[3], -p[1] * (w[1] * rm[6] - w[0] * rm[7])])
        s = np.array(rm).reshape(3, 3).T @ v + np.cross(w, r)
        g = np.array(wf0[6:9])
        return s - (s @ g) * g

    def force_effect(z):  # B (frozen at y) applied to N k(s(z)) s(z)
        s = slip(z)
        f = n * law.coefficient(p[6], *s, p[7]) * s
        rm = np.array(wf0[:9]).reshape(3, 3)
        r = np.array(wf0[9:12])
        dv = rm @ f / p[2]
        dw = np.cross(r, f) / np.array([p[4], p[4], p[5]])
        out = np.zeros(11)
        out[2:4], out[8:11] = dv[:2], dw
        return out

    yv = np.array(y)
    jac = np.empty((11, 11))
    for i in range(11):
        d = 1e-9 * max(1.0, abs(yv[i]))
        yp, ym = yv.copy(), yv.copy()
        yp[i] += d
        ym[i] -= d
        jac[:, i] = (force_effect(yp) - force_effect(ym)) / (2 * d)
    x = np.random.default_rng(3).normal(size=11) * np.abs(yv).clip(1.0)
    z = np.array(forms.solve(p, forms.factor(p, y, None, gh), tuple(x)))
    residual = (np.eye(11) - gh * jac) @ z - x
    assert np.abs(residual).max() <= 1e-6 * np.abs(x).max() * max(1.0, gh * np.abs(jac).max())


class _Linear:
    """``y' = lam y`` with its Jacobian as the W-matrix: a scheme's stability function."""

    dim = 1

    def __init__(self, lam):
        self.kernel_rhs = (lambda P, y, u: (P[0] * y[0],), (lam,))
        self.kernel_implicit = (
            lambda P, y, u, g: 1.0 / (1.0 - g * P[0]),
            lambda P, w, x: (w * x[0],),
            (lam,),
        )
        self.kernel_normalize = (lambda N, y: y, ())


class _Pendulum:
    """A damped pendulum ``(q, p)' = (p, -sin q - 0.3 p)`` with a given constant ``J`` for the
    W-matrix: a W-method keeps its order whatever ``J`` is."""

    dim = 2

    def __init__(self, jac):
        jac = np.array(jac, dtype=float)

        def factor(P, y, u, g):
            return tuple(np.linalg.inv(np.eye(2) - g * jac).ravel())

        self.kernel_rhs = (lambda P, y, u: (y[1], -math.sin(y[0]) - 0.3 * y[1]), ())
        self.kernel_implicit = (
            factor,
            lambda P, w, x: (w[0] * x[0] + w[1] * x[1], w[2] * x[0] + w[3] * x[1]),
            (),
        )
        self.kernel_normalize = (lambda N, y: y, ())


def test_ros2_stability_function_is_l_stable():
    """On ``y' = lam y`` (``J = lam``): ``R(z) = (1 + (1 - 2 gamma) z) / (1 - gamma z)^2``, ``|R| <=
    1`` on the negative real axis, ``R(-inf) = 0`` (L-stable)."""
    scheme = Ros2()
    assert ROS2_GAMMA**2 - 2 * ROS2_GAMMA + 0.5 == pytest.approx(0.0, abs=1e-15)
    for z in (-1e-3, -0.5, -1.0, -2.785, -10.0, -1e3, -1e6):
        r = scheme.step(_Linear(z), (1.0,), None, 1.0)[0]
        assert r == pytest.approx(
            (1 + (1 - 2 * ROS2_GAMMA) * z) / (1 - ROS2_GAMMA * z) ** 2, rel=1e-12
        )


def test_ros34pw2_is_stiffly_accurate():
    """Its weights are its last stage's (``b_i = alpha_4i + gamma_4i``, ``b_4 = gamma``): the
    transformed weights ``m`` are the last row of ``a`` and a 1, so the step ends on the last
    stage's value."""
    s = Ros34pw2
    assert np.allclose(s.m[:3], s.a[3], rtol=1e-14, atol=0) and s.m[3] == 1.0
    a, c, m = transformed(
        [[0, 0], [1, 0]], [[2.0, 0], [-1.0, 2.0]], [0.5, 0.5]
    )  # a hand-computed case
    assert (
        np.allclose(a, [[0, 0], [0.5, 0]])
        and np.allclose(c, [[0, 0], [-0.25, 0]])
        and np.allclose(m, [0.375, 0.25])
    )


@pytest.mark.parametrize("scheme", [Ros2(), Ros34pw2()], ids=lambda s: s.name)
def test_rosenbrock_w_stability_and_order(scheme):
    """L-stable (``|R(z)| <= 1`` on the negative real axis, ``R(-inf) -> 0``), and the declared
    order on a nonlinear problem for ``J = 0`` (the explicit limit), an arbitrary ``J`` and the
    exact Jacobian at the start (fitted over two halvings from 160 steps, against scipy's DOP853 at
    rtol 1e-13)."""
    for z in (-1e-3, -0.5, -1.0, -2.785, -10.0, -1e3, -1e6):
        assert abs(scheme.step(_Linear(z), (1.0,), None, 1.0)[0]) <= 1.0
    assert abs(scheme.step(_Linear(-1e12), (1.0,), None, 1.0)[0]) < 1e-10
    from scipy.integrate import solve_ivp

    ref = solve_ivp(
        lambda t, y: [y[1], -math.sin(y[0]) - 0.3 * y[1]],
        (0, 2),
        [1.0, 0.5],
        method="DOP853",
        rtol=1e-13,
        atol=1e-13,
    ).y[:, -1]
    for jac in ([[0, 0], [0, 0]], [[0.3, -1.1], [2.0, -0.7]], [[0, 1], [-math.cos(1.0), -0.3]]):
        step = scheme.bind(_Pendulum(jac), 2)
        errs = []
        for n in (160, 320, 640):
            y = (1.0, 0.5)
            for _ in range(n):
                y = step(y, None, 2.0 / n)
            errs.append(np.abs(np.array(y) - ref).max())
        orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
        assert np.all(np.abs(orders - scheme.order) < 0.1), orders


def _run(n, start="vertical", spin=180.0, periods=30, integrator=None, compiled=False, **kw):
    env = gym.make(
        ID,
        start=start,
        spin=spin,
        tilt=0.1,
        integrator=integrator or Ros2(),
        guard="off",
        substeps=n,
        compiled=compiled,
        max_episode_steps=5000,
        **kw,
    ).unwrapped
    _, info = env.reset(seed=0)
    j0, e0 = info["jellett"], info["energy"]
    e_prev, rise, drift = e0, 0.0, 0.0
    action = np.zeros(env.action_space.shape, dtype=np.float32)
    for _ in range(periods):
        _, _, term, _, info = env.step(action)
        assert not term
        rise = max(rise, info["energy"] - e_prev)
        e_prev = info["energy"]
        drift = max(drift, abs(info["jellett"] - j0) / abs(j0))
    return np.array(env.state_components), drift, rise


@pytest.mark.parametrize("scheme", [Ros2(), Ros34pw2()], ids=lambda s: s.name)
@pytest.mark.parametrize(
    "start,spin,law",
    [("vertical", 180.0, "coulomb"), ("rest", 180.0, "coulomb"), ("rest", -150.0, "viscous")],
)
def test_rosenbrock_w_on_the_tippe_top_converges_keeps_jellett_and_dissipates(
    scheme, start, spin, law
):
    """Over 0.3 s against rk4 at 400 steps a period (its error below 1e-11 here): the error of the
    state falls at the declared order per halving of the step (fitted within 0.3), Jellett's
    integral drifts less and less and the energy never rises, from two starts, both spin signs
    and both laws (viscous: ``mu`` in s/m)."""
    friction = 0.3 if law == "coulomb" else 30.0
    ref, _, _ = _run(400, start, spin, integrator="rk4", friction_law=law, friction=friction)
    errs, drifts = [], []
    for n in (40, 80, 160):
        y, drift, rise = _run(
            n, start, spin, integrator=scheme, friction_law=law, friction=friction
        )
        errs.append(np.abs(y - ref).max())
        drifts.append(drift)
        assert rise <= 1e-15
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(np.abs(orders - scheme.order) < 0.3), orders
    assert drifts[-1] < drifts[0] / 10 and drifts[-1] < 1e-5


@pytest.mark.parametrize(
    "scheme,free_flight",
    [(Ros2(), False), (Ros34pw2(), False), (Ros34pw2(), True)],
    ids=["ros2", "ros34pw2", "ros34pw2-flight"],
)
def test_rosenbrock_w_compiled_step_is_the_float_step_bit_for_bit(scheme, free_flight):
    y_c, _, _ = _run(
        25, "rest", periods=10, integrator=scheme, compiled=True, free_flight=free_flight
    )
    y_f, _, _ = _run(
        25, "rest", periods=10, integrator=scheme, compiled=False, free_flight=free_flight
    )
    assert np.array_equal(y_c, y_f)


def test_steps_bench_measures_an_inversion_and_the_tight_count():
    """``python -m rbenvs.bench.tippe_steps``' pieces: the tight count is rk4's real-axis interval
    over the tight rate at the start (recomputed here from the dense mobility), and a row from
    the vertical start (which passes 90 degrees while still sliding) agrees with the converged
    value of the same model (rk4 at 160 steps) and keeps the energy from rising."""
    from rbenvs.bench import tippe_steps

    env = gym.make(ID, start="rolling", spin=150.0, tilt=0.1).unwrapped
    env.reset(seed=0)
    y, p = env.state_components, env.system.form_params
    rm = tippe_frame(*y[4:8])
    mob, proj = _mobility(p, np.array(rm[6:9]))
    rate = (
        p[6]
        * env.system.constraint_normal_force(y, None)
        * np.linalg.eigvalsh(proj @ mob @ proj).max()
        / p[7]
    )
    assert (
        tippe_steps.tight_count("rolling", 150.0) == math.ceil(env.dt * rate / 2.785) == 23
    )  # (above the spin bound's 16)
    spin = math.sqrt(
        sum(w * w for w in y[8:11])
    )  # viscous (30 s/m: 620/s, 3 steps): the spin bound, 0.1 rad a step
    assert tippe_steps.tight_count("rolling", 150.0, "viscous") == math.ceil(env.dt * spin / 0.1)
    fine = tippe_steps.inversion("vertical", 180.0, 160, compiled=False)
    coarse = tippe_steps.inversion("vertical", 180.0, 20, compiled=False)
    assert fine["ended"] is None and coarse["ended"] is None and coarse["steps"] == 20.0
    assert (
        abs(coarse["t90"] - fine["t90"]) < 1e-6 and coarse["rise"] <= 0.0 and coarse["drift"] < 1e-6
    )
    assert "| vertical | 180 |" in tippe_steps.table(
        [
            dict(
                coarse,
                start="vertical",
                spin=180.0,
                law="coulomb",
                scheme="rk4",
                count=20,
                error=0.0,
            )
        ]
    )


@pytest.mark.parametrize("start,spin,periods", [("rest", 180.0, 290), ("vertical", 180.0, 90)])
def test_guard_rate_bounds_the_tight_rate_within_every_period_of_an_inversion(start, spin, periods):
    """The guard sizes a period's steps from its start, and the normal force moves within the
    period (most in the fast rise, where it swings between 0.55 and 1.4 m g): over a whole
    inversion the tight rate inside a period exceeds its value at the period's start by up to
    about twice (measured 1.77 from rest, 2.10 from the rolling start, not run here: 7 s), and
    the guard's rate (twice max(m g, N), the mobility bound) stays above the tight rate at every
    internal step of every period."""
    from rbenvs.integrators import RK4

    env = gym.make(ID, start=start, spin=spin, tilt=0.1, compiled=False).unwrapped
    env.reset(seed=0)
    system, p = env.system, env.system.form_params
    y = env.state_components
    step = RK4().bind(system, system.dim)
    n = 160
    growth = 0.0
    for _ in range(periods):
        guard, tight0 = system.forms.friction_rate(p, y, None), system.implicit.rate(p, y, None)
        for _ in range(n):
            y = step(y, None, env.dt / n)
            tight = system.implicit.rate(p, y, None)
            assert tight < guard
            growth = max(growth, tight / tight0)
    assert math.degrees(system.tilt(y)) > 90.0  # the whole rise was visited
    assert 1.0 < growth < 2.0


@pytest.mark.parametrize(
    "start,spin,law,friction",
    [
        ("rolling", 150.0, "coulomb", 0.3),
        ("rest", -180.0, "coulomb", 0.3),
        ("vertical", 180.0, "coulomb", 0.3),
        ("rolling", 150.0, "coulomb", 0.1),
        ("rest", 180.0, "viscous", 30.0),
    ],
)
def test_accuracy_bound_inverts_as_the_converged_model_with_fewer_steps(start, spin, law, friction):
    """``friction_bound="accuracy"`` against the default guard, whose time to 90 degrees is within
    2e-6 s of the converged one from these starts (tests/test_tippe_starts.py refines it;
    ``python -m rbenvs.bench.tippe_steps``): the same outcome, the time to 90 degrees within
    1e-4 s, Jellett's drift below 1e-8 under Coulomb friction, the energy never rising, and at
    the default friction fewer steps (0.40-0.85 of them; the sweep of tops below holds the rule
    across the inversion band)."""
    from rbenvs.bench import tippe_steps

    base = tippe_steps.inversion(start, spin, None, law=law, compiled=False, friction=friction)
    fast = tippe_steps.inversion(
        start, spin, "accuracy", law=law, compiled=False, friction=friction
    )
    assert base["ended"] is None and fast["ended"] is None
    assert abs(fast["t90"] - base["t90"]) < 1e-4
    assert fast["rise"] <= 0.0 and (
        fast["drift"] < 1e-8 or law == "viscous"
    )  # viscous: the spin bound sets both
    if law == "coulomb":
        # at the default friction 0.40-0.85 of the guard's counts (measured: a sliding top's
        # friction is not stiff); at 0.1 the friction is softer and the accuracy term sets them
        # (1.22 times)
        assert fast["steps"] < (1.0 if friction == 0.3 else 1.6) * base["steps"]
    # viscous (620/s here): the spin bound sets the default count; the rule's mixed term adds steps
    # (1.57 times)
    else:
        assert base["steps"] < fast["steps"] < 2.0 * base["steps"]


@pytest.mark.parametrize("start,spin", [("rest", 180.0), ("rolling", 150.0)])
def test_accuracy_bound_is_its_rule_compiled_as_on_floats_and_is_checked(start, spin):
    """The first period's count is ``ceil(dt lambda_a / (0.45 * 2.78))``, ``lambda_a(x) = max(x, K
    sqrt(x w))``, ``w = max(|Omega|, omega_g)``, ``K`` the law's scale (Coulomb 19, viscous 10.4),
    from the tight rate ``lambda_d`` (recomputed here from the dense mobility): from the rolling
    start (zero slip: the law's full stiffness) ``lambda_a(lambda_d)``; from rest (sliding at
    about 270 eps: the saturated friction is not stiff) the rotation's floor ``min(50 w,
    lambda_a(lambda_d))``. The compiled step takes the float path's states and counts."""
    from rbenvs.dynamics.contact import FRICTION_LAWS
    from rbenvs.dynamics.tippe_top import ACCURACY_MARGIN, JELLETT_SCALE

    assert (
        FRICTION_LAWS["coulomb"].accuracy_scale == 19.0
        and FRICTION_LAWS["viscous"].accuracy_scale == 10.4
    )

    out = []
    for compiled in (True, False):
        env = gym.make(
            ID, start=start, spin=spin, friction_bound="accuracy", compiled=compiled
        ).unwrapped
        env.reset(seed=0)
        y, p = env.state_components, env.system.form_params
        rm = tippe_frame(*y[4:8])
        mob, proj = _mobility(p, np.array(rm[6:9]))
        lam = (
            p[6]
            * env.system.constraint_normal_force(y, None)
            * np.linalg.eigvalsh(proj @ mob @ proj).max()
            / p[7]
        )
        w = max(np.linalg.norm(y[8:11]), env.params.gravity_rate())
        lam_a = max(lam, env.system.friction.accuracy_scale * math.sqrt(lam * w))
        if start == "rest":
            lam_a = min(lam_a, JELLETT_SCALE * w)
        counts = []
        for _ in range(10):
            _, _, _, _, info = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
            counts.append(round(env.dt / info["internal_step"]))
        assert counts[0] == math.ceil(env.dt * lam_a / (ACCURACY_MARGIN * 2.78))
        out.append((np.array(env.state_components), counts))
    assert np.array_equal(out[0][0], out[1][0]) and out[0][1] == out[1][1]
    with pytest.raises(ValueError, match="friction_bound must be one of"):
        gym.make(ID, friction_bound="tight")


def test_accuracy_bound_takes_the_stiffness_at_the_periods_smallest_slip():
    """From rest at 150 rad/s the slip falls from 225 eps to the rolling band (0.4-0.5 eps) within
    three periods; each period's count is ``ceil(dt max(lambda_a(kappa' lambda_d), min(lambda_a(
    lambda_d), 50 w)) / 1.25)``, ``kappa' = min(1, 4 kappa)``, ``kappa = eps / sqrt(r^2 +
    eps^2)`` at the smallest slip the period can reach, ``r = |s| + 2 dt min(d|s|/dt, 0)``, here
    recomputed from the state: ``d|s|/dt`` by central differences of the slip along the vector
    field, ``lambda_d`` the tight rate. The three branches occur: the floor while the slip is
    far outside the band (60 steps), the reduced stiffness above the floor (73), the whole rate
    where the slip can close within the period or lies in the band (145-146)."""
    from rbenvs.dynamics.tippe_top import ACCURACY_MARGIN, JELLETT_SCALE, STIFF_BAND

    env = gym.make(ID, start="rest", spin=150.0, compiled=False).unwrapped
    env.reset(seed=0)
    system, p = env.system, env.system.form_params
    eps, scale = p[7], system.friction.accuracy_scale
    branches = set()
    for _ in range(12):
        y = env.state_components
        slip = system.forms.slip_speed(p, y)
        f, x, d = np.array(system.rhs(y, None)), np.array(y), 1e-7
        closing = (
            system.forms.slip_speed(p, tuple(x + d * f))
            - system.forms.slip_speed(p, tuple(x - d * f))
        ) / (2.0 * d)
        reach = max(slip + 2.0 * env.dt * min(closing, 0.0), 0.0)
        kappa = min(1.0, STIFF_BAND * eps / math.sqrt(reach * reach + eps * eps))
        lam_d = system.implicit.rate(p, y, None)
        w = max(np.linalg.norm(y[8:11]), env.params.gravity_rate())
        reduced = max(kappa * lam_d, scale * math.sqrt(kappa * lam_d * w))
        floor = min(max(lam_d, scale * math.sqrt(lam_d * w)), JELLETT_SCALE * w)
        _, _, _, _, info = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
        n = round(env.dt / info["internal_step"])
        assert n == math.ceil(env.dt * max(reduced, floor) / (ACCURACY_MARGIN * 2.78))
        branches.add("whole" if kappa == 1.0 else ("reduced" if reduced > floor else "floor"))
    assert branches == {"floor", "reduced", "whole"}


def test_tippe_sweep_bench_prints_each_top_against_its_reference(monkeypatch, capsys):
    """``rbenvs bench accuracy --tippe-sweep`` (the docs' figures of the sweep below): a row per
    top with its time to 90 degrees, the error against rk4 at 2560 steps a period, Jellett's
    drift per second and the steps a period, and the largest of each (here one top, the
    fastest, for time)."""
    from rbenvs.bench import tippe_steps
    from rbenvs.bench.accuracy.command import main

    monkeypatch.setattr(tippe_steps, "SWEEP", [(0.3, 0.9)])
    assert main(["--tippe-sweep"]) == 0
    lines = capsys.readouterr().out.splitlines()
    rows = [line.split("|")[1:-1] for line in lines if line.startswith("| 0.3 |")]
    assert len(rows) == 1
    alpha, ratio, t90, error, drift, steps = (float(x) for x in rows[0])
    assert (alpha, ratio) == (0.3, 1.27) and 0.9 < t90 < 1.1
    assert error < 1e-4 and drift < 3e-9 and 0 < steps < 200
    assert lines[-1].startswith("largest t90 error")


# viscous friction (30 s/m, from rest at 180 rad/s: the stiff case of the test above) across alpha
VISCOUS = dict(friction_law="viscous", friction=30.0, spin=180.0)


@pytest.mark.parametrize(
    "alpha,f",
    [(0.1, -0.5), (0.2, 0.0), (0.3, 0.5)],
    ids=["alpha0.1-AC0.950", "alpha0.2-AC1.000", "alpha0.3-AC1.150"],
)
def test_accuracy_bound_holds_t90_under_viscous_friction(alpha, f):
    """Viscous friction is linear in the slip everywhere (no creeping phase near rolling): its
    scale 10.4 holds the time to 90 degrees within 1e-4 s of rk4 at 2560 fixed steps a period
    (measured at most 2.3e-6 s over nine tops at 30 s/m and 5.1e-6 s at 3 s/m; Coulomb's 19 would
    take 1.8 times the steps)."""
    t90, _, _ = to_ninety(alpha, f, **VISCOUS)
    t90_ref, _, _ = to_ninety(alpha, f, guard="off", substeps=2560, **VISCOUS)
    assert abs(t90 - t90_ref) < 1e-4, (t90, t90_ref)


@pytest.mark.slow
@pytest.mark.parametrize("alpha,f", SWEEP, ids=[f"alpha{a}-AC{1 + f * a:.3f}" for a, f in SWEEP])
def test_accuracy_bound_holds_t90_and_jellett_over_a_sweep_of_tops(alpha, f):
    """The default guard (``friction_bound="accuracy"``, rk4) on 15 tops against rk4 at 2560 fixed
    steps a period (converged to about 1e-8 s in t90: 1280 and 2560 differ by at most 8e-9 s; the
    differences fall 16-fold a doubling from 320): the time to 90 degrees within 1e-4 s (measured
    at most 5.2e-5 s, alpha 0.3, A/C 0.76, which rises for 15 s near rolling; the scale 10.4
    fitted on the default top alone had let a top pass 5.1e-4 s), and Jellett's drift at most
    3e-9 per simulated second up to 90 degrees (measured at most 2.7e-9/s, alpha 0.1, A/C 0.95:
    the drift gathers while the top rolls, so a top that rises slowly drifts more in all; the
    fast tops' drift, 1-2e-9/s, is the sliding phase's, at the rotation's floor)."""
    t90, drift, steps = to_ninety(alpha, f)
    t90_ref, _, _ = to_ninety(alpha, f, guard="off", substeps=2560)
    assert abs(t90 - t90_ref) < 1e-4, (t90, t90_ref)
    assert drift < 3e-9 * t90, (drift, t90)
    assert steps < 200  # (the accuracy bound's count, 70-162 a period here: not the reference's)

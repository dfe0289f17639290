"""The free rigid body (docs/physics.md §1): vector field, parameters, exact elliptic flow,
attitude.

References are independent of the code under test: the DOP853 reference integrates a
numpy-cross-product form of Euler's equations, not ``FreeBody.rhs``.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from rbenvs.dynamics import FreeBody, FreeBodyOrbit, FreeBodyParams
from rbenvs.integrators import get_integrator
from rbenvs.rotations import quat_multiply, quat_random, quat_rotate

EPS = np.finfo(float).eps


# ---------------------------------------------------------------------------- helpers
def random_inertia(rng, low=0.2, high=1.0):
    """Principal moments obeying the triangle inequalities (rejection sampling)."""
    while True:
        inertia = rng.uniform(low, high, 3)
        if np.all(inertia.sum() - inertia >= inertia):
            return tuple(float(x) for x in inertia)


def random_momentum(rng, inertia, omega):
    """A random direction with |Omega| of order ``omega`` rad/s."""
    d = rng.standard_normal(3)
    d /= np.linalg.norm(d)
    return tuple(float(x) for x in d * omega * float(np.mean(inertia)))


def euler_cross(inertia, pi):
    """dPi/dt = Pi x Omega (docs/physics.md §1) written with np.cross, independent of
    FreeBody.rhs."""
    return np.cross(pi, pi / np.asarray(inertia))


def dop853(inertia, y0, t_eval, rtol=1e-13, attitude=False, dense=False):
    """Reference solution with solve_ivp DOP853, atol = rtol |Pi| (and rtol on the quaternion)."""
    inertia = np.asarray(inertia, dtype=float)
    y0 = np.asarray(y0, dtype=float)
    n = np.linalg.norm(y0[:3])

    def fun(_t, y):
        dpi = euler_cross(inertia, y[:3])
        if not attitude:
            return dpi
        w, x, yy, z = y[3:]
        o1, o2, o3 = y[:3] / inertia
        dq = 0.5 * np.array(
            [
                -x * o1 - yy * o2 - z * o3,
                w * o1 + yy * o3 - z * o2,
                w * o2 - x * o3 + z * o1,
                w * o3 + x * o2 - yy * o1,
            ]
        )
        return np.concatenate([dpi, dq])

    atol = np.full(y0.size, rtol * n)
    if attitude:
        atol[3:] = rtol
    t_end = float(np.max(t_eval)) if t_eval is not None else None
    sol = solve_ivp(
        fun,
        (0.0, t_end),
        y0,
        method="DOP853",
        rtol=rtol,
        atol=atol,
        t_eval=None if dense else t_eval,
        dense_output=dense,
    )
    assert sol.success
    return sol


def energy(inertia, pi):
    return 0.5 * sum(p * p / i for p, i in zip(pi, inertia))


# ---------------------------------------------------------------------------- vector field
def test_rhs_is_cross_product_plus_torque():
    rng = np.random.default_rng(10)
    for _ in range(5):
        inertia = random_inertia(rng)
        body = FreeBody(FreeBodyParams(inertia))
        pi = rng.standard_normal((3, 50)) * 3.0
        tau = rng.standard_normal((3, 50))
        want = euler_cross(inertia, pi.T).T
        # Products of O(1-10) numbers in a different association: ~10 ulp of |Pi|^2/I.
        tol = 64 * EPS * np.max(np.abs(want))
        np.testing.assert_allclose(np.array(body.rhs(tuple(pi), None)), want, atol=tol)
        np.testing.assert_allclose(np.array(body.rhs(tuple(pi), tuple(tau))), want + tau, atol=tol)
        # The float path gives floats and the same numbers as the batch path.
        single = body.rhs(tuple(float(c) for c in pi[:, 0]), tuple(float(c) for c in tau[:, 0]))
        assert all(isinstance(c, float) for c in single)
        np.testing.assert_array_equal(single, np.array(body.rhs(tuple(pi), tuple(tau)))[:, 0])


def test_quaternion_rhs_is_half_q_times_omega():
    rng = np.random.default_rng(11)
    inertia = random_inertia(rng)
    body = FreeBody(FreeBodyParams(inertia), attitude=True)
    assert body.dim == 7
    pi = tuple(rng.standard_normal((3, 20)) * 2.0)
    q = quat_random(rng, (20,))
    tau = tuple(rng.standard_normal((3, 20)))
    d = body.rhs(pi + q, tau)
    omega = tuple(p / i for p, i in zip(pi, inertia))
    want = quat_multiply(q, (0.0 * pi[0], *omega))
    for got, w in zip(d[3:], want):
        # A sum of three products of O(1) numbers: a few ulp of |Omega|.
        np.testing.assert_allclose(got, 0.5 * w, atol=16 * EPS * np.max(np.abs(omega)))
    # The Pi part is the same with or without attitude.
    plain = FreeBody(FreeBodyParams(inertia)).rhs(pi, tau)
    for a, b in zip(d[:3], plain):
        np.testing.assert_array_equal(a, b)


# ---------------------------------------------------------------------------- parameters
@pytest.mark.parametrize(
    "bad",
    [
        (0.0, 1.0, 1.0),
        (-1.0, 1.0, 1.0),
        (1.0, 1.0, -0.5),
        (float("nan"), 1.0, 1.0),
        (1.0, float("inf"), 1.0),
        (1.0, 2.0),
        (1.0, 2.0, 3.0, 4.0),
        ((1.0, 2.0, 3.0),),
        "abc",
        (1.0, 1.0, 2.5),  # I1 + I2 < I3
        (3.0, 1.0, 1.5),  # I2 + I3 < I1
        (1.0, 5.0, 2.0),  # I3 + I1 < I2
        (1.0, 1.0, 2.0 + 1e-9),  # just beyond a flat plate
    ],
)
def test_params_reject_invalid_inertia(bad):
    with pytest.raises(ValueError, match="inertia"):
        FreeBodyParams(bad)


@pytest.mark.parametrize(
    "good",
    [
        (1.0, 2.0, 3.0),  # flat plate: I1 + I2 = I3 exactly
        (3.0, 1.0, 2.0),
        (0.1, 0.2, 0.3),  # flat plate in decimals (0.1 + 0.2 != 0.3 in floating point)
        (0.3, 0.6, 0.9),  # 0.3 + 0.6 = 0.8999999999999999 < 0.9: within the ulp slack
        (1.0, 1.0, 1.0),
        (2.0, 2.0, 1.0),
        (1.0, 2.0, 2.0),
        [0.5, 0.7, 0.9],
        np.array([0.5, 0.7, 0.9]),
    ],
)
def test_params_accept_valid_inertia(good):
    params = FreeBodyParams(good)
    assert params.inertia == tuple(float(x) for x in good)
    assert all(isinstance(x, float) for x in params.inertia)


# ---------------------------------------------------------------------------- exact flow
def _random_cases():
    rng = np.random.default_rng(12)
    cases = [random_inertia(rng) for _ in range(32)]
    for base in [
        (1.0, 1.0, 0.999),
        (1.0, 0.999, 0.999),
        (1.0, 0.9995, 0.999),
        (1.0, 1.0, 0.5),
        (1.0, 0.5, 0.5),
    ]:
        cases.extend(sorted(set(itertools.permutations(base))))
    cases.append((1.0, 1.0, 1.0))
    return cases


EXACT_CASES = _random_cases()


@pytest.mark.parametrize("case", range(len(EXACT_CASES)))
def test_exact_solution_matches_dop853(case):
    inertia = EXACT_CASES[case]
    rng = np.random.default_rng(1000 + case)
    pi0 = random_momentum(rng, inertia, rng.uniform(1.0, 5.0))
    t = np.linspace(0.0, 100.0, 41)
    ref = dop853(inertia, pi0, t).y
    orbit = FreeBodyOrbit(FreeBodyParams(inertia), pi0)
    got = np.array(orbit.momentum_at(t))
    n0 = np.linalg.norm(pi0)
    # DOP853 at rtol 1e-13 drifts ~1e-12 |Pi| per period; over 100 time units at |Omega| <= 5
    # that is <= ~5e-11 (measured), so 1e-10 is the reference's accuracy, not the exact flow's.
    assert np.max(np.abs(got - ref)) / n0 <= 1e-10
    # Invariants along the exact solution: ulp-level (each value one sn/cn/dn evaluation).
    np.testing.assert_allclose(np.sqrt(np.sum(got**2, axis=0)), n0, rtol=1e-14)
    np.testing.assert_allclose(energy(inertia, got), energy(inertia, pi0), rtol=1e-13)


FAST_CASES = [
    ((0.9, 0.6, 0.5), 1e2),
    ((1.0, 0.999, 0.998), 1e3),
    ((0.3, 0.5, 0.7), 1e4),
    ((1.0, 1.0, 0.5), 1e4),
]


@pytest.mark.parametrize("inertia, omega", FAST_CASES)
def test_exact_solution_fast_spin(inertia, omega):
    """|Omega| = 1e2..1e4 rad/s over 100 periods (DOP853 covers the same number of periods,
    so its error is that of the slow problem: Pi -> lambda Pi, t -> t / lambda is a symmetry)."""
    rng = np.random.default_rng(int(omega))
    pi0 = random_momentum(rng, inertia, omega)
    params = FreeBodyParams(inertia)
    orbit = FreeBodyOrbit(params, pi0)
    period = float(orbit.period)
    t = np.linspace(0.0, 100.0 * period, 21)
    # rtol 3e-14 (scipy's floor is 2.2e-14): at 1e-13 the reference alone drifts 1-2e-10 in
    # 100 periods (measured); at 3e-14 it stays <= 4e-11.
    ref = dop853(inertia, pi0, t, rtol=3e-14).y
    got = np.array(orbit.momentum_at(t))
    n0 = np.linalg.norm(pi0)
    assert np.max(np.abs(got - ref)) / n0 <= 1e-10
    # The scaling symmetry holds for the exact solution itself to round-off: the elliptic
    # argument u = tau0 + nu t is the same up to a few ulp of |u| ~ 4K * 100 (~1e-13).
    lam = omega
    slow = FreeBodyOrbit(params, tuple(p / lam for p in pi0))
    scaled = lam * np.array(slow.momentum_at(t * lam))
    assert np.max(np.abs(scaled - got)) / n0 <= 1e-12
    assert float(slow.period) / lam == pytest.approx(period, rel=1e-13)  # K and nu scale exactly


def test_exact_steps_compose_to_direct_evaluation():
    """100 steps of the 'exact' integrator equal one evaluation at T (the flow is a group)."""
    rng = np.random.default_rng(13)
    integ = get_integrator("exact")
    for inertia in [random_inertia(rng) for _ in range(4)] + [(1.0, 1.0, 0.5), (1.0, 0.999, 0.998)]:
        params = FreeBodyParams(inertia)
        body = FreeBody(params)
        pi0 = np.array([random_momentum(rng, inertia, rng.uniform(1.0, 5.0)) for _ in range(16)]).T
        y = tuple(pi0)
        h, steps = 0.13, 100
        for _ in range(steps):
            y = integ.step(body, y, None, h)
        direct = np.array(FreeBodyOrbit(params, tuple(pi0)).momentum_at(h * steps))
        rel = np.max(np.abs(np.array(y) - direct), axis=0) / np.linalg.norm(pi0, axis=0)
        # Each step restarts from a rounded state: 100 * a few ulp, plus the conditioning
        # of the phase (tau0) through the step, measured <~1e-13.
        assert np.max(rel) <= 1e-11


# ---------------------------------------------------------------------------- separatrix
# With (I_major, I_mid, I_minor) = (3, 2, 1.5) the two separatrix terms (3-2)/3 and (1.5-2)/1.5
# round to the same +-1/3, so Pi = (p, q, p) lies on |Pi|^2 = 2 H I2 exactly in floating point.
SEPARATRIX_INERTIAS = sorted(set(itertools.permutations((3.0, 2.0, 1.5))))


def _separatrix_state(inertia, p, q, signs=(1.0, 1.0, 1.0)):
    i_mid = inertia.index(2.0)
    pi = [signs[0] * p, 0.0, signs[2] * p]
    out = [0.0, 0.0, 0.0]
    others = [i for i in range(3) if i != i_mid]
    out[others[0]], out[others[1]] = pi[0], pi[2]
    out[i_mid] = signs[1] * q
    return tuple(out), i_mid


@pytest.mark.parametrize("inertia", SEPARATRIX_INERTIAS)
@pytest.mark.parametrize("signs", [(1, 1, 1), (-1, 1, 1), (1, -1, -1), (-1, -1, 1)])
def test_exact_flow_on_separatrix(inertia, signs):
    pi0, i_mid = _separatrix_state(inertia, 2.0, 4.0, signs)
    params = FreeBodyParams(inertia)
    orbit = FreeBodyOrbit(params, pi0)
    n0 = math.sqrt(sum(p * p for p in pi0))
    assert float(orbit.m1) == 0.0  # the construction is exactly on the separatrix
    assert float(orbit.period) == math.inf  # heteroclinic: no period
    # Short horizon: the separatrix is hyperbolic (rate ~0.8 here), so reference errors grow
    # like e^{0.8 t}; at t = 3 DOP853's 1e-13 becomes ~1e-12, far inside 1e-10.
    t = np.linspace(0.0, 3.0, 31)
    ref = dop853(inertia, pi0, t).y
    got = np.array(orbit.momentum_at(t))
    assert np.max(np.abs(got - ref)) / n0 <= 1e-10
    # Heteroclinic limit: Pi(t) -> +-|Pi| e_mid as t -> +inf and the opposite one as t -> -inf.
    # lambda = |Omega2| sqrt((I1-I2)(I2-I3)/(I1 I3)) = 0.82 here: distance ~ e^{-33} at t = 40.
    lam = (n0 / 2.0) * math.sqrt((3.0 - 2.0) * (2.0 - 1.5) / (3.0 * 1.5))
    assert lam * 40.0 > 30.0
    ends = []
    for t_end in (40.0, -40.0):
        pi_end = np.array([float(x) for x in orbit.momentum_at(t_end)])
        target = np.zeros(3)
        target[i_mid] = math.copysign(n0, pi_end[i_mid])
        assert np.linalg.norm(pi_end - target) < 1e-6 * n0
        ends.append(pi_end[i_mid])
    assert ends[0] * ends[1] < 0.0  # the orbit joins the two opposite equilibria


@pytest.mark.parametrize("inertia", SEPARATRIX_INERTIAS)
@pytest.mark.parametrize("delta", [1e-12, -1e-12])
def test_exact_flow_near_separatrix(inertia, delta):
    """Within 1e-12 (relative) of the separatrix, on either side (both orbit families)."""
    pi_sep, i_mid = _separatrix_state(inertia, 2.0, 4.0)
    pi0 = list(pi_sep)
    i_other = [i for i in range(3) if i != i_mid][0]
    pi0[i_other] *= 1.0 + delta
    pi0 = tuple(pi0)
    n2 = sum(p * p for p in pi0)
    dist = n2 - 2.0 * energy(inertia, pi0) * 2.0
    assert 0.0 < abs(dist) / n2 < 1e-11  # really within ~1e-12 of the separatrix
    orbit = FreeBodyOrbit(FreeBodyParams(inertia), pi0)
    assert 0.0 < float(orbit.m1) < 1e-10
    t = np.linspace(0.0, 3.0, 31)
    ref = dop853(inertia, pi0, t).y
    got = np.array(orbit.momentum_at(t))
    # As on the separatrix: short hyperbolic horizon, reference error ~1e-12.
    assert np.max(np.abs(got - ref)) / math.sqrt(n2) <= 1e-10


# ---------------------------------------------------------------------------- period
def _zero_crossings(sol, component, t_end, n_grid=4000):
    t = np.linspace(0.0, t_end, n_grid)
    v = sol.sol(t)[component]
    roots = []
    for k in np.nonzero(np.sign(v[:-1]) * np.sign(v[1:]) < 0)[0]:
        roots.append(
            brentq(lambda s: sol.sol(s)[component], t[k], t[k + 1], xtol=1e-15, rtol=4 * EPS)
        )
    return np.array(roots)


@pytest.mark.parametrize("seed", range(6))
def test_period_matches_dop853_zero_crossings(seed):
    rng = np.random.default_rng(200 + seed)
    inertia = random_inertia(rng)
    pi0 = random_momentum(rng, inertia, rng.uniform(1.0, 3.0))
    orbit = FreeBodyOrbit(FreeBodyParams(inertia), pi0)
    period = float(orbit.period)
    # The orbit circulates the major axis if |Pi|^2 > 2 H I_mid, else the minor one; the
    # component along the other extreme axis is the cn one: it has two zeros per period.
    i_major, i_mid, i_minor = np.argsort(inertia)[::-1]
    circulates_major = sum(p * p for p in pi0) > 2.0 * energy(inertia, pi0) * inertia[i_mid]
    comp = i_minor if circulates_major else i_major
    sol = dop853(inertia, pi0, np.array([6.2 * period]), dense=True)
    roots = _zero_crossings(sol, comp, 6.2 * period)
    assert len(roots) >= 11
    n_half = len(roots) - 1
    measured = 2.0 * (roots[-1] - roots[0]) / n_half
    # Root positions from the dense output carry ~1e-12 relative error; spanning 5+ periods.
    assert period == pytest.approx(measured, rel=1e-8)
    # Pi is periodic with that period: a direct check on the exact solution (ulp-level after
    # reduction mod 4K).
    np.testing.assert_allclose(orbit.momentum_at(period), pi0, atol=1e-12 * np.linalg.norm(pi0))


@pytest.mark.parametrize(
    "inertia, axis", [((1.0, 1.0, 0.5), 2), ((0.7, 0.9, 0.9), 0), ((2.0, 1.5, 2.0), 1)]
)
def test_symmetric_body_precesses_uniformly(inertia, axis):
    """Two equal moments: Pi_axis constant, the other pair rotates at lambda = (I1-I3)/(I1 I3)
    Pi3."""
    rng = np.random.default_rng(21)
    pi0 = random_momentum(rng, inertia, 2.0)
    j, k = (axis + 1) % 3, (axis + 2) % 3
    i_sym, i_ax = inertia[j], inertia[axis]
    lam = (i_sym - i_ax) / (i_sym * i_ax) * pi0[axis]
    orbit = FreeBodyOrbit(FreeBodyParams(inertia), pi0)
    # 4K(0) = 2 pi; only rounding of |nu|.
    assert float(orbit.period) == pytest.approx(2.0 * math.pi / abs(lam), rel=1e-14)
    t = np.linspace(0.0, 50.0, 101)
    got = np.array(orbit.momentum_at(t))
    # With (j, k) cyclic after axis: dPi_j/dt = lam Pi_k, dPi_k/dt = -lam Pi_j.
    c, s = np.cos(lam * t), np.sin(lam * t)
    want_j = pi0[j] * c + pi0[k] * s
    want_k = pi0[k] * c - pi0[j] * s
    n0 = np.linalg.norm(pi0)
    # Argument lam t up to ~50 rad: a few ulp times 50 in the phase.
    np.testing.assert_allclose(got[j], want_j, atol=1e-13 * n0)
    np.testing.assert_allclose(got[k], want_k, atol=1e-13 * n0)
    np.testing.assert_allclose(got[axis], pi0[axis], atol=1e-14 * n0)


# ---------------------------------------------------------------------------- equilibria
@pytest.mark.parametrize(
    "inertia", [(0.9, 0.6, 0.5), (0.5, 0.9, 0.6), (1.0, 1.0, 0.5), (1.0, 0.999, 0.998)]
)
@pytest.mark.parametrize("axis", [0, 1, 2])
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_principal_axis_spin_stays_put(inertia, axis, sign):
    body = FreeBody(FreeBodyParams(inertia), attitude=True)
    integ = get_integrator("exact")
    pi0 = [0.0, 0.0, 0.0]
    pi0[axis] = sign * 1.7
    q0 = (math.cos(0.3), math.sin(0.3), 0.0, 0.0)
    y = tuple(pi0) + q0
    h, steps = 0.25, 40
    for _ in range(steps):
        y = integ.step(body, y, None, h)
    # An equilibrium of Euler's equations stays exactly there (including the unstable middle axis).
    assert [float(v) for v in y[:3]] == pi0
    # The attitude turns uniformly about the axis at Omega = Pi_axis / I_axis.
    angle = pi0[axis] / inertia[axis] * h * steps
    r = [math.cos(0.5 * angle), 0.0, 0.0, 0.0]
    r[1 + axis] = math.sin(0.5 * angle)
    want = quat_multiply(q0, tuple(r))
    # 40 steps each with a few ulp of rounding in a unit quaternion.
    np.testing.assert_allclose([float(v) for v in y[3:]], want, atol=1e-13)


def test_all_equal_moments_keep_pi_constant():
    rng = np.random.default_rng(22)
    body = FreeBody(FreeBodyParams((0.8, 0.8, 0.8)))
    integ = get_integrator("exact")
    pi0 = tuple(rng.standard_normal(10) * 3.0)
    y = pi0
    for _ in range(50):
        y = integ.step(body, y, None, 0.7)
    for a, b in zip(y, pi0):
        np.testing.assert_array_equal(a, b)  # Omega parallel to Pi: Pi x Omega = 0 exactly


# ---------------------------------------------------------------------------- attitude
ATTITUDE_INERTIAS = [
    (0.9, 0.6, 0.5),
    (0.5, 0.6, 0.9),
    (0.6, 0.9, 0.5),
    (1.0, 0.999, 0.998),
    (1.0, 1.0, 0.5),
    (0.5, 1.0, 1.0),
    (1.0, 1.0, 1.0),
    (0.3, 0.5, 0.7),
]


@pytest.mark.parametrize("inertia", [(0.9, 0.6, 0.5), (1.0, 0.999, 0.998), (1.0, 1.0, 0.5)])
def test_exact_attitude_conserves_spatial_momentum(inertia):
    rng = np.random.default_rng(23)
    body = FreeBody(FreeBodyParams(inertia), attitude=True)
    integ = get_integrator("exact")
    n_batch = 8
    pi0 = tuple(
        np.array([random_momentum(rng, inertia, rng.uniform(1.0, 5.0)) for _ in range(n_batch)]).T
    )
    q0 = quat_random(rng, (n_batch,))
    s0 = np.array(quat_rotate(q0, pi0))
    y = pi0 + q0
    drift = 0.0
    for _ in range(1000):
        y = integ.step(body, y, None, 0.01)
        s = np.array(quat_rotate(y[3:], y[:3]))
        drift = max(
            drift, float(np.max(np.linalg.norm(s - s0, axis=0) / np.linalg.norm(s0, axis=0)))
        )
    # Each step is exact to ~1e-16 and the quaternion is renormalised; 1000 steps of random
    # rounding stay ~1e-14 (measured); 1e-12 leaves room for unlucky accumulation.
    assert drift <= 1e-12


@pytest.mark.parametrize(
    "inertia, h",
    [(i, h) for i in ATTITUDE_INERTIAS for h in (0.1, 1.0)],
)
def test_exact_attitude_matches_dop853(inertia, h):
    rng = np.random.default_rng(24)
    body = FreeBody(FreeBodyParams(inertia), attitude=True)
    integ = get_integrator("exact")
    pi0 = random_momentum(rng, inertia, rng.uniform(1.0, 5.0))
    q0 = tuple(float(c) for c in quat_random(rng))
    y = pi0 + q0
    steps = int(round(10.0 / h))
    for _ in range(steps):
        y = integ.step(body, y, None, h)
    ref = dop853(inertia, pi0 + q0, np.array([10.0]), attitude=True).y[:, -1]
    got = np.array([float(v) for v in y])
    # DOP853 at rtol 1e-13 over 10 time units: ~1e-12; the exact steps: round-off.
    assert np.max(np.abs(got[:3] - ref[:3])) / np.linalg.norm(pi0) <= 1e-10
    q_err = min(np.max(np.abs(got[3:] - ref[3:])), np.max(np.abs(got[3:] + ref[3:])))  # q ~ -q
    assert q_err <= 1e-10


# ------------------------------------------- regressions: near the middle axis, long steps
@pytest.mark.parametrize("eps", [1e-4, 1e-6, 1e-8, 1e-12, 1e-15])
def test_exact_flow_from_near_middle_axis(eps):
    _check_near_middle_axis(eps)


def _check_near_middle_axis(eps):
    """Start eps |Pi| off the unstable middle axis and follow the flip (docs/physics.md §1).

    The true solution is well conditioned in the relative size of eps (the flip time moves by
    ~ulp/lambda), so DOP853 with a tiny atol (relative accuracy on the small components while
    they grow) is a valid reference up to just after the flip.
    """
    inertia = (3.0, 2.0, 1.0)
    pi0 = (eps, 1.0, eps)
    orbit = FreeBodyOrbit(FreeBodyParams(inertia), pi0)
    t_flip = float(orbit.tau0 / abs(orbit.nu))  # u = 0: Pi_mid crosses zero
    t = np.linspace(0.0, t_flip + 5.0, 121)
    fun = lambda _t, y: euler_cross(inertia, y)  # noqa: E731
    ref = solve_ivp(
        fun, (0.0, t[-1]), np.array(pi0), method="DOP853", rtol=1e-13, atol=1e-40, t_eval=t
    ).y
    got = np.array(orbit.momentum_at(t))
    # Reference self-consistency at rtol 1e-12 vs 1e-13 is ~2e-12 over this horizon (measured).
    assert np.max(np.abs(got - ref)) <= 1e-10


def test_exact_attitude_long_step_symmetric_body():
    inertia = (1.0, 1.0, 0.5)
    pi0 = (1.0, 0.0, 0.03)  # small spin about the symmetry axis, passing near the e1 axis
    q0 = (1.0, 0.0, 0.0, 0.0)
    body = FreeBody(FreeBodyParams(inertia), attitude=True)
    got = np.array([float(v) for v in get_integrator("exact").step(body, pi0 + q0, None, 10.0)])
    ref = dop853(inertia, pi0 + q0, np.array([10.0]), attitude=True).y[:, -1]
    q_err = min(np.max(np.abs(got[3:] - ref[3:])), np.max(np.abs(got[3:] + ref[3:])))
    assert q_err <= 1e-10  # measured 4.5e-5


def test_period_speed_bounds_the_speed_over_the_period():
    """:func:`rbenvs.dynamics.free_body.period_speed` against the torque-free motion (DOP853 at
    rtol 1e-11) from six starts (random triaxial bodies, one 1e-4 off the intermediate axis, a
    symmetric body): over a long period it is the orbit's fastest ``|dPi| / |Pi|`` (to 1e-6: the
    orbit's segment end is the maximum, not merely a bound), and over a short period (``s |Pi|
    dt <= 1``: the Jacobian's growth) it bounds every speed the period reaches; one state's floats
    give the batch's elements."""
    from rbenvs.dynamics.free_body import error_rate_params, period_speed

    rng = np.random.default_rng(7)
    bodies = [np.sort(rng.uniform(1.0, 3.0, 3))[::-1] for _ in range(4)] + [
        np.array([3.0, 2.0, 1.0]),
        np.array([2.0, 2.0, 1.0]),
    ]
    starts = [rng.normal(size=3) * 5.0 for _ in range(4)] + [
        np.array([1e-4, 5.0, 1e-4]),
        np.array([1.0, 2.0, 3.0]),
    ]
    for inertia, pi0 in zip(bodies, starts):
        inv, spread, _ = error_rate_params(tuple(1.0 / inertia))
        j = np.array(inv)

        def speed(p):
            return float(np.linalg.norm(np.cross(p, j * p)) / np.linalg.norm(p))

        period = 60.0 / float(
            np.linalg.norm(j * pi0)
        )  # (radians of the fastest rotation: every orbit passes its maximum)
        sol = solve_ivp(
            lambda t, p: np.cross(p, j * p),
            (0.0, period),
            pi0,
            rtol=1e-11,
            atol=1e-12,
            max_step=period / 6000,
        )
        along = [speed(p) for p in sol.y.T]
        orbit = period_speed((inv, spread), tuple(pi0), None, 1e9)
        assert max(along) <= orbit * (1 + 1e-6) and orbit <= max(along) * (1 + 1e-6), (inertia, pi0)
        dt = 0.5 / (spread * float(np.linalg.norm(pi0)))  # (z = 0.5: the growth bound)
        short = solve_ivp(
            lambda t, p: np.cross(p, j * p),
            (0.0, dt),
            pi0,
            rtol=1e-11,
            atol=1e-12,
            max_step=dt / 200,
        )
        assert max(speed(p) for p in short.y.T) <= period_speed(
            (inv, spread), tuple(pi0), None, dt
        ) * (1 + 1e-9)
    batch = rng.normal(size=(3, 6))
    inv, spread, _ = error_rate_params((1 / 3, 1 / 2, 1.0))
    rows = period_speed((inv, spread), tuple(batch), (0.1, -0.2, 0.3), 0.05)
    assert [float(v) for v in rows] == [
        period_speed((inv, spread), tuple(float(c) for c in batch[:, i]), (0.1, -0.2, 0.3), 0.05)
        for i in range(6)
    ]

"""The heavy-top and tippe-top oracles, each against an independent computation.

Heavy top: the vector field [MR 15.10.1-2] is written again here, its Jacobian taken by central
differences and integrated with DOP853; nothing below reuses the oracle's formulas.
Tippe top: E* against a constrained minimization of the kinetic energy (KKT system), its
stability thresholds against numerical second derivatives, Jellett against the geometry.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rbenvs.oracles import heavy_top as ht
from rbenvs.oracles import tippe_top as tt

E3 = np.array([0.0, 0.0, 1.0])


# --------------------------------------------------------------------------------------------
# heavy top: independent model


def heavy_top_field(y, inertia, mgl):
    """[MR 15.10.1-2] with chi = e3: y = (Pi, Gamma), body frame."""
    Pi, Gam = y[:3], y[3:]
    Om = Pi / inertia
    return np.concatenate([np.cross(Pi, Om) + mgl * np.cross(Gam, E3), np.cross(Gam, Om)])


def upright_jacobian(I1, I3, mgl, spin):
    """6x6 central-difference Jacobian at Gamma = e3, Pi = (0, 0, I3 spin). The field is
    quadratic, so central differences are exact up to rounding."""
    inertia = np.array([I1, I1, I3])
    y0 = np.array([0.0, 0.0, I3 * spin, 0.0, 0.0, 1.0])
    jac = np.empty((6, 6))
    for j in range(6):
        step = 1e-3 * max(1.0, abs(y0[j]))
        e = np.zeros(6)
        e[j] = step
        jac[:, j] = (
            heavy_top_field(y0 + e, inertia, mgl) - heavy_top_field(y0 - e, inertia, mgl)
        ) / (2 * step)
    return jac


def match_multiset(expected, actual, tol):
    """Greedy nearest matching; returns the unmatched rest of ``actual``."""
    rest = list(actual)
    for lam in expected:
        d = [abs(lam - mu) for mu in rest]
        i = int(np.argmin(d))
        assert d[i] <= tol, (
            f"oracle eigenvalue {lam} not found in {actual} (nearest off by {d[i]:.3g})"
        )
        rest.pop(i)
    return np.array(rest)


HEAVY_CASES = [
    # I1 (pivot), I3, M, l, g, spin  -- below and above the critical spin, oblate and prolate
    (1.0, 0.5, 1.0, 1.0, 1.0, 1.0),
    (1.0, 0.5, 1.0, 1.0, 1.0, 7.0),
    (0.3, 0.5, 2.0, 0.1, 9.81, 2.0),
    (0.3, 0.5, 2.0, 0.1, 9.81, -9.0),
    (2.0, 3.5, 0.7, 0.4, 9.81, 0.5),
    (2.0, 3.5, 0.7, 0.4, 9.81, 25.0),
    (1.5, 1.0, 1.0, 1.0, 1.0, 0.0),
]


@pytest.mark.parametrize("I1, I3, M, l, g, spin", HEAVY_CASES)
def test_upright_eigenvalues_match_finite_difference_jacobian(I1, I3, M, l, g, spin):
    lam = ht.upright_eigenvalues(I1, I3, M, l, g, spin)
    assert lam.shape == (4,) and lam.dtype == complex
    numeric = np.linalg.eigvals(upright_jacobian(I1, I3, M * g * l, spin))
    scale = max(1.0, np.max(np.abs(numeric)))
    rest = match_multiset(lam, numeric, 1e-7 * scale)
    np.testing.assert_allclose(rest, 0.0, atol=1e-9 * scale)  # dPi3 and dGamma3 are frozen
    # the spectrum is that of a real Hamiltonian matrix: symmetric under lambda -> -lambda, conj
    match_multiset(-lam, lam, 1e-12 * scale)
    match_multiset(lam.conj(), lam, 1e-12 * scale)
    stable = abs(spin) > ht.critical_spin(I1, I3, M, l, g)
    assert (np.max(np.abs(lam.real)) < 1e-12 * scale) == stable


@pytest.mark.parametrize(
    "I1, I3, M, l, g",
    [(1.0, 0.5, 1.0, 1.0, 1.0), (0.3, 0.5, 2.0, 0.1, 9.81), (2.0, 3.5, 0.7, 0.4, 9.81)],
)
def test_critical_spin_is_where_the_jacobian_spectrum_turns_imaginary(I1, I3, M, l, g):
    def unstable(spin):
        return np.max(np.linalg.eigvals(upright_jacobian(I1, I3, M * g * l, spin)).real) > 1e-5

    lo, hi = 0.0, 1.0
    while unstable(hi):
        hi *= 2.0
    assert unstable(lo)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if unstable(mid) else (lo, mid)
    # near the threshold Re(lambda) ~ sqrt(distance): a 1e-5 detection level puts the
    # numerical crossing within ~1e-9 (relative) of the true one
    assert ht.critical_spin(I1, I3, M, l, g) == pytest.approx(0.5 * (lo + hi), rel=1e-7)


# --------------------------------------------------------------------------------------------
# heavy top in space: (Pi, R) integrated with DOP853


def lagrange_top_rhs(A, C, mgh):
    inertia = np.array([A, A, C])

    def rhs(t, y):
        Pi = y[:3]
        Rm = y[3:].reshape(3, 3)
        Om = Pi / inertia
        Gam = Rm[2]  # R^T e_z
        dPi = np.cross(Pi, Om) + mgh * np.cross(Gam, E3)
        hat = np.array([[0.0, -Om[2], Om[1]], [Om[2], 0.0, -Om[0]], [-Om[1], Om[0], 0.0]])
        return np.concatenate([dPi, (Rm @ hat).ravel()])

    return rhs


def initial_state(A, C, tilt, spin, precession):
    """Axis k = (sin tilt, 0, cos tilt) (azimuth 0), angular velocity p z + (n - p cos) k:
    spin n along k, theta' = 0, phi' = p."""
    ca, sa = math.cos(tilt), math.sin(tilt)
    Rm = np.array([[ca, 0.0, sa], [0.0, 1.0, 0.0], [-sa, 0.0, ca]])  # rotation about y by tilt
    gam = Rm[2]
    omega = precession * gam + (spin - precession * ca) * E3  # body frame
    return np.concatenate([np.array([A, A, C]) * omega, Rm.ravel()])


def axis_angles(y):
    """(tilt, azimuth) of k = R e3 from states y (..., 12)."""
    k = y[..., 3:].reshape(*y.shape[:-1], 3, 3)[..., :, 2]
    return np.arctan2(np.hypot(k[..., 0], k[..., 1]), k[..., 2]), np.arctan2(k[..., 1], k[..., 0])


PRECESSION_CASES = [
    # A, C, m, g, h, spin, tilt
    (1.2, 0.8, 0.5, 10.0, 0.2, 4.2, 0.6),
    (1.2, 0.8, 0.5, 10.0, 0.2, -4.2, 0.6),
    (0.9, 1.1, 1.0, 9.81, 0.1, 2.5, 2.3),  # axis below horizontal: roots of opposite sign
    (0.9, 1.1, 1.0, 9.81, 0.1, 3.0, math.pi / 2),  # horizontal: single root
    (0.9, 1.1, 1.0, 9.81, 0.1, 0.0, 2.6),  # no spin: conical pendulum
]


@pytest.mark.parametrize("A, C, m, g, h, spin, tilt", PRECESSION_CASES)
def test_regular_precession_keeps_tilt_and_precesses_at_the_root(A, C, m, g, h, spin, tilt):
    roots = ht.regular_precession_rates(A, C, m, g, h, spin, tilt)
    assert abs(roots.slow) <= abs(roots.fast) or math.isnan(roots.fast)
    for p in roots:
        if math.isnan(p):
            assert abs(math.cos(tilt)) < 1e-15
            continue
        assert A * p * p * math.cos(tilt) - C * spin * p + m * g * h == pytest.approx(
            0.0, abs=1e-12 * (C * abs(spin * p) + m * g * h)
        )
        t_end = 3.0 * 2.0 * math.pi / abs(p)  # three precession periods
        rhs = lagrange_top_rhs(A, C, m * g * h)
        sol = solve_ivp(
            rhs,
            (0.0, t_end),
            initial_state(A, C, tilt, spin, p),
            method="DOP853",
            rtol=1e-11,
            atol=1e-12,
            dense_output=True,
        )
        assert sol.success
        t = np.linspace(0.0, t_end, 601)
        theta, phi = axis_angles(sol.sol(t).T)
        assert np.max(np.abs(theta - tilt)) < 1e-6
        np.testing.assert_allclose(np.unwrap(phi), p * t, atol=1e-6 * max(1.0, abs(p) * t_end))


def test_regular_precession_check_is_sensitive():
    """A rate off by 1e-4 (relative) visibly nutates: the 1e-6 tilt tolerance above has teeth."""
    A, C, m, g, h, spin, tilt = PRECESSION_CASES[0]
    p = ht.regular_precession_rates(A, C, m, g, h, spin, tilt).fast * (1.0 + 1e-4)
    t_end = 2.0 * math.pi / abs(p)
    sol = solve_ivp(
        lagrange_top_rhs(A, C, m * g * h),
        (0.0, t_end),
        initial_state(A, C, tilt, spin, p),
        method="DOP853",
        rtol=1e-11,
        atol=1e-12,
        dense_output=True,
    )
    theta, _ = axis_angles(sol.sol(np.linspace(0.0, t_end, 601)).T)
    assert np.max(np.abs(theta - tilt)) > 1e-5


def test_regular_precession_large_spin_limits_3_83():
    A, C, m, g, h, tilt = 1.0, 0.7, 1.0, 9.81, 0.3, 0.8
    spin = 1e4
    slow, fast = ht.regular_precession_rates(A, C, m, g, h, spin, tilt)
    assert slow == pytest.approx(m * g * h / (C * spin), rel=1e-6)
    assert fast == pytest.approx(C * spin / (A * math.cos(tilt)), rel=1e-6)


def test_regular_precession_minimum_spin_boundary():
    A, C, m, g, h, tilt = 1.0, 0.7, 1.0, 9.81, 0.3, 0.8
    n_min = 2.0 * math.sqrt(A * m * g * h * math.cos(tilt)) / C
    slow, fast = ht.regular_precession_rates(A, C, m, g, h, n_min * (1 + 1e-12), tilt)
    assert slow == pytest.approx(fast, rel=1e-5)  # double root C n / (2 A cos)
    with pytest.raises(ValueError, match="spin"):
        ht.regular_precession_rates(A, C, m, g, h, n_min * (1 - 1e-9), tilt)


def fast_top_measurement(A, C, m, g, h, spin, tilt, periods):
    """Integrate the release of [T 3.71] and read nutation amplitude, period, mean precession."""
    rhs = lagrange_top_rhs(A, C, m * g * h)
    t_nut = 2.0 * math.pi * A / (C * abs(spin))  # only to size the run

    def kz_rate(t, y):  # d(k_z)/dt = Gamma . (Omega x e3)
        Om = y[:3] / np.array([A, A, C])
        return float(np.dot(y[3:].reshape(3, 3)[2], np.cross(Om, E3)))

    cusp = lambda t, y: kz_rate(t, y)  # noqa: E731  k_z maximal: theta = alpha
    cusp.direction = -1.0
    bottom = lambda t, y: kz_rate(t, y)  # noqa: E731  k_z minimal: theta = beta
    bottom.direction = 1.0
    sol = solve_ivp(
        rhs,
        (0.0, (periods + 0.5) * t_nut),
        initial_state(A, C, tilt, spin, 0.0),
        method="DOP853",
        rtol=1e-11,
        atol=1e-12,
        events=(cusp, bottom),
    )
    assert sol.success
    keep = sol.t_events[0] > 0.25 * t_nut  # the release itself is a cusp at t = 0
    t_cusp, y_cusp = sol.t_events[0][keep], sol.y_events[0][keep]
    y_bottom = sol.y_events[1]
    assert len(t_cusp) == periods and len(y_bottom) == periods
    theta_cusp, phi_cusp = axis_angles(y_cusp)
    np.testing.assert_allclose(theta_cusp, tilt, atol=1e-8)  # the axis returns to alpha
    theta_bottom, _ = axis_angles(y_bottom)
    beta = float(np.mean(theta_bottom))
    phi_total = np.unwrap(np.concatenate([[0.0], phi_cusp]))[-1]
    return dict(
        cos_amplitude=math.cos(beta) - math.cos(tilt),
        angle_amplitude=beta - tilt,
        period=t_cusp[-1] / periods,
        mean_precession_rate=phi_total / t_cusp[-1],
    )


def test_fast_top_nutation_asymptotics():
    """Release [T 3.71] at C n / sqrt(A m g h) = 25 and 50, i.e. eps = A m g h/(C n)^2 = 1/625
    and 1/2500, the expansion parameter of [T 3.76]-[T 3.80]. The formulas are leading order, so
    every measured quantity (amplitude in cos and in angle, nutation period, mean precession)
    must agree to a relative error O(eps). Tolerance 6 eps (1% at eps = 1/625); the measured
    errors are about (4, 3, 2, 1) eps cos(alpha). And the error must shrink by more than 2.5x
    when eps shrinks 4x (first-order convergence), which no formula with a wrong O(1) factor
    or a wrong power of the spin satisfies."""
    A, C, m, g, h, tilt = 1.0, 0.6, 0.5, 9.81, 0.2, 0.7
    errors = []
    for ratio in (25.0, 50.0):
        spin = ratio * math.sqrt(A * m * g * h) / C
        oracle = ht.fast_top_nutation(A, C, m, g, h, spin, tilt)
        eps = oracle.expansion_parameter
        assert eps == pytest.approx(1.0 / ratio**2)
        assert oracle.mean_tilt == pytest.approx(tilt + 0.5 * oracle.angle_amplitude)  # [T 3.77]
        measured = fast_top_measurement(A, C, m, g, h, spin, tilt, periods=12)
        err = {key: abs(measured[key] / getattr(oracle, key) - 1.0) for key in measured}
        for key, e in err.items():
            assert e < 6.0 * eps, (
                f"{key}: relative error {e:.3g} > 6 eps = {6 * eps:.3g} at ratio {ratio}"
            )
        errors.append(err)
    for key in errors[0]:
        assert errors[1][key] < errors[0][key] / 2.5, key


def test_fast_top_signs_follow_the_spin():
    a = ht.fast_top_nutation(1.0, 0.6, 0.5, 9.81, 0.2, 40.0, 0.7)
    b = ht.fast_top_nutation(1.0, 0.6, 0.5, 9.81, 0.2, -40.0, 0.7)
    assert a.mean_precession_rate > 0 and b.mean_precession_rate == -a.mean_precession_rate
    assert a.period == b.period and a.cos_amplitude == b.cos_amplitude < 0
    assert ht.fast_top_nutation(1.0, 0.6, 0.5, 9.81, 0.2, 40.0, 0.0).angle_amplitude == 0.0


# --------------------------------------------------------------------------------------------
# tippe top

LEINE = dict(m=0.006, g=9.81, R=0.015, alpha=0.2, A=8e-7, C=7e-7)


def e_star_kkt(theta, J, m, g, R, alpha, A, C):
    """min 1/2 L.I^-1 L subject to L.(R z - h k) = J, by the KKT linear system, plus m g z_G."""
    k = np.array([math.sin(theta), 0.0, math.cos(theta)])
    inertia = A * (np.eye(3) - np.outer(k, k)) + C * np.outer(k, k)
    a = R * E3 - alpha * R * k
    kkt = np.zeros((4, 4))
    kkt[:3, :3] = np.linalg.inv(inertia)
    kkt[:3, 3] = a
    kkt[3, :3] = a
    L = np.linalg.solve(kkt, np.array([0.0, 0.0, 0.0, J]))[:3]
    return 0.5 * L @ np.linalg.solve(inertia, L) + m * g * (R - alpha * R * math.cos(theta))


def test_energy_star_is_the_constrained_minimum_of_the_energy():
    rng = np.random.default_rng(3)
    for _ in range(40):
        p = dict(
            m=rng.uniform(0.1, 2),
            g=rng.uniform(1, 10),
            R=rng.uniform(0.01, 1),
            alpha=rng.uniform(0.05, 0.95),
            C=rng.uniform(0.1, 1),
        )
        p["A"] = p["C"] * rng.uniform(0.5, 2.5)
        theta, J = rng.uniform(0, math.pi), rng.normal() * 2
        assert tt.energy_star(theta, J, **p) == pytest.approx(e_star_kkt(theta, J, **p), rel=1e-11)
    th = np.linspace(0, math.pi, 7)
    out = tt.energy_star(th[:, None], np.array([0.5, 1.0]), **LEINE)
    assert out.shape == (7, 2)
    assert isinstance(tt.energy_star(0.3, 1e-6, **LEINE), float)


def second_derivative(theta, J, p, step=1e-3):
    f = lambda t: tt.energy_star(t, J, **p)  # noqa: E731
    return (f(theta + step) - 2.0 * f(theta) + f(theta - step)) / step**2


def bisect(fun, lo, hi, iterations=80):
    """The point where fun changes sign, fun(lo) and fun(hi) of opposite signs."""
    s_lo = fun(lo) > 0
    assert s_lo != (fun(hi) > 0)
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        if (fun(mid) > 0) == s_lo:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@pytest.mark.parametrize("alpha, gamma", [(0.2, 1.1429), (0.3, 0.85), (0.5, 1.3), (0.1, 1.05)])
def test_energy_star_thresholds_from_numerical_second_derivatives(alpha, gamma):
    p = dict(m=0.8, g=9.81, R=0.1, alpha=alpha, C=0.01)
    p["A"] = gamma * p["C"]
    crit = tt.inversion_criterion(p["A"], p["C"], alpha, m=p["m"], g=p["g"], R=p["R"])
    assert crit.gamma == pytest.approx(gamma)
    # theta = 0: the sign change of E*''(0) as J grows is at J_upright
    J_up = bisect(lambda J: second_derivative(0.0, J, p), 0.0, 1e3)
    assert crit.J_upright == pytest.approx(J_up, rel=1e-5)
    # theta = pi: E*''(pi) turns positive at J_min (when 1 + alpha > gamma)
    if crit.inverted_can_be_stable:
        J_pi = bisect(lambda J: second_derivative(math.pi, J, p), 0.0, 1e3)
        assert crit.J_min == pytest.approx(J_pi, rel=1e-5)
    else:
        assert crit.J_min is None
        assert all(second_derivative(math.pi, J, p) < 0 for J in np.geomspace(1e-4, 1e4, 30))


def test_upright_instability_boundary_tends_to_A_equals_one_minus_alpha_C():
    """docs/physics.md: theta = 0 unstable iff A > (1 - alpha) C. Numerically the sign change of
    E*''(0) in A sits at (1 - alpha) C + m g R^3 alpha C^2 (1 - alpha)^4 / J^2: docs/physics.md's
    statement is the large-J limit."""
    m, g, R, alpha, C = 0.8, 9.81, 0.1, 0.3, 0.01
    for J in (0.05, 0.2, 10.0):
        p = dict(m=m, g=g, R=R, alpha=alpha, C=C)
        A_switch = bisect(lambda A: second_derivative(0.0, J, dict(p, A=A)), 0.3 * C, 3.0 * C)
        expected = (1 - alpha) * C + m * g * R**3 * alpha * C**2 * (1 - alpha) ** 4 / J**2
        assert A_switch == pytest.approx(expected, rel=1e-5)
    assert A_switch == pytest.approx((1 - alpha) * C, rel=1e-5)


def test_inversion_criterion_classifications():
    C, alpha = 1.0, 0.2
    assert tt.inversion_criterion(0.7, C, alpha).classification == "no inversion"
    assert tt.inversion_criterion(1.1, C, alpha).classification == "full inversion"
    assert tt.inversion_criterion(1.5, C, alpha).classification == "partial inversion"
    c = tt.inversion_criterion(1.1, C, alpha)
    assert (
        c.upright_unstable and c.inverted_can_be_stable and c.J_min is None and c.J_upright is None
    )
    # the Leine-Glocker top at 180 rad/s inverts fully; docs/physics.md's numbers
    J = tt.jellett_upright(LEINE["C"], LEINE["R"], LEINE["alpha"], 180.0)
    crit = tt.inversion_criterion(
        LEINE["A"], LEINE["C"], LEINE["alpha"], m=LEINE["m"], g=LEINE["g"], R=LEINE["R"], J=J
    )
    assert crit.classification == "full inversion" and crit.J == J
    assert tt.final_tilt(J, **LEINE) == math.pi


def test_inversion_criterion_with_J_agrees_with_the_energy_landscape():
    rng = np.random.default_rng(7)
    seen = set()
    for _ in range(150):
        p = dict(m=1.0, g=9.81, R=0.1, alpha=rng.uniform(0.05, 0.6), C=0.01)
        p["A"] = p["C"] * rng.uniform(0.5, 2.0)
        J = float(np.exp(rng.uniform(np.log(1e-3), np.log(3.0))))
        crit = tt.inversion_criterion(p["A"], p["C"], p["alpha"], m=p["m"], g=p["g"], R=p["R"], J=J)
        seen.add(crit.classification)
        d0, dpi = second_derivative(0.0, J, p), second_derivative(math.pi, J, p)
        if crit.classification == "no inversion":
            assert d0 > 0
            continue
        assert d0 < 0
        theta_f = tt.final_tilt(J, **p)
        if crit.classification == "full inversion":
            assert dpi > 0 and theta_f == math.pi
        else:
            assert dpi < 0 and 0.0 < theta_f < math.pi
    assert seen == {"no inversion", "partial inversion", "full inversion"}


def test_inversion_spin_threshold_gives_J_min():
    n = tt.inversion_spin_threshold(
        LEINE["A"], LEINE["C"], LEINE["alpha"], LEINE["m"], LEINE["g"], LEINE["R"]
    )
    crit = tt.inversion_criterion(
        LEINE["A"], LEINE["C"], LEINE["alpha"], m=LEINE["m"], g=LEINE["g"], R=LEINE["R"]
    )
    assert tt.jellett_upright(LEINE["C"], LEINE["R"], LEINE["alpha"], n) == pytest.approx(
        crit.J_min, rel=1e-14
    )
    assert 100.0 < n < 180.0  # the docs/physics.md spin of 180 rad/s is above it


def test_final_tilt_matches_brute_force_grid():
    rng = np.random.default_rng(11)
    grid = np.linspace(0.0, math.pi, 400001)
    for _ in range(25):
        p = dict(
            m=rng.uniform(0.1, 2),
            g=9.81,
            R=rng.uniform(0.02, 0.2),
            alpha=rng.uniform(0.05, 0.9),
            C=rng.uniform(1e-3, 1e-2),
        )
        p["A"] = p["C"] * rng.uniform(0.5, 2.5)
        J = float(rng.uniform(0, 3) * math.sqrt(p["m"] * p["g"] * p["R"] ** 3 * p["C"]))
        theta = tt.final_tilt(J, **p)
        values = tt.energy_star(grid, J, **p)
        i = int(np.argmin(values))
        assert 0.0 <= theta <= math.pi
        assert tt.energy_star(theta, J, **p) <= values[i] + 1e-13 * abs(values[i])
        assert abs(theta - grid[i]) < 1e-4
    assert tt.final_tilt(0.0, **LEINE) == 0.0  # no spin: the centre of mass stays low


def test_jellett_against_the_contact_geometry():
    rng = np.random.default_rng(5)
    R, alpha = 0.015, 0.2
    L = rng.normal(size=(5, 3))
    k = rng.normal(size=(5, 3))
    k /= np.linalg.norm(k, axis=-1, keepdims=True)
    centre = rng.normal(size=(5, 3))
    G = centre - alpha * R * k
    P = centre - R * E3
    expected = -np.sum(L * (P - G), axis=-1)
    np.testing.assert_allclose(tt.jellett(L, k, R, alpha), expected, rtol=1e-13, atol=1e-16)
    # broadcasting over leading axes, and scalars for single vectors
    out = tt.jellett(L[:, None, :], k[None, :4, :], R, alpha)
    assert out.shape == (5, 4)
    assert out[2, 3] == pytest.approx(-np.dot(L[2], R * -E3 + alpha * R * k[3]), rel=1e-13)
    assert isinstance(tt.jellett(L[0], k[0], R, alpha), float)


def test_jellett_matches_seed_form_3_106():
    """R A phi' sin^2(theta) + (R cos(theta) - h) C omega3 with L from Euler-angle rates."""
    rng = np.random.default_rng(9)
    A, C, R, alpha = 8e-7, 7e-7, 0.015, 0.2
    for _ in range(10):
        theta, phi, dphi, dtheta, omega3 = (
            rng.uniform(0, math.pi),
            rng.uniform(0, 6),
            rng.normal(),
            rng.normal(),
            rng.normal() * 50,
        )
        k = np.array(
            [math.sin(theta) * math.sin(phi), -math.sin(theta) * math.cos(phi), math.cos(theta)]
        )
        node = np.array([math.cos(phi), math.sin(phi), 0.0])
        omega = dphi * E3 + dtheta * node + (omega3 - dphi * math.cos(theta)) * k  # spin rate psi'
        L = A * (omega - np.dot(omega, k) * k) + C * np.dot(omega, k) * k
        seed = R * A * dphi * math.sin(theta) ** 2 + (R * math.cos(theta) - alpha * R) * C * omega3
        assert tt.jellett(L, k, R, alpha) == pytest.approx(seed, rel=1e-12, abs=1e-20)


def test_jellett_upright():
    C, R, alpha, n = 7e-7, 0.015, 0.2, 180.0
    assert tt.jellett_upright(C, R, alpha, n) == pytest.approx(
        tt.jellett(C * n * E3, E3, R, alpha), rel=1e-15
    )
    assert tt.jellett_upright(C, R, alpha, n) == pytest.approx(R * C * n * (1 - alpha))


# --------------------------------------------------------------------------------------------
# every ValueError path

HT = dict(A=1.0, C=0.6, mass=0.5, length=0.2, gravity=9.81)
BAD_POSITIVE = [0.0, -1.0, math.nan, math.inf, True, "1"]


@pytest.mark.parametrize("bad", BAD_POSITIVE)
@pytest.mark.parametrize("name", ["I1", "I3", "mass", "length", "gravity"])
def test_heavy_top_rejects_bad_positive_parameters(name, bad):
    kw = dict(I1=1.0, I3=0.6, mass=0.5, length=0.2, gravity=9.81)
    kw[name] = bad
    with pytest.raises(ValueError, match=name):
        ht.critical_spin(**kw)
    with pytest.raises(ValueError, match=name):
        ht.upright_eigenvalues(**kw, spin=3.0)


@pytest.mark.parametrize("bad", BAD_POSITIVE)
@pytest.mark.parametrize("name", ["A", "C", "mass", "length", "gravity"])
def test_precession_oracles_reject_bad_positive_parameters(name, bad):
    kw = dict(HT, **{name: bad})
    with pytest.raises(ValueError, match=name):
        ht.regular_precession_rates(**kw, spin=40.0, tilt=0.5)
    with pytest.raises(ValueError, match=name):
        ht.fast_top_nutation(**kw, spin=40.0, tilt=0.5)


@pytest.mark.parametrize("bad", [-0.1, math.pi + 1e-9, math.nan, math.inf, None])
def test_precession_oracles_reject_bad_tilt(bad):
    with pytest.raises(ValueError, match="tilt"):
        ht.regular_precession_rates(**HT, spin=40.0, tilt=bad)
    with pytest.raises(ValueError, match="tilt"):
        ht.fast_top_nutation(**HT, spin=40.0, tilt=bad)


@pytest.mark.parametrize("bad", [math.nan, math.inf, "3"])
def test_spin_must_be_finite(bad):
    with pytest.raises(ValueError, match="spin"):
        ht.upright_eigenvalues(1.0, 0.6, 0.5, 0.2, 9.81, bad)
    with pytest.raises(ValueError, match="spin"):
        ht.regular_precession_rates(**HT, spin=bad, tilt=0.5)
    with pytest.raises(ValueError, match="spin"):
        ht.fast_top_nutation(**HT, spin=bad, tilt=0.5)
    with pytest.raises(ValueError, match="spin"):
        tt.jellett_upright(7e-7, 0.015, 0.2, bad)


def test_spin_zero_paths():
    with pytest.raises(ValueError, match="spin"):
        ht.fast_top_nutation(**HT, spin=0.0, tilt=0.5)
    with pytest.raises(ValueError, match="spin"):
        ht.regular_precession_rates(**HT, spin=0.0, tilt=math.pi / 2)
    with pytest.raises(ValueError, match="spin"):
        ht.regular_precession_rates(**HT, spin=0.0, tilt=0.3)  # too slow above the horizontal


@pytest.mark.parametrize("bad", BAD_POSITIVE)
@pytest.mark.parametrize("name", ["m", "g", "R", "A", "C"])
def test_tippe_top_rejects_bad_positive_parameters(name, bad):
    kw = dict(LEINE, **{name: bad})
    with pytest.raises(ValueError, match=name):
        tt.energy_star(0.3, 1e-6, **kw)
    with pytest.raises(ValueError, match=name):
        tt.final_tilt(1e-6, **kw)
    with pytest.raises(ValueError, match=name):
        tt.inversion_criterion(kw["A"], kw["C"], kw["alpha"], m=kw["m"], g=kw["g"], R=kw["R"])
    if name in ("C", "R"):
        with pytest.raises(ValueError, match=name):
            tt.jellett_upright(kw["C"], kw["R"], 0.2, 100.0)
    if name == "R":
        with pytest.raises(ValueError, match="R"):
            tt.jellett(E3, E3, bad, 0.2)


@pytest.mark.parametrize("bad", [0.0, 1.0, -0.2, 1.5, math.nan, True])
def test_tippe_top_rejects_bad_alpha(bad):
    with pytest.raises(ValueError, match="alpha"):
        tt.jellett(E3, E3, 0.015, bad)
    with pytest.raises(ValueError, match="alpha"):
        tt.jellett_upright(7e-7, 0.015, bad, 100.0)
    with pytest.raises(ValueError, match="alpha"):
        tt.energy_star(0.3, 1e-6, **dict(LEINE, alpha=bad))
    with pytest.raises(ValueError, match="alpha"):
        tt.inversion_criterion(8e-7, 7e-7, bad)
    with pytest.raises(ValueError, match="alpha"):
        tt.final_tilt(1e-6, **dict(LEINE, alpha=bad))


def test_tippe_top_array_and_J_errors():
    with pytest.raises(ValueError, match="L"):
        tt.jellett(np.ones(2), E3, 0.015, 0.2)
    with pytest.raises(ValueError, match="k"):
        tt.jellett(E3, np.ones((2, 4)), 0.015, 0.2)
    with pytest.raises(ValueError, match="L"):
        tt.jellett([math.nan, 0, 0], E3, 0.015, 0.2)
    with pytest.raises(ValueError, match="broadcast"):
        tt.jellett(np.ones((3, 3)), np.ones((2, 3)), 0.015, 0.2)
    with pytest.raises(ValueError, match="theta"):
        tt.energy_star(math.nan, 1e-6, **LEINE)
    with pytest.raises(ValueError, match="J"):
        tt.energy_star(0.3, math.inf, **LEINE)
    with pytest.raises(ValueError, match="J"):
        tt.final_tilt(math.nan, **LEINE)
    with pytest.raises(ValueError, match="J"):
        tt.inversion_criterion(8e-7, 7e-7, 0.2, m=0.006, g=9.81, R=0.015, J=math.nan)
    with pytest.raises(ValueError, match="J needs"):
        tt.inversion_criterion(8e-7, 7e-7, 0.2, J=1e-6)
    with pytest.raises(ValueError, match="missing g, R"):
        tt.inversion_criterion(8e-7, 7e-7, 0.2, m=0.006)
    with pytest.raises(ValueError, match="A must satisfy"):
        tt.inversion_spin_threshold(2e-6, 7e-7, 0.2, 0.006, 9.81, 0.015)
    with pytest.raises(ValueError, match="A must satisfy"):
        tt.inversion_spin_threshold(4e-7, 7e-7, 0.2, 0.006, 9.81, 0.015)

"""Free-body oracles against independent computations."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rbenvs.oracles import (
    axis_stability,
    exact_solution,
    intermediate_axis_growth_rate,
    linearization,
    linearization_eigenvalues,
    orbit_period,
)


def euler_cross(inertia):
    inertia = np.asarray(inertia, float)
    return lambda t, p: np.cross(p, p / inertia)


def numerical_jacobian(f, x, eps=1e-6):
    cols = [(f(0.0, x + eps * e) - f(0.0, x - eps * e)) / (2 * eps) for e in np.eye(len(x))]
    return np.array(cols).T


def random_bodies(rng, n):
    out = []
    while len(out) < n:
        i = rng.uniform(0.5, 2.0, 3)
        s = np.sort(i)
        if s[0] + s[1] >= s[2] and s[1] / s[0] > 1.01 and s[2] / s[1] > 1.01:
            out.append(i)
    return out


@pytest.mark.parametrize("seed", range(5))
def test_linearization_and_eigenvalues_match_numerical_jacobian(seed):
    rng = np.random.default_rng(seed)
    inertia = random_bodies(rng, 1)[0]
    for axis in range(3):
        p = rng.uniform(0.5, 3.0)
        x = np.zeros(3)
        x[axis] = p
        jac = numerical_jacobian(euler_cross(inertia), x)
        # central differences of a quadratic field are exact up to round-off (~eps/1e-6)
        np.testing.assert_allclose(linearization(inertia, x), jac, atol=1e-8)
        ev = np.sort_complex(np.linalg.eigvals(jac))
        np.testing.assert_allclose(
            np.sort_complex(linearization_eigenvalues(inertia, axis, p)), ev, atol=1e-7
        )


@pytest.mark.parametrize("seed", range(5))
def test_stability_classification_agrees_with_eigenvalues(seed):
    inertia = random_bodies(np.random.default_rng(seed), 1)[0]
    labels = axis_stability(inertia)
    assert labels.count("unstable") == 1 and labels.count("stable") == 2
    middle = int(np.argsort(inertia)[1])
    assert labels[middle] == "unstable"
    for axis in range(3):
        growth = np.max(linearization_eigenvalues(inertia, axis, 1.0).real)
        assert (growth > 0) == (labels[axis] == "unstable")
    lam = intermediate_axis_growth_rate(inertia, 1.3)
    assert lam == pytest.approx(
        np.max(linearization_eigenvalues(inertia, middle, 1.3).real), rel=1e-12
    )


def test_equal_moments_are_neutral_and_have_no_intermediate_axis():
    assert axis_stability((1.0, 1.0, 1.5)) == ("neutral", "neutral", "stable")
    with pytest.raises(ValueError, match="distinct"):
        intermediate_axis_growth_rate((1.0, 1.0, 1.5), 1.0)


def test_exact_solution_batched_against_dop853():
    rng = np.random.default_rng(7)
    for inertia in random_bodies(rng, 4):
        pi0 = rng.standard_normal((3, 3))
        ts = np.linspace(0.0, 20.0, 5)
        got = exact_solution(inertia, pi0[:, :, None], ts)
        assert got.shape == (3, 3, 5)
        for b in range(3):
            sol = solve_ivp(
                euler_cross(inertia),
                (0, 20),
                pi0[:, b],
                method="DOP853",
                rtol=1e-13,
                atol=1e-14,
                dense_output=True,
            )
            # DOP853 at rtol 1e-13 over ~20 periods is itself good to ~1e-11
            np.testing.assert_allclose(
                got[:, b, :], sol.sol(ts), atol=1e-10 * np.linalg.norm(pi0[:, b])
            )


def test_orbit_period_is_the_period_of_the_exact_solution_and_of_dop853():
    inertia = (2.0, 1.5, 1.0)
    pi0 = np.array([0.3, 0.2, 1.0])
    T = float(orbit_period(inertia, pi0))
    sol = solve_ivp(euler_cross(inertia), (0, T), pi0, method="DOP853", rtol=1e-13, atol=1e-14)
    np.testing.assert_allclose(sol.y[:, -1], pi0, atol=1e-10)
    # and not before: at half the period the state is elsewhere
    assert np.linalg.norm(exact_solution(inertia, pi0, T / 2) - pi0) > 0.1
    assert np.isinf(orbit_period(inertia, np.array([0.0, 1.0, 0.0])))  # an equilibrium


def test_bad_inputs():
    with pytest.raises(ValueError, match="inertia"):
        exact_solution((1.0, 1.0, 5.0), np.ones(3), 1.0)
    with pytest.raises(ValueError, match="pi"):
        exact_solution((1.0, 1.0, 1.0), np.ones(2), 1.0)
    with pytest.raises(ValueError, match="finite"):
        orbit_period((1.0, 1.0, 1.0), np.array([np.nan, 0, 0]))
    with pytest.raises(ValueError, match="axis"):
        linearization_eigenvalues((1.0, 2.0, 2.5), 3, 1.0)


def test_the_taylor_solution_is_the_exact_one_where_float64_holds_and_settles_near_the_separatrix():
    """:func:`rbenvs.oracles.taylor_solution` (mpmath's Taylor series, a dev dependency: missing
    it must fail, not skip) agrees with the elliptic solution to 1e-13 far from the separatrix
    (over 5 s); 0.0001 rad/s off the intermediate axis, where the elliptic solution in float64
    keeps fewer digits, 32 and 36 digits give the same answer to 1e-15 over 20 s."""
    from rbenvs.oracles import exact_solution, taylor_solution

    inertia = (2.0, 1.5, 1.0)
    times = [0.05 * (k + 1) for k in range(0, 400, 7)]
    pi0 = np.array(inertia) * np.array((-2.0, 4.0, 6.0))
    exact = np.array([exact_solution(inertia, pi0, t) for t in times[:15]])
    taylor = taylor_solution(inertia, pi0, times[:15])
    assert np.max(np.linalg.norm(taylor - exact, axis=1) / np.linalg.norm(exact, axis=1)) < 1e-13
    near = np.array(inertia) * np.array((1e-4, 5.0, 7e-5))
    a, b = (
        taylor_solution(inertia, near, times, digits=32),
        taylor_solution(inertia, near, times, digits=36),
    )
    assert np.max(np.linalg.norm(a - b, axis=1) / np.linalg.norm(b, axis=1)) < 1e-15

"""Jacobi elliptic functions and F(phi|m) with the parameter split as (m, m1 = 1 - m).

References: scipy.special (moderate m) and mpmath at 60 digits (m -> 1, where scipy's ellipj
forms 1 - m itself and is useless, docs/physics.md §4).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import special

from rbenvs.elliptic import elliptic_f, elliptic_k, jacobi_sn_cn_dn

EPS = np.finfo(float).eps
# The documented accuracy of jacobi_sn_cn_dn is "a few ulp times |u|" (no reduction mod 4K):
# rounding u alone moves sn, cn, dn by up to eps |u| (their derivatives are bounded by 1).
ULP_FACTOR = 16.0

MODERATE_M = [0.0, 1e-12, 0.1, 0.5, 0.9, 0.99]
NEAR_ONE_M1 = [1e-8, 1e-12, 1e-16, 1e-30]


@pytest.fixture(autouse=True)
def _mpmath_precision():
    """60 digits so that 1 - m keeps ~16 digits of m1 = 1e-30 (30 + 16 and margin); restored
    after."""
    try:
        import mpmath
    except ImportError:
        yield
        return
    with mpmath.workdps(60):
        yield


def _u_grid(k, rng):
    """Arguments over several quarter periods, both signs, plus random points."""
    return np.concatenate([np.linspace(-2.0 * k, 4.0 * k, 61), rng.uniform(-4.0 * k, 4.0 * k, 40)])


@pytest.mark.parametrize("m", MODERATE_M)
def test_sn_cn_dn_match_scipy_for_moderate_m(m):
    rng = np.random.default_rng(1)
    m1 = 1.0 - m
    u = _u_grid(special.ellipk(m), rng)
    sn, cn, dn = jacobi_sn_cn_dn(u, m, m1)
    s_ref, c_ref, d_ref, _ = special.ellipj(u, m)
    # Both are AGM evaluations with error ~ a few ulp times |u|; allow the sum of both.
    tol = 2 * ULP_FACTOR * EPS * np.maximum(1.0, np.abs(u))
    for got, ref in ((sn, s_ref), (cn, c_ref), (dn, d_ref)):
        assert np.all(np.abs(got - ref) <= tol)


@pytest.mark.parametrize("m", MODERATE_M)
def test_elliptic_f_matches_scipy_for_moderate_m(m):
    m1 = 1.0 - m
    phi = np.linspace(-np.pi, np.pi, 97)
    got = elliptic_f(phi, m, m1)
    ref = special.ellipkinc(phi, m)
    # Carlson R_F and scipy's ellipkinc are both accurate to a few ulp of the result.
    np.testing.assert_allclose(got, ref, rtol=1e-14, atol=1e-15)


@pytest.mark.parametrize("m", [0.1, 0.5, 0.9])
def test_elliptic_k_matches_scipy(m):
    # Same cephes routine underneath (ellipkm1 vs ellipk): agreement to round-off.
    assert elliptic_k(1.0 - m) == pytest.approx(special.ellipk(m), rel=1e-15)


@pytest.mark.parametrize("m1", NEAR_ONE_M1)
def test_sn_cn_dn_near_m_one_match_mpmath(m1):
    import mpmath as mp  # a dev dependency: missing it must fail, not skip

    m_mp = mp.mpf(1) - mp.mpf(m1)  # the exact parameter; the float m = 1 - m1 rounds it
    k = float(mp.ellipk(m_mp))
    rng = np.random.default_rng(2)
    u = np.concatenate([np.linspace(-k, 2.0 * k, 31), rng.uniform(0.0, 2.0 * k, 20)])
    sn, cn, dn = jacobi_sn_cn_dn(u, 1.0 - m1, m1)
    tol = ULP_FACTOR * EPS * np.maximum(1.0, np.abs(u))  # the documented "few ulp times |u|"
    for i, ui in enumerate(u):
        for name, got in (("sn", sn[i]), ("cn", cn[i]), ("dn", dn[i])):
            ref = float(mp.ellipfun(name, mp.mpf(float(ui)), m_mp))
            assert abs(got - ref) <= tol[i], (name, ui, got, ref)


@pytest.mark.parametrize("m1", [1e-8, 1e-12, 1e-16, 1e-30])
def test_elliptic_f_and_k_near_m_one_match_mpmath(m1):
    import mpmath as mp  # a dev dependency: missing it must fail, not skip

    m_mp = mp.mpf(1) - mp.mpf(m1)
    phi = np.linspace(-np.pi, np.pi, 41)
    got = elliptic_f(phi, 1.0 - m1, m1)
    for p, g in zip(phi, got):
        ref = float(mp.ellipf(mp.mpf(float(p)), m_mp))
        # Carlson R_F with 1 - m sin^2 = cos^2 + m1 sin^2 is accurate to a few ulp of F.
        assert g == pytest.approx(ref, rel=1e-14, abs=1e-15)
    assert elliptic_k(m1) == pytest.approx(float(mp.ellipk(m_mp)), rel=1e-14)  # a few ulp


@pytest.mark.parametrize("m1", [0.5, 1e-4, 1e-8, 1e-12, 1e-16, 1e-30])
def test_identities_near_m_one(m1):
    """Checks that need no reference: Pythagorean identities, sn' = cn dn, and sn(F(phi)) = sin
    phi."""
    m = 1.0 - m1
    k = elliptic_k(m1)
    u = np.linspace(-k, 2.0 * k, 201)
    sn, cn, dn = jacobi_sn_cn_dn(u, m, m1)
    # sn = sin(am), cn = cos(am) are one rounding each: the identity holds to a few ulp.
    np.testing.assert_allclose(sn * sn + cn * cn, 1.0, atol=4 * EPS)
    # dn^2 + m sn^2 = cn^2 + (m + m1) sn^2 = 1 up to a few ulp (m + m1 = 1 to one ulp).
    np.testing.assert_allclose(dn * dn + m * sn * sn, 1.0, atol=8 * EPS)
    # Central difference: truncation h^2/6 |sn'''| <= ~1e-11 (|sn'''| <= ~6), rounding eps/h ~
    # 2e-11.
    h = 1e-5
    sp, _, _ = jacobi_sn_cn_dn(u + h, m, m1)
    sm, _, _ = jacobi_sn_cn_dn(u - h, m, m1)
    np.testing.assert_allclose((sp - sm) / (2 * h), cn * dn, atol=1e-9)
    # am(F(phi)) = phi on (-pi/2, pi/2): sn(F(phi)) = sin(phi) and cn(F(phi)) = cos(phi).
    phi = np.linspace(-1.5, 1.5, 61)
    f = elliptic_f(phi, m, m1)
    s, c, d = jacobi_sn_cn_dn(f, m, m1)
    np.testing.assert_allclose(s, np.sin(phi), atol=1e-13)  # sn' = cn dn <= 1: error ~ |F| ulp
    # dcn/du = -sn dn is small where cn is small near m=1, so cn is as accurate as sn here.
    np.testing.assert_allclose(c, np.cos(phi), atol=1e-13)
    np.testing.assert_allclose(d, np.sqrt(np.cos(phi) ** 2 + m1 * np.sin(phi) ** 2), atol=1e-13)


def test_separatrix_gives_tanh_sech_exactly():
    u = np.array([-50.0, -3.0, -1e-9, 0.0, 1e-9, 0.5, 2.0, 20.0, 400.0, 800.0])
    sn, cn, dn = jacobi_sn_cn_dn(u, 1.0, 0.0)
    with np.errstate(over="ignore"):
        sech = 1.0 / np.cosh(u)
    # m1 == 0 takes the closed form branch: bit-identical to numpy's tanh and sech.
    assert np.array_equal(sn, np.tanh(u))
    assert np.array_equal(cn, sech)
    assert np.array_equal(dn, sech)
    assert np.all(np.isfinite(sn)) and np.all(np.isfinite(cn))


def test_separatrix_incomplete_integral():
    phi = np.array([-1.5, -0.3, 0.0, 0.7, 1.5])
    # F(phi|1) = asinh(tan phi): closed form, so agreement to a couple of ulp.
    np.testing.assert_allclose(elliptic_f(phi, 1.0, 0.0), np.arcsinh(np.tan(phi)), rtol=4 * EPS)
    # The float pi/2 lies 6e-17 below pi/2, so F there is finite (asinh(1.6e16) = 38.0): the
    # closed form evaluated at the same float, to a few ulp.
    half_pi = np.pi / 2
    assert elliptic_f(half_pi, 1.0, 0.0) == pytest.approx(np.arcsinh(np.tan(half_pi)), rel=4 * EPS)
    assert elliptic_f(-half_pi, 1.0, 0.0) == pytest.approx(
        -np.arcsinh(np.tan(half_pi)), rel=4 * EPS
    )
    assert elliptic_k(0.0) == np.inf


def test_mixed_batch_matches_elementwise():
    """A batch mixing the separatrix branch with ordinary parameters equals one call per element."""
    u = np.array([0.3, 1.7, -2.2, 5.0])
    m1 = np.array([0.0, 1e-12, 0.5, 0.0])
    m = 1.0 - m1
    batch = jacobi_sn_cn_dn(u, m, m1)
    for i in range(u.size):
        single = jacobi_sn_cn_dn(u[i], m[i], m1[i])
        for b, s in zip(batch, single):
            # The AGM loop stops when the whole batch has converged, so an element may take
            # an extra (no-op at round-off) iteration: allow one ulp-level difference.
            assert b[i] == pytest.approx(float(s), abs=4 * EPS)

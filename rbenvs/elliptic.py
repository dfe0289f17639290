"""Jacobi elliptic functions and the incomplete integral, accurate up to the separatrix.

``scipy.special.ellipj(u, m)`` takes the parameter ``m`` and forms ``1 - m`` itself, so it
loses the complementary parameter ``m1 = 1 - m`` to cancellation as ``m -> 1`` (about 1e-8
error at ``m1 = 1e-8``, wrong below 1e-10; docs/physics.md §4). Near the free rigid body's
separatrix ``m1`` is small but *known accurately* from the separatrix distance, so these
routines take ``m`` and ``m1`` separately and never form ``1 - m``:

* :func:`jacobi_sn_cn_dn` uses the arithmetic-geometric mean (descending Landen
  transformation, Abramowitz & Stegun 16.4) started from ``b0 = sqrt(m1)``, and
  ``dn = sqrt(cn^2 + m1 sn^2)``; ``m1 == 0`` gives ``tanh``/``sech`` exactly.
* :func:`elliptic_f` uses Carlson's ``R_F`` with ``1 - m sin^2 phi = cos^2 phi + m1 sin^2 phi``.

All functions are elementwise over numpy broadcasting.
"""

from __future__ import annotations

import numpy as np

# scipy.special is imported where it is used: importing it is a large share of an env's start
# (rbenvs bench startup), and only the exact solution (oracles, the exact integrator) calls it

__all__ = ["jacobi_sn_cn_dn", "elliptic_f", "elliptic_f_sc", "elliptic_k"]

_MAX_AGM_ITERATIONS = 64  # AGM converges quadratically; even m1 = 1e-300 needs about 12
_EPS = float(np.finfo(float).eps)


def elliptic_k(m1):
    """Complete integral of the first kind ``K`` as a function of ``m1 = 1 - m``."""
    from scipy import special

    return special.ellipkm1(m1)


def jacobi_sn_cn_dn(u, m, m1):
    """``sn(u|m), cn(u|m), dn(u|m)`` with the parameter given as ``m`` and ``m1 = 1 - m``.

    ``0 <= m <= 1``; ``m1`` must equal ``1 - m`` to the accuracy wanted (it is the accurate one
    of the pair near the separatrix, ``m`` the accurate one near ``m = 0``).
    Accuracy: absolute, a few ulp times ``|u|`` (the argument is not reduced modulo ``4K``).

    Each element runs the AGM until its own convergence (finished elements are frozen), so an
    element's result does not depend on the rest of the batch: a single state and the same
    state inside a batch give the same bits.
    """
    u, m, m1 = np.broadcast_arrays(
        np.asarray(u, float), np.asarray(m, float), np.asarray(m1, float)
    )
    separatrix = m1 == 0.0
    m1_safe = np.where(separatrix, 0.5, m1)
    # Descending Landen / AGM: a0 = 1, b0 = sqrt(m1), c0 = sqrt(m).
    a = np.ones_like(u)
    b = np.sqrt(m1_safe)
    steps = []  # (c_n, a_n, b_{n-1}) per iteration
    done = np.zeros(u.shape, dtype=bool)
    for _ in range(_MAX_AGM_ITERATIONS):
        c = np.where(done, 0.0, 0.5 * (a - b))
        b_prev = b
        a, b = np.where(done, a, 0.5 * (a + b)), np.where(done, b, np.sqrt(a * b))
        steps.append((c, a, b_prev))
        done = done | (np.abs(c) <= _EPS * a)
        if np.all(done):
            break
    phi = (2.0 ** len(steps)) * a * u
    for c_n, a_n, b_prev in reversed(steps):
        # phi_{n-1} = (phi_n + asin(x)) / 2 with x = (c_n / a_n) sin(phi_n). Near |x| = 1 (m -> 1)
        # asin amplifies the rounding of x by 1/sqrt(1 - x^2); there use
        # asin(x) = sign(x) (pi/2 - 2 asin(sqrt((1 - |x|)/2))) with 1 - |x| formed without
        # cancellation: a_n - c_n = b_{n-1} and 1 - |sin| = cos^2 / (1 + |sin|).
        sp, cp = np.sin(phi), np.cos(phi)
        x = c_n / a_n * sp
        one_minus = (b_prev + c_n * (cp * cp) / (1.0 + np.abs(sp))) / a_n
        near_one = np.abs(x) > 0.5
        alt = np.sign(x) * (
            0.5 * np.pi - 2.0 * np.arcsin(np.sqrt(np.clip(0.5 * one_minus, 0.0, 1.0)))
        )
        phi = 0.5 * (phi + np.where(near_one, alt, np.arcsin(np.clip(x, -1.0, 1.0))))
    sn = np.sin(phi)
    cn = np.cos(phi)
    dn = np.sqrt(cn * cn + m1_safe * sn * sn)
    if np.any(separatrix):
        with np.errstate(over="ignore"):
            sech = 1.0 / np.cosh(u)
        sn = np.where(separatrix, np.tanh(u), sn)
        cn = np.where(separatrix, sech, cn)
        dn = np.where(separatrix, sech, dn)
    return sn, cn, dn


def elliptic_f_sc(s, c, m, m1):
    """``F(phi|m)`` with ``phi`` in ``[-pi, pi]`` given by ``(s, c)``, proportional to
    ``(sin phi, cos phi)`` (not necessarily normalised).

    Passing the sine and cosine keeps ``phi`` near ``+-pi/2`` exact where ``F`` is steep (near
    the separatrix ``F'`` is ``1/sqrt(cos^2 + m1 sin^2)``): forming ``phi`` first would round away
    the small cosine.
    """
    s, c, m, m1 = np.broadcast_arrays(*(np.asarray(x, float) for x in (s, c, m, m1)))
    r = np.hypot(s, c)
    r = np.where(r > 0.0, r, 1.0)
    s, c = s / r, c / r
    upper = c < 0.0  # |phi| > pi/2: F(phi) = sign(phi) (2K - F(pi - |phi|))
    sa, ca = np.abs(s), np.abs(c)
    from scipy import special

    f = sa * special.elliprf(ca * ca, ca * ca + m1 * sa * sa, 1.0)
    separatrix = m1 == 0.0
    if np.any(separatrix):
        with np.errstate(divide="ignore", over="ignore"):
            f = np.where(separatrix, np.arcsinh(sa / ca), f)
    with np.errstate(invalid="ignore"):
        f = np.where(upper, 2.0 * elliptic_k(m1) - f, f)
    return np.where(s < 0.0, -f, f)


def elliptic_f(phi, m, m1):
    """Incomplete integral of the first kind ``F(phi|m)`` for ``phi`` in ``[-pi, pi]``.

    For ``m1 == 0`` (``m = 1``) only ``|phi| < pi/2`` is finite: ``F = asinh(tan phi)``.
    """
    phi = np.asarray(phi, float)
    return elliptic_f_sc(np.sin(phi), np.cos(phi), m, m1)

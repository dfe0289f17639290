"""Jacobi elliptic functions and the incomplete integral, accurate up to the separatrix.

``scipy.special.ellipj(u, m)`` takes the parameter ``m`` and forms ``1 - m`` itself, so it
loses the complementary parameter ``m1 = 1 - m`` to cancellation as ``m -> 1`` (about 1e-8
error at ``m1 = 1e-8``, wrong below 1e-10; physics.md §4). Near the free rigid body's
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
from scipy import special

__all__ = ["jacobi_sn_cn_dn", "elliptic_f", "elliptic_k"]

_MAX_AGM_ITERATIONS = 64  # AGM converges quadratically; even m1 = 1e-300 needs about 12


def elliptic_k(m1):
    """Complete integral of the first kind ``K`` as a function of ``m1 = 1 - m``."""
    return special.ellipkm1(m1)


def jacobi_sn_cn_dn(u, m, m1):
    """``sn(u|m), cn(u|m), dn(u|m)`` with the parameter given as ``m`` and ``m1 = 1 - m``.

    ``0 <= m <= 1``; ``m1`` must equal ``1 - m`` to the accuracy wanted (it is the accurate one
    of the pair near the separatrix, ``m`` the accurate one near ``m = 0``).
    Accuracy: a few ulp times ``|u|`` (the argument is not reduced modulo ``4K`` here).
    """
    u, m, m1 = np.broadcast_arrays(np.asarray(u, float), np.asarray(m, float), np.asarray(m1, float))
    separatrix = m1 == 0.0
    m1_safe = np.where(separatrix, 0.5, m1)
    m_safe = np.where(separatrix, 0.5, m)
    # Descending Landen / AGM: a0 = 1, b0 = sqrt(m1), c0 = sqrt(m).
    a = np.ones_like(u)
    b = np.sqrt(m1_safe)
    c_list = []
    a_list = []
    for _ in range(_MAX_AGM_ITERATIONS):
        c = 0.5 * (a - b)
        a, b = 0.5 * (a + b), np.sqrt(a * b)
        c_list.append(c)
        a_list.append(a)
        if np.all(np.abs(c) <= 1e-17 * a):
            break
    n = len(c_list)
    phi = (2.0**n) * a * u
    for c_n, a_n in zip(reversed(c_list), reversed(a_list)):
        phi = 0.5 * (phi + np.arcsin(np.clip(c_n / a_n * np.sin(phi), -1.0, 1.0)))
    sn = np.sin(phi)
    cn = np.cos(phi)
    dn = np.sqrt(cn * cn + m1_safe * sn * sn)
    if np.any(separatrix):
        with np.errstate(over="ignore"):
            sech = 1.0 / np.cosh(u)
        sn = np.where(separatrix, np.tanh(u), sn)
        cn = np.where(separatrix, sech, cn)
        dn = np.where(separatrix, sech, dn)
    del m_safe
    return sn, cn, dn


def elliptic_f(phi, m, m1):
    """Incomplete integral of the first kind ``F(phi|m)`` for ``phi`` in ``[-pi, pi]``.

    For ``m1 == 0`` (``m = 1``) only ``|phi| < pi/2`` is finite: ``F = asinh(tan phi)``, and
    ``|phi| = pi/2`` gives ``+-inf``.
    """
    phi, m, m1 = np.broadcast_arrays(np.asarray(phi, float), np.asarray(m, float), np.asarray(m1, float))
    sign = np.sign(phi)
    a = np.abs(phi)
    # Reflect the upper half: F(pi - x) = 2K - F(x) for 0 <= x <= pi/2.
    upper = a > 0.5 * np.pi
    x = np.where(upper, np.pi - a, a)
    s = np.sin(x)
    c = np.cos(x)
    f = s * special.elliprf(c * c, c * c + m1 * s * s, 1.0)
    separatrix = m1 == 0.0
    if np.any(separatrix):
        with np.errstate(divide="ignore", over="ignore"):
            f = np.where(separatrix, np.arcsinh(s / c), f)
    k = elliptic_k(m1)
    f = np.where(upper, 2.0 * k - f, f)
    return sign * f

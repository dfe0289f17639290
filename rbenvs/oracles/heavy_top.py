"""Analytic results for the heavy (Lagrange) top on a fixed pivot (docs/physics.md §2).

Pure numpy/math functions of scalar parameters; nothing here knows about environments.

Conventions (shared by every function below, and by the treatment of the top in [T 3.62-3.83]):

* ``z`` is the upward vertical; gravity ``g`` acts along ``-z``.
* The symmetry axis ``k`` points from the pivot ``O`` to the centre of mass ``G`` (body axis
  ``chi = e3``); ``length`` (``l`` in docs/physics.md, ``h`` in [T]) is ``|OG|``.
* ``I1 = I2 = A`` and ``I3 = C`` are the principal moments **about the pivot** (not about the
  centre of mass: ``A = A_G + mass * length**2``).
* ``tilt`` (``alpha``, the Euler angle ``theta``) is the angle from ``+z`` to ``k``: 0 is the
  upright ("sleeping") top, ``pi/2`` horizontal, ``pi`` hanging straight down.
* ``spin`` (``n`` in [T], ``Omega3`` in [MR]) is the body angular velocity
  component along ``k``: ``spin > 0`` is a right-handed (counter-clockwise seen from the tip of
  ``k``) rotation about the pivot-to-centre-of-mass axis. It is conserved [T 3.66].
* A precession rate ``p`` is ``d(phi)/dt`` with ``phi`` the azimuth of ``k`` about ``+z``:
  ``p > 0`` is counter-clockwise seen from above. With these conventions ``spin > 0`` gives a
  slow precession ``p ~ m g h/(C n) > 0``: the top precesses in the same sense as it spins.

Units: SI throughout (kg, m, s, rad, kg m^2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..dynamics.validation import require_all_positive, require_finite

__all__ = [
    "critical_spin",
    "upright_eigenvalues",
    "RegularPrecession",
    "regular_precession_rates",
    "FastTopNutation",
    "fast_top_nutation",
]


# --------------------------------------------------------------------------------------------
# validation helpers (ValueError naming the parameter and the rule, as rbenvs.dynamics.validation)


def _require_tilt(name: str, value) -> float:
    v = require_finite(name, value)
    if not (0.0 <= v <= math.pi):
        raise ValueError(
            f"{name} must lie in [0, pi] (angle from the upward vertical), got {value!r}"
        )
    return v


def _require_nonzero(name: str, value) -> float:
    v = require_finite(name, value)
    if v == 0.0:
        raise ValueError(f"{name} must be finite and nonzero, got {value!r}")
    return v


# --------------------------------------------------------------------------------------------
# upright (sleeping) top: [MR 15.10]


def critical_spin(I1, I3, mass, length, gravity) -> float:
    """Spin rate ``Omega3`` above which the upright spinning Lagrange top is stable.

    ``Omega_c = 2 sqrt(M g l I1) / I3`` (Heavy Top Stability Theorem [MR 15.10.1]; equivalently
    ``Pi3^2 > 4 M g l I1`` with ``Pi3 = I3 Omega3``). ``I1`` is the transverse moment **about the
    pivot**, ``I3`` the axial moment [kg m^2]; ``mass`` [kg], ``length`` = pivot to centre of mass
    [m], ``gravity`` [m/s^2]. Above ``Omega_c`` (either sense of spin: the condition is on
    ``|Omega3|``) the linearization :func:`upright_eigenvalues` is purely imaginary; below it two
    eigenvalues have positive real part.
    """
    I1, I3, mass, length, gravity = require_all_positive(
        I1=I1, I3=I3, mass=mass, length=length, gravity=gravity
    )
    return 2.0 * math.sqrt(mass * gravity * length * I1) / I3


def upright_eigenvalues(I1, I3, mass, length, gravity, spin) -> np.ndarray:
    """Eigenvalues of the heavy top linearized about the upright spinning state.

    System [MR 15.10.1-2]: ``dPi/dt = Pi x Omega + M g l Gamma x chi``, ``dGamma/dt = Gamma x
    Omega`` with ``I = diag(I1, I1, I3)`` about the pivot and ``chi = e3``; equilibrium
    ``Gamma = e3``, ``Pi = (0, 0, I3 spin)``. On the 4-dimensional tangent space to the coadjoint
    orbit ([MR 15.10.14]; the linearized flow leaves ``dPi3`` and ``dGamma3`` fixed, so the full 6x6
    Jacobian has these four eigenvalues plus two zeros) the characteristic polynomial is
    [MR 15.10.16], with ``w = Pi3/I3 = spin``:

        lambda^4 + [(I1^2 + (I1 - I3)^2) w^2 - 2 M g l I1] / I1^2 * lambda^2
                 + [(I1 - I3) w^2 + M g l]^2 / I1^2 = 0,

    a quadratic in ``x = lambda^2`` with discriminant
    ``(2 I1 - I3)^2 w^2 (I3^2 w^2 - 4 M g l I1) / I1^4`` (printed after [MR 15.10.16]): for
    ``|spin| >`` :func:`critical_spin` both roots ``x`` are real and non-positive, so every
    ``lambda`` is imaginary (spectrally stable); below it ``x`` is a complex pair and the four
    ``lambda`` are ``+-lambda0, +-conj(lambda0)`` with ``Re lambda0 != 0`` (unstable).
    (tests/test_oracles_tops.py checks these roots against the eigenvalues of a
    finite-difference Jacobian of the 6-dimensional vector field.)

    Returns a complex array of shape ``(4,)`` [1/s], sorted by real part then imaginary part
    (``numpy.sort_complex``).
    """
    I1, I3, mass, length, gravity = require_all_positive(
        I1=I1, I3=I3, mass=mass, length=length, gravity=gravity
    )
    w = require_finite("spin", spin)
    mgl = mass * gravity * length
    w2 = w * w
    b = ((I1 * I1 + (I1 - I3) ** 2) * w2 - 2.0 * mgl * I1) / (I1 * I1)
    c = ((I1 - I3) * w2 + mgl) ** 2 / (I1 * I1)
    disc = complex((2.0 * I1 - I3) ** 2 * w2 * (I3 * I3 * w2 - 4.0 * mgl * I1) / I1**4)
    x1, x2 = _quadratic_roots(complex(b), complex(c), disc)
    if disc.real < 0.0:  # real coefficients: the roots are an exact conjugate pair
        x2 = x1.conjugate()
    r1, r2 = np.sqrt(x1), np.sqrt(x2)
    return np.sort_complex(np.array([r1, -r1, r2, -r2], dtype=complex))


def _quadratic_roots(b: complex, c: complex, disc: complex) -> tuple[complex, complex]:
    """Roots of ``x^2 + b x + c`` given its discriminant ``b^2 - 4c``, without cancellation."""
    s = np.sqrt(disc)
    # pick the sign that adds |b| and |s| (citardauq form); q = 0 only when b = disc = 0 (c = 0)
    if (b.conjugate() * s).real < 0.0:
        s = -s
    q = -0.5 * (b + s)
    if q == 0:
        return 0j, 0j
    return complex(q), complex(c / q)


# --------------------------------------------------------------------------------------------
# regular and pseudo-regular precession: [T 3.71-3.83]


# |cos(tilt)| at or below this is a horizontal axis: cos(pi/2) evaluates to 6.1e-17, not 0.
_COS_ZERO = 4.0 * float(np.finfo(float).eps)


class RegularPrecession(NamedTuple):
    """The two regular-precession rates [rad/s], ``slow`` (smaller ``|p|``) then ``fast``."""

    slow: float
    fast: float


def regular_precession_rates(A, C, mass, length, gravity, spin, tilt) -> RegularPrecession:
    """Precession rates ``p`` of the regular (steady) precession at constant ``tilt``.

    For ``theta = alpha`` constant, ``theta' = theta'' = 0`` in [T 3.74] gives [T 3.82]
    ``sin(alpha) (A p^2 cos(alpha) - C n p + m g h) = 0``; for ``sin(alpha) != 0``:

        A cos(alpha) p^2 - C n p + m g h = 0,

    with ``A``, ``C`` about the pivot, ``n = spin``, ``h = length``, ``alpha = tilt`` and the sign
    conventions of the module docstring (``p`` counter-clockwise about ``+z``, ``n`` about the
    pivot-to-centre-of-mass axis; checked in the tests by integrating the top from the state
    built with each root). The roots are computed without cancellation:
    ``q = (C n + sgn(C n) sqrt(D)) / 2``, ``slow = m g h / q``, ``fast = q / (A cos(alpha))``,
    with ``D = (C n)^2 - 4 A m g h cos(alpha)``; ``|slow| <= |fast|`` always. For large spin
    [T 3.83] ``slow ~ m g h/(C n)`` and ``fast ~ C n/(A cos(alpha))``, both in the sense of ``n``
    when ``cos(alpha) > 0``. For ``cos(alpha) < 0`` (centre of mass below the pivot) the roots
    have opposite signs and always exist; at ``spin = 0`` they are the conical-pendulum rates
    ``+-sqrt(m g h/(A |cos(alpha)|))``, returned as ``(positive, negative)``.

    ``cos(alpha) = 0`` (horizontal axis, ``tilt = pi/2`` up to rounding: ``|cos| <= 4 eps``):
    the equation is linear, the single root is ``slow = m g h/(C n)`` and ``fast`` is ``nan``
    (it escapes to infinity); ``spin = 0`` is then impossible. At ``tilt = 0`` or ``pi`` the
    factor ``sin(alpha)`` of [T 3.82] vanishes and any ``p`` is a (trivial) steady state; the
    returned roots are then the limits of the tilted ones.

    Raises ``ValueError`` (naming ``spin``) when ``(C n)^2 < 4 A m g h cos(alpha)``: the top
    spins too slowly for any real regular precession at this tilt.
    """
    A, C, mass, length, gravity = require_all_positive(
        A=A, C=C, mass=mass, length=length, gravity=gravity
    )
    n = require_finite("spin", spin)
    alpha = _require_tilt("tilt", tilt)
    mgh = mass * gravity * length
    cos_a = math.cos(alpha)
    K = C * n
    if abs(cos_a) <= _COS_ZERO:
        if K == 0.0:
            raise ValueError(
                "spin must be nonzero for a regular precession of a horizontal top (tilt = pi/2), "
                "got 0"
            )
        return RegularPrecession(mgh / K, math.nan)
    disc = K * K - 4.0 * A * mgh * cos_a
    if disc < 0.0:
        n_min = 2.0 * math.sqrt(A * mgh * cos_a) / C
        raise ValueError(
            f"spin must satisfy (C*spin)^2 >= 4 A m g h cos(tilt) for a real regular precession, "
            f"i.e. |spin| >= {n_min!r} at tilt={alpha!r}; got spin={spin!r}"
        )
    if K == 0.0:  # cos(alpha) < 0 here: the conical pendulum, an exactly symmetric pair
        rate = math.sqrt(mgh / (A * -cos_a))
        return RegularPrecession(rate, -rate)
    q = 0.5 * (K + math.copysign(math.sqrt(disc), K))
    return RegularPrecession(mgh / q, q / (A * cos_a))


@dataclass(frozen=True)
class FastTopNutation:
    """Asymptotic pseudo-regular precession of a fast top released without precession.

    Fields (SI units, angles in rad):

    * ``cos_amplitude``: ``cos(beta) - cos(alpha) ~ -2 A m g h sin^2(alpha)/(C n)^2`` [T 3.76],
      ``beta`` the lowest tilt reached (``beta >= alpha``);
    * ``angle_amplitude``: ``beta - alpha ~ 2 A m g h sin(alpha)/(C n)^2`` [T 3.79];
    * ``period``: nutation period ``T_n = 2 pi A/(C |n|)`` (after [T 3.79]);
    * ``mean_precession_rate``: ``<phi'> ~ m g h/(C n)`` [T 3.78], signed like ``n``;
    * ``mean_tilt``: ``<theta> ~ alpha + A m g h sin(alpha)/(C n)^2`` [T 3.77];
    * ``expansion_parameter``: ``eps = A m g h/(C n)^2 = T_n/T_p`` [T 3.80]. The formulas are the
      leading terms of an expansion in ``eps``: their relative errors are ``O(eps)``, so they are
      meaningful only for ``eps << 1``.
    """

    cos_amplitude: float
    angle_amplitude: float
    period: float
    mean_precession_rate: float
    mean_tilt: float
    expansion_parameter: float


def fast_top_nutation(A, C, mass, length, gravity, spin, tilt) -> FastTopNutation:
    """Nutation of a fast top released at ``tilt`` with spin ``n`` and no precession [T 3.71-3.81].

    Initial conditions [T 3.71]: ``theta = alpha``, ``theta' = phi' = 0``, ``omega3 = n``. The axis
    first falls, then nods between ``alpha`` and ``beta > alpha`` (cusps at ``alpha``) while
    drifting around ``+z`` in the sense of the spin. ``A``, ``C`` about the pivot, ``h = length``;
    conventions as in the module docstring. The results are asymptotic for large spin, with
    relative errors ``O(A m g h/(C n)^2)`` (see :class:`FastTopNutation`); nothing checks that the
    spin is actually large: read ``expansion_parameter``.

    ``spin`` must be finite and nonzero (the formulas divide by ``C n``).
    """
    A, C, mass, length, gravity = require_all_positive(
        A=A, C=C, mass=mass, length=length, gravity=gravity
    )
    n = _require_nonzero("spin", spin)
    alpha = _require_tilt("tilt", tilt)
    mgh = mass * gravity * length
    K = C * n
    eps = A * mgh / (K * K)
    s = math.sin(alpha)
    return FastTopNutation(
        cos_amplitude=-2.0 * eps * s * s,
        angle_amplitude=2.0 * eps * s,
        period=2.0 * math.pi * A / abs(K),
        mean_precession_rate=mgh / K,
        mean_tilt=alpha + eps * s,
        expansion_parameter=eps,
    )

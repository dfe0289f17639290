"""Oracles for the free rigid body (docs/physics.md §1): the exact solution and the stability
theorem.

Pure functions of the moments of inertia and the angular momentum, no dependency on the
environments. The exact solution is the elliptic-function motion of [MR 15.8] (implemented
once, in :class:`rbenvs.dynamics.FreeBodyOrbit`, which the ``exact`` integrator also uses);
tests check it against DOP853 so that the integrator and the oracle are not only checked
against each other.
"""

from __future__ import annotations

import numpy as np

from ..dynamics import FreeBodyOrbit, FreeBodyParams

__all__ = [
    "exact_solution",
    "taylor_solution",
    "orbit_period",
    "linearization",
    "linearization_eigenvalues",
    "axis_stability",
    "intermediate_axis_growth_rate",
]


def _params(inertia) -> FreeBodyParams:
    return FreeBodyParams(tuple(inertia))


def _momentum(pi) -> tuple:
    arr = np.asarray(pi, dtype=float)
    if arr.shape[:1] != (3,):
        raise ValueError(
            f"pi must have a leading axis of length 3 (Pi1, Pi2, Pi3), got shape {arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        raise ValueError("pi must be finite")
    return tuple(arr)


def exact_solution(inertia, pi0, t):
    """Body angular momentum ``Pi(t)`` of the torque-free body ([MR 15.8]).

    Args:
        inertia: principal moments ``(I1, I2, I3)`` (any order; equal moments allowed).
        pi0: ``(3, ...)`` initial ``Pi``; trailing axes are a batch.
        t: times [s], broadcast against the batch (e.g. shape ``(..., nt)`` with ``pi0[...,
        None]``).

    Returns:
        ``(3, ...)`` array. Both orbit families, the symmetric case (``m = 0``), the separatrix
        (``m = 1``: sech/tanh, [MR 15.8.10]) and the equilibria are covered.
    """
    orbit = FreeBodyOrbit(_params(inertia), _momentum(pi0))
    return np.array(np.broadcast_arrays(*orbit.momentum_at(np.asarray(t, dtype=float))))


def taylor_solution(inertia, pi0, times, digits: int = 32):
    """Body angular momentum ``Pi(t)`` of the torque-free body at ``times`` (a 1-D sequence),
    ``(len(times), 3)``, by mpmath's Taylor-series integrator (``mpmath.odefun``) at ``digits``
    decimal digits from the float64 ``pi0`` exactly: the reference where float64's elliptic
    solution runs out of digits, near the separatrix (0.0001 rad/s off the intermediate axis of
    the body (2, 1.5, 1) at 5 rad/s :func:`exact_solution` agrees with it only to 1.5e-9; at 32
    and at 45 digits it gives the same floats over 20 s). Needs mpmath (the ``reference`` extra,
    in ``dev``)."""
    try:
        import mpmath as mp
    except ImportError as exc:  # (an optional dependency, imported only here)
        raise ImportError("taylor_solution needs mpmath: pip install 'rbenvs[reference]'") from exc
    moments = _params(inertia).inertia
    start = _momentum(pi0)
    with mp.workdps(int(digits)):
        ii = [mp.mpf(float(x)) for x in moments]
        y0 = [mp.mpf(float(x)) for x in start]

        def euler(t, p):  # Euler's equations, dPi/dt = Pi x I^-1 Pi
            w = [p[i] / ii[i] for i in range(3)]
            return [p[1] * w[2] - p[2] * w[1], p[2] * w[0] - p[0] * w[2], p[0] * w[1] - p[1] * w[0]]

        solution = mp.odefun(euler, 0, y0)
        return np.array([[float(x) for x in solution(mp.mpf(float(t)))] for t in times])


def orbit_period(inertia, pi0):
    """Period [s] of ``Pi(t)``: ``4 K(m) / |nu|`` (``2 pi / |lambda|`` for a symmetric body,
    ``lambda = (I1 - I3) Pi3 / (I1 I3)``); ``inf`` on the separatrix and at equilibria."""
    return FreeBodyOrbit(_params(inertia), _momentum(pi0)).period


def linearization(inertia, pi_star):
    """Jacobian ``d(Pi x Omega)/dPi`` at ``pi_star`` (3x3): the linearised Euler equations."""
    i = np.asarray(_params(inertia).inertia)
    p = np.asarray(_momentum(pi_star))
    w = p / i

    # d/dPi (Pi x I^-1 Pi) = hat(Pi) I^-1 - hat(I^-1 Pi)
    def hat(v):
        return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])

    return hat(p) @ np.diag(1.0 / i) - hat(w)


def linearization_eigenvalues(inertia, axis: int, p: float):
    """Eigenvalues of the linearisation at the steady spin ``Pi = p e_axis`` [MR 15.9].

    ``lambda^2 = p^2 (I_j - I_i)(I_k - I_j) / (I_i I_j^2 I_k)`` for the two transverse modes and
    0 for the axial one (``j = axis``): real ``+-lambda`` (unstable) only about the middle axis.
    """
    if axis not in (0, 1, 2):
        raise ValueError(f"axis must be 0, 1 or 2, got {axis!r}")
    ii = _params(inertia).inertia
    j = axis
    a, b = (j + 1) % 3, (j + 2) % 3
    lam2 = p * p * (ii[j] - ii[a]) * (ii[b] - ii[j]) / (ii[a] * ii[j] ** 2 * ii[b])
    lam = np.sqrt(complex(lam2))
    return np.array([lam, -lam, 0.0 + 0.0j])


def axis_stability(inertia) -> tuple[str, str, str]:
    """Rigid body stability theorem [MR 15.9.1], per axis: ``"stable"`` (largest or smallest
    moment: Lyapunov stable), ``"unstable"`` (the intermediate one) or ``"neutral"`` (a
    moment equal to another: the linearisation is degenerate; with two equal moments every
    axis in their plane is an equilibrium, neutrally stable, and the distinct axis is stable).
    """
    ii = _params(inertia).inertia
    out = []
    for j in range(3):
        a, b = ii[(j + 1) % 3], ii[(j + 2) % 3]
        if ii[j] == a or ii[j] == b:
            out.append("neutral")
        elif (ii[j] - a) * (b - ii[j]) > 0.0:
            out.append("unstable")
        else:
            out.append("stable")
    return tuple(out)


def intermediate_axis_growth_rate(inertia, p: float) -> float:
    """Growth rate [1/s] of a perturbation of the spin ``Pi = p e_mid`` about the middle axis:
    ``lambda = (|p| / I2) sqrt((I1 - I2)(I2 - I3) / (I1 I3))`` with ``I1 > I2 > I3``
    (docs/physics.md §1). Raises ``ValueError`` when the moments are not distinct (no intermediate
    axis)."""
    ii = sorted(_params(inertia).inertia, reverse=True)
    i1, i2, i3 = ii
    if not (i1 > i2 > i3):
        raise ValueError(
            "inertia must have three distinct moments for an intermediate axis, got "
            f"{tuple(inertia)}"
        )
    return abs(p) / i2 * float(np.sqrt((i1 - i2) * (i2 - i3) / (i1 * i3)))

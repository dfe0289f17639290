"""Analytic results for the tippe top: Jellett's integral and the energy criterion for inversion.

Pure functions; conventions of docs/physics.md §3 ([T 3.92-3.114]):

* a sphere of radius ``R`` (``a`` in [T]) on the table ``z = 0``, ``z_hat`` up;
* symmetry axis ``k`` (unit vector, space frame); centre of mass ``G = centre - h k`` with
  ``h = alpha R``, ``0 < alpha < 1``;
* ``A = I1 = I2``, ``C = I3``: principal moments **about the centre of mass** [kg m^2];
  ``gamma = A / C``;
* ``theta`` = angle between ``k`` and ``z_hat``: ``theta = 0`` is the top on its broad end with
  the centre of mass low (height ``R - h``), ``theta = pi`` the inverted top on its stem (centre
  of mass high, ``R + h``); the height of ``G`` is ``R - h cos(theta)`` [T 3.93];
* contact point ``P = centre - R z_hat``; ``L`` = angular momentum about ``G`` (space frame);
* ``spin`` is the angular velocity about ``k`` (right-handed about ``k``).

The energy argument (docs/physics.md §3; Rauch-Wojciechowski, Sköldstam and Glad 2005): at fixed
Jellett integral ``J`` and tilt ``theta`` the least total energy is

    E*(theta) = J^2 / (2 R^2 D(theta)) + m g R (1 - alpha cos(theta)),
    D(theta)  = A sin^2(theta) + C (alpha - cos(theta))^2,

(minimize ``L . I^-1 L / 2`` over ``L . (R z_hat - h k) = J``: ``L = J I a / (a . I a)`` with
``a = R z_hat - h k``, ``a . I a = R^2 D``; no translational or nutational kinetic energy).
Friction dissipates energy but keeps ``J``; as ``E >= E*(theta)`` always, the top ends near a
minimum of ``E*``. Expanding ``E*`` to second order about the two ends (derived here and checked
numerically in the tests):

* ``theta = 0`` is a local maximum (unstable) iff ``gamma > 1 - alpha`` **and**
  ``|J| > J_upright = sqrt(m g R^3 C alpha) (1 - alpha)^2 / sqrt(gamma - 1 + alpha)``;
* ``theta = pi`` is a local minimum (stable) iff ``gamma < 1 + alpha`` **and**
  ``|J| > J_min = sqrt(m g R^3 C alpha) (1 + alpha)^2 / sqrt(1 + alpha - gamma)``.

docs/physics.md states the first condition as ``A > (1 - alpha) C`` alone; that is its large-``J``
limit (the sign of ``d^2E*/dtheta^2`` at ``theta = 0`` changes at
``A = (1 - alpha) C + m g R^3 alpha C^2 (1 - alpha)^4 / J^2``). The second condition agrees
with docs/physics.md exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from ..dynamics.validation import require_all_positive, require_finite

__all__ = [
    "jellett",
    "jellett_upright",
    "energy_star",
    "InversionCriterion",
    "inversion_criterion",
    "inversion_spin_threshold",
    "final_tilt",
]

FULL_INVERSION = "full inversion"
PARTIAL_INVERSION = "partial inversion"
NO_INVERSION = "no inversion"

_FINAL_TILT_GRID = 4097  # grid points on [0, pi] before the local refinement


# --------------------------------------------------------------------------------------------
# validation


def _require_alpha(value) -> float:
    v = require_finite("alpha", value)
    if not (0.0 < v < 1.0):
        raise ValueError(
            f"alpha (= h/R, centre-of-mass offset over radius) must lie in (0, 1), got {value!r}"
        )
    return v


def _finite_array(name: str, value) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an array of real numbers, got {value!r}") from None
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite in every component")
    return arr


def _vector_array(name: str, value) -> np.ndarray:
    arr = _finite_array(name, value)
    if arr.ndim < 1 or arr.shape[-1] != 3:
        raise ValueError(
            f"{name} must have a last axis of length 3 (x, y, z), got shape {arr.shape}"
        )
    return arr


# --------------------------------------------------------------------------------------------
# Jellett's integral


def jellett(L, k, R, alpha):
    """Jellett's integral ``J = L . (R z_hat - h k) = -L . (P - G)`` [T 3.106], ``h = alpha R``.

    ``L``: ``(..., 3)`` angular momentum about the centre of mass [kg m^2/s], space frame;
    ``k``: ``(..., 3)`` unit symmetry axis, space frame (not renormalized here); the leading axes
    broadcast. Returns ``(...)`` [kg m^3/s] (a float for single vectors). In Euler angles this is
    [T]'s ``R A phi' sin^2(theta) + (R cos(theta) - h) C omega3``. Conserved under any friction
    law at the contact point.
    """
    (R,) = require_all_positive(R=R)
    alpha = _require_alpha(alpha)
    L = _vector_array("L", L)
    k = _vector_array("k", k)
    try:
        np.broadcast_shapes(L.shape, k.shape)
    except ValueError:
        raise ValueError(f"L and k must broadcast, got shapes {L.shape} and {k.shape}") from None
    out = R * (L[..., 2] - alpha * np.sum(L * k, axis=-1))
    return float(out) if np.ndim(out) == 0 else out


def jellett_upright(C, R, alpha, spin) -> float:
    """Jellett's integral of the top spinning at ``spin`` [rad/s] upright on its broad end
    (``theta = 0``, ``L = C spin z_hat``): ``J = R C spin (1 - alpha)``."""
    C, R = require_all_positive(C=C, R=R)
    alpha = _require_alpha(alpha)
    n = require_finite("spin", spin)
    return R * C * n * (1.0 - alpha)


# --------------------------------------------------------------------------------------------
# the least energy at fixed J and tilt


def _d_theta(theta, alpha, A, C):
    c = np.cos(theta)
    s = np.sin(theta)
    return A * s * s + C * (alpha - c) ** 2


def _energy_star(theta, J, m, g, R, alpha, A, C):
    return J * J / (2.0 * R * R * _d_theta(theta, alpha, A, C)) + m * g * R * (
        1.0 - alpha * np.cos(theta)
    )


def _slope_factor(theta, J, m, g, R, alpha, A, C):
    """``dE*/dtheta = sin(theta) * factor``,
    ``factor = m g R alpha - J^2 ((A - C) cos + C alpha)/(R^2 D^2)``.

    ``d^2E*/dtheta^2`` is ``factor(0)`` at ``theta = 0`` and ``-factor(pi)`` at ``theta = pi``.
    """
    d = _d_theta(theta, alpha, A, C)
    return m * g * R * alpha - J * J * ((A - C) * np.cos(theta) + C * alpha) / (R * R * d * d)


def _tippe_params(m, g, R, alpha, A, C):
    m, g, R, A, C = require_all_positive(m=m, g=g, R=R, A=A, C=C)
    return m, g, R, _require_alpha(alpha), A, C


def energy_star(theta, J, m, g, R, alpha, A, C):
    """Least energy [J] at tilt ``theta`` [rad] and Jellett integral ``J`` [kg m^3/s]:

    ``E*(theta) = J^2/(2 R^2 D(theta)) + m g R (1 - alpha cos(theta))``,
    ``D = A sin^2(theta) + C (alpha - cos(theta))^2`` (docs/physics.md §3; see the module
    docstring).

    ``theta`` and ``J`` broadcast (any shapes); a float comes back for scalar inputs. Energy zero:
    the centre of mass at the table (potential ``m g (R - h cos(theta))``).
    """
    m, g, R, alpha, A, C = _tippe_params(m, g, R, alpha, A, C)
    theta = _finite_array("theta", theta)
    J = _finite_array("J", J)
    out = _energy_star(theta, J, m, g, R, alpha, A, C)
    return float(out) if np.ndim(out) == 0 else out


# --------------------------------------------------------------------------------------------
# the inversion criterion


@dataclass(frozen=True)
class InversionCriterion:
    """Result of :func:`inversion_criterion`.

    * ``gamma = A/C``;
    * ``upright_unstable``: ``gamma > 1 - alpha``: ``theta = 0`` is unstable for large enough
      ``J`` (namely ``|J| > J_upright``); for ``gamma <= 1 - alpha`` it is stable for every ``J``;
    * ``inverted_can_be_stable``: ``gamma < 1 + alpha``: ``theta = pi`` is stable for
      ``|J| > J_min``; for ``gamma >= 1 + alpha`` it is unstable for every ``J``;
    * ``J_min``: the Jellett threshold for a stable inverted top,
      ``sqrt(m g R^3 C alpha) (1 + alpha)^2 / sqrt(1 + alpha - gamma)``; given when
      ``1 - alpha < gamma < 1 + alpha`` and ``m, g, R`` were given, else ``None``;
    * ``J_upright``: the threshold for an unstable upright top,
      ``sqrt(m g R^3 C alpha) (1 - alpha)^2 / sqrt(gamma - 1 + alpha)``; given when
      ``gamma > 1 - alpha`` and ``m, g, R`` were given, else ``None``;
    * ``classification``: ``'full inversion'``, ``'partial inversion'`` or ``'no inversion'``
      (see :func:`inversion_criterion`);
    * ``J``: the Jellett integral the classification used, or ``None``.
    """

    gamma: float
    upright_unstable: bool
    inverted_can_be_stable: bool
    J_min: float | None
    J_upright: float | None
    classification: str
    J: float | None = None


def inversion_criterion(A, C, alpha, m=None, g=None, R=None, J=None) -> InversionCriterion:
    """Will a top spun on its broad end turn over? The energy criterion (module docstring).

    ``A``, ``C`` about the centre of mass, ``alpha = h/R``. Without ``J`` the classification is
    the regime of ``gamma = A/C`` (the outcome for fast enough spin):

    * ``gamma <= 1 - alpha``: ``'no inversion'`` (``theta = 0`` is stable whatever ``J``);
    * ``1 - alpha < gamma < 1 + alpha``: ``'full inversion'`` once ``|J| > max(J_upright, J_min)``;
    * ``gamma >= 1 + alpha``: ``'partial inversion'`` once ``|J| > J_upright``: the top rises to the
      interior minimum of ``E*`` (:func:`final_tilt`), never to ``theta = pi``.

    With ``J`` (which needs ``m``, ``g``, ``R``) it is the outcome at that ``J`` for a top that
    starts near ``theta = 0``: ``'no inversion'`` if ``theta = 0`` is a local minimum of ``E*``
    (``gamma <= 1 - alpha`` or ``|J| <= J_upright``; the top stays up even where ``E*`` has a
    lower minimum elsewhere, which happens), else ``'full inversion'`` if ``theta = pi`` is a
    local minimum (``gamma < 1 + alpha`` and ``|J| > J_min``), else ``'partial inversion'``.
    (Whenever ``theta = 0`` is unstable, ``E*`` has a single minimum on ``[0, pi]``; checked
    numerically over a wide parameter scan, not proved.)

    ``m`` [kg], ``g`` [m/s^2] and ``R`` [m] come together or not at all; without them the
    thresholds are ``None``.
    """
    A, C = require_all_positive(A=A, C=C)
    alpha = _require_alpha(alpha)
    mgr, J = _checked_scale(m, g, R, J)
    gamma = A / C
    upright_unstable = gamma > 1.0 - alpha
    inverted_can_be_stable = gamma < 1.0 + alpha
    J_min = J_upright = None
    if mgr is not None:
        m, g, R = mgr
        scale = math.sqrt(m * g * R**3 * C * alpha)
        if upright_unstable:
            J_upright = scale * (1.0 - alpha) ** 2 / math.sqrt(gamma - 1.0 + alpha)
        if upright_unstable and inverted_can_be_stable:
            J_min = scale * (1.0 + alpha) ** 2 / math.sqrt(1.0 + alpha - gamma)
    label = _inversion_label(J, upright_unstable, inverted_can_be_stable, J_min, J_upright)
    return InversionCriterion(
        gamma, upright_unstable, inverted_can_be_stable, J_min, J_upright, label, J
    )


def _checked_scale(m, g, R, J) -> tuple:
    """``((m, g, R), J)`` of :func:`inversion_criterion`, checked: ``m``, ``g`` and ``R``
    together (``None`` in place of the three without them) and ``J`` only with them."""
    given = {"m": m, "g": g, "R": R}
    missing = [name for name, v in given.items() if v is None]
    if missing and len(missing) < 3:
        raise ValueError(f"m, g and R must be given together; missing {', '.join(missing)}")
    mgr = None if missing else require_all_positive(m=m, g=g, R=R)
    if J is not None:
        if missing:
            raise ValueError(
                "J needs m, g and R (the thresholds it is compared with depend on them)"
            )
        J = require_finite("J", J)
    return mgr, J


def _inversion_label(J, upright_unstable, inverted_can_be_stable, J_min, J_upright) -> str:
    """The outcome of :func:`inversion_criterion`: the regime without ``J``, else the outcome
    at ``J`` of a top that starts near ``theta = 0``."""
    if J is None:
        if not upright_unstable:
            return NO_INVERSION
        if inverted_can_be_stable:
            return FULL_INVERSION
        return PARTIAL_INVERSION
    if not (upright_unstable and abs(J) > J_upright):
        return NO_INVERSION
    if inverted_can_be_stable and abs(J) > J_min:
        return FULL_INVERSION
    return PARTIAL_INVERSION


def inversion_spin_threshold(A, C, alpha, m, g, R) -> float:
    """Spin ``n`` [rad/s] of an upright start whose Jellett integral ``R C n (1 - alpha)`` equals
    ``J_min`` (:func:`inversion_criterion`): above it the inverted state is stable.

    Defined for ``1 - alpha < gamma < 1 + alpha`` (``ValueError`` naming ``A`` otherwise: there is
    no full inversion). Leaving ``theta = 0`` needs ``|J| > J_upright`` as well, which is usually
    the weaker condition but not always (``gamma`` just above ``1 - alpha``): for a guaranteed
    full inversion use ``max(J_min, J_upright) / (R C (1 - alpha))``.
    """
    crit = inversion_criterion(A, C, alpha, m=m, g=g, R=R)
    if crit.J_min is None:
        raise ValueError(
            "A must satisfy 1 - alpha < A/C < 1 + alpha for a full inversion, got A/C = "
            f"{crit.gamma!r} with alpha = {alpha!r}"
        )
    return crit.J_min / (float(R) * float(C) * (1.0 - float(alpha)))


# --------------------------------------------------------------------------------------------
# the final tilt


def final_tilt(J, m, g, R, alpha, A, C) -> float:
    """The tilt ``theta`` in ``[0, pi]`` of the global minimum of :func:`energy_star` at this ``J``.

    ``dE*/dtheta = sin(theta) F(theta)`` with ``F = m g R alpha - J^2 ((A - C) cos(theta) +
    C alpha) / (R^2 D^2)``. Candidates: ``theta = 0`` if ``F(0) >= 0``, ``theta = pi`` if
    ``F(pi) <= 0`` (the ends are always critical, ``E*`` being even about both), and every
    interior minimum, found as a ``-`` to ``+`` sign change of ``F`` on a dense grid (4097 points)
    and refined by the bracketing ``scipy.optimize.brentq``; the candidate with the least ``E*``
    wins. Deciding the ends by the sign of the curvature, not by comparing energies, matters:
    near a flat end the energy differences are below rounding (``E*`` is dominated by its
    ``J^2`` term). A dense-grid minimum refined by ``minimize_scalar(method='bounded')`` is the
    fallback should no candidate be found.

    This is where dissipation takes a top whose ``theta = 0`` is unstable (then ``E*`` has a single
    minimum); if ``theta = 0`` is stable (:func:`inversion_criterion` says ``'no inversion'``) the
    top stays near 0 even when the global minimum lies elsewhere.
    """
    m, g, R, alpha, A, C = _tippe_params(m, g, R, alpha, A, C)
    J = require_finite("J", J)
    args = (J, m, g, R, alpha, A, C)

    def energy(t):
        return float(_energy_star(t, *args))

    def factor(t):
        return float(_slope_factor(t, *args))

    grid = np.linspace(0.0, math.pi, _FINAL_TILT_GRID)
    F = _slope_factor(grid, *args)
    candidates = []
    if F[0] >= 0.0:
        candidates.append(0.0)
    if F[-1] <= 0.0:
        candidates.append(math.pi)
    for i in np.flatnonzero((F[:-1] < 0.0) & (F[1:] > 0.0)):
        candidates.append(
            optimize.brentq(
                factor, grid[i], grid[i + 1], xtol=1e-15, rtol=4.0 * np.finfo(float).eps
            )
        )
    if not candidates:  # not expected: a continuous E* has a minimum; guard against rounding
        values = _energy_star(grid, *args)
        i = int(np.argmin(values))
        lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
        res = optimize.minimize_scalar(
            energy, bounds=(lo, hi), method="bounded", options={"xatol": 1e-12}
        )
        candidates = [float(res.x), float(grid[i])]
    return float(min(candidates, key=energy))

"""Heavy-top checks of ``rbenvs verify`` (docs/physics.md §2), per integrator, on random Lagrange
tops.

Every top is a Lagrange top (``I1 = I2 = A`` and ``I3 = C`` about the pivot, centre of mass on
the symmetry axis ``chi = e3``) drawn from these ranges (``--seed``):

* mass ``M ~ U(0.5, 2)`` kg, pivot-to-centre-of-mass length ``l ~ U(0.05, 0.5)`` m,
  ``g = 9.81`` m/s^2;
* transverse inertia about the centre of mass ``A_G ~ U(1, 3) M l^2`` and axial
  ``C_G ~ U(1, 2) A_G`` (oblate bodies, from a sphere to a thin disc: real tops);
* about the pivot ``A = A_G + M l^2``, ``C = C_G``; so ``r = C/A`` lies in ``(0.5, 1.5)``.

Why these ranges: the checks below are scale-free in the gravity time ``t_g = sqrt(A/(M g l))``
(the tilt of a Lagrange top obeys an equation with the coefficients ``C n/A`` and ``M g l/A``
alone), but the body-frame rates, which set the step, are the spin ``n ~ 2/(r t_g)`` at the
threshold: a slender top (``r << 1``) needs ``1/r`` times more steps, ``1/r^2`` with Euler. The
range keeps every integrator within the time of the command.

Small fast tops (``n_small`` of them; ``--quick`` 1, full 3, :data:`SMALL_TOP_CASES`), toy tops
at whose rates a step of 1e-3 s matters: a thin disc of radius ``rho = s l``, ``s ~ U(0.9,
1.1)``, on a stem, the pivot at its tip ``l ~ U(1.5, 2.5)`` cm below the disc's centre, mass
``M ~ U(20, 100)`` g, ``A_G = M rho^2/4``, ``C_G = c M rho^2/2`` with ``c ~ U(0.9, 0.98)`` (the
stem's share of the axial moment neglected, and kept below a flat disc's ``2 A_G``). So ``C/A``
lies in ``(0.3, 0.46)`` and the critical spin ``4 sqrt(g/l) sqrt(s^2/4 + 1)/(c s^2)`` in
``(75, 155)`` rad/s. Rows: the critical spin by bisection, the tilt at 1.2 x critical and the
growth rate at 0.8 x critical, as for the tops above (:func:`threshold_checks`). At 1.2 x
critical the transverse components of ``Omega`` turn in the body at ``(1 - C/A) n ~ 80`` rad/s:
a scheme that turns rotating vectors outward by ``sqrt(1 + (w h)^2)`` per step (explicit
Euler) makes a stable top fall at ``h = 1e-3`` s (the tilt grows by ``exp((w h)^2 T/(2 h))``,
``e^4`` to ``e^18`` over ``50 t_g``: past the 1e-2 rad bound from 1e-3), where the tops above,
slower in the body, do not show it.

Each run's step is ``h = (omega h)/omega`` with ``omega`` the run's fastest body rate (the
initial ``|Omega|``, plus ``2/t_g`` where the top may fall) and ``omega h`` from
:data:`HEAVY_TOP_SETTINGS`; ``dop853`` is adaptive (``rtol = 1e-12``) and is only sampled.
One row per (integrator, check): the worst of the random cases (the one closest to, or
farthest beyond, its tolerance), with its parameters for a replay.

Checks:

* ``critical spin by bisection``: start upright (``Pi = C n e3``) with a ``1e-3`` rad tilt;
  the top *falls* if its tilt passes ``0.1`` rad within ``50 t_g``. Bisection (for ``dop853``,
  whose cost is per call, a multisection over 63 spins at once) of the spin between
  ``1`` and ``3 sqrt(M g l A)/C`` until the bracket is 0.1% of the spin; predicted:
  :func:`~rbenvs.oracles.critical_spin`, tolerance 1% relative. The horizon: just below the
  threshold, ``n = n_c (1 - delta)``, the tilt grows like ``exp(sigma t)`` with
  ``sigma t_g = sqrt(1 - (n/n_c)^2) ~ sqrt(2 delta)`` (the roots of [MR 15.10.16]: the same for
  every ``C/A``), so from ``1e-3`` to ``0.1`` rad it needs ``ln(100)/sigma`` plus
  the slower nonlinear part: 31 t_g at ``delta = 0.5%``, 43 t_g at ``0.2%``, 49 t_g at
  ``0.15%``. And a top with ``delta < 0.125%`` never passes ``0.1`` rad at all: its orbit from
  the upright state turns at ``cos(theta_max) = 2 (n/n_c)^2 - 1``, ``theta_max ~ sqrt(8 delta)``.
  So ``50 t_g`` puts the bisection ``0.1-0.2%`` below ``n_c``: well inside 1%, and any error of
  the simulator's gravity, inertia or spin coupling larger than that shows.
* ``upright stable at 1.2 x critical``: max tilt over ``50 t_g`` from a ``1e-3`` rad tilt
  (theorem: bounded; the row passes below ``1e-2``).
* ``upright growth rate at 0.5 x critical``: from a ``1e-8`` rad tilt, the exponential rate of
  the tilt fitted while it grows from ``1e-6`` to ``1e-4`` rad (the decaying mode is then
  ``1e-4`` of the growing one, and the motion still linear), against ``max Re`` of
  :func:`~rbenvs.oracles.upright_eigenvalues`, 2% relative.
* ``regular precession held``: tilt ``alpha ~ U(0.2, 1.2)``, spin ``n = k n_min``,
  ``k ~ U(1.1, 1.5)`` (``n_min = 2 sqrt(A M g l cos(alpha))/C``: the least spin with a real
  root), started on the slow root ``p`` of :func:`~rbenvs.oracles.regular_precession_rates`
  (``Omega = p Gamma + (n - p cos(alpha)) chi``). Over :data:`HEAVY_TOP_SETTINGS` ``periods``
  precession periods: ``max |tilt - alpha|`` (predicted 0) and the mean of
  ``precession_rate`` against ``p``, with tolerances from the scheme's order at its step.
* ``fast top``: released at ``alpha ~ U(0.2, 1.2)`` with ``Omega = n chi`` and
  ``eps = A M g l/(C n)^2`` log-uniform in ``(5e-4, 2e-3)``, over ``nods`` nutation periods:
  the nutation amplitude (the largest height of a nod above the mean of the cusps either side
  of it: for the exact motion ``beta - alpha``, the cusps lying at ``alpha``; for Euler, whose
  axis drifts outward at ``omega^2 h sin(2 alpha)/4`` per second, the drift cancels to first
  order; negative if the axis first rises instead of falling), the
  period (between the first and last maxima, each refined by a parabola through three
  samples) and the mean precession rate (``phi`` from the trapezoid of ``precession_rate``, from
  the release to the last cusp, where ``phi' = 0``), against
  :func:`~rbenvs.oracles.fast_top_nutation`. Relative tolerance ``5 eps``: the formulas are the
  first terms in ``eps``; the next are ``3 eps cos(alpha)`` for the amplitude (the cubic's root
  and ``arccos`` to second order), ``2 eps cos(alpha)`` for the period (the small-oscillation
  frequency ``C n/A (1 - 2 eps cos(alpha))``) and 1 to 1.5 ``eps`` for the mean rate (measured
  with dop853), so ``5 eps`` leaves ``2 eps`` to the integrator and the peak interpolation.
  Euler's tolerances add its own error at its step (``nutation_drift``), at most ``RATE_TOL``
  (2%, :mod:`rbenvs.verify.common`: what a first-order scheme may add is bounded by what the
  behaviour rows allow a rate, whatever its step).
* invariants with zero torque, from a random state (``Gamma`` uniform on the sphere,
  ``Omega`` of random direction and ``|Omega| ~ U(1, 4) sqrt(M g l A)/C``) over ``20 t_g``:
  the energy drift (relative to ``1/2 Pi.Omega + M g l``), the ``Pi.Gamma`` drift (relative to
  ``|Pi|``) and ``| |Gamma| - 1 |``, all as the max over the run. The splitting keeps both
  Casimirs to round-off (its pieces are exact rotations and a kick normal to ``Gamma``):
  tolerance ``ROUND_OFF sqrt(steps)``; the others project ``Gamma`` back to unit length after
  each step, so ``|Gamma|`` is at round-off for them too, while their energy and ``Pi.Gamma``
  drift by the order of the scheme at its step (:data:`HEAVY_TOP_SETTINGS`).

The package by concern: :mod:`.settings` (settings and random tops) and :mod:`.checks`.
"""

from __future__ import annotations

from ...dynamics import HeavyTop  # (the system the checks run, as the tests reach it)
from ..settings import HEAVY_TOP_SETTINGS, TopSetting
from .checks import checks_for_top, heavy_top_checks, threshold_checks
from .settings import (
    SMALL_TOP_CASES,
    _random_small_tops,
    random_tops,
)

__all__ = [
    "HEAVY_TOP_SETTINGS",
    "SMALL_TOP_CASES",
    "TopSetting",
    "heavy_top_checks",
    "random_tops",
    "HeavyTop",
    "_random_small_tops",
    "threshold_checks",
    "checks_for_top",
]

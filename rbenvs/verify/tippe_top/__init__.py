"""Tippe-top checks of ``rbenvs verify`` (docs/physics.md §3), per integrator (euler, rk4, dop853),
on random tops, and the ``--sweep`` of the final tilt over ``A/C`` and ``alpha``.

Random tops (``--seed``), every quantity from these ranges:

* radius ``R ~ U(0.01, 0.03)`` m, mass ``m ~ U(0.005, 0.05)`` kg, ``g = 9.81`` m/s^2 (toy tops);
* ``alpha = h/R ~ U(0.1, 0.4)`` (``U(0.1, 0.3)`` below the window, see next);
* ``A/C`` in one of three regimes of the theorem: **below** the window,
  ``A/C ~ U(max(0.55, 1 - 1.5 alpha), 1 - 1.15 alpha)`` (``C <= 2 A``, the model's triangle
  inequality, needs ``A/C >= 0.5``: the range is empty for ``alpha > 0.3``, hence the narrower
  ``alpha``); **inside**, ``A/C = 1 + s alpha``, ``s ~ U(-0.6, 0.6)``; **above**,
  ``A/C = 1 + (1 + s) alpha``, ``s ~ U(0.15, 0.5)`` (a partial inversion to 115-135 degrees);
* ``C = c m R^2``, ``c ~ U(0.38, 0.45)``, at most :func:`ball_bound` (the mass fits in the ball);
* Jellett's integral ``J = k J_c``, ``k ~ U(1.15, 1.3)``, ``J_c = sqrt(m g R^3 C alpha)
  (1 + alpha)^2 / sqrt(0.4 alpha)``: the ``J_min`` of :func:`~rbenvs.oracles.inversion_criterion`
  at ``A/C = 1 + 0.6 alpha``, the largest of the thresholds (``J_min``, ``J_upright``) over the
  inside range, so every top inside the window exceeds both and every top above it exceeds
  ``J_upright``; the upright spin is ``n = J/(R C (1 - alpha))``, ``n sqrt(R/g)`` 4 to 11.
  The ranges keep the top on the table (``N > 0``): faster or lighter-cored tops (``k = 1.5``,
  or ``c = 0.3``, at ``alpha >= 0.3``; measured) hop off it during the climb, which the model
  does not follow (no free flight: a run stops at the first ``N < 0`` and its row FAILs).

Time is measured in ``t_g = sqrt(R/g)`` (39 ms at ``R = 15`` mm), viscous friction by
``mu* = mu sqrt(g R)`` (``mu`` in s/m), so that every range above costs the same number of steps
whatever ``R``.

Checks (one row per integrator and check: the worst of the cases, with its parameters):

* ``Jellett held (<law>)``: the largest ``|J(t) - J(0)|`` over ``[0, T]``, relative to
  ``|L| (R + h)`` (the largest ``J`` the state's momentum allows; ``J`` itself can be near zero),
  for gliding friction (Coulomb ``mu ~ U(0.2, 0.5)``, regularised at the default ``1e-3`` m/s,
  and viscous ``mu* ~ U(0.1, 0.5)``), frictionless, rolling, and a moving table (viscous, the
  table's acceleration ``a_T = 0.3 g (cos(w1 t + p1), sin(w2 t + p2))``, ``w t_g ~ U(0.3, 1)``,
  held over each step at its mid-time). ``J`` is the oracle's :func:`~rbenvs.oracles.jellett` of
  ``L`` and ``k`` built from the simulated attitude and angular velocity. Random states per law:
  tilt ``U(0.2, pi - 0.2)``, uniform azimuth and heading, spin ``U(0.5, 1) n``, a transverse
  angular velocity ``U(0, 0.3)/t_g``, and (gliding) an initial slip ``U(0, 0.5) sqrt(g R)`` of
  random direction. ``T = 40 t_g``, ``10 t_g`` under Coulomb friction (stiff near zero slip: the
  step is then the stability bound) and for dop853 (costly per step). A run stops at the first
  step with ``N < 0`` (the top would hop; the case gives the time); a state
  that hops before its second sample is replaced by a new draw.
* ``energy non-increasing (<law>)``: the largest rise of the energy between two samples
  (``t_g/2`` apart), relative to ``E(0)``: friction dissipates while the table pushes
  (``N >= 0``, checked after every step). ``energy conserved (frictionless | rolling)``:
  ``max |E - E(0)|/E(0)``.
* ``inversion class`` and ``final tilt [deg]`` per regime: upright start (tilt 0.1 rad about a
  horizontal axis, spin ``n``, no slip), viscous friction ``mu* = 0.01/alpha``: the rise slows as
  ``mu* alpha`` falls, a large ``mu*`` makes the climb violent (hops at ``alpha >= 0.3``) and the
  last approach slow (near rolling, which keeps the energy); this settles every range above
  within the horizon. Run until settled: over the last ``25 t_g`` the tilt moves less than 0.05
  degree and the slip speed is below ``3e-5 R n`` (else ``5000 t_g``; the case says which).
  Predicted: :func:`~rbenvs.oracles.inversion_criterion` at the start's ``J`` (classes 0 = none,
  1 = partial, 2 = full) and the tilt of the minimum of ``E*`` (:func:`~rbenvs.oracles.final_tilt`),
  or 0 when the criterion says no inversion (``theta = 0`` is then a local minimum that the top
  keeps, though ``E*`` is lower at ``pi``). Measured: the final tilt and its class (below 30
  degrees none, above 170 full, else partial). Tolerance 0.5 degree: in the last, gliding phase
  the distance to the limit falls with the slip speed; at ``3e-5 R n`` it is below 0.1 degree
  (measured worst over 60 random tops: 0.1; 0.3 at ``1e-4 R n``); rk4's own error on the tilt is
  below 0.01 degree; the rest is margin. Behind the prediction: ``E >= E*(theta)`` at the state's
  ``J``, friction lowers ``E`` and keeps ``J``. Tops per integrator (quick / full): rk4 one /
  two per regime; dop853 one above the window / one per regime (rtol 1e-8: a final tilt needs
  no more); euler one / two inside the window with ``alpha <= 0.3`` (at its affordable step
  euler's outward drift outruns the slow frictional damping of an upright or a partially
  inverted top: see :data:`TIPPE_TOP_SETTINGS`).
* ``Jellett held through an inversion``: the default Leine-Glocker top (spin 150 rad/s, tilt
  0.1 rad, Coulomb ``mu = 0.3``) over 10 s, a whole inversion and more (the random states above
  run 10 to 40 ``t_g``, under a second): ``max |J - J0| / (|L| (R+h))``. rk4 at
  ``max_stable_step`` (measured 1.4e-8; tolerance 1e-7); a simulator at its own step is held to
  that scaled by the order when it declares order 4, else to the physical bound (2%: there is
  no first-order reference run). Not run for euler and dop853 at their settings (the rows above
  hold them to Jellett's integral).
* ``time to pass 90 deg`` (rk4): the default Leine-Glocker top (docs/physics.md §3, spin 150 rad/s,
  tilt 0.1 rad, Coulomb ``mu = 0.3``), ``t90`` (about 6.99 s) at ``h = max_stable_step`` and
  ``h/2``, linear interpolation between steps. rk4 at ``|Omega| h < 0.01`` commits a relative
  error ``(|Omega| h)^5/120 < 1e-12`` per step, ``< 1e-7`` over the ``1.1e5`` steps; the climb
  from 0.1 rad turns a tilt error ``d`` into a delay ``d/(sigma theta)`` (growth rate
  ``sigma ~ 0.5/s``): ``< 1e-5`` s (measured 2e-6 s). Tolerance ``1e-4`` s. Full runs add the
  order: ``log2((t(h) - t(h/2))/(t(h/2) - t(h/4)))``, 4 within 0.5 (measured 4.2).

Integrator settings (:data:`TIPPE_TOP_SETTINGS`) give each scheme's steps and tolerances, from
its order at its step and the worst measured over many seeds (in the comments there).

The components are floats, one state per run: on numpy arrays the tippe top's vector field pays
one numpy call per operation, which a batch repays only with more states of one parameter set
than any check here runs.

The package by concern: :mod:`.settings` (settings, random tops, measurements),
:mod:`.invariants`, :mod:`.inversion` (settling, t90, Jellett through an inversion),
:mod:`.hops` (free flight), :mod:`.checks` (every row) and :mod:`.sweep`.
"""

from __future__ import annotations

from ..settings import TIPPE_TOP_SETTINGS, TippeSetting
from .checks import progress_total, tippe_top_checks
from .hops import HOP_CASE
from .inversion import inversion_criterion, settle
from .settings import (
    RandomTop,
    ball_bound,
    oracle_jellett,
    random_tops,
    settling_friction,
)
from .sweep import (
    SWEEP_ALPHAS,
    SWEEP_OFFSETS,
    SWEEP_QUICK,
    SweepPoint,
    plot_sweep,
    print_sweep,
    sweep,
)

__all__ = [
    "TIPPE_TOP_SETTINGS",
    "TippeSetting",
    "RandomTop",
    "SweepPoint",
    "random_tops",
    "tippe_top_checks",
    "settle",
    "sweep",
    "print_sweep",
    "plot_sweep",
    "SWEEP_ALPHAS",
    "SWEEP_OFFSETS",
    "SWEEP_QUICK",
    "oracle_jellett",
    "ball_bound",
    "inversion_criterion",
    "settling_friction",
    "progress_total",
    "HOP_CASE",
]

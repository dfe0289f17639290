"""``rbenvs bench accuracy``: speed against accuracy, per system and integrator, in one run.

Cases (one panel each in the figure; ``--system`` picks them):

* ``free_body``: the default body ``I = (2, 1.5, 1)`` kg m^2, 8 states of random direction with
  ``|Omega| = 1`` rad/s (seed 0). Reference: the exact elliptic solution
  (:func:`rbenvs.oracles.exact_solution`, one evaluation at ``T`` from the start).
* ``heavy_top``: the default Lagrange top (``I = (0.45, 0.45, 0.3)`` about the pivot, 1 kg,
  0.5 m), 8 states: ``Gamma`` uniform on the sphere, ``Omega`` of random direction with
  ``|Omega| ~ U(1, 4) sqrt(M g l A)/C`` (5 to 20 rad/s; the ranges of ``rbenvs verify``).
* ``tippe_top``: the ``tippe_viscous`` scene (Leine-Glocker top, viscous friction 3 s/m,
  150 rad/s at 0.1 rad tilt; its reset states for seeds 0-3). Viscous friction because it is
  not stiff: under the default regularised Coulomb law every explicit step is pinned to the
  stability bound (``|Omega| h ~ 1e-2``), where no order can be read.
* ``tippe_frictionless``: the same states at the ``frictionless`` fidelity (energy conserved).

The references of the last three: scipy's DOP853 at ``rtol = 1e-13``, ``atol = 1e-15``
(:data:`REFERENCE`; the registry's ``dop853`` runs at ``rtol = 1e-12``), one solve from the
start to ``T``; ``ref. check`` in the output is its distance from the same solve at
``rtol = 1e-12``, which bounds what the orders are read above.

Measured per case and integrator:

* ``error``: after ``T`` (:data:`CASES`), the worst over the states and the named blocks of the
  state (``system.layout``; the tippe top's horizontal position is left out: it does not feed
  back into the motion) of ``|y_b - ref_b| / max(|ref_b|, |y0_b|)``, on a grid of steps ``h``.
* ``order``: the slope of ``log(error)`` against ``log(h)`` (least squares) over the grid points
  whose error lies in ``(FIT_FLOOR, FIT_CEILING)``: above the reference's error and in the
  asymptotic range. ``exact`` is at round-off at every ``h``: no order is fitted.
* ``cost``: seconds per step of one state on plain floats (as a single env steps it; best of
  several timings, this machine), and rhs evaluations per step from ``step_counted``
  (``dop853``: the real count of that step; ``splitting`` and ``exact`` evaluate exact flows,
  no rhs). The figure plots the error against the seconds per simulated second
  (``cost / h``).
* ``drift``: each invariant's largest change from its start over the first ``1e3`` steps and
  over a long run (``long`` steps, printed) at the case's ``drift h`` (the envs' own step), all
  states batched as arrays (the tippe top as floats, state by state: cheaper for a few states).
  Relative to: the energy ``E0`` (the heavy top: ``|kinetic| + M g l``), ``|Pi0|`` for ``|Pi|``
  and ``Pi.Gamma``, 1 for ``|Gamma|``, ``|L| (R + h)`` for Jellett's integral. A run that
  passes a drift of 1 (100%) or goes non-finite stops there: ``diverged at step k``.

MuJoCo (``--mujoco``, on when the ``mujoco`` extra is installed): the free-body case as a
free-floating body with the same principal moments and zero gravity, under MuJoCo's ``Euler``,
``RK4``, ``implicit`` and ``implicitfast`` integrators, on the same grids and states
(:func:`mujoco_free_body`; its long run is 1e5 steps, state by state).

``--quick`` runs shorter grids and long runs (CI); ``--json PATH`` writes every figure;
``--tolerance`` runs only the table of ``tolerance=`` (:mod:`rbenvs.bench.tolerance`);
``--roundoff`` only the roundoff floor near the free body's intermediate axis
(:mod:`rbenvs.bench.roundoff`); ``--floor`` only ``tolerance_check`` on that floor
(:mod:`rbenvs.bench.floor`);
``--plot PATH.png`` draws the work-precision figure (needs matplotlib, the ``plot`` extra).

Scenes (``--scenes``, on by default, off with ``--quick``): for every scene in
``configs/scenes``, each integrator the env takes (but ``dop853``, the reference) at
``substeps = 1, 2, 4, ...`` (the scene's ``dt`` kept: it is the control period, part of the
task): the env itself is stepped (``env.unwrapped.step``, past any termination) with the same
seeded random actions as an env built with the reference integrator, from the scene's reset
states (seeds 0 to 2); error = the worst over the episode and the seeds of the per-block
relative error (relative to the block's largest norm along the reference). Cost = one env
step, measured. :data:`TARGET` is the accuracy asked for; the cheapest pair meeting it is the
recommendation (a scene that already meets it changes only for a pair at most :data:`SAVING`
of its cost: smaller savings are within the timing noise). The tippe top's scenes are checked over
their first :data:`TIPPE_HORIZON` seconds (their reference is slow under Coulomb friction:
``rbenvs bench accuracy --tippe`` prints dop853's cost).

The package by concern: :mod:`.convergence` (cases, errors, orders, drift, cost),
:mod:`.mujoco`, :mod:`.scenes`, :mod:`.report` (tables and figure) and :mod:`.command`.
"""

from __future__ import annotations

from .command import main
from .convergence import (
    CASES,
    REFERENCE,
    TARGET,
    Case,
    _block_error,
    convergence,
    drift,
    fit_order,
)
from .measure import run
from .mujoco import mujoco_free_body, progress_total
from .report import cheapest, plot, print_report, print_scenes
from .scenes import run_scenes

__all__ = [
    "CASES",
    "REFERENCE",
    "TARGET",
    "Case",
    "run",
    "run_scenes",
    "fit_order",
    "convergence",
    "drift",
    "mujoco_free_body",
    "print_report",
    "print_scenes",
    "plot",
    "main",
    "cheapest",
    "_block_error",
    "progress_total",
]

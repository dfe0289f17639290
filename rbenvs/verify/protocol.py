"""The contract ``rbenvs verify`` runs its checks through (docs/verification.md, "Any
simulator"): what to simulate, a run and a simulator, and the option helpers every adapter's
``--simulator NAME:key=value,...`` parser shares. The adapters: :mod:`rbenvs.verify.simulator`
(rbenvs' own integrators, a plain Python step function) and :mod:`rbenvs.verify.mujoco_adapter`.

A :class:`Simulator` is told a :class:`Problem` (which system, its physical parameters, the
tippe top's fidelity) and a start state, and returns a :class:`Run` that advances by a step
``h`` under a control held over the step. States are tuples of floats in rbenvs' layouts
(docs/physics.md §1-§3); converting to and from an engine's own coordinates is the adapter's job:

* ``free_body``: ``y = Pi``, the body angular momentum in the principal body frame
  (``Omega = Pi / params.inertia``); ``u``: a body-frame torque [N m] or ``None``.
* ``heavy_top``: ``y = (Pi1, Pi2, Pi3, Gamma1, Gamma2, Gamma3)`` (one flat tuple, as every
  state is: :data:`rbenvs.verify.simulator.LAYOUTS`): ``Pi`` about the pivot in the principal body
  frame (``params.inertia`` are the moments about the pivot), ``Gamma = R^T e_z`` the upward
  vertical seen from the body; the centre of mass at ``params.length`` along
  ``params.com_direction``; gravity ``-params.gravity e_z``; ``u`` is ``None``.
* ``tippe_top`` (a sphere of ``params.radius`` whose centre of mass ``G`` lies ``h = offset R``
  below its centre along the body axis ``e3``; moments ``(A, A, C)`` about ``G``): fidelity
  ``gliding`` (friction ``params.friction_law``, coefficient ``params.friction``) and
  ``frictionless``: ``y = (x, y, vx, vy, qw, qx, qy, qz, W1, W2, W3)``: horizontal position and
  velocity of ``G`` on the table ``z = 0``, the attitude body -> space, the body angular
  velocity; ``rolling`` (no slip): ``y = (x, y, qw, qx, qy, qz, W1, W2, W3)``. ``u``: ``None``, or
  the moving table's ``(a_x, a_y, mu, tau1, tau2, tau3)``.

A system, fidelity or control an engine does not model is declined by raising
``NotImplementedError`` (from :meth:`Simulator.start` or :meth:`Run.step`) with the reason: its
rows read ``n/a`` with that reason, never silently dropped.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

__all__ = [
    "Problem",
    "Run",
    "Simulator",
    "ManyStepsRun",
    "BatchedSimulator",
    "batched",
    "take_option",
    "no_more_options",
]


@dataclass(frozen=True)
class Problem:
    """What to simulate: ``system`` (``"free_body"``, ``"heavy_top"`` or ``"tippe_top"``), its
    ``params`` (:class:`~rbenvs.dynamics.FreeBodyParams`, :class:`~rbenvs.dynamics.HeavyTopParams`,
    :class:`~rbenvs.dynamics.TippeTopParams`), the tippe top's ``fidelity`` (``None`` for the
    others) and ``model``: rbenvs' own system object for them (its ``layout``, read-outs and
    ``rhs``, for an adapter that wants them)."""

    system: str
    params: Any
    fidelity: str | None
    model: Any


class Run(Protocol):
    """One trajectory in an engine, from the start state it was given."""

    def step(self, u, h: float) -> tuple:
        """Advance by ``h`` [s] under the control ``u`` (``None``: none) held over the step; the
        new state in rbenvs' layout. ``NotImplementedError`` for a control not modelled."""
        ...


@runtime_checkable
class Simulator(Protocol):
    """An engine under test. ``name`` labels its rows; ``dt`` is its fixed step [s] (``None``:
    the checks choose each run's step, as for rbenvs' integrators at their verify settings);
    ``order`` is its declared order of accuracy, which scales the tolerances of the accuracy rows
    to ``dt`` (docs/verification.md). An adapter may set ``batched = True`` when it steps
    components that are arrays (many states) at once."""

    name: str
    dt: float | None
    order: int

    def start(self, problem: Problem, y0: tuple) -> Run:
        """A run from ``y0``; ``NotImplementedError`` (with the reason) for a problem not
        modelled."""
        ...


@runtime_checkable
class ManyStepsRun(Run, Protocol):
    """A run that takes ``n`` steps in one call (an engine that loops in compiled code)."""

    def advance(self, n: int, u, h: float) -> tuple:
        """The state after ``n`` steps of ``h`` under ``u``."""
        ...


@runtime_checkable
class BatchedSimulator(Simulator, Protocol):
    """A simulator that declares whether it steps components that are arrays (many states) at
    once (``batched``); one that does not declare it is stepped state by state."""

    batched: bool


def batched(sim) -> bool:
    """Whether ``sim`` steps a batch at once (:class:`BatchedSimulator` with ``batched`` true)."""
    return isinstance(sim, BatchedSimulator) and sim.batched


def take_option(options, key, kind, default):
    if key not in options:
        return default
    value = options.pop(key)
    try:
        return kind(value)
    except ValueError:
        raise ValueError(f"simulator option {key}={value!r}: not a {kind.__name__}") from None


def no_more_options(options, what):
    if options:
        raise ValueError(f"unknown {what} simulator option(s): {sorted(options)}")

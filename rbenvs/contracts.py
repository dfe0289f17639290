"""What a system, a task, an integrator and an actuator must provide: the contracts, written down.

The step core (:mod:`rbenvs.core`) runs any combination of these parts through one written-once
step, on Python floats (one env) or on arrays (a batch). Each part declares what it can do; the
core reads the declarations and probes nothing, so a missing piece is an error at construction
(:func:`require_parts`), never a silent change of behaviour.

Conventions shared by every contract:

* **Components.** A state ``y`` is a tuple of components, each a Python float (one state) or a
  float64 array of one batch shape (many states). Every function below takes and returns
  components, so the same function serves the single env, the numpy batch and, where it is
  marked :func:`rbenvs.jit.jitable`, the compiled batch.
* **Pure parts.** ``(fn, P)`` pairs: a module-level function and its parameter tuple, with
  ``fn(P, ...)`` depending on nothing else. These are what compiled code can call.
* Controls ``u`` are the system's physical inputs (torques, accelerations), ``None`` for none;
  ``u_norm`` is the normalised action on every input in ``[-1, 1]``.

This module is the bottom of the package's layers: it imports nothing from rbenvs.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple, Protocol, runtime_checkable

__all__ = [
    "PureFunction",
    "StepRegion",
    "GuardRates",
    "Steppable",
    "System",
    "HybridSystem",
    "Task",
    "Integrator",
    "Actuator",
    "StepResult",
    "CompiledBackend",
    "require_parts",
]

# A pure function and its parameters: ``fn(P, *args)``.
PureFunction = tuple[Callable[..., Any], tuple]


@dataclass(frozen=True)
class StepRegion:
    """Where an integrator's step ``h`` can be trusted, in units of a rate ``lambda`` of the
    dynamics: what the step guard reads to size the internal step
    (:mod:`rbenvs.stepsize.controller`).

    * ``rotation``: the largest ``|lambda| h`` for an oscillatory rate (eigenvalues on the
      imaginary axis: a rotation), a stability or an accuracy bound (``inf``: none);
    * ``growth``: the largest ``|lambda|^2 h dt`` per control period ``dt`` (forward Euler
      multiplies a rotation's amplitude by ``sqrt(1 + (lambda h)^2)`` a step, by at most
      ``exp(lambda^2 h dt / 2)`` a period; ``inf``: none);
    * ``dissipation``: the stability interval on the negative real axis (``|lambda| h`` for a
      decaying rate, such as regularised friction near zero slip; ``inf``: unconditionally
      stable there);
    * ``exact_subflows``: the scheme composes the system's exact sub-flows (splitting, the
      exact flow), so the rates those flows solve exactly do not count;
    * ``reason``: what the bounds are, in words (shown in refusals and docs).

    Every integrator declares one; an integrator without a region cannot be guarded, and the
    envs refuse it (rather than run it unguarded).
    """

    rotation: float = math.inf
    growth: float = math.inf
    dissipation: float = math.inf
    exact_subflows: bool = False
    reason: str = ""

    @classmethod
    def unbounded(cls, reason: str, exact_subflows: bool = False) -> StepRegion:
        """No bound: an exact flow, or a scheme that controls its own error (adaptive)."""
        return cls(exact_subflows=exact_subflows, reason=reason)

    @property
    def bounded(self) -> bool:
        return not (
            self.rotation == math.inf and self.growth == math.inf and self.dissipation == math.inf
        )


@dataclass(frozen=True)
class GuardRates:
    """The rates of a system that an internal step must resolve, for one integrator's region
    (:meth:`System.guard_rates`); the guard turns them into a step count.

    * ``rotation``: pure ``fn(P, y) -> lambda`` [1/s], the fastest oscillatory rate at ``y``;
    * ``rotation_bound``: a bound on ``lambda h`` the system itself needs whatever the scheme
      (an accuracy bound of its geometry), replacing the region's ``rotation`` and ``growth``;
      ``None``: the region's bounds apply;
    * ``dissipation``: pure ``fn(P, y, u) -> lambda_d`` [1/s], the stiffest decaying rate, or
      ``None``; resolved within ``dissipation_margin`` of the region's ``dissipation``;
    * ``ceiling``: an upper bound of ``lambda`` over every state inside the observation bounds
      (``inf``: none known; a guard whose ceiling fits in ``substeps`` never needs checking);
    * ``text``: the rule in words, with the parameters that set the rates;
    * ``accuracy``: pure ``fn(P, y) -> lambda_e`` [1/s], the rate of the error at ``y`` (a bound
      of the vector field's Jacobian and of its higher derivatives' share, or the motion's own
      frequency within it, :func:`rbenvs.stepsize.forms.motion_rates`), sharper than ``rotation``
      for the error ``tolerance=`` estimates; used only there, never
      for the stability bound; ``None``: ``rotation``'s rate;
    * ``dissipation_share``: pure ``fn((P, r), y, u, dt, p, lambda_d) -> a`` in ``[0, 1]`` (``r``:
      the scheme's ``forced_error_constant`` over its ``error_constant``, 0 where it declares
      none, put in by the guard): the share
      of ``C (lambda_d h)^p`` (``lambda_d`` the ``dissipation`` rate at ``y``, ``C`` the
      scheme's error constant) that the decaying mode's error is in a period of ``dt`` from
      ``y`` under ``u`` with a scheme of order ``p``: less where the mode is less stiff than
      ``lambda_d`` in that period (a saturated friction), near its slow manifold (only its
      distance from it errs), or driven slower than it relaxes; used only by ``tolerance=``
      (:func:`rbenvs.stepsize.forms.relaxation_steps`); ``None``: 1.
    * ``error_blocks``: the names of the state's blocks (``layout``) whose relative speed counts
      in the state's own rate ``mu`` of ``tolerance=`` (:func:`rbenvs.stepsize.forms.motion_rates`):
      those the error is measured on. ``None``: every block, and a hybrid system then keeps the
      rate alone; a hybrid system that names them takes ``mu`` too (the tippe top: its velocity
      and angular velocity; the horizontal position drifts, the contact flags are not measured);
    * ``rotating_blocks``: pairs ``(block, driver)`` of names: a block that turns as a rotation of
      itself at its own speed, ``dy_b/dt = A(y_d) y_b`` with ``A`` skew and ``|A| = |dy_b/dt| /
      |y_b|`` (a unit quaternion, at half the angular speed, driven by the angular velocity): its
      own local error is ``C (mu_b h)^(p+1)``, and it carries the driver's error to the end of the
      horizon (:func:`rbenvs.stepsize.forms.motion_rates`);
    * ``speed``: pure ``fn(P, y, u, dt) -> m`` [1/s], an upper bound of the relative speed
      ``|dy_b/dt| / |y_b|`` of the state's blocks (the rotating ones aside) over a control period
      of ``dt`` from ``y`` under ``u``, where the system knows its motion (the free body's orbit);
      used only by ``tolerance=`` (:func:`rbenvs.stepsize.forms.motion_rates`); ``None``: the speed
      at the period's start.
    * ``accuracy_bound``: pure ``fn(P, y) -> Lambda`` [1/s], a cheap upper bound of ``accuracy``'s
      rate at every ``y`` (the free body's Jacobian bound ``s |Pi|``): the default accuracy tests
      it first and reads the sharp rates only where it does not hold the period within its budget
      (:func:`rbenvs.stepsize.forms.motion_rates`' gate); ``None``: no gate where ``accuracy`` is
      declared (without ``accuracy`` the gate takes ``rotation``'s rate).
    """

    rotation: PureFunction
    text: str
    rotation_bound: float | None = None
    dissipation: PureFunction | None = None
    dissipation_margin: float = 1.0
    ceiling: float = math.inf
    accuracy: PureFunction | None = None
    dissipation_share: PureFunction | None = None
    error_blocks: tuple | None = None
    rotating_blocks: tuple = ()
    speed: PureFunction | None = None
    accuracy_bound: PureFunction | None = None


@runtime_checkable
class Steppable(Protocol):
    """What an integrator steps: a vector field on ``dim`` components and its projection.

    ``needs_projection``: whether :meth:`normalize` does anything (false: it is the identity
    and a step may skip it); ``kernel_rhs`` and ``kernel_normalize``: their pure forms, or
    ``None`` (see :class:`System`). A test problem (:class:`rbenvs.integrators.error.Rotation`)
    declares these alone."""

    dim: int
    needs_projection: bool
    kernel_rhs: Any
    kernel_normalize: Any

    def rhs(self, y, u):
        """``dy/dt`` at ``y`` under ``u`` (components)."""

    def normalize(self, y):
        """``y`` projected back onto the state manifold (unit quaternions, unit vectors)."""


@runtime_checkable
class System(Steppable, Protocol):
    """The physics of one rigid-body system: a vector field, its exact pieces, read-outs.

    Attributes: ``dim`` (number of state components), ``layout`` (name -> ``(start, stop)``
    slices of the components, the names of ``get_state``), ``readout_names`` (the ``info`` keys
    of :meth:`readouts`), ``params`` (a frozen parameter object), ``hybrid`` (whether its
    contact can switch: then it is a :class:`HybridSystem`). ``provides``: the optional
    capabilities it has, by name, which an integrator's ``requires`` names (a class attribute:
    an env's choice of integrators reads it before any system exists): ``"split_flows"``
    (exact sub-flows, for the splitting), ``"free_flow"`` and ``"kick"`` (the exact flow),
    ``"implicit"`` (the Rosenbrock schemes' linear solve, :attr:`kernel_implicit`).

    **Pure forms** (``(fn, P)`` pairs, or ``None`` where the system has none; what generated
    steps and compiled kernels call, and what the methods call too, so there is one
    implementation):

    * ``kernel_rhs``: ``fn(P, y, u) -> dy``, equal to :meth:`rhs` (``u`` a tuple of controls);
    * ``kernel_normalize``: ``fn(P, y) -> y``, equal to :meth:`normalize`; ``None`` where there is
      nothing to project (the identity may be skipped);
    * ``kernel_readouts``: ``fn(P, y, u, fired) -> (r_1, ...)`` in ``readout_names`` order, equal
      to :meth:`readouts` (``u`` the control that acted, ``fired`` the period's terminal event);
    * ``kernel_split_flows`` (with ``split_flows``): the exact sub-flows as ``((fn, P), ...)``,
      ``fn(P, y, u, h) -> y``, in :meth:`split_flows` order;
    * ``kernel_implicit`` (with ``implicit``): ``(factor, solve, P)``, the linear solve of a
      Rosenbrock-W stage (:mod:`rbenvs.integrators.rosenbrock`).

    Every pure function is marked :func:`rbenvs.jit.jitable`: arithmetic on floats and tuples
    of floats that also runs on numpy arrays (``isinstance(x, float)`` and ``x is None``
    branches are resolved when compiled).
    """

    layout: dict
    readout_names: tuple
    hybrid: bool
    provides: frozenset
    kernel_readouts: Any
    kernel_split_flows: Any
    kernel_implicit: Any

    def readouts(self, y, u, fired):
        """The physical read-outs in ``readout_names`` order at ``y`` after a period under
        ``u`` (``None`` after a reset); ``fired``: whether the period ended at the terminal
        event. Floats or arrays."""

    def angular_velocity(self, y):
        """Body angular velocity ``Omega`` [rad/s] (components)."""

    def guard_rates(self, region: StepRegion, speed_ceiling: float, dt: float) -> GuardRates:
        """The rates the internal step must resolve with an integrator of ``region``;
        ``speed_ceiling`` bounds ``|Omega|`` inside the observation bounds, ``dt`` is the control
        period (a rate may hold over the whole period from its start)."""

    start_draw_kinds: str  # the kinds of the numbers the system adds to a start (rbenvs.draws)

    def start_draws(self, rng):
        """The generator's numbers the system adds to a start (an array, maybe empty), in the
        order of :attr:`start_draw_kinds`."""

    def complete_initial_state(self, y, d):
        """A task's start ``y`` completed from the system's draws ``d`` (or ``y``); floats or
        rows of a batch."""

    kernel_complete: Any  # (fn, P): fn(P, y, d) -> y, the pure form of complete_initial_state

    def export_state(self, y) -> dict:
        """The named state (float64 copies)."""

    def import_state(self, state: dict) -> tuple:
        """Components from a named state, checked (shapes, finiteness, physical constraints)."""


@runtime_checkable
class HybridSystem(System, Protocol):
    """A system whose contact can open (the tippe top): ``hybrid`` is true.

    ``switches``: whether the contact switches (free flight: lift-off and touchdown, located
    inside the internal step by :mod:`rbenvs.core.hybrid` from :meth:`events`) rather than a
    lift-off ending the episode (:meth:`terminal_event`). The system never calls an
    integrator: locating an event is the hybrid layer's job.

    Pure forms of the terminal event, for compiled kernels (``None`` where there is none):
    ``kernel_event = (fn, P)``, ``fn(P, y, u) -> g``, the event's value (it fires where
    ``g < 0``: the tippe top's normal force); ``kernel_rhs_event = (fn, P)``, ``fn(P, y, u) ->
    (dy, g)``, the vector field and that value from one evaluation (one contact solve), so that
    the check at a new state serves as the next step's first stage; ``kernel_switches``: the
    switches of :meth:`events` as ``((applies, P), (function, P), tolerance, (switch, P))`` with
    ``applies(P, y) -> bool``, ``function(P, y, u) -> g`` and ``switch(P, y) -> y`` pure (or
    ``None``: switching then runs on numpy).
    """

    switches: bool
    kernel_event: Any
    kernel_rhs_event: Any
    kernel_switches: Any

    def terminal_event(self):
        """``(name, fn)`` with ``fn(y, u)`` true where the episode ends, or ``None``."""

    def events(self, u) -> tuple:
        """The switches under control ``u``: ``Event(name, applies, function, tolerance,
        switch)`` each (:class:`rbenvs.dynamics.tippe_top.Event`)."""


@runtime_checkable
class Task(Protocol):
    """What an agent is asked to do with a system: start, observation, reward, end.

    Attributes: ``name``; ``observation_names`` and ``observation_units`` (one per observation
    component: the env maps a unit to its bound); ``metric_names`` (the ``info`` keys of the
    metrics, ``is_success`` last); ``final_measure`` (the metric or read-out that summarises an
    episode's end, for ``rbenvs run``); ``controller`` (the class name of the reference
    controller in :mod:`rbenvs.controllers`); ``kernels`` (pure forms of ``observe`` and
    ``evaluate`` for generated and compiled steps, or ``None``). Starts come in two stages
    (:class:`rbenvs.tasks.common.TwoStageStart`): the generator's draws per sub-env, then one
    conversion for the whole batch.
    """

    name: str
    observation_names: tuple
    observation_units: tuple
    metric_names: tuple
    final_measure: str
    controller: str
    kernels: Any

    draw_kinds: str  # the kinds of one start's raw numbers, in order (rbenvs.draws)

    def initial_draws(self, rng):
        """The generator's raw numbers for one start (an array), in the order of
        :attr:`draw_kinds`."""

    def initial_from_draws(self, system, d):
        """A start's components from its draws (floats, or rows of a batch)."""

    def kernel_start(self, system):
        """``(fn, P)`` with ``fn(P, d) -> y``: the pure form of :meth:`initial_from_draws` (the
        arithmetic of compiled restarts), or ``None``."""

    def observe(self, system, y) -> tuple:
        """The observation components at ``y``."""

    def evaluate(self, system, y, u_norm):
        """``(reward, terminated, metrics)``: metrics a dict in ``metric_names`` order."""

    def reward_floor(self, system, observation_high) -> float:
        """The least reward one step can have while the state is inside the observation bounds
        ``observation_high`` (at full effort): what an episode that ends without success is
        charged per step it skipped (:attr:`rbenvs.core.model.Model.failure_charge`)."""


@runtime_checkable
class Integrator(Protocol):
    """How to advance a state by ``h`` (stateless, immutable).

    Attributes: ``name``; ``order`` (global order for smooth problems); ``evaluations`` (rhs
    calls per step, ``None`` if not rhs-based: the cost); ``conserves`` (invariants kept to
    round-off); ``requires`` (system capabilities it needs, of the system's ``provides``);
    ``region`` (:class:`StepRegion`); ``uniform_step_only`` (one scalar step for a whole batch:
    adaptive schemes); ``error_constant``, ``error_in_phase`` and ``forced_error_constant``
    (what ``tolerance=`` reads, ``None``/false where the scheme has none:
    :class:`rbenvs.integrators.base.Integrator`).
    """

    name: str
    order: int
    evaluations: Any
    conserves: tuple
    requires: tuple
    region: StepRegion
    uniform_step_only: bool
    error_constant: Any
    error_in_phase: bool
    forced_error_constant: Any

    def supports(self, system) -> bool:
        """Whether ``system`` offers everything this scheme needs."""

    def step(self, system, y, u, h):
        """``y`` advanced by ``h`` under ``u``."""

    def bind(self, system, dim: int, compensated: bool = False):
        """``step(y, u, h)`` with ``system`` bound once (the hot path; the same bits); with
        ``compensated``, ``step(y, c, u, h) -> (y, c)`` summing with compensation, or ``None``."""

    def kernel_step(self, system, compensated: bool = False):
        """``(step, P)``, a pure form of :meth:`bind`'s step for compiled code, or ``None``."""

    def kernel_step_first_stage(self, system, compensated: bool = False):
        """``(step, P)`` with ``step(P, y, k0, u, h)``: the step given its first stage (a
        hybrid system's event shares it), or ``None``."""


@runtime_checkable
class Actuator(Protocol):
    """Maps a normalised action (components in ``[-1, 1]``) to the system's controls.

    ``size``: the action size. ``control(a) -> (u_norm, u)``: the normalised action on every
    input (0 where none acts; for the reward's effort term) and the physical control, on
    floats or arrays alike; ``kernel_control``: its pure form (what ``control`` runs, and what
    the compiled vector step calls).
    """

    size: int
    kernel_control: Any  # (fn, P): fn(P, a) -> (u_norm, u), the pure form of control

    def control(self, a) -> tuple:
        """``(u_norm, u)`` for the action components ``a``."""


class CompiledBackend(Protocol):
    """The compiled forms of one state's step the step core builds from a model's pure parts
    (:class:`rbenvs.compiled.Backend`; the core is given a loader of it and imports no compiled
    code): ``StateStep`` (the period and finish), ``CheckedRuns`` (``tolerance_check``'s runs),
    ``PeriodPlan`` (a tolerance's count and rates), ``available()`` (numba installed and not
    disabled by the environment variable ``DISABLE_VARIABLE``)."""

    StateStep: Any
    CheckedRuns: Any
    PeriodPlan: Any
    DISABLE_VARIABLE: str

    def available(self) -> bool:
        """Whether compiled code can run in this process."""


class StepResult(NamedTuple):
    """Everything one control period of one env produces (:meth:`rbenvs.core.step.Engine.step_one`
    returns a plain tuple in these fields; ``StepResult._make`` names it where speed does not
    matter).

    ``y``: the new state (the last finite one where the period failed); ``obs``: observation
    (float32, clipped to the bounds); ``reward``; ``terminated``; ``info``: read-outs, metrics,
    ``internal_step``, ``numerical_failure`` (and ``terminal_reason`` where the episode ended);
    ``u``: the control that acted (an input of the next read-outs: the tippe top's normal force
    depends on it); ``plain``: whether the next period may take the unchecked loop (false once
    the state left the observation bounds).
    """

    y: Any
    obs: Any
    reward: Any
    terminated: Any
    info: dict
    u: Any
    plain: bool


def require_parts(obj, protocol, role: str) -> None:
    """``TypeError`` naming ``role`` and the missing members unless ``obj`` provides every
    member of ``protocol`` (checked once, at construction)."""
    missing = [name for name in _members(protocol) if not hasattr(obj, name)]
    if missing:
        raise TypeError(
            f"{role} {type(obj).__name__} does not provide {missing} "
            f"({protocol.__name__} contract, rbenvs.contracts)"
        )


def _members(protocol) -> list[str]:
    names = []
    for klass in reversed(protocol.__mro__):
        if klass in (object, Protocol) or not getattr(klass, "_is_protocol", False):
            continue
        names += [n for n in getattr(klass, "__annotations__", {})]
        names += [n for n, v in vars(klass).items() if callable(v) and not n.startswith("_")]
    return sorted(set(names))

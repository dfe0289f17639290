"""A model: everything one env configuration steps with, frozen, shared by every front end.

An env's constructor validates its keyword arguments and builds one :class:`Model` (system,
task, integrator, actuator, control period, guard, observation bounds); the single env and the
vector env then run the same :class:`~rbenvs.core.step.Engine` of that model. Nothing else is
needed to step, reset or read the state: the vector env reads no attribute of a single env
but its public ``model`` and spaces.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cache

from ..codegen import generate
from ..contracts import Actuator, HybridSystem, Integrator, StepRegion, System, Task, require_parts
from ..draws import batch_draws
from ..jit import jitable
from ..stepsize.controller import StepRule

__all__ = ["Model", "observation_bounds"]


@dataclass(frozen=True, eq=False)
class Model:
    """One env configuration (see the contracts in :mod:`rbenvs.contracts`).

    * ``system``, ``task``, ``integrator``, ``actuator``: the parts;
    * ``dt`` [s] and ``substeps``: the control period and its minimum number of internal steps;
    * ``guard``: ``"subdivide"``, ``"refuse"`` or ``"off"`` (:mod:`rbenvs.stepsize.controller`);
    * ``observation_high``: the bound of each observation component (the box ``[-high, high]``);
    * ``speed_ceiling``: an upper bound of ``|Omega|`` inside those bounds (``inf``: unknown),
      which lets a guard prove it never needs more than ``substeps`` steps;
    * ``tolerance``: the relative error allowed over ``horizon`` control periods (``None``: no
      accuracy bound; :mod:`rbenvs.stepsize.controller`);
    * ``accuracy``: where ``tolerance`` came from: ``"explicit"`` (the user's: its steps sum
      with compensation) or ``"default"`` (the env's default accuracy: the steps sum plainly, so
      that a default scene's trajectory is the one it had without);
    * ``check``: with a tolerance, whether a companion run estimates the episode's global error
      (``tolerance_check``; :mod:`rbenvs.stepsize.controller`) and ends it where it passes the
      tolerance;
    * ``episode_steps``: the episode's length in control periods (the registered
      ``max_episode_steps``; ``None``: none);
    * ``failure_charge`` (derived): what the last reward of an episode that ends without success
      carries on top of its own (the task's failure, the system's event such as the tippe top's
      lift-off, the observation limit, a numerical failure): ``episode_steps`` times the task's
      least reward (:meth:`~rbenvs.contracts.Task.reward_floor`) where that is negative, else 0.
      Ending early then never pays: a failed episode's return is at most the worst return a
      whole episode can have, whatever steps it skipped (without it an agent on a task whose
      rewards are negative learns to end its episode, e.g. to lift the tippe top off);
    * ``step_rule`` (derived): the guard's rule from the system's rates and the integrator's
      region; ``draw_kinds`` (derived): the kinds of a start's numbers, the task's then the
      system's (:mod:`rbenvs.draws`); ``system_draws``: how many of them the system adds.
    """

    system: object
    task: object
    integrator: object
    actuator: object
    dt: float
    substeps: int
    guard: str
    observation_high: tuple
    speed_ceiling: float = math.inf
    tolerance: float | None = None
    horizon: int | None = None
    episode_steps: int | None = None
    check: bool = False
    accuracy: str = "explicit"
    failure_charge: float = field(init=False)
    step_rule: StepRule = field(init=False)
    draw_kinds: str = field(init=False)
    system_draws: int = field(init=False)

    def __post_init__(self):
        # the contracts, checked once: a missing piece is an error here, not a silent change
        require_parts(self.system, HybridSystem if self.system.hybrid else System, "system")
        require_parts(self.task, Task, "task")
        require_parts(self.integrator, Integrator, "integrator")
        require_parts(self.actuator, Actuator, "actuator")
        region: StepRegion = self.integrator.region
        rates = self.system.guard_rates(region, self.speed_ceiling, self.dt)
        zero = (
            self.actuator.control((0.0,) * self.actuator.size)[1]
            if self.tolerance is not None
            else ()
        )
        object.__setattr__(
            self,
            "step_rule",
            StepRule.build(
                rates,
                region,
                self.dt,
                self.guard,
                self.integrator,
                self.tolerance,
                self.horizon,
                self.system,
                zero,
                gate_steps=self.substeps if self.accuracy == "default" else None,
            ),
        )
        floor = float(self.task.reward_floor(self.system, self.observation_high))
        if not math.isfinite(floor):
            raise ValueError(
                f"the task's reward floor must be finite, got {floor} (task "
                f"{type(self.task).__name__})"
            )
        object.__setattr__(
            self,
            "failure_charge",
            min(floor, 0.0) * self.episode_steps if self.episode_steps else 0.0,
        )
        object.__setattr__(self, "draw_kinds", self.task.draw_kinds + self.system.start_draw_kinds)
        object.__setattr__(self, "system_draws", len(self.system.start_draw_kinds))

    def __reduce__(self):
        """Pickled as its parts and settings; the derived rule is made again on loading (it holds
        the system's pure forms, which may be functions made at run time)."""
        return (
            Model,
            (
                self.system,
                self.task,
                self.integrator,
                self.actuator,
                self.dt,
                self.substeps,
                self.guard,
                self.observation_high,
                self.speed_ceiling,
                self.tolerance,
                self.horizon,
                self.episode_steps,
                self.check,
                self.accuracy,
            ),
        )

    @property
    def h(self) -> float:
        """The internal step of a period of ``substeps`` steps [s]."""
        return self.dt / self.substeps

    def initial_draws(self, rng) -> tuple:
        """The generator's numbers for one start: ``(the task's, the system's)`` (the heavy top
        adds a heading where it carries the attitude). Only these run per sub-env of a batch."""
        return self.task.initial_draws(rng), self.system.start_draws(rng)

    def batch_draws(self, rngs) -> tuple:
        """The draws of many starts, one generator each (:attr:`draw_kinds` per generator, in its
        order), stacked along axis 1: ``(the task's, the system's)`` (:meth:`split_draws`)."""
        return self.split_draws(batch_draws(rngs, self.draw_kinds))

    def split_draws(self, d) -> tuple:
        """``(the task's, the system's)`` rows of draws ``d`` made in :attr:`draw_kinds` order
        (one start's array, or a batch's ``(len(draw_kinds), n)`` rows)."""
        k = len(self.draw_kinds) - self.system_draws
        return d[:k], d[k:]

    def initial_from_draws(self, task_draws, system_draws) -> tuple:
        """A start's components from its draws (floats, or rows of a batch: the draws of many
        sub-envs stacked, converted at once)."""
        y = self.task.initial_from_draws(self.system, task_draws)
        return self.system.complete_initial_state(y, system_draws)

    def initial_state(self, rng) -> tuple:
        """A random start from ``rng``: the task's distribution, completed by the system."""
        return self.initial_from_draws(*self.initial_draws(rng))

    def kernel_start(self):
        """``(start, P)``: :meth:`initial_from_draws` as one pure function of a start's draws in
        :attr:`draw_kinds` order, ``start(P, d) -> y`` (the task's pure start, completed by the
        system's), for compiled restarts; ``None`` where the task has no pure start."""
        task = self.task.kernel_start(self.system)
        if task is None:
            return None
        complete = self.system.kernel_complete
        k = len(self.draw_kinds) - self.system_draws
        return _start_form(task[0], complete[0], k, self.system_draws), (task[1], complete[1])

    @property
    def kernel_control(self):
        """The actuator's pure ``(control, P)``: ``control(P, a) -> (u_norm, u)``."""
        return self.actuator.kernel_control


@cache
def _start_form(task_start, complete, k: int, m: int):
    """``start((PT, PC), d) = complete(PC, task_start(PT, d[:k]), d[k:k + m])`` (generated: the
    draws as tuples of floats in compiled code, rows of a batch on numpy)."""

    def items(a, b):
        return "(" + "".join(f"d[{j}], " for j in range(a, b)) + ")"

    src = (
        "def start(P, d):\n"
        f"    return complete(P[1], task_start(P[0], {items(0, k)}), {items(k, k + m)})\n"
    )
    namespace = generate(
        src, f"start k={k} m={m}", {"task_start": task_start, "complete": complete}
    )
    return jitable(namespace["start"])


def observation_bounds(task, limits: dict) -> tuple:
    """The bound of each of ``task``'s observation components from its declared units:
    ``limits`` maps a unit (``"rad/s"``, ``"m/s"``) to the env's limit; unit ``"1"`` is bound
    by 1 (unit vectors, quaternions)."""
    bounds = dict(limits, **{"1": 1.0})
    return tuple(float(bounds[unit]) for unit in task.observation_units)

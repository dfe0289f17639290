"""``rbenvs/FreeRigidBody-v0``: a torque-controlled free rigid body."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import numpy as np

from ..codegen import generate
from ..core.model import observation_bounds
from ..dynamics import FreeBody, FreeBodyParams
from ..dynamics.validation import (
    ParameterTypeError,
    require_bool_mask,
    require_choice,
    require_finite_nonnegative,
    require_finite_positive,
    require_real_vector,
)
from ..jit import jitable
from ..tasks import AXIS_NAMES, DetumbleTask, ReorientTask, SpinTask
from .base import RigidBodyEnv, require_authority, require_float32_bound

__all__ = ["FreeRigidBodyEnv", "BodyTorque"]


def _task(task, axis, spin_rate, perturbation, control_cost, target, params):
    """``(task, start_speed, source)``: the task object, an upper bound of ``|Omega|`` over its
    starts [rad/s] and the keywords that set it (for the message that compares it with
    ``max_angular_velocity``)."""
    if task == "spin":
        spin = SpinTask(
            axis=axis, spin_rate=spin_rate, perturbation=perturbation, control_cost=control_cost
        )
        # |Omega| <= |Pi| / I_min, |Pi| = I_axis spin_rate
        speed = params.inertia[axis] * spin_rate / min(params.inertia)
        return spin, speed, "spin_rate * I_axis / I_min"
    if task == "detumble":
        return DetumbleTask(spin_rate=spin_rate, control_cost=control_cost), spin_rate, "spin_rate"
    reorient = ReorientTask(target=target, spin_rate=spin_rate, control_cost=control_cost)
    return reorient, 0.1 * spin_rate, "0.1 spin_rate"


class FreeRigidBodyEnv(RigidBodyEnv):
    """A rigid body turning freely about its centre of mass, driven by bounded body torques.

    ## Description
    Euler's equations ``dPi/dt = Pi x Omega + tau`` in the principal body frame (docs/physics.md §1,
    [MR 15.3]). Without torque, spins about the major and minor axes are stable and the
    intermediate-axis spin is unstable (the rigid body stability theorem, [MR 15.9.1]): a small
    perturbation grows like ``exp(lambda t)``, ``lambda = |Omega2| sqrt((I1-I2)(I2-I3)/(I1 I3))``,
    and the body flips. The attitude quaternion is integrated only for the ``reorient`` task.

    ## Action space
    ``Box(-1, 1, (k,), float32)``, ``k`` = number of actuated axes (``actuated`` mask, in axis
    order). Action ``a`` gives the body torque ``tau_i = max_torque * a_j`` [N m] on the
    ``j``-th actuated axis ``i``, held constant over the control period; unactuated axes get
    none. Out-of-range actions are clipped to [-1, 1]; non-finite actions raise ``ValueError``.

    ## Observation space (float32)
    | task | components | unit | bounds |
    |---|---|---|---|
    | spin, detumble | ``Omega1, Omega2, Omega3`` (body angular velocity) | rad/s |
    ``+-max_angular_velocity`` | | reorient | ``Omega1..3``, then error quaternion ``conj(target) *
    q`` (``w >= 0``) | rad/s, 1 | ``+-max_angular_velocity``, ``+-1`` |

    ## Rewards (per step; ``u`` = clipped action on all three axes, 0 if unactuated)
    * ``spin``: ``Pi_axis / |Pi| - control_cost * mean(u^2)``: alignment of the angular
      momentum with the chosen principal axis, in [-1, 1].
    * ``detumble``: ``-|Omega| / spin_rate - control_cost * mean(u^2)``.
    * ``reorient``: ``-angle/pi - 0.1 |Omega| / spin_rate - control_cost * mean(u^2)``, ``angle``
      the rotation angle between attitude and target.

    ## Starting state (drawn from the env's seeded generator)
    * ``spin``: ``Pi = I_axis spin_rate n``, ``n`` tilted from ``+e_axis`` by an angle uniform in
      ``[0, perturbation]`` rad.
    * ``detumble``: ``Omega`` of magnitude ``spin_rate * U(0.5, 1)`` in a uniform direction.
    * ``reorient``: uniform random attitude, ``|Omega| = spin_rate * U(0, 0.1)``.

    ## Episode end
    * Terminated: ``detumble`` when ``|Omega| < 0.01 spin_rate`` (success); any task when an
      observation component leaves its bounds (the last observation is clipped to them,
      ``info["terminal_reason"] = "observation_limit"``) or when the state goes non-finite
      (a ``NumericalFailureWarning``, ``info["numerical_failure"] = True``, the last finite
      state and observation are kept, reward 0).
    * Truncated: after ``max_episode_steps`` (400 steps = 20 s at the default ``dt``) by the
      registration's ``TimeLimit``.

    ## Info (after every reset and step)
    ``energy`` [J], ``momentum_norm`` ``|Pi|`` [kg m^2/s], ``internal_step`` [s] (the
    integrator step of the last control period), ``numerical_failure``, ``is_success``, and per
    task ``alignment`` / ``angular_speed`` / ``attitude_error`` [rad].

    ## Guarded stepping (``guard``)
    In the body frame ``Pi`` turns about ``Omega`` at the rate ``|Omega|`` (``dPi/dt = -Omega x
    Pi``; at a steady spin the linearisation's eigenvalues have modulus ``<= |Omega|``, [MR 15.9.1]
    with the triangle inequality; the quaternion turns at ``|Omega|/2``): the fastest rate of
    the dynamics is ``|Omega|``, a rotation with eigenvalues ``+-i|Omega|``. Bounds on
    ``|Omega| h`` (``h`` the internal step), from the state at the start of each period:

    * ``rk4``: ``|Omega| h <= 1.0``. Its stability interval on the imaginary axis is
      ``|h lambda| <= 2 sqrt(2) = 2.83`` (beyond it every step amplifies the rotation); at 1.0
      the per-step amplitude error is 0.61 % and the phase error 0.56 %.
    * ``euler``: ``|Omega| h <= 0.1`` and ``|Omega|^2 h dt <= 0.02``. Forward Euler has no
      stability interval on the imaginary axis: each torque-free step adds to ``Pi`` a vector
      normal to it, ``|Pi|`` grows by the factor ``sqrt(1 + (|Omega| h)^2) > 1`` (0.5 % at
      0.1), so ``n`` steps grow it by up to ``exp(|Omega|^2 h dt / 2)``: at most 1 % per
      control period (and ``|Omega|`` grows with ``|Pi|``: without the second bound the growth
      runs away within a period at ``|Omega| dt >> 1``). The steps needed grow like
      ``(dt |Omega|)^2 / 0.02``; past ``MAX_INTERNAL_STEPS`` euler cannot follow the spin.
    * ``splitting``: ``|Omega| h <= 1.0``, an accuracy bound only: every piece is an exact
      rotation, so ``|Pi|`` is kept to round-off at any ``h`` and nothing can blow up (the
      energy stays within ``[|Pi|^2 / (2 I_max), |Pi|^2 / (2 I_min)]``), but past about a radian
      per step the composed axis rotations no longer follow the motion (second order in
      ``|Omega| h``: at ``|Omega| h = 500`` the energy is off by tens of percent).
    * ``exact``: none (the exact flow; torque enters as exact kicks). ``dop853``: none (adaptive
      error control picks its own steps).

    ``guard="subdivide"`` (default) takes the fewest equal steps ``n >= substeps`` that meet the
    bounds (``n = max(substeps, ceil(dt |Omega| / bound), ceil((dt |Omega|)^2 / 0.02))``);
    ``"refuse"`` raises ``ValueError`` from ``step`` (naming ``substeps`` and the ``n`` needed)
    instead, leaving the state unchanged; ``"off"`` always takes ``substeps`` (euler then grows
    without bound at large ``|Omega| dt``: a non-finite state ends the episode as a numerical
    failure). More than ``MAX_INTERNAL_STEPS`` (1e6) steps in a period is a numerical failure. When
    no state inside the observation bounds (``|Omega| <= sqrt(3) max_angular_velocity``) can exceed
    the bound, no check runs: at the defaults ``rk4`` and
    ``splitting`` cost nothing extra (``0.05 * sqrt(3) * 10 = 0.87 <= 1``). The guard keeps every
    step stable; it does not make a low-order scheme accurate at fast spin: rk4 inside its
    interval damps a rotation slightly (``|R(i x)| <= 1``); use ``exact`` (or ``splitting``
    with small steps) where accuracy at ``|Omega| dt >> 1`` matters.

    ## State access
    ``get_state()`` returns ``{"angular_momentum": Pi (3,), "attitude": q (4,) (w, x, y, z),
    body to space; reorient only}`` as float64 copies; ``reset(options={"state": d})`` starts
    exactly there (a round trip reproduces the trajectory bit for bit). Unknown or missing
    names, wrong shapes, non-finite values or a non-unit quaternion raise ``ValueError``.

    ## Arguments
    * ``inertia=(2.0, 1.5, 1.0)``: principal moments [kg m^2]; positive, ``Ii + Ij >= Ik``.
    * ``task="spin"``: ``"spin"``, ``"detumble"`` or ``"reorient"``.
    * ``axis="intermediate"``: spin task's axis, ``"major"``, ``"intermediate"``, ``"minor"`` or an
      index 0-2 (a name must be unambiguous: no tie in the moments).
    * ``spin_rate=1.0``: rad/s, the initial spin (spin) or angular-speed scale (detumble, reorient).
    * ``perturbation=0.05``: rad, largest initial tilt of the spin from its axis, in [0, pi).
    * ``max_torque=0.2``: N m per actuated axis (``>= 0``).
    * ``actuated=(True, True, True)``: which body axes take torque (at least one).
    * ``control_cost=0.01``: weight of ``mean(u^2)`` in the reward (``>= 0``; the rewards and
      the failure charge it makes must fit float32, in which RL libraries store rewards).
    * ``max_angular_velocity=10.0``: rad/s, observation bound.
    * ``target_attitude=(1, 0, 0, 0)``: reorient target, unit quaternion (w, x, y, z).

    Every keyword is checked at construction, whatever the task (one the task ignores, such as
    ``target_attitude`` for ``spin`` must still be a valid value): a wrong type raises
    ``TypeError`` (a ``ParameterTypeError``, also a ``ValueError``), a bad value ``ValueError``,
    each naming the keyword and the rule. Flags and ``actuated`` (three bools) take ``bool``
    only (``"False"`` is refused, not read as true). Beyond the ranges above: ``substeps <=
    1e6`` (``MAX_INTERNAL_STEPS``: more in a period is a numerical failure); ``dt`` must be
    resolvable at the start (the guard's step count at the fastest initial state at most 1e6;
    not checked with ``guard="off"``); the full torque may change ``Omega`` by at most the
    observation box's width per period (``max_torque sqrt(k) dt / I_min <= 2
    max_angular_velocity``, ``k`` actuated axes: the guard sizes the step from the period's
    start); the initial state must lie inside the observation bounds. ``axis`` is resolved (by
    name, against the moments) for the spin task only, so a sphere detumbles.

    ## Rendering
    ``render_mode="rgb_array"``: ``render()`` returns a 480x480x3 uint8 frame of the box with
    the body's moments, its principal axes, ``Pi`` (red) and ``Omega`` (blue); in the body frame
    with the orbit of ``Pi`` dotted, or in space for ``reorient``. ``"human"``: the same in a
    matplotlib window after every step (when a display exists). Needs the ``plot`` extra.

    ## Version history
    * v0: initial release.
    """

    tasks = ("spin", "detumble", "reorient")
    # info keys of the quantities the uncontrolled motion conserves (summaries, checks)
    invariants = ("energy", "momentum_norm")
    system_class = FreeBody
    randomizable = ("inertia", "max_torque")  # param_ranges keywords

    def __init__(
        self,
        inertia=(2.0, 1.5, 1.0),
        task: str = "spin",
        axis="intermediate",
        spin_rate: float = 1.0,
        perturbation: float = 0.05,
        max_torque: float = 0.2,
        actuated=(True, True, True),
        control_cost: float = 0.01,
        max_angular_velocity: float = 10.0,
        target_attitude=(1.0, 0.0, 0.0, 0.0),
        **options,
    ):
        # every keyword is checked, whatever the task (a keyword the task ignores must still be
        # a valid value: a typo is reported, not silently kept)
        task = require_choice("task", task, self.tasks)
        params = FreeBodyParams(inertia)
        require_finite_nonnegative("max_torque", max_torque)
        spin_rate = require_finite_positive("spin_rate", spin_rate)
        control_cost = require_finite_nonnegative("control_cost", control_cost)
        perturbation = require_finite_nonnegative("perturbation", perturbation)
        if perturbation >= math.pi:
            raise ValueError(f"perturbation must be in [0, pi) rad, got {perturbation!r}")
        max_w = require_float32_bound("max_angular_velocity", max_angular_velocity)
        self.actuated = require_bool_mask(
            "actuated", actuated, 3, " (one per body axis: which take torque)"
        )
        if not any(self.actuated):
            raise ValueError("actuated must enable at least one axis")
        target = _unit_quaternion("target_attitude", target_attitude)
        _check_axis(axis)
        # the axis is resolved only where it is used: a name is ambiguous with equal moments,
        # which a detumble or reorient scene may well have
        self.axis = _axis_index(axis, params) if task == "spin" else None
        task_obj, start_speed, source = _task(
            task, self.axis, spin_rate, perturbation, control_cost, target, params
        )
        if not start_speed < max_w:
            raise ValueError(
                f"max_angular_velocity ({max_w!r} rad/s) must exceed the initial angular speed "
                f"({source} = {start_speed:.6g} rad/s): lower spin_rate or raise "
                "max_angular_velocity"
            )
        system = FreeBody(params, attitude=task_obj.needs_attitude)
        self.max_torque = max_torque = require_finite_nonnegative("max_torque", max_torque)
        actuator = BodyTorque(max_torque, tuple(i for i in range(3) if self.actuated[i]))
        self._max_w = max_w
        self._start_speed = start_speed
        high = observation_bounds(task_obj, {"rad/s": max_w})
        self._setup(system, task_obj, actuator, high, options)
        self.action_size = actuator.size
        # |Delta Omega| <= max_torque sqrt(k) dt / I_min over a period of full torque on k axes
        change = max_torque * math.sqrt(actuator.size) * self.dt / min(params.inertia)
        require_authority(
            "max_torque", change, "max_angular_velocity", max_w, "angular velocity [rad/s]"
        )
        self._setup_options(options)

    _rate_sources = "spin_rate and inertia"

    @property
    def params(self) -> FreeBodyParams:
        return self.system.params

    def _unstable_motion(self, system, task, span):
        """A spin about the intermediate axis: unstable (the rigid body stability theorem,
        :func:`rbenvs.oracles.free_body.axis_stability`), a perturbation growing at
        :func:`~rbenvs.oracles.free_body.intermediate_axis_growth_rate`; said where that is at
        least one e-fold over the horizon (not for moments equal to 1e-9, whose rate is ~1e-5
        |Pi|)."""
        from ..oracles.free_body import axis_stability, intermediate_axis_growth_rate

        inertia = system.params.inertia
        if self.axis is None or axis_stability(inertia)[self.axis] != "unstable":
            return None
        growth = intermediate_axis_growth_rate(inertia, inertia[self.axis] * task.spin_rate)
        if not growth * span >= 1.0:
            return None
        return (
            f"a spin about the intermediate axis (axis {self.axis}) is unstable: a perturbation "
            f"grows at {growth:.3g} 1/s "
            f"({growth * span:.3g} e-folds over the tolerance's horizon of {span:g} s) and the "
            "motion runs near the separatrix"
        )

    def _speed_ceiling(self):
        return math.sqrt(3.0) * self._max_w  # every Omega_i within +-max_angular_velocity

    @staticmethod
    def scene(system, y):
        from ..render.free_body import scene

        return scene(system, y)


@dataclass(frozen=True)
class BodyTorque:
    """The free body's actuator: a normalised action ``a`` on the actuated body ``axes`` gives
    the torque ``max_torque * a`` [N m] there (none elsewhere); floats or arrays alike."""

    max_torque: float
    axes: tuple

    @property
    def size(self) -> int:
        return len(self.axes)

    def control(self, a):
        """``(u_norm, u)``: the normalised action on all three axes (0 where unactuated; the
        reward's effort term) and the torque (:attr:`kernel_control`)."""
        fn, p = self.kernel_control
        return fn(p, a)

    @property
    def kernel_control(self):
        """``(control, max_torque)``: the pure form of :meth:`control`, ``control(P, a) ->
        (u_norm, u)`` (generated for the actuated axes)."""
        return _body_torque_form(tuple(int(i) for i in self.axes)), float(self.max_torque)


@cache
def _body_torque_form(axes: tuple):
    """``control(tau, a)`` for the actuated ``axes``: the action on them, 0.0 elsewhere."""
    items = ["0.0"] * 3
    for j, i in enumerate(axes):
        items[i] = f"a[{j}]"
    un = ", ".join(items)
    src = (
        f"def control(tau, a):\n    un = ({un})\n"
        "    return un, (tau * un[0], tau * un[1], tau * un[2])\n"
    )
    return jitable(generate(src, f"body torque control axes={axes}")["control"])


def _check_axis(axis) -> None:
    """``axis`` is an index 0-2 or one of the names (checked for every task)."""
    if isinstance(axis, (int, np.integer)) and not isinstance(axis, (bool, np.bool_)):
        if not 0 <= int(axis) <= 2:
            raise ValueError(f"axis must be 0, 1, 2 or one of {list(AXIS_NAMES)}, got {axis!r}")
    elif not isinstance(axis, str):
        raise ParameterTypeError(
            f"axis must be 0, 1, 2 or one of {list(AXIS_NAMES)}, got {axis!r} "
            f"({type(axis).__name__})"
        )
    elif axis not in AXIS_NAMES:
        raise ValueError(f"axis must be 0, 1, 2 or one of {list(AXIS_NAMES)}, got {axis!r}")


def _axis_index(axis, params: FreeBodyParams) -> int:
    _check_axis(axis)
    if not isinstance(axis, str):
        return int(axis)
    i1, i2, i3 = params.inertia
    if len({i1, i2, i3}) < 3:
        # With a tie "major"/"minor"/"intermediate" can name two axes: demand an index.
        raise ValueError(
            f"axis={axis!r} is ambiguous for inertia {params.inertia} with equal moments; give an "
            "index 0-2"
        )
    return params.axis_order[AXIS_NAMES.index(axis)]


def _unit_quaternion(name, q) -> tuple[float, float, float, float]:
    comps = require_real_vector(name, q, 4, " (a unit quaternion w, x, y, z)")
    if abs(math.sqrt(sum(c * c for c in comps)) - 1.0) > 1e-6:
        raise ValueError(f"{name} must be a finite unit quaternion (w, x, y, z), got {q!r}")
    return comps

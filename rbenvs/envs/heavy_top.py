"""``rbenvs/LagrangeTop-v0``: a heavy top on a fixed pivot, driven by bounded body torques."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import numpy as np

from ..codegen import generate
from ..core.model import observation_bounds
from ..dynamics import HeavyTop, HeavyTopParams
from ..dynamics.validation import (
    require_bool,
    require_choice,
    require_finite,
    require_finite_nonnegative,
    require_finite_positive,
    require_range,
)
from ..jit import jitable
from ..tasks import PrecessTask, UprightTask, transverse_basis
from .base import RigidBodyEnv, require_authority, require_float32_bound

__all__ = ["LagrangeTopEnv", "PivotTorque"]

# the tasks by name: each declares its defaults and builds itself from the checked keywords
TASKS = {task.name: task for task in (UprightTask, PrecessTask)}


class LagrangeTopEnv(RigidBodyEnv):
    """A spinning top on a fixed pivot under gravity, kept upright or precessing by body torques.

    ## Description
    The heavy top in Lie-Poisson form (docs/physics.md §2, [MR 15.10]): body angular momentum about
    the pivot ``Pi`` and the upward vertical seen from the body ``Gamma = R^T e_z``, with
    ``dPi/dt = Pi x Omega + M g l Gamma x chi + tau``, ``dGamma/dt = Gamma x Omega``. The default
    is the Lagrange top (``I1 = I2``, centre of mass on the symmetry axis ``chi = e3``); any
    inertia and centre-of-mass direction are allowed. Without torque the upright ("sleeping") top
    is stable only above the critical spin ``2 sqrt(M g l I1) / I3`` (heavy top stability
    theorem, [MR 15.10.1]); below it, it falls. Euler angles are never integrated (singular
    upright).

    ## Action space
    ``Box(-1, 1, (2,) or (3,), float32)``: body torque ``max_torque * (a0 t1 + a1 t2 [+ a2 chi])``
    [N m], ``(t1, t2)`` the body axes normal to ``chi`` (``e1``, ``e2`` for a Lagrange top) and
    the third entry, about ``chi``, only with ``axial_torque=True``. Held over the control
    period; out-of-range actions are clipped to [-1, 1]; non-finite actions raise ``ValueError``.

    ## Observation space (float32, both tasks)
    | components | unit | bounds |
    |---|---|---|
    | ``Gamma / |Gamma|`` (upward vertical in the body frame) | 1 | ``+-1`` |
    | ``Omega1, Omega2, Omega3`` (body angular velocity) | rad/s | ``+-max_angular_velocity`` |

    ## Rewards (per step; ``u`` = clipped action)
    * ``upright``: ``cos(tilt) - control_cost * mean(u^2)``.
    * ``precess``: ``1 - |tilt - target_tilt| / tilt_limit - min(|p - p*| / |p*|, 1) -
      control_cost * mean(u^2)``, ``p`` the precession rate of the axis about the vertical and
      ``p*`` the target rate.

    ## Starting state (drawn from the env's seeded generator)
    * spin ``n ~ U(spin)`` about ``chi`` (a number gives a fixed spin);
    * ``upright``: the vertical tilted from ``chi`` by ``U(0, perturbation)`` rad, ``Omega = n
      chi``;
    * ``precess``: tilt ``target_tilt + U(-perturbation, perturbation)`` and the angular velocity
      of the regular precession at the target rate, ``Omega = p* Gamma + (n - p* cos(tilt)) chi``;
    * azimuths (and the heading, with ``attitude=True``) uniform.

    ## Episode end
    * Terminated: ``upright`` when ``tilt > tilt_limit`` (default ``pi/4``: beyond it the
      default ``max_torque`` cannot hold gravity's ``M g l sin(tilt)``); ``precess`` when
      ``|tilt - target_tilt| > tilt_limit`` (default 0.3 rad); any task when an angular velocity
      leaves ``+-max_angular_velocity`` (``info["terminal_reason"] = "observation_limit"``) or
      the state goes non-finite (a ``NumericalFailureWarning``, ``info["numerical_failure"]``,
      the last finite state kept, reward 0).
    * Truncated: after ``max_episode_steps`` (500 steps = 10 s at the default ``dt``).

    ## Info (after every reset and step)
    ``energy`` [J], ``pi_dot_gamma`` (Casimir ``Pi.Gamma`` [kg m^2/s]), ``vertical_norm``
    (Casimir ``|Gamma|``), ``tilt`` [rad] between ``chi`` and the upward vertical, ``spin``
    ``Omega.chi`` [rad/s], ``critical_spin`` [rad/s] (a Lagrange top only: [MR 15.10.1] gives no
    threshold for another top, so the key is absent there; every ``info`` value is finite),
    ``numerical_failure``, ``is_success``; ``precess`` adds ``precession_rate``,
    ``target_precession_rate`` [rad/s] and ``tilt_error`` [rad]; ``attitude=True`` adds the Euler
    angles ``precession_angle``, ``nutation_angle``, ``spin_angle`` [rad] (z-x-z, for output);
    ``internal_step`` [s], the integrator step of the last control period.

    ## Guarded stepping (``guard``)
    Three rates bound the dynamics: the body-frame rotation of ``Pi`` and ``Gamma`` about
    ``Omega`` (``dGamma/dt = -Omega x Gamma``: eigenvalues ``+-i|Omega|``), the gravity frequency
    ``omega_g = sqrt(M g l / I_min)`` (the hanging top's pendulum frequency, the upright top's
    growth rate; ``I_min`` the smallest principal moment about the pivot: conservative, as for a
    Lagrange top gravity acts about the transverse axes, ``sqrt(M g l / I1)``) and the spin
    friction's decay rate ``kappa = k chi.I^-1 chi``.
    Bounds on the internal step ``h``, from the state at the start of each period:

    * ``rk4``: ``(|Omega| + omega_g + kappa) h <= 1.0``: its stability interval is
      ``|h lambda| <= 2.83`` on the imaginary axis (2.78 on the negative real axis); at 1.0 the
      per-step amplitude and phase errors of a rotation are 0.61 % and 0.56 %.
    * ``euler``: ``lambda h <= 0.1`` and ``lambda^2 h dt <= 0.02``, ``lambda = |Omega| +
      omega_g + kappa``: no stability interval on the imaginary axis (a rotation grows by
      ``sqrt(1 + (h lambda)^2)`` per step, by at most ``exp(lambda^2 h dt / 2)``, 1 %, per
      control period): accuracy bounds.
    * ``splitting``: ``omega_g h <= 1.0`` for a Lagrange top, whose free flow is exact: no bound
      on ``|Omega| h``; ``(|Omega| + omega_g) h <= 1.0`` for another top, whose free flow is
      made of exact axis rotations (``|Pi|``, ``|Gamma|`` kept at any step, accurate only below
      about a radian per step). The friction is solved exactly in the kick. The gravity kick
      composed with the free flow is the leapfrog scheme for the pendulum ``omega_g``, stable
      for ``omega_g h < 2``; the bound keeps half of that.
    * ``dop853``: none (adaptive).

    ``guard="subdivide"`` (default) takes the fewest equal steps ``n >= substeps`` that meet the
    bounds;
    ``"refuse"`` raises ``ValueError`` from ``step`` (naming ``substeps`` and the ``n`` needed),
    leaving the state unchanged; ``"off"`` always takes ``substeps`` (an explicit scheme may
    then blow up: a non-finite state ends the episode as a numerical failure). More than
    ``MAX_INTERNAL_STEPS`` (1e6) steps in a period is a numerical failure. When no state inside
    the observation bounds (``|Omega| <= sqrt(3) max_angular_velocity``) can exceed the bound no
    check runs (the default splitting: ``omega_g dt = 0.081``).

    ## State access
    ``get_state()`` returns ``{"angular_momentum": Pi (3,), "vertical": Gamma (3,), "attitude":
    q (4,) (w, x, y, z), body to space, only with attitude=True}`` as float64 copies;
    ``reset(options={"state": d})`` starts exactly there. ``Gamma`` must be a unit vector and ``q``
    a unit quaternion with ``R(q)^T e_z = Gamma`` (within 1e-6), else ``ValueError``.

    ## Arguments
    * ``inertia=(0.45, 0.45, 0.3)``: principal moments **about the pivot** [kg m^2]; with
      ``mass`` and ``length`` they must be a real body's (inertia about the centre of mass
      ``inertia - M l^2 (1 - chi chi^T)`` positive semi-definite, triangle inequality).
    * ``mass=1.0`` [kg], ``length=0.5`` [m] (pivot to centre of mass), ``gravity=9.81`` [m/s^2].
      The defaults give a critical spin of 9.90 rad/s.
    * ``com_direction=(0, 0, 1)``: ``chi`` in the body frame (normalised).
    * ``task="upright"``: ``"upright"`` or ``"precess"`` (``precess`` needs a Lagrange top).
    * ``spin=None``: rad/s, a number or a range ``(low, high)`` drawn per episode. ``None``:
      half the critical spin for ``upright`` (the top falls without control), twice it for
      ``precess``; 0 for an upright top that is not a Lagrange top.
    * ``perturbation=0.05``: rad, initial tilt (upright) or tilt offset (precess) bound.
    * ``target_tilt=0.5`` rad, ``target_rate=None`` rad/s (precess; ``None``: the slow root of
      [T 3.82], torque-free).
    * ``tilt_limit=None``: rad, see Episode end.
    * ``max_torque=2.0``: N m per torque direction (``>= 0``); ``axial_torque=False``.
    * ``spin_friction=0.0``: N m s, viscous pivot torque ``-k (Omega.chi) chi``.
    * ``control_cost=0.01`` (its rewards must fit float32); ``max_angular_velocity=100.0`` rad/s
      (observation bound); ``attitude=False``: also integrate the attitude quaternion (heading,
      Euler angles).

    Every keyword is checked at construction, whatever the task (one the task ignores, such as
    ``target_tilt`` or ``target_rate`` for ``upright`` must still be a valid value): a wrong
    type raises ``TypeError`` (a ``ParameterTypeError``, also a ``ValueError``), a bad value
    ``ValueError``, each naming the keyword and the rule. Flags (``axial_torque``, ``attitude``)
    take ``bool`` only (``"False"`` is refused, not read as true). Beyond the ranges above:
    ``substeps <= 1e6`` (``MAX_INTERNAL_STEPS``: more in a period is a numerical failure);
    ``dt`` must be resolvable at the start (the guard's step count at the fastest initial state
    at most 1e6; not checked with ``guard="off"``); the full torque may change ``Omega`` by at
    most the observation box's width per period (``max_torque sqrt(k) dt / I_min <= 2
    max_angular_velocity``); ``M g l`` and ``M l^2`` must be finite; the initial state must lie
    inside the observation bounds. ``target_tilt`` lies in (0, pi) for every task (and in
    (tilt_limit, pi - tilt_limit) for ``precess``); a ``target_rate`` is finite, nonzero and
    below ``max_angular_velocity``.

    ## Rendering
    ``render_mode="rgb_array"``: ``render()`` returns a 480x480x3 uint8 frame of the top on its
    pivot with ``Pi`` (red), ``Omega`` (blue) and gravity; in space with ``attitude=True``, else in
    a frame turning with the precession. ``"human"``: the same in a matplotlib window after every
    step (when a display exists). Needs the ``plot`` extra.

    ## Version history
    * v0: initial release.
    """

    tasks = tuple(TASKS)
    # info keys of the quantities the uncontrolled, frictionless motion conserves
    invariants = ("energy", "pi_dot_gamma", "vertical_norm")
    system_class = HeavyTop
    randomizable = (
        "inertia",
        "mass",
        "length",
        "gravity",
        "spin_friction",
        "max_torque",
    )  # param_ranges keywords
    shared_defaults = {"dt": 0.02, "integrator": "splitting"}
    integrator_note = (
        "The default splitting applies the free flow of a Lagrange top exactly (fast spin costs "
        "nothing in accuracy) and keeps both Casimirs to round-off; ``euler``, ``rk4`` and "
        "``dop853`` project ``Gamma`` (and ``q``) back to unit length after each step; their "
        'energy and ``Pi.Gamma`` drift (``task="precess"`` with zero torque, seed 0, one 10 s '
        "episode: rk4 1.6e-4 and 2.1e-3 relative, splitting 7e-8 and 1e-15)."
    )

    def __init__(
        self,
        inertia=(0.45, 0.45, 0.3),
        mass: float = 1.0,
        length: float = 0.5,
        gravity: float = 9.81,
        com_direction=(0.0, 0.0, 1.0),
        task: str = "upright",
        spin=None,
        perturbation: float = 0.05,
        target_tilt: float = 0.5,
        target_rate=None,
        tilt_limit=None,
        max_torque: float = 2.0,
        axial_torque: bool = False,
        spin_friction: float = 0.0,
        control_cost: float = 0.01,
        max_angular_velocity: float = 100.0,
        attitude: bool = False,
        **options,
    ):
        # every keyword is checked, whatever the task (one the task ignores must still be valid)
        task_class = TASKS[require_choice("task", task, self.tasks)]
        params = HeavyTopParams(inertia, mass, length, gravity, com_direction, spin_friction)
        self.max_torque = require_finite_nonnegative("max_torque", max_torque)
        control_cost = require_finite_nonnegative("control_cost", control_cost)
        perturbation = require_finite_nonnegative("perturbation", perturbation)
        max_w = require_float32_bound("max_angular_velocity", max_angular_velocity)
        limit = _tilt_limit(task_class.default_tilt_limit, tilt_limit, perturbation)
        alpha, target_rate = _targets(target_tilt, target_rate, max_w)
        self.axial_torque = require_bool("axial_torque", axial_torque)
        attitude = require_bool("attitude", attitude)
        if task_class.needs_lagrange and not params.is_lagrange:
            raise ValueError(
                f"task={task!r} needs a Lagrange top: two equal moments and com_direction "
                "along the third axis"
            )
        system = HeavyTop(params, attitude=attitude)
        tilts = (limit, alpha, target_tilt, target_rate)
        task_obj, peak = _task_and_speed(
            task_class, system, spin, perturbation, tilts, control_cost, max_w
        )
        t1, t2 = transverse_basis(params.com_direction)
        self.torque_directions = (t1, t2) + ((params.com_direction,) if self.axial_torque else ())
        actuator = PivotTorque(self.max_torque, self.torque_directions)
        self._max_w = max_w
        self._start_speed = peak
        high = observation_bounds(task_obj, {"rad/s": max_w})
        self._setup(system, task_obj, actuator, high, options)
        _require_slow_spin_friction(params, self.dt)
        # orthonormal torque directions: |tau| <= max_torque sqrt(k), |Delta Omega| <= |tau| dt /
        # I_min
        change = (
            self.max_torque * math.sqrt(len(self.torque_directions)) * self.dt / min(params.inertia)
        )
        require_authority(
            "max_torque", change, "max_angular_velocity", max_w, "angular velocity [rad/s]"
        )
        self._setup_options(options)

    _rate_sources = "mass, length, gravity, inertia, spin_friction and spin"

    def _unstable_motion(self, system, task, span):
        """An upright Lagrange top whose spin range reaches below the critical spin: unstable
        there (the stability theorem, :func:`rbenvs.oracles.heavy_top.critical_spin`), its tilt
        growing at the largest real part of :func:`~rbenvs.oracles.heavy_top.upright_eigenvalues`;
        said where that is at least one e-fold over the horizon."""
        from ..oracles.heavy_top import upright_eigenvalues

        params = system.params
        if not isinstance(task, UprightTask) or not params.is_lagrange:
            return None
        low, high = task.spin_low, task.spin_high
        slowest = 0.0 if low * high <= 0.0 else min(abs(low), abs(high))
        crit = params.critical_spin
        if not slowest < crit:
            return None
        i1, i3 = params.transverse_inertia, params.axial_inertia
        growth = float(
            max(
                np.real(
                    upright_eigenvalues(i1, i3, params.mass, params.length, params.gravity, slowest)
                )
            )
        )
        if not growth * span >= 1.0:
            return None
        return (
            f"the upright top is unstable below its critical spin {crit:.6g} rad/s "
            "(I3^2 spin^2 < 4 I1 M g l), "
            f"and spin reaches {slowest:.6g} rad/s, where a tilt grows at {growth:.3g} 1/s "
            f"({growth * span:.3g} e-folds over the "
            f"tolerance's horizon of {span:g} s)"
        )

    @property
    def params(self) -> HeavyTopParams:
        return self.system.params

    @property
    def critical_spin(self) -> float:
        return self.system.params.critical_spin

    def _speed_ceiling(self):
        return math.sqrt(3.0) * self._max_w  # every Omega_i within +-max_angular_velocity

    @staticmethod
    def scene(system, y):
        from ..render.heavy_top import scene

        return scene(system, y)


@dataclass(frozen=True)
class PivotTorque:
    """The heavy top's actuator: body torque ``max_torque * sum_j a_j d_j`` [N m] along the
    orthonormal ``directions`` (the two transverse axes, and ``chi`` with axial torque)."""

    max_torque: float
    directions: tuple

    @property
    def size(self) -> int:
        return len(self.directions)

    def control(self, a):
        """``(u_norm, u)``: the normalised action and the body torque; floats or arrays
        (:attr:`kernel_control`)."""
        fn, p = self.kernel_control
        return fn(p, a)

    @property
    def kernel_control(self):
        """``(control, (max_torque, directions))``: the pure form of :meth:`control`,
        ``control(P, a) -> (u_norm, u)`` (generated for the number of directions)."""
        directions = tuple(tuple(float(c) for c in d) for d in self.directions)
        return _pivot_torque_form(len(directions)), (float(self.max_torque), directions)


@cache
def _pivot_torque_form(k: int):
    """``control((m, d), a)`` for ``k`` directions: ``tau_i = sum_j m a_j d_j[i]``, summed from
    0.0 in the directions' order."""
    un = ", ".join(f"a[{j}]" for j in range(k)) + ("," if k == 1 else "")
    tau = [" + ".join(["0.0"] + [f"m * un[{j}] * d[{j}][{i}]" for j in range(k)]) for i in range(3)]
    src = f"def control(P, a):\n    m, d = P\n    un = ({un})\n    return un, ({', '.join(tau)})\n"
    return jitable(generate(src, f"pivot torque control k={k}")["control"])


def _spin_range(spin, task_class, params) -> tuple[float, float]:
    if spin is None:
        if not params.is_lagrange:
            return 0.0, 0.0
        s = task_class.default_spin[0] * params.critical_spin
        return s, s
    return require_range("spin", spin)


def _tilt_limit(default: float, tilt_limit, perturbation: float) -> float:
    """``tilt_limit`` (the task's ``default`` for None) in (0, pi], above ``perturbation``."""
    limit = default if tilt_limit is None else require_finite_positive("tilt_limit", tilt_limit)
    if limit > math.pi:
        raise ValueError(f"tilt_limit must be in (0, pi] rad, got {tilt_limit!r}")
    if perturbation >= limit:
        raise ValueError(
            f"perturbation must be below tilt_limit ({limit!r} rad), got {perturbation!r}"
        )
    return limit


def _targets(target_tilt, target_rate, max_w: float) -> tuple:
    """``(target_tilt, target_rate)`` checked: a tilt in (0, pi), a nonzero rate below
    ``max_angular_velocity`` or None."""
    alpha = require_finite("target_tilt", target_tilt)
    if not 0.0 < alpha < math.pi:
        raise ValueError(f"target_tilt must lie in (0, pi) rad, got {target_tilt!r}")
    if target_rate is not None:
        target_rate = require_finite("target_rate", target_rate)
        if target_rate == 0.0:
            raise ValueError("target_rate must be nonzero (or None for the torque-free rate)")
        if not abs(target_rate) < max_w:
            raise ValueError(
                f"target_rate ({target_rate!r} rad/s) must be below max_angular_velocity "
                f"({max_w!r} rad/s) in magnitude"
            )
    return alpha, target_rate


def _task_and_speed(task_class, system, spin, perturbation, tilts, control_cost, max_w):
    """The task's object (:meth:`UprightTask.build`) and the fastest start's angular speed,
    refused where it reaches ``max_angular_velocity`` (the message names what sets it)."""
    low, high = _spin_range(spin, task_class, system.params)
    task, peak, more = task_class.build(system, low, high, perturbation, tilts, control_cost)
    if spin is None:
        source = (
            f"spin=None: {task_class.default_spin[1]} the critical spin "
            "2 sqrt(M g l I1) / I3, set by mass, length, gravity and inertia"
        )
    else:
        source = "spin"
    if not peak < max_w:
        raise ValueError(
            f"max_angular_velocity ({max_w!r} rad/s) must exceed the initial angular speed "
            f"({peak:.6g} rad/s, from {source}{more}); lower it or raise max_angular_velocity"
        )
    return task, peak


def _require_slow_spin_friction(params, dt: float) -> None:
    # the pivot's friction decays the spin about chi at the rate k / I_chi: faster than a
    # control period, it stops the spin within one step, a clamp rather than a friction
    i_chi = sum(i * c * c for i, c in zip(params.inertia, params.com_direction))
    if not params.spin_friction * dt <= i_chi:
        raise ValueError(
            f"spin_friction must be at most I_chi / dt = {i_chi / dt:.6g} N m s (the "
            "spin's decay time I_chi / spin_friction at "
            f"least the control period dt = {dt!r} s; faster, the spin stops within one "
            f"step), got {params.spin_friction!r}; "
            "lower spin_friction or dt"
        )

"""``rbenvs/TippeTop-v0``: the tippe top on a moving table, with contact and friction."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import numpy as np

from ..codegen import generate
from ..core.model import observation_bounds
from ..dynamics import TippeTop, TippeTopParams
from ..dynamics.tippe_top import FIDELITIES, FRICTION_BOUNDS
from ..dynamics.validation import (
    require_bool,
    require_choice,
    require_finite_nonnegative,
    require_range,
)
from ..jit import jitable
from ..tasks import HoldTask, InvertTask
from ..tasks.tippe_top import STARTS
from .base import RigidBodyEnv, require_authority, require_float32_bound

__all__ = ["TippeTopEnv", "TableActuator"]


class TippeTopEnv(RigidBodyEnv):
    """A sphere with an offset centre of mass spinning on a table that the agent can move.

    ## Description
    The tippe top of docs/physics.md §3 ([T 3.92-3.114]): a sphere of radius ``a`` whose centre
    of mass sits ``h = alpha a`` below its centre along the symmetry axis, moments ``A``
    (transverse) and ``C`` (axial) about the centre of mass. Spun fast on its broad end it
    climbs onto its stem when ``1 - alpha < A/C < 1 + alpha`` and Jellett's integral is large
    enough: sliding friction at the contact dissipates energy while keeping Jellett's integral.
    The contact is a constraint (the normal force is solved from it, no spring, no penetration),
    with a choice of ``fidelity``: ``gliding`` (friction; the default), ``frictionless``, or
    ``rolling`` (no slip). If the normal force would have to pull (``N < 0``) the top lifts
    off: by default the episode ends there (``terminal_reason = "lift_off"``); with
    ``free_flight=True`` the top flies (ballistic, torque-free) and lands again with a plastic,
    frictionless impact, so long runs go on through the hops that real tippe tops make
    (:class:`rbenvs.dynamics.TippeTop`, "Free flight").

    ## Action space
    ``Box(-1, 1, (k,), float32)``: the table's horizontal acceleration
    ``max_table_acceleration * (a0, a1)`` [m/s^2] in the table frame (it acts on the top only
    through friction at the contact); with ``friction_action=True`` a further entry sets the
    friction coefficient in ``friction_range`` (affine in [-1, 1]); with ``torque_action=True``
    three more give a body torque ``max_torque * (a_i)`` [N m] about the centre of mass (this
    one breaks Jellett's integral). Out-of-range actions are clipped; non-finite ones raise.

    ## Observation space (float32, 8 numbers, space frame)
    | components | unit | bounds |
    |---|---|---|
    | ``k`` (symmetry axis; ``k_z = cos(theta)``) | 1 | ``+-1`` |
    | ``omega`` (angular velocity) | rad/s | ``+-max_angular_velocity`` |
    | ``v_x, v_y`` (centre of mass, relative to the table) | m/s | ``+-max_speed`` |

    ## Rewards (per step; ``u`` = clipped action)
    * ``invert``: ``-(1 + cos(theta))/2 - control_cost * mean(u^2)``: the time to invert,
      weighted by how far from inverted. Time rather than dissipated energy: Jellett's integral
      fixes the energy left at the end (the top settles near the minimum ``E*(pi)``), so every
      successful policy dissipates nearly the same energy; the time differs.
    * ``hold``: ``(1 + cos(theta))/2 - control_cost * mean(u^2)``.

    ## Starting state (seeded)
    Spin ``n ~ U(spin)`` at tilt ``theta ~ U(tilt)``, uniform azimuth and heading, at the
    origin; ``start`` says how it was spun (docs/physics.md §3): ``"rest"`` (the default, but
    for ``fidelity="rolling"``): about the symmetry axis with the centre of mass at rest, so the
    contact point slips at first (a top spun by hand; Leine and Glocker's start and that of most
    numerical studies); ``"rolling"`` (the default of ``fidelity="rolling"``, and of ``-v0``
    before issue 18): about the symmetry axis with the contact point at rest (``v_G = -omega x
    r``); ``"vertical"``: the centre of mass at rest and the spin about the space vertical.
    ``"rest"`` and ``"vertical"`` need a fidelity with slip (not ``"rolling"``).

    ## Episode end
    * Terminated: ``invert`` when ``theta > 150 deg`` (success; past it the climb slows with the
      slip speed under regularised Coulomb friction, docs/physics.md §3); ``hold`` when
      ``theta > 90 deg``; lift-off (``N < 0`` at any internal step; not with ``free_flight``);
      an observation bound; a non-finite state (``NumericalFailureWarning``, last finite state
      kept).
    * Truncated: after ``max_episode_steps`` (2500 steps = 25 s at the default ``dt``; without
      action the default top passes 90 deg at 1.61 s and 150 deg at 18.84 s, its normal force
      above 0.75 m g; from ``start="rolling"`` at 7.0 s and 17.3 s).
    * An episode that ends without success (``hold`` past 90 deg, lift-off, an observation
      bound, a numerical failure) carries in its last reward the failure charge,
      ``max_episode_steps`` times the task's least reward where negative (``invert``: ``-(1 +
      control_cost)``; ``hold``: ``-control_cost``; :class:`rbenvs.core.model.Model`): ending
      early never pays.

    ## Info
    ``energy`` [J] (table frame), ``jellett`` ``J = L.(a z_hat - h k)`` [kg m^2/s], ``tilt``
    ``theta`` [rad], ``normal_force`` ``N`` [N] (0 in flight), ``slip_speed`` ``|v_P|`` [m/s],
    ``lifted_off`` (the top has left the table this episode), ``airborne`` (in flight now),
    ``hops`` (lift-offs this episode), ``gap`` (height of the sphere's lowest point above the
    table [m]), ``spin`` (``Omega3`` [rad/s]), ``internal_step`` [s], ``numerical_failure``,
    ``is_success``.

    ## State access
    ``get_state()``: ``position`` (3, ``G`` in the table frame; ``z`` from the contact),
    ``velocity`` (3), ``attitude`` (4, w x y z, body to space), ``angular_velocity`` (3, body).
    ``reset(options={"state": d})`` checks the contact: ``z`` must be ``a - h cos(theta)`` and
    ``v_z`` (rolling: the whole velocity) what the attitude and spin require. With
    ``free_flight`` a state above the table starts in flight (the hop count starts at 0).

    ## Internal step (guarded stepping, ``guard``)
    With ``guard="subdivide"`` (default) each control period is split into ``n = max(substeps,
    ceil(dt max(|Omega|, omega_g) / 0.1), ceil(dt / h_f))`` equal steps: ``|Omega| h <= 0.1``
    (``SPIN_STEP``, an accuracy bound for every integrator: the contact geometry turns with the
    body), the same for gravity's rate ``omega_g = sqrt(m g (a + h) / min(A, C))`` (an upper
    bound of the rocking frequency; 38.9 rad/s for the default top, below its spin, so it sets
    the step only for slow tops without friction; :meth:`TippeTopParams.gravity_rate`) and
    ``h <= h_f``, the explicit stability bound of the friction law
    (:meth:`rbenvs.dynamics.TippeTop.max_stable_step`: near zero slip, regularised Coulomb
    friction is a viscous law of rate ``lambda = mu N |M| / slip_regularization``, stiff;
    ``h_f = 1 / lambda`` for euler, whose interval on the negative real axis is
    ``|h lambda| <= 2``, and ``1.39 / lambda`` for rk4, interval 2.78: half the margin, with
    ``N`` taken as twice the larger of ``m g`` and its current value; ``inf`` without friction,
    when rolling, and for dop853): ``friction_bound="stability"``. ``friction_bound="accuracy"``
    (the default) sizes ``h_f`` from
    accuracy instead, from the tight rate ``lambda_d`` (the law's stiffness at the actual ``N``
    and the largest mobility of the contact point along the table: within 1 % of the vector
    field's stiffest decay rate near zero slip): for rk4 ``h_f = min(1.25 / lambda_d, 1.25 /
    (K sqrt(lambda_d w)))``, ``w = max(|Omega|, omega_g)``, ``K`` the law's ``accuracy_scale``
    (Coulomb 19, viscous 10.4; :mod:`rbenvs.dynamics.contact`), ``lambda_d`` taken at the
    smallest slip the period can reach (beyond ``|s| = 3.9 eps`` a sliding top's friction is not
    stiff; then at least ``50 w``, what Jellett's integral needs: ``STIFF_BAND``,
    ``JELLETT_SCALE``): 0.81-0.85 of the stability bound's steps for the default top, the time
    to 90 degrees within 1e-4 s of the converged value
    and Jellett's drift at most 3e-9 per simulated second on every top of a sweep across the
    inversion band (tests/test_tippe_stiff.py; ``python -m rbenvs.bench.tippe_steps``). ``n`` is set
    from the state at the start of each period;
    ``info["internal_step"]`` reports ``dt / n``. ``guard="refuse"`` raises ``ValueError`` from
    ``step`` (naming ``substeps`` and the ``n`` needed) when ``n > substeps``, leaving the state
    unchanged; ``guard="off"`` always takes ``substeps`` steps (an explicit scheme may then
    blow up: a numerical failure). More than ``MAX_INTERNAL_STEPS`` (1e6) steps is a numerical
    failure.

    ## Arguments
    * ``radius=0.015`` m, ``mass=0.006`` kg, ``offset=0.2`` (``alpha``), ``inertia=(8e-7, 7e-7)``
      (``A, C`` about the centre of mass, kg m^2), ``gravity=9.81``: the Leine-Glocker top.
    * ``friction=0.3``, ``friction_law="coulomb"`` or ``"viscous"``,
      ``slip_regularization=1e-3`` m/s (below ``max_speed``), ``fidelity="gliding"``,
      ``"frictionless"`` or ``"rolling"``.
    * ``free_flight=False``: model hops (gliding or frictionless) instead of ending the episode
      at lift-off; about 1.15x the gliding level's cost per step on the table (the contact
      flag is carried and the switch tested at every internal step; ``rbenvs bench fidelity``).
    * ``stem=None``: or ``(b, d)`` [m], the stem's tip as a second contact, a sphere of radius
      ``b`` centred ``d`` from the centre of mass on the symmetry axis beyond the sphere's centre
      (Leine and Glocker's top: ``(0.005, 0.016)``, scene ``tippe_leine_glocker``): the inverted
      top lands on it (located touchdown, plastic impact; the sphere lifts) and spins on it
      (docs/physics.md §3, "The stem"). Gliding or frictionless, without ``free_flight``; a
      lift-off from either contact ends the episode. The state carries a contact flag (0 on the
      sphere, 1 on the stem); ``gap`` is the sphere's, ``jellett`` the sphere's integral. Both
      contacts pressing at once is not modelled: a top that settles at the touch tilt alternates
      between them by impacts (an approximation; docs/physics.md §3).
    * ``task="invert"`` or ``"hold"``; ``spin=150.0`` rad/s and ``tilt=0.1`` rad (numbers or
      ``(low, high)`` ranges). Not Leine and Glocker's 180 rad/s: with this model (gliding
      friction, regularised Coulomb, no drilling friction) and the rolling start, their top's
      normal force dips just below zero near 80 degrees of tilt at 180 rad/s (a hop, which ends
      the episode), while at 150 rad/s it stays positive through the inversion
      (tests/test_tippe_top_env.py); from their own start (``start="rest"``) at 180 rad/s it
      stays above 0.55 m g and passes 90 degrees at 2.71 s (tests/test_tippe_starts.py).
    * ``start=None``: how the top was spun, ``"rest"``, ``"rolling"`` or ``"vertical"``
      (``None``: ``"rest"``, or ``"rolling"`` with ``fidelity="rolling"``; Starting state).
    * ``friction_bound="accuracy"``: or ``"stability"``, what sizes the step under friction
      (Internal step).
    * ``max_table_acceleration=2.0`` m/s^2; ``friction_action=False``, ``friction_range=(0.0,
      0.6)``; ``torque_action=False``, ``max_torque=1e-4`` N m; ``control_cost=0.01``.
    * ``max_angular_velocity=None`` (``2 max|spin| + 50``) rad/s, ``max_speed=5.0`` m/s.

    Every keyword is checked at construction, whatever the task (one the task ignores, such as
    ``friction_range`` without ``friction_action`` must still be a valid value): a wrong type
    raises ``TypeError`` (a ``ParameterTypeError``, also a ``ValueError``), a bad value
    ``ValueError``, each naming the keyword and the rule. Flags (``friction_action``,
    ``torque_action``, ``free_flight``) take ``bool`` only (``"False"`` is refused, not read as
    true). Beyond the ranges above: ``substeps <= 1e6`` (``MAX_INTERNAL_STEPS``: more in a
    period is a numerical failure); ``dt`` must be resolvable at the start (the guard's step
    count at the fastest initial state at most 1e6; not checked with ``guard="off"``); the full
    table acceleration and body torque may change the observed velocities by at most the width
    of their boxes per period; the friction law's stability bound is checked at the largest
    coefficient the env can use (``friction`` or ``friction_range``'s upper end); the initial
    state must lie inside the observation bounds. ``m a^2``, ``(a + h)^2 / min(A, C)`` and ``m g
    a`` must be finite.

    ## Rendering
    ``render_mode="rgb_array"``: ``render()`` returns a 480x480x3 uint8 frame of the sphere on
    the table (broad and stem halves in two colours) with the contact point, the centre of mass,
    ``L`` about it (red) and ``omega`` (blue); the view follows the top. ``"human"``: the same in
    a matplotlib window after every step (when a display exists). Needs the ``plot`` extra.

    ## Version history
    * v0: initial release.
    """

    tasks = ("invert", "hold")
    system_class = TippeTop
    # no default accuracy yet: unchecked (its steps the stability and friction bounds') until a
    # default bound is sized over the tops the docs name (issue 44; its estimate costs the
    # friction's share a contact solve per stage of its own: measured first)
    default_tolerance = None
    randomizable = (
        "radius",
        "mass",
        "offset",
        "inertia",
        "gravity",
        "friction",
        "max_table_acceleration",
        "max_torque",
    )  # param_ranges keywords
    shared_defaults = {"dt": 0.01}
    guard_section = "Internal step"
    fidelities = FIDELITIES
    # info keys of the quantities the motion keeps: Jellett always (no body torque), the energy
    # without friction
    invariants = ("jellett", "energy")

    def __init__(
        self,
        radius: float = 0.015,
        mass: float = 0.006,
        offset: float = 0.2,
        inertia=(8e-7, 7e-7),
        gravity: float = 9.81,
        friction: float = 0.3,
        friction_law: str = "coulomb",
        slip_regularization: float = 1e-3,
        fidelity: str = "gliding",
        task: str = "invert",
        spin=150.0,
        tilt=0.1,
        start=None,
        max_table_acceleration: float = 2.0,
        friction_action: bool = False,
        friction_range=(0.0, 0.6),
        torque_action: bool = False,
        max_torque: float = 1e-4,
        control_cost: float = 0.01,
        max_angular_velocity=None,
        max_speed: float = 5.0,
        free_flight: bool = False,
        friction_bound: str = "accuracy",
        stem=None,
        **options,
    ):
        # every keyword is checked, whatever the task and options (an unused one must be valid)
        task = require_choice("task", task, self.tasks)
        fidelity = require_choice("fidelity", fidelity, FIDELITIES)
        body = (radius, mass, offset, inertia, gravity)
        params = TippeTopParams(*body, friction, friction_law, slip_regularization, stem)
        spin_lo, spin_hi = require_range("spin", spin)
        tilt_lo, tilt_hi = require_range("tilt", tilt)
        start = _start(start, fidelity, tilt, tilt_lo, tilt_hi)
        self.max_table_acceleration = require_finite_nonnegative(
            "max_table_acceleration", max_table_acceleration
        )
        self.max_torque = require_finite_nonnegative("max_torque", max_torque)
        control_cost = require_finite_nonnegative("control_cost", control_cost)
        self.friction_action = require_bool("friction_action", friction_action)
        self.torque_action = require_bool("torque_action", torque_action)
        self.friction_range = _friction_range(friction_range)
        self.free_flight = require_bool("free_flight", free_flight)
        _require_modelled(fidelity, self.free_flight, stem, self.friction_action)
        peak = max(abs(spin_lo), abs(spin_hi))
        max_w = _angular_velocity_bound(max_angular_velocity, spin, peak)
        max_v = _speed_bound(max_speed, params, slip_regularization, peak)
        task_cls = InvertTask if task == "invert" else HoldTask
        task_obj = task_cls(spin_lo, spin_hi, tilt_lo, tilt_hi, control_cost, start=start)
        friction_bound = require_choice("friction_bound", friction_bound, FRICTION_BOUNDS)
        system = TippeTop(params, fidelity, flight=self.free_flight, friction_bound=friction_bound)
        actuator = self._actuator(params)
        self._start_speed = peak
        self._max_w = max_w
        high = observation_bounds(task_obj, {"rad/s": max_w, "m/s": max_v})
        self._setup(system, task_obj, actuator, high, options)
        self._require_authority(params, max_w, max_v)
        self._setup_options(options)

    def _actuator(self, params) -> TableActuator:
        return TableActuator(
            self.max_table_acceleration,
            params.friction,
            self.friction_range if self.friction_action else None,
            self.max_torque if self.torque_action else None,
        )

    def _require_authority(self, params, max_w: float, max_v: float) -> None:
        # the table's acceleration moves v_G (relative to the table) by at most |a_T| dt per period;
        # a body torque moves Omega by at most |tau| dt / min(A, C)
        require_authority(
            "max_table_acceleration",
            self.max_table_acceleration * math.sqrt(2.0) * self.dt,
            "max_speed",
            max_v,
            "velocity of the centre of mass [m/s]",
        )
        # (without the torque action max_torque acts on nothing: validated above, no veto on the
        # body)
        if self.torque_action:
            change = self.max_torque * math.sqrt(3.0) * self.dt / min(params.inertia)
            require_authority(
                "max_torque", change, "max_angular_velocity", max_w, "angular velocity [rad/s]"
            )

    @property
    def params(self) -> TippeTopParams:
        return self.system.params

    _rate_sources = (
        "spin, gravity, mass, inertia, radius, offset, friction, friction_range and "
        "slip_regularization"
    )

    def _unstable_motion(self, system, task, span):
        """A top with friction spun above the inversion threshold: its upright start is left and
        the top inverts (the inversion criterion,
        :func:`rbenvs.oracles.tippe_top.inversion_spin_threshold`)."""
        from ..oracles.tippe_top import inversion_spin_threshold

        p = system.params
        if system.friction_law is None or p.friction == 0.0:
            return None
        try:
            threshold = inversion_spin_threshold(
                p.inertia[0], p.inertia[1], p.offset, p.mass, p.gravity, p.radius
            )
        except ValueError:  # no full inversion for these moments
            return None
        fastest = max(abs(task.spin_low), abs(task.spin_high))
        if not fastest > threshold:
            return None
        return (
            f"the top inverts (the inversion criterion: spin above {threshold:.6g} rad/s, and spin "
            f"reaches {fastest:.6g} rad/s), "
            "and its rise amplifies errors (a slip leaving the friction band grows with its error; "
            "held at the slip's own "
            "scale where the law saturates, which keeps the scenes' top inverting from rest at 150 "
            "rad/s within the tolerance, "
            "not the one hopping at 180 rad/s)"
        )

    def _speed_ceiling(self):
        return math.sqrt(3.0) * self._max_w

    def _start_dissipation(self, system):
        """The friction's stiffness at the start (``N = m g``) at the largest coefficient the env
        can use (``friction``, or ``friction_range``'s upper end with ``friction_action``)."""
        return system.friction_stiffness(max(system.params.friction, self.friction_range[1]))

    @staticmethod
    def scene(system, y):
        from ..render.tippe_top import scene

        return scene(system, y)


@dataclass(frozen=True)
class TableActuator:
    """The tippe top's actuator: the table's horizontal acceleration ``max_table_acceleration *
    (a0, a1)`` [m/s^2]; with ``friction_range`` a further entry sets the friction coefficient
    (affine in [-1, 1]); with ``max_torque`` three more a body torque [N m]. Controls
    ``(a_x, a_y, mu, tau1, tau2, tau3)`` (:mod:`rbenvs.dynamics.tippe_top`)."""

    max_table_acceleration: float
    friction: float  # the coefficient when the action does not set it
    friction_range: tuple | None = None
    max_torque: float | None = None

    @property
    def size(self) -> int:
        return 2 + (self.friction_range is not None) + 3 * (self.max_torque is not None)

    def control(self, a):
        """``(u_norm, u)``: the normalised action and the controls ``(a_x, a_y, mu, tau1, tau2,
        tau3)``; floats or arrays (:attr:`kernel_control`)."""
        fn, p = self.kernel_control
        return fn(p, a)

    @property
    def kernel_control(self):
        """``(control, (acc, mu, lo, hi, max_torque))``: the pure form of :meth:`control`,
        ``control(P, a) -> (u_norm, u)`` (generated for the action's entries)."""
        lo, hi = (
            (float(c) for c in self.friction_range)
            if self.friction_range is not None
            else (0.0, 0.0)
        )
        torque = float(self.max_torque) if self.max_torque is not None else 0.0
        form = _table_form(self.friction_range is not None, self.max_torque is not None)
        return form, (float(self.max_table_acceleration), float(self.friction), lo, hi, torque)


@cache
def _table_form(sets_friction: bool, torque: bool):
    """``control(P, a)``: the table's acceleration from ``a[0:2]``, the friction coefficient
    affine in the next entry (``sets_friction``; else the fixed one), the body torque from the
    next three (``torque``; else zero)."""
    k = 2 + sets_friction + 3 * torque
    lines = [
        "def control(P, a):",
        "    acc, mu, lo, hi, m = P",
        f"    un = ({', '.join(f'a[{j}]' for j in range(k))})",
        "    ax, ay = acc * un[0], acc * un[1]",
    ]
    if sets_friction:
        lines.append("    mu = lo + 0.5 * (un[2] + 1.0) * (hi - lo)")
    j = 2 + sets_friction
    tau = f"(m * un[{j}], m * un[{j + 1}], m * un[{j + 2}])" if torque else "(0.0, 0.0, 0.0)"
    lines.append(f"    return un, (ax, ay, mu) + {tau}")
    return jitable(
        generate("\n".join(lines), f"table control friction={sets_friction} torque={torque}")[
            "control"
        ]
    )


def _friction_range(friction_range) -> tuple:
    mu_lo, mu_hi = require_range("friction_range", friction_range)
    if mu_lo < 0.0:
        raise ValueError(f"friction_range must lie in [0, inf), got {friction_range!r}")
    return mu_lo, mu_hi


def _start(start, fidelity: str, tilt, tilt_lo: float, tilt_hi: float) -> str:
    """``start`` checked (None: the literature's start; a rolling top's contact point never
    slips, so it starts rolling), then the tilt's range."""
    if start is None:
        start = "rolling" if fidelity == "rolling" else "rest"
    start = require_choice("start", start, STARTS)
    if start != "rolling" and fidelity == "rolling":
        raise ValueError(
            f"start={start!r} needs fidelity 'gliding' or 'frictionless': a rolling top's "
            "contact point never slips, so it starts rolling (start='rolling')"
        )
    if tilt_lo < 0.0 or tilt_hi >= math.pi / 2:
        raise ValueError(f"tilt must lie in [0, pi/2) rad (a start on the broad end), got {tilt!r}")
    return start


def _require_modelled(fidelity: str, free_flight: bool, stem, friction_action: bool) -> None:
    """Refuse options the fidelity level does not model."""
    if free_flight and fidelity == "rolling":
        raise ValueError(
            "free_flight needs fidelity 'gliding' or 'frictionless' (a rolling top has no slip "
            "to resume after a touchdown)"
        )
    if stem is not None and (free_flight or fidelity == "rolling"):
        raise ValueError(
            "stem needs fidelity 'gliding' or 'frictionless' and free_flight=False "
            "(a touchdown from flight could meet "
            "both contacts at once, which needs a two-contact impact law; a rolling top has no "
            "slip to resume)"
        )
    if friction_action and fidelity != "gliding":
        raise ValueError(
            "friction_action needs fidelity='gliding' (there is no friction coefficient to set "
            f"when {fidelity!r})"
        )


def _angular_velocity_bound(max_angular_velocity, spin, peak: float) -> float:
    """The observation bound of the angular velocity (None: 2 max|spin| + 50 rad/s), above the
    fastest start's spin ``peak``."""
    if max_angular_velocity is None:
        max_w = 2.0 * peak + 50.0
        if not max_w <= float(np.finfo(np.float32).max):
            raise ValueError(
                f"spin ({spin!r} rad/s) is too large for float32 observations "
                f"(max_angular_velocity=None takes 2 max|spin| + 50 = {max_w:.6g} rad/s)"
            )
    else:
        max_w = require_float32_bound("max_angular_velocity", max_angular_velocity)
    if not peak < max_w:
        raise ValueError(
            f"max_angular_velocity ({max_w!r} rad/s) must exceed the initial spin (spin = "
            f"{peak!r} rad/s); lower spin or raise max_angular_velocity"
        )
    return max_w


def _speed_bound(max_speed, params, slip_regularization, peak: float) -> float:
    """The observation bound of the centre of mass's velocity, above the friction law's
    regularisation and the fastest start's rolling speed."""
    max_v = require_float32_bound("max_speed", max_speed)
    if not params.slip_regularization < max_v:
        raise ValueError(
            f"slip_regularization must be below max_speed = {max_v!r} m/s, got "
            f"{slip_regularization!r}: above every slip speed the env "
            "allows, the friction law weakens to a viscous one of vanishing rate (friction off "
            "in all but name)"
        )
    if not params.radius * peak < max_v:
        raise ValueError(
            "max_speed must exceed the initial speed of the centre of mass (radius * spin = "
            f"{params.radius * peak!r} m/s), got {max_speed!r}"
        )
    return max_v

"""The tippe top as a system (:class:`rbenvs.contracts.HybridSystem`): :class:`TippeTop`."""

from __future__ import annotations

import math

import numpy as np

from ...contracts import GuardRates, StepRegion
from ...draws import draw
from ..contact import FRICTION_LAWS, no_friction
from ..state import start_as_drawn
from ..validation import (
    did_you_mean,
    real_array,
)
from .forms import (
    contact_arm,
    flight_airborne,
    flight_gap,
    flight_impact,
    flight_on_table,
    flight_take_off,
    flight_touch_down,
    pure_forms,
    pure_parameters,
    rolling_velocity_body,
    tippe_frame,
    to_space,
)
from .implicit import ImplicitForms, implicit_forms
from .params import (
    ACCURACY_MARGIN,
    FIDELITIES,
    FRICTION_BOUNDS,
    FRICTION_MARGIN,
    LIFT_OFF_TOL,
    SPIN_STEP,
    TOUCHDOWN_TOL,
    Event,
    TippeTopParams,
    tippe_rotation_rate,
)
from .stem import (
    STEM_TOL,
    stem_accuracy_rate,
    stem_forms,
    stem_impact,
    stem_jellett,
    stem_on_sphere,
    stem_on_stem,
    stem_other_gap,
    stem_switch,
)


class TippeTop:
    """Vector field, contact forces and read-outs of the tippe top at one fidelity level.

    The arithmetic is in the pure forms (:func:`pure_forms` of this top's law, fidelity and
    flight, parameters ``P`` = :func:`pure_parameters`): the methods call them, and the
    ``kernel_*`` attributes expose them as ``(fn, P)`` pairs for generated and compiled steps
    (:class:`rbenvs.contracts.System`): ``kernel_rhs``, ``kernel_rhs_normal`` (``(dy, N)`` from one
    contact solve), ``kernel_normalize``, ``kernel_readouts``, ``kernel_normal`` (``N``),
    ``kernel_gap`` and, with flight, the switches ``kernel_take_off``, ``kernel_touch_down``,
    ``kernel_on_table``, ``kernel_airborne`` (``None`` without); all ``None`` for a friction law
    given by its methods alone (which compiled code cannot call; the methods then run it on
    floats and arrays).
    """

    def __init__(
        self,
        params: TippeTopParams,
        fidelity: str = "gliding",
        flight: bool = False,
        friction_bound: str = "stability",
    ):
        self._memo = None  # the last contact solve (see _contact)
        if fidelity not in FIDELITIES:
            raise ValueError(
                f"fidelity must be one of {list(FIDELITIES)}, got "
                f"{fidelity!r}{did_you_mean(fidelity, FIDELITIES)}"
            )
        if friction_bound not in FRICTION_BOUNDS:
            raise ValueError(
                f"friction_bound must be one of {list(FRICTION_BOUNDS)}, got "
                f"{friction_bound!r}{did_you_mean(friction_bound, FRICTION_BOUNDS)}"
            )
        self.friction_bound = friction_bound
        self.fidelity = fidelity
        self.rolling = fidelity == "rolling"
        self.flight = bool(flight)
        if self.flight and self.rolling:
            raise ValueError(
                "flight=True needs fidelity 'gliding' or 'frictionless' (a rolling top has no slip "
                "to resume after a touchdown)"
            )
        self.stem = params.stem is not None
        if self.stem and self.rolling:
            raise ValueError(
                "stem needs fidelity 'gliding' or 'frictionless' (the rolling limit has no slip to "
                "resume after the stem's touchdown)"
            )
        if self.stem and self.flight:
            raise ValueError(
                "stem with flight=True is not modelled: a touchdown from flight could meet both "
                "contacts at once, "
                "which needs a two-contact impact law (docs/physics.md §3, 'The stem')"
            )
        if self.stem:
            self.layout = {
                "position": (0, 2),
                "velocity": (2, 4),
                "attitude": (4, 8),
                "angular_velocity": (8, 11),
                "contact": (11, 12),
            }
            self.dim = 12
            self._q, self._w = 4, 8
        elif self.flight:
            self.layout = {
                "position": (0, 3),
                "velocity": (3, 6),
                "attitude": (6, 10),
                "angular_velocity": (10, 13),
                "contact": (13, 14),
                "hops": (14, 15),
            }
            self.dim = 15
            self._q, self._w = 6, 10
        elif self.rolling:
            self.layout = {"position": (0, 2), "attitude": (2, 6), "angular_velocity": (6, 9)}
            self.dim = 9
            self._q, self._w = 2, 6
        else:
            self.layout = {
                "position": (0, 2),
                "velocity": (2, 4),
                "attitude": (4, 8),
                "angular_velocity": (8, 11),
            }
            self.dim = 11
            self._q, self._w = 4, 8
        self.params = params  # (sets the law and the pure forms: see the setter)

    @property
    def params(self) -> TippeTopParams:
        """The parameters. Setting them sets everything derived from them: the friction law,
        the pure forms and their ``P`` (:attr:`forms`, :attr:`form_params`) and the ``kernel_*``
        pairs."""
        return self._params

    @params.setter
    def params(self, params: TippeTopParams):
        if (params.stem is not None) != self.stem:  # (set first by __init__ and __setstate__)
            raise ValueError(
                "params must keep the stem as it is (a stem changes the state's layout)"
            )
        self._params = params
        self._memo = None
        self.friction_law = None if self.fidelity != "gliding" else params.friction_law  # its name
        self.friction = (
            None if self.friction_law is None else FRICTION_LAWS[self.friction_law]
        )  # the law (dynamics.contact)
        coefficient, stiffness = (
            (no_friction, None) if self.friction is None else self.friction.pure_forms()
        )
        if self.stem:
            self.forms = forms = stem_forms(coefficient, stiffness)
        else:
            self.forms = forms = pure_forms(coefficient, stiffness, self.rolling, self.flight)
        self.form_params = p = pure_parameters(params)
        compilable = self.friction is None or self.friction.compilable

        def pair(fn, offered=True):
            return (fn, p) if compilable and offered else None

        self.kernel_rhs = pair(forms.rhs)
        self.kernel_rhs_normal = pair(forms.rhs_normal)
        self.kernel_normalize = pair(forms.normalize)
        self.kernel_readouts = pair(forms.readouts)
        self.kernel_normal = pair(forms.normal)
        self.kernel_gap = pair(forms.gap)
        self.kernel_take_off = pair(flight_take_off, self.flight)
        self.kernel_touch_down = pair(flight_touch_down, self.flight)
        self.kernel_on_table = pair(flight_on_table, self.flight)
        self.kernel_airborne = pair(flight_airborne, self.flight)
        # the hybrid contract's pure forms (rbenvs.contracts.HybridSystem): without flight the
        # terminal event is the lift-off (N < 0), checked from the contact solve that is also
        # the next step's first stage; with flight the two switches of events()
        self.kernel_event = pair(forms.normal, not self.flight)
        # (with the stem the switches come between a step and the check: no shared first stage)
        self.kernel_rhs_event = pair(forms.rhs_normal, not self.flight and not self.stem)
        # the friction's linearisation (ImplicitForms): the W-matrix of a linearly implicit
        # scheme, (factor, solve, P); the tight stiffness rate; None for a law with no slope
        slope = None if self.friction is None else self.friction.kernel_slope
        self.implicit = None
        if self.friction is None or (slope is not None and compilable):
            saturates = self.friction is not None and self.friction.saturates
            self.implicit = implicit_forms(
                coefficient, stiffness, slope, self.rolling, self.flight, saturates
            )
        self.kernel_implicit = (
            None if self.implicit is None else (self.implicit.factor, self.implicit.solve, p)
        )
        if self.stem and self.implicit is not None:
            # with the stem: the accuracy rate at the pressing contact; no W-matrix (the linearly
            # implicit schemes are not offered: their solve is written for the 11 components)
            rate = self.implicit.accuracy_rate
            self.implicit = ImplicitForms(
                None, None, None, None if rate is None else stem_accuracy_rate(rate)
            )
            self.kernel_implicit = None
        self.kernel_switches = None
        if self.stem and compilable:
            tol = STEM_TOL * min(params.radius, params.stem[0])
            self.kernel_switches = (
                ((stem_on_sphere, ()), (stem_other_gap, p), tol, (stem_switch, p)),
                ((stem_on_stem, ()), (stem_other_gap, p), tol, (stem_switch, p)),
            )
        if self.flight and compilable:
            self.kernel_switches = (
                (
                    (flight_on_table, ()),
                    (forms.normal, p),
                    LIFT_OFF_TOL * params.mass * params.gravity,
                    (flight_take_off, ()),
                ),
                (
                    (flight_airborne, ()),
                    (flight_gap, p),
                    TOUCHDOWN_TOL * params.radius,
                    (flight_touch_down, p),
                ),
            )

    # what the parameters' setter derives: the pure forms are functions made per combination
    # (closures, which pickle cannot carry), so a pickle carries the parameters and the setter
    # makes the rest again on loading
    _DERIVED = (
        "friction_law",
        "friction",
        "forms",
        "form_params",
        "kernel_rhs",
        "kernel_rhs_normal",
        "kernel_normalize",
        "kernel_readouts",
        "kernel_normal",
        "kernel_gap",
        "kernel_take_off",
        "kernel_touch_down",
        "kernel_on_table",
        "kernel_airborne",
        "kernel_event",
        "kernel_rhs_event",
        "kernel_switches",
        "implicit",
        "kernel_implicit",
    )

    def __getstate__(self):
        state = {k: v for k, v in self.__dict__.items() if k not in self._DERIVED}
        state["_memo"] = None
        return state

    def __setstate__(self, state):
        state = dict(state)
        params = state.pop("_params")
        self.__dict__.update(state)
        self.params = params

    # ------------------------------------------------------------------ kinematics
    def frame(self, y):
        """Rotation matrix entries of ``q`` (body -> space) and ``Gamma = R^T z_hat``."""
        return self.forms.frame(self.form_params, y)

    def angular_velocity(self, y):
        o = self._w
        return (y[o], y[o + 1], y[o + 2])

    def vertical(self, y):
        """``Gamma``: the upward vertical in the body frame."""
        rm = self.frame(y)
        return (rm[6], rm[7], rm[8])

    def contact_arm(self, g1, g2, g3):
        """``r = P - G = h e3 - a Gamma`` in the body frame."""
        return contact_arm(self.form_params, g1, g2, g3)

    def velocity(self, y):
        """Velocity of ``G`` relative to the table, space frame, vertical part included."""
        return self.forms.velocity(self.form_params, y)

    def height(self, y):
        """``z_G`` [m]: ``a - h cos(theta)`` on the table (the constraint); with flight, the
        state's."""
        return self.forms.height(self.form_params, y)

    def gap(self, y):
        """Height of the sphere's lowest point above the table [m]: ``z_G + h cos(theta) - a``
        (0 on the table; positive in flight)."""
        return self.forms.gap(self.form_params, y)

    def gap_rate(self, y):
        """``d gap / dt`` [m/s]: ``v_z + h d(cos theta)/dt``, ``d Gamma/dt = Gamma x Omega``."""
        if not self.flight:
            return 0.0 * y[0]
        rm = self.frame(y)
        w1, w2, _ = self.angular_velocity(y)
        return y[5] + self.params.height * (rm[6] * w2 - rm[7] * w1)

    def in_contact(self, y):
        """Whether the sphere is on the table (the contact flag; always true without flight)."""
        if not self.flight:
            return 0.0 * y[0] == 0.0
        return y[13] == 1.0

    # ------------------------------------------------------------------ contact
    def _contact(self, y, u):
        """The contact tuple of :class:`TippeForms` (``N``, friction, ``dOmega``, ...) at ``y``
        under ``u``.

        The last result is kept for the same ``y`` and ``u`` objects: a look at the contact
        force at a state (:meth:`contact_forces`, :meth:`constraint_normal_force`) and the
        vector field there (the next step's first stage of an integrator that calls :meth:`rhs`,
        as ``Integrator.step`` does) share one solve. A pure cache: same inputs, same outputs.
        (The envs' bound steps call ``kernel_rhs`` itself, and their lift-off checks
        ``kernel_normal``.)"""
        memo = self._memo
        if memo is not None and memo[0] is y and memo[1] is u:
            return memo[2]
        out = self._solve_contact(y, u)
        self._memo = (y, u, out)
        return out

    def _solve_contact(self, y, u):
        return self.forms.contact(self.form_params, y, u)

    # ------------------------------------------------------------------ vector field
    def rhs(self, y, u):
        """``dy/dt`` at ``y`` under ``u`` (``None``: a table at rest, the parameter's friction
        coefficient, no torque): ``kernel_rhs``, through the shared contact solve."""
        return self.forms.derivative(self.form_params, y, self._contact(y, u))

    def normalize(self, y):
        """The quaternion projected back onto the unit sphere; with flight, in contact, also
        ``(z, v_z)`` put on the constraint (``kernel_normalize``)."""
        return self.forms.normalize(self.form_params, y)

    # ------------------------------------------------------------------ free flight: switches
    def impact(self, y):
        """Touchdown of a state at the table (gap 0, approaching): a plastic, frictionless
        impact. The normal impulse ``lambda z_hat`` at the contact point ends the vertical motion
        of the contact point, ``lambda = -v_Pz / M_zz``, ``M_zz = 1/m + (r x Gamma).I^-1(r x
        Gamma)``; the energy drops by ``lambda^2 M_zz / 2`` and Jellett's integral ``-L.r`` is
        unchanged (``(r x Gamma).r = 0``). Returns the state in contact (``c = 1``) and ``lambda``
        [N s] (:func:`flight_impact`; one state of floats)."""
        return flight_impact(self.form_params, y)

    # ------------------------------------------------------------------ hybrid system
    # (rbenvs.contracts.HybridSystem) A contact that can open: without free flight a lift-off
    # ends the episode (the terminal event); with it the top flies and lands (the switches).
    hybrid = True
    # the optional capabilities (rbenvs.contracts.System): the Rosenbrock-W schemes' linear
    # solve (kernel_implicit, None with a stem); no exact sub-flows
    provides = frozenset({"implicit"})
    kernel_split_flows = None
    needs_projection = True  # (the quaternion)

    @property
    def switches(self) -> bool:
        """Whether the contact switches (free flight; the stem's and sphere's touchdowns) rather
        than ending the episode (with the stem a lift-off still ends it)."""
        return self.flight or self.stem

    def terminal_event(self):
        """``("lift_off", fn)``: the event that ends an episode, ``fn(y, u)`` true where the
        contact would have to pull (``N < 0``); ``None`` with free flight (the top flies)."""
        return None if self.flight else ("lift_off", self.lifts_off)

    def lifts_off(self, y, u):
        """Lift-off: the contact would have to pull (``N < 0``); a bool or a mask
        (``kernel_normal``, called directly: the step after it does not go through :meth:`rhs`)."""
        return self.forms.normal(self.form_params, y, u) < 0.0

    readout_names = (
        "energy",
        "jellett",
        "tilt",
        "normal_force",
        "slip_speed",
        "lifted_off",
        "airborne",
        "hops",
        "gap",
        "spin",
    )

    def readouts(self, y, u=None, fired=False) -> tuple:
        """The read-outs in :attr:`readout_names` order under the control ``u`` that acted
        (``None``: a table at rest; the normal force depends on it): energy, Jellett's
        integral, tilt, normal force, slip speed, ``lifted_off`` (with free flight: a hop so
        far; without: the lift-off that ended this period, ``fired``), ``airborne``, ``hops``,
        the gap to the table and the spin. Floats (``hops`` an int, the flags bools) or arrays
        (``kernel_readouts``)."""
        return self.forms.readouts(self.form_params, y, u, fired)

    start_draw_kinds = ""  # the system adds no numbers to a task's start (rbenvs.draws)

    def start_draws(self, rng):
        return draw(rng, self.start_draw_kinds)

    def complete_initial_state(self, y, d):
        """A task's start as it is."""
        return y

    kernel_complete = (start_as_drawn, ())  # the pure form of complete_initial_state

    def events(self, u):
        """The contact switches to watch after each internal step under control ``u``
        (:class:`rbenvs.contracts.HybridSystem`; located and applied by
        :mod:`rbenvs.core.hybrid`, which calls the integrator: the dynamics never does).

        * lift-off, from the table (``c = 1``): the constraint's normal force turns negative
          (located to ``|N| <= LIFT_OFF_TOL m g``); the state goes to flight (``c = 0``) and the
          hop count up by one. Locating it matters for the energy: past ``N = 0`` the friction
          law would push along the slip.
        * touchdown, in flight: the sphere's gap to the table turns negative (located to
          ``|gap| <= TOUCHDOWN_TOL a``); the state after the plastic :meth:`impact`.
        """
        if self.stem:
            p = self.form_params
            tol = STEM_TOL * min(self.params.radius, self.params.stem[0])

            def other_gap(z):
                return stem_other_gap(p, z, u)

            def switch(z):
                return stem_switch(p, z)

            return (
                Event("stem_touchdown", self.on_sphere, other_gap, tol, switch),
                Event("sphere_touchdown", self.on_stem, other_gap, tol, switch),
            )
        if not self.flight:
            return ()
        prm = self.params
        forms_normal, p = self.forms.normal, self.form_params

        def normal(z):  # (the pure normal force: after every internal step, no method between)
            return forms_normal(p, z, u)

        lift_off = Event(
            "lift_off", self.on_table, normal, LIFT_OFF_TOL * prm.mass * prm.gravity, self.take_off
        )
        touchdown = Event(
            "touchdown", self.airborne, self.gap, TOUCHDOWN_TOL * prm.radius, self.touch_down
        )
        return (lift_off, touchdown)

    @staticmethod
    def on_sphere(y) -> bool:
        """With the stem: whether the sphere presses (contact flag 0)."""
        return stem_on_sphere((), y)

    @staticmethod
    def on_stem(y) -> bool:
        """With the stem: whether the stem presses (contact flag 1)."""
        return stem_on_stem((), y)

    def stem_impact(self, y):
        """With the stem: the other contact's touchdown at ``y`` (its gap 0, approaching), a
        plastic frictionless impact: ``(state pressing on it, lambda [N s])``
        (:func:`stem_impact`; one state of floats)."""
        return stem_impact(self.form_params, y)

    def stem_jellett(self, y):
        """With the stem: its Jellett integral ``L.(b z_hat - d k)`` [kg m^2/s] (conserved while
        the stem alone presses)."""
        return stem_jellett(self.form_params, y)

    def other_gap(self, y):
        """With the stem: the gap [m] of the contact that does not press (the stem's while the
        sphere presses, the sphere's while the stem does)."""
        return stem_other_gap(self.form_params, y, None)

    @staticmethod
    def on_table(y) -> bool:
        return flight_on_table((), y)

    @staticmethod
    def airborne(y) -> bool:
        return flight_airborne((), y)

    @staticmethod
    def take_off(y):
        """The state at a lift-off: in flight, one more hop."""
        return flight_take_off((), y)

    def touch_down(self, y):
        """The state after a touchdown: the plastic impact's."""
        return self.impact(y)[0]

    def constraint_normal_force(self, y, u):
        """``N`` [N] the contact constraint asks for at ``y`` under ``u`` (negative: the table
        would have to pull; lift-off); 0 in flight (``kernel_normal``)."""
        return self._contact(y, u)[0]

    # ------------------------------------------------------------------ read-outs
    def contact_forces(self, y, u=None):
        """``(N, (Fx, Fy), slip_speed)``: normal force [N], friction in space [N] and the slip
        speed ``|v_P|`` [m/s] (0 when rolling)."""
        c = self._contact(y, u)
        return c[0], (c[1], c[2]), self.slip_speed(y)

    def slip_speed(self, y):
        """``|v_P|`` [m/s], the speed of the material point at the contact."""
        return self.forms.slip_speed(self.form_params, y)

    def energy(self, y):
        """Kinetic (translation + rotation about ``G``) plus potential ``m g z_G`` [J], table
        frame."""
        return self.forms.energy(self.form_params, y)

    def jellett(self, y):
        """``J = L . (a z_hat - h k)`` [kg m^2/s] [T 3.106], in the body frame
        ``L.(a Gamma - h e3)``."""
        return self.forms.jellett(self.form_params, y)

    def tilt(self, y):
        """``theta`` [rad] between the symmetry axis and the upward vertical (0 upright, pi
        inverted on the stem)."""
        return self.forms.tilt(self.form_params, y)

    def spin(self, y):
        """``Omega3`` [rad/s], the angular velocity about the symmetry axis."""
        return y[self._w + 2]

    # ------------------------------------------------------------------ state construction
    def state(self, position, attitude, angular_velocity, velocity=None):
        """Components from a horizontal position ``(x, y)`` [m], an attitude quaternion, the body
        angular velocity [rad/s] and the horizontal velocity of ``G`` [m/s] (``None``: the
        contact point at rest, ``v_G = -omega x r``; ignored when rolling, where it is always
        that)."""
        pos = tuple(position)[:2]
        v = None if velocity is None else tuple(velocity)[:2]
        return self.forms.state(
            self.form_params, pos[0], pos[1], tuple(attitude), tuple(angular_velocity), v
        )

    def no_slip_velocity(self, attitude, angular_velocity):
        """``v_G = -omega x r`` in space [m/s]: the velocity that puts the contact point at rest."""
        qw, qx, qy, qz = attitude
        w1, w2, w3 = angular_velocity
        rm = tippe_frame(qw, qx, qy, qz)
        v1, v2, v3 = rolling_velocity_body(self.form_params, rm, w1, w2, w3)
        return to_space(rm, v1, v2, v3)

    def export_state(self, y) -> dict:
        """Named arrays: ``position`` (3, with ``z_G`` from the constraint), ``velocity`` (3,
        space, table frame), ``attitude`` (4, w x y z, body to space), ``angular_velocity`` (3,
        body)."""
        o = self._q
        return {
            "position": np.array([y[0], y[1], self.height(y)], dtype=np.float64),
            "velocity": np.array(self.velocity(y), dtype=np.float64),
            "attitude": np.array(y[o : o + 4], dtype=np.float64),
            "angular_velocity": np.array(y[o + 4 : o + 7], dtype=np.float64),
        }

    def import_state(self, state: dict) -> tuple:
        """Components from :meth:`export_state`'s dict, checked against the contact constraint:
        ``z_G = a - h cos(theta)``, ``v_z`` (and, rolling, the whole velocity) as the attitude and
        angular velocity require. ``ValueError`` naming the entry otherwise."""
        names = ("position", "velocity", "attitude", "angular_velocity")
        if not isinstance(state, dict):
            raise ValueError(
                f"options['state'] must be a dict of named arrays, got {type(state).__name__}"
            )
        unknown, missing = sorted(set(state) - set(names)), sorted(set(names) - set(state))
        if unknown or missing:
            raise ValueError(
                f"state must have exactly the names {sorted(names)}"
                + (f"; unknown: {unknown}" if unknown else "")
                + (f"; missing: {missing}" if missing else "")
            )
        arrs = {}
        for name, size in zip(names, (3, 3, 4, 3)):
            arr = real_array(f"state[{name!r}]", state[name])
            if arr.shape != (size,):
                raise ValueError(f"state[{name!r}] must have shape ({size},), got {arr.shape}")
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"state[{name!r}] must be finite, got {arr}")
            arrs[name] = arr
        qn = float(np.linalg.norm(arrs["attitude"]))
        if abs(qn - 1.0) > 1e-6:
            raise ValueError(
                f"state['attitude'] must be a unit quaternion (|q| = 1 within 1e-6), got |q| = {qn}"
            )
        q = tuple(float(c) for c in arrs["attitude"])
        w = tuple(float(c) for c in arrs["angular_velocity"])
        pos = tuple(float(c) for c in arrs["position"])
        vel = tuple(float(c) for c in arrs["velocity"])
        y = self.state(pos, q, w, vel[:2])
        prm = self.params
        if self.flight:
            return self._place_flight_state(y, pos, vel)
        if self.stem:  # on the stem where its constraint's height is the one given
            on_stem = y[:11] + (1.0,)
            if (
                abs(pos[2] - self.height(on_stem)) <= 1e-9 * prm.radius + 1e-12
                and self.other_gap(on_stem) >= 0.0
            ):
                y = on_stem
        z = self.height(y)
        if abs(pos[2] - z) > 1e-9 * prm.radius + 1e-12:
            raise ValueError(
                f"state['position'][2] must be the contact height a - h cos(theta) = {z!r} m for "
                f"this attitude (the sphere touches the table), got {pos[2]!r}"
            )
        v_need = self.velocity(y)
        scale = 1e-9 * (1.0 + prm.radius * float(np.linalg.norm(w)))
        checked = range(3) if self.rolling else (2,)
        for i in checked:
            if abs(vel[i] - v_need[i]) > scale:
                what = (
                    "the rolling velocity -omega x r"
                    if self.rolling
                    else "the vertical velocity the contact constraint gives"
                )
                raise ValueError(
                    f"state['velocity'] must equal {what} ({list(v_need)}), got {list(vel)}"
                )
        return y

    def _place_flight_state(self, y, pos, vel):
        """With flight: the given height and vertical velocity, classified. On the table (gap
        within round-off of 0, not approaching faster than round-off): in contact, ``v_z`` must
        be the constraint's; above it: in flight; below it: refused."""
        prm = self.params
        tol = 1e-9 * prm.radius + 1e-12
        air = y[:2] + (pos[2],) + y[3:5] + (vel[2],) + y[6:13] + (0.0, 0.0)
        gap = self.gap(air)
        if gap < -tol:
            raise ValueError(
                f"state['position'][2] puts the sphere {-gap!r} m into the table (z_G must be >= a "
                f"- h cos(theta) = {pos[2] - gap!r} m)"
            )
        if gap > tol:
            return air
        v_need = self.velocity(y)[2]  # y is on the table: the constraint's v_z
        scale = 1e-9 * (1.0 + prm.radius * float(np.linalg.norm(y[10:13])))
        if vel[2] - v_need > scale:  # on the table and leaving it: in flight
            return air
        if abs(vel[2] - v_need) > scale:
            raise ValueError(
                "state['velocity'][2] must be the vertical velocity the contact constraint gives "
                f"({v_need!r}) or above it (leaving the table), got {vel[2]!r}"
            )
        return y

    # ------------------------------------------------------------------ step guard
    # Near zero slip regularised Coulomb friction is a viscous law of rate mu N |M| / eps (viscous:
    # mu N |M|), |M| the contact mobility: stiff, a decaying (negative real) rate. The guard takes
    # twice the larger of m g and the current N (N varies within a control period) and keeps half
    # of the scheme's real-axis interval (FRICTION_MARGIN).
    def friction_stiffness(self, mu, normal_force=None):
        """``lambda_d`` [1/s]: the friction law's stiffness (:mod:`rbenvs.dynamics.contact`) at
        twice ``max(m g, N)`` and the contact mobility ``|M|`` (Coulomb: ``mu 2 max(m g, N) |M|
        / eps``); 0 without friction. ``mu`` and ``normal_force`` may be arrays (a batch)."""
        if self.friction is None:
            return 0.0
        prm = self.params
        weight = prm.mass * prm.gravity
        load = weight if normal_force is None else np.maximum(weight, normal_force)
        return self.friction.stiffness(
            mu, 2.0 * load, prm.contact_mobility(), prm.slip_regularization
        )

    def guard_rates(self, region, speed_ceiling: float = math.inf) -> GuardRates:
        """The contact geometry turns with the body: ``max(|Omega|, omega_g) h <= SPIN_STEP``
        (0.1 rad, an accuracy bound of this system for every scheme; ``omega_g`` from
        :meth:`TippeTopParams.gravity_rate`), and, with friction, ``h <= c / lambda_d``
        (:meth:`friction_stiffness`) with ``c`` half the scheme's real-axis interval (euler
        1.0, rk4 1.39; none for dop853). With ``friction_bound="accuracy"``: ``lambda_a =
        max(lambda_d, K sqrt(lambda_d w))`` (``K`` the law's ``accuracy_scale``;
        :func:`implicit_forms`'
        ``accuracy_rate``; ``lambda_d`` the tight rate: the law's stiffness at the actual ``N`` and
        the largest mobility along the table; ``w = max(|Omega|, omega_g)``) and ``c``
        ``ACCURACY_MARGIN`` of the interval (rk4 1.25); a law without a slope (no ``implicit``)
        keeps the stability bound."""
        omega_g = self.params.gravity_rate()
        dissipation = (
            (self.forms.friction_rate, self.form_params) if self.friction_law is not None else None
        )
        margin = FRICTION_MARGIN
        text = f"lambda = max(|Omega|, omega_g) (omega_g = {omega_g:.6g} rad/s)"
        if (
            dissipation is not None
            and self.friction_bound == "accuracy"
            and self.implicit is not None
            and self.implicit.accuracy_rate is not None
        ):
            dissipation = (
                self.implicit.accuracy_rate,
                (self.form_params, self.friction.accuracy_scale, omega_g),
            )
            margin = ACCURACY_MARGIN
            text += (
                f", lambda_d = the {self.friction_law} law's stiffness at N and the mobility "
                "along the table (friction_bound='accuracy')"
            )
        elif dissipation is not None:
            text += f", lambda_d = the {self.friction_law} law's stiffness at 2 max(m g, N)"
        share = None
        if (
            dissipation is not None
            and self.implicit is not None
            and self.implicit.share is not None
        ):
            share = (
                self.implicit.share,
                (self.form_params, omega_g),
            )  # (the tolerance's relaxation share)
        # tolerance=: the error is measured on v_G and Omega (the horizontal position drifts, the
        # contact flags are not measured), and the attitude turns at |Omega| / 2, integrating Omega
        # (motion_rates)
        measured = tuple(n for n in ("velocity", "angular_velocity") if n in self.layout)
        return GuardRates(
            rotation=(tippe_rotation_rate, (self._w, omega_g)),
            rotation_bound=SPIN_STEP,
            dissipation=dissipation,
            dissipation_margin=margin,
            ceiling=max(speed_ceiling, omega_g),
            text=text,
            dissipation_share=share,
            error_blocks=measured,
            rotating_blocks=(("attitude", "angular_velocity"),),
        )

    def max_stable_step(
        self, region, mu: float | None = None, normal_force: float | None = None
    ) -> float:
        """The largest internal step [s] at which the friction law is stable for a scheme of
        ``region`` (a :class:`~rbenvs.contracts.StepRegion`, or an integrator declaring one):
        ``c / lambda_d``, ``c`` =
        ``FRICTION_MARGIN`` of its real-axis interval (euler ``h lambda <= 2``: ``c = 1``; rk4
        2.78: ``c = 1.39``), ``lambda_d`` from :meth:`friction_stiffness` at ``mu`` (default:
        the parameter's) and ``normal_force`` (default ``m g``). ``inf`` without friction, when
        rolling, and for schemes without a real-axis bound (dop853). Arrays in, array out."""
        if not isinstance(region, StepRegion):  # an integrator: its region
            region = region.region
        c = FRICTION_MARGIN * region.dissipation
        if self.friction_law is None or c == math.inf:
            return math.inf
        rate = self.friction_stiffness(self.params.friction if mu is None else mu, normal_force)
        with np.errstate(divide="ignore"):
            bound = np.where(rate > 0.0, c / np.where(rate > 0.0, rate, 1.0), np.inf)
        return float(bound) if bound.ndim == 0 else bound

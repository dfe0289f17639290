"""The tippe top as a system (:class:`rbenvs.contracts.HybridSystem`): :class:`TippeTop`."""

from __future__ import annotations

from ...contracts import GuardRates
from ...draws import draw
from ..state import start_as_drawn
from .derived import DERIVED, derived_parts
from .forms import (
    contact_arm,
    flight_airborne,
    flight_impact,
    flight_on_table,
    flight_take_off,
    rolling_velocity_body,
    tippe_frame,
    to_space,
)
from .guard import friction_stiffness, guard_rates, max_stable_step
from .params import (
    LIFT_OFF_TOL,
    TOUCHDOWN_TOL,
    Event,
    TippeTopParams,
)
from .states import export_state, import_state, require_fidelity, state_layout
from .stem import (
    STEM_TOL,
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
        require_fidelity(fidelity, friction_bound, bool(flight), params.stem is not None)
        self.friction_bound, self.fidelity = friction_bound, fidelity
        self.rolling, self.flight, self.stem = (
            fidelity == "rolling",
            bool(flight),
            params.stem is not None,
        )
        self.layout, self.dim = state_layout(self.stem, self.flight, self.rolling)
        self._w = self.layout["angular_velocity"][0]
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
        self.__dict__.update(
            derived_parts(params, self.fidelity, self.rolling, self.flight, self.stem)
        )

    def __getstate__(self):
        state = {k: v for k, v in self.__dict__.items() if k not in DERIVED}
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
        body) (:func:`rbenvs.dynamics.tippe_top.states.export_state`)."""
        return export_state(self, y)

    def import_state(self, state: dict) -> tuple:
        """Components from :meth:`export_state`'s dict, checked against the contact constraint
        (:func:`rbenvs.dynamics.tippe_top.states.import_state`); ``ValueError`` naming the entry
        otherwise."""
        return import_state(self, state)

    # ------------------------------------------------------------------ step guard
    def friction_stiffness(self, mu, normal_force=None):
        """``lambda_d`` [1/s]: the friction law's stiffness at twice ``max(m g, N)`` and the
        contact mobility (:func:`rbenvs.dynamics.tippe_top.guard.friction_stiffness`); 0 without
        friction. ``mu`` and ``normal_force`` may be arrays (a batch)."""
        return friction_stiffness(self, mu, normal_force)

    def guard_rates(self, region, speed_ceiling: float, dt: float) -> GuardRates:
        """The rates a step must resolve for ``region`` in periods of ``dt``
        (:func:`rbenvs.dynamics.tippe_top.guard.guard_rates`)."""
        return guard_rates(self, region, speed_ceiling, dt)

    def max_stable_step(self, region, mu=None, normal_force=None):
        """The largest internal step [s] at which the friction law is stable for a scheme of
        ``region`` (:func:`rbenvs.dynamics.tippe_top.guard.max_stable_step`)."""
        return max_stable_step(self, region, mu, normal_force)

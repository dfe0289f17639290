"""Tasks on the tippe top: initial states, observation, reward, termination.

Both tasks observe, in the space (table) frame, the symmetry axis ``k`` (3 numbers in
[-1, 1]; ``k_z = cos(theta)``), the angular velocity ``omega`` [rad/s] and the horizontal
velocity of the centre of mass [m/s]: 8 numbers. The table's acceleration, the action, is a
space-frame vector, so the observation is too. With the position (irrelevant: the table is
uniform) and the turn about ``k`` (irrelevant: the body is symmetric) left out, this is the
Markov state.

Observation and reward are pure functions of the system's pure forms (:func:`observation_form`,
:func:`invert_form`, :func:`hold_form`): the tasks' methods call them on floats or arrays, and
compiled code can call them on floats (:meth:`InvertTask.kernels`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import numpy as np

from ..dynamics.tippe_top import tippe_frame, vertical_tilt
from ..dynamics.validation import did_you_mean
from ..jit import jitable
from ..rotations import quat_multiply
from .common import TwoStageStart, effort

__all__ = [
    "InvertTask",
    "HoldTask",
    "STARTS",
    "tilted_spin_state",
    "unit_component",
    "observation_form",
    "invert_form",
    "hold_form",
]


# The starts (docs/physics.md §3, "Starts"): how a top is spun before it is let go.
# "rolling": the contact point at rest (v_G = -omega x r), spin about the symmetry axis;
# "rest": the centre of mass at rest, spin about the symmetry axis, so the contact point slips
# at first: a top spun by hand, the start of Leine and Glocker (2003) and most numerical studies;
# "vertical": the centre of mass at rest, spin about the space vertical.
STARTS = ("rolling", "rest", "vertical")


def tilted_spin_state(system, d, spin_low, spin_high, tilt_low, tilt_high, start="rolling"):
    """Spin ``n ~ U(spin)`` at tilt ``theta ~ U(tilt)`` at a uniform azimuth and heading, as
    ``start`` says (:data:`STARTS`), from the uniforms ``d`` on [0, 1) (floats or rows of a
    batch: tilt, azimuth, heading, spin)."""
    fn, p = spun_start(system, spin_low, spin_high, tilt_low, tilt_high, start)
    return fn(p, d)


def spun_start(system, spin_low, spin_high, tilt_low, tilt_high, start="rolling") -> tuple:
    """``(start, P)``: the pure form of :func:`tilted_spin_state` for ``system``'s layout."""
    if start not in STARTS:
        raise ValueError(
            f"start must be one of {list(STARTS)}, got {start!r}{did_you_mean(start, STARTS)}"
        )
    form = spun_start_form(system.forms.state, start != "rolling", start == "vertical")
    return form, (
        system.form_params,
        float(spin_low),
        float(spin_high),
        float(tilt_low),
        float(tilt_high),
    )


@cache
def spun_start_form(state, at_rest: bool = False, about_vertical: bool = False):
    """``start(P, d)`` of :func:`tilted_spin_state` on the system's pure ``state`` builder:
    ``at_rest``, the centre of mass at rest (else the contact point); ``about_vertical``, the
    angular velocity along the space vertical (else the symmetry axis). Both are constants of
    the function (compiled code keeps the branch that applies)."""

    @jitable
    def start(p, d):
        form_params, spin_low, spin_high, tilt_low, tilt_high = p
        theta = tilt_low + (tilt_high - tilt_low) * d[0]
        phi = 0.0 + 2.0 * np.pi * d[1]
        psi = 0.0 + 2.0 * np.pi * d[2]
        n = spin_low + (spin_high - spin_low) * d[3]
        zero = 0.0 * theta
        qz1 = (np.cos(0.5 * phi), zero, zero, np.sin(0.5 * phi))
        qx = (np.cos(0.5 * theta), np.sin(0.5 * theta), zero, zero)
        qz2 = (np.cos(0.5 * psi), zero, zero, np.sin(0.5 * psi))
        q = quat_multiply(quat_multiply(qz1, qx), qz2)  # R = Rz(phi) Rx(theta) Rz(psi)
        if about_vertical:
            rm = tippe_frame(q[0], q[1], q[2], q[3])
            w = (n * rm[6], n * rm[7], n * rm[8])  # R^T e3 n: the vertical in the body
        else:
            w = (zero, zero, n)
        if at_rest:
            return state(form_params, zero, zero, q, w, (zero, zero))
        return state(form_params, zero, zero, q, w)

    return start


@jitable
def unit_component(c):
    """A component of a unit vector, clamped to [-1, 1]: ``1 - 2 (x^2 + y^2)`` from a
    quaternion normalised to round-off can be ``-1 - 4e-16`` at tilt pi, which the observation
    bound of exactly 1 would report as an observation limit. (A NaN stays NaN.)"""
    if isinstance(c, float):
        return 1.0 if c > 1.0 else (-1.0 if c < -1.0 else c)
    return _unit_component_arrays(c)


@jitable  # (registered so that compiled code can name it; it only ever runs on arrays)
def _unit_component_arrays(c):
    return np.clip(c, -1.0, 1.0)


# The tasks' arithmetic as pure functions of (parameters, state[, action]), made once per layout
# of the system (its pure ``frame``, ``angular_velocity`` and ``velocity``: constants of the
# functions, as compiled code needs them). ``P`` is the system's (TippeTop.form_params).
@cache
def observation_form(frame, angular_velocity, velocity):
    """``observe(P, y)``: the symmetry axis ``k`` (clamped), ``omega`` in space and the horizontal
    velocity of ``G`` (8 components), from the system's pure state functions."""

    @jitable
    def observe(p, y):
        rm = frame(p, y)
        w1, w2, w3 = angular_velocity(p, y)
        v = velocity(p, y)
        return (
            unit_component(rm[2]),
            unit_component(rm[5]),
            unit_component(rm[8]),
            rm[0] * w1 + rm[1] * w2 + rm[2] * w3,
            rm[3] * w1 + rm[4] * w2 + rm[5] * w3,
            rm[6] * w1 + rm[7] * w2 + rm[8] * w3,
            v[0],
            v[1],
        )

    return observe


@cache
def invert_form(frame):
    """``evaluate(PE, y, u_norm) -> (reward, terminated, is_success)`` of :class:`InvertTask`,
    ``PE = (P, control_cost, goal_tilt)``."""

    @jitable
    def evaluate(pe, y, u):
        p, control_cost, goal_tilt = pe
        rm = frame(p, y)
        done = vertical_tilt(rm[6], rm[7], rm[8]) > goal_tilt
        return -0.5 * (1.0 + rm[8]) - control_cost * effort(u), done, done

    return evaluate


@cache
def hold_form(frame):
    """``evaluate(PE, y, u_norm) -> (reward, terminated, is_success)`` of :class:`HoldTask`,
    ``PE = (P, control_cost, fall_tilt, success_tilt)``."""

    @jitable
    def evaluate(pe, y, u):
        p, control_cost, fall_tilt, success_tilt = pe
        rm = frame(p, y)
        tilt = vertical_tilt(rm[6], rm[7], rm[8])
        return 0.5 * (1.0 + rm[8]) - control_cost * effort(u), tilt > fall_tilt, tilt < success_tilt

    return evaluate


def observe(system, y):
    """The observation of the tippe-top tasks at ``y`` (floats or arrays)."""
    forms = system.forms
    return observation_form(forms.frame, forms.angular_velocity, forms.velocity)(
        system.form_params, y
    )


class _SpunTop(TwoStageStart):
    """Start and observation shared by the tippe-top tasks (fields ``spin_low``, ``spin_high``,
    ``tilt_low``, ``tilt_high`` of the dataclass)."""

    observation_size = 8
    observation_names = ("k_x", "k_y", "k_z", "omega_x", "omega_y", "omega_z", "v_x", "v_y")
    observation_units = ("1",) * 3 + ("rad/s",) * 3 + ("m/s",) * 2
    metric_names = ("is_success",)
    final_measure = "tilt"

    draw_kinds = "uuuu"  # tilt, azimuth, heading, spin

    def kernel_start(self, system):
        """``(start, P)``: the pure form of :meth:`initial_from_draws`
        (:func:`tilted_spin_state`)."""
        return spun_start(
            system, self.spin_low, self.spin_high, self.tilt_low, self.tilt_high, self.start
        )

    def observe(self, system, y):
        return observe(system, y)

    def kernels(self, system):
        """``((observe, P), (evaluate, PE))``: the pure forms of :meth:`observe` and
        :meth:`evaluate` for this system (:class:`rbenvs.contracts.Task`)."""
        forms = system.forms
        observe_fn = observation_form(forms.frame, forms.angular_velocity, forms.velocity)
        return (observe_fn, system.form_params), (
            self._form(forms.frame),
            self._evaluate_params(system),
        )

    def evaluate(self, system, y, u):
        """``(reward, terminated, metrics)`` with the tilt computed once."""
        reward, terminated, success = self._form(system.forms.frame)(
            self._evaluate_params(system), y, u
        )
        return reward, terminated, {"is_success": success}


@dataclass(frozen=True)
class InvertTask(_SpunTop):
    """Turn the top onto its stem as fast as possible.

    * Start: spin ``n ~ U(spin_low, spin_high)`` at tilt ``U(tilt_low, tilt_high)``, as
      ``start`` says (:data:`STARTS`: ``"rolling"``, the contact point at rest, spin about the
      symmetry axis; ``"rest"``, the centre of mass at rest; ``"vertical"``, the centre of mass
      at rest and the spin about the space vertical).
    * Reward: ``-(1 + cos(theta)) / 2 - control_cost * mean(u^2)`` per step, in [-1, 0]: 0
      only once inverted, so the return counts the time spent getting there (weighted by how
      far from inverted). Time, not dissipated energy, because the energy left at the end is
      fixed by Jellett's integral (the top ends near the minimum ``E*(pi)`` whatever the path),
      so the least dissipated energy is nearly the same for every policy; the time to invert is
      what varies, and what is measured in the literature (docs/physics.md §3).
    * Terminates (success) when ``theta > goal_tilt`` (150 degrees: the last part of the climb
      slows with the slip speed under regularised Coulomb friction, docs/physics.md §3).
    """

    spin_low: float
    spin_high: float
    tilt_low: float
    tilt_high: float
    control_cost: float
    goal_tilt: float = math.radians(150.0)
    start: str = "rolling"

    name = "invert"
    # the top inverts by itself: no action is the reference (an analytic law that inverts
    # faster is an open problem here)
    controller = "ZeroController"

    _form = staticmethod(invert_form)

    def _evaluate_params(self, system):
        return (system.form_params, float(self.control_cost), float(self.goal_tilt))

    def reward_floor(self, system, observation_high) -> float:
        """The least reward of a step: upright (on the broad end) at full effort."""
        return -1.0 - float(self.control_cost)


@dataclass(frozen=True)
class HoldTask(_SpunTop):
    """Keep the top spinning on its broad end, against its own tendency to invert.

    * Start: as :class:`InvertTask`.
    * Reward: ``(1 + cos(theta)) / 2 - control_cost * mean(u^2)`` per step, in [0, 1].
    * Terminates (failure) when ``theta > fall_tilt`` (90 degrees: past the equator the top
      is on its way over). Success: ``theta < success_tilt``.
    """

    spin_low: float
    spin_high: float
    tilt_low: float
    tilt_high: float
    control_cost: float
    fall_tilt: float = math.pi / 2
    success_tilt: float = 0.2
    start: str = "rolling"

    name = "hold"
    controller = "SlipCancelling"

    _form = staticmethod(hold_form)

    def _evaluate_params(self, system):
        return (
            system.form_params,
            float(self.control_cost),
            float(self.fall_tilt),
            float(self.success_tilt),
        )

    def reward_floor(self, system, observation_high) -> float:
        """The least reward of a step: inverted at full effort."""
        return -float(self.control_cost)

"""Tasks on the free rigid body: initial states, observation, reward, termination.

A task never integrates anything: it reads the state components (floats for one env, arrays
for a batch) through the system's read-outs and returns components. Rewards are per control
step; ``u`` is the normalised action on every axis (``0`` on unactuated ones), in ``[-1, 1]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..dynamics.free_body import angular_velocity, momentum_norm
from ..jit import jitable
from ..rotations import quat_angle, quat_conjugate, quat_from_uniforms, quat_multiply, select, sqrt
from .common import TwoStageStart, effort, speed_bound

__all__ = [
    "SpinTask",
    "DetumbleTask",
    "ReorientTask",
    "AXIS_NAMES",
    "spin_evaluate",
    "detumble_evaluate",
    "attitude_error",
    "reorient_observe",
    "reorient_evaluate",
]

AXIS_NAMES = ("major", "intermediate", "minor")


# Initial states: two stages (rbenvs.tasks.common.TwoStageStart). The arithmetic from a start's
# draws ``d`` as pure functions ``start(P, d)`` (floats, rows of a batch, compiled restarts).
@jitable
def _directions(n0, n1, n2):
    """Unit vectors along normal deviates (a uniform direction)."""
    norm = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    return n0 / norm, n1 / norm, n2 / norm


@jitable
def spin_start(p, d):
    """Spin ``p[1] = I_axis * spin_rate`` about a direction at a polar angle uniform in ``[0,
    perturbation]`` from body axis ``p[0]``, azimuth uniform; ``d = (tilt, azimuth)`` uniforms."""
    axis, momentum, perturbation = p
    theta = 0.0 + perturbation * d[0]  # polar angle uniform in [0, perturbation]
    phi = 0.0 + 2.0 * np.pi * d[1]  # azimuth uniform
    st = np.sin(theta)
    x, y, z = st * np.cos(phi), st * np.sin(phi), np.cos(theta)
    # the spin axis gets z, the next two axes (cyclically) x and y
    if axis == 0:
        return momentum * z, momentum * x, momentum * y
    if axis == 1:
        return momentum * y, momentum * z, momentum * x
    return momentum * x, momentum * y, momentum * z


@jitable
def detumble_start(p, d):
    """``Pi = I Omega``, ``Omega = spin_rate (0.5 + 0.5 d[3]) n``, ``n`` along the normals
    ``d[0:3]``; ``p = (inertia, spin_rate)``."""
    inertia, spin_rate = p
    n = _directions(d[0], d[1], d[2])
    s = spin_rate * (0.5 + 0.5 * d[3])
    return inertia[0] * s * n[0], inertia[1] * s * n[1], inertia[2] * s * n[2]


@jitable
def reorient_start(p, d):
    """A uniform attitude from ``d[0:3]`` (Shoemake) and ``Omega = spin_rate (0.1 d[6]) n``,
    ``n`` along the normals ``d[3:6]``; ``p = (inertia, spin_rate)``."""
    inertia, spin_rate = p
    q = quat_from_uniforms(d[0], d[1], d[2])
    n = _directions(d[3], d[4], d[5])
    s = spin_rate * (0.0 + 0.1 * d[6])
    return (
        inertia[0] * s * n[0],
        inertia[1] * s * n[1],
        inertia[2] * s * n[2],
        q[0],
        q[1],
        q[2],
        q[3],
    )


# The tasks' arithmetic as pure functions of (parameters, state, action): the methods below
# call them on floats or arrays, the compiled batch kernel (rbenvs.compiled) on floats.
# ``evaluate`` returns ``(reward, terminated, *metrics)`` in the order of ``metric_names``.
@jitable
def spin_alignment(axis, y):
    # + 1e-300 keeps Pi = 0 (a full despin) finite without changing any normal value
    return y[axis] / (momentum_norm(y) + 1e-300)


@jitable
def spin_evaluate(p, y, u):
    axis, control_cost, cos_success = p
    a = spin_alignment(axis, y)
    return a - control_cost * effort(u), False, a, a >= cos_success


@jitable
def angular_speed(inv, y):
    w = angular_velocity(inv, y)
    return sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])


@jitable
def detumble_evaluate(p, y, u):
    inv, spin_rate, control_cost, tolerance = p
    s = angular_speed(inv, y)
    done = s < tolerance * spin_rate
    return -s / spin_rate - control_cost * effort(u), done, s, done


@jitable
def attitude_error(target, y):
    """The error quaternion ``conj(target) * q`` of ``y = (Pi, q)``, its sign chosen so that
    ``w >= 0`` (``q`` and ``-q`` are one attitude)."""
    e = quat_multiply(quat_conjugate(target), (y[3], y[4], y[5], y[6]))
    sign = select(e[0] < 0.0, -1.0, 1.0)
    return (sign * e[0], sign * e[1], sign * e[2], sign * e[3])


@jitable
def reorient_observe(p, y):
    """``(Omega, error quaternion)``; ``p = (inverse moments, target)``."""
    inv, target = p
    return angular_velocity(inv, y) + attitude_error(target, y)


@jitable
def reorient_evaluate(p, y, u):
    """``(reward, terminated, attitude_error, is_success)``; ``p = (inverse, target, spin_rate,
    rate_cost, control_cost, success_angle)``."""
    inv, target, spin_rate, rate_cost, control_cost, success_angle = p
    angle = quat_angle(attitude_error(target, y))
    speed = angular_speed(inv, y)
    reward = -angle / math.pi - rate_cost * speed / spin_rate - control_cost * effort(u)
    return reward, False, angle, (angle < success_angle) & (speed < success_angle * spin_rate)


@dataclass(frozen=True)
class SpinTask(TwoStageStart):
    """Hold the rotation about principal axis ``axis`` (an index 0, 1, 2).

    * Start: ``Pi = I_axis spin_rate n`` with ``n`` tilted from ``+e_axis`` by an angle uniform in
      ``[0, perturbation]`` (azimuth uniform).
    * Observation: body angular velocity ``Omega`` [rad/s].
    * Reward: alignment ``Pi_axis / |Pi|`` (in [-1, 1]) minus ``control_cost * mean(u^2)``.
    * Success: alignment >= ``cos(success_angle)``. No termination of its own.
    """

    axis: int
    spin_rate: float
    perturbation: float
    control_cost: float
    success_angle: float = 0.1

    name = "spin"
    needs_attitude = False
    observation_size = 3
    observation_names = ("Omega1", "Omega2", "Omega3")
    observation_units = ("rad/s",) * 3
    final_measure = "alignment"
    controller = "SpinLQR"

    draw_kinds = "uu"  # tilt and azimuth of the spin direction

    def kernel_start(self, system):
        """``(spin_start, P)``: the pure form of :meth:`initial_from_draws`."""
        return spin_start, (
            int(self.axis),
            system.params.inertia[self.axis] * self.spin_rate,
            float(self.perturbation),
        )

    metric_names = ("alignment", "is_success")

    def observe(self, system, y):
        return system.angular_velocity(y)

    def evaluate(self, system, y, u):
        """``(reward, terminated, metrics)`` with the alignment computed once."""
        reward, terminated, a, success = spin_evaluate(self._params, y, u)
        return reward, terminated, {"alignment": a, "is_success": success}

    def kernels(self, system):
        """``((observe, P), (evaluate, P))`` for :mod:`rbenvs.compiled`."""
        return (angular_velocity, system.params.inverse), (spin_evaluate, self._params)

    def reward_floor(self, system, observation_high) -> float:
        """The least reward of a step: alignment -1 at full effort."""
        return -1.0 - float(self.control_cost)

    def __post_init__(self):
        object.__setattr__(self, "cos_success", math.cos(self.success_angle))
        object.__setattr__(
            self, "_params", (int(self.axis), float(self.control_cost), self.cos_success)
        )


@dataclass(frozen=True)
class DetumbleTask(TwoStageStart):
    """Bring the angular velocity to zero.

    * Start: ``Omega = spin_rate * s * n``, ``n`` a uniform random direction, ``s ~ U(0.5, 1)``.
    * Observation: ``Omega`` [rad/s].
    * Reward: ``-|Omega| / spin_rate - control_cost * mean(u^2)`` (<= 0, so ending early pays).
    * Terminates (success) when ``|Omega| < tolerance * spin_rate``.
    """

    spin_rate: float
    control_cost: float
    tolerance: float = 0.01

    name = "detumble"
    needs_attitude = False
    observation_size = 3
    observation_names = ("Omega1", "Omega2", "Omega3")
    observation_units = ("rad/s",) * 3
    final_measure = "angular_speed"
    controller = "DetumbleDamping"

    draw_kinds = "nnnu"  # direction, speed

    def kernel_start(self, system):
        """``(detumble_start, P)``: the pure form of :meth:`initial_from_draws`."""
        return detumble_start, (
            tuple(float(c) for c in system.params.inertia),
            float(self.spin_rate),
        )

    metric_names = ("angular_speed", "is_success")

    def observe(self, system, y):
        return system.angular_velocity(y)

    def evaluate(self, system, y, u):
        """``(reward, terminated, metrics)`` with the speed computed once."""
        reward, done, s, success = detumble_evaluate(self._params(system), y, u)
        return reward, done, {"angular_speed": s, "is_success": success}

    def kernels(self, system):
        """``((observe, P), (evaluate, P))`` for :mod:`rbenvs.compiled`."""
        return (angular_velocity, system.params.inverse), (detumble_evaluate, self._params(system))

    def reward_floor(self, system, observation_high) -> float:
        """The least reward of a step inside the observation bounds, at full effort."""
        return -speed_bound(self, observation_high) / float(self.spin_rate) - float(
            self.control_cost
        )

    def _params(self, system):
        return (
            system.params.inverse,
            float(self.spin_rate),
            float(self.control_cost),
            float(self.tolerance),
        )


@dataclass(frozen=True)
class ReorientTask(TwoStageStart):
    """Reach the target attitude ``target`` (unit quaternion, body -> space) and stay there.

    The one free-body task that carries the attitude quaternion.

    * Start: attitude uniform on SO(3); ``Omega = spin_rate * s * n`` with ``s ~ U(0, 0.1)``.
    * Observation: ``Omega`` [rad/s] and the error quaternion ``conj(target) * q`` with its
      sign chosen so that ``w >= 0`` (4 numbers in [-1, 1]).
    * Reward: ``-angle/pi - rate_cost * |Omega| / spin_rate - control_cost * mean(u^2)``,
      ``angle`` in [0, pi] the rotation angle of the error.
    * Success: angle < ``success_angle`` and ``|Omega| < success_angle * spin_rate``.
    """

    target: tuple[float, float, float, float]
    spin_rate: float
    control_cost: float
    rate_cost: float = 0.1
    success_angle: float = 0.05

    name = "reorient"
    needs_attitude = True
    observation_size = 7
    observation_names = ("Omega1", "Omega2", "Omega3", "error_w", "error_x", "error_y", "error_z")
    observation_units = ("rad/s",) * 3 + ("1",) * 4
    metric_names = ("attitude_error", "is_success")
    final_measure = "attitude_error"
    controller = "ReorientPD"

    draw_kinds = "uuunnnu"  # attitude, direction of Omega, speed

    def kernel_start(self, system):
        """``(reorient_start, P)``: the pure form of :meth:`initial_from_draws`."""
        return reorient_start, (
            tuple(float(c) for c in system.params.inertia),
            float(self.spin_rate),
        )

    def error(self, y):
        """The error quaternion (:func:`attitude_error`)."""
        return attitude_error(self._target, tuple(y))

    def observe(self, system, y):
        return reorient_observe((system.params.inverse, self._target), tuple(y))

    def evaluate(self, system, y, u):
        """``(reward, terminated, metrics)`` with the angle and speed computed once."""
        reward, terminated, angle, success = reorient_evaluate(self._params(system), tuple(y), u)
        return reward, terminated, {"attitude_error": angle, "is_success": success}

    def kernels(self, system):
        """``((observe, P), (evaluate, P))`` for :mod:`rbenvs.compiled`."""
        return (reorient_observe, (system.params.inverse, self._target)), (
            reorient_evaluate,
            self._params(system),
        )

    def reward_floor(self, system, observation_high) -> float:
        """The least reward of a step inside the observation bounds: upside down (angle pi) at
        the bound's speed, at full effort."""
        return (
            -1.0
            - float(self.rate_cost) * speed_bound(self, observation_high) / float(self.spin_rate)
            - float(self.control_cost)
        )

    def _params(self, system):
        return (
            system.params.inverse,
            self._target,
            float(self.spin_rate),
            float(self.rate_cost),
            float(self.control_cost),
            float(self.success_angle),
        )

    def __post_init__(self):
        object.__setattr__(self, "_target", tuple(float(c) for c in self.target))

"""Tasks on the free rigid body: initial states, observation, reward, termination.

A task never integrates anything: it reads the state components (floats for one env, arrays
for a batch) through the system's read-outs and returns components. Rewards are per control
step; ``u`` is the normalised action on every axis (``0`` on unactuated ones), in ``[-1, 1]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..rotations import quat_angle, quat_conjugate, quat_multiply, quat_random, sqrt

__all__ = ["SpinTask", "DetumbleTask", "ReorientTask", "AXIS_NAMES"]

AXIS_NAMES = ("major", "intermediate", "minor")


def _unit_vectors_in_cone(rng, shape, max_angle):
    """Unit vectors about +z with polar angle uniform in ``[0, max_angle]``, azimuth uniform."""
    theta = rng.uniform(0.0, max_angle, shape)
    phi = rng.uniform(0.0, 2.0 * np.pi, shape)
    st = np.sin(theta)
    return st * np.cos(phi), st * np.sin(phi), np.cos(theta)


def _random_directions(rng, shape):
    v = rng.standard_normal((3,) + tuple(shape))
    v /= np.linalg.norm(v, axis=0)
    return v[0], v[1], v[2]


def _effort(u):
    return (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]) / 3.0


@dataclass(frozen=True)
class SpinTask:
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

    def initial_state(self, system, rng, shape):
        p = system.params.inertia[self.axis] * self.spin_rate
        x, y, z = _unit_vectors_in_cone(rng, shape, self.perturbation)
        comps = [None, None, None]
        j, k = (self.axis + 1) % 3, (self.axis + 2) % 3
        comps[self.axis], comps[j], comps[k] = p * z, p * x, p * y
        return tuple(comps)

    def alignment(self, system, y):
        # + 1e-300 keeps Pi = 0 (a full despin) finite without changing any normal value
        return y[self.axis] / (system.momentum_norm(y) + 1e-300)

    def observe(self, system, y):
        return system.angular_velocity(y)

    def reward(self, system, y, u):
        return self.alignment(system, y) - self.control_cost * _effort(u)

    def terminated(self, system, y):
        return False

    def metrics(self, system, y):
        a = self.alignment(system, y)
        return {"alignment": a, "is_success": a >= self.cos_success}

    def evaluate(self, system, y, u):
        """``(reward, terminated, metrics)`` with the alignment computed once."""
        a = self.alignment(system, y)
        return a - self.control_cost * _effort(u), False, {"alignment": a, "is_success": a >= self.cos_success}

    def __post_init__(self):
        object.__setattr__(self, "cos_success", math.cos(self.success_angle))


@dataclass(frozen=True)
class DetumbleTask:
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

    def initial_state(self, system, rng, shape):
        n = _random_directions(rng, shape)
        s = self.spin_rate * rng.uniform(0.5, 1.0, shape)
        inertia = system.params.inertia
        return tuple(inertia[i] * s * n[i] for i in range(3))

    def speed(self, system, y):
        w = system.angular_velocity(y)
        return sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])

    def observe(self, system, y):
        return system.angular_velocity(y)

    def reward(self, system, y, u):
        return -self.speed(system, y) / self.spin_rate - self.control_cost * _effort(u)

    def terminated(self, system, y):
        return self.speed(system, y) < self.tolerance * self.spin_rate

    def metrics(self, system, y):
        s = self.speed(system, y)
        return {"angular_speed": s, "is_success": s < self.tolerance * self.spin_rate}


@dataclass(frozen=True)
class ReorientTask:
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

    def initial_state(self, system, rng, shape):
        q = quat_random(rng, shape)
        n = _random_directions(rng, shape)
        s = self.spin_rate * rng.uniform(0.0, 0.1, shape)
        inertia = system.params.inertia
        return tuple(inertia[i] * s * n[i] for i in range(3)) + tuple(q)

    def error(self, y):
        e = quat_multiply(quat_conjugate(self.target), y[3:7])
        sign = np.where(e[0] < 0.0, -1.0, 1.0)
        return tuple(sign * c for c in e)

    def observe(self, system, y):
        return tuple(system.angular_velocity(y)) + self.error(y)

    def _angle_and_speed(self, system, y):
        w = system.angular_velocity(y)
        speed = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
        return quat_angle(self.error(y)), speed

    def reward(self, system, y, u):
        angle, speed = self._angle_and_speed(system, y)
        return -angle / np.pi - self.rate_cost * speed / self.spin_rate - self.control_cost * _effort(u)

    def terminated(self, system, y):
        return False

    def metrics(self, system, y):
        angle, speed = self._angle_and_speed(system, y)
        return {"attitude_error": angle, "is_success": (angle < self.success_angle) & (speed < self.success_angle * self.spin_rate)}

"""Tasks on the heavy top: initial states, observation, reward, termination.

As for the free body, a task reads state components (floats for one env, arrays for a batch)
through the system's read-outs and never integrates. ``u`` is the normalised action (one entry
per actuated torque direction, in ``[-1, 1]``).

Both tasks observe ``(Gamma / |Gamma|, Omega)``: the upward vertical seen from the body (3
numbers in [-1, 1]) and the body angular velocity [rad/s]. That is the Markov state of the
top (``Pi = I Omega``); the heading about the vertical does not enter the dynamics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .common import TwoStageStart, effort

__all__ = ["UprightTask", "PrecessTask", "transverse_basis", "slow_precession_rate"]


def transverse_basis(chi) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """Unit vectors ``(t1, t2)`` with ``(t1, t2, chi)`` right-handed and orthonormal.

    For ``chi = +-e_k`` they are the other two body axes (``e_i``, ``+-e_j``, ``(i, j, k)``
    cyclic), so a Lagrange top's transverse torques act on body axes 1 and 2.
    """
    x = np.asarray(chi, dtype=float)
    k = int(np.argmax(np.abs(x)))
    e = np.zeros(3)
    e[(k + 1) % 3] = 1.0
    t1 = e - x * np.dot(e, x)
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(x, t1)
    return tuple(float(c) for c in t1), tuple(float(c) for c in t2)


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _clip_unit(x):
    if isinstance(x, float):
        return min(1.0, max(-1.0, x))
    return np.clip(x, -1.0, 1.0)


def _vertical_in_cone(chi, u_tilt, u_azimuth, low, high):
    """Unit vectors at an angle uniform in ``[low, high]`` from ``chi``, azimuth uniform, from two
    uniforms on [0, 1) (floats or rows of a batch); ``(vector, angle)``."""
    t1, t2 = transverse_basis(chi)
    theta = low + (high - low) * u_tilt
    phi = 0.0 + 2.0 * np.pi * u_azimuth
    a, b, c = np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)
    return tuple(a * t1[i] + b * t2[i] + c * chi[i] for i in range(3)), theta


def _observe(system, y):
    n = system.vertical_norm(y)
    g = tuple(_clip_unit(y[i] / n) for i in (3, 4, 5))  # a unit vector: clipped against round-off
    return g + tuple(system.angular_velocity(y))


def slow_precession_rate(system, spin, tilt):
    """Slow root of (3.82) ``A cos(a) p^2 - C n p + M g l = 0`` for arrays/floats of ``spin``.

    Without cancellation: ``q = (C n + sgn(C n) sqrt(D)) / 2``, ``p = M g l / q``, with the
    discriminant ``D`` clamped at 0 (a spin too slow for a real root, reached only if friction
    has slowed the top, gives the double root's rate) and ``|q|`` kept off 0.
    """
    prm = system.params
    a, c, mgl = prm.transverse_inertia, prm.axial_inertia, prm.mgl
    k = c * spin
    disc = k * k - 4.0 * a * mgl * math.cos(tilt)
    root = np.sqrt(np.maximum(disc, 0.0))
    q = 0.5 * (k + np.where(k < 0.0, -root, root))
    q = np.where(np.abs(q) > 1e-300, q, 1e-300)
    p = mgl / q
    return float(p) if np.ndim(p) == 0 else p


@dataclass(frozen=True)
class UprightTask(TwoStageStart):
    """Keep the top upright: the centre-of-mass axis on the upward vertical.

    * Start: spin ``n ~ U(spin_low, spin_high)`` about ``chi`` (``Omega = n chi``), the vertical
      tilted from ``chi`` by an angle uniform in ``[0, perturbation]`` (azimuth uniform).
    * Reward: ``cos(tilt) - control_cost * mean(u^2)``, in [-1, 1] (1 = upright, no effort).
    * Terminates when ``tilt > tilt_limit``. Success: ``tilt < success_tilt``.
    """

    spin_low: float
    spin_high: float
    perturbation: float
    tilt_limit: float
    control_cost: float
    success_tilt: float = 0.05

    name = "upright"
    observation_size = 6
    observation_names = ("Gamma1", "Gamma2", "Gamma3", "Omega1", "Omega2", "Omega3")
    observation_units = ("1",) * 3 + ("rad/s",) * 3
    metric_names = ("is_success",)
    final_measure = "tilt"
    controller = "UprightLQR"
    kernels = None  # no pure forms (yet): the batch runs on numpy

    def initial_draws(self, rng):
        return rng.random(3)  # tilt, azimuth, spin

    def initial_from_draws(self, system, d):
        prm = system.params
        chi = prm.com_direction
        gamma, _ = _vertical_in_cone(chi, d[0], d[1], 0.0, self.perturbation)
        n = self.spin_low + (self.spin_high - self.spin_low) * d[2]
        pi = tuple(prm.inertia[i] * n * chi[i] for i in range(3))
        return pi + gamma

    def observe(self, system, y):
        return _observe(system, y)

    def evaluate(self, system, y, u):
        """``(reward, terminated, metrics)`` with the tilt computed once."""
        tilt = system.tilt(y)
        return _cos_tilt(system, y) - self.control_cost * effort(u), tilt > self.tilt_limit, {"is_success": tilt < self.success_tilt}


def _cos_tilt(system, y):
    n = system.vertical_norm(y)
    chi = system.params.com_direction
    return (y[3] * chi[0] + y[4] * chi[1] + y[5] * chi[2]) / n


@dataclass(frozen=True)
class PrecessTask(TwoStageStart):
    """Hold a regular precession at tilt ``target_tilt`` (Lagrange tops only).

    The target rate is ``target_rate`` [rad/s] if given (a forced precession: it needs torque
    unless it solves (3.82)), else the slow root of (3.82) at the current spin, the torque-free
    steady precession (seed 2, 3.82-3.83).

    * Start: spin ``n ~ U(spin_low, spin_high)``, tilt ``target_tilt + U(-perturbation,
      perturbation)`` at a uniform azimuth, and the angular velocity of the regular precession
      at the target rate: ``Omega = p Gamma + (n - p cos(tilt)) chi`` (so ``Omega.chi = n``).
      Off the target tilt this is not steady: the top nutates.
    * Reward: ``1 - |tilt - target_tilt| / tilt_limit - min(|p - p*| / |p*|, 1) -
      control_cost * mean(u^2)`` with ``p`` the precession rate of the axis about the vertical.
    * Terminates when ``|tilt - target_tilt| > tilt_limit``. Success: tilt within
      ``success_tilt`` and rate within 10% of the target.
    """

    spin_low: float
    spin_high: float
    target_tilt: float
    target_rate: float | None
    perturbation: float
    tilt_limit: float
    control_cost: float
    success_tilt: float = 0.02

    name = "precess"
    observation_size = 6
    observation_names = ("Gamma1", "Gamma2", "Gamma3", "Omega1", "Omega2", "Omega3")
    observation_units = ("1",) * 3 + ("rad/s",) * 3
    metric_names = ("precession_rate", "target_precession_rate", "tilt_error", "is_success")
    final_measure = "tilt_error"
    controller = "PrecessionTracking"
    kernels = None  # no pure forms (yet): the batch runs on numpy

    def rate_target(self, system, y):
        if self.target_rate is not None:
            return self.target_rate
        return slow_precession_rate(system, system.spin(y), self.target_tilt)

    def initial_draws(self, rng):
        return rng.random(3)  # tilt, azimuth, spin

    def initial_from_draws(self, system, d):
        prm = system.params
        chi = prm.com_direction
        lo, hi = self.target_tilt - self.perturbation, self.target_tilt + self.perturbation
        gamma, tilt = _vertical_in_cone(chi, d[0], d[1], lo, hi)
        n = self.spin_low + (self.spin_high - self.spin_low) * d[2]
        p = self.target_rate if self.target_rate is not None else slow_precession_rate(system, n, self.target_tilt)
        axial = n - p * np.cos(tilt)
        omega = tuple(p * gamma[i] + axial * chi[i] for i in range(3))
        return tuple(prm.inertia[i] * omega[i] for i in range(3)) + gamma

    def observe(self, system, y):
        return _observe(system, y)

    def _errors(self, system, y):
        target = self.rate_target(system, y)
        rate = system.precession_rate(y)
        tilt_err = abs(system.tilt(y) - self.target_tilt)
        rate_err = abs(rate - target) / abs(target)
        if isinstance(rate_err, float):
            rate_err = 1.0 if not rate_err <= 1.0 else rate_err  # capped at 1 (the axis exactly upright has rate 0: error 1)
        else:
            rate_err = np.where(rate_err <= 1.0, rate_err, 1.0)
        return tilt_err, rate_err, rate, target

    def evaluate(self, system, y, u):
        """``(reward, terminated, metrics)`` with the errors computed once."""
        tilt_err, rate_err, rate, target = self._errors(system, y)
        reward = 1.0 - tilt_err / self.tilt_limit - rate_err - self.control_cost * effort(u)
        metrics = {"precession_rate": rate, "target_precession_rate": target, "tilt_error": tilt_err,
                   "is_success": (tilt_err < self.success_tilt) & (rate_err < 0.1)}
        return reward, tilt_err > self.tilt_limit, metrics


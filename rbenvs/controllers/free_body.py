"""Analytic feedback laws for the free rigid body (baselines and the main job's reference).

Every controller is built from an env (it reads the physics parameters and the task) and maps
an observation to a normalised action in [-1, 1], like an agent. numpy and scipy only.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solve_continuous_are

__all__ = ["ZeroController", "SpinLQR", "DetumbleDamping", "ReorientPD"]


class ZeroController:
    """No torque: the free motion the theorems speak of."""

    def __init__(self, env):
        self.size = env.unwrapped.action_space.shape[0]

    def __call__(self, obs):
        return np.zeros(self.size, dtype=np.float32)


class _Actuated:
    def __init__(self, env):
        e = env.unwrapped
        self.inertia = np.array(e.params.inertia)
        self.max_torque = e.max_torque
        self.axes = [i for i in range(3) if e.actuated[i]]

    def _action(self, torque):
        if self.max_torque == 0.0:
            return np.zeros(len(self.axes), dtype=np.float32)
        return np.clip(torque[self.axes] / self.max_torque, -1.0, 1.0).astype(np.float32)


class SpinLQR(_Actuated):
    """LQR on Euler's equations linearised about the target spin ``Pi* = I_j spin_rate e_j``.

    The linearisation (docs/physics.md §1) couples only the two transverse components:
    ``d(dPi_k)/dt = c_k Pi*_j dPi_i`` and ``d(dPi_i)/dt = c_i Pi*_j dPi_k`` (``(i, j, k)`` cyclic),
    unstable with rate ``lambda`` for the intermediate axis. The transverse gain comes from the
    continuous Riccati equation with ``Q = 1/p^2``, ``R = r / max_torque^2`` on the actuated
    transverse axes; the axial component (decoupled, neutrally stable) gets a proportional law
    with time constant ``axial_time`` when its axis is actuated. Saturated at ``max_torque``.
    """

    def __init__(self, env, r: float = 0.1, axial_time: float = 1.0):
        super().__init__(env)
        e = env.unwrapped
        j = e.axis
        self.axis = j
        p = e.task.spin_rate * self.inertia[j]
        self.target = np.zeros(3)
        self.target[j] = p
        c = np.array(e.params.coefficients)
        i, k = (j + 1) % 3, (j + 2) % 3
        # d(dPi_i)/dt = c_i (Pi_j dPi_k + Pi_k dPi_j) -> c_i p dPi_k at the target; likewise k.
        a = np.array([[0.0, c[i] * p], [c[k] * p, 0.0]])
        trans = [i, k]
        cols = [n for n, ax in enumerate(trans) if ax in self.axes]
        self.gain = np.zeros((3, 3))
        if cols and self.max_torque > 0.0:
            b = np.eye(2)[:, cols] * self.max_torque
            q = np.eye(2) / p**2
            rr = r * np.eye(len(cols))
            x = solve_continuous_are(a, b, q, rr)
            k_t = np.linalg.solve(rr, b.T @ x) * self.max_torque  # torque per unit dPi
            for row, col in enumerate(cols):
                self.gain[trans[col], trans] = k_t[row]
        if j in self.axes:
            self.gain[j, j] = 1.0 / axial_time

    def __call__(self, obs):
        pi = self.inertia * np.asarray(obs[:3], dtype=float)
        return self._action(-self.gain @ (pi - self.target))


class DetumbleDamping(_Actuated):
    """``tau = -k Omega`` (saturated), with ``k = max(I) / time_constant``: the kinetic energy
    falls monotonically, ``dH/dt = -k |Omega|^2`` on a fully actuated body."""

    def __init__(self, env, time_constant: float = 0.5):
        super().__init__(env)
        self.k = float(np.max(self.inertia)) / time_constant

    def __call__(self, obs):
        return self._action(-self.k * np.asarray(obs[:3], dtype=float))


class ReorientPD(_Actuated):
    """Quaternion PD: ``tau = -kp I vec(q_err) - kd I Omega`` (``q_err`` with ``w >= 0``, so the
    shorter rotation is taken), gains from a natural frequency and damping ratio."""

    def __init__(self, env, frequency: float = 1.0, damping: float = 1.0):
        super().__init__(env)
        self.kp = 2.0 * frequency**2  # small angles: vec(q) ~ angle/2
        self.kd = 2.0 * damping * frequency

    def __call__(self, obs):
        obs = np.asarray(obs, dtype=float)
        omega, err = obs[:3], obs[4:7]
        return self._action(self.inertia * (-self.kp * err - self.kd * omega))

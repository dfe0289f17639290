"""Analytic laws for the tippe top (references for the learned agents).

The top inverts because its contact point slides: friction, the only horizontal force,
dissipates energy at fixed Jellett's integral and so drives the top toward the minimum of
``E*(theta)`` at ``theta = pi`` (docs/physics.md §3). A table that moves with the contact point
removes the slip, and with it the dissipation: the top then keeps its energy, like a rolling
top, and stays on its broad end.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SlipCancelling"]


class SlipCancelling:
    """Hold task: accelerate the table along the slip, ``a_T = rate * v_P`` (saturated).

    In the table frame ``dv_G/dt = F/m - a_T``, so moving the table along the slip velocity of
    the contact point, ``v_P = v_G + omega x r`` with ``r = h k - a z_hat`` (all from the
    observation), takes the slip away as far as ``max_table_acceleration`` allows. Without
    slip, friction does no work and the top cannot climb. ``rate`` [1/s]: on the ``tippe_hold``
    scene the default keeps the tilt at its initial value, where half of it lets the top escape
    within the episode. Other action entries (friction, torque) are
    left at 0 (the middle of ``friction_range``, no torque).
    """

    def __init__(self, env, rate: float = 300.0):
        e = env.unwrapped
        p = e.params
        self.radius, self.height = p.radius, p.height
        self.max_acceleration = e.max_table_acceleration
        self.rate = rate
        self.size = e.action_space.shape[0]

    def __call__(self, obs):
        obs = np.asarray(obs, dtype=float)
        k, omega, v = obs[0:3], obs[3:6], obs[6:8]
        r = self.height * k - np.array([0.0, 0.0, self.radius])
        slip = np.append(v, 0.0) + np.cross(omega, r)
        action = np.zeros(self.size, dtype=np.float32)
        if self.max_acceleration > 0.0:
            action[:2] = np.clip(self.rate * slip[:2] / self.max_acceleration, -1.0, 1.0)
        return action

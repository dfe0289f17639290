"""Exact sub-flows shared by the rigid-body systems: rotations of body vectors and attitude.

For a Hamiltonian that depends on the angular momentum ``Pi`` alone, every body vector ``v``
that the bracket transports (``Pi`` itself, the vertical ``Gamma`` of the heavy top) obeys
``dv/dt = v x Omega`` with ``Omega = dH/dPi``, and the attitude ``dq/dt = q * (0, Omega)/2``.
When ``Omega`` is constant along the flow the solution is one rotation: the vectors turn by
``-Omega h`` and the attitude by ``+Omega h``. These pieces are exact, so a splitting built
from them keeps ``|Pi|``, ``|Gamma|``, ``Pi . Gamma`` and ``|q|`` to round-off.

A state is a tuple of components (floats or arrays of one batch shape). ``vectors`` lists the
offsets of the 3-vectors to turn (``Pi`` first, at offset 0) and ``quaternion`` the offset of
the attitude, or ``None``. The flows are small frozen classes, not closures, so that
environments pickle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..rotations import quat_multiply, quat_rotate, sqrt

__all__ = ["sincos", "AxisRotation", "SymmetricFreeRotation"]


def sincos(x):
    """``(sin x, cos x)`` of a float (libm) or an array (numpy)."""
    if isinstance(x, float):
        return math.sin(x), math.cos(x)
    return np.sin(x), np.cos(x)


@dataclass(frozen=True)
class AxisRotation:
    """Exact flow ``flow(y, u, h)`` of ``H_i = rate * Pi_i^2 / 2``: a rotation about body axis ``i``.

    ``Pi_i`` is constant, so ``Omega = rate * Pi_i e_i`` is too (``rate = 1 / I_i`` for the
    Lie-Poisson splitting of physics.md §4; a difference of inverse moments for a symmetric
    body). The control is ignored (it acts in the kick).
    """

    i: int
    rate: float
    vectors: tuple[int, ...] = (0,)
    quaternion: int | None = None

    def __call__(self, y, u, h):
        i = self.i
        j, k = (i + 1) % 3, (i + 2) % 3
        w = self.rate * y[i] * h
        s, c = sincos(w)
        out = list(y)
        for o in self.vectors:
            vj, vk = y[o + j], y[o + k]
            out[o + j] = vj * c + vk * s
            out[o + k] = vk * c - vj * s
        if self.quaternion is not None:
            a = self.quaternion
            sh, ch = sincos(0.5 * w)
            r = [0.0, 0.0, 0.0]
            r[i] = sh
            out[a : a + 4] = quat_multiply(y[a : a + 4], (ch, r[0], r[1], r[2]))
        return tuple(out)


@dataclass(frozen=True)
class SymmetricFreeRotation:
    """The exact torque-free flow of a body with two equal moments ``I_t`` about axis ``k``.

    ``H = |Pi|^2 / (2 I_t) + (1/I_k - 1/I_t) Pi_k^2 / 2``. The two terms Poisson-commute (both
    depend on ``Pi`` only, and ``|Pi|^2`` commutes with every ``Pi_k``), so their flows can be
    applied one after the other in either order:

    * ``|Pi|^2 / (2 I_t)``: ``Omega = Pi / I_t``; ``Pi`` stays put, the other vectors turn about it;
    * ``(1/I_k - 1/I_t) Pi_k^2 / 2``: an :class:`AxisRotation` about ``e_k``.

    Together: the free symmetric top, exact for any step (seed 1, 15.8 with ``I1 = I2``).
    """

    k: int
    transverse_inertia: float
    axial_inertia: float
    vectors: tuple[int, ...] = (0,)
    quaternion: int | None = None
    axial: AxisRotation = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        rate = 1.0 / self.axial_inertia - 1.0 / self.transverse_inertia
        object.__setattr__(self, "axial", AxisRotation(self.k, rate, self.vectors, self.quaternion))

    def __call__(self, y, u, h):
        # Rotation vector theta = Pi h / I_t, as the unit quaternion r = (cos |theta|/2, theta s),
        # s = sin(|theta|/2) / |theta| (-> 1/2 at theta = 0, where the axis is undefined).
        f = h / self.transverse_inertia
        tx, ty, tz = f * y[0], f * y[1], f * y[2]
        t = sqrt(tx * tx + ty * ty + tz * tz)
        if isinstance(t, float):
            sh, ch = sincos(0.5 * t)
            s = sh / t if t > 0.0 else 0.5
        else:
            sh, ch = sincos(0.5 * t)
            nonzero = t > 0.0
            s = np.where(nonzero, sh / np.where(nonzero, t, 1.0), 0.5)
        conj_r = (ch, -tx * s, -ty * s, -tz * s)  # vectors turn by -theta: v' = R(r)^T v
        out = list(y)
        for o in self.vectors[1:]:  # Pi itself is the rotation axis: unchanged
            out[o : o + 3] = quat_rotate(conj_r, y[o : o + 3])
        if self.quaternion is not None:
            a = self.quaternion
            out[a : a + 4] = quat_multiply(y[a : a + 4], (ch, tx * s, ty * s, tz * s))
        return self.axial(tuple(out), u, h)

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
environments pickle; each has a pure form (``kernel``: a function generated for its layout and
its parameters) that the splitting's generated step calls on floats, arrays and in compiled
kernels, and that calling the object runs too.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache

import numpy as np

from ..codegen import generate
from ..jit import jitable
from ..rotations import quat_multiply, quat_rotate, sincos, sqrt

__all__ = ["sincos", "half_turn", "AxisRotation", "SymmetricFreeRotation"]


@jitable
def half_turn(t):
    """``(sin(t/2) / t, cos(t/2))``: the rotation by the vector ``theta`` (``|theta| = t``) as the
    quaternion ``(cos(t/2), theta sin(t/2)/t)``; ``sin(t/2)/t -> 1/2`` at ``t = 0``, where the axis
    is undefined."""
    sh, ch = sincos(0.5 * t)
    if isinstance(t, float):
        return (sh / t if t > 0.0 else 0.5), ch
    return _half_turn_arrays(t, sh), ch


@jitable  # (registered so that compiled code can name it; it only ever runs on arrays)
def _half_turn_arrays(t, sh):
    nonzero = t > 0.0
    return np.where(nonzero, sh / np.where(nonzero, t, 1.0), 0.5)


def _state_size(vectors, quaternion) -> int:
    return max([o + 3 for o in vectors] + ([quaternion + 4] if quaternion is not None else []))


def _axis_rotation_lines(i, vectors, quaternion, dim, rate: str, y: str, out: str) -> list[str]:
    """Lines that set ``out`` to the rotation about body axis ``i`` of the state ``y`` by
    ``rate * y[i] * h`` (the vectors at ``vectors`` turn by minus that angle, the quaternion at
    ``quaternion`` by plus it)."""
    j, k = (i + 1) % 3, (i + 2) % 3
    lines = [f"w = {rate} * {y}[{i}] * h", "s, c = sincos(w)"]
    items = [f"{y}[{n}]" for n in range(dim)]
    for o in vectors:
        lines.append(f"vj, vk = {y}[{o + j}], {y}[{o + k}]")
        lines.append(f"n{o + j}, n{o + k} = vj * c + vk * s, vk * c - vj * s")
        items[o + j], items[o + k] = f"n{o + j}", f"n{o + k}"
    if quaternion is not None:
        a = quaternion
        r = ["0.0", "0.0", "0.0"]
        r[i] = "sh"
        lines.append("sh, ch = sincos(0.5 * w)")
        lines.append(
            f"qn = quat_multiply(({y}[{a}], {y}[{a + 1}], {y}[{a + 2}], {y}[{a + 3}]), (ch, "
            f"{', '.join(r)}))"
        )
        items[a : a + 4] = [f"qn[{m}]" for m in range(4)]
    lines.append(f"{out} = ({', '.join(items)},)")
    return lines


_NAMESPACE = {
    "sincos": sincos,
    "half_turn": half_turn,
    "quat_multiply": quat_multiply,
    "quat_rotate": quat_rotate,
    "sqrt": sqrt,
}


@cache
def _axis_rotation(i: int, vectors: tuple, quaternion, dim: int):
    """The pure flow ``flow(rate, y, u, h)`` of :class:`AxisRotation` for one layout (generated:
    a state of ``dim`` components is a tuple of that size for compiled code)."""
    body = _axis_rotation_lines(i, vectors, quaternion, dim, "P", "y", "y")
    src = "def flow(P, y, u, h):\n" + "".join(f"    {line}\n" for line in body) + "    return y\n"
    label = f"axis rotation i={i} vectors={vectors} quaternion={quaternion} dim={dim}"
    return jitable(generate(src, label, dict(_NAMESPACE))["flow"])


@cache
def _symmetric_rotation(k: int, vectors: tuple, quaternion, dim: int):
    """The pure flow ``flow((I_t, rate_k), y, u, h)`` of :class:`SymmetricFreeRotation`."""
    lines = [
        "transverse, axial_rate = P",
        # rotation vector theta = Pi h / I_t, the unit quaternion r = (cos |theta|/2, theta s)
        "f = h / transverse",
        "tx, ty, tz = f * y[0], f * y[1], f * y[2]",
        "t = sqrt(tx * tx + ty * ty + tz * tz)",
        "s, ch = half_turn(t)",
        "conj_r = (ch, -tx * s, -ty * s, -tz * s)",  # vectors turn by -theta: v' = R(r)^T v
    ]
    items = [f"y[{n}]" for n in range(dim)]
    for o in vectors[1:]:  # Pi itself is the rotation axis: unchanged
        lines.append(f"v{o} = quat_rotate(conj_r, (y[{o}], y[{o + 1}], y[{o + 2}]))")
        items[o : o + 3] = [f"v{o}[{m}]" for m in range(3)]
    if quaternion is not None:
        a = quaternion
        lines.append(
            f"q = quat_multiply((y[{a}], y[{a + 1}], y[{a + 2}], y[{a + 3}]), (ch, tx * s, ty * s, "
            "tz * s))"
        )
        items[a : a + 4] = [f"q[{m}]" for m in range(4)]
    lines.append(f"z = ({', '.join(items)},)")
    lines += _axis_rotation_lines(k, vectors, quaternion, dim, "axial_rate", "z", "z")
    src = "def flow(P, y, u, h):\n" + "".join(f"    {line}\n" for line in lines) + "    return z\n"
    label = f"symmetric free rotation k={k} vectors={vectors} quaternion={quaternion} dim={dim}"
    return jitable(generate(src, label, dict(_NAMESPACE))["flow"])


@dataclass(frozen=True)
class AxisRotation:
    """Exact flow ``flow(y, u, h)`` of ``H_i = rate * Pi_i^2 / 2``: a rotation about body axis
    ``i``.

    ``Pi_i`` is constant, so ``Omega = rate * Pi_i e_i`` is too (``rate = 1 / I_i`` for the
    Lie-Poisson splitting of docs/physics.md §4; a difference of inverse moments for a symmetric
    body). The control is ignored (it acts in the kick). :attr:`kernel` is the pure form
    (generated for the state's layout); calling the object runs it.
    """

    i: int
    rate: float
    vectors: tuple[int, ...] = (0,)
    quaternion: int | None = None

    @property
    def kernel(self):
        """``(flow, rate)`` with ``flow(rate, y, u, h)`` pure (floats, arrays, compiled)."""
        return _axis_rotation(
            self.i, tuple(self.vectors), self.quaternion, _state_size(self.vectors, self.quaternion)
        ), self.rate

    def __call__(self, y, u, h):
        fn, p = self.kernel
        return fn(p, tuple(y), u, h)


@dataclass(frozen=True)
class SymmetricFreeRotation:
    """The exact torque-free flow of a body with two equal moments ``I_t`` about axis ``k``.

    ``H = |Pi|^2 / (2 I_t) + (1/I_k - 1/I_t) Pi_k^2 / 2``. The two terms Poisson-commute (both
    depend on ``Pi`` only, and ``|Pi|^2`` commutes with every ``Pi_k``), so their flows can be
    applied one after the other in either order:

    * ``|Pi|^2 / (2 I_t)``: ``Omega = Pi / I_t``; ``Pi`` stays put, the other vectors turn about it;
    * ``(1/I_k - 1/I_t) Pi_k^2 / 2``: an :class:`AxisRotation` about ``e_k``.

    Together: the free symmetric top, exact for any step ([MR 15.8] with ``I1 = I2``).
    :attr:`kernel` is the pure form; calling the object runs it.
    """

    k: int
    transverse_inertia: float
    axial_inertia: float
    vectors: tuple[int, ...] = (0,)
    quaternion: int | None = None
    axial_rate: float = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        object.__setattr__(
            self, "axial_rate", 1.0 / self.axial_inertia - 1.0 / self.transverse_inertia
        )

    @property
    def kernel(self):
        """``(flow, (I_t, rate_k))`` with ``flow(P, y, u, h)`` pure (floats, arrays, compiled)."""
        fn = _symmetric_rotation(
            self.k, tuple(self.vectors), self.quaternion, _state_size(self.vectors, self.quaternion)
        )
        return fn, (self.transverse_inertia, self.axial_rate)

    def __call__(self, y, u, h):
        fn, p = self.kernel
        return fn(p, tuple(y), u, h)

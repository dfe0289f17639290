"""A linearly implicit scheme for stiff friction: the Rosenbrock-W method ROS2.

ROS2 (Verwer, Spee, Blom and Hundsdorfer 1999, docs/integrators.md) advances ``y' = f(y)`` by

    W k1 = f(y_n),   W k2 = f(y_n + h k1) - 2 k1,   y_{n+1} = y_n + h (3/2 k1 + 1/2 k2),

``W = I - gamma h J``, ``gamma = 1 + 1/sqrt(2)``. It is second order for *any* matrix ``J`` (a
W-method: the order conditions do not involve ``J``), and for ``J`` the exact Jacobian of a
linear problem its stability function ``R(z) = (1 + (1 - 2 gamma) z + (gamma^2 - 2 gamma + 1/2)
z^2) / (1 - gamma z)^2 = (1 + (1 - 2 gamma) z) / (1 - gamma z)^2`` is L-stable: ``|R| <= 1`` on
the left half plane and ``R(-inf) = 0``, so a stiff decaying mode is damped at any step, as the
true flow damps it (tests/test_tippe_stiff.py).

Here ``J`` is the friction's linearisation alone (:func:`rbenvs.dynamics.tippe_top.implicit_forms`:
the slip's relaxation, ``B N D C``, with the normal force and the geometry frozen at the step's
start), so the scheme is implicit exactly where the tippe top is stiff (regularised Coulomb
friction near zero slip relaxes the slip at ``mu N |M| / eps``, about 6000/s for the default top)
and explicit elsewhere: with ``J = 0`` it is Heun's method (explicit trapezoidal rule). ``W^-1``
is a 3x3 solve (Woodbury), made once per step. Two vector-field evaluations per step.

The system offers ``kernel_implicit = (factor, solve, P)``: ``factor(P, y, u, gamma h) -> w``
and ``solve(P, w, x) -> W^-1 x``, pure (:mod:`rbenvs.jit`); the step is generated from them, per
state dimension, as the explicit Runge-Kutta steps are (:mod:`rbenvs.integrators.runge_kutta`):
the bound step of the single env, the numpy batch and the pure step of the compiled kernels
are the same operations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

from ..core.codegen import generate
from .base import Integrator, StepRegion

__all__ = ["Ros2", "ROS2_GAMMA"]

# L-stability: gamma^2 - 2 gamma + 1/2 = 0; both roots give it, Verwer et al. take 1 + 1/sqrt(2)
ROS2_GAMMA = 1.0 + 1.0 / math.sqrt(2.0)


def _body(dim: int) -> list[str]:
    ys = [f"y{i}" for i in range(dim)]

    def tup(items):
        return "(" + ", ".join(items) + ("," if len(items) == 1 else "") + ")"

    lines = [", ".join(ys) + ("," if dim == 1 else "") + " = y"]
    lines.append(f"w = factor(PI, y, u, {ROS2_GAMMA!r} * h)")
    lines.append(", ".join(f"k1_{i}" for i in range(dim)) + ("," if dim == 1 else "") + " = solve(PI, w, f(P, y, u))")
    lines.append(", ".join(f"f1_{i}" for i in range(dim)) + ("," if dim == 1 else "") + " = f(P, " + tup([f"y{i} + h * k1_{i}" for i in range(dim)]) + ", u)")
    lines.append(", ".join(f"k2_{i}" for i in range(dim)) + ("," if dim == 1 else "") + " = solve(PI, w, " + tup([f"f1_{i} - 2.0 * k1_{i}" for i in range(dim)]) + ")")
    lines.append("return normalize(N, " + tup([f"y{i} + h * (1.5 * k1_{i} + 0.5 * k2_{i})" for i in range(dim)]) + ")")
    return lines


@lru_cache(maxsize=None)
def _generated(dim: int) -> dict:
    inner = "\n".join("        " + line for line in _body(dim))
    src = "def make(f, P, factor, solve, PI, normalize, N):\n    def step(y, u, h):\n" + inner + "\n    return step\n"
    src += "def pure(f, factor, solve, normalize):\n    def step(PS, y, u, h):\n        P, PI, N = PS\n" + inner + "\n    return step\n"
    return generate(src, f"ros2 dim={dim}")


@lru_cache(maxsize=None)
def _pure_step(dim: int, f, factor, solve, normalize):
    """The pure step ``step((P, PI, N), y, u, h)``; one function per combination (compiled
    kernels key on it)."""
    return _generated(dim)["pure"](f, factor, solve, normalize)


@dataclass(frozen=True)
class Ros2(Integrator):
    """ROS2, the second-order L-stable Rosenbrock-W method of Verwer et al. (1999), implicit in
    the system's stiff part (``kernel_implicit``: the tippe top's friction) and explicit
    elsewhere (see the module). Two rhs evaluations and one 3x3 factorisation per step."""

    name = "ros2"
    order = 2
    evaluations = 2
    requires = ("kernel_implicit",)
    # On the imaginary axis it is Heun's method (J = 0 there): no stability interval, a rotation's
    # amplitude grows by about (lambda h)^4 / 8 a step (1.25e-5 at lambda h = 0.1, where its phase
    # error is (lambda h)^3 / 6 = 1.7e-4 rad): an accuracy bound. On the negative real axis, for
    # the decay the W-matrix carries, L-stable: no bound.
    region = StepRegion(rotation=0.1, growth=0.02, dissipation=math.inf,
                        reason="explicit (Heun) on rotations: accuracy bounds as euler's; L-stable for the implicit (friction) part")

    def supports(self, system) -> bool:
        return getattr(system, "kernel_implicit", None) is not None and getattr(system, "kernel_rhs", None) is not None \
            and getattr(system, "kernel_normalize", None) is not None

    def _parts(self, system):
        f, p = system.kernel_rhs
        factor, solve, pi = system.kernel_implicit
        normalize, n = system.kernel_normalize
        return f, p, factor, solve, pi, normalize, n

    def step(self, system, y, u, h):
        return self.bind(system, len(y))(y, u, h)

    def bind(self, system, dim):
        return _generated(dim)["make"](*self._parts(system))

    def kernel_step(self, system):
        if not self.supports(system):
            return None
        f, p, factor, solve, pi, normalize, n = self._parts(system)
        return _pure_step(system.dim, f, factor, solve, normalize), (p, pi, n)

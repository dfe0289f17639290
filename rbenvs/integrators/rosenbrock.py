"""Linearly implicit schemes for stiff friction: the Rosenbrock-W methods ROS2 and ROS34PW2.

ROS2 (Verwer, Spee, Blom and Hundsdorfer 1999, docs/accuracy.md) advances ``y' = f(y)`` by

    W k1 = f(y_n),   W k2 = f(y_n + h k1) - 2 k1,   y_{n+1} = y_n + h (3/2 k1 + 1/2 k2),

``W = I - gamma h J``, ``gamma = 1 + 1/sqrt(2)``. It is second order for *any* matrix ``J`` (a
W-method: the order conditions do not involve ``J``), and for ``J`` the exact Jacobian of a
linear problem its stability function ``R(z) = (1 + (1 - 2 gamma) z + (gamma^2 - 2 gamma + 1/2)
z^2) / (1 - gamma z)^2 = (1 + (1 - 2 gamma) z) / (1 - gamma z)^2`` is L-stable: ``|R| <= 1`` on
the left half plane and ``R(-inf) = 0``, so a stiff decaying mode is damped at any step, as the
true flow damps it (tests/test_tippe_stiff.py).

ROS34PW2 (Rang and Angermann 2005) is the four-stage third-order one: order 3 for any ``J``,
L-stable and stiffly accurate (its step is its last stage), embedded order 2; :class:`Ros34pw2`
holds its coefficients in the form without ``J`` products (:func:`transformed`). Both are
:class:`RosenbrockW` subclasses, one generator for every such method.

Here ``J`` is the friction's linearisation alone (:func:`rbenvs.dynamics.tippe_top.implicit_forms`:
the slip's relaxation, ``B N D C``, with the normal force and the geometry frozen at the step's
start; the slip's change through the attitude included), so the scheme is implicit exactly where the
tippe top is stiff (regularised Coulomb friction near zero slip relaxes the slip at ``mu N |M| /
eps``, about 6000/s for the default top) and explicit elsewhere: with ``J = 0`` ROS2 is Heun's
method (explicit trapezoidal rule). ``W^-1`` is a 3x3 solve (Woodbury), made once per step. Two
(ROS2) or four (ROS34PW2) vector-field evaluations per step.

Measured (``python -m rbenvs.bench.tippe_steps``, docs/accuracy.md "Stiff friction"): near
zero slip neither is more accurate than rk4 at the counts where it would pay, so neither is
registered by name; they are here to be measured and built on.

The system offers ``kernel_implicit = (factor, solve, P)``: ``factor(P, y, u, gamma h) -> w``
and ``solve(P, w, x) -> W^-1 x``, pure (:mod:`rbenvs.jit`); the step is generated from them, per
state dimension, as the explicit Runge-Kutta steps are (:mod:`rbenvs.integrators.runge_kutta`):
the bound step of the single env, the numpy batch and the pure step of the compiled kernels
are the same operations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache
from typing import ClassVar

import numpy as np

from ..codegen import generate
from .base import Integrator, StepRegion

__all__ = ["RosenbrockW", "Ros2", "Ros34pw2", "ROS2_GAMMA", "transformed"]

# L-stability: gamma^2 - 2 gamma + 1/2 = 0; both roots give it, Verwer et al. take 1 + 1/sqrt(2)
ROS2_GAMMA = 1.0 + 1.0 / math.sqrt(2.0)


def transformed(alpha, gamma, b):
    """The coefficients ``(a, c, m)`` of the form without products by ``J`` (Hairer and Wanner,
    Solving ODEs II, IV.7 (7.25)) from a Rosenbrock-W method's ``alpha`` (strictly lower), ``gamma``
    (lower triangular, constant diagonal) and weights ``b``: ``a = alpha Gamma^-1``, ``c =
    diag(1/gamma) - Gamma^-1``, ``m = b Gamma^-1``. Then, with ``v_i = u_i / h``,

        W v_i = gamma_ii (f(y + h sum_j a_ij v_j) + sum_j c_ij v_j),   y_1 = y + h sum_i m_i v_i.
    """
    alpha, gam, b = (
        np.array(alpha, dtype=float),
        np.array(gamma, dtype=float),
        np.array(b, dtype=float),
    )
    inv = np.linalg.inv(gam)
    return alpha @ inv, np.diag(1.0 / np.diag(gam)) - inv, b @ inv


def _tup(items):
    return "(" + ", ".join(items) + ("," if len(items) == 1 else "") + ")"


def _body(scheme, dim: int) -> list[str]:
    """One step of ``scheme`` (its ``gamma``, ``scale``, ``a``, ``d``, ``m``: ``W v_i = scale
    f(Y_i) + sum_j d_ij v_j``, ``Y_i = y + h sum_j a_ij v_j``, ``y_1 = y + h sum_i m_i v_i``)
    for states of ``dim`` components."""

    def names(prefix):
        return ", ".join(f"{prefix}_{k}" for k in range(dim)) + ("," if dim == 1 else "")

    def combination(coefs, stage_names):
        terms = [(c, n) for c, n in zip(coefs, stage_names) if c != 0.0]
        return terms

    lines = [", ".join(f"y{k}" for k in range(dim)) + ("," if dim == 1 else "") + " = y"]
    lines.append(f"w = factor(PI, y, u, {float(scheme.gamma)!r} * h)")
    for i in range(len(scheme.m)):
        a_terms = combination(scheme.a[i], [f"v{j}" for j in range(i)])
        if not a_terms:
            stage = "y"
        else:
            stage = _tup(
                [
                    f"y{k} + h * ("
                    + " + ".join(f"{c!r} * {n}_{k}" if c != 1.0 else f"{n}_{k}" for c, n in a_terms)
                    + ")"
                    for k in range(dim)
                ]
            )
        d_terms = combination(scheme.d[i], [f"v{j}" for j in range(i)])
        if scheme.scale == 1.0 and not d_terms:
            lines.append(f"{names(f'v{i}')} = solve(PI, w, f(P, {stage}, u))")
            continue
        lines.append(f"{names(f'f{i}')} = f(P, {stage}, u)")
        # (a stage's component names: called in this iteration only)
        head = (
            (lambda k: f"f{i}_{k}")  # noqa: B023
            if scheme.scale == 1.0
            else (lambda k: f"{float(scheme.scale)!r} * f{i}_{k}")  # noqa: B023
        )
        rhs = _tup(
            [head(k) + "".join(f" + {c!r} * {n}_{k}" for c, n in d_terms) for k in range(dim)]
        )
        lines.append(f"{names(f'v{i}')} = solve(PI, w, {rhs})")
    m_terms = [(c, f"v{i}") for i, c in enumerate(scheme.m) if c != 0.0]
    lines.append(
        "return normalize(N, "
        + _tup(
            [
                f"y{k} + h * (" + " + ".join(f"{c!r} * {n}_{k}" for c, n in m_terms) + ")"
                for k in range(dim)
            ]
        )
        + ")"
    )
    return lines


def _generated(scheme: type, dim: int) -> dict:
    key = (scheme, dim)
    ns = _GENERATED.get(key)
    if ns is None:
        inner = "\n".join("        " + line for line in _body(scheme, dim))
        src = (
            "def make(f, P, factor, solve, PI, normalize, N):\n    def step(y, u, h):\n"
            + inner
            + "\n    return step\n"
        )
        src += (
            "def pure(f, factor, solve, normalize):\n    def step(PS, y, u, h):\n"
            "        P, PI, N = PS\n" + inner + "\n    return step\n"
        )
        ns = _GENERATED[key] = generate(src, f"{scheme.name} dim={dim}")
    return ns


_GENERATED: dict = {}


@cache
def _pure_step(scheme: type, dim: int, f, factor, solve, normalize):
    """The pure step ``step((P, PI, N), y, u, h)``; one function per combination (compiled
    kernels key on it)."""
    return _generated(scheme, dim)["pure"](f, factor, solve, normalize)


@dataclass(frozen=True)
class RosenbrockW(Integrator):
    """A Rosenbrock-W method in the form without ``J`` products (:func:`transformed`): a subclass
    sets ``name``, ``order``, ``evaluations``, ``region`` and the coefficients ``gamma``, ``scale``,
    ``a``, ``d`` (rows, strictly lower) and ``m``; ``W = I - gamma h J`` is the system's
    (``kernel_implicit``), factored once per step."""

    gamma: ClassVar[float]
    scale: ClassVar[float]
    a: ClassVar[tuple]
    d: ClassVar[tuple]
    m: ClassVar[tuple]
    requires = ("implicit",)

    def supports(self, system) -> bool:
        # (the instance's forms: a tippe top with a stem has no implicit solve)
        return (
            super().supports(system)
            and system.kernel_implicit is not None
            and system.kernel_rhs is not None
            and system.kernel_normalize is not None
        )

    def _parts(self, system):
        f, p = system.kernel_rhs
        factor, solve, pi = system.kernel_implicit
        normalize, n = system.kernel_normalize
        return f, p, factor, solve, pi, normalize, n

    def step(self, system, y, u, h):
        return self.bind(system, len(y))(y, u, h)

    def bind(self, system, dim, compensated=False):
        if compensated:  # (no compensated form: tolerance= does not take this scheme)
            return None
        return _generated(type(self), dim)["make"](*self._parts(system))

    def kernel_step(self, system, compensated=False):
        if compensated or not self.supports(system):
            return None
        f, p, factor, solve, pi, normalize, n = self._parts(system)
        return _pure_step(type(self), system.dim, f, factor, solve, normalize), (p, pi, n)


@dataclass(frozen=True)
class Ros2(RosenbrockW):
    """ROS2, the second-order L-stable Rosenbrock-W method of Verwer et al. (1999), implicit in
    the system's stiff part (``kernel_implicit``: the tippe top's friction) and explicit
    elsewhere (see the module). Two rhs evaluations and one 3x3 factorisation per step."""

    name = "ros2"
    order = 2
    evaluations = 2
    gamma = ROS2_GAMMA
    scale = 1.0
    a = ((), (1.0,))
    d = ((), (-2.0,))
    m = (1.5, 0.5)
    # On the imaginary axis it is Heun's method (J = 0 there): no stability interval, a rotation's
    # amplitude grows by about (lambda h)^4 / 8 a step (1.25e-5 at lambda h = 0.1, where its phase
    # error is (lambda h)^3 / 6 = 1.7e-4 rad): an accuracy bound. On the negative real axis, for
    # the decay the W-matrix carries, L-stable: no bound.
    region = StepRegion(
        rotation=0.1,
        growth=0.02,
        dissipation=math.inf,
        reason="explicit (Heun) on rotations: accuracy bounds as euler's; L-stable for the "
        "implicit (friction) part",
    )


# ROS34PW2 (Rang and Angermann 2005; their alpha, gamma, b): four stages, order
# 3 for any W (a W-method), embedded order 2, L-stable and stiffly accurate (b_i = alpha_4i +
# gamma_4i, b_4 = gamma); gamma the root of its L-stability polynomial, 0.4358665215084590
_G = 0.43586652150845900
_ALPHA = (
    (0.0, 0.0, 0.0, 0.0),
    (0.87173304301691801, 0.0, 0.0, 0.0),
    (0.84457060015369423, -0.11299064236484185, 0.0, 0.0),
    (0.0, 0.0, 1.0, 0.0),
)
_GAMMA = (
    (_G, 0.0, 0.0, 0.0),
    (-0.87173304301691801, _G, 0.0, 0.0),
    (-0.90338057013044082, 0.054180672388095326, _G, 0.0),
    (0.24212380706095346, -1.2232505839045147, 0.54526025533510214, _G),
)
_B = (0.24212380706095346, -1.2232505839045147, 1.5452602553351020, _G)
_B_HAT = (0.37810903145819369, -0.096042292212423178, 0.5, 0.21793326075422950)
_A34, _C34, _M34 = transformed(_ALPHA, _GAMMA, _B)


@dataclass(frozen=True)
class Ros34pw2(RosenbrockW):
    """ROS34PW2 (Rang and Angermann 2005): a Rosenbrock-W method of order 3 for any W (so the
    frozen friction linearisation keeps it), L-stable and stiffly accurate (its last stage is
    the step: the stiff part sits on its slow manifold at the step's end). Four rhs evaluations
    and one 3x3 factorisation per step; with ``J = 0`` a four-stage explicit scheme of order 3."""

    name = "ros34pw2"
    order = 3
    evaluations = 4
    gamma = _G
    scale = _G
    a = tuple(tuple(float(x) for x in _A34[i, :i]) for i in range(4))
    d = tuple(tuple(float(_G * x) for x in _C34[i, :i]) for i in range(4))
    m = tuple(float(x) for x in _M34)
    region = StepRegion(
        rotation=0.5,
        dissipation=math.inf,
        reason="accuracy on rotations (explicit there, third order); L-stable for the implicit "
        "(friction) part",
    )

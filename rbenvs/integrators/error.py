"""The error constant of a scheme, measured: what ``tolerance=`` turns into a step count.

A scheme of order ``p`` with step ``h`` on the rotation ``dy/dt = i lambda y`` (the mode of the
dynamics whose rate the step guard bounds, :mod:`rbenvs.stepsize.controller`) commits a local error
of
``C (lambda h)^(p+1) |y|`` per step to leading order; rotations neither amplify nor damp an
error to leading order, so after a time ``T`` the error is the sum of the local ones:

    |y_n - y(T)| / |y| = C lambda T (lambda h)^p (1 + O(lambda h))

``C`` is the scheme's **error constant** (its ``error_constant`` attribute): rk4 ``1/120``
(``R(z) - exp(z) = -z^5 / 120 + ...``: the phase lags), forward Euler ``1/2`` (each step grows
the amplitude by ``sqrt(1 + (lambda h)^2)``). :func:`measure_error_constant` measures it by
running the scheme on that rotation (its own step, the code the envs run) and dividing the
error by ``lambda T (lambda h)^p``; ``tests/test_tolerance.py`` re-measures every declared
constant and ``rbenvs bench accuracy --tolerance`` prints the measurement.
"""

from __future__ import annotations

import math

__all__ = ["Rotation", "measure_error_constant", "measure_amplitude_share"]


class Rotation:
    """``dy/dt = lambda J y`` in the plane: the test problem (``y = (a, b)``, a rotation at
    ``lambda`` rad/s; its exact flow turns ``y`` by ``lambda t``). A system as the integrators
    see one: ``rhs``, ``normalize`` (nothing to project)."""

    dim = 2
    needs_projection = False
    kernel_rhs = kernel_normalize = None  # (no pure forms: the integrators' float path)

    def __init__(self, rate: float = 1.0):
        self.rate = float(rate)

    def rhs(self, y, u):
        a, b = y
        return (-self.rate * b, self.rate * a)

    def normalize(self, y):
        return y

    def exact(self, y, t):
        c, s = math.cos(self.rate * t), math.sin(self.rate * t)
        a, b = y
        return (c * a - s * b, s * a + c * b)


def measure_error_constant(integrator, z: float | None = None, turns: float = 10.0) -> float:
    """``C`` of ``integrator`` (a name or an object with ``step`` and ``order``): the relative
    error after ``turns`` radians of the rotation at ``lambda h = z``, over ``lambda T z^p``.

    The default ``z`` lies in the asymptotic range and well above round-off (rk4: 0.01, where
    the error is ~1e-9 and the next term is ``O(z)`` smaller; first order: 1e-4)."""
    from . import get_integrator

    integ = get_integrator(integrator)
    p = integ.order
    if z is None:
        z = 1e-2 if p >= 3 else 1e-4
    system = Rotation(1.0)
    n = int(round(turns / z))
    h = turns / n
    y0 = (1.0, 0.0)
    y = y0
    for _ in range(n):
        y = integ.step(system, y, None, h)
    ref = system.exact(y0, n * h)
    err = math.hypot(y[0] - ref[0], y[1] - ref[1])
    return err / (n * h * h**p)


def measure_amplitude_share(integrator, z: float = 1e-2) -> float:
    """The share of one step's error on the rotation at ``lambda h = z`` that changes the
    amplitude: ``||R(i z)| - 1| / |R(i z) - exp(i z)|``. Near 0 for a scheme whose leading error
    is in the phase (rk4: ``z / 1.2``), near 1 where it is in the amplitude (euler)."""
    from . import get_integrator

    integ = get_integrator(integrator)
    system = Rotation(1.0)
    y = integ.step(system, (1.0, 0.0), None, z)
    exact = system.exact((1.0, 0.0), z)
    return abs(math.hypot(*y) - 1.0) / math.hypot(y[0] - exact[0], y[1] - exact[1])

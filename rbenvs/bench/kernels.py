"""``rbenvs bench kernels``: the memory-layout measurement behind the component design.

One RK4 step of Euler's equations, three ways, on the same states:

* ``components``: the package's own kernel (:class:`rbenvs.integrators.RK4` on
  :class:`rbenvs.dynamics.FreeBody`), state = three floats (n = 1) or three ``(n,)`` arrays,
  i.e. a ``(3, n)`` layout;
* ``np.cross (n,3)``: a textbook numpy RK4 on an ``(n, 3)`` array with ``np.cross``;
* for n = 1 also the ``(n, 3)`` version, which is how a naive single env would call numpy.

Prints microseconds per step (per batch) and the ratio of the peer to ours.
"""

from __future__ import annotations

import timeit

import numpy as np

from ..dynamics import FreeBody, FreeBodyParams
from ..integrators import RK4

__all__ = ["run"]


def _cross_rk4(inertia, pi, tau, h):
    inv = 1.0 / inertia

    def f(p):
        return np.cross(p, p * inv) + tau

    k1 = f(pi)
    k2 = f(pi + 0.5 * h * k1)
    k3 = f(pi + 0.5 * h * k2)
    k4 = f(pi + h * k3)
    return pi + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


def _time(fn, repeat=5):
    number, _ = timeit.Timer(fn).autorange()
    return min(timeit.Timer(fn).repeat(repeat=repeat, number=number)) / number


def run(sizes=(1, 16, 256, 4096), seed=0) -> list[dict]:
    rng = np.random.default_rng(seed)
    inertia = (2.0, 1.5, 1.0)
    system = FreeBody(FreeBodyParams(inertia))
    rk4 = RK4()
    inertia_arr = np.array(inertia)
    h = 0.01
    rows = []
    for n in sizes:
        pi = rng.standard_normal((n, 3))
        tau = 0.1 * rng.standard_normal((n, 3))
        if n == 1:
            y = tuple(float(x) for x in pi[0])
            u = tuple(float(x) for x in tau[0])
        else:
            y = tuple(np.ascontiguousarray(pi.T))
            u = tuple(np.ascontiguousarray(tau.T))
        ours = _time(lambda: rk4.step(system, y, u, h))
        peer = _time(lambda: _cross_rk4(inertia_arr, pi, tau, h))
        # same numbers: the two kernels agree to round-off
        diff = float(np.max(np.abs(np.array(rk4.step(system, y, u, h)).reshape(3, -1).T - _cross_rk4(inertia_arr, pi, tau, h))))
        rows.append({"n": n, "components_us": ours * 1e6, "cross_n3_us": peer * 1e6, "ratio": peer / ours, "max_abs_difference": diff})
    return rows


def main(args=None) -> int:
    rows = run()
    print("RK4 step of Euler's equations with torque, microseconds per call (best of 5)")
    print(f"{'n':>6}  {'components (ours)':>18}  {'np.cross on (n,3)':>18}  {'peer/ours':>9}  {'max |diff|':>10}")
    for r in rows:
        print(f"{r['n']:>6}  {r['components_us']:>18.2f}  {r['cross_n3_us']:>18.2f}  {r['ratio']:>9.2f}  {r['max_abs_difference']:>10.1e}")
    return 0

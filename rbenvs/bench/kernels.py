"""``rbenvs bench kernels``: the memory-layout measurement behind the component design.

One RK4 step of Euler's equations, three ways, on the same states:

* ``components``: the package's own kernel (:class:`rbenvs.integrators.RK4` on
  :class:`rbenvs.dynamics.FreeBody`), state = three floats (n = 1) or three ``(n,)`` arrays,
  i.e. a ``(3, n)`` layout;
* ``np.cross (n,3)``: a textbook numpy RK4 on an ``(n, 3)`` array with ``np.cross``;
* for n = 1 also the ``(n, 3)`` version, which is how a naive single env would call numpy;
* ``compiled`` (with the ``fast`` extra): the same generated step, compiled by numba with a
  batch loop over the ``(3, n)`` states (:func:`rbenvs.compiled.physics_kernel`): what the
  vector env's compiled step spends on physics.

Prints microseconds per step (per batch) and the ratio of the peer to ours.
"""

from __future__ import annotations

import timeit

import numpy as np

from ..compiled import available, physics_kernel
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


def run(sizes=(1, 16, 256, 4096), seed=0, progress: bool = False) -> list[dict]:
    from ..progress import Progress

    bar = Progress(len(sizes), enabled=progress, desc="bench kernels: sizes")
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
        diff = float(
            np.max(
                np.abs(
                    np.array(rk4.step(system, y, u, h)).reshape(3, -1).T
                    - _cross_rk4(inertia_arr, pi, tau, h)
                )
            )
        )
        row = {
            "n": n,
            "components_us": ours * 1e6,
            "cross_n3_us": peer * 1e6,
            "ratio": peer / ours,
            "max_abs_difference": diff,
        }
        if available():
            step, params = rk4.kernel_step(system)
            advance = physics_kernel(step, 3, 3)
            Y, U, Ynew = (
                np.ascontiguousarray(pi.T),
                tuple(np.ascontiguousarray(tau.T)),
                np.empty((3, n)),
            )
            advance(Y, Ynew, U, h, 1, params)  # compiles on the first call
            row["compiled_us"] = _time(lambda: advance(Y, Ynew, U, h, 1, params)) * 1e6
            want = np.array(rk4.step(system, tuple(Y), U, h)).reshape(3, -1)
            row["compiled_equals_components"] = bool(np.array_equal(Ynew, want))
        rows.append(row)
        bar.update()
    bar.close()
    return rows


def main(args=None, progress: bool = True) -> int:
    rows = run(progress=progress)
    print("RK4 step of Euler's equations with torque, microseconds per call (best of 5)")
    compiled = "compiled_us" in rows[0]
    head = (
        f"{'n':>6}  {'components (ours)':>18}  {'np.cross on (n,3)':>18}  "
        f"{'peer/ours':>9}  {'max |diff|':>10}"
    )
    print(head + (f"  {'compiled (ours)':>16}  {'same bits':>9}" if compiled else ""))
    for r in rows:
        line = (
            f"{r['n']:>6}  {r['components_us']:>18.2f}  {r['cross_n3_us']:>18.2f}  "
            f"{r['ratio']:>9.2f}  {r['max_abs_difference']:>10.1e}"
        )
        if compiled:
            line += f"  {r['compiled_us']:>16.2f}  {str(r['compiled_equals_components']):>9}"
        print(line)
    if not compiled:
        print("(the compiled column needs the 'fast' extra: numba)")
    return 0

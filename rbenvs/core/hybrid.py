"""Switching of hybrid systems between internal steps: the one layer that locates events.

A hybrid system (:class:`~rbenvs.contracts.HybridSystem`, the tippe top with free flight)
declares its switching events (:meth:`events`: where each can happen, the function whose sign
change it is, a tolerance, the state in the new mode). After every internal step
``y_prev -> y`` of length ``h`` this layer checks the event of ``y_prev``'s mode; when its
function has turned negative at ``y`` it locates the crossing inside the step by a bracketed
regula falsi (Illinois) whose every trial is one step of the integrator from ``y_prev``,
switches there and takes the rest of the step in the new mode. A state that already violates
its mode at the start of the step (a second event inside one step) switches at once.

The dynamics never calls an integrator; the integrator knows nothing of events; only this
layer joins them. A batch (arrays) runs the rare switches element by element through the same
float code, so sub-env ``i`` of a vector env takes exactly its single env's steps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Switching", "locate", "LOCATE_ITERATIONS"]

# At most this many trial steps to locate an event (the bracket shrinks to round-off first).
LOCATE_ITERATIONS = 60
EPS = float(np.finfo(float).eps)


def locate(y0, y1, f1, step, h, event, tol):
    """First time ``t`` in ``(0, h]`` where ``event`` (``>= 0`` at ``y0``, ``f1 < 0`` at
    ``y1``) turns negative, to ``|event| <= tol`` or the bracket's round-off: ``(t, state at t)``
    with ``event(state) < 0``, the state from one ``step(y0, t)``."""
    a, fa = 0.0, event(y0)
    b, fb, yb = h, f1, y1
    wa, wb = fa, fb  # Illinois weights (halved on a repeated side)
    side = 0
    for _ in range(LOCATE_ITERATIONS):
        if fb >= -tol or b - a <= 4.0 * EPS * h:
            break
        t = (a * wb - b * wa) / (wb - wa)
        if not a < t < b:
            t = 0.5 * (a + b)
        yt = step(y0, t)
        ft = event(yt)
        if ft < 0.0:
            b, fb, yb, wb = t, ft, yt, ft
            if side == -1:
                wa *= 0.5
            side = -1
        else:
            a, fa, wa = t, ft, ft
            if side == 1:
                wb *= 0.5
            side = 1
    return b, yb


@dataclass(frozen=True)
class Switching:
    """The switching of ``system`` stepped by ``integrator``: :meth:`after_step` is the hook the
    step core calls after every internal step (floats or arrays)."""

    system: object
    integrator: object

    def after_step(self, y_prev, y, u, h):
        """``y``, or, where an event happened inside the step, the state after the switch and
        the rest of the step in the new mode."""
        if isinstance(y[0], np.ndarray):
            return self._after_step_batch(y_prev, y, u, h)
        return self._after_step_one(y_prev, y, u, h)

    def _after_step_one(self, y_prev, y, u, h):
        system, integ = self.system, self.integrator
        for event in system.events(u):
            if not event.applies(y_prev):
                continue
            f_end = event.function(y)
            if f_end >= 0.0:
                return y
            if event.function(y_prev) < 0.0:
                t, y_at = 0.0, y_prev
            else:
                t, y_at = locate(
                    y_prev,
                    y,
                    f_end,
                    lambda z, dt: integ.step(system, z, u, dt),
                    h,
                    event.function,
                    event.tolerance,
                )
            y_new = event.switch(y_at)
            return integ.step(system, y_new, u, h - t) if t < h else y_new
        return y

    def _after_step_batch(self, y_prev, y, u, h):
        system = self.system
        switch = np.zeros(np.shape(y[0]), dtype=bool)
        with np.errstate(invalid="ignore"):
            for event in system.events(u):
                switch |= event.applies(y_prev) & (event.function(y) < 0.0)
        if not switch.any():
            return y
        y = [np.array(c, dtype=np.float64) for c in y]
        for i in np.flatnonzero(switch):
            one = self._after_step_one(
                tuple(float(c[i]) for c in y_prev),
                tuple(float(c[i]) for c in y),
                None if u is None else tuple(float(c[i]) if np.ndim(c) else float(c) for c in u),
                float(h[i]) if np.ndim(h) else float(h),
            )
            for c, v in zip(y, one):
                c[i] = v
        return tuple(y)

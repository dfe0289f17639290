"""A vector env's accuracy report (the step controller's, :mod:`rbenvs.stepsize.controller`):
each sub-env's ``info["error_estimate"]`` and ``info["global_error_estimate"]``, from whichever
path ran the step, so that every path reports alike."""

from __future__ import annotations

import numpy as np

from ..stepsize.controller import GlobalErrorCheck

__all__ = ["BatchAccuracy"]


class BatchAccuracy:
    """A vector env's report of ``n`` sub-envs stepped by ``engine``: each sub-env's
    ``info["error_estimate"]`` (NaN under a ``False`` mask without a tolerance) and, with
    ``tolerance_check`` (``checked``), ``info["global_error_estimate"]``, from what each step's
    path wrote (the compiled step, each episode's engine with ``param_ranges``), the gate, or the
    rates before the step: sub-env ``i`` reports what a single env seeded ``s + i`` reports.
    ``companion``: the batch's own companion run (the numpy path)."""

    def __init__(self, engine, n: int, checked: bool, companion: bool):
        self.engine, self.n = engine, n
        self.estimated = engine.tolerance is not None
        self.checked = checked
        self.check = GlobalErrorCheck(engine) if companion else None
        self.estimates = None  # this step's estimates, where its path wrote them
        self.global_ = None  # the last step's global error estimates (checked)
        self.period_h = None  # the internal steps of the last period (the rates' estimate)
        # shared read-only arrays: every report reuses them instead of allocating
        self.true, self.false = np.ones(n, dtype=bool), np.zeros(n, dtype=bool)
        self.unestimated = np.full(n, np.nan)  # (NaN, its mask False: not estimated)
        self._freeze()

    def _freeze(self) -> None:
        for array in (self.true, self.false, self.unestimated):
            array.flags.writeable = False

    def __setstate__(self, state) -> None:
        # (pickle gives arrays back writable: freeze them again, for their sharers and for the
        # kernels, which numba compiles once per writability of their arguments)
        self.__dict__.update(state)
        self._freeze()

    def reset_info(self, info) -> None:
        """A reset's keys: 0 with a tolerance (no period yet), else not estimated."""
        info["error_estimate"] = np.zeros(self.n) if self.estimated else self.unestimated
        info["_error_estimate"] = self.true if self.estimated else self.false
        if self.checked:
            info["global_error_estimate"] = np.zeros(self.n)
            info["_global_error_estimate"] = self.true

    def restart(self, y, idx) -> None:
        """The batch companion's sub-envs ``idx`` start at their states in ``y``."""
        if self.check is not None:
            mask = np.zeros(self.n, dtype=bool)
            mask[idx] = True
            self.check.restart(y, mask)

    def companion_period(self, y, u, h, restart):
        """The batch companion's period (:meth:`GlobalErrorCheck.batch_period`): the mask of
        sub-envs whose estimate passed the tolerance, or ``None``."""
        self.global_, inaccurate = self.check.batch_period(y, u, h, restart)
        return inaccurate

    def begin(self) -> None:
        """A step begins: nothing written yet."""
        self.estimates = None

    def wrote(self, estimates, global_=None) -> None:
        """The step's path wrote its ``estimates`` (and, with its own companions, ``global_``)."""
        self.estimates = estimates
        if global_ is not None:
            self.global_ = global_

    def ran(self, h) -> None:
        """The period just run took the internal steps ``h`` (what the rates' estimate reads)."""
        if self.estimated:
            self.period_h = np.array(h, dtype=np.float64)

    def gated(self, y):
        """:meth:`StepRule.gated` over the batch ``y``: every sub-env's estimate, or ``None``."""
        gated = self.engine.gated(y)
        if gated is not None and np.shape(gated) != (self.n,):  # (a batch's is its own)
            gated = np.full(self.n, gated, dtype=np.float64)
        return gated

    def unestimated_report(self, out):
        """``out`` (a step's five values) with its info's keys where nothing is estimated."""
        info = out[4]
        info["error_estimate"], info["_error_estimate"] = self.unestimated, self.false
        if "final_info" in info:
            final = info["final_info"]
            final["error_estimate"], final["_error_estimate"] = self.unestimated, self.false
        return out

    def report(self, out, restart, estimate=None, control=None, y0=None, y2d0=None):
        """``out`` (a step's five values) with each period's ``estimate`` in its info: the one
        the step wrote or the gate's, else from the rates of the states ``y0`` (``y2d0``: as a
        ``(dim, n)`` array) under ``control``; 0 where no period ran (``restart``)."""
        obs, reward, terminated, truncated, info = out
        if estimate is None:
            estimate = self.estimates
        if estimate is None:
            rule = self.engine.rule
            u = control[1] if rule.motion or rule.dissipation is not None else None
            lam, lam_d, share = self.engine.forms.rates_batch(y0, u, y2d0)
            estimate = np.broadcast_to(
                rule.estimate(lam, self.period_h, lam_d, share), (self.n,)
            ).astype(np.float64)
        if restart is not self.false:  # (a compiled step wrote a restart's 0 itself)
            estimate[restart] = 0.0
        final = info.get("final_info")
        if final is not None:
            final["error_estimate"], final["_error_estimate"] = estimate.copy(), self.true
            estimate[info["_final_info"]] = 0.0
        info["error_estimate"], info["_error_estimate"] = estimate, self.true
        if self.checked:
            global_ = np.where(restart, 0.0, self.global_)
            if final is not None:
                final["global_error_estimate"] = global_.copy()
                final["_global_error_estimate"] = self.true
                global_[info["_final_info"]] = 0.0
            info["global_error_estimate"], info["_global_error_estimate"] = global_, self.true
        return obs, reward, terminated, truncated, info

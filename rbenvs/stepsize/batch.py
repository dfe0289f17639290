"""The step controller's report over a vector env's batch (:mod:`rbenvs.stepsize.controller`).

Every step of a vector env reports each sub-env's ``info["error_estimate"]`` (with a tolerance:
the estimated relative error of its period, 0 where no period ran; without one NaN under a
``False`` mask, the single env's ``None``) and, with ``tolerance_check``,
``info["global_error_estimate"]`` from the batch's companion run. The estimates come from the
step where its path writes them (the compiled vector step, from the rates at each period's
start; with ``param_ranges`` each sub-env's episode engine), from the default accuracy's gate,
or from the rates of the states before the step (the numpy path): :class:`BatchAccuracy` holds
what a step leaves for its report and writes the report, so that every path reports alike and
sub-env ``i`` reports what a single env seeded ``s + i`` reports.
"""

from __future__ import annotations

import numpy as np

from .check import GlobalErrorCheck

__all__ = ["BatchAccuracy"]


class BatchAccuracy:
    """The report of ``n`` sub-envs stepped by ``engine`` (its rule and tolerance); ``checked``:
    ``tolerance_check``; ``companion``: the batch's own companion run (the numpy path; with
    ``param_ranges`` each sub-env's episode has one of its own instead)."""

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
        for array in (self.true, self.false, self.unestimated):
            array.flags.writeable = False

    def reset_info(self, info) -> None:
        """A reset's keys: no period yet, so 0 with a tolerance (the single env's reset), else
        not estimated."""
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
        """The batch companion's period beside the period that took the states to ``y`` under
        ``u`` with internal steps ``h`` (a restarting sub-env's is discarded: it restarts): the
        sub-envs whose global error estimate passed the tolerance (a mask), or ``None``."""
        engine = self.engine
        counts = np.rint(engine.dt / np.broadcast_to(h, (self.n,))).astype(np.int64)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            self.global_ = np.where(restart, 0.0, self.check.period(y, u, counts))
            inaccurate = self.global_ > engine.tolerance
        return inaccurate if inaccurate.any() else None

    def begin(self) -> None:
        """A step begins: nothing written yet."""
        self.estimates = None

    def wrote(self, estimates, global_=None) -> None:
        """The step's path wrote its ``estimates`` (and, with its own companions, the global
        ``global_``)."""
        self.estimates = estimates
        if global_ is not None:
            self.global_ = global_

    def ran(self, h) -> None:
        """The period just run took the internal steps ``h`` (what the rates' estimate reads)."""
        if self.estimated:
            self.period_h = np.array(h, dtype=np.float64)

    def gated(self, y):
        """The default accuracy's gate over the batch ``y`` (:meth:`.controller.StepRule.gated`):
        every sub-env's estimate where each one lies within it (its periods then take
        ``substeps`` unchecked), else ``None``."""
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
        the step wrote (:attr:`estimates`) or the gate's, else from the rates of the states
        ``y0`` (``y2d0``: their ``(dim, n)`` array) before the step under ``control``; 0 where
        no period ran (``restart``; a SAME_STEP's ended periods' go with their final info)."""
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

"""The step controller's report for a vector env (:mod:`rbenvs.stepsize.controller`): each
sub-env's ``info["error_estimate"]`` and ``info["global_error_estimate"]``, written by whichever
path ran the step (the compiled step, each episode's engine with ``param_ranges``, or the numpy
path through :meth:`BatchAccuracy.before` and :meth:`BatchAccuracy.after`), so that every path
reports alike."""

from __future__ import annotations

import warnings

import numpy as np

from ..core.step import NumericalFailureWarning
from .controller import GlobalErrorCheck, inaccurate_text

__all__ = ["BatchAccuracy"]


class BatchAccuracy:
    """A vector env's report of ``n`` sub-envs stepped by ``engine``: each sub-env's
    ``info["error_estimate"]`` (NaN under a ``False`` mask without a tolerance) and, with
    ``tolerance_check`` (``checked``), ``info["global_error_estimate"]``, from what each step's
    path wrote (the compiled step, each episode's engine with ``param_ranges``; the numpy path's
    gate or rates, :meth:`before`): sub-env ``i`` reports what a single env seeded ``s + i``
    reports. ``companion``: the batch's own companion run (the numpy path)."""

    def __init__(self, engine, n: int, checked: bool, companion: bool):
        self.engine, self.n = engine, n
        self.estimated = engine.tolerance is not None
        self.checked = checked
        self.check = GlobalErrorCheck(engine) if companion else None
        self.estimates = None  # this step's estimates, as its path wrote them
        self.global_ = None  # the last step's global error estimates (checked)
        self.rates = None  # the numpy path's: the rates at the period's start (before)
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

    def held(self, y, u, h, restart):
        """The batch companion's period beside the one that took the states to ``y`` under ``u``
        in steps ``h`` (:meth:`GlobalErrorCheck.batch_period`; ``None`` without it): the mask of
        finite sub-envs (not ``restart``) whose global error estimate passed the tolerance, which
        hold their last state within it and end their episodes (a warning names them), or
        ``None``."""
        if self.check is None:
            return None
        self.global_, inaccurate = self.check.batch_period(y, u, h, restart)
        if inaccurate is None:
            return None
        late = inaccurate & ~restart
        for c in y:
            late &= np.isfinite(c)  # (a non-finite state is reported as that)
        if not late.any():
            return None
        engine = self.engine
        why = inaccurate_text(
            np.max(self.global_[late]),
            np.min(self.check.periods[late]),
            engine.tolerance,
            engine.dt,
        )
        warnings.warn(
            f"sub-envs {np.flatnonzero(late).tolist()}: {why}; their episodes end and their last "
            "states within the tolerance are kept",
            NumericalFailureWarning,
            stacklevel=4,
        )
        return late

    def wrote(self, estimates, global_=None) -> None:
        """The step's path wrote its ``estimates`` (and, with its own companions, ``global_``)."""
        self.estimates = estimates
        if global_ is not None:
            self.global_ = global_

    def before(self, y0, y2d0, u):
        """The numpy path's period from the states ``y0`` (``y2d0``: as a ``(dim, n)`` array, or
        ``None``) under the controls ``u``: ``True`` where every sub-env lies within the default
        accuracy's gate (:meth:`StepRule.gated`: the period then takes ``substeps`` unchecked,
        its estimate the gate's), else ``None`` with the rates its estimate reads kept for
        :meth:`after`."""
        if not self.estimated:
            return None
        engine = self.engine
        gated = None if self.checked else engine.gated(y0)
        if gated is not None:
            self.rates = None
            if np.shape(gated) != (self.n,):  # (a batch's is its own)
                gated = np.full(self.n, gated, dtype=np.float64)
            self.estimates = gated
            return True
        rule = engine.rule
        u = u if rule.motion or rule.dissipation is not None else None
        self.rates = engine.forms.rates_batch(y0, u, y2d0)
        return None

    def after(self, h, restart) -> None:
        """The numpy path's period took the internal steps ``h``: each sub-env's estimate, from
        the rates :meth:`before` kept (or the gate's), 0 where it restarts."""
        if not self.estimated:
            return
        if self.rates is not None:
            lam, lam_d, share = self.rates
            estimate = self.engine.rule.estimate(lam, np.array(h, dtype=np.float64), lam_d, share)
            self.estimates = np.broadcast_to(estimate, (self.n,)).astype(np.float64)
            self.rates = None
        if restart is not self.false:  # (the shared all-false mask: nothing restarts)
            self.estimates[restart] = 0.0

    def report(self, out):
        """``out`` (a step's five values) with each period's estimate in its info, as the step's
        path wrote it (NaN, not estimated, without a tolerance)."""
        info = out[4]
        final = info.get("final_info")
        if not self.estimated:
            info["error_estimate"], info["_error_estimate"] = self.unestimated, self.false
            if final is not None:
                final["error_estimate"], final["_error_estimate"] = self.unestimated, self.false
            return out
        estimate = self.estimates
        if final is not None:
            final["error_estimate"], final["_error_estimate"] = estimate.copy(), self.true
            estimate[info["_final_info"]] = 0.0
        info["error_estimate"], info["_error_estimate"] = estimate, self.true
        if self.checked:
            global_ = self.global_.copy()
            if final is not None:
                final["global_error_estimate"] = global_.copy()
                final["_global_error_estimate"] = self.true
                global_[info["_final_info"]] = 0.0
            info["global_error_estimate"], info["_global_error_estimate"] = global_, self.true
        return out

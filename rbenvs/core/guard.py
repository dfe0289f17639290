"""The step guard: how many internal steps a control period needs, from declarations only.

The integrator declares where its step can be trusted (:class:`~rbenvs.contracts.StepRegion`);
the system declares the rates a step must resolve for that region
(:meth:`~rbenvs.contracts.System.guard_rates`). A period of length ``dt`` that starts at ``y``
takes ``n = max(substeps, ceil(x))`` equal internal steps with

    x = max(dt lambda / b, (dt lambda)^2 / growth, dt / (c / lambda_d))

``lambda`` the system's fastest oscillatory rate at ``y``, ``b`` the region's ``rotation``
bound (or the system's own accuracy bound, which then replaces ``b`` and ``growth``),
``lambda_d`` its stiffest decaying rate and ``c`` the part of the region's ``dissipation``
interval the system allows. An integrator with no bound and a system with no dissipation give
no term. More than ``MAX_INTERNAL_STEPS`` is a numerical failure (reported, never a hang).

Everything here works on floats (one state) and arrays (a batch) with the same IEEE
operations, so a sub-env of a vector env takes exactly its single env's steps; the pure
:func:`step_ratio` is what the compiled batch step calls.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..jit import jitable
from ..rotations import maximum

__all__ = ["MAX_INTERNAL_STEPS", "GUARDS", "StepRule", "step_ratio", "require_guard"]

# More internal steps than this in one control period is treated as a numerical failure.
MAX_INTERNAL_STEPS = 1_000_000

# ``guard=`` of every env: when the internal step ``dt / substeps`` is beyond what the
# integrator can resolve at the current state, ``"subdivide"`` (default) splits the period
# into more equal steps, ``"refuse"`` raises ``ValueError`` from ``step``, ``"off"`` takes
# ``substeps`` steps regardless (a blow-up then ends the episode as a numerical failure).
GUARDS = ("subdivide", "refuse", "off")


def require_guard(guard) -> str:
    if not isinstance(guard, str) or guard not in GUARDS:
        raise ValueError(f"guard must be one of {list(GUARDS)}, got {guard!r}")
    return guard


@jitable
def step_ratio(g, lam):
    """``x`` (a period needs ``ceil(x)`` steps) from the oscillatory rate ``lam`` alone:
    ``g = (dt, bound, growth)`` (pure; floats or arrays)."""
    dt, bound, growth = g
    x = dt * lam / bound
    if growth != math.inf:
        z = dt * lam
        x = maximum(x, z * z / growth)
    return x


@dataclass(frozen=True)
class StepRule:
    """The guard of one env: its system's rates, its integrator's region and its ``dt``.

    ``active`` is false where nothing bounds the step (``guard="off"``, or an integrator with
    no bound for this system): the period then always takes ``substeps`` steps.
    """

    rotation: tuple  # (fn, P): lambda(P, y)
    params: tuple  # (dt, bound, growth) for step_ratio
    dissipation: tuple | None  # (fn, P): lambda_d(P, y, u), and below its c
    dissipation_step: float  # c: h <= c / lambda_d
    ceiling: float  # upper bound of lambda inside the observation bounds
    text: str
    active: bool

    @classmethod
    def build(cls, rates, region, dt: float, guard: str) -> "StepRule":
        """The rule for ``rates`` (the system's :class:`~rbenvs.contracts.GuardRates` for
        ``region``) at control period ``dt`` under ``guard``."""
        if rates.rotation_bound is not None:  # the system's accuracy bound replaces the scheme's
            bound, growth = rates.rotation_bound, math.inf
        else:
            bound, growth = region.rotation, region.growth
        step_d = rates.dissipation_margin * region.dissipation if rates.dissipation is not None else math.inf
        dissipation = rates.dissipation if step_d != math.inf else None
        active = guard != "off" and (bound != math.inf or growth != math.inf or dissipation is not None)
        text = rates.text
        if bound != math.inf:
            text = f"lambda h <= {bound}" + (f" and lambda^2 h dt <= {growth}" if growth != math.inf else "") + f", {text}"
        if dissipation is not None:
            text += f"; h <= {step_d:.6g} / lambda_d"
        return cls(rates.rotation, (float(dt), float(bound), float(growth)), dissipation, step_d, rates.ceiling, text, active)

    def ratio(self, y, u):
        """``x`` at ``y`` under ``u`` (the period needs ``ceil(x)`` steps); floats or arrays."""
        fn, p = self.rotation
        x = step_ratio(self.params, fn(p, y))
        if self.dissipation is not None:
            fd, pd = self.dissipation
            rate = fd(pd, y, u)
            dt = self.params[0]
            if type(rate) is float:
                x = max(x, dt / (self.dissipation_step / rate)) if rate > 0.0 else x
            else:
                with np.errstate(divide="ignore", invalid="ignore"):
                    h_d = np.where(rate > 0.0, self.dissipation_step / np.where(rate > 0.0, rate, 1.0), np.inf)
                    x = np.maximum(x, dt / h_d)
        return x

    def idle(self, substeps: int) -> bool:
        """True when no state inside the observation bounds can need more than ``substeps``
        steps (then no check needs to run: the plain loop is exact)."""
        if not self.active:
            return True
        if self.dissipation is not None:
            return False
        return step_ratio(self.params, self.ceiling * (1.0 + 1e-9)) <= substeps

    def steps(self, y, u, substeps: int):
        """``max(substeps, ceil(x))``, or ``MAX_INTERNAL_STEPS + 1`` (refused: a numerical
        failure) for a non-finite or absurd ``x``: an int, or an int array for a batch."""
        if not self.active:
            return substeps
        x = self.ratio(y, u)
        if type(x) is float or np.ndim(x) == 0:
            x = float(x)
            if x <= substeps:
                return substeps
            return math.ceil(x) if x <= MAX_INTERNAL_STEPS else MAX_INTERNAL_STEPS + 1
        x = np.broadcast_to(x, np.shape(y[0]))
        with np.errstate(invalid="ignore"):
            n = np.where(x <= MAX_INTERNAL_STEPS, np.ceil(np.where(x <= MAX_INTERNAL_STEPS, x, 0.0)), MAX_INTERNAL_STEPS + 1)
        return np.maximum(substeps, n).astype(np.int64)

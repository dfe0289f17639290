"""The step controller: every decision about a control period's internal steps, every estimate of
its error and every report of what it did, for the single env, the vector env (with and without
``param_ranges``) and, through its pure forms (:mod:`rbenvs.stepsize.forms`), the compiled
kernels. Its settings: the stability bound alone (``tolerance=None``), an error bound
(``tolerance=``, the env's default accuracy included) and the measured check
(``tolerance_check=True``). The derivations and the measurements: docs/accuracy.md.

* **Stability** (:class:`StepRule`): a period of length ``dt`` from ``y`` takes ``n = max(substeps,
  ceil(x))`` steps, ``x = max(dt lambda / b, (dt lambda)^2 / growth, dt / (c / lambda_d))`` from
  the integrator's :class:`~rbenvs.contracts.StepRegion` and the system's
  :meth:`~rbenvs.contracts.System.guard_rates`; more than ``MAX_INTERNAL_STEPS`` is a numerical
  failure (reported, never a hang).
* **Accuracy** (``tolerance=``, a relative error per episode of ``N`` periods): a scheme of order
  ``p`` and error constant ``C`` commits ``e = C lambda dt (lambda h)^p`` a period
  (``info["error_estimate"]``); every period meeting ``e <= log(1 + tolerance) / N`` keeps the
  episode's compounded error within the tolerance (a decaying rate shares the budget: half for
  it, relaxing within ``1 / lambda_d``). It assumes a motion that does not amplify errors.
* **The measured check** (:class:`GlobalErrorCheck`): a companion run at twice the step estimates
  the episode's global error, amplification included (Richardson's estimate, Hairer, Norsett and
  Wanner, *Solving Ordinary Differential Equations I*, 2nd ed., Springer 1993, section II.8).
* **Settings** (:func:`accuracy_settings`, :func:`require_accuracy`, :func:`cheapest_scheme`,
  :func:`require_resolvable`): resolved and refused at construction, never at the first step.

Everything works on floats (one state) and arrays (a batch) with the same IEEE operations, so a
sub-env of a vector env takes exactly its single env's steps.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..dynamics.validation import did_you_mean, require_int_in
from ..rotations import every, power
from .forms import (
    accuracy_steps,
    error_estimate,
    gated_estimate,
    mode_share,
    motion_error_estimate,
    motion_form,
    relative_difference,
    relaxation_estimate,
    relaxation_steps,
    stability_ratio,
    step_ratio,
    step_ratio_motion,
    whole_root,
)

__all__ = [
    "MAX_INTERNAL_STEPS", "GUARDS", "DEFAULT_TOLERANCE", "TOLERANCE_FLOOR", "MARGIN",
    "UnstableMotionWarning", "StepRule", "GlobalErrorCheck", "require_guard",
    "require_tolerance", "require_tolerance_check", "default_accuracy", "accuracy_settings",
    "takes_tolerance", "tolerance_schemes", "require_accuracy", "unstable_motion_warning",
    "cheapest_scheme", "start_steps", "require_resolvable", "tolerance_blocks",
    "companion_ratio", "companion_steps", "inaccurate_text",
]  # fmt: skip

# More internal steps than this in one control period is treated as a numerical failure.
MAX_INTERNAL_STEPS = 1_000_000

# ``guard=`` of every env: when the internal step ``dt / substeps`` is beyond what the
# integrator can resolve at the current state, ``"subdivide"`` (default) splits the period
# into more equal steps, ``"refuse"`` raises ``ValueError`` from ``step``, ``"off"`` takes
# ``substeps`` steps regardless (a blow-up then ends the episode as a numerical failure).
GUARDS = ("subdivide", "refuse", "off")
# ``tolerance=``'s default: the env's default accuracy (RigidBodyEnv.default_tolerance)
DEFAULT_TOLERANCE = "default"
# the least tolerance float64 carries over an episode: near the free body's separatrix the motion
# amplifies the (compensated) sums' roundoff to about this (rbenvs bench accuracy --floor)
TOLERANCE_FLOOR = 1e-12
# the reported global error estimate over the classical one (its next order's share)
MARGIN = 1.25


class UnstableMotionWarning(UserWarning):
    """``tolerance=`` on a motion that is unstable by the system's own theorem (an upright top
    below its critical spin, a spin about the intermediate axis, a tippe top that inverts): the
    steps hold the error they commit within the tolerance, but the motion amplifies errors
    already made, so over a horizon that spans the instability the error can end above it."""


# --- settings, resolved and refused at construction ---


def require_guard(guard) -> str:
    if not isinstance(guard, str) or guard not in GUARDS:
        raise ValueError(
            f"guard must be one of {list(GUARDS)}, got {guard!r}{did_you_mean(guard, GUARDS)}"
        )
    return guard


def require_tolerance(tolerance):
    """``tolerance=``: ``"default"`` (the env's default accuracy), ``None`` (no accuracy bound)
    or a finite number with ``TOLERANCE_FLOOR <= tolerance < 1`` (a relative error per episode)."""
    if tolerance is None or (isinstance(tolerance, str) and tolerance == DEFAULT_TOLERANCE):
        return tolerance
    rule = (
        f"{DEFAULT_TOLERANCE!r} (the env's default accuracy), None (unchecked: the stability bound "
        f"alone) or a finite number with {TOLERANCE_FLOOR:g} <= tolerance < 1 (the relative error "
        "allowed over an episode)"
    )
    if isinstance(tolerance, (bool, np.bool_)) or not isinstance(
        tolerance, (int, float, np.integer, np.floating)
    ):
        raise TypeError(f"tolerance must be {rule}, got {tolerance!r} ({type(tolerance).__name__})")
    tol = float(tolerance)
    if not (math.isfinite(tol) and 0.0 < tol < 1.0):
        raise ValueError(f"tolerance must be {rule}, got {tolerance!r}")
    if tol < TOLERANCE_FLOOR:
        raise ValueError(
            f"tolerance={tolerance!r} is below what float64 carries over an episode "
            f"({TOLERANCE_FLOOR:g}: near an unstable motion the sums' roundoff alone reaches "
            "1e-13-1e-12, 'rbenvs bench accuracy --roundoff'); pass tolerance >= "
            f"{TOLERANCE_FLOOR:g}, or integrate in extended precision outside the env "
            "(rbenvs.oracles.taylor_solution)"
        )
    return tol


def require_tolerance_check(check, tolerance):
    """``tolerance_check=``: ``False`` or ``True`` (a companion run checks the episode's global
    error against ``tolerance=``, which it then needs)."""
    if isinstance(check, str) and check == "refine":
        raise ValueError(
            "tolerance_check='refine' was removed (2026-11-29: each replay ran the episode again "
            "from its start); use tolerance_check=True, which ends the episode, flagged, where the "
            "estimate passes the tolerance, with a tighter tolerance= to hold it longer"
        )
    if not (check is True or check is False):
        raise ValueError(
            "tolerance_check must be False or True (a companion run checks the episode's global "
            f"error and ends the episode where it passes the tolerance), got {check!r}"
        )
    if check and tolerance is None:
        raise ValueError(
            "tolerance_check=True needs tolerance= (the relative error per episode the global "
            "error estimate is checked against)"
        )
    return check


def default_accuracy(tolerance, guard: str, default):
    """``(tolerance, accuracy)`` for a validated ``tolerance=``: the env's ``default`` tolerance
    (``"default"``: ``accuracy="default"``; none with ``guard="off"``, which takes ``substeps``
    steps whatever, or where the env declares none) or the user's (``"explicit"``)."""
    if isinstance(tolerance, str):
        return (
            (default, "default") if guard != "off" and default is not None else (None, "explicit")
        )
    return tolerance, "explicit"


def accuracy_settings(tolerance, horizon, check, guard: str, default, episode_steps):
    """``(tolerance, horizon, check, accuracy)`` from the keywords: ``tolerance`` validated and
    the env's ``default`` accuracy resolved, ``horizon`` the control periods it covers (``None``:
    the registered episode's ``episode_steps``, else 1000) and the measured check's setting."""
    tolerance = require_tolerance(tolerance)
    if tolerance is None and horizon is not None:
        raise ValueError(
            f"tolerance_horizon={horizon!r} is the span of control periods that tolerance= "
            "covers, and tolerance is None: pass tolerance= with it, or leave tolerance_horizon out"
        )
    tolerance, accuracy = default_accuracy(tolerance, guard, default)
    check = require_tolerance_check(check, tolerance)
    if horizon is None:
        horizon = 1000 if episode_steps is None else episode_steps
    else:
        horizon = require_int_in(
            "tolerance_horizon", horizon, 1, 10**12, " (control periods over which tolerance holds)"
        )
    return tolerance, horizon, check, accuracy


def takes_tolerance(cls) -> bool:
    """Whether ``tolerance=`` takes the scheme ``cls``: an error constant, and its leading error on
    a rotation in the phase (:func:`require_accuracy` says why)."""
    return cls.error_constant is not None and cls.error_in_phase


def tolerance_schemes() -> list:
    """The registered integrators ``tolerance=`` takes (:func:`takes_tolerance`)."""
    from ..integrators import INTEGRATORS

    return sorted(name for name, cls in INTEGRATORS.items() if takes_tolerance(cls))


def _amplitude_reason(integrator) -> str:
    return (
        f"integrator {integrator.name!r} errs in the amplitude (each step grows a rotation by "
        "sqrt(1 + (lambda h)^2)), which on a nonlinear rotation moves the frequency, so its phase "
        "error grows like T^2 and no per-period estimate bounds it without overestimating it many "
        "times (measured: 15 times the steps of its cheapest fixed substeps meeting the same "
        "tolerance)"
    )


def require_accuracy(integrator, guard: str, tolerance, accuracy: str, env_name: str):
    """``(tolerance, accuracy)`` the integrator runs under. The default accuracy of a scheme without
    an error constant (exact flows, the splitting, adaptive schemes) is none (unchecked); of one
    whose error is in the amplitude (euler) it is refused, with ``tolerance=None`` as the way out.
    An explicit tolerance needs a guard that acts on it and a scheme whose error it can estimate."""
    if tolerance is not None and accuracy != "explicit" and not takes_tolerance(type(integrator)):
        if integrator.error_constant is not None:  # (euler: its error is in the amplitude)
            raise ValueError(
                f"integrator {integrator.name!r} cannot be held to {env_name}'s default accuracy "
                f"(tolerance='default': {tolerance!r} relative over an episode): "
                f"{_amplitude_reason(integrator)}. Pass tolerance=None to run it unchecked (the "
                "stability bound alone, info['error_estimate'] None), or an integrator that takes "
                f"a tolerance, {tolerance_schemes()}"
            )
        return None, "explicit"
    if tolerance is None or accuracy != "explicit":
        return tolerance, accuracy
    if guard == "off":
        raise ValueError(
            f"tolerance={tolerance!r} needs guard='subdivide' or 'refuse': guard='off' takes "
            "substeps steps whatever the error"
        )
    if integrator.error_constant is None:
        raise ValueError(
            f"tolerance={tolerance!r} needs an integrator whose error it can estimate, "
            f"{tolerance_schemes()} (or integrator='auto'): one that declares an error constant "
            "(its error C lambda T (lambda h)^order on a rotation, rbenvs.integrators.error) with "
            f"its leading error in the phase; integrator {integrator.name!r} declares none (exact "
            "sub-flows err by the system's commutators, not by one rate; an adaptive scheme "
            "controls its own error)"
        )
    if not integrator.error_in_phase:
        # euler: a per-period sum either misses its T^2 phase error (with the state's own rate)
        # or overestimates it many times (with lambda): docs/accuracy.md
        raise ValueError(
            f"tolerance={tolerance!r} needs an integrator whose leading error on a rotation is in "
            f"the phase, {tolerance_schemes()} (or integrator='auto'): "
            f"{_amplitude_reason(integrator)}; with tolerance=None it runs at the guard's "
            "stability bound"
        )
    return tolerance, accuracy


def unstable_motion_warning(tolerance: float, unstable: str, check: bool) -> UnstableMotionWarning:
    """The construction warning for an explicit ``tolerance`` on a motion ``unstable`` by the
    system's own theorem (the env says why), and what the check does about it."""
    then = (
        "tolerance_check=True: a companion run estimates the episode's global error "
        "(info['global_error_estimate']) and the episode ends as a numerical failure where it "
        "passes the tolerance"
        if check
        else "over a horizon that spans it the error can end above the tolerance "
        "(tolerance_check=True estimates it and ends the episode as a numerical failure where it "
        "passes the tolerance)"
    )
    return UnstableMotionWarning(
        f"tolerance={tolerance!r}: {unstable}. The steps hold the error they commit within the "
        f"tolerance, but an unstable motion amplifies errors already made; {then} ('rbenvs bench "
        "accuracy --tolerance' measures it per scene; docs/integrators.md, 'Unstable motions')"
    )


# --- the rule: a period's steps and its error estimate ---


def _ungated(y):  # (a rule whose gate does not apply: every state is evaluated)
    return None


@dataclass(frozen=True)
class StepRule:
    """The rule of one env's periods: its system's rates, its integrator's region, its ``dt`` and
    its tolerance. ``active`` is false where nothing bounds the step (``guard="off"``, or an
    integrator with no bound for this system): a period then takes ``substeps`` steps."""

    rotation: tuple  # (fn, P): lambda(P, y)
    params: tuple  # (dt, bound, growth, k, p, kd) for step_ratio
    dissipation: tuple | None  # (fn, P): lambda_d(P, y, u), and below its c
    dissipation_step: float  # c: h <= c / lambda_d
    ceiling: float  # upper bound of lambda inside the observation bounds
    text: str
    active: bool
    error: tuple | None = None  # (C, p, dt) of error_estimate, with a tolerance
    accuracy_text: str = ""  # the accuracy bound in words ("" without a tolerance)
    # the state's own speed in the estimate: rotation is motion_rates' (fn, P), fn(P, y, u) ->
    # (lambda, mu, lambda_e); zero_control: the u of a state without one
    motion: bool = False
    zero_control: tuple = ()
    # a decaying mode's share of its error: (fn, Q), fn(Q, y, u, dt, p, lambda_d) -> a in [0, 1]
    share: tuple | None = None
    # the default accuracy's gate: (fn, P, limit), fn(P, y) -> Lambda, a cheap bound of the
    # error's rate within which substeps steps hold the budget (forms.gate_limit)
    gate: tuple | None = None
    gate_estimate: object = None  # with the gate: Lambda -> C Lambda dt (Lambda h)^p (substeps)

    @classmethod
    def build(
        cls,
        rates,
        region,
        dt: float,
        guard: str,
        integrator=None,
        tolerance=None,
        horizon=None,
        system=None,
        zero_control=(),
        gate_steps=None,
    ) -> StepRule:
        """The rule for ``rates`` (the system's :class:`~rbenvs.contracts.GuardRates` for
        ``region``) at ``dt`` under ``guard``; with ``tolerance`` (over ``horizon`` periods) also
        ``integrator``'s accuracy bound; ``gate_steps``: the default accuracy's ``substeps``."""
        if rates.rotation_bound is not None:  # the system's accuracy bound replaces the scheme's
            bound, growth = rates.rotation_bound, math.inf
        else:
            bound, growth = region.rotation, region.growth
        dissipation, step_d = None, math.inf
        if rates.dissipation is not None and region.dissipation != math.inf:
            dissipation = rates.dissipation
            step_d = rates.dissipation_margin * region.dissipation
        k, p, kd, error, share = 0.0, 1.0, 0.0, None, None
        if tolerance is not None:
            c, p = float(integrator.error_constant), float(integrator.order)
            # with a decaying rate the budget is shared: half for the rotation's error, which adds
            # up over the periods, half for the decaying mode's, which relaxes
            half = 0.5 if dissipation is not None else 1.0
            k, error = c / (half * math.log1p(tolerance) / horizon), (c, p, float(dt))
            if dissipation is not None:
                kd = c / (half * math.log1p(tolerance))
                share = mode_share(rates, integrator, c)
        active = guard != "off" and (
            bound != math.inf or growth != math.inf or dissipation is not None or error is not None
        )
        motion = (
            error is not None
            and system is not None
            and system.kernel_rhs is not None
            and (rates.error_blocks is not None or not system.hybrid)
            and integrator.error_in_phase
        )
        rotation, gate = rates.rotation, None
        if motion:
            # the state's own speed in the estimate, for a scheme whose leading error is in the
            # phase; a hybrid system keeps the rate alone unless it names the blocks its error is
            # measured on (its contact flags are not)
            rotation, gate = motion_form(rates, system, dt, horizon, p, k, gate_steps)
        # with the gate, its estimate C L dt (L h)^p at substeps steps (None without)
        gate_estimate = gate and gated_estimate(error[0], p, float(dt), float(dt) / gate_steps)
        step_text = step_d if dissipation is not None else None
        words = (rates, bound, growth, step_text, integrator, tolerance, horizon, motion, share)
        text, accuracy = describe(*words)
        params = (float(dt), float(bound), float(growth), float(k), float(p), float(kd))
        fields = (rotation, params, dissipation, step_d, rates.ceiling, text, active, error)
        return cls(*fields, accuracy, motion, tuple(zero_control), share, gate, gate_estimate)

    def gated(self, y):
        """The default accuracy's gate at ``y`` (floats or arrays): where every state lies within
        it, their periods' estimates at ``substeps`` steps (which they then take); else ``None``."""
        fn, params, limit = self.gate
        big = fn(params, y)
        return self.gate_estimate(big) if every(big <= limit) else None

    def plain_gate(self, substeps: int, plain_loop: bool):
        """:meth:`gated` for the float and numpy paths where a state within the gate may take the
        plain loop (``plain_loop``: a period without event, switches, compensated sums or
        companion) and the stability bound alone never asks for more than ``substeps``: its
        estimate is then the bound's (the compiled paths test the gate themselves); elsewhere a
        function that evaluates every state (returns ``None``)."""
        if self.gate is not None and plain_loop and self.dissipation is None:
            if self.stable(substeps):
                return self.gated
        return _ungated

    def rate(self, y, u=None):
        """``lambda`` at ``y`` (the rate both the bounds and the error estimate use); with
        :attr:`motion` ``(lambda, mu, lambda_e)`` under the control ``u`` (``None``: none)."""
        fn, p = self.rotation
        if self.motion:
            return fn(p, y, self.zero_control if u is None else u)
        return fn(p, y)

    def dissipation_rate(self, y, u):
        """``lambda_d`` at ``y`` under ``u`` (0 where the system has none, or where it is not
        positive); floats or arrays."""
        if self.dissipation is None:
            return 0.0
        fd, pd = self.dissipation
        rate = fd(pd, y, u)
        if type(rate) is float:
            return rate if rate > 0.0 else 0.0
        with np.errstate(invalid="ignore"):
            return np.where(rate > 0.0, rate, 0.0)

    def dissipation_share(self, y, u, rate):
        """The decaying mode's share ``a`` of its error at ``y`` under ``u`` and ``rate`` (1.0
        where the system declares none); floats or arrays."""
        if self.share is None:
            return 1.0
        fa, pa = self.share
        return fa(pa, y, u, self.params[0], self.params[4], rate)

    def batch_rates(self, y, u):
        """A batch's ``(lam, lam_d, a)`` at ``y`` under ``u`` (:meth:`plan`'s per element, as
        float64 arrays; ``lam`` a tuple of three with :attr:`motion`), its ratio not evaluated."""
        lam = self.rate(y, u)
        lam = (
            tuple(np.array(v, dtype=np.float64) for v in lam)
            if self.motion
            else np.array(lam, dtype=np.float64)
        )
        lam_d, a = 0.0, 1.0
        if self.dissipation is not None:
            lam_d = np.array(self.dissipation_rate(y, u), dtype=np.float64)
            with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                # (a blown-up element is reported by its step)
                a = np.array(self.dissipation_share(y, u, lam_d), dtype=np.float64)
            a = np.where(lam_d > 0.0, a, 1.0)  # (as plan: no decaying mode, no share of it)
        return lam, lam_d, a

    def estimate(self, lam, h, lam_d=0.0, a=1.0):
        """The relative error of a period started at rates ``lam`` (``lam_d`` a decaying one, ``a``
        its share) with internal step ``h`` (``None`` without a tolerance; the compiled vector
        step calls the same functions)."""
        if self.error is None:
            return None
        e = (
            motion_error_estimate(self.error, lam, h)
            if self.motion
            else error_estimate(self.error, lam, h)
        )
        if self.dissipation is None:
            return e
        return e + relaxation_estimate(self.error, lam_d, a, h)

    def binding(self, y, u) -> str:
        """Which bound asks for the most steps at ``y`` under ``u``, in words: the accuracy
        bound (with a tolerance) or the stability bound."""
        if self.error is None:
            return f"the step bound ({self.text})"
        dt, bound, growth, k, p, kd = self.params
        lam = self.rate(y, u)
        if self.motion:
            lam, mu, lam_e = lam
            accuracy = whole_root(k * (power(dt * lam_e, p) * (mu * dt)), p)
        else:
            accuracy = accuracy_steps(k, p, dt * lam)
        stability = step_ratio((dt, bound, growth, 0.0, 1.0, 0.0), lam)
        rate = self.dissipation_rate(y, u) if u is not None else 0.0
        if rate > 0.0:
            stability = max(stability, dt / (self.dissipation_step / rate))
            accuracy = max(
                accuracy, relaxation_steps(self.params, rate, self.dissipation_share(y, u, rate))
            )
        if not accuracy > stability:
            return f"the stability bound ({self.text})"
        return f"the tolerance ({self.accuracy_text})"

    def plan(self, y, u):
        """One state's ``(x, lam, lam_d, a)`` at ``y`` under ``u``, each evaluated once: the
        period's count (:meth:`count`) and its estimate (:meth:`estimate`) come from the same
        values (compiled: :func:`rbenvs.compiled.plan_kernel`)."""
        fn, p = self.rotation
        if self.motion:
            lam = fn(p, y, self.zero_control if u is None else u)
            x = step_ratio_motion(self.params, lam)
        else:
            lam = fn(p, y)
            x = step_ratio(self.params, lam)
        rate, a = 0.0, 1.0
        if self.dissipation is not None:
            fd, pd = self.dissipation
            r = fd(pd, y, u)
            if r > 0.0:
                rate = r
                x = max(x, self.params[0] / (self.dissipation_step / rate))
                a = self.dissipation_share(y, u, rate)
                if self.params[5] != 0.0:
                    x = max(x, relaxation_steps(self.params, rate, a))
        return x, lam, rate, a

    def ratio(self, y, u):
        """``x`` at ``y`` under ``u`` (the period needs ``ceil(x)`` steps); floats or arrays (a
        batch: :meth:`plan`'s rule per element)."""
        if not isinstance(y[0], np.ndarray):
            return self.plan(y, u)[0]
        x = (step_ratio_motion if self.motion else step_ratio)(self.params, self.rate(y, u))
        if self.dissipation is not None:
            dt, _, _, _, p, kd = self.params
            lam_d = self.dissipation_rate(y, u)
            positive = lam_d > 0.0
            with np.errstate(divide="ignore", invalid="ignore"):
                stable = dt / (self.dissipation_step / np.where(positive, lam_d, 1.0))
                x = np.maximum(x, np.where(positive, stable, 0.0))
                if kd != 0.0:
                    a = self.dissipation_share(y, u, lam_d)
                    accurate = whole_root(kd * (a * power(dt * lam_d, p)), p)
                    x = np.maximum(x, np.where(positive, accurate, 0.0))
        return x

    def idle(self, substeps: int) -> bool:
        """No state inside the observation bounds can need more than ``substeps`` steps."""
        return self._bounded(self.params, substeps)

    def stable(self, substeps: int) -> bool:
        """:meth:`idle` without the accuracy term (a batch's states within the gate then take
        ``substeps`` unevaluated)."""
        dt, bound, growth = self.params[:3]
        return self._bounded((dt, bound, growth, 0.0, 1.0, 0.0), substeps)

    def _bounded(self, params, substeps: int) -> bool:
        """:func:`step_ratio` with ``params`` within ``substeps`` up to the rate's ceiling."""
        if not self.active:
            return True
        if self.dissipation is not None:
            return False
        return step_ratio(params, self.ceiling * (1.0 + 1e-9)) <= substeps

    def count(self, x: float, substeps: int) -> int:
        """One state's count from its ratio ``x`` (:meth:`plan`): :meth:`steps`' rule."""
        if not self.active or x <= substeps:
            return substeps
        return math.ceil(x) if x <= MAX_INTERNAL_STEPS else MAX_INTERNAL_STEPS + 1

    def steps(self, y, u, substeps: int):
        """``max(substeps, ceil(x))``, or ``MAX_INTERNAL_STEPS + 1`` (a numerical failure) for a
        non-finite or absurd ``x``: an int, or an int array for a batch."""
        if not self.active:
            return substeps
        x = self.ratio(y, u)
        if type(x) is float or np.ndim(x) == 0:
            return self.count(float(x), substeps)
        return self.counts(np.broadcast_to(x, np.shape(y[0])), substeps)

    def counts(self, x, substeps: int):
        """A batch's counts from its ratios ``x`` (an array): :meth:`steps`' rule."""
        if not self.active:
            return np.full(np.shape(x), substeps, dtype=np.int64)
        with np.errstate(invalid="ignore"):
            n = np.where(
                x <= MAX_INTERNAL_STEPS,
                np.ceil(np.where(x <= MAX_INTERNAL_STEPS, x, 0.0)),
                MAX_INTERNAL_STEPS + 1,
            )
        return np.maximum(substeps, n).astype(np.int64)


def describe(rates, bound, growth, step_d, integrator, tolerance, horizon, motion, share):
    """``(text, accuracy_text)``: a rule in words for the messages that cite it (``step_d``: the
    decaying rate's step bound, ``None`` without one; ``share``: the decaying mode's share, if
    the system declares one), and its tolerance's part (``""`` without a tolerance)."""
    text = rates.text
    if bound != math.inf:
        grows = f" and lambda^2 h dt <= {growth}" if growth != math.inf else ""
        text = f"lambda h <= {bound}{grows}, {text}"
    if step_d is not None:
        text += f"; h <= {step_d:.6g} / lambda_d"
    if tolerance is None:
        return text, ""
    p = integrator.order
    sharp = motion and rates.accuracy is not None
    half = "half of " if step_d is not None else ""
    accuracy = (
        f"error C {'mu' if motion else 'lambda'} dt ({'lambda_e' if sharp else 'lambda'} h)^{p} "
        f"<= {half}log(1 + tolerance) / {horizon} per period"
    )
    if step_d is not None:
        accuracy += f" and C {'a ' if share else ''}(lambda_d h)^{p} <= half of log(1 + tolerance)"
    accuracy += (
        f" (tolerance={tolerance!r} over tolerance_horizon={horizon} periods; {integrator.name}: "
        f"order {p}, error constant C = {float(integrator.error_constant):g}"
    )
    if motion:
        accuracy += "; mu: the state's own relative speed, rbenvs.stepsize.forms.motion_rates"
    if sharp:
        accuracy += f"; lambda_e: the system's bound of its Jacobian, {rates.accuracy[0].__name__}"
    if share:
        accuracy += "; a: the decaying mode's share of the error"
    accuracy += ")"
    return f"{text}; {accuracy}", accuracy


# --- the choice of scheme and the refusals at the start ---


def cheapest_scheme(schemes, system, tolerance, model_with, speed: float, dissipation: float):
    """``integrator="auto"``: of the ``schemes`` that ``tolerance=`` and ``system`` take, the one
    whose steps at the fastest start (:func:`start_steps`) times its evaluations a step cost the
    least (ties: the first); ``model_with(scheme)``: the env's model with that scheme."""
    if tolerance is None:
        raise ValueError(
            "integrator='auto' chooses the scheme that meets tolerance= at the least cost: pass "
            "tolerance= (a relative error per episode)"
        )
    best = None
    for scheme in schemes:
        if not takes_tolerance(type(scheme)) or not scheme.evaluations:
            continue
        if not scheme.supports(system):
            continue
        model = model_with(scheme)
        x = start_steps(model, speed, dissipation)[0]
        steps = max(model.substeps, math.ceil(x)) if x <= MAX_INTERNAL_STEPS else math.inf
        cost = steps * scheme.evaluations
        if best is None or cost < best[0]:
            best = (cost, scheme)
    if best is None:
        raise ValueError(
            f"integrator='auto' found no scheme with an error constant for {type(system).__name__}"
        )
    return best[1]


def start_steps(model, speed: float, dissipation: float = 0.0) -> tuple[float, str, bool]:
    """``(x, rule, by_tolerance)``: the steps per period (``ceil(x)``) the rule asks for at the
    fastest start (``speed`` bounds ``|Omega|``, ``dissipation`` the decaying rate), the rule in
    words, and whether only the tolerance asks for more than ``MAX_INTERNAL_STEPS`` (a scheme
    without a bound counts one radian of the fastest rate per step)."""
    integrator, dt = model.integrator, model.dt
    region = integrator.region
    if not region.bounded:
        region = dataclasses.replace(
            region, rotation=1.0, reason="one radian of the fastest rate per step"
        )
    rates = model.system.guard_rates(region, speed, dt)
    rule = StepRule.build(
        rates, region, dt, "subdivide", integrator, model.tolerance, model.horizon
    )
    x = step_ratio(rule.params, rates.ceiling)
    d_stable = 0.0
    if rule.dissipation is not None and dissipation > 0.0:
        d_stable = dt / (rule.dissipation_step / dissipation)
        # (the accuracy term 0 without a tolerance; the mode's full share: no state yet)
        x = max(x, d_stable, relaxation_steps(rule.params, dissipation, 1.0))
    if rule.error is None:
        return x, rule.text, False
    if not max(stability_ratio(*rule.params[:3], rates.ceiling), d_stable) <= MAX_INTERNAL_STEPS:
        return x, rule.text, False
    # only the tolerance asks for more: say so, with the reason
    p = integrator.order
    return (
        x,
        f"to keep the error of {model.horizon} periods within it ({rule.accuracy_text}): at a "
        f"fixed step an order-{p} scheme's error grows without bound, like lambda T (lambda "
        f"h)^{p}, so the steps a tolerance costs grow like (lambda T)^{(p + 1) / p:.3g} / "
        f"tolerance^{1 / p:.3g}; raise tolerance, lower tolerance_horizon, or use a "
        "higher-order integrator",
        True,
    )


def require_resolvable(model, speed, dissipation, env_name: str, rate_sources: str) -> None:
    """Refuse at construction a period no run could resolve (more than ``MAX_INTERNAL_STEPS``
    steps at the start: ``dt=1e300``, a rate far above the step), naming the keywords that set
    the rate (``rate_sources``) or the tolerance; ``guard="off"`` opts out."""
    if model.guard == "off":
        return
    x, rule, by_tolerance = start_steps(model, speed, dissipation)
    if x <= MAX_INTERNAL_STEPS:
        return
    name = model.integrator.name
    if by_tolerance:
        default = (
            f" (tolerance='default': {env_name}'s default accuracy; tolerance=None runs "
            "unchecked, the stability bound alone)"
            if model.accuracy != "explicit"
            else ""
        )
        raise ValueError(
            f"tolerance={model.tolerance!r}{default} cannot be met: at the start the integrator "
            f"{name!r} needs {x:.3g} internal steps per control period, more than "
            f"MAX_INTERNAL_STEPS = {MAX_INTERNAL_STEPS}, {rule}"
        )
    raise ValueError(
        f"dt={model.dt!r} s cannot be resolved: at the start the integrator {name!r} needs "
        f"{x:.3g} internal steps per control period ({rule}), more than MAX_INTERNAL_STEPS = "
        f"{MAX_INTERNAL_STEPS}; lower dt, or check {rate_sources}, which set the fastest rate"
    )


# --- the measured check: a companion run at twice the step ---


def tolerance_blocks(system) -> tuple:
    """The ``(start, stop)`` blocks of the state a tolerance is measured on: the layout's, less
    a hybrid system's horizontal position (no scale of the motion), contact flags and hops."""
    return tuple(
        tuple(span)
        for name, span in system.layout.items()
        if not (system.hybrid and name in ("position", "contact", "hops"))
    )


def companion_ratio(p: float) -> float:
    """``2^p - 1``: the companion's global error over the main run's, less one (order ``p``)."""
    return 2.0 ** float(p) - 1.0


def companion_steps(n):
    """The companion's steps beside a checked period of ``n`` (even) steps (ints or arrays)."""
    return n // 2


class GlobalErrorCheck:
    """The measured check of one env (or one batch): a companion run that takes every period's
    even count ``n`` of steps as ``n / 2`` steps of twice the size. An order-``p`` scheme's
    companion commits ``2^p`` times the run's local error, so their difference ``D`` is ``2^p -
    1`` times the run's global error, amplification included; reported is ``MARGIN D / (2^p -
    1)``, and where it passes the tolerance the episode ends as a numerical failure at the last
    state within it (why even counts, and the checks against exact solutions: docs/accuracy.md,
    "Unstable motions")."""

    __slots__ = ("engine", "blocks", "ratio", "runs", "periods")

    def __init__(self, engine):
        self.engine = engine
        self.blocks = tolerance_blocks(engine.system)
        self.ratio = companion_ratio(engine.integrator.order)
        self.runs = None  # the companion's state and compensation (yc, cc)
        self.periods = 0

    def restart(self, y, mask=None, engine=None):
        """The companion starts at ``y`` (a batch: at the rows ``mask`` of ``y``, or all; with
        ``param_ranges`` beside a new episode's ``engine``)."""
        if engine is not None:
            self.engine = engine
        if mask is None or self.runs is None:
            self.runs = (y, self.engine.fresh_comp)
            self.periods = (
                np.zeros(len(y[0]), dtype=np.int64) if isinstance(y[0], np.ndarray) else 0
            )
            return
        yc, cc = self.runs
        yc = tuple(np.where(mask, c, r) for c, r in zip(y, yc))
        if cc is not None:
            cc = tuple(np.where(mask, 0.0, c) for c in cc)
        self.runs = (yc, cc)
        self.periods = np.where(mask, 0, self.periods)

    def period(self, y, u, n):
        """After a period that took the run to ``y`` in ``n`` steps under ``u``: the companion's
        period, and the global error estimate of ``y`` (floats, or arrays for a batch)."""
        self.runs = self.engine.companion(self.runs[0], u, n, self.runs[1])
        self.periods = self.periods + 1
        return MARGIN * relative_difference(self.blocks, y, self.runs[0]) / self.ratio

    def batch_period(self, y, u, h, restart):
        """A batch's :meth:`period` beside the one that took the states to ``y`` under ``u`` in
        steps ``h`` (0 where a sub-env restarts): ``(estimates, inaccurate)``, the mask of
        sub-envs whose estimate passed the tolerance (``None`` where none did)."""
        counts = np.rint(self.engine.dt / np.broadcast_to(h, np.shape(y[0]))).astype(np.int64)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            estimates = np.where(restart, 0.0, self.period(y, u, counts))
            inaccurate = estimates > self.engine.tolerance
        return estimates, (inaccurate if inaccurate.any() else None)

    def step_one(self, y0, a, plain):
        """The engine's :meth:`~rbenvs.core.step.Engine.step_one` with the companion's period
        after it: ``info["global_error_estimate"]``, or the episode's end at ``y0``."""
        engine = self.engine
        comp0 = engine.comp  # (the run's compensation at y0: kept with y0 where the period is not)
        out = engine.step_one(y0, a, plain)
        info = out[4]
        if info["numerical_failure"]:
            # no state to compare: the check cannot vouch for it (a batch's companion reads inf)
            info["global_error_estimate"] = math.inf
            return out
        n = int(round(engine.dt / info["internal_step"]))
        runs0 = self.runs
        e = self.period(out[0], out[5], n)
        if e > engine.tolerance:  # the companion and the run stay with the state kept
            self.runs, self.periods = runs0, self.periods - 1
            why = inaccurate_text(e, self.periods + 1, engine.tolerance, engine.dt)
            out = engine.inaccurate_one(y0, a, info["internal_step"], plain, comp0, why)
            out[4]["global_error_estimate"] = e
            return out
        info["global_error_estimate"] = e
        return out


def inaccurate_text(estimate, periods, tolerance, dt) -> str:
    """Why an episode ended where its global error ``estimate`` passed ``tolerance`` after
    ``periods`` control periods of ``dt``, and what holds it longer (the warning's words)."""
    return (
        f"the global error estimate {float(estimate):.3g} passed tolerance={tolerance!r} after "
        f"{int(periods)} periods ({int(periods) * dt:.6g} s; tolerance_check: a companion run at "
        "twice the step measures the error the state carries, errors the motion amplified "
        "included, which the steps' estimate does not budget for; more steps per period hold it "
        "longer: a tighter tolerance= or substeps= (the least count), and 'rbenvs bench accuracy "
        "--tolerance' shows the counts that hold each shipped scene)"
    )

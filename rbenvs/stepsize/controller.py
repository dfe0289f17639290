"""The step controller: how many internal steps a control period takes, what error it commits and
what an episode carries, from declarations only; its settings the stability bound alone
(``tolerance=None``), an error bound (``tolerance=``, the env's default accuracy included) and the
measured check (``tolerance_check=True``, the companion run below).

**Stability.**

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

**Accuracy** (``tolerance=``, a relative error per episode of ``N`` control periods): a scheme
of order ``p`` and error constant ``C`` (declared by the integrator, measured by
:func:`rbenvs.integrators.error.measure_error_constant`) commits, over a period of ``n`` steps
``h = dt / n`` at rate ``lambda``, the relative error

    e = C lambda dt (lambda h)^p                                  (:func:`error_estimate`)

(``n`` local errors ``C (lambda h)^(p+1)``; a rotation carries an error on without amplifying
it). Errors of successive periods compound at worst as ``prod(1 + e_k) - 1 <=
exp(sum e_k) - 1``, which stays within the tolerance when every period meets
``e <= b = log(1 + tolerance) / N``. With ``z = lambda dt`` that asks for ``n^p >= (C / b)
z^(p+1)``: the fewest such whole ``n`` (:func:`accuracy_steps`) is a fourth term of ``x``,
and ``info["error_estimate"]`` reports ``e`` of the steps taken. Where the system also declares
a decaying rate ``lambda_d`` the budget is shared: half for the rotation (per period, as above),
half for the decaying mode, ``C a (lambda_d h)^p <= log(1 + tolerance) / 2`` (its error relaxes
within ``1 / lambda_d`` instead of adding up: :func:`relaxation_steps`; ``a <= 1`` the share of
it the mode's error is, where the system declares it: a saturated friction is not stiff). For a
scheme whose
leading error is in the phase (rk4) on a system with a pure vector field, ``lambda dt`` in front
becomes ``mu dt``, the state's own relative speed (:func:`motion_rates`, :func:`step_ratio_motion`).
The estimate assumes the motion
does not amplify errors (a stable spin, a precession); near an unstable equilibrium (the
intermediate axis, an upright top below its critical spin) an error grows with the motion and
no step bounds it for long.

Everything here works on floats (one state) and arrays (a batch) with the same IEEE
operations, so a sub-env of a vector env takes exactly its single env's steps; the pure
:func:`~rbenvs.stepsize.forms.step_ratio` is what the compiled batch step calls (the accuracy term's
fractional power is corrected to the exact whole count by integer powers, so a last-bit difference
between libm's ``pow`` and numpy's cannot change a count).

**The measured check** (``tolerance_check=True``): a companion run at twice the step estimates
the episode's global error, amplification included (:mod:`rbenvs.stepsize.check`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..dynamics.validation import did_you_mean
from ..rotations import every, power
from .forms import (
    accuracy_steps,
    error_estimate,
    gate_limit,
    gated_estimate,
    motion_error_estimate,
    motion_rates,
    relaxation_estimate,
    relaxation_steps,
    step_ratio,
    step_ratio_motion,
    whole_root,
)

__all__ = [
    "MAX_INTERNAL_STEPS",
    "GUARDS",
    "DEFAULT_TOLERANCE",
    "TOLERANCE_FLOOR",
    "UnstableMotionWarning",
    "StepRule",
    "require_guard",
    "require_tolerance",
    "default_accuracy",
    "takes_tolerance",
    "tolerance_schemes",
    "require_accuracy",
    "unstable_motion_warning",
]

# More internal steps than this in one control period is treated as a numerical failure.
MAX_INTERNAL_STEPS = 1_000_000

# ``guard=`` of every env: when the internal step ``dt / substeps`` is beyond what the
# integrator can resolve at the current state, ``"subdivide"`` (default) splits the period
# into more equal steps, ``"refuse"`` raises ``ValueError`` from ``step``, ``"off"`` takes
# ``substeps`` steps regardless (a blow-up then ends the episode as a numerical failure).
GUARDS = ("subdivide", "refuse", "off")


class UnstableMotionWarning(UserWarning):
    """``tolerance=`` on a motion that is unstable by the system's own theorem (an upright top
    below its critical spin, a spin about the intermediate axis, a tippe top that inverts): the
    steps hold the error they commit within the tolerance, but the motion amplifies errors
    already made, so over a horizon that spans the instability the error can end above it."""


def require_guard(guard) -> str:
    if not isinstance(guard, str) or guard not in GUARDS:
        raise ValueError(
            f"guard must be one of {list(GUARDS)}, got {guard!r}{did_you_mean(guard, GUARDS)}"
        )
    return guard


# ``tolerance=``'s default: the env's default accuracy (RigidBodyEnv.default_tolerance)
DEFAULT_TOLERANCE = "default"
# the least tolerance float64 carries over an episode: near the free body's separatrix the motion
# amplifies the (compensated) sums' roundoff to about this (rbenvs bench accuracy --roundoff,
# --floor)
TOLERANCE_FLOOR = 1e-12


def require_tolerance(tolerance):
    """``tolerance=``: ``"default"`` (the env's default accuracy), ``None`` (no accuracy bound)
    or a finite number with ``TOLERANCE_FLOOR <= tolerance < 1`` (a relative error per episode)."""
    if tolerance is None or (isinstance(tolerance, str) and tolerance == DEFAULT_TOLERANCE):
        return tolerance
    rule = (
        f"{DEFAULT_TOLERANCE!r} (the env's default accuracy), None (unchecked: the stability bound "
        "alone) or a finite number with "
        f"{TOLERANCE_FLOOR:g} <= tolerance < 1 (the relative error allowed over an episode)"
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
            f"({TOLERANCE_FLOOR:g}: near an unstable "
            "motion the sums' roundoff alone reaches 1e-13-1e-12, 'rbenvs bench accuracy "
            "--roundoff'); pass tolerance >= "
            f"{TOLERANCE_FLOOR:g}, or integrate in extended precision outside the env "
            "(rbenvs.oracles.taylor_solution)"
        )
    return tol


def default_accuracy(tolerance, guard: str, default):
    """``(tolerance, accuracy)`` for a validated ``tolerance=``: the env's ``default`` tolerance
    (``"default"``: ``accuracy="default"``; none with ``guard="off"``, which takes ``substeps``
    steps whatever, or where the env declares none) or the user's (``"explicit"``)."""
    if isinstance(tolerance, str):
        return (
            (default, "default") if guard != "off" and default is not None else (None, "explicit")
        )
    return tolerance, "explicit"


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
        "sqrt(1 + (lambda h)^2)), which on a "
        "nonlinear rotation moves the frequency, so its phase error grows like T^2 and no "
        "per-period estimate bounds it without "
        "overestimating it many times (measured: 15 times the steps of its cheapest fixed substeps "
        "meeting the same tolerance)"
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
                "(tolerance='default': "
                f"{tolerance!r} relative over an episode): {_amplitude_reason(integrator)}. Pass "
                "tolerance=None to run it "
                "unchecked (the stability bound alone, info['error_estimate'] None), or an "
                "integrator that takes a tolerance, "
                f"{tolerance_schemes()}"
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
            f"{tolerance_schemes()} (or integrator='auto'): one that declares an "
            "error constant (its error C lambda T (lambda h)^order on a rotation, "
            "rbenvs.integrators.error) with its leading error in the "
            f"phase; integrator {integrator.name!r} declares none "
            "(exact sub-flows err by the system's commutators, not by one rate; an adaptive scheme "
            "controls its own error)"
        )
    if not integrator.error_in_phase:
        # euler: its leading error grows a rotation's amplitude (by sqrt(1 + (lambda h)^2) a
        # step); on a nonlinear rotation the amplitude sets the frequency, so the phase error
        # grows like T^2 and a per-period sum either misses it (with the state's own rate:
        # 2.7 times the tolerance) or overestimates it (with lambda: 16 times the error, 15
        # times the steps of the cheapest fixed substeps; docs/integrators.md)
        raise ValueError(
            f"tolerance={tolerance!r} needs an integrator whose leading error on a rotation is in "
            f"the phase, {tolerance_schemes()} "
            f"(or integrator='auto'): {_amplitude_reason(integrator)}; with tolerance=None it runs "
            "at the guard's stability bound"
        )
    return tolerance, accuracy


def unstable_motion_warning(tolerance: float, unstable: str, check: bool) -> UnstableMotionWarning:
    """The construction warning for an explicit ``tolerance`` on a motion ``unstable`` by the
    system's own theorem (the env says why), and what the check does about it."""
    then = (
        "tolerance_check=True: a companion run estimates the episode's global error "
        "(info['global_error_estimate']) "
        "and the episode ends as a numerical failure where it passes the tolerance"
        if check
        else "over a horizon that spans it the error can end above the tolerance "
        "(tolerance_check=True estimates it and ends "
        "the episode as a numerical failure where it passes the tolerance)"
    )
    return UnstableMotionWarning(
        f"tolerance={tolerance!r}: {unstable}. The steps hold the error they commit within the "
        "tolerance, but an unstable "
        f"motion amplifies errors already made; {then} ('rbenvs bench accuracy --tolerance' "
        "measures it per scene; "
        f"docs/integrators.md, 'Unstable motions')"
    )


@dataclass(frozen=True)
class StepRule:
    """The guard of one env: its system's rates, its integrator's region and its ``dt``.

    ``active`` is false where nothing bounds the step (``guard="off"``, or an integrator with
    no bound for this system): the period then always takes ``substeps`` steps. ``error``:
    ``(C, p, dt)`` of :func:`error_estimate` where a tolerance is set, else ``None``.
    """

    rotation: tuple  # (fn, P): lambda(P, y)
    params: tuple  # (dt, bound, growth, k, p, kd) for step_ratio
    dissipation: tuple | None  # (fn, P): lambda_d(P, y, u), and below its c
    dissipation_step: float  # c: h <= c / lambda_d
    ceiling: float  # upper bound of lambda inside the observation bounds
    text: str
    active: bool
    error: tuple | None = None  # (C, p, dt) of error_estimate, with a tolerance
    accuracy_text: str = ""  # the accuracy bound in words ("" without a tolerance)
    # with a tolerance on a system with a pure vector field: rotation is motion_rates' (fn, P),
    # fn(P, y, u) -> (lambda, mu), and zero_control the u of internal_steps(y, None)
    motion: bool = False
    zero_control: tuple = ()
    # with a tolerance and a decaying rate: the system's (fn, Q), Q = (P, c_f / C) (c_f the scheme's
    # forced_error_constant, 0 if none), fn(Q, y, u, dt, p, lambda_d) -> a in [0, 1], the share of
    # C (lambda_d h)^p its decaying mode's error is (relaxation_steps); None: a = 1
    share: tuple | None = None
    # the default accuracy's gate (motion_rates'): (fn, P, limit), fn(P, y) -> Lambda, a cheap
    # bound of the error's rate, which holds the period within its budget at substeps steps where
    # Lambda <= limit (forms.gate_limit); a batch tests it first (rbenvs.compiled's gate loop);
    # None: no gate
    gate: tuple | None = None
    # with the gate: estimate(Lambda) = C Lambda dt (Lambda h)^p at substeps steps (gated_estimate)
    gate_estimate: object = None

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
        ``region``) at control period ``dt`` under ``guard``; with ``tolerance`` (a relative
        error over ``horizon`` periods) also the accuracy bound of ``integrator`` (its
        ``order`` and ``error_constant``). ``gate_steps``: the default accuracy's ``substeps``,
        with which the rates test a cheap bound first (:func:`motion_rates`' gate)."""
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
                share = _mode_share(rates, integrator, c)
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
            rotation, gate = _motion_rates(rates, system, dt, horizon, p, k, gate_steps)
        # with the gate, its estimate C L dt (L h)^p at substeps steps (None without)
        gate_estimate = gate and gated_estimate(error[0], p, float(dt), float(dt) / gate_steps)
        step_text = step_d if dissipation is not None else None
        words = (rates, bound, growth, step_text, integrator, tolerance, horizon, motion, share)
        text, accuracy = describe(*words)
        params = (float(dt), float(bound), float(growth), float(k), float(p), float(kd))
        fields = (rotation, params, dissipation, step_d, rates.ceiling, text, active, error)
        return cls(*fields, accuracy, motion, tuple(zero_control), share, gate, gate_estimate)

    def gated(self, y):
        """The default accuracy's gate at the states ``y`` (:attr:`gate`; floats or arrays): where
        every state lies within the cheap bound ``Lambda``, their periods' estimates ``C Lambda dt
        (Lambda h)^p`` at ``substeps`` steps (the rates :func:`motion_rates` gives there: the
        period then takes ``substeps`` steps); else ``None``."""
        fn, params, limit = self.gate
        big = fn(params, y)
        return self.gate_estimate(big) if every(big <= limit) else None

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
        """``a`` of :func:`relaxation_steps` at ``y`` under ``u`` with the guard's decaying rate
        ``rate`` there: the system's declared share of its decaying mode, 1.0 where it declares
        none; floats or arrays."""
        if self.share is None:
            return 1.0
        fa, pa = self.share
        return fa(pa, y, u, self.params[0], self.params[4], rate)

    def estimate(self, lam, h, lam_d=0.0, a=1.0):
        """The relative error of a period started at rates ``lam`` (and ``lam_d``, a decaying
        one, its error's share ``a``) with internal step ``h``: :func:`error_estimate` plus
        ``C a (lam_d h)^p`` where the system has a decaying rate (``None`` without a tolerance)."""
        if self.error is None:
            return None
        # (the compiled vector step's estimate calls the same functions:
        # rbenvs.compiled.vector_kernel)
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
        """One state's (floats) ``(x, lam, lam_d, a)`` at ``y`` under ``u``: the ratio ``x`` of
        :meth:`ratio`, the rate(s) of :meth:`rate`, the decaying rate ``lam_d`` of
        :meth:`dissipation_rate` (0 without one) and its share ``a`` (:meth:`dissipation_share`;
        1 where ``lam_d`` is 0, whose term is then 0), each evaluated once: the period's count
        (:meth:`count`) and its error estimate (:meth:`estimate`) come from the same values
        (compiled: :func:`rbenvs.compiled.plan_kernel`, the same lines as the kernels' count)."""
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
        """``x`` at ``y`` under ``u`` (the period needs ``ceil(x)`` steps); floats or arrays."""
        if not isinstance(y[0], np.ndarray):
            return self.plan(y, u)[0]
        fn, p = self.rotation
        if self.motion:
            x = step_ratio_motion(self.params, fn(p, y, self.zero_control if u is None else u))
        else:
            x = step_ratio(self.params, fn(p, y))
        if self.dissipation is not None:
            fd, pd = self.dissipation
            rate = fd(pd, y, u)
            dt = self.params[0]
            if type(rate) is float:  # (a rate constant over the batch)
                if rate > 0.0:
                    x = max(x, dt / (self.dissipation_step / rate))
                    if self.params[5] != 0.0:
                        x = max(
                            x,
                            relaxation_steps(self.params, rate, self.dissipation_share(y, u, rate)),
                        )
            else:
                with np.errstate(divide="ignore", invalid="ignore"):
                    h_d = np.where(
                        rate > 0.0, self.dissipation_step / np.where(rate > 0.0, rate, 1.0), np.inf
                    )
                    x = np.maximum(x, dt / h_d)
                    if self.params[5] != 0.0:
                        _, _, _, _, p, kd = self.params
                        positive = rate > 0.0
                        r = np.where(positive, rate, 0.0)
                        a = self.dissipation_share(y, u, r)
                        x = np.maximum(
                            x, np.where(positive, whole_root(kd * (a * power(dt * r, p)), p), 0.0)
                        )
        return x

    def idle(self, substeps: int) -> bool:
        """True when no state inside the observation bounds can need more than ``substeps``
        steps (then no check needs to run: the plain loop is exact)."""
        return self._bounded(self.params, substeps)

    def stable(self, substeps: int) -> bool:
        """True when the stability bound alone can never ask for more than ``substeps`` steps
        inside the observation bounds (:meth:`idle` without the accuracy term): with a
        :attr:`gate`, a batch's states within it then take ``substeps`` unevaluated."""
        dt, bound, growth = self.params[:3]
        return self._bounded((dt, bound, growth, 0.0, 1.0, 0.0), substeps)

    def _bounded(self, params, substeps: int) -> bool:
        """Whether :func:`step_ratio` with ``params`` stays within ``substeps`` up to the rate's
        ceiling."""
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
        """``max(substeps, ceil(x))``, or ``MAX_INTERNAL_STEPS + 1`` (refused: a numerical
        failure) for a non-finite or absurd ``x``: an int, or an int array for a batch."""
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


def _mode_share(rates, integrator, c: float):
    """The decaying mode's share of its error (``StepRule.share``): the system's declared
    ``(fn, P)`` with the scheme's forced-mode error constant over ``C`` (0: none) added to ``P``;
    ``None`` where the system declares none (the share is then 1)."""
    if rates.dissipation_share is None:
        return None
    fn, params = rates.dissipation_share
    forced = integrator.forced_error_constant
    return fn, (params, 0.0 if forced is None else float(forced) / c)


def _motion_rates(rates, system, dt: float, horizon: int, p: float, k: float, gate_steps):
    """``(rotation, gate)`` of a rule whose estimate takes the state's own speed: the generated
    :func:`motion_rates` with its parameters, and the default accuracy's gate ``(fn, P, limit)``
    (``None`` without ``gate_steps``, or with rotating blocks, whose carried term no cheap bound
    covers)."""
    rhs, layout = system.kernel_rhs, system.layout
    names = rates.error_blocks if rates.error_blocks is not None else tuple(layout)
    blocks = tuple(tuple(layout[n]) for n in names)
    rotating = tuple((tuple(layout[q]), tuple(layout[d])) for q, d in rates.rotating_blocks)
    extra, tail, gate = {}, (), None
    if rotating:  # (span: the mean time from a period to the horizon's end)
        extra.update(rotating=rotating, order=p, span=(float(horizon) + 1.0) * float(dt) / 2.0)
    if rates.speed is not None:  # the system's bound of its speed over a period
        extra.update(speed_bound=rates.speed[0], dt=float(dt))
        tail = (rates.speed[1],)
    sharp = rates.accuracy is not None  # the system's sharper rate of the error, lambda_e
    if gate_steps is not None and not rotating and (not sharp or rates.accuracy_bound is not None):
        # C L dt (L dt / substeps)^p <= budget, i.e. (L dt)^(p + 1) <= substeps^p / k, solved
        # once for its largest L (L: the system's cheap bound of lambda_e, else lambda)
        fn, params = rates.accuracy_bound if sharp else rates.rotation
        limit = gate_limit(float(dt), p + 1.0, float(gate_steps) ** p / k)
        extra.update(gate=True, gate_rate=fn if sharp else None)
        tail += ((limit, params if sharp else ()),)
        gate = (fn, params, limit)
    accuracy, accuracy_p = rates.accuracy if sharp else (None, ())
    rate = motion_rates(rates.rotation[0], rhs[0], blocks, accuracy, **extra)
    return (rate, (rates.rotation[1], rhs[1], accuracy_p) + tail), gate


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

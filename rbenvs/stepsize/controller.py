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

**The measured check** (``tolerance_check=True``, :class:`GlobalErrorCheck`). The error bound above
holds the error each period *commits*. A motion that is unstable by
its own theorem (a tippe top that inverts, a top below its critical spin, a spin near the
intermediate axis) amplifies errors already made, by a factor no local estimate knows in
advance, so the error at the end of an episode can pass the tolerance although every period
met its share. The classical remedy is Richardson's: a second solution of the same problem with
a known ratio of steps, whose difference from the first is a multiple of the first's global
error, amplification included (it rests on the asymptotic expansion of the global error,
``y_h(t) - y(t) = e_p(t) h^p + O(h^(p+1))`` with ``e_p`` carried by the linearised flow: Hairer,
Norsett and Wanner, *Solving Ordinary Differential Equations I*, 2nd ed., Springer 1993,
section II.8; docs/physics.md's references).

Here every period takes an even count ``n`` of steps ``h`` (the guard's count, plus one where
it is odd), and the companion starts with the state at every reset and runs each control period
under the same control with ``n / 2`` steps ``2 h``. A scheme of order ``p`` commits the local
error ``c h^(p+1)`` per step, so the companion's period commits ``2^p`` times the main run's;
while both are in the asymptotic range their difference ``D`` is ``2^p - 1`` times the main
run's global error, carried by the same linearised flow, amplification included:
``E = D / (2^p - 1)``, the classical estimate, exact up to the next order's share. Reported
(``info["global_error_estimate"]``) is ``MARGIN = 1.25`` times it, and where it passes the
tolerance the episode ends as a numerical failure at the last state within it
(``tests/test_global_error.py`` and ``rbenvs verify``'s tolerance rows check the estimate
against the free body's exact solution and a DOP853 reference of the tippe top that hops). A
ratio that changed from period to period would weight the periods' errors unequally, and errors
that cancel over an orbit, such as a free body's energy error near its separatrix, would not
cancel in ``D``: hence the even counts.

Roundoff the motion amplifies (near the separatrix) enters ``D`` at ``1 / (2^p - 1)`` of its
size, but the check ends such an episode where the steps' error passes the tolerance, before the
roundoff does: ``rbenvs bench accuracy --floor`` (20 runs 0.0001-0.01 rad/s off the intermediate
axis, tolerances 1e-8 to 1e-12, against mpmath's Taylor series) is within on every period
returned. The runs (the main run's and the companion's) are the engine's
(:meth:`rbenvs.core.period.Period.companion`), compiled where numba is installed
(:class:`rbenvs.compiled.CheckedRuns`, the float path's bits); ``D`` is measured as
:mod:`rbenvs.bench.tolerance` measures the error against its reference: the largest over the
state's blocks (:func:`tolerance_blocks`) of ``|y_b - yc_b| / |y_b|``, on one state (floats) or
a batch (arrays).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..dynamics.validation import did_you_mean
from ..rotations import power
from .forms import (
    accuracy_steps,
    error_estimate,
    gate_limit,
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
    "MARGIN",
    "UnstableMotionWarning",
    "StepRule",
    "GlobalErrorCheck",
    "require_guard",
    "require_tolerance",
    "require_tolerance_check",
    "default_accuracy",
    "takes_tolerance",
    "tolerance_schemes",
    "require_accuracy",
    "unstable_motion_warning",
    "tolerance_blocks",
    "companion_ratio",
    "companion_steps",
    "relative_difference",
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
        step_d = (
            rates.dissipation_margin * region.dissipation
            if rates.dissipation is not None
            else math.inf
        )
        dissipation = rates.dissipation if step_d != math.inf else None
        k, p, kd, error, accuracy = 0.0, 1.0, 0.0, None, ""
        if tolerance is not None:
            c, p = float(integrator.error_constant), float(integrator.order)
            # with a decaying rate the budget is shared: half for the rotation's error, which adds
            # up over the periods, half for the decaying mode's, which relaxes
            share = 0.5 if dissipation is not None else 1.0
            budget = share * math.log1p(tolerance) / horizon
            k, error = c / budget, (c, p, float(dt))
            if dissipation is not None:
                kd = c / (share * math.log1p(tolerance))
            half = "half of " if dissipation is not None else ""
            accuracy = (
                f"error C lambda dt (lambda h)^{integrator.order} <= {half}log(1 + tolerance) / "
                f"{horizon} per period"
                + (
                    f" and C (lambda_d h)^{integrator.order} <= half of log(1 + tolerance)"
                    if dissipation is not None
                    else ""
                )
                + f" (tolerance={tolerance!r} over tolerance_horizon={horizon} periods; "
                f"{integrator.name}: order {integrator.order}, "
                f"error constant C = {c:g})"
            )
        active = guard != "off" and (
            bound != math.inf or growth != math.inf or dissipation is not None or error is not None
        )
        text = rates.text
        if bound != math.inf:
            text = (
                f"lambda h <= {bound}"
                + (f" and lambda^2 h dt <= {growth}" if growth != math.inf else "")
                + f", {text}"
            )
        if dissipation is not None:
            text += f"; h <= {step_d:.6g} / lambda_d"
        if accuracy:
            text += f"; {accuracy}"
        rotation, motion, gate = rates.rotation, False, None
        rhs = None if system is None else system.kernel_rhs
        named = rates.error_blocks is not None
        if (
            error is not None
            and rhs is not None
            and (named or not system.hybrid)
            and integrator.error_in_phase
        ):
            # the state's own speed in the estimate (motion_rates), for a scheme whose leading
            # error is in the phase; a hybrid system keeps the rate alone unless it names the
            # blocks its error is measured on (its contact flags are not)
            names = rates.error_blocks if named else tuple(system.layout)
            blocks = tuple(tuple(system.layout[n]) for n in names)
            rotating = tuple(
                (tuple(system.layout[q]), tuple(system.layout[d])) for q, d in rates.rotating_blocks
            )
            span = (
                (float(horizon) + 1.0) * float(dt) / 2.0
            )  # (the mean time to the horizon's end: motion_rates)
            mu_text = (
                "; mu = min(lambda, max over the state's blocks"
                f"{' ' + ', '.join(names) if named else ''} of |dy_b/dt| / |y_b|)"
            )
            for q, d in rates.rotating_blocks:
                mu_text += (
                    f", with {q} (turning at its own speed m, driven by {d}): max(mu over the "
                    f"others, mu_{d} + a_{d} m {span:g} s "
                    f"+ m (m / lambda)^{integrator.order}), a_{d} = |{d} . d{d}/dt| / |{d}|^2 (the "
                    f"error {q} carries: {d}'s along itself)"
                )
            extra = (
                {"rotating": rotating, "order": float(integrator.order), "span": span}
                if rotating
                else {}
            )
            if rates.speed is not None:  # the system's bound of its speed over a period
                extra.update(speed_bound=rates.speed[0], dt=float(dt))
                mu_text += (
                    f"; over the period at most {rates.speed[0].__name__}'s bound "
                    "(the motion's own)"
                )
            tail = (rates.speed[1],) if rates.speed is not None else ()
            if (
                gate_steps is not None
                and not rotating
                and (rates.accuracy is None or rates.accuracy_bound is not None)
            ):
                # the default accuracy: a cheap bound first (motion_rates' gate)
                bound_fn, bound_p = (
                    rates.accuracy_bound if rates.accuracy is not None else (None, ())
                )
                extra.update(gate=True, gate_rate=bound_fn)
                # C L dt (L dt / substeps)^p <= budget, i.e. (L dt)^(p + 1) <= substeps^p / k,
                # solved once for its largest L
                limit = gate_limit(float(dt), p + 1.0, float(gate_steps) ** p / k)
                tail += ((limit, bound_p),)
                gate = (
                    (bound_fn, bound_p, limit)
                    if bound_fn is not None
                    else (rates.rotation[0], rates.rotation[1], limit)
                )
                mu_text += (
                    f"; first the bound C L dt (L dt / {gate_steps})^{integrator.order}, L = "
                    + (f"{bound_fn.__name__}" if bound_fn is not None else "lambda")
                    + " (the default accuracy: where it holds, reported)"
                )
            if rates.accuracy is not None:  # the system's sharper rate of the error (lambda_e)
                rotation = (
                    motion_rates(rates.rotation[0], rhs[0], blocks, rates.accuracy[0], **extra),
                    (rates.rotation[1], rhs[1], rates.accuracy[1]) + tail,
                )
                accuracy, text = (
                    t.replace("(lambda h)^", "(lambda_e h)^") for t in (accuracy, text)
                )
                mu_text = (
                    "; lambda_e = the system's bound of its Jacobian ("
                    + rates.accuracy[0].__name__
                    + ")"
                    + mu_text.replace("min(lambda,", "min(lambda_e,").replace(
                        "/ lambda)^", "/ lambda_e)^"
                    )
                )
            else:
                rotation = (
                    motion_rates(rates.rotation[0], rhs[0], blocks, None, **extra),
                    (rates.rotation[1], rhs[1], ()) + tail,
                )
            motion = True
            accuracy = accuracy.replace("error C lambda dt", "error C mu dt") + mu_text
            text = text.replace("error C lambda dt", "error C mu dt") + mu_text
        mode_share = (
            rates.dissipation_share if error is not None and dissipation is not None else None
        )
        if mode_share is not None:
            # the system's parameters with the scheme's forced-mode error constant (over C; 0: none)
            forced = integrator.forced_error_constant
            mode_share = (
                mode_share[0],
                (mode_share[1], 0.0 if forced is None else float(forced) / c),
            )
            accuracy, text = (
                t.replace("C (lambda_d h)^", "C a (lambda_d h)^")
                + " (a = the decaying mode's share of it, "
                + mode_share[0].__name__
                + ")"
                for t in (accuracy, text)
            )
        return cls(
            rotation,
            (float(dt), float(bound), float(growth), float(k), float(p), float(kd)),
            dissipation,
            step_d,
            rates.ceiling,
            text,
            active,
            error,
            accuracy,
            motion,
            tuple(zero_control),
            mode_share,
            gate,
        )

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


# the reported estimate over the classical one (its next order's share: the module docstring)
MARGIN = 1.25


def require_tolerance_check(check, tolerance):
    """``tolerance_check=``: ``False`` or ``True`` (a companion run checks the episode's global
    error against ``tolerance=``, which it then needs)."""
    if isinstance(check, str) and check == "refine":
        raise ValueError(
            "tolerance_check='refine' was removed (2026-11-29: each replay ran the episode again "
            "from its start); use "
            "tolerance_check=True, which ends the episode, flagged, where the estimate passes the "
            "tolerance, with a tighter "
            "tolerance= to hold it longer"
        )
    if not (check is True or check is False):
        raise ValueError(
            "tolerance_check must be False or True (a companion run checks the episode's global "
            "error and ends the episode "
            f"where it passes the tolerance), got {check!r}"
        )
    if check and tolerance is None:
        raise ValueError(
            "tolerance_check=True needs tolerance= (the relative error per episode the global "
            "error estimate is checked against)"
        )
    return check


def tolerance_blocks(system) -> tuple:
    """The ``(start, stop)`` blocks of the state over which a tolerance is measured: every block
    of the layout, less a hybrid system's horizontal position (it drifts along the table: its
    size is no scale of the motion) and its contact flags and hop counts (counts, not
    quantities)."""
    return tuple(
        tuple(span)
        for name, span in system.layout.items()
        if not (system.hybrid and name in ("position", "contact", "hops"))
    )


def companion_ratio(p: float) -> float:
    """``2^p - 1``: the companion's global error over the main run's, less one (order ``p``)."""
    return 2.0 ** float(p) - 1.0


def companion_steps(n):
    """The steps the companion takes beside a checked period of ``n`` (even) steps: ``n / 2`` (an
    int, or an int array)."""
    return n // 2


def block_sums(y, yc, lo, hi):
    """``(|y_b - yc_b|^2, |y_b|^2)`` over the components ``lo:hi`` (floats or arrays: the same
    operations in the same order)."""
    d2 = s2 = 0.0
    for i in range(lo, hi):
        d = y[i] - yc[i]
        d2 = d2 + d * d
        s2 = s2 + y[i] * y[i]
    return d2, s2


def block_difference(blocks, y, yc):
    """:func:`relative_difference` of one state (floats). A block whose difference is NaN (a
    companion that went non-finite beside a finite run)
    counts as ``inf``: the check cannot vouch for the state, so its estimate passes any
    tolerance."""
    out = 0.0
    for lo, hi in blocks:
        d2, s2 = block_sums(y, yc, lo, hi)
        r = 0.0 if d2 == 0.0 else (math.sqrt(d2 / s2) if s2 > 0.0 else math.inf)
        r = r if r == r else math.inf
        out = r if r > out else out
    return out


def relative_difference(blocks, y, yc):
    """``max_b |y_b - yc_b| / |y_b|`` over ``blocks`` (a block of norm 0 in both: 0; a NaN
    difference: ``inf``); one state (a float: :func:`block_difference`) or a batch (an array,
    the same rule element by element)."""
    if not isinstance(y[0], np.ndarray):
        return block_difference(blocks, y, yc)
    out = 0.0
    for lo, hi in blocks:
        d2, s2 = block_sums(y, yc, lo, hi)
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.where(
                d2 == 0.0,
                0.0,
                np.where(s2 > 0.0, np.sqrt(d2 / np.where(s2 > 0.0, s2, 1.0)), np.inf),
            )
        out = np.maximum(out, np.where(r == r, r, np.inf))
    return out


class GlobalErrorCheck:
    """One env's (or one batch's) companion: its state, its compensation and the periods it has
    run. :meth:`restart` at a reset (rows ``mask`` of a batch); :meth:`period` after each period;
    :meth:`step_one` a single env's checked step."""

    __slots__ = ("engine", "blocks", "ratio", "runs", "periods")

    def __init__(self, engine):
        self.engine = engine
        self.blocks = tolerance_blocks(engine.system)
        self.ratio = companion_ratio(engine.integrator.order)
        self.runs = None  # the companion's state and compensation (yc, cc)
        self.periods = 0

    def restart(self, y, mask=None):
        """The companion starts at ``y`` (a batch: at the rows ``mask`` of ``y``, or all)."""
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
        """After a period that took ``y``'s run ``n`` (even) steps under ``u``: the companion's
        period, and the global error estimate of ``y``, ``MARGIN D / (2^p - 1)`` (floats, or
        arrays for a batch)."""
        self.runs = self.engine.companion(self.runs[0], u, n, self.runs[1])
        self.periods = self.periods + 1
        return MARGIN * relative_difference(self.blocks, y, self.runs[0]) / self.ratio

    def step_one(self, y0, a, plain):
        """The engine's :meth:`~rbenvs.core.step.Engine.step_one` with the companion's period after
        it (the single env's step, and a sub-env's in a vector env whose sub-envs step models of
        their own): ``info["global_error_estimate"]``; where the estimate passes the tolerance, the
        episode ends as a numerical failure at ``y0``."""
        engine = self.engine
        comp0 = engine.comp  # (the run's compensation at y0: kept with y0 where the period is not)
        out = engine.step_one(y0, a, plain)
        info = out[4]
        if info["numerical_failure"]:
            return out
        n = int(round(engine.dt / info["internal_step"]))
        runs0 = self.runs
        e = self.period(out[0], out[5], n)
        if e > engine.tolerance:  # the companion and the run stay with the state kept
            self.runs, self.periods = runs0, self.periods - 1
            return engine.inaccurate_one(
                y0, a, info["internal_step"], plain, e, self.periods + 1, comp0
            )
        info["global_error_estimate"] = e
        return out

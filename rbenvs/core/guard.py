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
:func:`step_ratio` is what the compiled batch step calls (the accuracy term's fractional power
is corrected to the exact whole count by integer powers, so a last-bit difference between
libm's ``pow`` and numpy's cannot change a count).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..dynamics.validation import did_you_mean
from ..jit import jitable
from ..rotations import every, maximum, power, select, sqrt
from .codegen import generate

__all__ = ["MAX_INTERNAL_STEPS", "GUARDS", "DEFAULT_TOLERANCE", "UnstableMotionWarning", "StepRule", "step_ratio", "step_ratio_motion", "motion_rates", "accuracy_steps", "relaxation_steps", "whole_root", "error_estimate", "require_guard",
           "require_tolerance", "TOLERANCE_FLOOR"]

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
        raise ValueError(f"guard must be one of {list(GUARDS)}, got {guard!r}{did_you_mean(guard, GUARDS)}")
    return guard


# ``tolerance=``'s default: the env's default accuracy (RigidBodyEnv.default_tolerance)
DEFAULT_TOLERANCE = "default"
# the least tolerance float64 carries over an episode: near the free body's separatrix the
# motion amplifies the (compensated) sums' roundoff to 1e-13-1e-12 over 20 s, and at 1e-13 the
# check returned periods 1.33 times outside (rbenvs bench accuracy --roundoff and --floor)
TOLERANCE_FLOOR = 1e-12


def require_tolerance(tolerance):
    """``tolerance=``: ``"default"`` (the env's default accuracy), ``None`` (no accuracy bound)
    or a finite number with ``TOLERANCE_FLOOR <= tolerance < 1`` (a relative error per episode)."""
    if tolerance is None or (isinstance(tolerance, str) and tolerance == DEFAULT_TOLERANCE):
        return tolerance
    rule = (f"{DEFAULT_TOLERANCE!r} (the env's default accuracy), None (unchecked: the stability bound alone) or a finite number with "
            f"{TOLERANCE_FLOOR:g} <= tolerance < 1 (the relative error allowed over an episode)")
    if isinstance(tolerance, (bool, np.bool_)) or not isinstance(tolerance, (int, float, np.integer, np.floating)):
        raise TypeError(f"tolerance must be {rule}, got {tolerance!r} ({type(tolerance).__name__})")
    tol = float(tolerance)
    if not (math.isfinite(tol) and 0.0 < tol < 1.0):
        raise ValueError(f"tolerance must be {rule}, got {tolerance!r}")
    if tol < TOLERANCE_FLOOR:
        raise ValueError(f"tolerance={tolerance!r} is below what float64 carries over an episode ({TOLERANCE_FLOOR:g}: near an unstable "
                         f"motion the sums' roundoff alone reaches 1e-13-1e-12, 'rbenvs bench accuracy --roundoff'); pass tolerance >= "
                         f"{TOLERANCE_FLOOR:g}, or integrate in extended precision outside the env (rbenvs.oracles.taylor_solution)")
    return tol


@jitable
def ceiling(x):
    """``ceil(x)`` as a float (``inf`` and NaN pass through; floats or arrays)."""
    if isinstance(x, float):
        return float(math.ceil(x)) if x <= 9.0e15 else x
    return _ceil_arrays(x)


@jitable  # (registered so that compiled code can name it; it only ever runs on arrays)
def _ceil_arrays(x):
    return np.ceil(x)


@jitable
def whole_root(y, p):
    """The fewest whole ``n >= 0`` with ``n^p >= y`` (floats or arrays): the root's guess moved to
    the exact answer of the integer-power test, so every path gives the same count."""
    if isinstance(y, float) and 0.0 < y <= 1.0:  # (one step is enough: the common case, without a root)
        return 1.0
    n = ceiling(y ** (1.0 / p))
    m = n - 1.0
    n = select(m >= 1.0, select(power(m, p) >= y, m, n), n)
    return select(power(n, p) < y, n + 1.0, n)


@jitable
def accuracy_steps(k, p, z):
    """The fewest whole ``n`` with ``n^p >= k z^(p+1)``: the steps a period of ``z = lambda dt``
    needs for an error ``C z (z / n)^p <= b`` (``k = C / b``, ``p`` the order; floats or arrays)."""
    return whole_root(k * power(z, p + 1.0), p)


@jitable
def relaxation_steps(g, rate, a):
    """The fewest whole ``n`` whose steps ``h = dt / n`` keep a decaying mode of rate ``rate``
    within its share of the tolerance, ``C a (rate h)^p <= b_d`` (``g[5] = C / b_d``; 0 without
    a tolerance): a decaying mode forgets its error within ``1 / rate``, so its error does not
    add up over the periods. ``a <= 1``: the system's ``dissipation_share`` (1 where it declares
    none), the share of ``C (rate h)^p`` the mode's error is in this period: less where the mode
    is less stiff than ``rate`` says (a saturated friction), near its slow manifold, or driven
    slowly. Floats; :meth:`StepRule.ratio` writes the array form."""
    dt, bound, growth, k, p, kd = g
    if kd == 0.0:
        return 0.0
    return whole_root(kd * (a * power(dt * rate, p)), p)


@jitable
def error_estimate(e, lam, h):
    """The relative error a period commits, ``C lambda dt (lambda h)^p``: ``e = (C, p, dt)``,
    ``lam`` the rate at its start, ``h`` its internal step (floats or arrays)."""
    c, p, dt = e
    return c * lam * dt * power(lam * h, p)


@jitable
def motion_error_estimate(e, rates, h):
    """:func:`error_estimate` with the state's own speed: ``C mu dt (lambda_e h)^p``, ``rates =
    (lambda, mu, lambda_e)`` (:func:`step_ratio_motion`'s; floats or arrays)."""
    c, p, dt = e
    lam, mu, lam_e = rates
    return c * mu * dt * power(lam_e * h, p)


@jitable
def relaxation_estimate(e, rate, a, h):
    """A decaying mode's error in a period of internal step ``h``: ``C a (lambda_d h)^p``,
    ``rate`` its rate ``lambda_d`` and ``a`` its error's share (floats or arrays)."""
    c, p, _ = e
    return c * (a * power(rate * h, p))


@jitable
def stability_ratio(dt, bound, growth, lam):
    """The stability bound's ``x``: ``dt lambda / b``, and ``(dt lambda)^2 / growth`` where the
    region bounds growth (pure; floats or arrays): the part both step ratios share."""
    x = dt * lam / bound
    if growth != math.inf:
        z = dt * lam
        x = maximum(x, z * z / growth)
    return x


@jitable
def step_ratio_motion(g, rates):
    """:func:`step_ratio` with the state's own rate: ``rates = (lambda, mu, lambda_e)``,
    ``lambda_e`` the error's rate (the system's Jacobian bound, or ``lambda``) and ``mu <=
    lambda_e`` the relative speed of the state (:func:`motion_rates`); the stability bound takes
    ``lambda``, the accuracy term the fewest whole ``n`` with ``C mu dt (lambda_e dt / n)^p <= b``
    (pure; floats or arrays)."""
    lam, mu, lam_e = rates
    dt, bound, growth, k, p, kd = g
    x = stability_ratio(dt, bound, growth, lam)
    if k != 0.0:
        x = maximum(x, whole_root(k * (power(dt * lam_e, p) * (mu * dt)), p))
    return x


@lru_cache(maxsize=None)
def motion_rates(rotation, rhs, blocks: tuple, accuracy=None, rotating: tuple = (), order: float = 1.0, span: float = 0.0, speed_bound=None, dt: float = 0.0,
                 gate: bool = False, gate_rate=None):
    """``rates(P, y, u) -> (lambda, mu, lambda_e)`` (generated, pure), ``P = (P_rotation, P_rhs)``
    (``(P_rotation, P_rhs, P_accuracy)`` with ``accuracy``): the guard's rate ``lambda =
    rotation(P_rotation, y)``, the error's rate ``lambda_e = accuracy(P_accuracy, y)`` (a bound
    of the vector field's Jacobian the system declares, :class:`~rbenvs.contracts.GuardRates`;
    without one ``lambda_e = lambda``) and the state's own relative speed ``mu = min(lambda_e,
    max_b |f_b(y, u)| / |y_b|)`` over the named blocks ``b`` of the state (``blocks``: ``(start,
    stop)`` slices), ``f`` the system's pure vector field under the control ``u``.

    Why ``mu``: a scheme's local error on ``dy/dt = A y`` is ``C h^(p+1) A^p (A y)`` to leading
    order, at most ``C h^(p+1) lambda^p |dy/dt|`` with ``lambda >= |A|``: relative to ``|y|``,
    ``C (lambda h)^p h mu``. A state that moves slower than its fastest rate (a body spinning
    near a principal axis, a fast top whose axis barely moves) commits less error than a
    rotation at ``lambda`` would, and a steady spin (``mu = 0``) none. Used for schemes whose
    leading error on a rotation is in the phase (``error_in_phase``: rk4): a scheme whose leading
    error changes the amplitude (euler) changes a nonlinear motion's frequency with it, and the
    phase then drifts over the whole episode (measured: euler on the free body at 1 rad/s ended
    2.7 times its tolerance with ``mu``, and 16 times inside it with ``lambda``): the envs refuse
    it with a tolerance.

    Why ``lambda_e``: the bound ``|A| <= lambda`` is loose where the vector field's Jacobian is
    far smaller than the fastest rotation rate (a free body's ``Pi`` moves in the body frame at
    a rate set by the spread of its moments, not by ``|Omega|``: nearly equal moments, a fast
    tumble); where the system bounds its Jacobian and its second derivative's share by
    ``lambda_e`` (:func:`rbenvs.dynamics.free_body.jacobian_rate`), the local error is at most
    ``C h^(p+1) lambda_e^p |dy/dt|`` to the same order; where the system knows its motion's own
    frequency (:func:`rbenvs.dynamics.free_body.error_rate`: ``Pi`` on its polhode), that
    frequency, within the bound.

    Why ``rotating`` (pairs of ``(start, stop)`` slices, a block and the block that drives it,
    with the scheme's ``order`` ``p`` and ``span``, the time an error of the horizon's periods is
    carried to its end, on average): a block that turns as a rotation of itself at its own speed
    ``m`` (``dy_q/dt = A(y_d) y_q``, ``A`` skew, ``|A| = m``: a unit quaternion at half the
    angular speed) errs by ``C (m h)^(p+1)`` a step, not at ``lambda_e``; but it integrates its
    driver: a relative error ``eps`` of ``y_d`` along ``y_d`` made in period ``k`` turns it at a
    rate off by ``m eps``, which it carries to the end of the horizon, ``m eps (N - k) dt``. Summed
    over the ``N`` periods of the horizon, each within the same budget, those weights ``m (N - k)
    dt`` add up to ``N m span`` with ``span = (N + 1) dt / 2``: exact where ``m`` is steady, and
    where it varies off by a share ``O(1 / (m span))``, small where the term matters. Only the
    error along the driver is carried: with ``dq/dt = q (0, Omega) / 2`` the error ``q (0, e)``
    follows ``de/dt = dOmega / 2 - Omega x e`` (body frame), whose part along ``Omega`` adds up
    (the angle turned) while its part across is turned at ``|Omega|`` as it is made and stays
    within ``|dOmega_perp| / |Omega|``, the driver's own relative error (a rotation by a large
    angle about an axis off by ``dn`` is off by at most ``|dn|``). The error along the driver
    follows the rate of its magnitude, ``a_d = |y_d . f_d| / |y_d|^2 <= mu_d``, to leading order
    (a scheme's error on a vector that turns is in its phase: rk4 errs in the amplitude of a
    rotation an order higher). So the driver counts ``mu_d`` once, its own error, and ``a_d m
    span`` carried, and the block's own error ``C m dt (m h)^p`` is written as ``C mu dt (lambda_e
    h)^p`` with ``mu = m (m / lambda_e)^p``:

        mu = max(mu over the other blocks, mu_d + a_d m span + m (m / lambda_e)^p)

    (the estimate and the step count keep their one form). Over a long horizon the carried term
    can pass ``lambda_e`` (the phase error of an integrated rate grows like the horizon squared):
    it is not capped there. The tippe top's attitude turns at ``|Omega| / 2``, driven by
    ``Omega``, while ``Omega`` and ``v_G`` move slowly. Measured (``rbenvs bench accuracy
    --tolerance``, the tippe top's rows): with ``mu_d (1 + m span)`` (the whole driver's error
    carried) every row was within and the viscous scene cost 1.44-2.24 times the cheapest fixed
    steps, its estimate about 6 times its error; with ``a_d`` 1.02-1.19, every row still within.

    Why ``speed`` (``P[3]``, with the period ``dt``): the speed at the period's start need not be
    the period's; where the system bounds its blocks' relative speed over a period
    (:class:`~rbenvs.contracts.GuardRates`' ``speed``: the free body's orbit, along which a
    state by the intermediate axis runs its separatrix within the period), that bound is the
    speed of every block but the rotating ones.

    Why ``gate`` (the default accuracy; ``P``'s last item ``(dt, p + 1, substeps^p / k, P_gate)``):
    ``mu <= lambda_e <= Lambda``, ``Lambda`` a cheap bound of the error's rate (``gate_rate``, the
    system's ``accuracy_bound``; ``None``: ``lambda``, which is ``lambda_e`` without ``accuracy``),
    so ``C Lambda dt (Lambda h)^p`` bounds the estimate. Where that bound keeps the period's
    ``substeps`` within its budget the rates are ``(lambda, Lambda, Lambda)``: the count is the
    one the sharp rates give (both within ``substeps``: the stability bound's), the estimate
    reported is the bound, and the sharp rates (the vector field, the system's rate) are not
    evaluated. Without rotating blocks only (their carried term is not bounded by ``Lambda``)."""
    lines = ["def rates(P, y, u):", "    lam = rotation(P[0], y)"]
    if gate:
        lines += [f"    G = P[{4 if speed_bound is not None else 3}]", "    big = gate_rate(G[3], y)" if gate_rate is not None else "    big = lam",
                  "    cheap = power(big * G[0], G[1]) <= G[2]",
                  "    if every(cheap):",  # (the sharp rates only where the bound does not hold: a batch, for all)
                  "        return (lam, big, big)"]
    lines += ["    f = rhs(P[1], y, u)", "    lam_e = accuracy(P[2], y)" if accuracy is not None else "    lam_e = lam"]

    def speed(a, b):
        ny = " + ".join(f"y[{i}] * y[{i}]" for i in range(a, b))
        nf = " + ".join(f"f[{i}] * f[{i}]" for i in range(a, b))
        return f"sqrt({nf}) / maximum(sqrt({ny}), 1e-300)"

    drivers = {tuple(d) for _, d in rotating}
    others = [blk for blk in blocks if tuple(blk) not in drivers]
    if speed_bound is not None:
        lines.append(f"    bound = speed_bound(P[3], y, u, {float(dt)!r})")
    for j, (a, b) in enumerate(others):
        lines.append(f"    mu = {speed(a, b)}" if j == 0 else f"    mu = maximum(mu, {speed(a, b)})")
    if not others:
        lines.append("    mu = 0.0 * lam")
    elif speed_bound is not None:
        lines.append("    mu = maximum(mu, bound)")
    lines.append("    mu = select(mu < lam_e, mu, lam_e)")
    for (a, b), (c, d) in rotating:
        ny = " + ".join(f"y[{i}] * y[{i}]" for i in range(c, d))
        dot = " + ".join(f"y[{i}] * f[{i}]" for i in range(c, d))
        lines += [f"    m = {speed(a, b)}", "    m = select(m < lam_e, m, lam_e)", f"    md = {speed(c, d)}"]
        if speed_bound is not None:
            lines.append("    md = maximum(md, bound)")
        lines += ["    md = select(md < lam_e, md, lam_e)",
                  f"    ma = abs({dot}) / maximum({ny}, 1e-300)", "    ma = select(ma < md, ma, md)",
                  f"    mq = md + ma * m * {float(span)!r} + m * power(m / maximum(lam_e, 1e-300), {float(order)!r})",
                  "    mu = maximum(mu, mq)"]
    if gate:  # (a batch: the bound where it holds)
        lines += ["    return (lam, select(cheap, big, mu), select(cheap, big, lam_e))"]
    else:
        lines += ["    return (lam, mu, lam_e)"]
    namespace = generate("\n".join(lines) + "\n", f"motion rates of {len(blocks)} blocks" + (f" and {len(rotating)} rotating" if rotating else "") + (" gated" if gate else ""),
                         {"rotation": rotation, "rhs": rhs, "accuracy": accuracy, "speed_bound": speed_bound, "gate_rate": gate_rate, "sqrt": sqrt, "maximum": maximum,
                          "select": select, "every": every, "power": power})
    return jitable(namespace["rates"])


@jitable
def step_ratio(g, lam):
    """``x`` (a period needs ``ceil(x)`` steps) from the oscillatory rate ``lam`` alone:
    ``g = (dt, bound, growth, k, p, kd)``; ``k = C / b > 0`` adds the accuracy term
    (:func:`accuracy_steps`), ``k = 0`` none (``kd``: :func:`relaxation_steps`; pure, floats
    or arrays)."""
    dt, bound, growth, k, p, kd = g
    x = stability_ratio(dt, bound, growth, lam)
    if k != 0.0:
        x = maximum(x, accuracy_steps(k, p, dt * lam))
    return x


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
    # the default accuracy's gate (motion_rates'): (fn, P, (dt, p + 1, substeps^p / k)), fn(P, y) -> Lambda,
    # a cheap bound of the error's rate; a batch tests it first (rbenvs.compiled's gate loop); None: no gate
    gate: tuple | None = None

    @classmethod
    def build(cls, rates, region, dt: float, guard: str, integrator=None, tolerance=None, horizon=None, system=None, zero_control=(), gate_steps=None) -> "StepRule":
        """The rule for ``rates`` (the system's :class:`~rbenvs.contracts.GuardRates` for
        ``region``) at control period ``dt`` under ``guard``; with ``tolerance`` (a relative
        error over ``horizon`` periods) also the accuracy bound of ``integrator`` (its
        ``order`` and ``error_constant``). ``gate_steps``: the default accuracy's ``substeps``,
        with which the rates test a cheap bound first (:func:`motion_rates`' gate)."""
        if rates.rotation_bound is not None:  # the system's accuracy bound replaces the scheme's
            bound, growth = rates.rotation_bound, math.inf
        else:
            bound, growth = region.rotation, region.growth
        step_d = rates.dissipation_margin * region.dissipation if rates.dissipation is not None else math.inf
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
            accuracy = (f"error C lambda dt (lambda h)^{integrator.order} <= {half}log(1 + tolerance) / {horizon} per period"
                        + (f" and C (lambda_d h)^{integrator.order} <= half of log(1 + tolerance)" if dissipation is not None else "")
                        + f" (tolerance={tolerance!r} over tolerance_horizon={horizon} periods; {integrator.name}: order {integrator.order}, "
                        f"error constant C = {c:g})")
        active = guard != "off" and (bound != math.inf or growth != math.inf or dissipation is not None or error is not None)
        text = rates.text
        if bound != math.inf:
            text = f"lambda h <= {bound}" + (f" and lambda^2 h dt <= {growth}" if growth != math.inf else "") + f", {text}"
        if dissipation is not None:
            text += f"; h <= {step_d:.6g} / lambda_d"
        if accuracy:
            text += f"; {accuracy}"
        rotation, motion, gate = rates.rotation, False, None
        rhs = getattr(system, "kernel_rhs", None)
        named = rates.error_blocks is not None
        if error is not None and rhs is not None and (named or not system.hybrid) and getattr(integrator, "error_in_phase", False):
            # the state's own speed in the estimate (motion_rates), for a scheme whose leading
            # error is in the phase; a hybrid system keeps the rate alone unless it names the
            # blocks its error is measured on (its contact flags are not)
            names = rates.error_blocks if named else tuple(system.layout)
            blocks = tuple(tuple(system.layout[n]) for n in names)
            rotating = tuple((tuple(system.layout[q]), tuple(system.layout[d])) for q, d in rates.rotating_blocks)
            span = (float(horizon) + 1.0) * float(dt) / 2.0  # (the mean time to the horizon's end: motion_rates)
            mu_text = f"; mu = min(lambda, max over the state's blocks{' ' + ', '.join(names) if named else ''} of |dy_b/dt| / |y_b|)"
            for q, d in rates.rotating_blocks:
                mu_text += (f", with {q} (turning at its own speed m, driven by {d}): max(mu over the others, mu_{d} + a_{d} m {span:g} s "
                            f"+ m (m / lambda)^{integrator.order}), a_{d} = |{d} . d{d}/dt| / |{d}|^2 (the error {q} carries: {d}'s along itself)")
            extra = {"rotating": rotating, "order": float(integrator.order), "span": span} if rotating else {}
            if rates.speed is not None:  # the system's bound of its speed over a period
                extra.update(speed_bound=rates.speed[0], dt=float(dt))
                mu_text += f"; over the period at most {rates.speed[0].__name__}'s bound (the motion's own)"
            tail = (rates.speed[1],) if rates.speed is not None else ()
            if gate_steps is not None and not rotating and (rates.accuracy is None or rates.accuracy_bound is not None):
                # the default accuracy: a cheap bound first (motion_rates' gate)
                bound_fn, bound_p = rates.accuracy_bound if rates.accuracy is not None else (None, ())
                extra.update(gate=True, gate_rate=bound_fn)
                test = (float(dt), p + 1.0, float(gate_steps) ** p / k)
                tail += (test + (bound_p,),)
                gate = (bound_fn, bound_p, test) if bound_fn is not None else (rates.rotation[0], rates.rotation[1], test)
                mu_text += (f"; first the bound C L dt (L dt / {gate_steps})^{integrator.order}, L = "
                            + (f"{bound_fn.__name__}" if bound_fn is not None else "lambda") + " (the default accuracy: where it holds, reported)")
            if rates.accuracy is not None:  # the system's sharper rate of the error (lambda_e)
                rotation = (motion_rates(rates.rotation[0], rhs[0], blocks, rates.accuracy[0], **extra), (rates.rotation[1], rhs[1], rates.accuracy[1]) + tail)
                accuracy, text = (t.replace("(lambda h)^", "(lambda_e h)^") for t in (accuracy, text))
                mu_text = ("; lambda_e = the system's bound of its Jacobian (" + rates.accuracy[0].__name__ + ")"
                           + mu_text.replace("min(lambda,", "min(lambda_e,").replace("/ lambda)^", "/ lambda_e)^"))
            else:
                rotation = (motion_rates(rates.rotation[0], rhs[0], blocks, None, **extra), (rates.rotation[1], rhs[1], ()) + tail)
            motion = True
            accuracy = accuracy.replace("error C lambda dt", "error C mu dt") + mu_text
            text = text.replace("error C lambda dt", "error C mu dt") + mu_text
        mode_share = rates.dissipation_share if error is not None and dissipation is not None else None
        if mode_share is not None:
            # the system's parameters with the scheme's forced-mode error constant (over C; 0: none)
            forced = getattr(integrator, "forced_error_constant", None)
            mode_share = (mode_share[0], (mode_share[1], 0.0 if forced is None else float(forced) / c))
            accuracy, text = (t.replace("C (lambda_d h)^", "C a (lambda_d h)^") + " (a = the decaying mode's share of it, "
                              + mode_share[0].__name__ + ")" for t in (accuracy, text))
        return cls(rotation, (float(dt), float(bound), float(growth), float(k), float(p), float(kd)), dissipation, step_d, rates.ceiling, text, active, error,
                   accuracy, motion, tuple(zero_control), mode_share, gate)

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
        # (the compiled vector step's estimate calls the same functions: rbenvs.compiled.vector_kernel)
        e = motion_error_estimate(self.error, lam, h) if self.motion else error_estimate(self.error, lam, h)
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
            accuracy = max(accuracy, relaxation_steps(self.params, rate, self.dissipation_share(y, u, rate)))
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
                        x = max(x, relaxation_steps(self.params, rate, self.dissipation_share(y, u, rate)))
            else:
                with np.errstate(divide="ignore", invalid="ignore"):
                    h_d = np.where(rate > 0.0, self.dissipation_step / np.where(rate > 0.0, rate, 1.0), np.inf)
                    x = np.maximum(x, dt / h_d)
                    if self.params[5] != 0.0:
                        _, _, _, _, p, kd = self.params
                        positive = rate > 0.0
                        r = np.where(positive, rate, 0.0)
                        a = self.dissipation_share(y, u, r)
                        x = np.maximum(x, np.where(positive, whole_root(kd * (a * power(dt * r, p)), p), 0.0))
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
        """Whether :func:`step_ratio` with ``params`` stays within ``substeps`` up to the rate's ceiling."""
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
            n = np.where(x <= MAX_INTERNAL_STEPS, np.ceil(np.where(x <= MAX_INTERNAL_STEPS, x, 0.0)), MAX_INTERNAL_STEPS + 1)
        return np.maximum(substeps, n).astype(np.int64)

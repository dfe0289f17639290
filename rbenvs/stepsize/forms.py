"""The step controller's pure forms (:mod:`rbenvs.stepsize.controller`): the step counts and
error estimates as functions of floats, which numpy arrays and compiled kernels run too, with
the same IEEE operations, so that a sub-env of a vector env and its compiled step take exactly
the single env's steps. The rules they implement are the controller's docstring's.
"""

from __future__ import annotations

import math
import sys
from functools import cache

import numpy as np

from ..codegen import generate
from ..jit import jitable
from ..rotations import every, maximum, power, select, sqrt

__all__ = [
    "ceiling",
    "whole_root",
    "accuracy_steps",
    "relaxation_steps",
    "error_estimate",
    "motion_error_estimate",
    "relaxation_estimate",
    "stability_ratio",
    "step_ratio_motion",
    "motion_rates",
    "step_ratio",
    "gate_limit",
    "gated_estimate",
    "relative_difference",
    "mode_share",
    "motion_form",
]


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
    if (
        isinstance(y, float) and 0.0 < y <= 1.0
    ):  # (one step is enough: the common case, without a root)
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


@cache
def motion_rates(
    rotation,
    rhs,
    blocks: tuple,
    accuracy=None,
    rotating: tuple = (),
    order: float = 1.0,
    span: float = 0.0,
    speed_bound=None,
    dt: float = 0.0,
    gate: bool = False,
    gate_rate=None,
):
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

    Why ``gate`` (the default accuracy; ``P``'s last item ``(limit, P_gate)``, ``limit`` the
    largest ``Lambda`` with ``C Lambda dt (Lambda dt / substeps)^p`` within the budget:
    :func:`gate_limit`):
    ``mu <= lambda_e <= Lambda``, ``Lambda`` a cheap bound of the error's rate (``gate_rate``, the
    system's ``accuracy_bound``; ``None``: ``lambda``, which is ``lambda_e`` without ``accuracy``),
    so ``C Lambda dt (Lambda h)^p`` bounds the estimate. Where that bound keeps the period's
    ``substeps`` within its budget the rates are ``(lambda, Lambda, Lambda)``: the count is the
    one the sharp rates give (both within ``substeps``: the stability bound's), the estimate
    reported is the bound, and the sharp rates (the vector field, the system's rate) are not
    evaluated. Without rotating blocks only (their carried term is not bounded by ``Lambda``)."""
    lines = ["def rates(P, y, u):", "    lam = rotation(P[0], y)"]
    if gate:
        lines += [
            f"    G = P[{4 if speed_bound is not None else 3}]",
            "    big = gate_rate(G[1], y)" if gate_rate is not None else "    big = lam",
            "    cheap = big <= G[0]",
            # (the sharp rates only where the bound does not hold: a batch, for all)
            "    if every(cheap):",
            "        return (lam, big, big)",
        ]
    lines += [
        "    f = rhs(P[1], y, u)",
        "    lam_e = accuracy(P[2], y)" if accuracy is not None else "    lam_e = lam",
    ]

    def speed(a, b):
        ny = " + ".join(f"y[{i}] * y[{i}]" for i in range(a, b))
        nf = " + ".join(f"f[{i}] * f[{i}]" for i in range(a, b))
        return f"sqrt({nf}) / maximum(sqrt({ny}), 1e-300)"

    drivers = {tuple(d) for _, d in rotating}
    others = [blk for blk in blocks if tuple(blk) not in drivers]
    if speed_bound is not None:
        lines.append(f"    bound = speed_bound(P[3], y, u, {float(dt)!r})")
    for j, (a, b) in enumerate(others):
        lines.append(
            f"    mu = {speed(a, b)}" if j == 0 else f"    mu = maximum(mu, {speed(a, b)})"
        )
    if not others:
        lines.append("    mu = 0.0 * lam")
    elif speed_bound is not None:
        lines.append("    mu = maximum(mu, bound)")
    lines.append("    mu = select(mu < lam_e, mu, lam_e)")
    for (a, b), (c, d) in rotating:
        ny = " + ".join(f"y[{i}] * y[{i}]" for i in range(c, d))
        dot = " + ".join(f"y[{i}] * f[{i}]" for i in range(c, d))
        lines += [
            f"    m = {speed(a, b)}",
            "    m = select(m < lam_e, m, lam_e)",
            f"    md = {speed(c, d)}",
        ]
        if speed_bound is not None:
            lines.append("    md = maximum(md, bound)")
        lines += [
            "    md = select(md < lam_e, md, lam_e)",
            f"    ma = abs({dot}) / maximum({ny}, 1e-300)",
            "    ma = select(ma < md, ma, md)",
            f"    mq = md + ma * m * {float(span)!r} + m * power(m / maximum(lam_e, 1e-300), "
            f"{float(order)!r})",
            "    mu = maximum(mu, mq)",
        ]
    if gate:  # (a batch: the bound where it holds)
        lines += ["    return (lam, select(cheap, big, mu), select(cheap, big, lam_e))"]
    else:
        lines += ["    return (lam, mu, lam_e)"]
    namespace = generate(
        "\n".join(lines) + "\n",
        f"motion rates of {len(blocks)} blocks"
        + (f" and {len(rotating)} rotating" if rotating else "")
        + (" gated" if gate else ""),
        {
            "rotation": rotation,
            "rhs": rhs,
            "accuracy": accuracy,
            "speed_bound": speed_bound,
            "gate_rate": gate_rate,
            "sqrt": sqrt,
            "maximum": maximum,
            "select": select,
            "every": every,
            "power": power,
        },
    )
    return jitable(namespace["rates"])


def gate_limit(dt: float, q: float, top: float) -> float:
    """The default accuracy's gate test ``power(L dt, q) <= top`` as a threshold: the largest float
    ``limit`` that passes it. The test is monotone in ``L >= 0`` (a product of non-negative floats
    rounds monotonically), so ``L <= limit`` is the same test, bit for bit, for every ``L``
    (NaN and ``inf`` fail both), one comparison instead of ``q`` products a period."""
    if not (dt > 0.0 and top >= 0.0 and math.isfinite(top)):
        raise ValueError(f"gate_limit needs dt > 0 and a finite top >= 0, got {dt!r}, {top!r}")

    def passes(L):
        return power(L * dt, q) <= top

    limit = top ** (1.0 / q) / dt
    if not math.isfinite(limit):
        limit = sys.float_info.max
    while not passes(limit):  # (terminates: 0 passes)
        limit = math.nextafter(limit, 0.0)
    while passes(math.nextafter(limit, math.inf)):
        limit = math.nextafter(limit, math.inf)
    return limit


def products(x: str, k: int) -> str:
    """The source of ``x^k`` written out as ``x * x * ... * x``: :func:`rbenvs.rotations.power`'s
    products in its order (the same bits), for generated code (a power with a run-time exponent
    is a loop of its own)."""
    return "(" + " * ".join([x] * k) + ")"


@cache
def gated_estimate(c: float, p: float, dt: float, h: float):
    """``estimate(L) = C L dt (L h)^p``: :func:`motion_error_estimate` at the rates ``(L, L, L)``
    and step ``h`` as one generated function of ``L`` (floats or arrays), the constants written in
    and the power written out as products: the same operations in the same order, so the same bits
    (the default accuracy's estimate where its gate holds; ``p`` a whole number)."""
    if not float(p).is_integer() or p < 1:
        raise ValueError(f"gated_estimate needs a whole order p >= 1, got {p!r}")
    source = (
        f"def estimate(big):\n    z = big * {h!r}\n"
        f"    return {c!r} * big * {dt!r} * {products('z', int(p))}\n"
    )
    return generate(source, f"gated estimate p={int(p)}")["estimate"]


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


def mode_share(rates, integrator, c: float):
    """The decaying mode's share of its error (``StepRule.share``): the system's declared
    ``(fn, P)`` with the scheme's forced-mode error constant over ``C`` (0: none) added to ``P``;
    ``None`` where the system declares none (the share is then 1)."""
    if rates.dissipation_share is None:
        return None
    fn, params = rates.dissipation_share
    forced = integrator.forced_error_constant
    return fn, (params, 0.0 if forced is None else float(forced) / c)


def motion_form(rates, system, dt: float, horizon: int, p: float, k: float, gate_steps):
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

"""One state's compiled step (:func:`state_kernel`) and the runs and plans of a checked or
tolerance-sized period (:func:`run_kernel`, :func:`runs_kernel`, :func:`plan_kernel`,
:func:`plans_kernel`)."""

from __future__ import annotations

from functools import cache

from ..codegen import generate
from ..kernel_cache import njit as _cached_njit
from .batch import (
    KERNEL_OPTIONS,
    Layout,
    _clip_lines,
    _comps,
    _count_lines,
    _estimate_expression,
    _lockstep_passes,
    _namespace,
    _period_lines,
    _ratio_lines,
    _steps_lines,
)


@cache
def state_kernel(layout: Layout, estimate: bool = False):
    """The compiled period and finish of ONE state (the single env's step where numba is
    installed): the batch kernel's lines for one sub-env, on tuples of floats. Signature::

        one(y, u, un, check, refuse, P) -> (status, count, h, fired, y, obs, over, r, q)
        one(y, cc, u, un, check, refuse, P) -> (status, count, h, fired, y, obs, over, r, q, cc)
        (with step_c)

    ``P = (h, dt, substeps, PS, PO, PE, PR, PG, PA, PD, CD, PV, PW, HI)`` (:class:`StateStep`);
    ``status`` 0, 1 (the new state is non-finite: the caller's failure path takes over) or -1
    (``refuse`` and the guard asks for ``count > substeps`` steps: nothing was run); ``obs``
    the observation clipped to ``HI``, ``over`` whether it was outside; ``r`` the task's
    ``(reward, terminated, metrics...)``, ``q`` the read-outs; ``cc`` the run's compensation,
    in and out (a layout with ``step_c`` only: the others' hot call takes no more arguments).
    Every output is computed in every case (one return type), the float path's values where it
    matters. ``estimate`` (a tolerance): ``P`` ends with ``PEE``, the estimate's ``(C, p, dt)``,
    and the period's error estimate ``e`` is returned last, from the rates the count reads
    (evaluated every period, counted or not: :func:`_checked_period`'s).
    """
    from ..stepsize.controller import MAX_INTERNAL_STEPS

    L = layout
    comps = _comps
    lines = [
        "def one(y, cc, u, un, check, refuse, P):"
        if L.step_c is not None
        else "def one(y, u, un, check, refuse, P):",
        "    h, dt, substeps, PS, PO, PE, PR, PG, PA, PD, CD, PV, PW, HI"
        + (", PEE" if estimate else "")
        + " = P",
        "    c = substeps",
        "    need = 0",
    ]
    if estimate:
        lines += [
            *("    " + line for line in _ratio_lines(L, "u = u", parts=True, rates="er")),
            "    if check and not (x <= substeps):",
            f"        c = ceil(x) if x <= {MAX_INTERNAL_STEPS} else {MAX_INTERNAL_STEPS + 1}",
            "        need += 1",
            "    hi = h if c == substeps else dt / c",
            f"    e = {_estimate_expression(L)}",
        ]
    elif L.rotation is not None:
        lines += ["    if check:", *("        " + line for line in _count_lines(L, "u = u"))]
    lines += [
        "    status = 0",
        "    hi = h",
        "    f = False",
        "    if refuse and need:",
        "        status = -1",
        "    else:",
    ]
    lines += ["        " + line for line in _period_lines(L)]
    lines += [
        "        if not (" + " and ".join(f"isfinite(y[{j}])" for j in range(L.dim)) + "):",
        "            status = 1",
        "    o = observe(PO, y)",
        "    out = False",
    ]
    for j in range(L.n_obs):
        lines += [
            f"    v{j} = o[{j}]",
            *("    " + line for line in _clip_lines(j, f"v{j}", f"v{j}")),
        ]
    lines += [
        "    r = evaluate(PE, y, un)",
        "    q = readouts(PR, y, u, f)",
        f"    return status, c, hi, f, y, ({comps('v{j}', L.n_obs)}), out, r, q"
        + (", cc" if L.step_c is not None else "")
        + (", e" if estimate else ""),
    ]
    namespace = _namespace(L)
    if estimate:
        from ..stepsize.forms import error_estimate, motion_error_estimate, relaxation_estimate

        namespace.update(
            error_estimate=error_estimate,
            motion_error_estimate=motion_error_estimate,
            relaxation_estimate=relaxation_estimate,
        )
    generate(
        "\n".join(lines),
        f"state kernel dim={L.dim} n_obs={L.n_obs}" + (" estimate" if estimate else ""),
        namespace,
    )
    return _cached_njit(namespace["one"], "one", **KERNEL_OPTIONS)


@cache
def run_kernel(layout: Layout):
    """The compiled internal steps of ONE state's run with a given count and step (the checked
    period's, ``tolerance_check``: the main run's even count, the companion's half as many steps
    of twice the size; :meth:`rbenvs.core.period.Period._run_one`), on
    tuples of floats, for a layout with ``step_c``. Signature::

        run(y, cc, u, c, hi, P) -> (y, fired, cc)

    ``P = (PS, PV, PW)``; ``c`` steps of ``hi`` from ``y`` with the compensation ``cc``, the
    switches after each, the terminal event ending them (``fired``), a non-finite state
    stopping them (returned as it is: the caller's failure path takes over)."""

    L = layout
    lines = ["def run(y, cc, u, c, hi, P):", "    PS, PV, PW = P", "    f = False"]
    lines += ["    " + line for line in _steps_lines(L)]
    lines += ["    return y, f, cc"]
    namespace = _namespace(L)
    generate("\n".join(lines), f"run kernel dim={L.dim}", namespace)
    return _cached_njit(namespace["run"], "run", **KERNEL_OPTIONS)


@cache
def runs_kernel(layout: Layout):
    """:func:`run_kernel` for a batch in one compiled loop (the vector env's checked runs): as
    passes over the batch (:func:`_lockstep_passes`) for a layout without switches whose event,
    if any, is its next first stage, else sub-env by sub-env. Signature::

        runs(Y, CC, U, counts, H, fired, P) -> None

    ``Y``, ``CC``: ``(dim, n)`` states and compensations, advanced in place; ``U``: ``(n_control,
    n)`` controls; ``counts``, ``H``: each sub-env's steps and step; ``fired``: ``(n,)`` bools
    written (the terminal event); ``P = (PS, PV, PW)``."""

    L = layout
    event = L.rhs_event is not None
    if (event or L.event is None) and not L.switches:
        # as passes over the batch (the batch kernel's lockstep, _lockstep_passes): a sub-env's
        # steps (and event) read only its own columns, so the bits are its own loop's
        u = f"u = ({_comps('U[{j}, i]', L.n_control)})"
        lines = [
            "def runs(Y, CC, U, counts, H, fired, P):",
            "    PS, PV, PW = P",
            "    n = Y.shape[1]",
            "    Ynew = Y",
            *([f"    K = np.empty(({L.dim}, n))"] if event else []),
            "    live = np.empty(n, dtype=np.bool_)",
            "    cmax = 0",
            "    for i in range(n):",
            f"        y = ({_comps('Y[{j}, i]', L.dim)})",
            "        " + u,
            "        live[i] = True",
            "        if counts[i] > cmax:",
            "            cmax = counts[i]",
            *(
                [
                    "        kk, g = rhs_event(PV, y, u)",
                    *(f"        K[{j}, i] = kk[{j}]" for j in range(L.dim)),
                ]
                if event
                else []
            ),
            "        fired[i] = False",
            *("    " + line for line in _lockstep_passes(L, u, "H[i]")),
        ]
        namespace = _namespace(L)
        generate("\n".join(lines), f"runs kernel dim={L.dim} lockstep", namespace)
        return _cached_njit(namespace["runs"], "runs", **KERNEL_OPTIONS)
    lines = [
        "def runs(Y, CC, U, counts, H, fired, P):",
        "    PS, PV, PW = P",
        "    for i in range(Y.shape[1]):",
        f"        y = ({_comps('Y[{j}, i]', L.dim)})",
        f"        cc = ({_comps('CC[{j}, i]', L.dim)})",
        f"        u = ({_comps('U[{j}, i]', L.n_control)})",
        "        c = counts[i]",
        "        hi = H[i]",
        "        f = False",
    ]
    lines += ["        " + line for line in _steps_lines(L)]
    lines += (
        [f"        Y[{j}, i] = y[{j}]" for j in range(L.dim)]
        + [f"        CC[{j}, i] = cc[{j}]" for j in range(L.dim)]
        + ["        fired[i] = f"]
    )
    namespace = _namespace(L)
    generate("\n".join(lines), f"runs kernel dim={L.dim}", namespace)
    return _cached_njit(namespace["runs"], "runs", **KERNEL_OPTIONS)


@cache
def plan_kernel(layout: Layout):
    """The guard's ratio and the rates of ONE state's period, compiled (a tolerance's single-env
    step: its count and its ``info["error_estimate"]`` from one evaluation;
    :meth:`rbenvs.stepsize.controller.StepRule.plan`, whose values it returns bit for bit).
    Signature::

        plan(y, u, P) -> (x, r, rate, a)

    ``P = (PG, PA, PD, CD)``; ``x`` the ratio (the period needs ``ceil(x)`` steps), ``r`` the
    rate(s) (``(lambda, mu, lambda_e)`` with the state's own speed), ``rate`` the decaying rate
    (0 where it is not positive) and ``a`` its share (1 where ``rate`` is 0)."""

    L = layout
    lines = ["def plan(y, u, P):", "    PG, PA, PD, CD = P", "    dt = PG[0]"]
    lines += ["    " + line for line in _ratio_lines(L, "u = u", parts=True)]
    lines += ["    return x, r, rate, a"]
    namespace = _namespace(L)
    generate("\n".join(lines), f"plan kernel dim={L.dim}", namespace)
    return _cached_njit(namespace["plan"], "plan", **KERNEL_OPTIONS)


@cache
def plans_kernel(layout: Layout, ratio: bool = False):
    """:func:`plan_kernel` for a batch, sub-env by sub-env in one compiled loop: the rates (the
    vector env's error estimate) or, with ``ratio``, the guard's ratio alone (its checked
    period's count). Signature::

        plans(Y, U, P, R, RATE, A) -> None      plans(Y, U, P, X) -> None  (ratio)

    ``Y``: ``(dim, n)`` states; ``U``: ``(n_control, n)`` controls; ``P = (PG, PA, PD, CD)``;
    written: ``RATE``, ``A`` ``(n,)`` and ``R`` ``(3, n)`` (the rates ``(lambda, mu,
    lambda_e)`` with the state's own speed) or ``(1, n)``; ``X`` ``(n,)``."""

    L = layout
    lines = [
        "def plans(Y, U, P, X):" if ratio else "def plans(Y, U, P, R, RATE, A):",
        "    PG, PA, PD, CD = P",
        "    dt = PG[0]",
        "    for i in range(Y.shape[1]):",
        f"        y = ({_comps('Y[{j}, i]', L.dim)})",
        f"        u = ({_comps('U[{j}, i]', L.n_control)})",
    ]
    if ratio:
        lines += ["        " + line for line in _ratio_lines(L, "u = u")] + ["        X[i] = x"]
    else:
        lines += ["        " + line for line in _ratio_lines(L, "u = u", parts=True, ratio=False)]
        lines += [
            *(
                [f"        R[{j}, i] = r[{j}]" for j in range(3)]
                if L.motion
                else ["        R[0, i] = r"]
            ),
            "        RATE[i] = rate",
            "        A[i] = a",
        ]
    namespace = _namespace(L)
    generate("\n".join(lines), f"plans kernel dim={L.dim}{' ratio' if ratio else ''}", namespace)
    return _cached_njit(namespace["plans"], "plans", **KERNEL_OPTIONS)

"""The batch kernels' parts (:class:`Layout`, the period's and finish's lines) and the batch step
(:func:`batch_kernel`) and a reset's finish."""

from __future__ import annotations

from collections.abc import Callable
from functools import cache
from typing import NamedTuple

from ..codegen import generate
from ..jit import register as _register
from ..jit import register_all as _register_all
from ..kernel_cache import njit as _cached_njit
from ..stepsize.forms import products

# How every kernel is compiled. error_model="numpy": a float division by zero gives inf/nan as
# on arrays, with no per-element check (which would keep the loops out of SIMD registers).
# forceinline: the kernel and, inherited, every pure function it calls are always-inlined, so a
# loop body is one function however large its parts (LLVM's inliner stops at a size threshold,
# a task's reward with an atan2 is over it, and a call left in a loop keeps it scalar).
KERNEL_OPTIONS = {"error_model": "numpy", "forceinline": True}

# LLVM vectorises a loop whose stores may overlap its loads only behind run-time checks that the
# arrays' ranges are disjoint, and gives up past 8 such checks by default: the tippe top's loops
# (its state and next first stage, with a tolerance its compensation too: 33 rows, 528 pairs)
# need more. Raising these process-wide limits changes no result (the checks fall back to the
# scalar loop where ranges overlap); set once, before rbenvs compiles its first kernel.
LLVM_OPTIONS = ("-runtime-memory-check-threshold=2048", "-vectorize-memory-check-threshold=2048")
_llvm_tuned = False


def _tune_llvm() -> None:
    global _llvm_tuned
    if not _llvm_tuned:
        import llvmlite.binding as llvm

        for option in LLVM_OPTIONS:
            llvm.set_option("rbenvs", option)
        _llvm_tuned = True


def _no_compensation():
    import numpy as np

    return np.zeros((0, 0))


# the kernels' CC argument where the layout carries no compensation (never read)
NO_COMPENSATION = _no_compensation()


def _comps(fmt, k):
    return ", ".join(fmt.format(j=j) for j in range(k)) + ("," if k == 1 else "")


def _controls(L, rows: bool = False) -> tuple[str, str]:
    """The lines that set sub-env ``i``'s controls ``u`` and normalised action ``un``: read from
    tuples of ``(n,)`` arrays ``U`` and ``UN`` (the batch kernel's arguments) or, with ``rows``,
    from the rows of ``(k, n)`` arrays (the vector step's, filled from the actions once: a loop
    reading unit-stride rows stays in SIMD registers, one reading each sub-env's actions from
    the ``(n, k)`` batch would not)."""
    access = "{name}[{j}, i]" if rows else "{name}[{j}][i]"
    return (
        f"u = ({_comps(access.format(name='U', j='{j}'), L.n_control)})",
        f"un = ({_comps(access.format(name='UN', j='{j}'), L.n_action)})",
    )


def _physics_lines(dim: int, u: str) -> list[str]:
    """The body of the physics loops: ``Ynew`` = ``substeps`` steps of ``step`` from ``Y``
    (``u``: the line that sets the controls ``u`` of sub-env ``i``)."""
    y_new = f"y = ({_comps('Ynew[{j}, i]', dim)})"
    return [
        "    n = Y.shape[1]",
        # substeps as passes over the batch: a runtime-length loop inside the element loop
        # would keep it scalar; the first pass reads Y, the rest update Ynew in place (the same
        # steps per element, in the same order)
        "    for i in range(n):",
        f"        y = ({_comps('Y[{j}, i]', dim)})",
        f"        {u}",
        "        y = step(PS, y, u, h)",
        *[f"        Ynew[{j}, i] = y[{j}]" for j in range(dim)],
        "    for _ in range(substeps - 1):",
        "        for i in range(n):",
        f"            {y_new}",
        f"            {u}",
        "            y = step(PS, y, u, h)",
        *[f"            Ynew[{j}, i] = y[{j}]" for j in range(dim)],
    ]


class Layout(NamedTuple):
    """What a batch kernel is compiled for (the parameters are arguments, not part of it):
    the pure functions and the sizes of their tuples.

    ``step(PS, y, u, h) -> y``; ``observe(PO, y) -> o`` (``n_obs``); ``evaluate(PE, y, u_norm)
    -> (reward, terminated, m_1..m_k)`` (``k = n_metrics``); ``readouts(PR, y, u, fired) ->
    (r_1..r_m)`` (``m = n_readouts``); the guard's ``rotation(PA, y) -> lambda`` and
    ``dissipation(PD, y, u) -> lambda_d`` (or ``None``: no such rate; with ``share``, the
    tolerance's share ``share(PD[1], y, u, dt, p, lambda_d) -> a`` of that mode's error, ``PD =
    (P_d, P_a)``); the terminal ``event(PV,
    y, u) -> g`` checked after every internal step, firing where ``g < 0`` (or ``None``); and
    ``rhs_event(PV, y, u) -> (dy, g)``: the vector field and the event from one evaluation (or
    ``None``), with which ``step`` is the integrator's step given its first stage,
    ``step(PS, y, k0, u, h)``: the evaluation that checks the event at a new state is the next
    step's first stage (the tippe top's contact solve, once per stage).
    """

    step: Callable
    dim: int
    n_control: int
    n_action: int
    observe: Callable
    n_obs: int
    evaluate: Callable
    n_metrics: int
    readouts: Callable
    n_readouts: int
    rotation: Callable | None = None
    dissipation: Callable | None = None
    event: Callable | None = None
    rhs_event: Callable | None = None
    switches: tuple = ()
    motion: bool = (
        False  # rotation(PA, y, u) -> (lambda, mu): the accuracy term with the state's speed
    )
    share: Callable | None = None
    # step's compensated form (a tolerance), stepc(PS, y, cc, u, h) -> (y, cc) (with rhs_event
    # stepc(PS, y, cc, k0, u, h)): the steps carry each run's compensation cc from period to
    # period (the kernels' CC, the state kernel's cc), from zero again after a switch
    # (rbenvs.core.period.Period.advance); None: the plain step
    step_c: Callable | None = None


def _ratio_lines(
    L: Layout, u: str, parts: bool = False, ratio: bool = True, rates: str = "r"
) -> list[str]:
    """Lines that set ``x``, the guard's ratio for the state ``y`` (and controls ``u``): the step
    core's rule (:meth:`StepRule.ratio`). ``parts``: also keep what the period's error estimate
    reads (:meth:`StepRule.plan`): the rate(s) (named ``rates``), the decaying rate ``rate`` (0
    where it is not positive) and its share ``a`` (1 where the rate is 0); with ``ratio=False``
    only those."""
    rotation = "rotation(PA, y, u)" if L.motion else "rotation(PA, y)"
    fn = "step_ratio_motion" if L.motion else "step_ratio"
    lines = (
        [u] if L.motion else []
    )  # the state's own speed in the accuracy term: rotation(PA, y, u) -> (lambda, mu, lambda_e)
    if parts:
        lines += [f"{rates} = {rotation}", *([f"x = {fn}(PG, {rates})"] if ratio else [])]
    else:
        lines += [f"x = {fn}(PG, {rotation})"]
    if L.dissipation is None:
        return lines + (["rate = 0.0", "a = 1.0"] if parts else [])
    # v > x: Python's max(x, v), the float path's (NaN in x stays NaN); a tolerance's term for
    # the decaying mode (0 without one), times the mode's share where the system declares one
    pd, a = (
        ("PD[0]", "share(PD[1], y, u, dt, PG[4], rate)") if L.share is not None else ("PD", "1.0")
    )
    raise_x = ["    if v > x:", "        x = v"]
    bound = ["    v = dt / (CD / rate)", *raise_x] if ratio else []
    if parts:
        relax = [
            f"    a = {a}",
            *(["    v = relaxation_steps(PG, rate, a)", *raise_x] if ratio else []),
        ]
    else:
        relax = [f"    v = relaxation_steps(PG, rate, {a})", *raise_x]
    lines += [
        u,
        *(["a = 1.0"] if parts else []),
        f"rate = dissipation({pd}, y, u)",
        "if rate > 0.0:",
        *bound,
        *relax,
    ]
    return lines + (["else:", "    rate = 0.0"] if parts else [])


def _count_lines(L: Layout, u: str) -> list[str]:
    """Lines that raise the count ``c`` (set to ``substeps``) to the guard's for the state ``y``
    (and controls ``u``), counting ``need``: the step core's rule (:meth:`StepRule.steps`)."""
    from ..stepsize.controller import MAX_INTERNAL_STEPS

    return _ratio_lines(L, u) + [
        "if not (x <= substeps):",
        f"    c = ceil(x) if x <= {MAX_INTERNAL_STEPS} else {MAX_INTERNAL_STEPS + 1}",
        "    need += 1",
    ]


def _locate_lines(k: int) -> list[str]:
    """Lines of :func:`rbenvs.core.hybrid.locate` for switch ``k``, inline (the same operations
    in the same order): from ``yp`` (``g >= 0``) to ``y`` (``g = fe < 0``) over ``hi``, the
    first time ``t`` and state ``ya`` where ``function_k`` turns negative."""
    from ..core.hybrid import EPS, LOCATE_ITERATIONS

    return [
        "a = 0.0",
        f"fa = function{k}(PW[{k}][0], yp, u)",
        "b = hi",
        "fb = fe",
        "yb = y",
        "wa = fa",
        "wb = fb",
        "side = 0",
        f"for it in range({LOCATE_ITERATIONS}):",
        f"    if fb >= -PW[{k}][1] or b - a <= 4.0 * {EPS!r} * hi:",
        "        break",
        "    t = (a * wb - b * wa) / (wb - wa)",
        "    if not a < t < b:",
        "        t = 0.5 * (a + b)",
        "    yt = step(PS, yp, u, t)",
        f"    ft = function{k}(PW[{k}][0], yt, u)",
        "    if ft < 0.0:",
        "        b, fb, yb, wb = t, ft, yt, ft",
        "        if side == -1:",
        "            wa *= 0.5",
        "        side = -1",
        "    else:",
        "        a, fa, wa = t, ft, ft",
        "        if side == 1:",
        "            wb *= 0.5",
        "        side = 1",
        "t, ya = b, yb",
    ]


def _switch_lines(L: Layout) -> list[str]:
    """Lines after an internal step ``yp -> y`` of length ``hi``: the first switch that applies
    to ``yp``'s mode, located inside the step where its function turned negative, made, and the
    rest of the step taken in the new mode (:meth:`rbenvs.core.hybrid.Switching.after_step`)."""
    lines = []
    for k in range(len(L.switches)):
        lines += [
            f"{'if' if k == 0 else 'elif'} applies{k}(PW[{k}][3], yp):",
            f"    fe = function{k}(PW[{k}][0], y, u)",
            "    if fe < 0.0:",
            f"        if function{k}(PW[{k}][0], yp, u) < 0.0:",
            "            t, ya = 0.0, yp",
            "        else:",
            *("            " + line for line in _locate_lines(k)),
            f"        ys = switch{k}(PW[{k}][2], ya)",
            "        y = step(PS, ys, u, hi - t) if t < hi else ys",
            *([f"        cc = ({_comps('0.0', L.dim)})"] if L.step_c is not None else []),
        ]
    return lines


def _period_lines(L: Layout) -> list[str]:
    """Lines that advance the state ``y`` under ``u`` by ``c`` internal steps (the step core's
    period, :meth:`rbenvs.core.period.Period.advance`): ``hi`` the internal step and ``f`` whether
    the terminal event ended it; past the cap the period is refused (``y`` NaN)."""
    from ..stepsize.controller import MAX_INTERNAL_STEPS

    lines = [
        "f = False",
        f"if c > {MAX_INTERNAL_STEPS}:",  # refused: a numerical failure, reported with dt / c
        "    hi = dt / c",
        f"    y = ({_comps('nan', L.dim)})",
        "else:",
        "    hi = h if c == substeps else dt / c",
    ]
    return lines + ["    " + line for line in _steps_lines(L)]


def _steps_lines(L: Layout) -> list[str]:
    """Lines that take ``c`` internal steps ``hi`` from ``y`` under ``u``
    (:meth:`rbenvs.core.period.Period._run_one`): the switches after each, the terminal event ending
    them (``f = True``), a non-finite state stopping them."""
    finite = "    if not (" + " and ".join(f"isfinite(y[{j}])" for j in range(L.dim)) + "):"
    # one internal step from y (kk: its first stage), plain or carrying the compensation cc
    # (cc: the run's compensation, set by the caller and carried on)
    take, take_first = ["y = step(PS, y, u, hi)"], ["y = step(PS, y, kk, u, hi)"]
    if L.step_c is not None:
        take, take_first = (
            ["y, cc = stepc(PS, y, cc, u, hi)"],
            ["y, cc = stepc(PS, y, cc, kk, u, hi)"],
        )
    if L.rhs_event is not None:  # the event's evaluation at a new state is the next first stage
        return [
            "kk, g = rhs_event(PV, y, u)",
            "for k in range(c):",
            *("    " + line for line in take_first),
            finite,
            "        break",
            "    kk, g = rhs_event(PV, y, u)",
            "    if g < 0.0:",
            "        f = True",
            "        break",
        ]
    if L.event is not None:  # the step core's rule: a non-finite state stops, an event freezes
        # (with switches, the stem's: the switches after each step, then the terminal event)
        switches = ["    " + line for line in _switch_lines(L)] if L.switches else []
        return [
            "for k in range(c):",
            *(["    yp = y"] if L.switches else []),
            *("    " + line for line in take),
            *switches,
            finite,
            "        break",
            "    if event(PV, y, u) < 0.0:",
            "        f = True",
            "        break",
        ]
    if L.switches:
        return [
            "for k in range(c):",
            "    yp = y",
            *("    " + line for line in take),
            *("    " + line for line in _switch_lines(L)),
        ]
    return ["for k in range(c):", *("    " + line for line in take)]


def _clip_lines(j: int, v: str, dest: str) -> list[str]:
    """The observation bound of component ``j`` (``HI[j]``), the single env's rule, written once
    for every kernel: ``out`` set where ``v`` lies outside (a NaN counts as outside), ``dest``
    the value clipped. Without a branch (min/max return ``v`` itself inside the bounds): a loop
    without branches stays in SIMD registers."""
    return [
        f"out = out | (not (({v} >= -HI[{j}]) & ({v} <= HI[{j}])))",
        f"{dest} = min(max({v}, -HI[{j}]), HI[{j}])",
    ]


def _finish_lines(
    L: Layout, y: str, un: str, u: str, fired: str, fresh: str | None = None
) -> list[str]:
    """The loops over a batch's states (``y`` reads state ``i``) that fill ``obs`` (clipped to
    ``HI``) and ``over``, the evaluation's ``reward``, ``terminated`` and metrics ``M_j`` under the
    normalised action ``un``, and the read-outs ``R_j`` under the control ``u`` with the event
    flag ``fired``. One loop per stage: a loop of arithmetic and unit-stride loads and stores
    runs in SIMD registers, one fused loop would not. ``fresh`` (an expression in ``i``): the
    states that are new starts, finished as after a reset instead (zero action; read-outs with
    no control acted and no event), selected per component, so that the loops keep no branch."""
    # the clip (:func:`_clip_lines`) writes the components as rows of a scratch array
    # (unit-stride stores, which stay in SIMD registers), then one loop interleaves them into
    # the (n, n_obs) observation
    lines = [
        f"    OT = np.empty(({L.n_obs}, n), dtype=np.float32)",
        "    for i in range(n):",
        "        " + y,
        "        o = observe(PO, y)",
        "        out = False",
    ]
    for j in range(L.n_obs):
        lines += [
            f"        v = o[{j}]",
            *("        " + line for line in _clip_lines(j, "v", f"OT[{j}, i]")),
        ]
    lines += [
        "        over[i] = out",
        "    for i in range(n):",
        *(f"        obs[i, {j}] = OT[{j}, i]" for j in range(L.n_obs)),
    ]
    if fresh is None:
        action, reads = [], [f"        R{j}[i] = q[{j}]" for j in range(L.n_readouts)]
    else:
        # (where the read-outs ignore u, LLVM computes the two calls' common arithmetic once)
        action = [
            "        z = " + fresh,
            f"        un = ({_comps('0.0 if z else un[{j}]', L.n_action)})",
        ]
        reads = [
            "        z = " + fresh,
            "        q0 = readouts(PR, y, None, False)",
            *[f"        R{j}[i] = q0[{j}] if z else q[{j}]" for j in range(L.n_readouts)],
        ]
    return lines + [
        "    for i in range(n):",
        "        " + y,
        "        " + un,
        *action,
        "        r = evaluate(PE, y, un)",
        "        reward[i] = r[0]",
        "        terminated[i] = r[1]",
        *[f"        M{j}[i] = r[{j + 2}]" for j in range(L.n_metrics)],
        "    for i in range(n):",
        "        " + y,
        "        " + u,
        f"        q = readouts(PR, y, u, {fired})",
        *reads,
    ]


@cache
def finish_kernel(layout: Layout):
    """The batch kernel's finish alone, for states that have just been reset (an autoreset's
    rows, a reset batch): ``finish(Y, PO, PE, PR, HI, obs, over, reward, terminated, M_1..M_k,
    R_1..R_m)`` with no control acted yet (read-outs under ``u = None``, the single env's rule),
    the task's evaluation at zero action, no event."""

    L = layout
    metrics = [f"M{j}" for j in range(L.n_metrics)]
    reads = [f"R{j}" for j in range(L.n_readouts)]
    args = ["Y", "PO", "PE", "PR", "HI", "obs", "over", "reward", "terminated"] + metrics + reads
    y = f"y = ({_comps('Y[{j}, i]', L.dim)})"
    lines = [f"def finish({', '.join(args)}):", "    n = Y.shape[1]"]
    lines += _finish_lines(L, y, f"un = ({_comps('0.0', L.n_action)})", "u = None", "False")
    namespace = _namespace(L)
    generate("\n".join(lines), f"finish kernel dim={L.dim} n_obs={L.n_obs}", namespace)
    return _cached_njit(namespace["finish"], "finish", **KERNEL_OPTIONS)


def _namespace(L: Layout) -> dict:
    from math import ceil, isfinite, nan

    import numpy as np

    from ..stepsize.forms import relaxation_steps, step_ratio, step_ratio_motion

    _tune_llvm()
    _register_all()
    switch_fns = [fn for triple in L.switches for fn in triple]
    for fn in (
        L.step,
        L.step_c,
        L.observe,
        L.evaluate,
        L.readouts,
        L.rotation,
        L.dissipation,
        L.share,
        L.event,
        L.rhs_event,
        *switch_fns,
    ):
        if fn is not None:
            _register(fn)
    namespace = {
        "step": L.step,
        "stepc": L.step_c,
        "observe": L.observe,
        "evaluate": L.evaluate,
        "readouts": L.readouts,
        "rotation": L.rotation,
        "dissipation": L.dissipation,
        "share": L.share,
        "event": L.event,
        "rhs_event": L.rhs_event,
        "step_ratio": step_ratio,
        "step_ratio_motion": step_ratio_motion,
        "relaxation_steps": relaxation_steps,
        "isfinite": isfinite,
        "ceil": ceil,
        "nan": nan,
        "np": np,
    }
    for k, (applies, function, switch) in enumerate(L.switches):
        namespace.update({f"applies{k}": applies, f"function{k}": function, f"switch{k}": switch})
    return namespace


@cache
def batch_kernel(layout: Layout):
    """The compiled step of a batch for one :class:`Layout` (cached per process). Signature::

        kernel(Y, Ynew, CC, U, UN, h, dt, substeps, check, refuse, skip, PS, PO, PE, PR, PG, PA,
               PD, CD, PV, PW, HI, counts, hstep, fired, obs, over, reward, terminated, M_1..M_k,
               R_1..R_m) -> status

    ``Y``/``Ynew``: ``(dim, n)`` float64 states before/after; ``CC``: ``(dim, n)``, each
    sub-env's compensation, carried on in place (a layout with ``step_c``; otherwise unread);
    ``U``/``UN``: tuples of ``(n,)`` float64 control and normalised action components; ``h =
    dt / substeps``.

    The period is the step core's (:meth:`rbenvs.core.period.Period.advance`), per sub-env:
    with ``check`` the guard counts its internal steps from its state (``x = step_ratio(PG,
    rotation(PA, y))``, raised to ``dt / (CD / dissipation(PD, y, u))`` where that is larger;
    ``max(substeps, ceil(x))``, or ``MAX_INTERNAL_STEPS + 1`` past the cap: a refused period,
    its state NaN), except sub-envs in ``skip`` (about to restart: ``substeps``). With
    ``refuse`` and any count above ``substeps`` nothing is written and ``-1`` returned (the
    caller raises, naming ``max(counts)``). When every count is ``substeps`` and no event is
    watched, the steps run as passes over the batch (SIMD); otherwise sub-env by sub-env,
    each with its own ``h = dt / count`` and, with an ``event``, frozen where it fires.
    ``counts``, ``hstep`` and ``fired`` report that per sub-env.

    If any new state is non-finite the kernel returns their count after the physics, the task
    outputs unset: the caller's numerical-failure path takes over from ``Ynew``. Otherwise the
    observation is clipped to ``HI`` (``over`` where the state left the bounds; the single
    env's rule), then the task's evaluation and the read-outs fill their arrays; 0 returned.
    """

    L = layout
    metrics = [f"M{j}" for j in range(L.n_metrics)]
    reads = [f"R{j}" for j in range(L.n_readouts)]
    args = (
        [
            "Y",
            "Ynew",
            "CC",
            "U",
            "UN",
            "h",
            "dt",
            "substeps",
            "check",
            "refuse",
            "skip",
            "PS",
            "PO",
            "PE",
            "PR",
            "PG",
            "PA",
            "PD",
            "CD",
            "PV",
            "PW",
            "HI",
            "counts",
            "hstep",
            "fired",
            "obs",
            "over",
            "reward",
            "terminated",
        ]
        + metrics
        + reads
    )
    lines = [f"def kernel({', '.join(args)}):", "    n = Y.shape[1]"]
    lines += _period_and_finish(L, *_controls(L), "")
    lines += ["    return 0"]
    namespace = _namespace(L)
    generate("\n".join(lines), f"batch kernel dim={L.dim} n_obs={L.n_obs}", namespace)
    return _cached_njit(namespace["kernel"], "kernel", **KERNEL_OPTIONS)


def _lockstep_lines(L: Layout, u: str) -> list[str]:
    """The period of every sub-env as passes over the batch: pass ``k`` takes internal step ``k``
    of every sub-env that has one left (and, with a terminal event shared with the next first
    stage, :func:`_period_lines`' ``rhs_event`` branch, the tippe top's lift-off, has neither
    fired nor gone non-finite) and leaves the others as they are (the same operations per
    sub-env as its own loop, so the same bits; a loop of arithmetic and selections stays in SIMD
    registers, and the period's steps are where the time goes). ``K`` holds
    each sub-env's next first stage (with the event), ``live`` whether it goes on. Without an
    event (a layout without switches: the free body's and the heavy top's compensated periods)
    a sub-env takes its count, as its own loop does."""
    from ..stepsize.controller import MAX_INTERNAL_STEPS

    dim, event = L.dim, L.rhs_event is not None
    return [
        *([f"K = np.empty(({dim}, n))"] if event else []),
        "live = np.empty(n, dtype=np.bool_)",
        "cmax = 0",
        "for i in range(n):",
        f"    y = ({_comps('Y[{j}, i]', dim)})",
        "    " + u,
        "    c = counts[i]",
        f"    if c > {MAX_INTERNAL_STEPS}:",  # refused: a numerical failure, reported with dt / c
        "        hstep[i] = dt / c",
        f"        y = ({_comps('nan', dim)})",
        "        live[i] = False",
        "    else:",
        "        hstep[i] = h if c == substeps else dt / c",
        "        live[i] = True",
        "        if c > cmax:",
        "            cmax = c",
        *(["    kk, g = rhs_event(PV, y, u)"] if event else []),
        *(f"    Ynew[{j}, i] = y[{j}]" for j in range(dim)),
        *((f"    K[{j}, i] = kk[{j}]" for j in range(dim)) if event else ()),
        "    fired[i] = False",
        *_lockstep_passes(L, u, "hstep[i]"),
    ]


def _lockstep_passes(L: Layout, u: str, h: str) -> list[str]:
    """:func:`_lockstep_lines`' passes over the batch (and the checked runs', :func:`runs_kernel`):
    ``Ynew``, ``K`` (and ``CC``) hold each sub-env's state, next first stage (with an event) and
    compensation (with one), ``live`` whether it goes on, ``cmax`` the largest of the
    ``counts``; ``h`` the expression of sub-env ``i``'s step."""
    dim, event = L.dim, L.rhs_event is not None
    y = f"y = ({_comps('Ynew[{j}, i]', dim)})"
    kk = f"kk = ({_comps('K[{j}, i]', dim)})"
    finite = " & ".join(f"isfinite(yn[{j}])" for j in range(dim))
    compensated = L.step_c is not None  # (CC: each sub-env's compensation, as K its first stage)
    args = "y, cc, kk, u" if event else "y, cc, u"
    take = [
        f"yn, cn = stepc(PS, {args}, {h})"
        if compensated
        else f"yn = step(PS, {args.replace('cc, ', '')}, {h})"
    ]
    # (the event fired or the state went non-finite: the sub-env stops; all stopped: the passes end)
    stop = [
        "        kn, g = rhs_event(PV, yn, u)",
        f"        fin = {finite}",
        "        hit = fin & (g < 0.0)",
    ]
    return [
        "for k in range(cmax):",
        *(["    going = 0"] if event else []),
        "    for i in range(n):",
        "        " + y,
        *(["        " + kk] if event else []),
        "        " + u,
        *([f"        cc = ({_comps('CC[{j}, i]', dim)})"] if compensated else []),
        "        a = live[i] & (k < counts[i])",
        *("        " + line for line in take),
        *(stop if event else []),
        *(f"        Ynew[{j}, i] = yn[{j}] if a else y[{j}]" for j in range(dim)),
        *((f"        K[{j}, i] = kn[{j}] if a else kk[{j}]" for j in range(dim)) if event else ()),
        *(
            (f"        CC[{j}, i] = cn[{j}] if a else cc[{j}]" for j in range(dim))
            if compensated
            else ()
        ),
        *(
            [
                "        fired[i] = fired[i] | (a & hit)",
                "        on = live[i] & (not (a & (hit | (not fin))))",
                "        live[i] = on",
                "        going += on",
                "    if going == 0:",
                "        break",
            ]
            if event
            else []
        ),
    ]


def _period_and_finish(
    L: Layout, u: str, un: str, more: str, starts: list[str] = (), fresh: str | None = None
) -> list[str]:
    """The batch kernel's body (see :func:`batch_kernel`): :func:`_checked_period`, the lines
    ``starts`` (the vector step's restarts: new starts written into ``Ynew``) and the finish
    loops (``fresh``: the states finished as new starts, :func:`_finish_lines`); ``u`` and
    ``un`` the lines that set sub-env ``i``'s controls and normalised action
    (:func:`_controls`); ``more``: further values the early returns append (``", 0"``)."""
    return (
        _checked_period(L, u, more)
        + list(starts)
        + _finish_lines(L, f"y = ({_comps('Ynew[{j}, i]', L.dim)})", un, u, "fired[i]", fresh)
    )


def _estimate_expression(L: Layout) -> str:
    """The period's error estimate from the rates ``er`` (``rate``, ``a``) and the step ``hi``:
    the functions :meth:`rbenvs.stepsize.controller.StepRule.estimate` calls, ``PEE`` its ``(C, p,
    dt)``."""
    estimate = "motion_error_estimate(PEE, er, hi)" if L.motion else "error_estimate(PEE, er, hi)"
    if L.dissipation is not None:
        estimate += " + relaxation_estimate(PEE, rate, a, hi)"
    return estimate


def _checked_period(
    L: Layout, u: str, more: str, estimate: bool = False, gate: int = 0
) -> list[str]:
    """The guard's counts (a refusal returns -1 before anything is written), the period per
    sub-env or as SIMD passes, and the non-finite check (returns ``bad``, the count).
    ``estimate``: the count's loop also writes each period's error estimate into ``EST`` from the
    same rates (0 for a restarting sub-env, ``next_step`` and ``skip``: no period of its own ran)
    and the step its count gives, the step the period takes (one evaluation of the rates).
    ``gate`` (with ``estimate``; :class:`VectorLayout`'s, its scheme's order ``p``, 0: none): first
    every sub-env's cheap bound
    ``Lambda = gate(PGT[0], y)``, its count ``substeps`` and its estimate ``C Lambda dt (Lambda
    h)^p`` (the rates :func:`rbenvs.stepsize.forms.motion_rates` returns there), in one loop without
    branches; the count's loop then runs only if a sub-env's bound does not hold, on those alone."""
    comps, dim = _comps, L.dim
    y_old = f"y = ({comps('Y[{j}, i]', dim)})"
    store = [f"Ynew[{j}, i] = y[{j}]" for j in range(dim)]
    lines = ["    uniform = True"]
    # 1. the guard's counts, before anything is written
    count = ["for i in range(n):", "    c = substeps"]
    if (
        estimate and gate
    ):  # (the sub-envs within the bound were counted and estimated in the gate's loop)
        # (motion_rates' test Lambda <= limit and motion_error_estimate's C Lambda dt (Lambda h)^p,
        # its power as products)
        test = "big <= PGT[1]"
        lines += [
            "    ng = 0",
            "    for i in range(n):",
            "        " + y_old,
            "        big = gate(PGT[0], y)",
            "        counts[i] = substeps",
            "        z = big * h",
            f"        EST[i] = PEE[0] * big * PEE[2] * {products('z', gate)}",
            f"        ng += not ({test})",
            # (a restart ran no period of its own: apart, so that the loop above has no branch)
            "    if next_step:",
            "        for i in range(n):",
            "            if skip[i]:",
            "                EST[i] = 0.0",
        ]
        count = [
            "if ng:",
            "for i in range(n):",
            "    c = substeps",
            "    " + y_old,
            "    big = gate(PGT[0], y)",
            f"    if {test}:",
            "        continue",
        ]
    if estimate:
        from ..stepsize.controller import MAX_INTERNAL_STEPS

        count += (["    " + y_old] if not gate else []) + [
            *("    " + line for line in _ratio_lines(L, u, parts=True, rates="er")),
            "    if check and not skip[i] and not (x <= substeps):",
            f"        c = ceil(x) if x <= {MAX_INTERNAL_STEPS} else {MAX_INTERNAL_STEPS + 1}",
            "        need += 1",
            "    if next_step and skip[i]:",
            "        EST[i] = 0.0",
            "    else:",
            "        hi = h if c == substeps else dt / c",
            f"        EST[i] = {_estimate_expression(L)}",
        ]
    elif L.rotation is not None:
        count += [
            "    if check and not skip[i]:",
            "        " + y_old,
            *("        " + line for line in _count_lines(L, u)),
        ]
    count += ["    counts[i] = c", "    if c != substeps:", "        uniform = False"]
    if estimate and gate:  # (the loop under "if ng:")
        count = count[:1] + ["    " + line for line in count[1:]]
    lines += [
        "    need = 0",
        *("    " + line for line in count),
        "    if refuse and need:",
        f"        return -1{more}",
    ]
    # 2. the physics: passes over the batch where every count is substeps, else per sub-env
    per_env = ["for i in range(n):", "    " + y_old, "    " + u, "    c = counts[i]"]
    if L.step_c is not None:  # the sub-env's compensation, carried in CC from period to period
        per_env += [f"    cc = ({comps('CC[{j}, i]', dim)})"]
    per_env += [
        *("    " + line for line in _period_lines(L)),
        *("    " + line for line in store),
        "    hstep[i] = hi",
        "    fired[i] = f",
    ]
    if L.step_c is not None:
        per_env += [f"    CC[{j}, i] = cc[{j}]" for j in range(dim)]
    simd = [line[4:] for line in _physics_lines(dim, u)] + [
        "for i in range(n):",
        "    hstep[i] = h",
        "    fired[i] = False",
    ]
    if L.event is None and L.rhs_event is None and not L.switches and L.step_c is None:
        lines += [
            "    if uniform:",
            *("        " + line for line in simd),
            "    else:",
            *("        " + line for line in per_env),
        ]
    elif (
        L.rhs_event is not None or L.event is None
    ) and not L.switches:  # (compensated without an event too)
        lines += ["    " + line for line in _lockstep_lines(L, u)]
    else:
        lines += ["    " + line for line in per_env]
    # 3. non-finite states go back to the caller's failure path
    return lines + [
        "    bad = 0",
        "    for i in range(n):",
        "        if not (" + " and ".join(f"isfinite(Ynew[{j}, i])" for j in range(dim)) + "):",
        "            bad += 1",
        "    if bad:",
        f"        return bad{more}",
    ]

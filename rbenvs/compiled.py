"""Optional compiled batch step (numba): the package's own functions, compiled, in one call.

Why: a numpy step of a batch is one array operation per arithmetic line. At 4096 states each
costs about 1 us, almost all of it dispatch, and a free-body RK4 step alone is about 65 of
them; the reward, observation and read-outs as many again (``rbenvs bench throughput`` prints
both paths). Compiled, a vector env's whole step is one call (:func:`vector_kernel`): the
actions checked, clipped and mapped by the actuator, the guard's check where the env has
one, the period (the physics as passes over the batch, in SIMD registers: a few ns per
state), one loop per read-out stage, the episode clocks and end reasons, and the restarts of
the sub-envs whose episodes ended, drawn from their own generators. :func:`batch_kernel` is
the period and finish alone (what ``rbenvs bench throughput`` times as the kernel),
:func:`state_kernel` the same for one state (the single env's compiled step), and
:func:`run_kernel` one state's internal steps with a given count and step (``tolerance_check``'s
runs: :class:`CheckedRuns`; :func:`runs_kernel` a batch's, sub-env by sub-env), from the same lines.

Every loop is written so that LLVM keeps it in SIMD registers: no call inside (libm's
``sin``/``cos`` replaced by :func:`rbenvs.rotations.sincos`, branches that hold a call
specialised away), selections instead of branches (the compiled forms of
:mod:`rbenvs.jit`), unit-stride loads and stores (the observation goes through scratch
rows), and the same run-time alias checks LLVM needs allowed (:data:`LLVM_OPTIONS`).

The same pure parts also make the single env's read-out function
(:func:`rbenvs.core.finish.state_finish`):
plain Python, generated per layout, one call instead of a method per part.

What is compiled is not a second implementation. The pure functions the single env runs on
Python floats (a system's vector field, a task's reward and observation, a system's read-outs)
are marked :func:`jitable`; that marker leaves each of them the plain Python function it was
(no call overhead on the single-env path) and, when numba is installed, registers it so that
compiled code may call it. The integrator step is the one generated per scheme and dimension
(:mod:`rbenvs.integrators.runge_kutta`). The only new code here is the batch loop that calls
them: generated per layout (state size, observation size, number of metrics and read-outs).
numba compiles float arithmetic in source order without contraction into fused multiply-adds
(no ``fastmath``), and ``sqrt`` is correctly rounded, so a compiled sub-env follows the single
env bit for bit (tested).

numba is optional (the ``fast`` extra); without it, or with ``RBENVS_COMPILED=0`` in the
environment, the vector env runs the same functions on numpy arrays. A kernel is compiled on
first use in a process (about a second) and reused by every env of the same layout.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache
from typing import NamedTuple

from .codegen import generate
from .core.finish import info_function
from .jit import DISABLE_VARIABLE, available, jitable
from .jit import register as _register
from .jit import register_all as _register_all
from .kernel_cache import njit as _cached_njit

__all__ = [
    "jitable",
    "available",
    "Layout",
    "VectorLayout",
    "batch_kernel",
    "vector_kernel",
    "rows_kernel",
    "finish_kernel",
    "state_kernel",
    "physics_kernel",
    "run_kernel",
    "runs_kernel",
    "CheckedRuns",
    "plan_kernel",
    "plans_kernel",
    "PeriodPlan",
    "BatchStep",
    "BatchResult",
    "VectorStep",
    "VectorResult",
    "StateStep",
    "DISABLE_VARIABLE",
    "LLVM_OPTIONS",
    "Backend",
]

# How every kernel is compiled. error_model="numpy": a float division by zero gives inf/nan as
# on arrays (and needs no per-element check, which would keep the loops out of SIMD
# registers). forceinline: the kernel and, inherited, every pure function it calls are marked
# always-inline for LLVM, so a loop body is one function however large its parts: LLVM's
# inliner otherwise stops at its size threshold (a task's reward with an atan2 inside is over
# it), and a call left in a loop keeps it scalar (measured: the heavy top's read-outs 19 ns a
# state with the calls, 4 without).
KERNEL_OPTIONS = {"error_model": "numpy", "forceinline": True}

# LLVM vectorises a loop whose stores may overlap its loads only behind run-time checks that the
# arrays' ranges are disjoint, and gives up past a number of such checks (8 by default): a loop
# that reads and writes the eleven rows of the tippe top's state and of its next first stage
# needs more, and stays scalar (measured: 277 against 68 ns per sub-env and internal step with
# the limit raised); with a tolerance its compensation's eleven rows too (33 rows, 528 pairs:
# at a limit of 512 the vector step of 64 tippe tops took 3.9 times as long). The limits are
# process-wide LLVM options; raising them lets more loops be
# vectorised and changes no result (the checks fall back to the scalar loop where ranges
# overlap). Set once, before rbenvs compiles its first kernel.
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
    the ``(n, k)`` batch would not; measured: 76 against 123 us a 4096 free-body step)."""
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
        # would keep it scalar (measured: 36 us against 5 us); the first pass reads Y, the
        # rest update Ynew in place (the same steps per element, in the same order)
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


@cache
def physics_kernel(step, dim: int, n_control: int):
    """The physics loops alone, compiled: ``advance(Y, Ynew, U, h, substeps, PS)`` (the batch
    kernel's first part; ``rbenvs bench kernels`` times it)."""

    _tune_llvm()
    _register_all()
    _register(step)
    u = f"u = ({_comps('U[{j}][i]', n_control)})"
    src = "def advance(Y, Ynew, U, h, substeps, PS):\n" + "\n".join(_physics_lines(dim, u)) + "\n"
    namespace = generate(src, f"physics kernel dim={dim}", {"step": step})
    return _cached_njit(namespace["advance"], "advance", **KERNEL_OPTIONS)


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
    # (rbenvs.core.step.Engine.advance); None: the plain step
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
    from .stepsize.controller import MAX_INTERNAL_STEPS

    return _ratio_lines(L, u) + [
        "if not (x <= substeps):",
        f"    c = ceil(x) if x <= {MAX_INTERNAL_STEPS} else {MAX_INTERNAL_STEPS + 1}",
        "    need += 1",
    ]


def _locate_lines(k: int) -> list[str]:
    """Lines of :func:`rbenvs.core.hybrid.locate` for switch ``k``, inline (the same operations
    in the same order): from ``yp`` (``g >= 0``) to ``y`` (``g = fe < 0``) over ``hi``, the
    first time ``t`` and state ``ya`` where ``function_k`` turns negative."""
    from .core.hybrid import EPS, LOCATE_ITERATIONS

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
    period, :meth:`rbenvs.core.step.Engine.advance`): ``hi`` the internal step and ``f`` whether
    the terminal event ended it; past the cap the period is refused (``y`` NaN)."""
    from .stepsize.controller import MAX_INTERNAL_STEPS

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
    (:meth:`rbenvs.core.step.Engine._run_one`): the switches after each, the terminal event ending
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
    runs in SIMD registers, one fused loop would not (measured: 56 us against 15 us at 4096
    free bodies). ``fresh`` (an expression in ``i``): the states that are new starts, finished
    as after a reset instead (zero action; read-outs with no control acted and no event),
    selected per component, so that the loops keep no branch."""
    # the clip (:func:`_clip_lines`) writes the components as rows of a scratch array
    # (unit-stride stores), then one loop interleaves them into the (n, n_obs) observation
    # (measured at 4096 reorients: 14 ns a sub-env storing into obs directly, 5 + 4 this way)
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

    from .stepsize.forms import relaxation_steps, step_ratio, step_ratio_motion

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

    The period is the step core's (:meth:`rbenvs.core.step.Engine.advance`), per sub-env:
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
    registers, and a period of some 160 steps per sub-env is where the time goes). ``K`` holds
    each sub-env's next first stage (with the event), ``live`` whether it goes on. Without an
    event (a layout without switches: the free body's and the heavy top's compensated periods)
    a sub-env takes its count, as its own loop does."""
    from .stepsize.controller import MAX_INTERNAL_STEPS

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


def _products(x: str, k: int) -> str:
    """``x^k`` written out as ``x * x * ... * x``: :func:`rbenvs.rotations.power`'s products in its
    order (the same bits), which a loop over a batch keeps in SIMD registers (a power with a
    run-time exponent is a loop of its own)."""
    return "(" + " * ".join([x] * k) + ")"


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
        # (motion_rates' test power(Lambda dt, p + 1) <= substeps^p / k and motion_error_estimate's
        # C Lambda dt (Lambda h)^p, their powers as products)
        test = f"{_products('w', gate + 1)} <= PGT[1][2]"
        lines += [
            "    ng = 0",
            "    for i in range(n):",
            "        " + y_old,
            "        big = gate(PGT[0], y)",
            "        counts[i] = substeps",
            "        w = big * PGT[1][0]",
            "        z = big * h",
            f"        EST[i] = PEE[0] * big * PEE[2] * {_products('z', gate)}",
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
            "    w = big * PGT[1][0]",
            f"    if {test}:",
            "        continue",
        ]
    if estimate:
        from .stepsize.controller import MAX_INTERNAL_STEPS

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


class VectorLayout(NamedTuple):
    """What the compiled vector step (:func:`vector_kernel`) is generated for, beyond its
    :class:`Layout`: the actuator's pure ``control(PC, a) -> (u_norm, u)`` for ``n_in`` action
    entries, the model's pure ``start(PI, d) -> y`` (or ``None``: restarts run in Python) and
    the kinds of a start's draws (:mod:`rbenvs.draws`), made in order from each sub-env's own
    generator; ``estimate``: the step also writes each period's error estimate (a tolerance's,
    :meth:`rbenvs.stepsize.controller.StepRule.estimate`)."""

    batch: Layout
    control: Callable
    n_in: int
    start: Callable | None
    kinds: str
    estimate: bool = (
        False  # each period's error estimate into EST (a tolerance: StepRule.estimate's)
    )
    # with estimate, the default accuracy's gate fn(P, y) -> Lambda (StepRule.gate) where the
    # stability bound never asks for more than substeps (StepRule.stable): every sub-env tested
    # first in one loop without branches, the rates read only where the bound does not hold
    gate: Callable | None = None
    gate_order: int = (
        0  # the scheme's order p (a whole number): the gate's powers written out as products
    )


# what a sub-env's generator call is, per draw kind (rbenvs.draws: the same streams as numpy's)
_DRAW_CALLS = {"u": "g.random()", "n": "g.standard_normal()"}


def _start_lines(V: VectorLayout, dest: str) -> list[str]:
    """Sub-env ``i``'s start, drawn from its own generator ``GEN[i]`` (the draws' kinds made as
    calls, one statement each: in order) through the model's pure start, written into column
    ``i`` of ``dest``: a restart, written once for the rows kernel and the vector step."""
    draws = [f"d{k} = {_DRAW_CALLS[kind]}" for k, kind in enumerate(V.kinds)]
    return [
        "g = GEN[np.int64(i)]",
        *draws,
        f"y = start(PI, ({''.join(f'd{k}, ' for k in range(len(V.kinds)))}))",
        *(f"{dest}[{j}, i] = y[{j}]" for j in range(V.batch.dim)),
    ]


@cache
def rows_kernel(V: VectorLayout):
    """Rows of a batch started or finished outside a step: ``rows(idx, draw, Y, GEN, PI, PO, PE,
    PR, HI, h, obs, over, hstep, steps, M_1..M_k, R_1..R_m)``. For each sub-env ``i = idx[m]``:
    where ``draw[m]``, its start from its own generator ``GEN[i]`` (the draws' kinds made as
    calls, in order; the model's pure start) written into ``Y`` and its episode clock set to 0
    (the single env's reset; a layout without a pure start never draws here); then its row of
    the observation (clipped; ``over`` where outside), the metrics at zero action and the
    read-outs with no control acted and no event (the single env's rules after a reset), and
    ``hstep = h``: the restarts of a vector step (autoreset) and a reset's finish."""

    L = V.batch
    metrics = [f"M{j}" for j in range(L.n_metrics)]
    reads = [f"R{j}" for j in range(L.n_readouts)]
    args = (
        [
            "idx",
            "draw",
            "Y",
            "GEN",
            "PI",
            "PO",
            "PE",
            "PR",
            "HI",
            "h",
            "obs",
            "over",
            "hstep",
            "steps",
        ]
        + metrics
        + reads
    )
    lines = [
        f"def rows({', '.join(args)}):",
        "    for m in range(idx.shape[0]):",
        "        i = idx[m]",
    ]
    if V.start is not None:
        lines += [
            "        if draw[m]:",
            *("            " + line for line in _start_lines(V, "Y")),
            "            steps[i] = 0",
        ]
    lines += [
        f"        y = ({_comps('Y[{j}, i]', L.dim)})",
        "        o = observe(PO, y)",
        "        out = False",
    ]
    for j in range(L.n_obs):
        lines += [
            f"        v = o[{j}]",
            *("        " + line for line in _clip_lines(j, "v", f"obs[i, {j}]")),
        ]
    lines += [
        "        over[i] = out",
        f"        r = evaluate(PE, y, ({_comps('0.0', L.n_action)}))",
        *[f"        M{j}[i] = r[{j + 2}]" for j in range(L.n_metrics)],
    ]
    lines += [
        "        q = readouts(PR, y, None, False)",
        *[f"        R{j}[i] = q[{j}]" for j in range(L.n_readouts)],
        "        hstep[i] = h",
    ]
    namespace = _vector_namespace(V)
    generate("\n".join(lines), f"rows kernel dim={L.dim} n_obs={L.n_obs}", namespace)
    return _cached_njit(namespace["rows"], "rows", error_model="numpy")


@cache
def _act(control, n_in: int):
    """``act(PC, A, i) -> (un, u)``: sub-env ``i``'s action, clipped to ``[-1, 1]`` (the single
    env's rule, :func:`rbenvs.core.step.action_values`), through the actuator's pure form."""
    items = [f"a{j}" for j in range(n_in)]
    lines = ["def act(PC, A, i):", *(f"    a{j} = float(A[i, {j}])" for j in range(n_in))]
    # max/min, not a branch per entry (random actions mispredict); the same value for every
    # finite entry (the only ones that reach it)
    lines += [f"    {a} = max(-1.0, min(1.0, {a}))" for a in items]
    lines += [f"    return control(PC, ({''.join(a + ', ' for a in items)}))"]
    return jitable(generate("\n".join(lines), f"act n_in={n_in}", {"control": control})["act"])


def _vector_namespace(V: VectorLayout) -> dict:
    import numpy as np

    from .core.reasons import end_code

    namespace = _namespace(V.batch)
    act = _act(V.control, V.n_in)
    for fn in (V.control, act, V.start, end_code, V.gate):
        if fn is not None:
            _register(fn)
    namespace.update(act=act, start=V.start, end_code=end_code, np=np, gate=V.gate)
    if V.estimate:
        from .rotations import power
        from .stepsize.forms import error_estimate, motion_error_estimate, relaxation_estimate

        namespace.update(
            error_estimate=error_estimate,
            motion_error_estimate=motion_error_estimate,
            relaxation_estimate=relaxation_estimate,
            power=power,
        )
    return namespace


def _vector_args(L: Layout) -> list[str]:
    metrics = [f"M{j}" for j in range(L.n_metrics)]
    reads = [f"R{j}" for j in range(L.n_readouts)]
    return (
        [
            "i_lo",
            "i_hi",
            "phase",
            "A",
            "Y",
            "Ynew",
            "CC",
            "h",
            "dt",
            "substeps",
            "check",
            "refuse",
            "next_step",
            "max_steps",
            "FC",
            "steps",
            "done",
            "skip",
            "GEN",
            "PC",
            "PI",
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
            "PEE",
            "counts",
            "hstep",
            "fired",
            "obs",
            "over",
            "reward",
            "terminated",
            "truncated",
            "RZ",
            "RN",
            "clear",
            "ends",
            "codes",
            "EST",
            "PGT",
        ]
        + metrics
        + reads
    )


@cache
def vector_kernel(V: VectorLayout, chunked: bool = False):
    """A vector env's whole step, compiled: one call per step with no Python per sub-env.
    Signature (arrays ``(n,)`` unless said; see :func:`batch_kernel` for the period's)::

        vstep(i_lo, i_hi, phase, A, Y, Ynew, CC, h, dt, substeps, check, refuse, next_step,
        max_steps,
              FC, steps, done, skip, GEN, PC, PI, PS, PO, PE, PR, PG, PA, PD, CD, PV, PW, HI, PEE,
              counts, hstep, fired, obs, over, reward, terminated, truncated, RZ, RN, clear, ends,
              codes, EST, PGT, M_1..M_k, R_1..R_m) -> (status, k, m, r)

    on the sub-envs ``i_lo <= i < i_hi`` with ``chunked`` (every array is the whole batch's; without
    it, on every sub-env, the bounds unread); ``phase`` 0 runs the
    whole step below; a step split over threads (:class:`VectorStep`) runs phase 1 (1 and 2
    below: the actions' check, the guard's counts, the period and its non-finite check) on
    every chunk, then, when every chunk returned 0, phase 2 (the rest; the caller zeroes the
    rows ``clear`` in between, and the compacted ``ends`` of a chunk start at ``i_lo``): each
    sub-env's arithmetic is the same whichever its chunk, so any split gives the same bits.

    1. the actions ``A`` ``(n, n_in)`` (float32 or float64): every entry finite (else ``(-2,
       i, 0, 0)`` for the first bad sub-env ``i``, nothing else written), clipped to ``[-1, 1]``
       (the single env's rule), mapped by the actuator's pure form into the rows of ``UN`` and
       ``U``;
    2. the period and finish of :func:`batch_kernel` (``(-1, 0, 0, 0)``: refused; ``(bad, 0,
       0, 0)``: ``bad`` new states non-finite, the caller's failure path takes over, nothing
       drawn; sub-envs in ``skip`` take ``substeps``); with ``next_step`` and a pure start, the
       sub-envs in ``skip`` (those whose previous step ended) restart between the period and
       the finish: their starts drawn from their own generators ``GEN[i]`` into ``Ynew``, their
       rows finished as after a reset (zero action, no control acted, no event, ``hstep = h``);
    3. the episode's bookkeeping per sub-env: ``steps += 1``; ``terminated`` where the task,
       the observation bounds or the event ended it, ``truncated`` where ``steps >= max_steps``
       (``max_steps < 0``: no limit); ``done`` their union (the ``_terminal_reason`` mask, and
       the next step's restarts); the reason's name (:func:`rbenvs.core.reasons.end_code`, row
       ``RN[code]`` of code points) written into the row of ``RZ``, a zero-filled reason
       array's ``(n, width)`` uint32 view whose rows ``clear`` are zeroed first
       (:class:`rbenvs.core.reasons.ReasonPool`); the failure charge ``FC`` added to the reward of
       every end without success (the last metric, ``is_success``; the single env's rule,
       :class:`rbenvs.core.model.Model`);
    4. with ``next_step`` (autoreset NEXT_STEP), the restarting sub-envs' step: reward 0, not
       terminated or truncated, their episode clock 0 (a layout without a pure start leaves
       their states and rows to the caller);
    5. with ``V.estimate`` (a tolerance), each period's error estimate into ``EST`` (0 for a
       restarting sub-env: no period ran), written in 2's count loop from the rates it counts
       with (:func:`_checked_period`) and the step the count gives, through the functions
       :meth:`rbenvs.stepsize.controller.StepRule.estimate` calls, ``PEE`` its ``(C, p, dt)``
       (unread otherwise): every sub-env's rates, counted or not.

    ``k``: the number of sub-envs whose step had an end or a truncation (restarting ones never:
    their period is discarded); ``ends[:m]`` the sub-envs whose row of ``RZ`` may have been
    written (``codes[:m]`` their codes); ``r`` the number of restarting sub-envs.
    """

    L = V.batch
    args = _vector_args(L)
    a_items = [f"a{j}" for j in range(V.n_in)]
    lines = [f"def vstep({', '.join(args)}):", "    n = Y.shape[1]"]
    # 1. the actions: every entry finite (counted: a loop without an exit stays in SIMD
    # registers), then clipped and mapped once into the rows of U and UN (scratch)
    read = [f"a{j} = A[i, {j}]" for j in range(V.n_in)]
    finite = "        if not (" + " & ".join(f"isfinite({a})" for a in a_items) + "):"
    check_actions = [
        "    bad = 0",
        "    for i in range(n):",
        *("        " + line for line in read),
        finite,
        "            bad += 1",
    ]
    check_actions += [
        "    if bad:",
        "        for i in range(n):",
        *("            " + line for line in read),
        "    " + finite,
        "                return -2, np.int64(i), 0, 0",
    ]
    lines += ["    if phase != 2:", *("    " + line for line in check_actions)]
    lines += [
        f"    U = np.empty(({L.n_control}, n))",
        f"    UN = np.empty(({L.n_action}, n))",
        "    for i in range(n):",
        "        un, u = act(PC, A, i)",
    ]
    lines += [f"        UN[{j}, i] = un[{j}]" for j in range(L.n_action)] + [
        f"        U[{j}, i] = u[{j}]" for j in range(L.n_control)
    ]
    # 2. the period, then (NEXT_STEP) the restarting sub-envs' starts drawn into their columns
    # of Ynew, so that the finish loops fill their rows as after a reset (per-row selections:
    # no second pass, no scattered writes into the step's arrays); a layout without a pure start
    # restarts in the caller
    starts, fresh = [], None
    if V.start is not None:
        starts = [
            "    if next_step:",
            "        for i in range(n):",
            "            if skip[i]:",
            *("                " + line for line in _start_lines(V, "Ynew")),
        ]
        starts += [
            "                hstep[i] = h"
        ]  # (their event flag is cleared with their step, below)
        if L.step_c is not None:  # (a new run: its compensation at zero)
            starts += [f"                CC[{j}, i] = 0.0" for j in range(L.dim)]
        fresh = "next_step & skip[i]"
    u_line, un_line = _controls(L, rows=True)
    lines += [
        "    if phase != 2:",
        *(
            "    " + line
            for line in _checked_period(
                L, u_line, ", 0, 0, 0", V.estimate, V.gate_order if V.gate is not None else 0
            )
        ),
        "    if phase == 1:",
        "        return 0, 0, 0, 0",
    ]
    lines += starts + _finish_lines(
        L, f"y = ({_comps('Ynew[{j}, i]', L.dim)})", un_line, u_line, "fired[i]", fresh
    )
    # 3. the episode's bookkeeping, then 4. the restarts' step (skip: the sub-envs that restart,
    # read-only here; with next_step they are those whose previous step ended)
    lines += [
        "    k = 0",
        "    m = 0",
        # the pooled reason array's last rows (a split step: the caller's, between the phases)
        "    if phase == 0:",
        "        for j in range(clear.shape[0]):",
        "            for w in range(RZ.shape[1]):",
        "                RZ[clear[j], w] = 0",
        # a loop of selections and unit-stride stores (SIMD), then the ends compacted in a
        # second loop whose branch is rarely taken (an end): one loop that compacted as it went
        # carried m from sub-env to sub-env and stayed scalar (measured at 4096 reorients: 4.2
        # against 2.3 ns a sub-env for both loops)
        "    for i in range(n):",
        "        s = steps[i] + 1",
        "        e = terminated[i] | over[i] | fired[i]",
        "        t = (max_steps >= 0) & (s >= max_steps)",
        # (a restart's discarded period ends nothing)
        "        k += (e | t) & (not (next_step & skip[i]))",
        "        steps[i] = s",
        "        codes[i] = end_code(False, fired[i], over[i], terminated[i])",
        "        terminated[i] = e",
        "        truncated[i] = t",
        "        done[i] = e | t",
        "    for i in range(n):",
        "        c = codes[i]",
        # (i_lo + m <= i: the compaction overwrites only rows it has read, in its own range)
        "        if c != 0:",
        # (i unsigned in the chunked form: cast, not converted silently)
        "            ends[i_lo + m] = np.int64(i)",
        "            codes[i_lo + m] = c",
        "            m += 1",
        # the reasons' names, UCS-4 code points into the rows of the (zero-filled) array
        "    for j in range(i_lo, i_lo + m):",
        "        i = ends[j]",
        "        if not (next_step and skip[i]):",
        "            for w in range(RZ.shape[1]):",
        "                RZ[i, w] = RN[codes[j], w]",
        f"            if not M{L.n_metrics - 1}[i]:",  # an end without success: the failure charge
        "                reward[i] += FC",
        "    r = 0",
        "    if next_step:",
        "        for i in range(n):",
        "            if skip[i]:",
    ]
    lines += [
        "                steps[i] = 0",
        "                reward[i] = 0.0",
        "                terminated[i] = False",
        "                truncated[i] = False",
        "                fired[i] = False",
        "                done[i] = False",
        "                r += 1",
    ]
    lines += ["    return 0, k, m, r"]
    namespace = _vector_namespace(V)
    source = "\n".join(lines)
    if (
        chunked
    ):  # every loop over the sub-envs over the call's range [i_lo, i_hi): the threads' chunks
        # (its own kernel: loops from a run-time start stay out of SIMD registers, so the
        # one-call step keeps range(n) and ignores i_lo, i_hi)
        # (unsigned bounds: an index numba cannot prove non-negative gets a wraparound select on
        # every access, which keeps the loop out of SIMD registers)
        source = source.replace(
            "    n = Y.shape[1]\n",
            "    n = Y.shape[1]\n    u_lo, u_hi = np.uint64(i_lo), np.uint64(i_hi)\n",
            1,
        )
        source = source.replace(" in range(n):", " in range(u_lo, u_hi):")
    generate(
        source, f"vector step dim={L.dim} n_obs={L.n_obs}{' chunked' if chunked else ''}", namespace
    )
    # (nogil: envs stepped from several Python threads run at once)
    return _cached_njit(namespace["vstep"], "vstep", **KERNEL_OPTIONS, nogil=True)


def _rebuild(shape, names: list[str]) -> str:
    """The expression that rebuilds a value of nested-tuple ``shape`` (``None``: a leaf) from
    flat leaf names, appending those to ``names``."""
    if shape is None:
        names.append(f"x{len(names)}")
        return names[-1]
    return "(" + "".join(_rebuild(part, names) + ", " for part in shape) + ")"


def tuple_shape(value):
    """``value``'s nesting of tuples, leaves as ``None`` (the key of :func:`split_kernel`)."""
    return tuple(tuple_shape(v) for v in value) if isinstance(value, tuple) else None


def flat_leaves(value) -> tuple:
    """``value``'s leaves in order, its tuples flattened."""
    if not isinstance(value, tuple):
        return (value,)
    return tuple(leaf for v in value for leaf in flat_leaves(v))


@cache
def split_kernel(V: VectorLayout, shape: tuple):
    """A vector step split over threads, in one call: ``vsplit(cuts, S, width, *leaves)`` runs
    the chunked :func:`vector_kernel`'s phase 1 on every chunk ``[cuts[c], cuts[c + 1])`` at once
    (``prange`` on ``width`` of numba's threads), then, when every chunk returned 0, zeroes the
    reason pool's rows ``clear`` and runs phase 2 the same way; ``S[c]`` is chunk ``c``'s
    ``(status, k, m, r)``. Returns -1 if a chunk refused, else the sum of the phase-1 statuses
    (0: phase 2 ran). ``leaves``: the chunked kernel's arguments after ``phase``, their tuples
    flattened (``shape``: :func:`tuple_shape` of them), since a parallel loop's body takes no
    nested tuple from outside; the body rebuilds them. The calling thread's thread count is
    put back before it returns."""
    import numba
    import numpy as np

    names: list[str] = []
    exprs = [_rebuild(part, names) for part in shape]
    at = dict(zip(_vector_args(V.batch)[3:], exprs))
    lines = [
        f"def vsplit(cuts, S, width, {', '.join(names)}):",
        "    nc = cuts.shape[0] - 1",
        "    before = get_num_threads()",
        "    set_num_threads(width)",
        "    status = 0",
        "    phase = 1",
        "    while phase != 0:",
        "        for c in prange(nc):",
        f"            r = vstep(cuts[c], cuts[c + 1], phase, {', '.join(exprs)})",
        *(f"            S[c, {j}] = r[{j}]" for j in range(4)),
        "        if phase == 2:",
        "            phase = 0",
        "            continue",
        "        refused = False",
        "        for c in range(nc):",
        "            refused |= S[c, 0] == -1",
        "            status += S[c, 0]",
        "        if refused:",
        "            status = -1",
        "        if status != 0:",
        "            phase = 0",
        "            continue",
        f"        for j in range({at['clear']}.shape[0]):",
        f"            for w in range({at['RZ']}.shape[1]):",
        f"                {at['RZ']}[{at['clear']}[j], w] = 0",
        "        phase = 2",
        "    set_num_threads(before)",
        "    return status",
    ]
    namespace = {
        "vstep": vector_kernel(V, chunked=True),
        "prange": numba.prange,
        "get_num_threads": numba.get_num_threads,
        "set_num_threads": numba.set_num_threads,
        "np": np,
    }
    generate(
        "\n".join(lines), f"vector step split dim={V.batch.dim} n_obs={V.batch.n_obs}", namespace
    )
    return _cached_njit(namespace["vsplit"], "vsplit", error_model="numpy", parallel=True)


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
    from .stepsize.controller import MAX_INTERNAL_STEPS

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
        from .stepsize.forms import error_estimate, motion_error_estimate, relaxation_estimate

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
    of twice the size; :meth:`rbenvs.core.step.Engine._run_one`), on
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


class PeriodPlan:
    """One env's compiled :func:`plan_kernel` and :func:`plans_kernel` with their parameters:
    calling it with one state ``y`` and its control ``u`` (tuples of floats) returns ``(x, r,
    rate, a)``, the bits of :meth:`rbenvs.stepsize.controller.StepRule.plan`; :meth:`batch` gives a
    batch's rates and :meth:`ratios` its ratios (the vector env's estimate and checked count).
    The first call compiles (about a second per layout and process) and then takes its
    overload's entry point."""

    def __init__(self, parts, dim: int, n_obs: int, n_control: int, n_action: int, sample):
        layout, params, _, _ = _layout(parts, dim, n_obs, n_control, n_action, sample)
        if layout.rotation is None:
            raise ValueError("the plan needs the guard's rate (a step rule that can ask for steps)")
        self.layout = layout
        self.kernel = plan_kernel(layout)
        self.params = params[4:8]  # PG, PA, PD, CD
        self._call = self._batch = self._ratios = None

    def __call__(self, y, u):
        call = self._call
        if call is not None:
            return call(y, u, self.params)
        out = self.kernel(y, u, self.params)  # compiles
        self._call = _entry_point(self.kernel, (y, u, self.params))
        return out

    def batch(self, Y, U):
        """``(R, RATE, A)`` of the ``(dim, n)`` states ``Y`` under the ``(n_control, n)``
        controls ``U`` (float64, C-contiguous): arrays, ``R`` ``(3, n)`` or ``(1, n)`` (the
        ratio is not evaluated)."""
        import numpy as np

        if self._batch is None:
            self._batch = plans_kernel(self.layout)
        n = Y.shape[1]
        RATE, A = np.empty(n), np.empty(n)
        R = np.empty((3 if self.layout.motion else 1, n))
        self._batch(Y, U, self.params, R, RATE, A)
        return R, RATE, A

    def ratios(self, Y, U):
        """The guard's ratios ``X`` ``(n,)`` of a batch (as :meth:`batch`'s arguments)."""
        import numpy as np

        if self._ratios is None:
            self._ratios = plans_kernel(self.layout, True)
        X = np.empty(Y.shape[1])
        self._ratios(Y, U, self.params, X)
        return X


class CheckedRuns:
    """One env's compiled runs for ``tolerance_check`` (:func:`run_kernel`, the main run's and
    the companion's): calling it runs ``c`` steps of ``hi`` from ``y`` with the compensation
    ``cc`` and returns ``(y, fired, cc)``, the bits of the float path's
    :meth:`rbenvs.core.step.Engine._run_one`. Each kernel's first call compiles it (about a
    second per layout and process) and then takes its overload's entry point."""

    def __init__(self, parts, dim: int, n_obs: int, n_control: int, n_action: int, sample):
        layout, params, _, _ = _layout(parts, dim, n_obs, n_control, n_action, sample)
        if layout.step_c is None:
            raise ValueError("the checked runs need a compensated step (a tolerance)")
        self.kernel = run_kernel(layout)
        self.batch_kernel = runs_kernel(layout)
        self.params = (params[0], params[8], params[9])  # PS, PV, PW
        self._call = None

    def batch(self, Y, CC, U, counts, H, fired) -> None:
        """A batch's runs in place (:func:`runs_kernel`): ``Y``, ``CC`` ``(dim, n)``, ``U``
        ``(n_control, n)``, ``counts``, ``H`` ``(n,)``, ``fired`` written."""
        self.batch_kernel(Y, CC, U, counts, H, fired, self.params)

    def __call__(self, y, cc, u, c: int, hi: float):
        if self._call is not None:
            return self._call(y, cc, u, c, hi, self.params)
        import numba

        args = (y, cc, u, c, hi, self.params)
        out = self.kernel(*args)  # compiles
        overload = self.kernel.overloads.get(tuple(numba.typeof(a) for a in args))
        self._call = overload.entry_point if overload is not None else self.kernel
        return out


def _switch_parts(parts) -> tuple:
    """``(layout triples, PW)`` from :attr:`KernelParts.switches` (``((applies, P), (function, P),
    tolerance, (switch, P))`` each)."""
    triples = tuple(
        (applies[0], function[0], switch[0])
        for applies, function, tolerance, switch in parts.switches
    )
    pw = tuple(
        (function[1], float(tolerance), switch[1], applies[1])
        for applies, function, tolerance, switch in parts.switches
    )
    return triples, pw


def _layout(parts, dim: int, n_obs: int, n_control: int, n_action: int, sample) -> tuple:
    """``(layout, kernel parameters, sample evaluation, sample read-outs)`` of
    :class:`rbenvs.core.step.KernelParts`: the functions for :class:`Layout`, their parameters
    ``(PS, PO, PE, PR, PG, PA, PD, CD, PV, PW)`` in the kernels' order, and the task's evaluation
    and the system's read-outs of the float state ``sample`` (their sizes and types)."""
    (step, ps), (observe, po), (evaluate, pe), (readouts, pr) = (
        parts.step,
        parts.observe,
        parts.evaluate,
        parts.readouts,
    )
    (rotation, pa) = parts.rotation if parts.rotation is not None else (None, ())
    (dissipation, pd) = parts.dissipation if parts.dissipation is not None else (None, ())
    share = None
    if dissipation is not None and parts.share is not None:
        share, pa_d = parts.share
        pd = (pd, pa_d)
    (event, pv) = parts.event if parts.event is not None else (None, ())
    rhs_event = None
    if parts.rhs_event is not None:  # (its parameters take the event's place)
        rhs_event, pv = parts.rhs_event
    switches, pw = _switch_parts(parts)
    values = evaluate(pe, tuple(sample), (0.0,) * n_action)
    physical = readouts(pr, tuple(sample), (0.0,) * n_control, False)
    layout = Layout(
        step,
        dim,
        n_control,
        n_action,
        observe,
        n_obs,
        evaluate,
        len(values) - 2,
        readouts,
        len(physical),
        rotation,
        dissipation,
        event,
        rhs_event,
        switches,
        parts.motion,
        share,
        None if parts.step_c is None else parts.step_c[0],
    )
    params = (ps, po, pe, pr, parts.guard_params, pa, pd, float(parts.dissipation_step), pv, pw)
    return layout, params, values, physical


class StateStep:
    """One env's compiled single-state step: :func:`state_kernel` of its layout, its
    parameters, and a ``(readouts, metrics, h) -> info`` function. Calling it returns the
    kernel's tuple. The first call compiles (once per layout and process) and then takes the
    compiled overload's entry point for these argument types, which skips numba's per-call
    type dispatch (about 0.9 us of a call's 1.7 with the parameter tuples)."""

    def __init__(
        self,
        parts,
        dim: int,
        n_obs: int,
        n_control: int,
        n_action: int,
        sample,
        obs_high,
        h: float,
        dt: float,
        substeps: int,
        metric_names,
        readout_names,
        error=None,
    ):
        layout, params, _, _ = _layout(parts, dim, n_obs, n_control, n_action, sample)
        # error: a tolerance's (C, p, dt): the kernel returns each period's estimate last
        self.estimated = error is not None and layout.rotation is not None
        self.kernel = state_kernel(layout, self.estimated)
        high = tuple(float(v) for v in obs_high)
        self.params = (
            (float(h), float(dt), int(substeps))
            + params
            + (high,)
            + ((tuple(float(v) for v in error),) if self.estimated else ())
        )
        self.info = info_function(tuple(readout_names), tuple(metric_names))
        self._call = None

    def __call__(self, y, u, un, check: bool, refuse: bool):
        call = self._call
        if call is None:
            return self._first(y, u, un, check, refuse, self.params)
        return call(y, u, un, check, refuse, self.params)

    def compensated(self, y, cc, u, un, check: bool, refuse: bool):
        """The call of a layout with ``step_c``: the run's compensation ``cc`` in, and out last."""
        call = self._call
        if call is None:
            return self._first(y, cc, u, un, check, refuse, self.params)
        return call(y, cc, u, un, check, refuse, self.params)

    def _first(self, *args):
        import numba

        out = self.kernel(*args)  # compiles
        overload = self.kernel.overloads.get(tuple(numba.typeof(a) for a in args))
        self._call = overload.entry_point if overload is not None else self.kernel
        return out


class BatchResult(NamedTuple):
    """What :class:`BatchStep` returns. ``status``: 0, the number of non-finite new states (the
    task outputs are then unset), or -1 when ``refuse`` was set and a sub-env needs more than
    ``substeps`` steps (nothing was run; ``counts`` holds the counts). ``fired``: the terminal
    event ended the sub-env's period; ``h``: its internal step; ``counts``: its step count."""

    Y: object
    status: int
    obs: object
    over: object
    reward: object
    terminated: object
    metrics: tuple
    readouts: tuple
    fired: object
    h: object
    counts: object


class BatchStep:
    """One env's compiled batch step: the kernel of its layout plus its parameters.

    ``parts`` is :meth:`rbenvs.core.step.Engine.kernel_parts` (a
    :class:`rbenvs.core.step.KernelParts`); ``dim`` the state size, ``n_obs`` the observation
    size, ``n_control`` the control size, ``n_action`` the normalised action's, ``sample`` any
    state (as floats) used once to learn the metrics' types, ``dt`` the control period.
    """

    def __init__(
        self,
        parts,
        dim: int,
        n_obs: int,
        n_control: int,
        sample,
        obs_high,
        n_action: int | None = None,
        dt: float | None = None,
    ):
        import numpy as np

        n_action = n_control if n_action is None else n_action
        layout, self.params, values, physical = _layout(
            parts, dim, n_obs, n_control, n_action, sample
        )
        self.n_metrics, self.n_readouts = layout.n_metrics, layout.n_readouts
        # each metric's and read-out's array type from its value on a float state (a bool stays a
        # bool, a count an int)
        # (dtype objects, not scalar types: np.empty converts a type on every call, ~0.3 us each)
        self.metric_dtypes = tuple(
            np.dtype(np.bool_ if isinstance(v, (bool, np.bool_)) else np.float64)
            for v in values[2:]
        )
        self.readout_dtypes = tuple(
            np.dtype(
                np.bool_
                if isinstance(v, (bool, np.bool_))
                else (np.int64 if isinstance(v, (int, np.integer)) else np.float64)
            )
            for v in physical
        )
        self._bool, self._f32 = np.dtype(np.bool_), np.dtype(np.float32)
        self.layout = layout
        self.kernel = batch_kernel(layout)
        self.high = np.asarray(obs_high, dtype=np.float64)
        self.n_obs = n_obs
        self.dt = float(dt) if dt is not None else None

    def __call__(
        self,
        Y,
        u,
        u_norm,
        h: float,
        substeps: int,
        check: bool = False,
        skip=None,
        refuse: bool = False,
        CC=None,
    ) -> BatchResult:
        """One control period of the states ``Y`` ``(dim, n)`` under controls ``u`` and normalised
        actions ``u_norm`` (tuples of ``(n,)`` float64 arrays): a :class:`BatchResult`.
        ``check``: run the guard (else ``substeps`` steps each); ``skip`` (bool ``(n,)``):
        sub-envs about to restart; ``refuse``: ``guard="refuse"``; ``CC`` ``(dim, n)``: the
        runs' compensations, carried on in place (a compensated layout: a tolerance)."""
        import numpy as np

        n = Y.shape[1]
        Ynew = np.empty_like(Y)
        obs = np.empty((n, self.n_obs), self._f32)
        over = np.empty(n, self._bool)
        reward = np.empty(n)
        terminated = np.empty(n, self._bool)
        fired = np.empty(n, self._bool)
        hstep = np.empty(n)
        counts = np.empty(n, dtype=np.int64)
        metrics = tuple(np.empty(n, t) for t in self.metric_dtypes)
        readouts = tuple(np.empty(n, t) for t in self.readout_dtypes)
        ps, po, pe, pr, pg, pa, pd, cd, pv, pw = self.params
        if skip is None:
            skip = np.zeros(n, dtype=bool)
        dt = self.dt if self.dt is not None else h * substeps
        status = self.kernel(
            Y,
            Ynew,
            NO_COMPENSATION if CC is None else CC,
            u,
            u_norm,
            h,
            dt,
            substeps,
            check,
            refuse,
            skip,
            ps,
            po,
            pe,
            pr,
            pg,
            pa,
            pd,
            cd,
            pv,
            pw,
            self.high,
            counts,
            hstep,
            fired,
            obs,
            over,
            reward,
            terminated,
            *metrics,
            *readouts,
        )
        return BatchResult(
            Ynew, status, obs, over, reward, terminated, metrics, readouts, fired, hstep, counts
        )

    def finish(self, Y):
        """``(obs, over, reward, terminated, metrics, readouts)`` of states ``Y`` ``(dim, k)`` that
        have just been reset (:func:`finish_kernel`: no control acted yet, zero action)."""
        import numpy as np

        k = Y.shape[1]
        obs = np.empty((k, self.n_obs), dtype=np.float32)
        over = np.empty(k, dtype=bool)
        reward = np.empty(k)
        terminated = np.empty(k, dtype=bool)
        metrics = tuple(np.empty(k, dtype=t) for t in self.metric_dtypes)
        readouts = tuple(np.empty(k, dtype=t) for t in self.readout_dtypes)
        ps, po, pe, pr, pg, pa, pd, cd, pv, pw = self.params
        finish_kernel(self.layout)(
            Y, po, pe, pr, self.high, obs, over, reward, terminated, *metrics, *readouts
        )
        return obs, over, reward, terminated, metrics, readouts


class VectorResult(NamedTuple):
    """What :class:`VectorStep` returns: ``status`` (0; ``-2``: a non-finite action; ``-1``:
    refused, ``counts`` holds the counts; or the number of non-finite new states: the task
    outputs are unset), ``n_ended`` (the sub-envs whose step had an end or a truncation), the
    step's arrays (see :func:`vector_kernel`), ``written``, the sub-envs whose row of the
    reason array may have been written, and ``n_restarted``, the number of sub-envs that
    restarted (NEXT_STEP; drawn inside the step where the model has a pure start). ``over``,
    ``fired``, ``counts`` and ``written`` are scratch, valid until the next step."""

    status: int
    n_ended: int
    Y: object
    obs: object
    over: object
    reward: object
    terminated: object
    truncated: object
    written: object
    metrics: tuple
    readouts: tuple
    fired: object
    h: object
    counts: object
    n_restarted: int
    # each period's error estimate (a layout with VectorLayout.estimate), 0 where no period ran
    estimate: object = None


# a split step's chunks start at multiples of this many sub-envs (no cache line of a bool
# array shared between threads; whole SIMD blocks)
_CHUNK_ALIGN = 64


def _entry_point(dispatcher, args):
    """The compiled overload of ``dispatcher`` for ``args``' types, called without numba's
    per-call typing (which costs several microseconds for forty arguments); the caller then
    passes arguments of those types only. The dispatcher itself where none is found."""
    import numba

    overload = dispatcher.overloads.get(tuple(numba.typeof(a) for a in args))
    return overload.entry_point if overload is not None else dispatcher


class VectorStep:
    """One vector env's compiled step (:func:`vector_kernel`) with its parameters, and its
    rows outside a step (:func:`rows_kernel`: a reset's finish, SAME_STEP restarts).

    ``parts``: :meth:`rbenvs.core.step.Engine.kernel_parts`; ``model``: the env's
    :class:`rbenvs.core.model.Model` (its actuator's and start's pure forms, its draw kinds);
    ``n_obs``: the observation size, ``obs_high`` its bounds; ``max_steps``: the time limit
    (``None``: none); ``error``: a tolerance's ``(C, p, dt)``
    (:attr:`rbenvs.stepsize.controller.StepRule.error`), with which the step also returns each
    period's error estimate (``None``: none). The call goes through the compiled overload's entry
    point after the first (numba's per-call typing of forty arguments costs more than a small
    batch's step); the actions must then be C-contiguous float32 or float64 (the caller converts).
    ``threads`` > 1: each step's sub-envs split into that many chunks, run at once
    (:class:`rbenvs.vector.threads.ThreadTeam`), with the same bits as one call."""

    def __init__(
        self,
        parts,
        model,
        n_obs: int,
        obs_high,
        max_steps: int | None,
        error=None,
        threads: int = 1,
    ):
        import numpy as np

        control, pc = model.kernel_control
        u_norm, u = control(pc, (0.0,) * model.actuator.size)
        sample = tuple(float(c) for c in model.initial_state(np.random.default_rng(0)))
        dim = model.system.dim
        layout, params, values, physical = _layout(parts, dim, n_obs, len(u), len(u_norm), sample)
        start = model.kernel_start()
        self.restarts = start is not None  # restarts inside the kernel (else the caller's)
        estimate = error is not None and layout.rotation is not None
        # the default accuracy's gate where the stability bound alone never asks for more steps
        # (an order that is a whole number: the gate's powers are written out)
        gate = (
            parts.gate
            if estimate
            and parts.gate is not None
            and model.step_rule.stable(int(model.substeps))
            and float(error[1]).is_integer()
            else None
        )
        self.layout = VectorLayout(
            layout,
            control,
            model.actuator.size,
            start[0] if start else None,
            model.draw_kinds,
            estimate,
            gate[0] if gate else None,
            int(error[1]) if gate else 0,
        )
        self.kernel = vector_kernel(self.layout)
        self._rows = rows_kernel(
            self.layout._replace(estimate=False, gate=None, gate_order=0)
        )  # (the rows write no estimate: one kernel for both)
        # (dtype objects, not scalar types: np.empty converts a type on every call, ~0.3 us each)
        self.metric_dtypes = tuple(
            np.dtype(np.bool_ if isinstance(v, (bool, np.bool_)) else np.float64)
            for v in values[2:]
        )
        self.readout_dtypes = tuple(
            np.dtype(
                np.bool_
                if isinstance(v, (bool, np.bool_))
                else (np.int64 if isinstance(v, (int, np.integer)) else np.float64)
            )
            for v in physical
        )
        self._bool, self._f32 = np.dtype(np.bool_), np.dtype(np.float32)
        self.high = np.asarray(obs_high, dtype=np.float64)
        self.h, self.dt, self.substeps = float(model.h), float(model.dt), int(model.substeps)
        self.max_steps = -1 if max_steps is None else int(max_steps)
        self.charge = float(model.failure_charge)
        self.n_obs, self.dim = n_obs, dim
        ps, po, pe, pr, pg, pa, pd, cd, pv, pw = params
        self.params = (
            pc,
            start[1] if start else (),
            ps,
            po,
            pe,
            pr,
            pg,
            pa,
            pd,
            cd,
            pv,
            pw,
            self.high,
            tuple(float(v) for v in error) if estimate else (0.0, 1.0, 0.0),
        )
        self.gate_params = (
            (gate[1], gate[2]) if gate else ((), (0.0, 1.0, 0.0))
        )  # (PGT: the gate's P and its test)
        self._calls = {}
        self._scratch = None
        self.threads = threads
        self._cuts = None
        self._split_calls = {}
        from .vector.threads import splits

        self._splits = splits  # (False in a forked child that cannot run numba's threads: one call)
        # (a parallel loop's body takes no nested tuple from outside: the split kernel's
        # parameters go in flattened, once)
        self._flat_params, self._flat_gate = flat_leaves(self.params), flat_leaves(self.gate_params)

    def __call__(
        self,
        A,
        Y,
        steps,
        done,
        skip,
        GEN,
        check: bool,
        refuse: bool,
        next_step: bool,
        reasons,
        CC=None,
    ) -> VectorResult:
        """One step of the states ``Y`` ``(dim, n)`` under the actions ``A`` ``(n, n_in)``
        (float32 or float64, C-contiguous); ``steps`` and ``done`` (the episode clocks and the
        sub-envs whose episode ended) are updated in place; ``skip``: the sub-envs to restart
        (with ``next_step``); ``GEN`` the sub-envs' generators (a numba typed list,
        :class:`rbenvs.draws.GeneratorTable`); ``reasons``: ``(RZ, RN, clear)`` of a
        :class:`rbenvs.core.reasons.ReasonPool` array; ``CC`` ``(dim, n)``: the runs'
        compensations, carried on in place (a compensated layout: a tolerance), a restarting
        sub-env's set to zero."""
        import numpy as np

        n = Y.shape[1]
        scratch = self._scratch  # (the arrays no caller keeps past the step: reused)
        if scratch is None or scratch[0].shape[0] != n:
            scratch = self._scratch = (
                np.empty(n, dtype=np.int64),
                np.empty(n, dtype=bool),
                np.empty(n, dtype=bool),
                np.empty(n, dtype=np.int64),
                np.empty(n, dtype=np.int64),
            )
        counts, fired, over, ends, codes = scratch
        estimate = np.empty(n if self.layout.estimate else 0)
        Ynew = np.empty_like(Y)
        hstep = np.empty(n)
        obs = np.empty((n, self.n_obs), self._f32)
        reward = np.empty(n)
        terminated = np.empty(n, self._bool)
        truncated = np.empty(n, self._bool)
        metrics = [np.empty(n, t) for t in self.metric_dtypes]
        readouts = [np.empty(n, t) for t in self.readout_dtypes]
        head = (
            A,
            Y,
            Ynew,
            NO_COMPENSATION if CC is None else CC,
            self.h,
            self.dt,
            self.substeps,
            check,
            refuse,
            next_step,
            self.max_steps,
            self.charge,
            steps,
            done,
            skip,
            GEN,
        )
        tail = (
            counts,
            hstep,
            fired,
            obs,
            over,
            reward,
            terminated,
            truncated,
            *reasons,
            ends,
            codes,
            estimate,
        )
        if (
            self.threads > 1 and n >= 2 * _CHUNK_ALIGN and np.isfinite(A).all() and self._splits()
        ):  # (a bad action: refused by the whole step, nothing written)
            leaves = (*head, *self._flat_params, *tail, *self._flat_gate, *metrics, *readouts)
            status, k, written, r = self._split(
                A.dtype,
                (*head, *self.params, *tail, self.gate_params, *metrics, *readouts),
                leaves,
                n,
                refuse and CC is not None,
                ends,
            )
        else:
            args = (*head, *self.params, *tail, self.gate_params, *metrics, *readouts)
            call = self._calls.get(A.dtype)
            if call is None:
                status, k, m, r = self.kernel(0, n, 0, *args)  # compiles
                self._calls[A.dtype] = _entry_point(self.kernel, (0, n, 0, *args))
            else:
                status, k, m, r = call(0, n, 0, *args)
            written = ends[:m]
        return VectorResult(
            status,
            k,
            Ynew,
            obs,
            over,
            reward,
            terminated,
            truncated,
            written,
            metrics,
            readouts,
            fired,
            hstep,
            counts,
            r,
            estimate if self.layout.estimate else None,
        )

    def _split(self, dtype, args, leaves, n: int, keep_cc: bool, ends) -> tuple:
        """The step as chunks of sub-envs, one per thread, in one call (:func:`split_kernel`):
        every chunk's phase 1 (the guard's counts, the period, its non-finite check) at once, then,
        where no chunk refused and every new state is finite, every chunk's phase 2.
        ``(status, k, ends, r)`` as one call's: a refusal (-1) before a non-finite count;
        ``keep_cc``: the compensations, carried in place, put back on a refusal (one call writes
        none)."""
        import numpy as np

        from .vector.threads import pool_size

        if self._cuts is None or self._cuts[-1] != n:  # (chunks of whole SIMD blocks)
            cuts = [
                min(n, round(n * c / self.threads / _CHUNK_ALIGN) * _CHUNK_ALIGN)
                for c in range(self.threads + 1)
            ]
            cuts[-1] = n
            self._cuts = np.unique(np.asarray(cuts, dtype=np.int64))
            self._S = np.zeros((len(self._cuts) - 1, 4), dtype=np.int64)
            self._width = min(
                len(self._cuts) - 1, pool_size()
            )  # (numba's threads: at most its pool)
            self._lows = self._cuts[:-1].tolist()
        cuts, S = self._cuts, self._S
        CC = args[3]
        saved = CC.copy() if keep_cc else None
        call = self._split_calls.get(dtype)
        if call is None:  # (compiled or loaded on the first split)
            kernel = split_kernel(self.layout, tuple_shape(args))
            status = kernel(cuts, S, self._width, *leaves)
            self._split_calls[dtype] = _entry_point(kernel, (cuts, S, self._width, *leaves))
        else:
            status = call(cuts, S, self._width, *leaves)
        if status == -1 and saved is not None:
            CC[...] = saved
        if status != 0:
            return status, 0, ends[:0], 0
        rows = S.tolist()  # (a few Python ints: cheaper than numpy's reductions on a tiny array)
        written = (
            np.concatenate([ends[lo : lo + row[2]] for lo, row in zip(self._lows, rows)])
            if any(row[2] for row in rows)
            else ends[:0]
        )
        return 0, sum(row[1] for row in rows), written, sum(row[3] for row in rows)

    def rows(self, idx, draw, Y, GEN, obs, over, hstep, steps, metrics, readouts) -> None:
        """:func:`rows_kernel` on the sub-envs ``idx`` of a step's (or a reset's) arrays: their
        starts drawn where ``draw``, their rows of the observation, metrics and read-outs
        filled."""
        import numpy as np

        self._rows(
            *self._rows_args(
                np.asarray(idx, dtype=np.int64),
                np.asarray(draw, dtype=np.bool_),
                Y,
                GEN,
                obs,
                over,
                hstep,
                steps,
                metrics,
                readouts,
            )
        )

    def _rows_args(self, idx, draw, Y, GEN, obs, over, hstep, steps, metrics, readouts) -> tuple:
        """:func:`rows_kernel`'s arguments, the start's, task's and read-outs' parameters in
        place."""
        pi, po, pe, pr = self.params[1], self.params[3], self.params[4], self.params[5]
        return (
            idx,
            draw,
            Y,
            GEN,
            pi,
            po,
            pe,
            pr,
            self.high,
            self.h,
            obs,
            over,
            hstep,
            steps,
            *metrics,
            *readouts,
        )

    def finish(self, Y, GEN) -> tuple:
        """``(obs, over, metrics, readouts)`` of the states ``Y`` ``(dim, k)`` as after a reset (no
        control acted, zero action): :func:`rows_kernel` without draws (``GEN``: the env's
        generators, only for the kernel's one signature)."""
        import numpy as np

        k = Y.shape[1]
        obs = np.empty((k, self.n_obs), dtype=np.float32)
        over = np.empty(k, dtype=bool)
        metrics = tuple(np.empty(k, dtype=t) for t in self.metric_dtypes)
        readouts = tuple(np.empty(k, dtype=t) for t in self.readout_dtypes)
        self.rows(
            np.arange(k),
            np.zeros(k, dtype=bool),
            Y,
            GEN,
            obs,
            over,
            np.empty(k),
            np.zeros(k, dtype=np.int64),
            metrics,
            readouts,
        )
        return obs, over, metrics, readouts


class Backend:
    """What the step core builds from this module (:class:`rbenvs.core.step.Engine` takes a
    loader of it, :class:`rbenvs.contracts.CompiledBackend`): the core imports no compiled code."""

    StateStep = StateStep
    CheckedRuns = CheckedRuns
    PeriodPlan = PeriodPlan
    DISABLE_VARIABLE = DISABLE_VARIABLE
    available = staticmethod(available)

"""The vector env's whole step, compiled (:func:`vector_kernel`), its rows outside a step
(:func:`rows_kernel`) and its split over threads (:func:`split_kernel`)."""

from __future__ import annotations

from collections.abc import Callable
from functools import cache
from typing import NamedTuple

from ..codegen import generate
from ..jit import jitable
from ..jit import register as _register
from ..kernel_cache import njit as _cached_njit
from .batch import (
    KERNEL_OPTIONS,
    Layout,
    _checked_period,
    _clip_lines,
    _comps,
    _controls,
    _finish_lines,
    _namespace,
)


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

    from ..core.reasons import end_code

    namespace = _namespace(V.batch)
    act = _act(V.control, V.n_in)
    for fn in (V.control, act, V.start, end_code, V.gate):
        if fn is not None:
            _register(fn)
    namespace.update(act=act, start=V.start, end_code=end_code, np=np, gate=V.gate)
    if V.estimate:
        from ..rotations import power
        from ..stepsize.forms import error_estimate, motion_error_estimate, relaxation_estimate

        namespace.update(
            error_estimate=error_estimate,
            motion_error_estimate=motion_error_estimate,
            relaxation_estimate=relaxation_estimate,
            power=power,
        )
    return namespace


# vector_kernel's arguments after (i_lo, i_hi, phase) and before its parameters: the actions, the
# states, the compensations, the period's settings, the episode clocks and the generators (a
# split step passes the parameters between them flattened: VectorStep)
HEAD_ARGS = (
    "A", "Y", "Ynew", "CC", "h", "dt", "substeps", "check", "refuse", "next_step", "max_steps",
    "FC", "steps", "done", "skip", "GEN",
)  # fmt: skip
# its parameters, then the arrays it writes
PARAM_ARGS = ("PC", "PI", "PS", "PO", "PE", "PR", "PG", "PA", "PD", "CD", "PV", "PW", "HI", "PEE")
OUT_ARGS = (
    "counts", "hstep", "fired", "obs", "over", "reward", "terminated", "truncated", "RZ", "RN",
    "clear", "ends", "codes", "U", "UN", "EST", "PGT",
)  # fmt: skip


def _vector_args(L: Layout) -> list[str]:
    metrics = [f"M{j}" for j in range(L.n_metrics)]
    reads = [f"R{j}" for j in range(L.n_readouts)]
    return ["i_lo", "i_hi", "phase", *HEAD_ARGS, *PARAM_ARGS, *OUT_ARGS, *metrics, *reads]


@cache
def vector_kernel(V: VectorLayout):
    """A vector env's whole step, compiled: one call per step with no Python per sub-env.
    Signature (arrays ``(n,)`` unless said; see :func:`batch_kernel` for the period's)::

        vstep(i_lo, i_hi, phase, A, Y, Ynew, CC, h, dt, substeps, check, refuse, next_step,
        max_steps,
              FC, steps, done, skip, GEN, PC, PI, PS, PO, PE, PR, PG, PA, PD, CD, PV, PW, HI, PEE,
              counts, hstep, fired, obs, over, reward, terminated, truncated, RZ, RN, clear, ends,
              codes, U, UN, EST, PGT, M_1..M_k, R_1..R_m) -> (status, k, m, r)

    on the sub-envs ``i_lo <= i < i_hi`` (every array is the whole batch's; one call's step: 0 and
    ``n``); ``phase`` 0 runs the whole step below; a step split over threads (:class:`VectorStep`)
    runs phase 1 (1 and 2 below: the actions' check, the guard's counts, the period and its
    non-finite check) on every chunk, then, when every chunk returned 0, phase 2 (the rest; the
    caller zeroes the rows ``clear`` in between, and the compacted ``ends`` of a chunk start at
    ``i_lo``): each sub-env's arithmetic is the same whichever its chunk, so any split gives the
    same bits.

    1. the actions ``A`` ``(n, n_in)`` (float32 or float64): every entry finite (else ``(-2,
       i, 0, 0)`` for the first bad sub-env ``i``, nothing else written), clipped to ``[-1, 1]``
       (the single env's rule), mapped by the actuator's pure form into the columns of the
       scratch ``UN`` ``(n_action, n)`` and ``U`` ``(n_control, n)`` (phase 2 reads phase 1's);
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
    # (into the caller's scratch rows U and UN: a split step's phase 2 reads phase 1's)
    lines += [
        "    if phase != 2:",
        "        for i in range(n):",
        "            un, u = act(PC, A, i)",
    ]
    lines += [f"            UN[{j}, i] = un[{j}]" for j in range(L.n_action)] + [
        f"            U[{j}, i] = u[{j}]" for j in range(L.n_control)
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
        # would carry m from sub-env to sub-env and stay scalar
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
        # (i unsigned: cast, not converted silently)
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
    # every loop over the sub-envs over the call's range [i_lo, i_hi): a thread's chunk, or the
    # whole batch (unsigned bounds: an index numba cannot prove non-negative gets a wraparound
    # select on every access, which keeps the loop out of SIMD registers; so bounded, one call's
    # step runs as fast as over range(n): one kernel serves both)
    source = source.replace(
        "    n = Y.shape[1]\n",
        "    n = Y.shape[1]\n    u_lo, u_hi = np.uint64(i_lo), np.uint64(i_hi)\n",
        1,
    )
    source = source.replace(" in range(n):", " in range(u_lo, u_hi):")
    generate(source, f"vector step dim={L.dim} n_obs={L.n_obs}", namespace)
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
    """A vector step split over threads, in one call: ``vsplit(cuts, S, *leaves)`` runs
    :func:`vector_kernel`'s phase 1 on every chunk ``[cuts[c], cuts[c + 1])`` at once (``prange`` on
    the calling thread's number of numba's threads: the caller sets it), then, when every chunk
    returned 0, zeroes the reason pool's rows ``clear`` and runs phase 2 the same way; ``S[c]`` is
    chunk ``c``'s ``(status, k, m, r)``. Returns -1 if a chunk refused, else the sum of the phase-1
    statuses (0: phase 2 ran). ``leaves``: the vector kernel's arguments after ``phase``, their
    tuples flattened (``shape``: :func:`tuple_shape` of them), since a parallel loop's body takes no
    nested tuple from outside; the body rebuilds them. (No numba.set_num_threads inside: its
    compiled form reaches the threading layer through a run-time address, which numba cannot keep in
    a cached kernel.)"""
    import numba
    import numpy as np

    names: list[str] = []
    exprs = [_rebuild(part, names) for part in shape]
    at = dict(zip(_vector_args(V.batch)[3:], exprs))
    lines = [
        f"def vsplit(cuts, S, {', '.join(names)}):",
        "    nc = cuts.shape[0] - 1",
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
        "    return status",
    ]
    namespace = {
        "vstep": vector_kernel(V),
        "prange": numba.prange,
        "np": np,
    }
    generate(
        "\n".join(lines), f"vector step split dim={V.batch.dim} n_obs={V.batch.n_obs}", namespace
    )
    return _cached_njit(namespace["vsplit"], "vsplit", error_model="numpy", parallel=True)

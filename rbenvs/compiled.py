"""Optional compiled batch step (numba): the package's own functions, compiled, in one call.

Why: a numpy step of a batch is one array operation per arithmetic line. At 4096 states each
costs about 1 us, almost all of it dispatch, and a free-body RK4 step alone is about 65 of
them; the reward, observation and read-outs as many again (``rbenvs bench throughput`` prints
both paths). Compiled, the whole step is one call: the guard's check where the env has one,
the physics loop in SIMD registers (about 1.3 ns per state, ``rbenvs bench kernels``), then
one loop per read-out stage.

The same pure parts also make the single env's read-out function (:func:`state_finish`):
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

from functools import lru_cache

from .core.codegen import generate
from .jit import DISABLE_VARIABLE, available, jitable
from .jit import register as _register
from .jit import register_all as _register_all

__all__ = ["jitable", "available", "batch_kernel", "physics_kernel", "state_finish", "BatchStep", "DISABLE_VARIABLE"]

def _comps(fmt, k):
    return ", ".join(fmt.format(j=j) for j in range(k)) + ("," if k == 1 else "")


def _physics_lines(dim: int, n_control: int) -> list[str]:
    """The body of the physics loops: ``Ynew`` = ``substeps`` steps of ``step`` from ``Y``."""
    y_new = f"y = ({_comps('Ynew[{j}, i]', dim)})"
    u = f"u = ({_comps('U[{j}][i]', n_control)})"
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


@lru_cache(maxsize=None)
def physics_kernel(step, dim: int, n_control: int):
    """The physics loops alone, compiled: ``advance(Y, Ynew, U, h, substeps, PS)`` (the batch
    kernel's first part; ``rbenvs bench kernels`` times it)."""
    import numba

    _register_all()
    _register(step)
    src = "def advance(Y, Ynew, U, h, substeps, PS):\n" + "\n".join(_physics_lines(dim, n_control)) + "\n"
    namespace = generate(src, f"physics kernel dim={dim}", {"step": step})
    return numba.njit(error_model="numpy")(namespace["advance"])


@lru_cache(maxsize=None)
def batch_kernel(step, dim: int, n_control: int, observe, n_obs: int, evaluate, n_metrics: int, readouts, n_readouts: int, guard=None, angular=None, n_action: int | None = None):
    """The compiled step of a batch for one layout (cached per process).

    ``step(PS, y, u, h) -> y`` (the integrator's generated step, pure), ``observe(PO, y) ->
    o`` (``n_obs`` components), ``evaluate(PE, y, u_norm) -> (reward, terminated, m_1..m_k)``
    (``k = n_metrics``), ``readouts(PR, y, u, fired) -> (r_1..r_m)`` (``m = n_readouts``, or
    ``readouts`` ``None``); ``guard(PG, angular(PA, y)) -> x`` the guard's step ratio (a period needs
    ``ceil(x)`` steps) or ``None``. The kernel's signature::

        kernel(Y, Ynew, U, UN, h, substeps, PS, PO, PE, PR, HI, check, skip, PG, PA, obs, over,
               reward, terminated, M_1..M_k, R_1..R_m) -> number of non-finite new states, or
               -1 when ``check`` and a sub-env not in ``skip`` needs more than ``substeps``

    ``Y``/``Ynew``: ``(dim, n)`` float64 state before/after; ``U``/``UN``: tuples of ``(n,)``
    float64 control and normalised action components; ``HI``: observation bounds ``(n_obs,)``.
    The observation is clipped to the bounds and ``over`` set where the state left them (the
    single env's rule). If any new state is non-finite the kernel stops after the physics
    and returns their count, the other outputs unset: the caller's numerical-failure path
    takes over from ``Ynew``.
    """
    import numba

    _register_all()
    for fn in (step, observe, evaluate, readouts, guard, angular):
        if fn is not None:
            _register(fn)

    comps = _comps
    metrics = comps("M{j}", n_metrics)
    reads = comps("R{j}", n_readouts) if readouts is not None else ""
    args = "Y, Ynew, U, UN, h, substeps, PS, PO, PE, PR, HI, check, skip, PG, PA, obs, over, reward, terminated"
    args += (", " + metrics.rstrip(",")) if n_metrics else ""
    args += (", " + reads.rstrip(",")) if reads else ""
    y_new = f"y = ({comps('Ynew[{j}, i]', dim)})"
    u = f"u = ({comps('U[{j}][i]', n_control)})"
    # One loop per stage: a loop with nothing but arithmetic and unit-stride loads and stores
    # runs in SIMD registers; one fused loop would run element by element (measured: 56 us
    # against 15 us at 4096 free bodies).
    lines = [f"def kernel({args}):"]
    if guard is not None:
        # the guard first, before anything is written: a period that needs more than
        # substeps steps goes back to the caller (the numpy path subdivides it per sub-env)
        lines += [
            "    if check:",
            "        need = 0",
            "        for i in range(Y.shape[1]):",
            f"            x = guard(PG, angular(PA, ({comps('Y[{j}, i]', dim)})))",
            "            if not (x <= substeps) and not skip[i]:",
            "                need += 1",
            "        if need:",
            "            return -1",
        ]
    lines += [
        *_physics_lines(dim, n_control),
        "    bad = 0",
        "    for i in range(n):",
        "        if not (" + " and ".join(f"isfinite(Ynew[{j}, i])" for j in range(dim)) + "):",
        "            bad += 1",
        "    if bad:",  # the caller's numerical-failure path takes over from the new states
        "        return bad",
        "    for i in range(n):",
        "        " + y_new,
        "        o = observe(PO, y)",
        "        out = False",
    ]
    for j in range(n_obs):
        lines += [
            f"        v = o[{j}]",
            f"        if not (-HI[{j}] <= v <= HI[{j}]):",
            "            out = True",
            f"            v = min(max(v, -HI[{j}]), HI[{j}])",
            f"        obs[i, {j}] = v",
        ]
    lines += [
        "        over[i] = out",
        "    for i in range(n):",
        "        " + y_new,
        f"        r = evaluate(PE, y, ({comps('UN[{j}][i]', n_control if n_action is None else n_action)}))",
        "        reward[i] = r[0]",
        "        terminated[i] = r[1]",
        *[f"        M{j}[i] = r[{j + 2}]" for j in range(n_metrics)],
    ]
    if readouts is not None:
        lines += ["    for i in range(n):", "        " + y_new, f"        {u}", "        q = readouts(PR, y, u, False)", *[f"        R{j}[i] = q[{j}]" for j in range(n_readouts)]]
    lines += ["    return bad"]
    from math import isfinite

    namespace = {"step": step, "observe": observe, "evaluate": evaluate, "readouts": readouts, "guard": guard, "angular": angular, "isfinite": isfinite}
    generate("\n".join(lines), f"batch kernel dim={dim} n_obs={n_obs}", namespace)
    # error_model="numpy": a float division by zero gives inf/nan as on arrays (and needs no
    # per-element check, which would keep the loops out of SIMD registers)
    return numba.njit(error_model="numpy")(namespace["kernel"])


@lru_cache(maxsize=None)
def state_finish(observe, n_obs: int, evaluate, metric_names: tuple, readouts, readout_names: tuple, high: tuple):
    """The single env's counterpart of the batch kernel's task loops, for one state of floats:
    ``finish(y, u_norm, PO, PE, PR, h, u, fired) -> (obs, over, reward, terminated, info)``
    (``u``: the control that acted, ``fired``: the period's terminal event; read-out inputs).

    Plain Python, generated per layout like the kernel: it calls the same pure functions
    (observation, reward and metrics, read-outs) and builds ``info`` as one dict display (the
    single env's step costs a few microseconds; a method call per part costs about a tenth
    of one each). ``high``: the observation bounds; a state outside them gets the clipped
    observation and ``over`` true.
    """
    import numpy as np

    lines = ["def finish(y, u_norm, PO, PE, PR, h, u=None, fired=False):", "    o = observe(PO, y)"]
    inside = " and ".join(f"{-hi!r} <= o[{j}] <= {hi!r}" for j, hi in enumerate(high))
    lines += [
        f"    if {inside}:",
        "        obs, over = array(o, F32), False",
        "    else:",
        "        obs, over = clip(array(o, F64), LOW, HIGH).astype(F32), True",
        "    r = evaluate(PE, y, u_norm)",
        "    v = readouts(PR, y, u, fired)",
    ]
    items = [f"{name!r}: v[{j}]" for j, name in enumerate(readout_names)] + ["'internal_step': h"]
    items += [f"{name!r}: r[{j + 2}]" for j, name in enumerate(metric_names)] + ["'numerical_failure': False"]
    lines += ["    return obs, over, float(r[0]), bool(r[1]), {" + ", ".join(items) + "}"]
    namespace = {
        "observe": observe, "evaluate": evaluate, "readouts": readouts, "array": np.array, "clip": np.clip,
        "F32": np.dtype(np.float32), "F64": np.dtype(np.float64), "LOW": -np.asarray(high), "HIGH": np.asarray(high),
    }
    assert len(high) == n_obs
    generate("\n".join(lines), f"state finish n_obs={n_obs}", namespace)
    return namespace["finish"]


class BatchStep:
    """One env's compiled batch step: the kernel of its layout plus its parameters.

    ``parts`` is :meth:`rbenvs.core.step.Engine.kernel_parts`; ``dim`` the state size,
    ``n_obs`` the observation size, ``n_control`` the control size, ``sample`` any state (as
    floats) used once to learn the metrics' types.
    """

    def __init__(self, parts, dim: int, n_obs: int, n_control: int, sample, obs_high, n_action: int | None = None):
        import numpy as np

        (step, ps), (observe, po), (evaluate, pe), (readouts, pr), guard = parts
        (guard_fn, pg), (angular, pa) = guard if guard is not None else ((None, ()), (None, ()))
        n_action = n_control if n_action is None else n_action
        values = evaluate(pe, tuple(sample), (0.0,) * n_action)
        physical = readouts(pr, tuple(sample), (0.0,) * n_control, False)
        self.n_metrics, self.n_readouts = len(values) - 2, len(physical)
        # each metric's array type from its value on a float state (a bool stays a bool)
        self.metric_dtypes = tuple(np.bool_ if isinstance(v, (bool, np.bool_)) else np.float64 for v in values[2:])
        self.kernel = batch_kernel(step, dim, n_control, observe, n_obs, evaluate, self.n_metrics, readouts, self.n_readouts, guard_fn, angular, n_action)
        self.params = (ps, po, pe, pr)
        self.guard_params = (pg, pa)
        self.high = np.asarray(obs_high, dtype=np.float64)
        self.n_obs = n_obs

    def __call__(self, Y, u, u_norm, h: float, substeps: int, check: bool = False, skip=None):
        """``(Ynew, bad, obs, over, reward, terminated, metrics, readouts)`` for states ``Y``
        ``(dim, n)`` under controls ``u`` and normalised actions ``u_norm`` (tuples of
        ``(n,)`` float64 arrays); ``bad`` counts non-finite new states, or is -1 when
        ``check`` is set and the guard asks more than ``substeps`` steps of a sub-env not in
        ``skip`` (bool ``(n,)``); in either case the other outputs are unset."""
        import numpy as np

        n = Y.shape[1]
        Ynew = np.empty_like(Y)
        obs = np.empty((n, self.n_obs), dtype=np.float32)
        over = np.empty(n, dtype=bool)
        reward = np.empty(n)
        terminated = np.empty(n, dtype=bool)
        metrics = tuple(np.empty(n, dtype=t) for t in self.metric_dtypes)
        readouts = tuple(np.empty(n) for _ in range(self.n_readouts))
        ps, po, pe, pr = self.params
        pg, pa = self.guard_params
        if skip is None:
            skip = np.zeros(n, dtype=bool)
        bad = self.kernel(Y, Ynew, u, u_norm, h, substeps, ps, po, pe, pr, self.high, check, skip, pg, pa, obs, over, reward, terminated, *metrics, *readouts)
        return Ynew, bad, obs, over, reward, terminated, metrics, readouts

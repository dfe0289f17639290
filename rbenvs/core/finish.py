"""The single env's finish of a period on Python floats as one generated function of the task's
and system's pure forms (observation, reward and metrics, read-outs, ``info``): plain Python,
no numba (the batch kernels' counterpart, :mod:`rbenvs.compiled`)."""

from __future__ import annotations

from functools import cache

from ..codegen import generate

__all__ = ["state_finish", "info_function", "generated_finish"]


@cache
def info_function(readout_names: tuple, metric_names: tuple):
    """``info(q, r, h, e=None)``: the single env's ``info`` from the read-outs ``q``, the evaluation
    ``r = (reward, terminated, metrics...)``, the internal step ``h`` and the period's error
    estimate ``e`` (``None``: not estimated), as one dict display (the order and keys of
    :func:`state_finish`'s)."""
    items = [f"{name!r}: q[{j}]" for j, name in enumerate(readout_names)] + [
        "'internal_step': h",
        "'error_estimate': e",
    ]
    items += [f"{name!r}: r[{j + 2}]" for j, name in enumerate(metric_names)] + [
        "'numerical_failure': False"
    ]
    src = "def info(q, r, h, e=None):\n    return {" + ", ".join(items) + "}\n"
    return generate(src, f"info of {len(readout_names)} read-outs and {len(metric_names)} metrics")[
        "info"
    ]


@cache
def state_finish(
    observe, n_obs: int, evaluate, metric_names: tuple, readouts, readout_names: tuple, high: tuple
):
    """The single env's counterpart of the batch kernel's task loops, for one state of floats:
    ``finish(y, u_norm, PO, PE, PR, h, u, fired) -> (obs, over, reward, terminated, info)``
    (``u``: the control that acted, ``fired``: the period's terminal event; read-out inputs).

    Plain Python, generated per layout like the kernel: it calls the same pure functions
    (observation, reward and metrics, read-outs) and builds ``info`` as one dict display (a
    method call per part would be a sizeable share of the single env's short step). ``high``:
    the observation bounds; a state outside them gets the clipped observation and ``over`` true.
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
    items = [f"{name!r}: v[{j}]" for j, name in enumerate(readout_names)] + [
        "'internal_step': h",
        "'error_estimate': None",
    ]
    items += [f"{name!r}: r[{j + 2}]" for j, name in enumerate(metric_names)] + [
        "'numerical_failure': False"
    ]
    lines += ["    return obs, over, float(r[0]), bool(r[1]), {" + ", ".join(items) + "}"]
    namespace = {
        "observe": observe,
        "evaluate": evaluate,
        "readouts": readouts,
        "array": np.array,
        "clip": np.clip,
        "F32": np.dtype(np.float32),
        "F64": np.dtype(np.float64),
        "LOW": -np.asarray(high),
        "HIGH": np.asarray(high),
    }
    assert len(high) == n_obs
    generate("\n".join(lines), f"state finish n_obs={n_obs}", namespace)
    return namespace["finish"]


def generated_finish(task, system, high_list, metric_names, readout_names):
    """``(finish, PO, PE, PR)``: the single env's finish (observation, evaluation, read-outs,
    ``info``) as one generated function of ``task``'s and ``system``'s pure forms
    (:func:`state_finish`), or ``None`` where a part has none (the engine's methods then run)."""
    kernels, readouts = task.kernels, system.kernel_readouts
    if kernels is None or readouts is None or system.hybrid:
        return None
    (observe, po), (evaluate, pe) = kernels(system)
    f, pr = readouts
    high = tuple(high_list)
    fn = state_finish(observe, len(high), evaluate, metric_names, f, readout_names, high)
    return fn, po, pe, pr

"""Every integrator on every system (and MuJoCo's free body beside them): the whole table of
``rbenvs bench accuracy`` (:func:`run`)."""

from __future__ import annotations

from ...integrators.reference import REFERENCE
from .convergence import (
    CASES,
    CHECK,
    _block_error,
    _n_states,
    _reference,
    _setup,
    convergence,
    drift,
)
from .mujoco import mujoco_free_body


def run(systems=None, quick=False, progress=None, min_time=None, mujoco=True) -> dict:
    """Convergence and drift of every case in ``systems`` (default all); with ``mujoco`` (and
    the package installed) MuJoCo's integrators on the free body too."""
    cases = [c for c in CASES if systems is None or c.key in systems]
    min_time = (0.02 if quick else 0.1) if min_time is None else min_time
    result = {"cases": {}, "convergence": [], "drift": []}
    for case in cases:
        setup = _setup(case.key)
        system, y0, _ = setup
        ref = _reference(case, system, y0)
        if case.key == "free_body":
            check = None  # the exact solution: nothing to check it against but round-off
        else:
            check = _block_error(system, case.key, _reference(case, system, y0, CHECK), ref, y0)
        result["cases"][case.key] = {
            "label": case.label,
            "horizon": case.horizon,
            "states": _n_states(y0),
            "drift_h": case.drift_h,
            "reference": "exact elliptic solution"
            if case.key == "free_body"
            else f"dop853 rtol={REFERENCE.rtol:g} atol={REFERENCE.atol:g}",
            "reference_check": check,
        }
        for name in case.integrators:
            result["convergence"].append(
                convergence(
                    case, name, quick=quick, min_time=min_time, progress=progress, setup=setup
                )
            )
            result["drift"].append(
                drift(case, name, case.long_steps[name][0 if quick else 1], setup=setup)
            )
            if progress:
                progress()
        if case.key == "free_body" and mujoco:
            conv, drifts = mujoco_free_body(quick=quick, min_time=min_time)
            result["convergence"] += conv
            result["drift"] += drifts
    return result

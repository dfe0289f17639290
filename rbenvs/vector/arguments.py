"""A vector env's own keywords checked (the single env's are checked by its constructor)."""

from __future__ import annotations

import inspect

from gymnasium.vector import AutoresetMode

from ..dynamics.validation import unknown_keyword

__all__ = ["require_known", "require_autoreset_mode", "batch_compiled", "batch_threads"]


def require_known(vector_class, base_init, kwargs) -> None:
    """Refuse a keyword that neither ``vector_class`` (its keywords: ``base_init``'s) nor its
    single env takes, naming the nearest."""
    env_class = vector_class.env_class
    valid = [
        k
        for f in (env_class.__init__, base_init)
        for k in inspect.signature(f).parameters
        if k not in ("self", "kwargs")
    ]
    error = unknown_keyword(
        vector_class.__name__,
        kwargs,
        valid,
        f"help(rbenvs.vector.{vector_class.__name__}) and "
        f"help(rbenvs.envs.{env_class.__name__}), docs/vector.md",
    )
    if error is not None:
        raise error


def require_autoreset_mode(value) -> AutoresetMode:
    """``autoreset_mode=``: NEXT_STEP or SAME_STEP (their values too)."""
    try:
        mode = AutoresetMode(value)
    except ValueError:
        raise ValueError(
            "autoreset_mode must be one of "
            f"{[m.value for m in AutoresetMode if m is not AutoresetMode.DISABLED]}, got "
            f"{value!r}"
        ) from None
    if mode is AutoresetMode.DISABLED:
        raise ValueError("autoreset_mode must be NextStep or SameStep (Disabled is not supported)")
    return mode


def batch_compiled(compiled, checked: bool, ranged: bool):
    """``compiled=`` of a batch with ``tolerance_check`` (``checked``: its checked period, an even
    count of steps and the companion run, runs on numpy, its runs in one compiled loop over the
    sub-envs where numba is installed) or ``param_ranges`` (``ranged``: each sub-env's episode has
    its own model, stepped on the float path): ``False`` for either, ``compiled=True`` refused."""
    if not (checked or ranged):
        return compiled
    if compiled is True:
        why = (
            "tolerance_check=True: the checked period (an even count of steps and the companion "
            "run) runs on numpy, its runs in a compiled loop over the sub-envs (where numba is "
            "installed)"
            if checked
            else "param_ranges: each sub-env's episode has its own model (drawn parameters), "
            "stepped one sub-env at a time on the float path"
        )
        raise ValueError(f"compiled=True cannot be had with {why}; pass compiled='auto' or False")
    return False


def batch_threads(num_threads, threads: int, whole) -> int:
    """The threads a batch steps on: ``threads`` (``num_threads=`` resolved) where the whole step
    is compiled (``whole``), else 1 (more than one asked for explicitly is refused)."""
    if whole is not None:
        return threads
    if num_threads != "auto" and threads > 1:
        raise ValueError(
            f"num_threads={num_threads} splits the compiled vector step, and this env steps on "
            "numpy (compiled=False, param_ranges, tolerance_check, an integrator without a pure "
            "form, or numba not installed: the 'fast' extra); pass num_threads=1, or 'auto' (1 "
            "where the step is not compiled)"
        )
    return 1

"""A vector env's reset arguments, checked: the seeds, the options and the start states.

``reset(seed=s)`` seeds sub-env ``i`` with ``s + i`` (a list gives one seed each);
``options`` may hold ``"state"`` (a dict of arrays batched along axis 0: every reset sub-env
starts there, each row checked by its system as the single env checks its start),
``"reset_mask"`` (a boolean array: reset only those sub-envs) and ``"elapsed_steps"`` (an
integer array in ``[0, max_episode_steps)``: the reset sub-envs' episode clocks start there).
Anything else is refused, naming what is accepted.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..dynamics.validation import real_array

__all__ = ["ResetRequest", "reset_request", "state_rows"]


class ResetRequest(NamedTuple):
    """What one ``reset`` asks for: a seed (or ``None``) per sub-env, the start states' dict (or
    ``None``: drawn), the sub-envs to reset (a mask) and their clocks' start (or ``None``: 0)."""

    seeds: list
    state: dict | None
    mask: np.ndarray
    elapsed: np.ndarray | None


def reset_request(n: int, seed, options, max_episode_steps) -> ResetRequest:
    """``reset(seed=..., options=...)``'s arguments for ``n`` sub-envs, checked."""
    if seed is None:
        seeds = [None] * n
    elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
        seeds = [int(seed) + i for i in range(n)]
    else:
        seeds = list(seed)
        if len(seeds) != n:
            raise ValueError(f"seed must be an int, None or a list of {n} seeds, got {len(seeds)}")
    options = {} if options is None else dict(options)
    state = options.pop("state", None)
    mask = options.pop("reset_mask", None)
    elapsed = options.pop("elapsed_steps", None)
    if options:
        raise ValueError(
            f"reset options must be a subset of {{'state', 'reset_mask', 'elapsed_steps'}}, "
            f"got unknown {sorted(options)}"
        )
    if elapsed is not None:
        elapsed = _elapsed_steps(elapsed, n, max_episode_steps)
    if mask is None:
        mask = np.ones(n, dtype=bool)
    else:
        mask = np.asarray(mask)
        if mask.shape != (n,) or mask.dtype != bool:
            raise ValueError(f"options['reset_mask'] must be a boolean array of shape ({n},)")
    return ResetRequest(seeds, state, mask, elapsed)


def _elapsed_steps(elapsed, n: int, max_episode_steps) -> np.ndarray:
    """``options["elapsed_steps"]`` checked: integers of shape ``(n,)`` in ``[0,
    max_episode_steps)`` (the env needs a time limit)."""
    if max_episode_steps is None:
        raise ValueError("options['elapsed_steps'] needs a time limit (max_episode_steps)")
    k = np.asarray(elapsed)
    if k.shape != (n,) or not np.issubdtype(k.dtype, np.integer):
        raise ValueError(
            f"options['elapsed_steps'] must be an integer array of shape ({n},), "
            f"got {k.dtype} {k.shape}"
        )
    if k.min() < 0 or k.max() >= max_episode_steps:
        raise ValueError(
            "options['elapsed_steps'] must lie in [0, max_episode_steps) = [0, "
            f"{max_episode_steps}), got [{k.min()}, {k.max()}]"
        )
    return k.astype(np.int64)


def state_rows(state, mask, n: int, system_of) -> dict:
    """``options["state"]``'s rows of the sub-envs in ``mask``: ``{i: state components}``, each
    row checked by ``system_of(i)`` (its system, or its episode's) as the single env checks its
    start."""
    if not isinstance(state, dict):
        raise ValueError(
            "options['state'] must be a dict of arrays batched along axis 0, got "
            f"{type(state).__name__}"
        )
    arrays = {}
    for name, value in state.items():
        arr = real_array(f"state[{name!r}]", value)
        if arr.ndim < 1 or arr.shape[0] != n:
            raise ValueError(
                f"state[{name!r}] must be batched along a leading axis of length num_envs = "
                f"{n}, got shape {arr.shape}"
            )
        arrays[name] = arr
    return {
        i: system_of(i).import_state({k: v[i] for k, v in arrays.items()})
        for i in np.flatnonzero(mask)
    }

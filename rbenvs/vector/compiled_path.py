"""A vector env's compiled parts: the batch step (period and finish) and the whole step (actions,
period, finish, episode clocks, restarts), built from the model and its settings, and built again
when a pickled or deep-copied env is loaded (numba's objects are not pickled)."""

from __future__ import annotations

import numpy as np

from .. import compiled as _compiled
from ..core.step import _REAL_FLOATS, action_columns
from ..dynamics.validation import real_array

__all__ = ["CompiledPath"]


class CompiledPath:
    """``batch``: the model's :class:`rbenvs.compiled.BatchStep` (``None``: the numpy path);
    ``whole``: its :class:`rbenvs.compiled.VectorStep` (``None`` without ``batch`` or where the
    generators cannot be handed to compiled code, ``tables``)."""

    def __init__(self, env_name, engine, obs_dim, max_episode_steps, compiled, tables, threads):
        self._settings = (env_name, engine, obs_dim, max_episode_steps, tables, threads)
        self._no_skip = None  # (SAME_STEP's skip: made on its first step)
        self._build(compiled)

    def _build(self, compiled) -> None:
        env_name, engine, obs_dim, max_episode_steps, tables, threads = self._settings
        self.batch = _batch_step(env_name, engine, obs_dim, compiled)
        self.whole = None
        if self.batch is not None and tables:
            self.whole = _compiled.VectorStep(
                engine.kernel_parts(),
                engine.model,
                obs_dim,
                engine.high,
                max_episode_steps,
                error=engine.rule.error,
                threads=threads,
            )

    def __getstate__(self):
        return {"settings": self._settings, "built": self.batch is not None}

    def __setstate__(self, state) -> None:
        self._settings, self._no_skip = state["settings"], None
        self._build(state["built"])

    def advance(self, run, u, u_norm, restart, plain, false):
        """The compiled period of the states ``run.y``: ``(y, fast, fired, h)``; ``fast`` is ``(Y,
        obs, over, reward, terminated, metrics, physical read-outs)``, or ``None`` when a new
        state is non-finite (the numpy path then handles the failure from ``y``). The kernel runs
        the guard per sub-env (those about to ``restart`` take ``substeps``, as on the numpy
        path); with ``guard="refuse"`` a period it would subdivide raises before anything
        changes."""
        engine = self._settings[1]
        n = len(restart)
        Y = run.y2d if run.y2d is not None else np.stack(run.y)
        # controls as (n,) float64 arrays (an unactuated axis is a 0.0 for every sub-env)
        u = tuple(c if type(c) is np.ndarray else np.full(n, c, dtype=np.float64) for c in u)
        u_norm = tuple(
            c if type(c) is np.ndarray else np.full(n, c, dtype=np.float64) for c in u_norm
        )
        refuse = engine.guard == "refuse"
        out = self.batch(
            Y, u, u_norm, engine.h, engine.substeps, not plain, restart, refuse, run.cc
        )
        if out.status < 0:
            _refuse(engine, out.counts, restart)
        fired = out.fired if out.fired.any() else false
        y = tuple(out.Y)
        if out.status:
            return y, None, fired, out.h
        fast = (out.Y, out.obs, out.over, out.reward, out.terminated, out.metrics, out.readouts)
        return y, fast, fired, out.h

    def step(self, run, actions, shape, next_step: bool, table, reasons, false):
        """The whole step of ``actions`` (of ``shape``) as one compiled call: the kernel's result
        ``r``, ``done`` (NEXT_STEP: the sub-envs to restart in, those whose episode ended out) and
        ``restart`` (the sub-envs restarted), ``a`` the actions as the kernel read them. A
        non-finite action and a refusal raise as on the numpy path (``table``: the generators';
        ``reasons``: the reason pool's ``(rz, names, clear)``)."""
        engine = self._settings[1]
        a = actions
        if not (
            type(a) is np.ndarray
            and a.dtype in _REAL_FLOATS
            and a.shape == shape
            and a.flags.c_contiguous
        ):
            a = real_array("actions", actions, dtype=None)
            if a.shape != shape:
                raise ValueError(f"actions must have shape {shape}, got {a.shape}")
            a = np.ascontiguousarray(a, dtype=a.dtype if a.dtype in _REAL_FLOATS else np.float64)
        Y = run.y2d if run.y2d is not None else np.stack(run.y)
        if next_step:
            if not run.prev_done.flags.writeable:
                run.prev_done = run.prev_done.copy()
            done = run.prev_done  # in: the sub-envs to restart; out: those whose episode ended
            restart = skip = done.copy()
        else:
            done, restart, skip = np.empty(len(run.steps), dtype=bool), false, self._no_skip
            if skip is None or len(skip) != len(done):
                # (all False and never written, but writable as NEXT_STEP's: numba compiles a
                # kernel per argument writability)
                skip = self._no_skip = np.zeros(len(done), dtype=bool)
        # (compiled arithmetic raises no floating-point warnings: no errstate needed here)
        r = self.whole(
            a,
            Y,
            run.steps,
            done,
            skip,
            table,
            not run.plain,
            engine.guard == "refuse",
            next_step,
            reasons,
            run.cc,
        )
        if r.status == -2:  # a non-finite action: the numpy path's check raises, naming it
            action_columns(actions, shape)
            raise AssertionError(
                "the compiled step found a non-finite action that action_columns accepted"
            )
        if r.status == -1:
            _refuse(engine, r.counts, restart)
        return r, done, restart, a


def _refuse(engine, counts, restart):
    over = (counts > engine.substeps) & ~restart
    raise engine.refusal(int(counts[over].max()), f" of sub-envs {np.flatnonzero(over).tolist()}")


def _batch_step(env_name, engine, obs_dim, compiled):
    """The model's :class:`rbenvs.compiled.BatchStep`, or ``None`` for the numpy path
    (``compiled=True``: demanded, or the reason why it cannot be had)."""
    if compiled is False:
        return None
    parts = engine.kernel_parts()
    model = engine.model
    if not _compiled.available():
        reason = (
            f"numba is not installed (the 'fast' extra) or {_compiled.DISABLE_VARIABLE}=0 is set"
        )
    elif parts is None:
        reason = (
            f"{env_name} with integrator {model.integrator.name!r}, task {model.task.name!r} and "
            "these settings has no compiled step (the integrator, system and task need pure "
            "forms; events and hybrid switching never compile)"
        )
    else:
        actuator = model.actuator
        u_norm, u = actuator.control((0.0,) * actuator.size)
        sample = model.initial_state(np.random.default_rng(0))
        return _compiled.BatchStep(
            parts,
            model.system.dim,
            obs_dim,
            len(u),
            sample,
            engine.high,
            len(u_norm),
            model.dt,
        )
    if compiled is True:
        raise ValueError(f"compiled=True but {reason}")
    return None

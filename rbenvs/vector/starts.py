"""A vector env's starts: each sub-env's generator, the start states drawn from them, their first
observations and info rows, and the autoreset of the sub-envs whose episode ended (NEXT_STEP and
SAME_STEP), writing only their rows."""

from __future__ import annotations

import numpy as np
from gymnasium.utils import seeding

from ..draws import GeneratorTable, kind_codes
from .resets import state_rows

__all__ = ["BatchStarts"]


class BatchStarts:
    """The starts of ``n`` sub-envs of ``engine``'s model. ``rngs``: each sub-env's generator
    (``None`` until its first reset); ``table``: the same generators as one compiled table
    (:class:`rbenvs.draws.GeneratorTable`), made once every sub-env has one where ``tables``
    (restarts then draw with no Python per sub-env). ``path``: the env's
    :class:`~rbenvs.vector.compiled_path.CompiledPath`; ``accuracy``: its
    :class:`~rbenvs.stepsize.report.BatchAccuracy` (a new run's companion); ``episodes``: its
    :class:`~rbenvs.vector.episodes.EpisodeBatch` with ``param_ranges`` (else ``None``)."""

    def __init__(self, engine, n, obs_dim, tables, info_readouts, path, accuracy, episodes):
        self.engine, self.model = engine, engine.model
        self.n, self.obs_dim, self.tables, self.info_readouts = n, obs_dim, tables, info_readouts
        self.path, self.accuracy, self.episodes = path, accuracy, episodes
        self.rngs = [None] * n
        self.table = None
        self.codes = kind_codes(self.model.draw_kinds)

    def __getstate__(self):
        """Everything but the table's typed lists, made again on loading around the same
        generators."""
        state = self.__dict__.copy()
        state["table"] = self.table is not None
        return state

    def __setstate__(self, state) -> None:
        self.__dict__.update(state)
        self.table = GeneratorTable(self.rngs) if state["table"] else None

    def seed(self, seeds, mask) -> None:
        """A new generator for each sub-env of ``mask`` with a seed (or none yet)."""
        for i in np.flatnonzero(mask):
            if seeds[i] is not None or self.rngs[i] is None:
                self.rngs[i] = seeding.np_random(seeds[i])[0]
                if self.table is not None:
                    self.table[i] = self.rngs[i]
        if self.tables and self.table is None and all(r is not None for r in self.rngs):
            self.table = GeneratorTable(self.rngs)

    def start(self, run, state, mask) -> None:
        """The sub-envs of ``mask`` start at ``state`` (a reset's option: each row checked by its
        system, its episode's with ``param_ranges``, as the single env checks its start), or at
        states drawn from their generators."""
        idx = np.flatnonzero(mask)
        if state is None:
            self.draw(run, idx)
            return
        if self.episodes is not None:  # the episodes' parameters first, as the single env draws
            self.episodes.start(idx, self.rngs)
        system = self.model.system
        system_of = self.episodes.system if self.episodes is not None else lambda i: system
        rows = state_rows(state, mask, self.n, system_of)
        if run.y is None:
            run.y = tuple(np.zeros(self.n) for _ in range(system.dim))
        run.set_rows(rows)
        self._restart_companion(run, list(rows))

    def draw(self, run, idx) -> None:
        """New initial states for the sub-envs ``idx``, each from its own generator: only the
        generator calls run per sub-env (the model's ``draw_kinds``; one compiled loop over the
        sub-envs where numba is installed), the arithmetic once on the batch
        (``Model.initial_from_draws``). Sub-env ``i`` gets the state a single env draws from the
        same generator (tested)."""
        if len(idx) == 0:
            return
        model = self.model
        if self.episodes is not None:
            comps = self.episodes.initial_states(idx, self.rngs)
        else:
            if self.table is not None:
                task_raw, system_raw = model.split_draws(self.table.draws(idx, self.codes))
            else:
                task_raw, system_raw = model.batch_draws([self.rngs[i] for i in idx])
            comps = model.initial_from_draws(tuple(task_raw), tuple(system_raw))
        if run.cc is not None:  # (new runs)
            run.cc[:, idx] = 0.0
        if run.y2d is not None:  # the rows of the kernel's (dim, n) state, which run.y views
            for j, v in enumerate(comps):
                run.y2d[j, idx] = v
            return
        y = (
            [c.copy() for c in run.y]
            if run.y is not None
            else [np.zeros(self.n) for _ in range(model.system.dim)]
        )
        for c, v in zip(y, comps):
            c[idx] = v
        run.y = tuple(y)
        self._restart_companion(run, idx)

    def _restart_companion(self, run, idx) -> None:
        """The companions of the sub-envs ``idx`` start at their new states
        (``tolerance_check``)."""
        if self.episodes is not None:  # (each its episode's)
            self.episodes.restart_checks(idx, run.y)
        self.accuracy.restart(run.y, idx)

    def fresh(self, y, idx, started=None, compiled=True):
        """``(obs, over, metrics, physical)`` of states ``y`` that have just been reset: no control
        acted yet (read-outs under ``u = None``, the single env's rule), the task's metrics at zero
        action. Compiled where the step is (:meth:`rbenvs.compiled.VectorStep.finish`); on numpy
        ``physical`` is ``None`` (the engine's read-outs are taken where needed). ``y``: the rows
        ``idx`` of the batch; ``started``: the sub-envs that start an episode (``None``: every
        one of ``idx``; a sub-env's episode engine keeps its run going where it does not);
        ``compiled=False``: on numpy (a reset: its rows once per reset are not worth a kernel
        that is slow to compile; the same bits)."""
        if self.episodes is not None:
            return self.episodes.fresh(y, idx, started, self.obs_dim)
        names = self.model.task.metric_names
        if compiled and self.path.whole is not None and self.table is not None:
            obs, over, metrics, physical = self.path.whole.finish(np.stack(y), self.table.list)
            return obs, over, dict(zip(names, metrics)), physical
        if compiled and self.path.batch is not None:
            obs, over, _, _, metrics, physical = self.path.batch.finish(np.stack(y))
            return obs, over, dict(zip(names, metrics)), physical
        actuator = self.model.actuator
        zero = actuator.control(tuple(np.zeros(len(y[0])) for _ in range(actuator.size)))[0]
        obs, over = self.engine.observe(y)
        return obs, over, self.engine.evaluate(y, zero)[2], None

    def restart(self, run, which, obs, info):
        """NEXT_STEP autoreset of the sub-envs in ``which``: new initial states, and their rows of
        ``obs`` and ``info`` as after a reset. Only those rows are computed and written: a few
        restarts in a large batch cost a few rows, not another pass over the batch."""
        idx = np.flatnonzero(which)
        self.draw(run, idx)
        run.steps[which] = 0
        y = tuple(c[idx] for c in run.y)
        new_obs, _, metrics, physical = self.fresh(y, idx)
        obs = obs.copy()
        obs[idx] = new_obs
        engine, values = self.engine, {}
        if self.info_readouts:
            if physical is None:
                values = engine.readouts(y, None, np.zeros(len(idx), dtype=bool), engine.h)
            else:
                values = dict(zip(engine.readout_names, physical), internal_step=engine.h)
        values.update(metrics)
        values["numerical_failure"] = False
        for key, value in values.items():
            column = info[key]
            if not column.flags.writeable:  # a shared mask (info's other arrays are the step's)
                column = info[key] = column.copy()
            column[idx] = value
        _clear_reasons(info, which)
        return obs, info

    def same_step_reset(self, run, done, obs, info, compiled=None):
        """SAME_STEP autoreset of the sub-envs in ``done``: the last observation and info kept in
        ``final_obs`` and ``final_info``, then :meth:`restart` (or, after a compiled step's
        result ``compiled``, the compiled restarts written into its arrays)."""
        final_obs = obs.copy()
        final_info = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in info.items()}
        if compiled is not None and self.path.whole.restarts:
            r, idx = compiled, np.flatnonzero(done)
            self.path.whole.rows(
                idx,
                np.ones(len(idx), dtype=bool),
                r.Y,
                self.table.list,
                obs,
                r.over,
                r.h,
                run.steps,
                r.metrics,
                r.readouts,
            )
            if run.cc is not None:  # (new runs)
                run.cc[:, idx] = 0.0
            _clear_reasons(info, done)  # (every ended sub-env restarts)
        else:
            obs, info = self.restart(run, done, obs, info)
        final = np.empty(self.n, dtype=object)  # one float32 observation per ended sub-env
        for i in np.flatnonzero(done):
            final[i] = final_obs[i]
        info["final_obs"], info["_final_obs"] = final, done.copy()
        info["final_info"], info["_final_info"] = final_info, done.copy()
        return obs, info


def _clear_reasons(info, which) -> None:
    """No terminal reason for the restarted sub-envs ``which`` (their period is discarded)."""
    if "terminal_reason" in info:
        info["terminal_reason"] = np.where(which, "", info["terminal_reason"])
        info["_terminal_reason"] = info["_terminal_reason"] & ~which

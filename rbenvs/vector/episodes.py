"""``param_ranges`` in a vector env: every sub-env's episode a model of its own.

Each sub-env draws its episode's parameters from its own generator, as the single env seeded
``s + i`` draws them, and gets that episode's engine (:meth:`rbenvs.envs.base.RigidBodyEnv.
episode_env`); its periods are the single env's very step on floats, one sub-env at a time (no
batched or compiled step of a model per row exists), with a tolerance's estimate and, with
``tolerance_check``, its own companion (:class:`rbenvs.stepsize.controller.GlobalErrorCheck`).
:class:`EpisodeBatch` holds those engines and returns the batch's arrays; the vector env does
the rest of its step (info, clocks, autoreset) as on its other paths.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..stepsize.controller import GlobalErrorCheck

__all__ = ["EpisodeBatch", "EpisodeStep"]


class EpisodeStep(NamedTuple):
    """A step's arrays over the batch (:meth:`EpisodeBatch.step`); a restarting sub-env's row
    holds its old state and zeros (its period is discarded)."""

    y: tuple  # the new states, one (n,) array per component
    obs: np.ndarray
    reward: np.ndarray
    terminated: np.ndarray
    over: np.ndarray  # left the observation bounds
    fired: np.ndarray  # the system's terminal event
    failed: np.ndarray  # numerical failure
    h: np.ndarray  # the internal step
    u: tuple | None  # the controls that acted, one (n,) array per input (None: none acted)
    metrics: dict
    physical: list  # the read-outs, one array each
    estimates: np.ndarray | None  # info["error_estimate"] (a tolerance)
    global_: np.ndarray | None  # info["global_error_estimate"] (tolerance_check)


class EpisodeBatch:
    """The episode engines of ``n`` sub-envs under ``ranges`` (the validated ``param_ranges``),
    made by ``template`` (the single env the vector env was built from); ``checked``: each
    episode has a companion run (``tolerance_check``); ``estimated``: each period reports its
    error estimate (a tolerance)."""

    def __init__(self, template, ranges, n: int, checked: bool, estimated: bool):
        self.template, self.ranges, self.n = template, ranges, n
        self.engines = [None] * n
        self.checks = [None] * n if checked else None
        self.estimated = estimated
        self.plains = np.ones(n, dtype=bool)  # each run's plain flag (Engine.step_one's)
        self.values = {}  # the drawn values per info["params"] name, (n, ...) each
        self.metric_names = template.model.task.metric_names
        self.readout_names = template.engine.readout_names
        self._dtypes = {}

    def start(self, idx, rngs) -> None:
        """Each sub-env in ``idx`` draws its episode's parameters from its generator ``rngs[i]``
        (the single env's first draws) and gets that episode's engine."""
        for i in idx:
            values = self.ranges.draw(rngs[i])
            engine = self.engines[i] = self.template.episode_env(values).engine
            self.plains[i] = engine.plain
            if self.checks is not None:  # (started at the episode's state: restart_checks)
                self.checks[i] = GlobalErrorCheck(engine)
            for name, v in self.ranges.info(values).items():
                column = self.values.get(name)
                if column is None:
                    column = self.values[name] = np.zeros((self.n,) + np.shape(v))
                column[i] = v

    def initial_states(self, idx, rngs) -> tuple:
        """New episodes for the sub-envs ``idx`` and their initial states (each drawn by its
        episode's model from its generator after the parameters, as the single env draws them),
        one array per component."""
        self.start(idx, rngs)
        starts = [self.engines[i].model.initial_state(rngs[i]) for i in idx]
        return tuple(np.array([float(c) for c in col]) for col in zip(*starts))

    def system(self, i):
        """Sub-env ``i``'s episode system (its drawn parameters)."""
        return self.engines[i].system

    def restart_checks(self, idx, y) -> None:
        """The companions of the sub-envs ``idx`` start at their states in ``y``."""
        if self.checks is not None:
            for i in idx:
                self.checks[i].restart(tuple(float(c[i]) for c in y))

    def params_info(self, started) -> dict:
        """``info["params"]``: the drawn values, masked to the sub-envs that ``started``."""
        params = {}
        for name, column in self.values.items():
            params[name] = column.copy()
            params["_" + name] = started.copy()
        return params

    def fresh(self, y, idx, started, n_obs: int):
        """``(obs, over, metrics, physical)`` of the rows ``idx`` (states ``y``) that have just
        been reset, by each one's episode engine; a sub-env the reset leaves running (not
        ``started``; ``None``: every one started) goes on with its run's compensation."""
        obs, over = np.zeros((len(idx), n_obs), dtype=np.float32), np.zeros(len(idx), dtype=bool)
        infos = []
        for j, i in enumerate(idx):
            engine = self.engines[i]
            start = engine.reset_one if started is None or started[i] else engine.fresh_one
            o, info = start(tuple(float(c[j]) for c in y))
            obs[j] = o
            infos.append(info)
        metrics = {
            name: self.column(name, [info[name] for info in infos]) for name in self.metric_names
        }
        physical = [
            np.array([info[name] for info in infos], dtype=np.float64)
            for name in self.readout_names
        ]
        return obs, over, metrics, physical

    def column(self, name, values):
        """A metric's values as an array of its type in the single env's info (bool, int or
        float)."""
        dtype = self._dtypes.get(name)
        if dtype is None:
            v = next((x for x in values if x is not None), 0.0)
            dtype = self._dtypes[name] = (
                np.bool_
                if isinstance(v, bool)
                else (np.int64 if isinstance(v, int) else np.float64)
            )
        return np.array([dtype(0) if x is None else x for x in values], dtype=dtype)

    def step(self, y, rows, restart, n_obs: int, h0: float, event) -> EpisodeStep:
        """One period of every sub-env from the states ``y`` under the actions ``rows`` (one
        list of floats each, checked): the single env's step by its episode engine (with its
        companion where checked), bit for bit; the sub-envs ``restart`` (NEXT_STEP) are left
        as they are. ``h0``: the nominal internal step; ``event``: the system's terminal event's
        name (or ``None``)."""
        n = self.n
        obs = np.zeros((n, n_obs), dtype=np.float32)
        reward = np.zeros(n)
        terminated, over, fired, failed = (np.zeros(n, dtype=bool) for _ in range(4))
        h = np.full(n, h0)
        metric_rows = {name: [None] * n for name in self.metric_names}
        physical = [np.zeros(n) for _ in self.readout_names]
        y_new = [c.copy() for c in y]
        us = [None] * n
        checks = self.checks
        estimates = np.zeros(n) if self.estimated else None  # (0 where no period ran)
        global_ = np.zeros(n) if checks is not None else None
        for i in range(n):
            if restart[i]:  # (NEXT_STEP: reset by the caller, the period discarded)
                continue
            yi = tuple(float(c[i]) for c in y)
            step_one = self.engines[i].step_one if checks is None else checks[i].step_one
            yi, o, r, _, info, u, plain = step_one(yi, rows[i], bool(self.plains[i]))
            self.plains[i] = plain
            if estimates is not None:
                estimates[i] = info["error_estimate"]
            if global_ is not None:
                global_[i] = info["global_error_estimate"]
            for c, v in zip(y_new, yi):
                c[i] = v
            obs[i], reward[i], us[i], h[i] = o, r, u, info["internal_step"]
            reason = info.get("terminal_reason")
            failed[i] = info["numerical_failure"]
            over[i] = reason == "observation_limit"
            fired[i] = event is not None and reason == event
            terminated[i] = reason == "task" or failed[i]
            for name in self.metric_names:
                metric_rows[name][i] = info[name]
            for column, name in zip(physical, self.readout_names):
                column[i] = info[name]
        size = next((len(u) for u in us if u is not None), None)
        u = (
            None
            if size is None
            else tuple(np.array([0.0 if u is None else u[j] for u in us]) for j in range(size))
        )
        metrics = {name: self.column(name, metric_rows[name]) for name in self.metric_names}
        flags = (terminated, over, fired, failed)
        return EpisodeStep(
            tuple(y_new), obs, reward, *flags, h, u, metrics, physical, estimates, global_
        )

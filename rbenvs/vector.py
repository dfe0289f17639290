"""Natively batched vector environments: one batched call of the same physics and tasks.

A :class:`RigidBodyVectorEnv` builds one single environment of its system as a *template*
(its constructor validates the arguments and builds the system, the task and the integrator)
and then steps ``num_envs`` states held as arrays, one array per state component, through
exactly the code the single env runs on Python floats: the system's vector field, the
integrator, the task's reward and termination, the env's action mapping and read-outs. There
is no second implementation of the dynamics or the rewards, and sub-environment ``i`` follows
bit for bit the trajectory of a single env started in the same state with the same actions
(``dop853`` excepted: one adaptive solve for the whole batch picks its steps from all
members, so it agrees to its tolerance only).

Conventions (gymnasium 1.x):

* ``gymnasium.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point", **kwargs)``
  returns one; the keyword arguments are the single env's.
* Autoreset: ``metadata["autoreset_mode"]``, ``NEXT_STEP`` by default (as gymnasium's own
  vector envs): the step after an episode ends resets that sub-env and returns its first
  observation with reward 0 and ``terminated = truncated = False``. ``SAME_STEP`` (argument
  ``autoreset_mode``) resets in the ending step and puts the last observation and info in
  ``info["final_obs"]`` and ``info["final_info"]`` (masks ``"_final_obs"``, ``"_final_info"``).
* Seeding: ``reset(seed=s)`` seeds sub-env ``i`` with ``s + i`` (a list gives one seed each),
  each with its own generator, so sub-env ``i`` draws the same initial states as a single env
  seeded ``s + i`` and reset without a seed after each episode.
* ``info``: a dict of arrays of length ``num_envs`` plus a boolean mask ``"_key"`` per key
  (gymnasium's vector convention). ``terminal_reason`` is a string array ("" where the episode
  goes on).
* Truncation at ``max_episode_steps`` (from the registration) is done here: a vector env is
  not wrapped in ``TimeLimit``.
* ``info_readouts=False`` leaves the physical read-outs (energy, invariants, contact forces)
  out of ``info``, keeping the task's metrics: on the numpy path at thousands of sub-envs
  they cost a good part of the step (``rbenvs bench throughput`` measures both).
* ``compiled="auto"`` (default): where numba is installed (the ``fast`` extra) and the env's
  integrator, system and task all have pure forms (today: the free body without attitude,
  spin and detumble, ``euler``/``rk4``; a guarded period that needs more than ``substeps``
  steps runs on numpy), the step runs as one compiled kernel of the same functions
  (:mod:`rbenvs.compiled`), bit for bit the numpy path's result; elsewhere, and with
  ``compiled=False``, the numpy path.
  ``compiled=True`` demands the kernel (``ValueError`` saying why it cannot be had).
  ``self.compiled`` tells which path runs.
* ``get_state()`` returns the single env's dict with every array batched along a leading
  axis of length ``num_envs``; ``reset(options={"state": d})`` starts every sub-env there
  (each row validated like the single env's). ``reset(options={"reset_mask": m})`` resets only
  the sub-envs where ``m`` is true.
"""

from __future__ import annotations

import warnings

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from . import compiled as _compiled
from .dynamics.validation import real_array, require_bool, require_int_at_least
from .envs import FreeRigidBodyEnv, LagrangeTopEnv, NumericalFailureWarning, TippeTopEnv
from .envs.base import MAX_INTERNAL_STEPS, RigidBodyEnv

__all__ = ["RigidBodyVectorEnv", "FreeRigidBodyVectorEnv", "LagrangeTopVectorEnv", "TippeTopVectorEnv"]


class RigidBodyVectorEnv(VectorEnv):
    """Base class: ``env_class`` is the single environment whose code is run on arrays."""

    env_class: type = None

    def __init__(self, num_envs: int = 1, max_episode_steps: int | None = None, autoreset_mode=AutoresetMode.NEXT_STEP, info_readouts: bool = True, compiled="auto", **kwargs):
        self.num_envs = require_int_at_least("num_envs", num_envs, 1)
        self.info_readouts = require_bool("info_readouts", info_readouts)
        if not (isinstance(compiled, (bool, np.bool_)) or compiled == "auto"):
            raise ValueError(f"compiled must be True, False or 'auto', got {compiled!r}")
        compiled = compiled if compiled == "auto" else bool(compiled)
        self.env = env = self.env_class(**kwargs)
        if max_episode_steps is not None:
            max_episode_steps = require_int_at_least("max_episode_steps", max_episode_steps, 1)
        self.max_episode_steps = max_episode_steps
        try:
            mode = AutoresetMode(autoreset_mode)
        except ValueError:
            raise ValueError(f"autoreset_mode must be one of {[m.value for m in AutoresetMode if m is not AutoresetMode.DISABLED]}, got {autoreset_mode!r}") from None
        if mode is AutoresetMode.DISABLED:
            raise ValueError("autoreset_mode must be NextStep or SameStep (Disabled is not supported)")
        self.autoreset_mode = mode
        self.metadata = dict(env.metadata, autoreset_mode=mode)
        self.render_mode = env.render_mode
        self.single_observation_space = env.observation_space
        self.single_action_space = env.action_space
        self.observation_space = batch_space(env.observation_space, self.num_envs)
        self.action_space = batch_space(env.action_space, self.num_envs)
        self.system, self.task, self.integrator = env.system, env.task, env.integrator
        self._obs_high = env._obs_high
        self._obs_high32 = env._obs_high.astype(np.float32)
        self._y = None
        self._steps = np.zeros(self.num_envs, dtype=np.int64)
        self._prev_done = np.zeros(self.num_envs, dtype=bool)
        self._rngs = [None] * self.num_envs
        # shared read-only masks: every step's info reuses them instead of allocating
        self._true = np.ones(self.num_envs, dtype=bool)
        self._false = np.zeros(self.num_envs, dtype=bool)
        self._true.flags.writeable = False
        self._false.flags.writeable = False
        self._batch_step = self._compiled_step(compiled)
        self.compiled = self._batch_step is not None
        self._y2d = None  # the (dim, n) array whose rows are self._y, when the kernel made it

    def _compiled_step(self, compiled):
        """The env's :class:`rbenvs.compiled.BatchStep`, or ``None`` for the numpy path."""
        if compiled is False:
            return None
        env = self.env
        parts = env._kernel_parts()
        if not _compiled.available():
            reason = f"numba is not installed (the 'fast' extra) or {_compiled.DISABLE_VARIABLE}=0 is set"
        elif parts is None:
            reason = (
                f"{type(env).__name__} with integrator {self.integrator.name!r}, task {getattr(self.task, 'name', '?')!r} "
                "and these settings has no compiled step (the integrator, system and task need pure forms; "
                "events and hybrid switching never compile)"
            )
        else:
            n_control = len(env._control((0.0,) * env.action_space.shape[0])[1])
            sample = env._initial_state(np.random.default_rng(0))
            return _compiled.BatchStep(parts, self.system.dim, self.single_observation_space.shape[0], n_control, sample, env._obs_high)
        if compiled is True:
            raise ValueError(f"compiled=True but {reason}")
        return None

    @property
    def dt(self) -> float:
        return self.env.dt

    # ------------------------------------------------------------------ reset
    def reset(self, *, seed=None, options=None):
        n = self.num_envs
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
        if options:
            raise ValueError(f"reset options must be a subset of {{'state', 'reset_mask'}}, got unknown {sorted(options)}")
        if mask is None:
            mask = np.ones(n, dtype=bool)
        else:
            mask = np.asarray(mask)
            if mask.shape != (n,) or mask.dtype != bool:
                raise ValueError(f"options['reset_mask'] must be a boolean array of shape ({n},)")
        for i in np.flatnonzero(mask):
            if seeds[i] is not None or self._rngs[i] is None:
                self._rngs[i] = seeding.np_random(seeds[i])[0]
        if state is not None:
            self._set_rows(self._rows_from_state(state, mask))
        else:
            self._draw_rows(np.flatnonzero(mask))
        self._steps[mask] = 0
        self._prev_done = self._prev_done & ~mask
        obs, over = self._observation(self._y)
        if np.any(over & mask):
            raise ValueError("an initial state lies outside the observation bounds; raise the limit parameters")
        self.env._last_h = np.full(n, self.env._h)
        if hasattr(self.env, "_u"):
            self.env._u = None  # as the single env after reset: table at rest
        info = self._info(self._y, self._false, lifted=self._false)
        return obs, info

    def _draw(self, i) -> tuple:
        return tuple(float(c) for c in self.env._initial_state(self._rngs[i]))

    def _draw_rows(self, idx) -> None:
        """New initial states for the sub-envs ``idx``, each from its own generator.

        Where the task draws in two stages (``initial_draws`` per generator, then
        ``initial_from_draws``: see :mod:`rbenvs.tasks.free_body`) only the generator calls run
        per sub-env and the arithmetic once on the batch (4096 resets: about 5 ms instead of
        22); otherwise one ``_initial_state`` per sub-env. Either way sub-env ``i`` gets the
        state a single env draws from the same generator (tested)."""
        env, task = self.env, self.task
        two_stage = type(env)._initial_state is RigidBodyEnv._initial_state and hasattr(task, "initial_draws")
        if not two_stage or len(idx) == 0:
            self._set_rows({i: self._draw(i) for i in idx})
            return
        raw = np.stack([task.initial_draws(self._rngs[i]) for i in idx], axis=1)
        comps = task.initial_from_draws(self.system, tuple(raw))
        y = [c.copy() for c in self._y] if self._y is not None else [np.zeros(self.num_envs) for _ in range(self.system.dim)]
        for c, v in zip(y, comps):
            c[idx] = v
        self._y = tuple(y)
        self._y2d = None

    def _rows_from_state(self, state, mask) -> dict:
        if not isinstance(state, dict):
            raise ValueError(f"options['state'] must be a dict of arrays batched along axis 0, got {type(state).__name__}")
        n = self.num_envs
        arrays = {}
        for name, value in state.items():
            arr = real_array(f"state[{name!r}]", value)
            if arr.ndim < 1 or arr.shape[0] != n:
                raise ValueError(f"state[{name!r}] must be batched along a leading axis of length num_envs = {n}, got shape {arr.shape}")
            arrays[name] = arr
        # each row validated by the single env's own checks
        return {i: self.env._state_from_dict({k: v[i] for k, v in arrays.items()}) for i in np.flatnonzero(mask)}

    def _set_rows(self, rows: dict) -> None:
        if self._y is None:
            dim = self.system.dim
            self._y = tuple(np.zeros(self.num_envs) for _ in range(dim))
        comps = [c.copy() for c in self._y]
        for i, row in rows.items():
            for c, v in zip(comps, row):
                c[i] = v
        self._y = tuple(comps)
        self._y2d = None

    # ------------------------------------------------------------------ step
    def step(self, actions):
        if self._y is None:
            raise RuntimeError("call reset() before step()")
        n = self.num_envs
        a = real_array("actions", actions, dtype=None)  # the single env's types: real numbers only
        if a.shape != self.action_space.shape:
            raise ValueError(f"actions must have shape {self.action_space.shape}, got {a.shape}")
        if not np.isfinite(a).all():
            bad = np.flatnonzero(~np.all(np.isfinite(a), axis=1))
            raise ValueError(f"actions must be finite; sub-envs {bad.tolist()} are not")
        # Out-of-range actions are clipped (as the single env); one (k, n) float64 copy, so that
        # each column the action mapping reads is contiguous.
        cols = np.clip(a.T, -1.0, 1.0).astype(np.float64, order="C")
        # NEXT_STEP: the sub-envs whose episode ended last step are reset, not stepped.
        restart = self._prev_done if self.autoreset_mode is AutoresetMode.NEXT_STEP else self._false
        any_restart = bool(restart.any())
        env = self.env
        u_norm, u = env._control(tuple(cols))
        y0 = self._y
        fast = None
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            # a sub-env blowing up is reported once, below, as the single env does
            y = None
            if self._batch_step is not None:
                y, fast = self._compiled_advance(y0, u, u_norm, restart)
                event, h = None, env._h
            if y is None:  # no kernel, or a guarded period that needs subdividing
                y, event, h = self._advance(y0, u, restart if any_restart else None)
        failed = self._false
        if fast is not None:  # the kernel's read-outs: every new state finite
            self._y, self._y2d = y, fast[0]
            env._last_h = h
            obs, over, reward, terminated, metrics, physical = fast[1:]
            if not over.any():
                over = self._false
            metrics = dict(zip(self.task.metric_names, metrics))
            return self._finish(n, obs, over, reward, terminated, None, failed, metrics, restart, any_restart, physical)
        self._y2d = None
        # one reduction on the sum of the components (a non-finite one makes it non-finite);
        # the exact per-component test runs only if that flags anything
        if not np.isfinite(sum(y)).all():
            finite = np.ones(n, dtype=bool)
            for c in y:
                finite &= np.isfinite(c)
            failed = ~finite & ~restart
            if failed.any():
                warnings.warn(
                    f"{type(self).__name__}: sub-envs {np.flatnonzero(failed).tolist()} became non-finite with integrator "
                    f"{self.integrator.name!r}; their episodes end and their last finite states are kept",
                    NumericalFailureWarning,
                    stacklevel=2,
                )
            y = tuple(np.where(finite, c, c0) for c, c0 in zip(y, y0))
        self._y = y
        env._last_h = h
        obs, over = self._observation(y)
        reward, terminated, metrics = env._evaluate_batch(y, u_norm)
        reward = np.asarray(reward, dtype=np.float64)
        if reward.shape != (n,):
            reward = np.broadcast_to(reward, (n,)).copy()
        terminated = np.asarray(terminated, dtype=bool)
        if terminated.shape != (n,):
            terminated = np.broadcast_to(terminated, (n,)).copy()
        if failed is not self._false:
            reward = np.where(failed, 0.0, reward)
            terminated = (terminated & ~failed) | failed
        return self._finish(n, obs, over, reward, terminated, event, failed, metrics, restart, any_restart)

    def _finish(self, n, obs, over, reward, terminated, event, failed, metrics, restart, any_restart, physical=None):
        """Info, truncation, terminal reasons and autoreset: the rest of :meth:`step`."""
        env, y = self.env, self._y
        lifted = self._false if event is None else event & ~failed
        info = self._info(y, failed, lifted=lifted, metrics=metrics, physical=physical)
        self._steps += 1
        truncated = self._false.copy() if self.max_episode_steps is None else self._steps >= self.max_episode_steps  # as TimeLimit
        ended = terminated | over | lifted
        if ended.any() or truncated.any():
            reason = np.full(n, "", dtype=object)
            reason[terminated] = "task"
            reason[over] = "observation_limit"
            reason[lifted] = env.event_name or ""
            reason[failed] = "numerical_failure"
            terminated = ended
            info["terminal_reason"] = reason
            info["_terminal_reason"] = terminated | truncated
        if any_restart:
            obs, info = self._restart(restart, obs, info)
            reward = np.where(restart, 0.0, reward)
            terminated = terminated & ~restart
            truncated = truncated & ~restart
        done = terminated | truncated
        if self.autoreset_mode is AutoresetMode.NEXT_STEP:
            self._prev_done = done
        elif done.any():
            obs, info = self._same_step_reset(done, obs, info)
        return obs, reward, terminated, truncated, info

    def _compiled_advance(self, y, u, u_norm, restart):
        """The compiled step: ``(y, fast)``; ``fast`` is ``(Y, obs, over, reward, terminated,
        metrics, physical read-outs)``, or ``None`` when a new state is non-finite (the numpy
        path then handles the failure from ``y``). ``(None, None)`` when the env's guard asks
        for more than ``substeps`` steps of a sub-env (other than those about to restart,
        which take ``substeps`` regardless, as in :meth:`_advance`): the numpy path runs that
        period."""
        n, env = self.num_envs, self.env
        Y = self._y2d if self._y2d is not None else np.stack(y)
        # controls as (n,) float64 arrays (an unactuated axis is a 0.0 for every sub-env)
        u = tuple(c if type(c) is np.ndarray else np.full(n, c, dtype=np.float64) for c in u)
        u_norm = tuple(c if type(c) is np.ndarray else np.full(n, c, dtype=np.float64) for c in u_norm)
        out = self._batch_step(Y, u, u_norm, env._h, env.substeps, not env._plain_advance, restart)
        Ynew, bad, obs, over, reward, terminated, metrics, physical = out
        if bad < 0:
            return None, None
        y = tuple(Ynew)
        if bad:
            return y, None
        return y, (Ynew, obs, over, reward, terminated, metrics, physical)

    def _advance(self, y, u, skip=None):
        """One control period for the whole batch: ``(y, event_mask, internal_step)``.

        The internal step count may differ per sub-env (guarded stepping): each element takes
        its own ``h = dt / n_i`` and is frozen once its ``n_i`` steps (or its event) are done,
        so it sees exactly the steps a single env would take. ``skip`` marks sub-envs whose
        result is discarded (NEXT_STEP restarts): they take ``substeps`` steps, are never
        refused and never stretch the batch's loop.
        """
        env, integ, system = self.env, self.integrator, self.system
        n_env = self.num_envs
        post = env._after_internal_step
        if env._plain_advance:
            # the common case (fixed substeps, no events): the single env's plain loop
            h = env._h
            for _ in range(env.substeps):
                y = integ.step(system, y, u, h)
            return y, None, h
        steps = np.broadcast_to(np.asarray(env.internal_steps(y, u)), (n_env,))
        if skip is not None:
            steps = np.where(skip, env.substeps, steps)
        if env.guard == "refuse" and np.any(steps > env.substeps):
            bad = np.flatnonzero(steps > env.substeps)
            raise env._refusal(int(steps.max()), f" of sub-envs {bad.tolist()}")
        refused = steps > MAX_INTERNAL_STEPS  # numerical failures, as in the single env
        if refused.any():
            # refused: NaN at once (one dummy step), reported with the single env's h = dt / n
            y = tuple(np.where(refused, np.nan, c) for c in y)
            y, event, h = self._advance(y, u, np.where(refused, True, skip) if skip is not None else refused)
            return y, event, np.where(refused, env.dt / steps, h)
        watch = env.event_name is not None
        event = np.zeros(n_env, dtype=bool) if watch else None
        if integ.name == "dop853" and np.any(steps != steps[0]):
            # one adaptive solve per group of equal internal steps (its h must be a scalar)
            out = [np.array(c, dtype=float) for c in y]
            for k in np.unique(steps):
                idx = np.flatnonzero(steps == k)
                sub_y = tuple(c[idx] for c in y)
                sub_u = tuple(c[idx] if np.ndim(c) else c for c in u)
                for _ in range(int(k)):
                    sub_prev, sub_y = sub_y, integ.step(system, sub_y, sub_u, env.dt / int(k))
                    if post is not None:
                        sub_y = post(sub_prev, sub_y, sub_u, env.dt / int(k))
                for o, c in zip(out, sub_y):
                    o[idx] = c
            return tuple(out), event, env.dt / steps
        uniform = bool(np.all(steps == steps[0]))
        h = env.dt / steps[0] if uniform else env.dt / steps
        if uniform and not watch:
            for _ in range(int(steps[0])):
                y_prev, y = y, integ.step(system, y, u, h)
                if post is not None:
                    y = post(y_prev, y, u, h)
            return y, event, h
        active = np.ones(n_env, dtype=bool)
        for k in range(int(steps.max())):
            y_new = integ.step(system, y, u, h)
            if post is not None:
                y_new = post(y, y_new, u, h)
            active &= k < steps
            if watch:
                with np.errstate(invalid="ignore"):
                    fired = active & np.asarray(env._event_mask(y_new, u), dtype=bool)
            y = tuple(np.where(active, c_new, c) for c_new, c in zip(y_new, y))
            if watch:
                event |= fired
                active &= ~fired
            if not np.any(active):
                break
        return y, event, np.broadcast_to(np.asarray(h, dtype=float), (n_env,)).copy()

    def _restart(self, which, obs, info):
        """NEXT_STEP autoreset of the sub-envs in ``which``: new initial states, fresh info."""
        idx = np.flatnonzero(which)
        self._draw_rows(idx)
        self._steps[which] = 0
        new_obs, _ = self._observation(self._y)
        obs = obs.copy()
        obs[which] = new_obs[which]
        env = self.env
        last_h, env._last_h = env._last_h, np.full(self.num_envs, env._h)  # as after reset()
        if hasattr(env, "_u"):
            env._u = None
        fresh = self._info(self._y, self._false, lifted=self._false)
        for key, value in fresh.items():
            if key.startswith("_"):
                continue
            info[key] = np.where(which, value, info[key]) if key in info else value
        if "terminal_reason" in info:
            info["terminal_reason"] = np.where(which, "", info["terminal_reason"])
            info["_terminal_reason"] = info["_terminal_reason"] & ~which
        env._last_h = last_h
        return obs, info

    def _same_step_reset(self, done, obs, info):
        final_obs = obs.copy()
        final_info = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in info.items()}
        obs, info = self._restart(done, obs, info)
        final = np.empty(self.num_envs, dtype=object)  # one float32 observation per ended sub-env
        for i in np.flatnonzero(done):
            final[i] = final_obs[i]
        info["final_obs"] = final
        info["_final_obs"] = done.copy()
        info["final_info"] = final_info
        info["_final_info"] = done.copy()
        return obs, info

    # ------------------------------------------------------------------ read-outs
    def _observation(self, y):
        """``(obs float32 (n, k), over)``; ``over`` flags sub-envs outside the bounds.

        Fast path: the float32 copy is checked against the float32 bounds with ``<``; as
        rounding to float32 is monotone, ``float32(v) < float32(hi)`` implies ``v < hi``, so
        passing it means every float64 value is inside. Otherwise the exact float64 test of
        the single env decides.
        """
        comps = self.task.observe(self.system, y)
        o = np.empty((self.num_envs, len(comps)), dtype=np.float32)
        for j, c in enumerate(comps):
            o[:, j] = c
        if (np.abs(o) < self._obs_high32).all():
            return o, self._false
        o64 = np.empty((self.num_envs, len(comps)))
        for j, c in enumerate(comps):
            o64[:, j] = c
        outside = ~(np.abs(o64) <= self._obs_high)
        if not outside.any():
            return o64.astype(np.float32), self._false
        return np.clip(o64, -self._obs_high, self._obs_high).astype(np.float32), outside.any(axis=1)

    def _info(self, y, failed, lifted, metrics=None, physical=None) -> dict:
        env = self.env
        if hasattr(env, "_lifted"):
            env._lifted = lifted
        n = self.num_envs
        if not self.info_readouts:
            raw = {}
        else:
            raw = env._readouts(y) if physical is None else env._readouts(y, physical)
        raw.update(self.task.metrics(self.system, y) if metrics is None else metrics)
        info = {}
        every = self._true
        # never hand out the state (or the env's own arrays): those values are copied
        own = {id(c) for c in y}
        own.add(id(getattr(env, "_last_h", None)))
        for key, value in raw.items():
            if type(value) is not np.ndarray:
                value = np.asarray(value)
            if value.shape != (n,):
                value = np.full(n, value) if value.ndim == 0 else np.broadcast_to(value, (n,)).copy()
            elif id(value) in own:
                value = value.copy()
            info[key] = value
            info["_" + key] = every
        info["numerical_failure"] = failed.copy() if failed is not self._false else self._false
        info["_numerical_failure"] = every
        return info

    # ------------------------------------------------------------------ state access
    def get_state(self) -> dict[str, np.ndarray]:
        """The physical state of every sub-env: the single env's names, batched on axis 0."""
        if self._y is None:
            raise RuntimeError("call reset() before get_state()")
        system = self.system
        if hasattr(system, "export_state"):
            return {k: np.array(v, dtype=np.float64).T.copy() for k, v in system.export_state(self._y).items()}
        return {name: np.stack(self._y[a:b], axis=1).astype(np.float64) for name, (a, b) in system.layout.items()}

    # ------------------------------------------------------------------ rendering
    def render(self):
        """``render_mode="rgb_array"``: a tuple with one ``(H, W, 3)`` uint8 frame per sub-env
        (gymnasium's vector convention), drawn by the template env with its state set to each
        row in turn; ``"human"``: sub-env 0 in the template's window, ``None``. The template's
        own state is restored; the batch is only read."""
        if self.render_mode is None:
            warnings.warn(f"{type(self).__name__}.render() called without a render_mode: pass render_mode='rgb_array' or 'human'", stacklevel=2)
            return None
        if self._y is None:
            raise RuntimeError("call reset() before render()")
        env, saved = self.env, self.env._y
        rows = range(self.num_envs) if self.render_mode == "rgb_array" else (0,)
        frames = []
        try:
            for i in rows:
                env._y = tuple(float(c[i]) for c in self._y)
                frames.append(env.render())
        finally:
            env._y = saved
        return tuple(frames) if self.render_mode == "rgb_array" else None

    def close_extras(self, **kwargs):
        self.env.close()


class FreeRigidBodyVectorEnv(RigidBodyVectorEnv):
    """``rbenvs/FreeRigidBody-v0`` batched (see :class:`rbenvs.envs.FreeRigidBodyEnv`)."""

    env_class = FreeRigidBodyEnv


class LagrangeTopVectorEnv(RigidBodyVectorEnv):
    """``rbenvs/LagrangeTop-v0`` batched (see :class:`rbenvs.envs.LagrangeTopEnv`)."""

    env_class = LagrangeTopEnv


class TippeTopVectorEnv(RigidBodyVectorEnv):
    """``rbenvs/TippeTop-v0`` batched (see :class:`rbenvs.envs.TippeTopEnv`)."""

    env_class = TippeTopEnv


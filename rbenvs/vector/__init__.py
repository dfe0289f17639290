"""Natively batched vector environments: the single env's step, on arrays.

A :class:`RigidBodyVectorEnv` validates its keyword arguments by constructing the single env
once and takes its public :class:`~rbenvs.core.model.Model`; from then on it holds its own
``num_envs`` states (one float64 array per state component), its own per-sub-env generators
and its own step counts, and steps them with the model's :class:`~rbenvs.core.step.Engine`:
the same advance, failure handling, observation, evaluation and read-outs the single env runs
on Python floats. There is no second implementation, and sub-env ``i`` follows bit for bit the
trajectory of a single env started in the same state with the same actions (``dop853``
excepted: one adaptive solve per group of sub-envs picks its steps from all members, so it
agrees to its tolerance only).

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
  goes on), present in the steps where some sub-env's episode ended or was truncated (under
  NEXT_STEP a restarting sub-env's step, whose period is discarded, ends nothing).
* Truncation at ``max_episode_steps`` (from the registration) is done here: a vector env is
  not wrapped in ``TimeLimit``.
* ``info_readouts=False`` leaves the physical read-outs (energy, invariants, contact forces)
  out of ``info``, keeping the task's metrics: on the numpy path at thousands of sub-envs
  they cost a good part of the step (``rbenvs bench throughput`` measures both).
* ``num_threads`` (1; ``"auto"``: every usable core): the compiled step split over that many
  threads (:mod:`rbenvs.vector.threads`), the same bits for any count; more than one where the
  step runs on numpy is refused.
* ``compiled="auto"`` (default): where numba is installed (the ``fast`` extra) and the model's
  integrator, system and task all have pure forms (every system and task with ``euler``,
  ``rk4`` or ``splitting``; not ``exact`` or ``dop853``), the whole step runs as one compiled
  call of the same functions (:func:`rbenvs.compiled.vector_kernel`: actions, period,
  finish, episode clocks, end reasons and the restarts, drawn from each sub-env's own
  generator), bit for bit the numpy path's result; Python only assembles ``info`` from its
  arrays. A non-finite state, a refusal and a bad action take the numpy path's handling.
  Elsewhere, and with ``compiled=False``, the numpy path. ``compiled=True`` demands the kernel
  (``ValueError`` saying why it cannot be had). ``self.compiled`` tells which path runs.
* The robustness options (``param_ranges``, ``observation_noise``, ``observation_bias``,
  ``action_delay``; :mod:`rbenvs.envs.options`) keep sub-env ``i`` the single env seeded
  ``s + i``, bit for bit: noise and delay keep the batched (or compiled) step, the actions
  queued in one ``(delay, n, k)`` ring and each sub-env's noise drawn from its own stream (one
  compiled call per step for the batch, :class:`rbenvs.draws.GeneratorTable`); with
  ``param_ranges`` each sub-env's episode has a model of its own, stepped on the float path one
  sub-env at a time (no batched or compiled step: ``compiled=True`` is refused; with a
  tolerance, its period estimated and, with ``tolerance_check``, checked on that model by the
  single env's step), and ``info["params"]`` holds the drawn values of the sub-envs that
  started an episode.
* The arrays a step returns are the caller's (fresh each step), except ``terminal_reason``'s,
  which comes from a small pool and is reused only once nothing else refers to it (CPython's
  reference count; :class:`rbenvs.core.reasons.ReasonPool`).
* ``get_state()`` returns the single env's dict with every array batched along a leading
  axis of length ``num_envs``; ``reset(options={"state": d})`` starts every sub-env there
  (each row validated like the single env's). ``reset(options={"reset_mask": m})`` resets only
  the sub-envs where ``m`` is true. ``reset(options={"elapsed_steps": k})`` starts the reset
  sub-envs' episode clocks at ``k`` (an int array, ``0 <= k < max_episode_steps``) instead of 0:
  a batch whose time limits would all end together then restarts a few sub-envs at each step,
  as a long run does once its episodes have drifted apart (large-batch trainers randomise
  this to avoid synchronised resets; ``rbenvs bench throughput`` measures that steady state).
"""

from __future__ import annotations

import warnings

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from .. import compiled as _compiled
from ..core.reasons import ReasonPool
from ..core.step import action_columns
from ..dynamics.validation import require_bool, require_int_at_least
from ..envs.base import require_compiled
from ..stepsize.report import BatchAccuracy
from .arguments import batch_compiled, batch_threads, require_autoreset_mode, require_known
from .compiled_path import CompiledPath
from .ends import BatchEnds
from .episodes import EpisodeBatch
from .info import BatchInfo
from .realism import BatchRealism
from .resets import reset_request
from .run import BatchRun
from .starts import BatchStarts
from .threads import resolve_num_threads

__all__ = [
    "RigidBodyVectorEnv",
    "vector_class",
    "FreeRigidBodyVectorEnv",
    "LagrangeTopVectorEnv",
    "TippeTopVectorEnv",
]


class RigidBodyVectorEnv(VectorEnv):
    """Base class: ``env_class`` is the single environment whose model is run on arrays."""

    env_class: type = None

    def __init__(
        self,
        num_envs: int = 1,
        max_episode_steps: int | None = None,
        autoreset_mode=AutoresetMode.NEXT_STEP,
        info_readouts: bool = True,
        compiled="auto",
        num_threads=1,
        **kwargs,
    ):
        require_known(type(self), RigidBodyVectorEnv.__init__, kwargs)
        self.num_envs = require_int_at_least("num_envs", num_envs, 1)
        threads = resolve_num_threads(num_threads)
        self.info_readouts = require_bool("info_readouts", info_readouts)
        compiled = require_compiled(compiled)
        if max_episode_steps is not None:
            max_episode_steps = require_int_at_least("max_episode_steps", max_episode_steps, 1)
        self.max_episode_steps = max_episode_steps
        self.autoreset_mode = mode = require_autoreset_mode(autoreset_mode)
        # the single env's constructor validates the arguments and builds the model; only its
        # public model, spaces and metadata are read (compiled=False: no compiled code, the
        # checked runs' neither)
        env = self.env_class(**kwargs, **({"compiled": False} if compiled is False else {}))
        self._adopt(env, mode)
        # the robustness options (rbenvs.envs.options), validated by the single env
        self._ranges, self._realism = env.param_ranges, env.realism
        self._options = self._ranges is not None or self._realism.active
        # tolerance_check's companion runs and param_ranges' episodes step on numpy or floats
        checked = bool(self.model.check)
        compiled = batch_compiled(compiled, checked, self._ranges is not None)
        self._build_batch(env, checked)
        self._build_steps(compiled, threads, num_threads)

    def _adopt(self, env, mode) -> None:
        """The single env's model, engine, spaces and metadata, batched over ``num_envs``
        (construction)."""
        self.model, self.engine = env.model, env.engine
        self.metadata = dict(env.metadata, autoreset_mode=mode)
        self.render_mode = env.render_mode
        self.single_observation_space = env.observation_space
        self.single_action_space = env.action_space
        self.observation_space = batch_space(env.observation_space, self.num_envs)
        self.action_space = batch_space(env.action_space, self.num_envs)
        m = self.model
        self.system, self.task, self.integrator = m.system, m.task, m.integrator
        self._obs_dim = self.single_observation_space.shape[0]

    def _build_batch(self, env, checked: bool) -> None:
        """The batch's state and what each step reports (construction): the episodes of
        ``param_ranges``, the accuracy, the robustness options, the run, info and reasons."""
        engine, n, obs_dim = self.engine, self.num_envs, self._obs_dim
        # param_ranges: each sub-env's episode has its own model (drawn parameters) and engine
        # (with a tolerance its own estimates, with tolerance_check its own companion)
        self._episodes = None
        if self._ranges is not None:
            self._episodes = EpisodeBatch(
                env, self._ranges, n, checked, engine.tolerance is not None
            )
        # what each step reports of its accuracy (info["error_estimate"], with tolerance_check
        # info["global_error_estimate"] and the batch's companion)
        self._accuracy = BatchAccuracy(engine, n, checked, checked and self._ranges is None)
        self._realism_batch = BatchRealism(
            self._realism, n, obs_dim, self.single_action_space.shape, _compiled.available()
        )
        self._renderer = None
        self.run = BatchRun(n, self.system.dim, engine.step_c is not None, engine.plain)
        # shared read-only masks: every step's info reuses them instead of allocating
        self._true, self._false = self._accuracy.true, self._accuracy.false
        self._infos = BatchInfo(engine, n, self.info_readouts, self._true, self._false)
        self._reasons = ReasonPool(n, engine.event_name)

    def _build_steps(self, compiled, threads: int, num_threads) -> None:
        """The compiled path (or the numpy one), the starts and the episode ends (construction;
        ``compiled``: the checked setting, ``threads``: the resolved ``num_threads``)."""
        engine, n, obs_dim = self.engine, self.num_envs, self._obs_dim
        max_episode_steps, mode = self.max_episode_steps, self.autoreset_mode
        tables = compiled is not False and _compiled.available()
        self.compiled_path = CompiledPath(
            self.env_class.__name__, engine, obs_dim, max_episode_steps, compiled, tables, threads
        )
        self.compiled = self.compiled_path.batch is not None
        self.num_threads = batch_threads(num_threads, threads, self.compiled_path.whole)
        batch = (engine, n, obs_dim, tables, self.info_readouts)
        self.starts = BatchStarts(*batch, self.compiled_path, self._accuracy, self._episodes)
        next_step = mode is AutoresetMode.NEXT_STEP
        self._ends = BatchEnds(
            engine, self._infos, self.starts, max_episode_steps, next_step, self._false
        )

    def __getstate__(self):
        """Everything but a figure (the compiled parts and the generators' table rebuild
        themselves on loading, around the same generators: the copy goes on bit for bit)."""
        return dict(self.__dict__, _renderer=None)

    @property
    def dt(self) -> float:
        return self.model.dt

    @property
    def batch_step(self):
        """The compiled :class:`rbenvs.compiled.BatchStep` this env steps with, or ``None`` on the
        numpy path (read-only; ``rbenvs bench throughput`` times it alone: the kernel's share of
        a step, without the Python around it)."""
        return self.compiled_path.batch

    # ------------------------------------------------------------------ reset
    def reset(self, *, seed=None, options=None):
        n = self.num_envs
        seeds, state, mask, elapsed = reset_request(n, seed, options, self.max_episode_steps)
        self.starts.seed(seeds, mask)
        self.starts.start(self.run, state, mask)
        self.run.steps[mask] = 0 if elapsed is None else elapsed[mask]
        self.run.prev_done = self.run.prev_done & ~mask
        self.run.plain = self.engine.plain
        obs, over, metrics, physical = self.starts.fresh(
            self.run.y, np.arange(n), started=mask, compiled=False
        )
        if np.any(over & mask):
            raise ValueError(
                "an initial state lies outside the observation bounds; raise the limit parameters"
            )
        self.run.u = None  # as the single env after reset: nothing acted yet (a table at rest)
        self.run.last_h = np.full(n, self.engine.h)
        run, no = self.run, self._false
        info = self._infos.of_batch(run.y, run.u, run.last_h, None, no, no, metrics, physical)
        self._accuracy.reset_info(info)
        if self._options:
            obs, info = self._realism_after(obs, info, mask)
        return obs, info

    # ------------------------------------------------------------------ step
    def step(self, actions):
        if self.run.y is None:
            raise RuntimeError("call reset() before step()")
        if self._options:  # (the delayed actions, then the step, then the noise)
            return self._step_options(actions)
        return self._accuracy.report(self._step(actions))

    def _step(self, actions):
        """The step of ``actions`` by the path the env runs, each period's error estimate written
        for :meth:`BatchAccuracy.report` (the numpy path's from the rates before its period, or
        the default accuracy's gate, within which its periods take ``substeps`` unchecked)."""
        if self._ranges is not None:
            return self._step_episodes(actions)
        if self.compiled_path.whole is not None and self.starts.table is not None:
            return self._compiled_step_all(actions)
        engine, run = self.engine, self.run
        # NEXT_STEP: the sub-envs whose episode ended last step are reset, not stepped.
        restart = run.prev_done if self.autoreset_mode is AutoresetMode.NEXT_STEP else self._false
        any_restart = bool(restart.any())
        u_norm, u = engine.control(action_columns(actions, self.action_space.shape))
        y0 = run.y
        fast = None
        accuracy = self._accuracy
        plain = accuracy.before(y0, run.y2d, u) or run.plain
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            # a sub-env blowing up is reported once, below, as the single env does
            if self.compiled_path.batch is not None:
                y, fast, fired, h = self.compiled_path.advance(
                    run, u, u_norm, restart, plain, self._false
                )
            else:
                comp = None if run.cc is None else tuple(run.cc)
                y, fired, h, comp = engine.advance(
                    y0, u, plain, restart if any_restart else None, comp
                )
                if comp is not None:
                    cc = run.cc = np.empty((len(comp), self.num_envs))
                    for j, c in enumerate(comp):  # (a component may be one float for every sub-env)
                        cc[j] = c
                if fired is False:
                    fired = self._false
        held = accuracy.held(y, u, h, restart)  # (tolerance_check's)
        run.u, run.last_h = u, h
        accuracy.after(h, restart)
        if fast is None:  # (the numpy path, or a non-finite new state)
            return self._numpy_finish(y0, y, u_norm, fired, restart, any_restart, held)
        # the kernel's read-outs: every new state finite
        run.y, run.y2d = y, fast[0]
        obs, over, reward, terminated, metrics, physical = fast[1:]
        if not over.any():
            over = self._false
        metrics = dict(zip(self.task.metric_names, metrics))
        return self._ends.finish(
            run, obs, over, reward, terminated, fired, None, metrics, restart, any_restart, physical
        )

    def _numpy_finish(self, y0, y, u_norm, fired, restart, any_restart, held=None):
        """The rest of a step on numpy from the period's new states ``y``: numerical failure
        (``held``: the sub-envs whose period the accuracy check did not accept), observation,
        evaluation, then :meth:`BatchEnds.finish`."""
        engine = self.engine
        self.run.y2d = None
        y, failed = engine.settle(y0, y, restart, self.run.last_h, held)
        self.run.y = y
        obs, over = engine.observe(y)
        reward, terminated, metrics = engine.evaluate(y, u_norm)
        if failed is not None:
            reward = np.where(failed, 0.0, reward)
            terminated = terminated | failed
        return self._ends.finish(
            self.run, obs, over, reward, terminated, fired, failed, metrics, restart, any_restart
        )

    def _compiled_step_all(self, actions):
        """:meth:`step` as one compiled call (:class:`rbenvs.compiled.VectorStep`): the same
        actions' checks, period, finish, episode clocks and NEXT_STEP restarts as the numpy
        path, bit for bit; Python builds ``info`` from its arrays. A non-finite new state goes
        to the numpy path's failure handling, a refusal or a bad action raises as there."""
        shape = self.action_space.shape
        next_step = self.autoreset_mode is AutoresetMode.NEXT_STEP
        reasons, rz, clear, entry = self._reasons.take()
        r, done, restart, a = self.compiled_path.step(
            self.run,
            actions,
            shape,
            next_step,
            self.starts.table.list,
            (rz, self._reasons.names, clear),
            self._false,
        )
        # the controls that acted: made from the actions where a failure needs them
        self.run.u, self.run.last_h = None, r.h
        if r.status > 0:  # non-finite new states: the numpy path's failure handling
            self._accuracy.wrote(r.estimate)
            fired = r.fired if r.fired.any() else self._false
            u_norm, self.run.u = self.engine.control(action_columns(a, shape))
            with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                return self._numpy_finish(
                    self.run.y, tuple(r.Y), u_norm, fired, restart, bool(restart.any())
                )
        self._reasons.written(entry, r.written)
        self.run.y2d, self.run.y = r.Y, tuple(r.Y)
        self._accuracy.wrote(r.estimate)
        info = self._infos.of_kernel(r, done, reasons)
        obs, reward = r.obs, r.reward  # (the failure charge is in: the kernel adds it)
        if not next_step:
            if r.n_ended:
                obs, info = self.starts.same_step_reset(self.run, done, obs, info, r)
        elif r.n_restarted and not self.compiled_path.whole.restarts:  # (no pure start)
            obs, info = self.starts.restart(self.run, restart, obs, info)
        return obs, reward, r.terminated, r.truncated, info

    # ------------------------------------------------------------------ robustness options
    def _step_episodes(self, actions):
        """A step of a batch whose sub-envs have their own parameters: each sub-env's period
        and finish by its episode engine on floats (:meth:`EpisodeBatch.step`, the single env's
        very step, so bit for bit), then the batch's info, clocks and autoreset
        (:meth:`BatchEnds.finish`)."""
        rows = np.stack(action_columns(actions, self.action_space.shape), axis=1).tolist()
        run, engine, no = self.run, self.engine, self._false
        restart = run.prev_done if self.autoreset_mode is AutoresetMode.NEXT_STEP else no
        r = self._episodes.step(run.y, rows, restart, self._obs_dim, engine.h, engine.event_name)
        run.y, run.y2d, run.u, run.last_h = r.y, None, r.u, r.h
        self._accuracy.wrote(r.estimates, r.global_)
        fired, failed = r.fired if r.fired.any() else no, r.failed if r.failed.any() else None
        over, metrics, charged = r.over, r.metrics, True
        ends = (restart, bool(restart.any()), r.physical, charged)
        return self._ends.finish(
            run, r.obs, over, r.reward, r.terminated, fired, failed, metrics, *ends
        )

    def _step_options(self, actions):
        """:meth:`step` with the robustness options: the action queue (``action_delay``) gives the
        actions that act; after the step the sub-envs that started a new episode get their
        zero-action queue, noise stream and ``info["params"]``, and every observation its noise
        (:meth:`_realism_after`). The same numbers, in the same order from the same generators,
        as the single env."""
        r = self._realism
        next_step = self.autoreset_mode is AutoresetMode.NEXT_STEP
        restart = self.run.prev_done.copy() if next_step else None
        if r.delay:  # (checked and clipped, as the single env's)
            actions = self._realism_batch.delayed(
                np.stack(action_columns(actions, self.action_space.shape), axis=1)
            )
        obs, reward, terminated, truncated, info = self._accuracy.report(self._step(actions))
        started = restart if next_step else (terminated | truncated)
        obs, info = self._realism_after(obs, info, started, same_step=not next_step)
        return obs, reward, terminated, truncated, info

    def _realism_after(self, obs, info, started, same_step: bool = False):
        """The options' part of a reset or step: ``started`` marks the sub-envs whose episode
        began here (their queues, noise streams and biases: :meth:`BatchRealism.after`; with
        ``param_ranges`` their drawn values in ``info["params"]``). Returns ``(obs, info)``;
        ``info`` is updated."""
        idx = np.flatnonzero(started)
        obs, info = self._realism_batch.after(
            obs, info, idx, self.starts.rngs, self.engine.high, same_step
        )
        if self._ranges is not None and len(idx):
            info["params"] = self._episodes.params_info(started)
            info["_params"] = started.copy()
        return obs, info

    @property
    def noiseless_observation(self):
        """The last observation before its noise (``None`` without observation noise or bias):
        the single env's attribute."""
        return self._realism_batch.noiseless_observation

    # ------------------------------------------------------------------ state access
    def get_state(self) -> dict[str, np.ndarray]:
        """The physical state of every sub-env: the single env's names, batched on axis 0."""
        if self.run.y is None:
            raise RuntimeError("call reset() before get_state()")
        return {
            k: np.array(v, dtype=np.float64).T.copy()
            for k, v in self.system.export_state(self.run.y).items()
        }

    @property
    def state_components(self) -> tuple:
        """The states as the components the model integrates (a tuple of ``(n,)`` arrays)."""
        if self.run.y is None:
            raise RuntimeError("call reset() before reading the state")
        return self.run.y

    # ------------------------------------------------------------------ rendering
    def render(self):
        """``render_mode="rgb_array"``: a tuple with one ``(H, W, 3)`` uint8 frame per sub-env
        (gymnasium's vector convention), each the single env's frame of that state (the env
        class's scene); ``"human"``: sub-env 0 in a window, ``None``. The batch is only read."""
        if self.render_mode is None:
            warnings.warn(
                f"{type(self).__name__}.render() called without a render_mode: pass "
                "render_mode='rgb_array' or 'human'",
                stacklevel=2,
            )
            return None
        if self.run.y is None:
            raise RuntimeError("call reset() before render()")
        if self._renderer is None:
            from ..render import Renderer

            self._renderer = Renderer()
        rows = range(self.num_envs) if self.render_mode == "rgb_array" else (0,)
        frames = []
        for i in rows:
            y = tuple(float(c[i]) for c in self.run.y)
            system = self.system if self._ranges is None else self._episodes.system(i)
            frames.append(self._renderer.frame(self.env_class.scene(system, y)))
        if self.render_mode == "human":
            if self._renderer.can_show():
                self._renderer.show(frames[0], self.metadata["render_fps"])
            return None
        return tuple(frames)

    def close_extras(self, **kwargs):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


# One vector class per registered id, made from its single env's class: ``rbenvs/X-v0`` with
# entry point ``...:XEnv`` has ``rbenvs.vector.XVectorEnv`` (its vector_entry_point). A new
# system needs its registration only.
_MADE: dict = {}


def vector_class(env_class: type) -> type:
    """The vector env class of a single env class (made once)."""
    cls = _MADE.get(env_class)
    if cls is None:
        name = env_class.__name__[: -len("Env")] + "VectorEnv"
        doc = (
            f"The vector env of :class:`{env_class.__module__}.{env_class.__name__}` "
            "(see :mod:`rbenvs.vector`)."
        )
        cls = _MADE[env_class] = type(
            name,
            (RigidBodyVectorEnv,),
            {"env_class": env_class, "__doc__": doc, "__module__": __name__},
        )
    return cls


def _registered() -> dict:
    """``{vector class name: "module:SingleEnvClass"}`` of every registered id."""
    from .. import ENVIRONMENTS

    out = {}
    for spec in ENVIRONMENTS.values():
        module, attr = spec["entry_point"].split(":")
        out[attr[: -len("Env")] + "VectorEnv"] = (module, attr)
    return out


def __getattr__(name):
    entry = _registered().get(name)
    if entry is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    module, attr = entry
    return vector_class(getattr(importlib.import_module(module), attr))


def __dir__():
    return sorted(list(globals()) + list(_registered()))

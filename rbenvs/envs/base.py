"""What every rbenvs environment shares: validation of the common arguments, the model, and the
gymnasium front end (spaces, seeding, reset, step, state access, rendering).

An env's constructor validates its keyword arguments and builds one
:class:`~rbenvs.core.model.Model` (:meth:`RigidBodyEnv._setup`); the step itself is the
model's :class:`~rbenvs.core.step.Engine`, the same one the vector env runs on arrays. The
state is held as a tuple of Python floats, the batch of one, so a single env pays no numpy call
overhead inside the integrator.
"""

from __future__ import annotations

import collections
import math
import os
import sys
import warnings

import gymnasium as gym
import numpy as np

from ..core.model import Model
from ..core.step import Engine, NumericalFailureWarning, action_values
from ..dynamics.validation import require_finite_positive, require_int_in
from ..integrators import integrator_for
from ..stepsize.controller import (
    GUARDS,
    MAX_INTERNAL_STEPS,
    GlobalErrorCheck,
    UnstableMotionWarning,
    accuracy_settings,
    cheapest_scheme,
    require_accuracy,
    require_guard,
    require_resolvable,
    unstable_motion_warning,
)
from .options import ParamRanges, Realism, noise_generator, noisy_observation, rekey
from .shared import keyword_init

__all__ = [
    "RigidBodyEnv",
    "NumericalFailureWarning",
    "UnstableMotionWarning",
    "MAX_INTERNAL_STEPS",
    "GUARDS",
    "FLOAT32_MAX",
    "require_float32_bound",
    "require_float32_rewards",
    "require_authority",
    "require_guard",
    "require_compiled",
]


FLOAT32_MAX = float(
    np.finfo(np.float32).max
)  # the largest observation value (and reward: RL libraries store float32)


def require_float32_bound(name: str, value) -> float:
    """An observation bound: finite, > 0 and representable in float32 (the observation dtype)."""
    v = require_finite_positive(name, value)
    if v > FLOAT32_MAX:
        raise ValueError(
            f"{name} must be <= {FLOAT32_MAX:.3g} (float32 observations), got {value!r}"
        )
    return v


def require_compiled(compiled):
    """``compiled=``: ``True``, ``False`` or ``"auto"`` (a bool only: ``"False"`` is refused)."""
    if isinstance(compiled, (bool, np.bool_)):
        return bool(compiled)
    if isinstance(compiled, str) and compiled == "auto":
        return compiled
    raise ValueError(f"compiled must be True, False or 'auto', got {compiled!r}")


def require_render_mode(mode, modes) -> None:
    """``render_mode=``: ``None`` or one of the env's ``modes``."""
    if mode is not None and (not isinstance(mode, str) or mode not in modes):
        raise ValueError(f"render_mode must be None or one of {modes}, got {mode!r}")


def compiled_backend():
    """The compiled backend (:class:`rbenvs.compiled.Backend`), loaded where the step core first
    wants a compiled form (the core imports no compiled code: it is given this loader)."""
    from ..compiled import Backend

    return Backend


def _registry() -> dict:
    from ..integrators import INTEGRATORS

    return INTEGRATORS


def _caller_level() -> int:
    """The ``stacklevel`` of the first frame outside this package, seen from the function that
    calls this one: a construction warning names the user's line, whether the env was built
    directly, by a vector env or by a wrapper of ours."""
    package = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    frame, level = sys._getframe(1), 1
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(
        package + os.sep
    ):
        frame, level = frame.f_back, level + 1
    return level


def require_float32_rewards(model) -> None:
    """``model``'s least reward of a step and its failure charge must be float32 numbers: RL
    libraries store rewards in float32 (stable-baselines3's buffers), where a larger one is -inf.
    The control term sets them (a task's own reward is of order one)."""
    floor, charge = (
        model.task.reward_floor(model.system, model.observation_high),
        model.failure_charge,
    )
    if not (abs(floor) <= FLOAT32_MAX and abs(charge) <= FLOAT32_MAX):
        raise ValueError(
            f"control_cost={model.task.control_cost!r} makes the least reward of a step "
            f"{floor:.3g} and the failure charge "
            f"{charge:.3g}, beyond float32's range (+-{FLOAT32_MAX:.3g}, in which RL libraries "
            "store rewards); lower control_cost"
        )


def require_authority(name: str, change: float, bound_name: str, bound: float, unit: str) -> None:
    """An actuator whose full action over one control period can change an observed
    velocity by more than the width of its observation box (``2 * bound``) is refused.

    Why the box: the guard sizes the internal step from the state at the start of a period,
    which lies inside the box; under full action the velocity can grow by ``change``
    within the period, and keeping that within one box width keeps the step inside the
    scheme's region (rk4: ``|Omega| h <= 1`` at the start, below its stability limit 2.83
    with the growth). It also keeps a huge value (``max_torque=1e300``) from overflowing
    the state and the energy in one step. An actuator that merely leaves the box within a
    few steps is legal: the episode ends there (``observation_limit``)."""
    if not change <= 2.0 * bound:
        raise ValueError(
            f"{name} is too large: its full action can change the {unit} by {change:.6g} "
            "in one control period, more "
            f"than the width of the observation box (2 * {bound_name} = {2.0 * bound:.6g}); "
            f"lower {name} or dt, or raise {bound_name}"
        )


class _SupportedSchemes:
    """``cls.integrators``: the registered integrators whose declared needs (``requires``) the
    env's ``system_class`` meets, in registry order (a scheme registered later appears too)."""

    def __get__(self, obj, cls):
        from ..integrators import INTEGRATORS

        return tuple(
            name
            for name, scheme in INTEGRATORS.items()
            if set(scheme.requires) <= cls.system_class.provides
        )


class RigidBodyEnv(gym.Env):
    """Base class. A subclass validates its arguments, builds its system, task and actuator,
    and calls :meth:`_setup`; it names the keywords that set its rates (``_rate_sources``),
    bounds ``|Omega|`` over its starts (``_start_speed``) and inside its observation bounds
    (``_speed_ceiling``), and draws its scene (``scene``)."""

    # render_fps is set per instance from dt (one frame per step)
    metadata = {"render_modes": ["human", "rgb_array"]}
    system_class: type = None  # the system the env builds (its capabilities pick the integrators)
    integrators = _SupportedSchemes()
    # the physical keywords ``param_ranges`` may randomize (rbenvs.envs.options), in draw order
    randomizable: tuple = ()
    # tolerance="default": the relative error over an episode each env is held to unless told
    # otherwise, for the integrators a tolerance takes (None: unchecked)
    default_tolerance: float | None = 1e-3
    _ranges = (
        None  # the validated param_ranges (None: every episode has the constructor's parameters)
    )
    _realism = Realism(None, None, 0)  # noise, bias, delay: none
    noiseless_observation = (
        None  # with observation noise or bias: the last observation without them
    )
    _noise_rng = None  # the noise stream's generator (rbenvs.envs.options.rekey at each reset)
    axis = None  # the env's named axis (the free body's spin tasks), else None
    _renderer = None  # made by the first render() (a close before __init__ ends finds None)

    def __init_subclass__(cls, **kwargs):
        """Each env's ``__init__`` wrapped once (:func:`rbenvs.envs.shared.keyword_init`): its
        keywords recorded, the shared ones in its signature, their defaults and docs."""
        super().__init_subclass__(**kwargs)
        keyword_init(cls)

    # a shared keyword's default where this env's differs (rbenvs.envs.shared)
    shared_defaults: dict = {}
    # the shared keywords' docs: the section of the class's docstring on the guard, and what
    # the env adds to the integrator's bullet
    guard_section = "Guarded stepping"
    integrator_note = ""

    def _setup(self, system, task, actuator, observation_high, options: dict):
        """The model, engine and spaces of ``system``, ``task`` and ``actuator`` under the shared
        keywords ``options`` (:mod:`rbenvs.envs.shared`), validated here."""
        integrator, render_mode = options["integrator"], options["render_mode"]
        guard, compiled, dt, substeps, settings = _step_keywords(
            options, self.default_tolerance, self.registered_episode_steps()
        )
        tolerance, horizon, check, accuracy = settings
        high = tuple(float(v) for v in observation_high)
        episode_steps = self.registered_episode_steps()

        # a closure over horizon: the final model reads it after a tolerance-free setting clears it
        def model_with(scheme, **accuracy_kw):
            parts = (system, task, scheme, actuator, dt, substeps, guard, high)
            limits = (self._speed_ceiling(), tolerance, horizon, episode_steps)
            return Model(*parts, *limits, **accuracy_kw)

        integrator = self._chosen_integrator(integrator, system, tolerance, model_with)
        require_render_mode(render_mode, self.metadata["render_modes"])
        tolerance, accuracy = require_accuracy(
            integrator, guard, tolerance, accuracy, type(self).__name__
        )
        if tolerance is not None and accuracy == "explicit":
            self._warn_unstable_motion(system, task, tolerance, horizon * dt, check)
        if tolerance is None:
            horizon = None
        self.model = model_with(integrator, check=check, accuracy=accuracy)
        require_float32_rewards(self.model)
        self._setup_engine(compiled, render_mode, dt, high, actuator, check)
        require_resolvable(
            self.model,
            self._start_speed,
            self._start_dissipation(system),
            type(self).__name__,
            self._rate_sources,
        )

    def _chosen_integrator(self, integrator, system, tolerance, model_with):
        """The integrator of ``integrator=``: with ``"auto"`` the cheapest registered scheme
        that meets ``tolerance`` (``model_with(scheme)`` builds each candidate's model)."""
        if isinstance(integrator, str) and integrator == "auto":
            schemes = [cls() for cls in _registry().values()]
            speed, dissipation = self._start_speed, self._start_dissipation(system)
            integrator = cheapest_scheme(schemes, system, tolerance, model_with, speed, dissipation)
        return integrator_for(integrator, system)

    def _warn_unstable_motion(self, system, task, tolerance, span: float, check) -> None:
        """Warn where the starts are unstable over ``span`` [s] (:meth:`_unstable_motion`): the
        motion amplifies errors already made, so the global error can pass ``tolerance``."""
        unstable = self._unstable_motion(system, task, span)
        if unstable:
            warnings.warn(
                unstable_motion_warning(tolerance, unstable, check), stacklevel=_caller_level()
            )

    def _setup_engine(self, compiled, render_mode, dt, high, actuator, check) -> None:
        """The engine of ``self.model``, the rendering, the spaces and the step's state."""
        self.engine = Engine(self.model, compiled, backend=compiled_backend)
        self.render_mode = render_mode
        self._renderer = None  # built by the first render(): matplotlib is imported only then
        if render_mode == "human":  # draw after every reset and step; the class's step is untouched
            self.step, self.reset = self._step_human, self._reset_human
        self.metadata = dict(self.metadata, render_fps=max(1, round(1.0 / dt)))
        high32 = np.asarray(high, dtype=np.float32)
        self.observation_space = gym.spaces.Box(-high32, high32, dtype=np.float32)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (actuator.size,), dtype=np.float32)
        self._action_shape = self.action_space.shape  # read on every step
        self._step_one = self.engine.step_one
        # tolerance_check: the companion run beside the state (rbenvs.stepsize.controller)
        self._check = GlobalErrorCheck(self.engine) if check else None
        if check:
            self._step_one = self._check.step_one
        self._y = None  # the state: a tuple of floats
        self._plain = self.engine.plain

    def _setup_options(self, options: dict):
        """Validate the robustness options (:mod:`rbenvs.envs.options`) of the shared keywords
        ``options``; with ``param_ranges`` build the env at every corner of the ranges' box and its
        centre, each of which must pass every check of the constructor and keep the env's
        structure."""
        param_ranges = options["param_ranges"]
        self._realism = realism = Realism(
            options["observation_noise"],
            options["observation_bias"],
            options["action_delay"],
            self.observation_space.high,
        )
        if param_ranges is not None:
            ranges = ParamRanges(type(self), self._kwargs, param_ranges)
            if self.engine.compiled is True:
                raise ValueError(
                    "compiled=True cannot be had with param_ranges: each episode builds its model "
                    "from drawn parameters and "
                    "a compiled step is built per parameter setting (about a second each); pass "
                    "compiled='auto' or False"
                )
            ranges.require_corners(self.episode_env, self.structure())
            self._ranges = ranges
        if realism.active:
            if self.render_mode != "human":
                self.step = self._step_options  # (the class's step stays the plain hot path)

    @property
    def param_ranges(self):
        """The validated ``param_ranges`` (:class:`rbenvs.envs.options.ParamRanges`), or
        ``None``."""
        return self._ranges

    @property
    def realism(self):
        """The validated noise, bias and delay (:class:`rbenvs.envs.options.Realism`)."""
        return self._realism

    def structure(self) -> tuple:
        """What a drawn parameter setting must leave unchanged: spaces, read-outs, metrics, the
        start's draws, the event and the env's named axis (the free body's)."""
        return (
            tuple(self.observation_space.high.tolist()),
            self.action_space.shape,
            self.engine.readout_names,
            self.engine.metric_names,
            self.model.draw_kinds,
            self.system.dim,
            self.engine.event_name,
            self.axis,
        )

    def episode_env(self, values: dict):
        """The env of one episode's drawn parameters: the constructor's keywords with ``values``,
        on the float path (its model and engine are what the episode runs)."""
        kw = dict(self._kwargs, **values)
        kw.update(
            param_ranges=None,
            observation_noise=None,
            observation_bias=None,
            action_delay=0,
            render_mode=None,
            compiled=False,
        )
        return type(self)(**kw)

    # The parts, read from the model (one place).
    system = property(lambda self: self.model.system)
    task = property(lambda self: self.model.task)
    integrator = property(lambda self: self.model.integrator)
    actuator = property(lambda self: self.model.actuator)
    substeps = property(lambda self: self.model.substeps)
    guard = property(lambda self: self.model.guard)
    tolerance = property(lambda self: self.model.tolerance)
    step_rule = property(lambda self: self.model.step_rule)

    @property
    def compiled(self) -> bool:
        """Whether the steps run as one compiled call (``compiled=``; decided on the first step)."""
        return self.engine.forms.state_step is not None

    @property
    def dt(self) -> float:
        """Control period [s]: time advanced by one :meth:`step`."""
        return self.model.dt

    # ------------------------------------------------------------------ construction checks
    # What sets the fastest rate at the start, named for the error messages (each env's keywords).
    _rate_sources = "dt"
    _start_speed = 0.0  # an upper bound of |Omega| [rad/s] over the task's initial states

    def _speed_ceiling(self) -> float:
        """An upper bound of ``|Omega|`` over the states inside the observation bounds (``inf``:
        none known); a guard whose ceiling fits in ``substeps`` needs no check."""
        return math.inf

    @classmethod
    def registered_episode_steps(cls) -> int | None:
        """``max_episode_steps`` of the id registered with this class (``None``: none)."""
        from .. import ENVIRONMENTS

        entry = f"{cls.__module__}:{cls.__name__}"
        for spec in ENVIRONMENTS.values():
            if spec["entry_point"] == entry:
                return spec["max_episode_steps"]
        return None

    def _unstable_motion(self, system, task, span: float) -> str | None:
        """With ``tolerance=``: why the starts this env draws are unstable by the system's own
        theorem, enough to matter over the tolerance's horizon of ``span`` seconds (an
        :class:`UnstableMotionWarning` says so at construction), or ``None``."""
        return None

    def _start_dissipation(self, system) -> float:
        """The stiffest decaying rate of ``system`` at the start (0 where none): the tippe top's
        friction."""
        return 0.0

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        options = {} if options is None else dict(options)
        state = options.pop("state", None)
        if options:
            raise ValueError(
                f"reset options must be a subset of {{'state'}}, got unknown {sorted(options)}"
            )
        params = None
        if self._ranges is not None:  # this episode's parameters, first from the generator
            values = self._ranges.draw(self.np_random)
            episode = self.episode_env(values).engine
            self.model, self.engine, self._step_one = episode.model, episode, episode.step_one
            params = self._ranges.info(values)
        self._plain = self.engine.plain
        if state is None:
            self._y = tuple(float(c) for c in self.model.initial_state(self.np_random))
        else:
            self._y = self.system.import_state(state)
        obs, info = self.engine.reset_one(self._y)
        if self._check is not None:  # (param_ranges: this episode's engine)
            self._check.restart(self._y, engine=self.engine)
            self._step_one = self._check.step_one
            info["global_error_estimate"] = 0.0
        if self._realism.active:
            obs = self._reset_realism(obs)
        if params is not None:
            info["params"] = params
        return obs, info

    def _reset_realism(self, obs):
        """A new episode's actuator queue (``action_delay`` zero actions) and noise stream (its
        key drawn from the env's generator after the start; the bias, then the observation's
        noise)."""
        r = self._realism
        if r.delay:
            self._queue = collections.deque([[0.0] * self._action_shape[0] for _ in range(r.delay)])
        if r.stream:
            if self._noise_rng is None:
                self._noise_rng = noise_generator()
            rekey(self._noise_rng, self.np_random)
            self._bias = (
                None if r.bias is None else r.bias * self._noise_rng.standard_normal(len(r.bias))
            )
            obs = self._noisy(obs)
        return obs

    def _noisy(self, obs):
        """The observation the agent sees: ``obs`` plus the episode's bias and fresh noise."""
        r = self._realism
        self.noiseless_observation = obs
        z = None if r.noise is None else self._noise_rng.standard_normal(len(r.noise))
        return noisy_observation(obs, self._bias, r.noise, z, self.engine.high)

    def _step_options(self, action):
        """:meth:`step` with action delay (the action acts ``action_delay`` periods later; the
        queue starts with zero actions) and observation noise; the physics, the reward and
        ``info`` come from the true state and the action that acted."""
        if self._y is None:
            raise RuntimeError("call reset() before step()")
        a = action_values(action, self._action_shape)
        r = self._realism
        if r.delay:
            self._queue.append(a)
            a = self._queue.popleft()
        self._y, obs, reward, terminated, info, _, self._plain = self._step_one(
            self._y, a, self._plain
        )
        if r.stream:
            obs = self._noisy(obs)
        return obs, reward, terminated, False, info

    def step(self, action):
        if self._y is None:
            raise RuntimeError("call reset() before step()")
        a = action_values(action, self._action_shape)
        self._y, obs, reward, terminated, info, _, self._plain = self._step_one(
            self._y, a, self._plain
        )
        return obs, reward, terminated, False, info

    def internal_steps(self, y, u):
        """Integrator steps per control period at ``y`` under ``u``: ``max(substeps, ceil(x))``
        from the step rule (an int, or an int array for a batch); ``MAX_INTERNAL_STEPS + 1``
        marks a period refused as a numerical failure. The guard's count: with
        ``tolerance_check`` a period takes one more where it is odd (``info["internal_step"]`` is
        the step taken)."""
        return self.engine.internal_steps(y, u)

    # ------------------------------------------------------------------ state access
    def get_state(self) -> dict[str, np.ndarray]:
        """The physical state as named float64 arrays (copies); see the class docstring."""
        if self._y is None:
            raise RuntimeError("call reset() before get_state()")
        return self.system.export_state(self._y)

    @property
    def state_components(self) -> tuple:
        """The state as the components the model integrates (a tuple of floats), read-only."""
        if self._y is None:
            raise RuntimeError("call reset() before reading the state")
        return self._y

    # ------------------------------------------------------------------ rendering
    def render(self):
        """A picture of the current state (it reads the state, never changes it).

        ``render_mode="rgb_array"``: an ``(H, W, 3)`` uint8 frame (``rbenvs.render.FRAME_SIZE``).
        ``"human"``: the frame in a matplotlib window when a display exists (drawn after every
        reset and step; nothing without a display), returns ``None``. Needs matplotlib (the
        ``plot`` extra): ``ImportError`` naming it otherwise. Without a render mode: ``None``
        and a warning, as in gymnasium.
        """
        if self.render_mode is None:
            gym.logger.warn(
                f"{type(self).__name__}.render() called without a render_mode: pass "
                "render_mode='rgb_array' or 'human'"
            )
            return None
        if self._y is None:
            raise RuntimeError("call reset() before render()")
        if self._renderer is None:
            from ..render import Renderer

            self._renderer = Renderer()
        if self.render_mode == "human" and not self._renderer.can_show():
            return None
        frame = self._renderer.frame(self.scene(self.system, self._y))
        if self.render_mode == "rgb_array":
            return frame
        self._renderer.show(frame, self.metadata["render_fps"])
        return None

    @staticmethod
    def scene(system, y) -> dict:
        """The geometry of state ``y`` for :meth:`render` (format: :mod:`rbenvs.render.common`);
        the vector env draws its sub-envs with it too."""
        raise NotImplementedError

    def _step_human(self, action):
        out = self._step_options(action) if self._realism.active else type(self).step(self, action)
        self.render()
        return out

    def _reset_human(self, *, seed=None, options=None):
        out = type(self).reset(self, seed=seed, options=options)
        self.render()
        return out

    def close(self):
        renderer = self._renderer
        if renderer is not None:
            renderer.close()
            self._renderer = None
        super().close()

    def __getstate__(self):
        state = self.__dict__.copy()
        state["_renderer"] = None  # a figure (and window) is rebuilt by the next render()
        return state


def _step_keywords(options: dict, default_tolerance, episode_steps) -> tuple:
    """``(guard, compiled, dt, substeps, (tolerance, horizon, check, accuracy))``: the step's
    shared keywords of ``options``, checked in the constructor's order."""
    guard = require_guard(options["guard"])
    settings = accuracy_settings(
        options["tolerance"],
        options["tolerance_horizon"],
        options["tolerance_check"],
        guard,
        default_tolerance,
        episode_steps,
    )
    compiled = require_compiled(options["compiled"])
    dt = require_finite_positive("dt", options["dt"])
    substeps = require_int_in(
        "substeps",
        options["substeps"],
        1,
        MAX_INTERNAL_STEPS,
        " (more internal steps in a control period is a numerical failure)",
    )
    return guard, compiled, dt, substeps, settings

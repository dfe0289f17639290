"""Glue shared by every rbenvs environment: spaces, seeding, stepping, state access, errors.

The physics (a system from :mod:`rbenvs.dynamics`), the time stepping (an integrator) and the
task (:mod:`rbenvs.tasks`) are separate objects; this class only wires them to gymnasium's
API. The state is held as a tuple of Python floats, the batch of one, so a single env pays no
numpy call overhead inside the integrator.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import gymnasium as gym
import numpy as np

from ..compiled import state_finish
from ..dynamics.validation import real_array, require_finite_positive, require_int_in
from ..core.guard import GUARDS, MAX_INTERNAL_STEPS, StepRule, require_guard, step_ratio
from ..integrators import get_integrator
from ..rotations import maximum, sqrt

__all__ = ["RigidBodyEnv", "NumericalFailureWarning", "MAX_INTERNAL_STEPS", "GUARDS", "require_float32_bound", "require_guard", "action_array"]


FLOAT32_MAX = float(np.finfo(np.float32).max)  # the largest observation value


def require_float32_bound(name: str, value) -> float:
    """An observation bound: finite, > 0 and representable in float32 (the observation dtype)."""
    v = require_finite_positive(name, value)
    if v > FLOAT32_MAX:
        raise ValueError(f"{name} must be <= {FLOAT32_MAX:.3g} (float32 observations), got {value!r}")
    return v


# float dtypes an action array may have on the fast path (builtin dtypes are singletons)
_REAL_FLOATS = (np.dtype(np.float32), np.dtype(np.float64))


def action_array(action, shape) -> np.ndarray:
    """An action (one env: ``shape`` the action space's; a batch: ``(n, k)``) as a float64
    array. Only real numbers are actions: strings (even ``"0.5"``), complex numbers, dicts and
    other objects raise :class:`~rbenvs.dynamics.validation.ParameterTypeError` (a
    ``TypeError``); a wrong shape raises ``ValueError``."""
    arr = real_array("action", action)
    if arr.shape != shape:
        raise ValueError(f"action must have shape {shape}, got {arr.shape}")
    return arr


class NumericalFailureWarning(RuntimeWarning):
    """The state went non-finite; the episode was ended and the last finite state kept."""


class RigidBodyEnv(gym.Env):
    """Base class. A subclass builds ``self.system``, ``self.task``, the action space and
    implements :meth:`_control` (normalised action -> control components)."""

    # render_fps is set per instance from dt (one frame per step)
    metadata = {"render_modes": ["human", "rgb_array"]}

    def _setup(self, system, task, integrator, dt, substeps, observation_high, render_mode, guard="subdivide"):
        self.guard = require_guard(guard)
        self.system = system
        self.task = task
        self._task_evaluate = getattr(task, "evaluate", None)  # reward, end and metrics at once
        self._dt = require_finite_positive("dt", dt)
        self.substeps = require_int_in("substeps", substeps, 1, MAX_INTERNAL_STEPS, " (more internal steps in a control period is a numerical failure)")
        self.integrator = get_integrator(integrator)
        if not self.integrator.supports(system):
            raise ValueError(f"integrator {self.integrator.name!r} is not available for {type(system).__name__}")
        region = getattr(self.integrator, "region", None)
        if region is None:  # declared, not probed: no region, no guard, no run
            raise ValueError(f"integrator {self.integrator.name!r} declares no step region (StepRegion, rbenvs.contracts): it cannot be guarded")
        self._h = self._dt / self.substeps
        self._last_h = self._h  # internal step of the last control period
        if render_mode is not None and (not isinstance(render_mode, str) or render_mode not in self.metadata["render_modes"]):
            raise ValueError(f"render_mode must be None or one of {self.metadata['render_modes']}, got {render_mode!r}")
        self.render_mode = render_mode
        self._renderer = None  # built by the first render(): matplotlib is imported only then
        if render_mode == "human":  # draw after every reset and step; the class's step is untouched
            self.step, self.reset = self._step_human, self._reset_human
        self.metadata = dict(self.metadata, render_fps=max(1, round(1.0 / self._dt)))
        self._obs_high = np.asarray(observation_high, dtype=np.float64)
        self._obs_high_list = self._obs_high.tolist()
        self._obs_high_uniform = self._obs_high_list[0] if len(set(self._obs_high_list)) == 1 else None
        # the plain substep loop applies unless the class steps by state or watches events; a
        # guarded env uses it when no state inside the observation bounds can trip its guard
        # (then a step that ends outside them drops to the checked path until the next reset)
        # the step guard: the system's rates for this integrator's region (rbenvs.core.guard)
        rates = system.guard_rates(region, self._speed_ceiling())
        self.step_rule = StepRule.build(rates, region, self._dt, self.guard)
        self._plain_default = self.event_name is None and self._after_internal_step is None and self.step_rule.idle(self.substeps)
        self._plain_advance = self._plain_default
        # the integrator with this system bound once (the hot path's step; same bits as integ.step)
        self._bound_step = self.integrator.bind(system, system.dim)
        self._pure = self._pure_parts()
        high32 = self._obs_high.astype(np.float32)
        self.observation_space = gym.spaces.Box(-high32, high32, dtype=np.float32)
        self._y = None
        self._require_resolvable()

    # ------------------------------------------------------------------ construction checks
    # What sets the fastest rate at the start, named for the error messages (each env's keywords).
    _rate_sources = "dt"
    _start_speed = 0.0  # an upper bound of |Omega| [rad/s] over the task's initial states

    def _start_steps(self) -> tuple[float, str]:
        """``(x, rule)``: the internal steps per control period (``ceil(x)``) that the step rule
        asks for at the fastest start, and the rule in words. Integrators without a bound of
        their own (exact flows, adaptive schemes) count one radian of the fastest rate per step."""
        region = self.integrator.region
        if not region.bounded:
            region = dataclasses.replace(region, rotation=1.0, reason="one radian of the fastest rate per step")
        rates = self.system.guard_rates(region, self._start_speed)
        rule = StepRule.build(rates, region, self._dt, "subdivide")
        x = step_ratio(rule.params, rates.ceiling)
        lam_d = self._start_dissipation()
        if rule.dissipation is not None and lam_d > 0.0:
            x = max(x, self._dt / (rule.dissipation_step / lam_d))
        return x, rule.text

    def _start_dissipation(self) -> float:
        """The stiffest decaying rate at the start (0 where none): the tippe top's friction."""
        return 0.0

    def _require_resolvable(self) -> None:
        """Refuse, at construction, a control period that no run could resolve: more than
        ``MAX_INTERNAL_STEPS`` internal steps at the start would end the first step as a
        numerical failure (``dt=1e300``; a friction, gravity or spin so large that its time
        scale is far below the step). The error names the parameters that set the rate.
        ``guard="off"`` opts out: it takes ``substeps`` steps whatever the state (a blow-up is
        then reported as a numerical failure, as documented)."""
        if self.guard == "off":
            return
        x, rule = self._start_steps()
        if not x <= MAX_INTERNAL_STEPS:
            raise ValueError(
                f"dt={self._dt!r} s cannot be resolved: at the start the integrator {self.integrator.name!r} needs "
                f"{x:.3g} internal steps per control period ({rule}), more than MAX_INTERNAL_STEPS = {MAX_INTERNAL_STEPS}; "
                f"lower dt, or check {self._rate_sources}, which set the fastest rate"
            )

    @staticmethod
    def _require_authority(name: str, change: float, bound_name: str, bound: float, unit: str) -> None:
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
                f"{name} is too large: its full action can change the {unit} by {change:.6g} in one control period, more "
                f"than the width of the observation box (2 * {bound_name} = {2.0 * bound:.6g}); lower {name} or dt, or raise {bound_name}"
            )

    # ------------------------------------------------------------------ gymnasium API
    @property
    def dt(self) -> float:
        """Control period [s]: time advanced by one :meth:`step`."""
        return self._dt

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        options = {} if options is None else dict(options)
        state = options.pop("state", None)
        if options:
            raise ValueError(f"reset options must be a subset of {{'state'}}, got unknown {sorted(options)}")
        self._plain_advance = self._plain_default
        self._last_h = self._h
        if state is None:
            self._y = tuple(float(c) for c in self._initial_state(self.np_random))
        else:
            self._y = self._state_from_dict(state)
        obs, over = self._observation(self._y)
        if over:
            raise ValueError("the initial state lies outside the observation bounds; raise the limit parameters")
        return obs, self._info(self._y, numerical_failure=False)

    def step(self, action):
        if self._y is None:
            raise RuntimeError("call reset() before step()")
        a = self._action_values(action)
        u_norm, u = self._control(a)
        if self._plain_advance:  # fixed substeps, no events: the loop inline (the hot path)
            y, event, step, h = self._y, None, self._bound_step, self._h
            if self.substeps == 1:
                y = step(y, u, h)
            else:
                for _ in range(self.substeps):
                    y = step(y, u, h)
        else:
            y, event = self._advance(self._y, u)
        # a non-finite component makes the sum non-finite; the exact test runs only then
        # (a finite sum that overflowed is let through by it)
        if not math.isfinite(sum(y)) and not all(math.isfinite(c) for c in y):
            return self._numerical_failure()
        # (integrators return the components of a float state as floats: no conversion)
        self._y = y
        pure = self._pure
        if pure is not None:
            # the task's and system's pure functions (the ones the compiled batch step calls),
            # composed into one generated function: on floats they return floats and bools
            finish, po, pe, pr = pure
            obs, over, reward, terminated, info = finish(y, u_norm, po, pe, pr, self._last_h)
        else:
            obs, over = self._observation(y)
            reward, terminated, metrics = self._evaluate(y, u_norm)
            info = self._info(y, numerical_failure=False, metrics=metrics)
        if event is not None:
            terminated = True
            info["terminal_reason"] = event
        elif over:
            terminated = True
            info["terminal_reason"] = "observation_limit"
            self._plain_advance = False  # outside the bounds the guard's static proof is void
        elif terminated:
            info["terminal_reason"] = "task"
        return obs, reward, terminated, False, info

    # Hooks for systems with internal events and state-dependent stepping (the tippe top);
    # each works on floats (this env) and on arrays (the vector env) alike.
    event_name: str | None = None  # e.g. "lift_off": what _event_mask detects

    # ------------------------------------------------------------------ guarded stepping
    # The step rule (self.step_rule, rbenvs.core.guard) sizes each period from the system's
    # declared rates and the integrator's declared region; no per-env table.
    def _speed_ceiling(self) -> float:
        """An upper bound of ``|Omega|`` over the states inside the observation bounds (``inf``:
        none known); a rule whose ceiling fits in ``substeps`` needs no check."""
        return math.inf

    def internal_steps(self, y, u):
        """Integrator steps per control period at ``y`` under ``u``: ``max(substeps, ceil(x))``
        from the step rule (an int, or an int array for a batch); ``MAX_INTERNAL_STEPS + 1``
        marks a period refused as a numerical failure."""
        return self.step_rule.steps(y, u, self.substeps)

    def _refusal(self, n, where: str = "") -> ValueError:
        """The ``guard="refuse"`` error for a period that needs ``n`` internal steps."""
        return ValueError(
            f"{type(self).__name__}: guard='refuse' and the state{where} needs {n} internal steps per control period, "
            f"more than substeps={self.substeps} (dt={self._dt!r}, integrator {self.integrator.name!r}: "
            f"{self.step_rule.text}); raise substeps to at least {n} or lower dt, or pass guard='subdivide'"
        )

    def _event_mask(self, y, u):
        """Whether the physical event ``event_name`` happened at ``y`` (bool or bool array)."""
        return False

    # ``_after_internal_step(y_prev, y, u, h) -> y``: a hybrid system's switching (the tippe
    # top's lift-off and touchdown) applied after every internal step; ``None`` for smooth ones.
    _after_internal_step = None

    def _advance(self, y, u):
        """Integrate one control period from ``y`` under ``u``: ``(y_new, event)``.

        ``event`` is ``None``, or ``event_name`` when :meth:`_event_mask` fired after an internal
        step (integration stops there), which becomes ``info["terminal_reason"]``.
        """
        integ, system = self.integrator, self.system
        n = self.internal_steps(y, u)
        if n > self.substeps and self.guard == "refuse":
            raise self._refusal(n)
        if n > MAX_INTERNAL_STEPS:
            # a state beyond what the scheme can resolve in a control period: a numerical
            # failure (the episode ends, the last finite state is kept), never a hang
            self._last_h = self._dt / n
            return tuple(math.nan for _ in y), None
        h = self._h if n == self.substeps else self._dt / n
        self._last_h = h
        watch = self.event_name is not None
        post = self._after_internal_step
        for _ in range(n):
            y_prev, y = y, integ.step(system, y, u, h)
            if post is not None:
                y = post(y_prev, y, u, h)
            if watch:
                if not all(math.isfinite(c) for c in y):
                    return y, None
                if self._event_mask(y, u):
                    return y, self.event_name
        return y, None

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
            gym.logger.warn(f"{type(self).__name__}.render() called without a render_mode: pass render_mode='rgb_array' or 'human'")
            return None
        if self._y is None:
            raise RuntimeError("call reset() before render()")
        if self._renderer is None:
            from ..render import Renderer

            self._renderer = Renderer()
        if self.render_mode == "human" and not self._renderer.can_show():
            return None
        frame = self._renderer.frame(self._render_scene())
        if self.render_mode == "rgb_array":
            return frame
        self._renderer.show(frame, self.metadata["render_fps"])
        return None

    def _render_scene(self) -> dict:
        """The geometry of the current state for :meth:`render` (format: :mod:`rbenvs.render.common`)."""
        raise NotImplementedError

    def _step_human(self, action):
        out = type(self).step(self, action)
        self.render()
        return out

    def _reset_human(self, *, seed=None, options=None):
        out = type(self).reset(self, seed=seed, options=options)
        self.render()
        return out

    def close(self):
        renderer = getattr(self, "_renderer", None)
        if renderer is not None:
            renderer.close()
            self._renderer = None
        super().close()

    def __getstate__(self):
        state = self.__dict__.copy()
        state["_renderer"] = None  # a figure (and window) is rebuilt by the next render()
        state["_bound_step"] = None  # generated code: made again on unpickling
        state["_pure"] = None
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._bound_step = self.integrator.bind(self.system, self.system.dim)
        self._pure = self._pure_parts()

    # ------------------------------------------------------------------ state access
    def get_state(self) -> dict[str, np.ndarray]:
        """The physical state as named float64 arrays (copies); see the class docstring."""
        if self._y is None:
            raise RuntimeError("call reset() before get_state()")
        if hasattr(self.system, "export_state"):  # a system whose named state is not slices
            return self.system.export_state(self._y)
        return {name: np.array(self._y[a:b], dtype=np.float64) for name, (a, b) in self.system.layout.items()}

    def _state_from_dict(self, state) -> tuple:
        if hasattr(self.system, "import_state"):
            return self.system.import_state(state)
        if not isinstance(state, dict):
            raise ValueError(f"options['state'] must be a dict of named arrays, got {type(state).__name__}")
        layout = self.system.layout
        unknown = sorted(set(state) - set(layout))
        missing = sorted(set(layout) - set(state))
        if unknown or missing:
            raise ValueError(
                f"state must have exactly the names {sorted(layout)} for this scene"
                + (f"; unknown: {unknown}" if unknown else "")
                + (f"; missing: {missing}" if missing else "")
            )
        comps = [0.0] * self.system.dim
        for name, (a, b) in layout.items():
            arr = real_array(f"state[{name!r}]", state[name])
            if arr.shape != (b - a,):
                raise ValueError(f"state[{name!r}] must have shape ({b - a},), got {arr.shape}")
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"state[{name!r}] must be finite, got {arr}")
            comps[a:b] = (float(x) for x in arr)
        self._check_state(dict((name, real_array(name, state[name])) for name in layout))
        return tuple(comps)

    def _initial_state(self, rng):
        """Components of a random initial state (the task's distribution; subclasses may add
        components the task does not know of, such as an attitude)."""
        return self.task.initial_state(self.system, rng, ())

    def _check_state(self, state):
        """Subclass hook for physical constraints on a state dict (e.g. unit quaternions)."""

    # ------------------------------------------------------------------ helpers
    # The single-env step path works on Python floats: for a handful of numbers, list and
    # math operations cost a fraction of numpy's per-call overhead (rbenvs bench throughput).
    def _action_values(self, action) -> list[float]:
        """The action as a list of Python floats, validated (type, shape, finite) and clipped to [-1, 1]."""
        if type(action) is np.ndarray and action.shape == self.action_space.shape and action.dtype in _REAL_FLOATS:
            values = action.tolist()
            # the common case in three builtins: every entry in [-1, 1] and the sum finite (min
            # and max may step over a NaN, the sum cannot); anything else goes the long way
            if -1.0 <= min(values) and max(values) <= 1.0 and math.isfinite(sum(values)):
                return values
        else:
            arr = action_array(action, self.action_space.shape)
            values = arr.tolist()
        out = []
        for v in values:
            v = float(v)
            if not math.isfinite(v):
                raise ValueError(f"action must be finite, got {action!r}")
            # Out-of-range actions are clipped to the action space (documented).
            out.append(-1.0 if v < -1.0 else (1.0 if v > 1.0 else v))
        return out

    def _observation(self, y):
        o = self.task.observe(self.system, y)
        hi = self._obs_high_uniform
        if hi is not None:  # one bound for every component: two builtin calls
            over = not (-hi <= min(o) and max(o) <= hi)
        else:
            over = False
            for v, hi in zip(o, self._obs_high_list):
                if not -hi <= v <= hi:
                    over = True
                    break
        if over:
            return np.clip(np.asarray(o, dtype=np.float64), -self._obs_high, self._obs_high).astype(np.float32), True
        return np.array(o, dtype=np.float32), False

    def _numerical_failure(self):
        warnings.warn(
            f"{type(self).__name__}: the state became non-finite with integrator {self.integrator.name!r} "
            f"(internal step h = {float(np.max(self._last_h)):g} s); the episode ends and the last finite state is kept",
            NumericalFailureWarning,
            stacklevel=3,
        )
        obs, _ = self._observation(self._y)
        info = self._info(self._y, numerical_failure=True)
        info["terminal_reason"] = "numerical_failure"
        return obs, 0.0, True, False, info

    def _evaluate(self, y, u_norm):
        """``(reward, terminated, metrics)`` as Python float, bool and dict. A task may offer
        ``evaluate`` to compute the three at once (sharing its intermediate read-outs)."""
        task, system = self.task, self.system
        evaluate = self._task_evaluate
        if evaluate is not None:
            reward, terminated, metrics = evaluate(system, y, u_norm)
        else:
            reward = task.reward(system, y, u_norm)
            terminated = task.terminated(system, y)
            metrics = task.metrics(system, y)
        return float(reward), bool(terminated), metrics

    def _evaluate_batch(self, y, u_norm):
        """:meth:`_evaluate` for a batch of states (arrays, no conversion to Python types)."""
        task, system = self.task, self.system
        evaluate = getattr(task, "evaluate", None)
        if evaluate is not None:
            return evaluate(system, y, u_norm)
        return task.reward(system, y, u_norm), task.terminated(system, y), task.metrics(system, y)

    def _info(self, y, numerical_failure: bool, metrics=None) -> dict:
        info = self._readouts(y)
        info.update(self.task.metrics(self.system, y) if metrics is None else metrics)
        for name, v in info.items():
            if type(v) is not float and type(v) is not bool:
                info[name] = _to_python(v)
        info["numerical_failure"] = numerical_failure
        return info

    def _readouts(self, y, physical=None) -> dict:
        """The physical read-outs of ``info``: a system with pure read-outs (``kernel_readouts``
        and ``readout_names``) gives them, plus the last internal step; other envs override.
        ``physical``: the system's values already computed (the compiled batch step)."""
        f, p = self.system.kernel_readouts
        info = dict(zip(self.system.readout_names, f(p, y) if physical is None else physical))
        info["internal_step"] = self._last_h
        return info

    def _pure_parts(self):
        """``(finish, PO, PE, PR)`` (:func:`rbenvs.compiled.state_finish` and its parameters)
        when the task and the system have pure forms and the env's read-outs are the base
        class's; ``None`` otherwise (the step then goes through the methods)."""
        kernels = getattr(self.task, "kernels", None)
        readouts = getattr(self.system, "kernel_readouts", None)
        if kernels is None or readouts is None or type(self)._readouts is not RigidBodyEnv._readouts:
            return None
        (observe, po), (evaluate, pe) = kernels(self.system)
        f, pr = readouts
        high = tuple(self._obs_high_list)
        finish = state_finish(observe, len(high), evaluate, tuple(self.task.metric_names), f, tuple(self.system.readout_names), high)
        return finish, po, pe, pr

    def _kernel_parts(self):
        """What :func:`rbenvs.compiled.batch_kernel` needs to run this env's step on a batch:
        ``(step, observe, evaluate, readouts, guard)``, each ``(pure function, parameters)``
        (``guard``: ``((step_ratio, G), (rotation rate, P))``, or ``None`` without a guard
        check), or ``None`` where a part has no pure form (then the batch runs on numpy
        arrays). The kernel takes ``substeps`` equal steps: a guarded period that needs more
        goes back to the numpy path; events and hybrid switching (the tippe top) never
        compile."""
        step = self.integrator.kernel_step(self.system)
        kernels = getattr(self.task, "kernels", None)
        readouts = getattr(self.system, "kernel_readouts", None)
        hybrid = self.event_name is not None or self._after_internal_step is not None
        if step is None or kernels is None or readouts is None or hybrid:
            return None
        guard = None
        rule = self.step_rule
        if rule.active and not self._plain_default:
            if rule.dissipation is not None:
                return None  # a rate that depends on the control: not in the kernel yet
            guard = ((step_ratio, rule.params), rule.rotation)
        observe, evaluate = kernels(self.system)
        return step, observe, evaluate, readouts, guard

    def _control(self, a):
        raise NotImplementedError


def _to_python(v):
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):  # counts stay counts
        return int(v)
    return float(v)

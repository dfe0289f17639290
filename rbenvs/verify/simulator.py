"""The simulator under test: the adapters for rbenvs' own integrators and for a plain Python
step function (docs/verification.md, "Any simulator"), and the parser of ``--simulator``; the
contract they meet is :mod:`rbenvs.verify.protocol`. MuJoCo's adapter is
:mod:`rbenvs.verify.mujoco_adapter`, imported only when named.

The states, controls and declining rules every adapter follows are the contract's
(:mod:`rbenvs.verify.protocol`).
"""

from __future__ import annotations

import importlib
import math
import os
import sys
from collections.abc import Callable

import numpy as np

from ..integrators import Integrator, get_integrator
from .protocol import (
    ManyStepsRun,
    Problem,
    Run,
    Simulator,
    batched,
    no_more_options,
    take_option,
)

__all__ = [
    "Problem",
    "Run",
    "Simulator",
    "IntegratorSimulator",
    "CallableSimulator",
    "problem_of",
    "advance",
    "start",
    "as_simulators",
    "parse_simulator",
    "take_option",
    "no_more_options",
    "ADAPTERS",
    "LAYOUTS",
    "SimulatorFunctionError",
]


def problem_of(model) -> Problem:
    """The :class:`Problem` of an rbenvs system object (a subclass of one, as the tests' broken
    simulators are, or one wrapped in the hybrid layer's :class:`rbenvs.core.hybrid.Switching`)."""
    from ..core.hybrid import Switching
    from ..dynamics import FreeBody, HeavyTop, TippeTop

    base = model.system if isinstance(model, Switching) else model
    for name, cls in (("free_body", FreeBody), ("heavy_top", HeavyTop), ("tippe_top", TippeTop)):
        if isinstance(base, cls):
            fidelity = base.fidelity if isinstance(base, TippeTop) else None
            return Problem(name, base.params, fidelity, model)
    raise TypeError(f"not an rbenvs system: {type(base).__name__}")


def advance(run, n: int, u, h: float):
    """``n`` steps of ``h`` under ``u``; the last state (a run's own ``advance`` when it has one:
    an engine may step many times per call)."""
    if isinstance(run, ManyStepsRun):
        return run.advance(n, u, h)
    y = None
    for _ in range(n):
        y = run.step(u, h)
    return y


def start(sim: Simulator, model, y0) -> Run:
    """``sim``'s run of the system ``model`` from ``y0``; components that are arrays (a batch) go
    to an adapter that is not ``batched`` column by column."""
    problem = problem_of(model)
    if batched(sim) or all(isinstance(c, float) for c in y0):
        return sim.start(problem, tuple(y0))
    columns = np.broadcast_arrays(*(np.asarray(c, dtype=float) for c in y0))
    shape = columns[0].shape
    runs = [sim.start(problem, tuple(float(c[i]) for c in columns)) for i in np.ndindex(shape)]
    return _Columns(runs, shape)


class _Columns:
    """Runs of single states stepped together, their states returned as arrays."""

    def __init__(self, runs, shape):
        self.runs, self.shape = runs, shape

    def step(self, u, h):
        return self._stack([r.step(u, h) for r in self.runs])

    def advance(self, n, u, h):
        return self._stack([advance(r, n, u, h) for r in self.runs])

    def _stack(self, states):
        return tuple(np.array(c).reshape(self.shape) for c in zip(*states))


# ------------------------------------------------------------------------------------------
# rbenvs' own integrators


class _IntegratorRun:
    def __init__(self, integrator, model, y0):
        self.integrator, self.model, self.y = integrator, model, y0

    def step(self, u, h):
        self.y = self.integrator.step(self.model, self.y, u, h)
        return self.y


class IntegratorSimulator:
    """rbenvs' own ``integrator`` (a name or an :class:`~rbenvs.integrators.Integrator`) on
    rbenvs' own system objects: ``integrator.step(model, y, u, h)``. ``dt=None``: the checks
    choose the steps and hold it to its settings' tolerances (``rbenvs verify``'s default table);
    a ``dt`` runs it like any other engine at that step."""

    batched = True

    def __init__(self, integrator, dt: float | None = None):
        self.integrator: Integrator = get_integrator(integrator)
        self.dt = None if dt is None else float(dt)
        self.order = self.integrator.order
        self.name = (
            self.integrator.name if dt is None else f"rbenvs {self.integrator.name} dt={dt:g}"
        )

    def start(self, problem: Problem, y0) -> Run:
        model = problem.model
        if not self.integrator.supports(model):
            raise NotImplementedError(
                f"{self.integrator.name} needs {list(self.integrator.requires)}, which this system "
                "lacks"
            )
        return _IntegratorRun(self.integrator, model, y0)


# ------------------------------------------------------------------------------------------
# a plain step function


# the state each system's step function receives and returns: one flat tuple of floats
LAYOUTS = {
    "free_body": "(Pi1, Pi2, Pi3)",
    "heavy_top": "(Pi1, Pi2, Pi3, Gamma1, Gamma2, Gamma3)",
    "tippe_top": (
        "(x, y, vx, vy, qw, qx, qy, qz, W1, W2, W3) (rolling: (x, y, qw, qx, qy, qz, W1, W2, W3))"
    ),
}


class SimulatorFunctionError(ValueError):
    """A user's step function raised, or returned something other than a state: the message names
    the function, the call, what was expected and what came back, with the function's own
    traceback lines (a ``ValueError``: the command line prints it as the user's error)."""


def _user_frames(error: BaseException) -> str:
    """The traceback lines of ``error`` from the user's code (rbenvs' own frames left out)."""
    import os
    import traceback

    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    frames = [
        f
        for f in traceback.extract_tb(error.__traceback__)
        if not os.path.abspath(f.filename).startswith(here)
    ]
    return "".join(traceback.format_list(frames)) + "".join(
        traceback.format_exception_only(type(error), error)
    )


class _CallableRun:
    def __init__(self, fn, name, problem, y0):
        self.fn, self.name, self.problem, self.y = fn, name, problem, tuple(float(c) for c in y0)

    def step(self, u, h):
        call = f"{self.name}(problem[{self.problem.system}], y, u, {h:g})"
        try:
            out = self.fn(self.problem, self.y, u, h)
        except NotImplementedError:
            raise
        except Exception as error:
            raise SimulatorFunctionError(
                f"the simulator function {call} raised {type(error).__name__}; its "
                f"traceback:\n{_user_frames(error)}"
            ) from error
        expected = f"a flat tuple of {len(self.y)} floats {LAYOUTS[self.problem.system]}"
        try:
            y = tuple(float(c) for c in out)
        except (TypeError, ValueError):
            y = None
        if y is None or len(y) != len(self.y):
            raise SimulatorFunctionError(
                f"the simulator function {call} returned {_short(out)}: expected {expected}"
            )
        self.y = y
        return y


def _short(value) -> str:
    text = repr(value)
    return (text if len(text) <= 200 else text[:200] + "...") + f" ({type(value).__name__})"


class CallableSimulator:
    """A user's engine as one function ``step(problem, y, u, dt) -> y`` (a :class:`Problem`, a
    state tuple in rbenvs' layout, the control, the step), at a fixed ``dt`` with a declared
    ``order``. The function raises ``NotImplementedError`` for what it does not model (its rows
    read ``n/a``). It keeps no state between calls: each call gets the state it returned last."""

    def __init__(self, fn: Callable, dt: float = 1e-3, order: int = 1, name: str | None = None):
        if not callable(fn):
            raise ValueError(f"a simulator function must be callable, got {fn!r}")
        if not (dt > 0.0 and math.isfinite(dt)):
            raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
        self.fn, self.dt, self.order = fn, float(dt), int(order)
        self.name = name or f"{getattr(fn, '__name__', 'callable')} dt={dt:g}"

    def start(self, problem: Problem, y0) -> Run:
        return _CallableRun(self.fn, self._qualname, problem, y0)

    @property
    def _qualname(self) -> str:
        return (
            f"{getattr(self.fn, '__module__', '?')}."
            f"{getattr(self.fn, '__qualname__', getattr(self.fn, '__name__', repr(self.fn)))}"
        )


# ------------------------------------------------------------------------------------------
# by name


def as_simulators(items) -> list:
    """Integrator names, :class:`~rbenvs.integrators.Integrator` objects and simulators, as
    simulators."""
    return [item if isinstance(item, Simulator) else IntegratorSimulator(item) for item in items]


def _options(text: str) -> dict[str, str]:
    out = {}
    for part in filter(None, text.split(",")):
        key, sep, value = part.partition("=")
        if not sep or not key.strip():
            raise ValueError(
                f"simulator options are key=value pairs separated by commas, got {part!r}"
            )
        out[key.strip()] = value.strip()
    return out


def _rbenvs(options) -> list:
    names = take_option(options, "integrator", str, None)
    dt = take_option(options, "dt", float, None)
    no_more_options(options, "rbenvs")
    from ..integrators import INTEGRATORS

    return [IntegratorSimulator(name, dt) for name in (names.split("+") if names else INTEGRATORS)]


def _mujoco(options) -> list:
    from ..extras import require

    require("mujoco")
    from .mujoco_adapter import (
        mujoco_simulators,
    )  # the only import of the mujoco adapter (and of mujoco)

    return mujoco_simulators(options)


ADAPTERS: dict[str, Callable[[dict], list]] = {"rbenvs": _rbenvs, "mujoco": _mujoco}


def parse_simulator(spec: str) -> list:
    """The simulators a ``--simulator`` argument names:

    * ``rbenvs[:integrator=rk4+euler,dt=1e-3]``: rbenvs' own integrators (all by default; without
      ``dt`` at their verify settings, as the default table);
    * ``mujoco[:integrator=RK4+implicitfast,dt=1e-3,...]``: MuJoCo
      (:mod:`rbenvs.verify.mujoco_adapter`);
    * ``module:function[,dt=1e-3,order=1,name=...]``: a step function ``f(problem, y, u, dt)``
      (:class:`CallableSimulator`), or an object that already is a :class:`Simulator`.
    """
    head, _, tail = spec.partition(":")
    if head in ADAPTERS:
        return ADAPTERS[head](_options(tail))
    if not tail:
        raise ValueError(
            f"simulator must be one of {sorted(ADAPTERS)} or module:function, got {spec!r}"
        )
    attr, _, rest = tail.partition(",")
    options = _options(rest)
    # the current folder, as `python -m rbenvs` has it (an installed `rbenvs` script does not)
    if "" not in sys.path and os.getcwd() not in sys.path:
        sys.path.insert(0, os.getcwd())
    try:
        target = importlib.import_module(head)
    except ImportError as exc:
        raise ValueError(f"simulator {spec!r}: cannot import {head!r} ({exc})") from None
    obj = target
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise ValueError(f"simulator {spec!r}: {head!r} has no attribute {attr!r}")
        obj = getattr(obj, part)
    if isinstance(obj, Simulator):
        no_more_options(options, spec)
        return [obj]
    sim = CallableSimulator(
        obj,
        dt=take_option(options, "dt", float, 1e-3),
        order=take_option(options, "order", int, 1),
        name=take_option(options, "name", str, None),
    )
    no_more_options(options, spec)
    return [sim]

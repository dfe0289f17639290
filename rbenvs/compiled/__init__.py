"""Optional compiled batch step (numba): the package's own functions, compiled, in one call.

The package by concern: :mod:`.batch` (a batch's period and finish, its lines and layout),
:mod:`.vector` (the vector env's whole step and its split over threads), :mod:`.state` (one
state's step, runs and plans) and :mod:`.steps` (the kernels with their parameters, as the
engine and the envs call them).

Why: a numpy step of a batch is one array operation per arithmetic line, each mostly dispatch,
and an RK4 step with its reward, observation and read-outs is many of them
(``rbenvs bench throughput`` prints both paths). Compiled, a vector env's whole step is one call
(:func:`vector_kernel`): the actions checked, clipped and mapped by the actuator, the guard's
check where the env has one, the period (the physics as passes over the batch, in SIMD
registers), one loop per read-out stage, the episode clocks and end reasons, and the restarts
of the sub-envs whose episodes ended, drawn from their own generators. :func:`batch_kernel` is
the period and finish alone (what ``rbenvs bench throughput`` times as the kernel),
:func:`state_kernel` the same for one state (the single env's compiled step), and
:func:`run_kernel` one state's internal steps with a given count and step (``tolerance_check``'s
runs: :class:`CheckedRuns`; :func:`runs_kernel` a batch's, sub-env by sub-env), from the same lines.

Every loop is written so that LLVM keeps it in SIMD registers: no call inside (libm's
``sin``/``cos`` replaced by :func:`rbenvs.rotations.sincos`, branches that hold a call
specialised away), selections instead of branches (the compiled forms of
:mod:`rbenvs.jit`), unit-stride loads and stores (the observation goes through scratch
rows), and the same run-time alias checks LLVM needs allowed (:data:`LLVM_OPTIONS`).

The same pure parts also make the single env's read-out function
(:func:`rbenvs.core.finish.state_finish`):
plain Python, generated per layout, one call instead of a method per part.

What is compiled is not a second implementation. The pure functions the single env runs on
Python floats (a system's vector field, a task's reward and observation, a system's read-outs)
are marked :func:`jitable`; that marker leaves each of them the plain Python function it was
(no call overhead on the single-env path) and, when numba is installed, registers it so that
compiled code may call it. The integrator step is the one generated per scheme and dimension
(:mod:`rbenvs.integrators.runge_kutta`). The only new code here is the batch loop that calls
them: generated per layout (state size, observation size, number of metrics and read-outs).
numba compiles float arithmetic in source order without contraction into fused multiply-adds
(no ``fastmath``), and ``sqrt`` is correctly rounded, so a compiled sub-env follows the single
env bit for bit (tested).

numba is optional (the ``fast`` extra); without it, or with ``RBENVS_COMPILED=0`` in the
environment, the vector env runs the same functions on numpy arrays. A kernel is compiled on
first use in a process (``rbenvs bench startup`` times it) and reused by every env of the same
layout.
"""

from __future__ import annotations

from ..jit import DISABLE_VARIABLE, available, jitable
from .batch import (
    KERNEL_OPTIONS,
    LLVM_OPTIONS,
    NO_COMPENSATION,
    Layout,
    batch_kernel,
    finish_kernel,
)
from .state import plan_kernel, plans_kernel, run_kernel, runs_kernel, state_kernel
from .steps import (
    Backend,
    BatchResult,
    BatchStep,
    CheckedRuns,
    PeriodPlan,
    StateStep,
    VectorResult,
    VectorStep,
)
from .vector import VectorLayout, flat_leaves, rows_kernel, split_kernel, tuple_shape, vector_kernel

__all__ = [
    "jitable",
    "available",
    "Layout",
    "VectorLayout",
    "batch_kernel",
    "vector_kernel",
    "rows_kernel",
    "finish_kernel",
    "state_kernel",
    "run_kernel",
    "runs_kernel",
    "CheckedRuns",
    "plan_kernel",
    "plans_kernel",
    "PeriodPlan",
    "BatchStep",
    "BatchResult",
    "VectorStep",
    "VectorResult",
    "StateStep",
    "DISABLE_VARIABLE",
    "LLVM_OPTIONS",
    "Backend",
    "KERNEL_OPTIONS",
    "NO_COMPENSATION",
    "split_kernel",
    "tuple_shape",
    "flat_leaves",
]

"""``rbenvs bench throughput``: env-steps per second, with gymnasium's own envs measured beside.

The headline, the **task table** (printed first): one row per registered id and task at the
env's defaults, and one per named scene (``configs/scenes``, each an id with keyword
arguments; needs the ``cli`` extra for PyYAML). Every row is measured from what the env
declares (its tasks, its path, its kernel), nothing listed here by hand:

* ``single us`` and ``/Pend``: one ``env.step`` of ``gymnasium.make(id, **kwargs)`` (wrappers
  included, as users call it; zero action, resets included) against ``Pendulum-v1`` measured
  interleaved in the same run; the ratio is the cost of one of our steps in Pendulum steps.
* ``N``, ``path``: the vector env (``gymnasium.make_vec(..., vectorization_mode=
  "vector_entry_point")``) at ``num_envs = N`` (``--num-envs``, 4096 by default) and whether
  its step runs compiled (:mod:`rbenvs.compiled`) or on numpy arrays.
* ``zero/s``: env-steps per second with zero action from a fresh reset (every episode clock
  at 0: an episode ends in the window only where the window reaches the time limit).
* ``random/s``, ``ends``, ``/Cart``: env-steps per second with actions drawn uniformly in
  [-1, 1] from a seeded generator beforehand (a pool of batches, cycled), so episodes end by
  termination and truncation and sub-envs restart inside the timed window; ``ends`` counts the
  episode ends the reported window crossed. The sub-envs' episode clocks are first spread
  uniformly over ``max_episode_steps`` (the steady state of a long run whose sub-envs have
  drifted apart, as termination makes them: every step truncates and restarts about
  ``N / max_episode_steps`` of them besides those that terminate). ``/Cart`` is this rate over
  CartPole-v1's native vector env at the same N, stepped the same way (random actions from a
  seeded pool, its own resets included: its episodes end every few dozen steps), in the same run:
  ours and CartPole are timed in turn, ``ALTERNATIONS`` rounds, and the best of each is kept
  (on a shared host the speed drifts within seconds).
* ``sync/s``, ``/Cart``: the same random actions from ``reset(seed)`` with every clock at 0,
  as a run whose episodes only end at the time limit keeps them: all sub-envs restart together
  once an episode (the window holds such a step only where it reaches the time limit;
  ``sync_episode_ends`` in the JSON).
* ``numpy/s``, ``c/np``: for a setting that runs compiled, the same env with
  ``compiled=False`` under the same actions and clocks, and the compiled/numpy ratio.
* ``kernel ns``, ``gap``: the compiled :class:`rbenvs.compiled.BatchStep` alone (the
  practical limit of a step: the physics, observation, reward and read-outs in one compiled
  call, without the Python around it), called on the env's current states with the controls
  of a fixed random action batch, the env's internal step and substeps, and the guard checked
  per sub-env where the env's periods are not plain (as the env calls it), in ns per
  env-step; ``gap`` is the env's random-action time per env-step over it (``gap_zero`` in the
  JSON: the zero-action time over it). The kernel writes new arrays only: the env's state is
  checked unchanged after it (a ``!`` and a line say otherwise). A setting with no compiled
  step shows ``-`` and a footnote with the env's own reason (the ``ValueError`` of
  ``compiled=True``).

``--only SUBSTRING`` keeps the rows whose label, id, task, scene name (or, in the integrator
tables, integrator) contains it, in any case; ``--tables`` picks the tables (below).

Slow settings (a vector step longer than the timing window, such as the stiff tippe top at
4096) are timed with fewer calls: at least one full call per round, best of as many rounds as
fit a per-figure budget (one second). ``--quick`` is a smoke run (rough figures, most of its
time compiling kernels): the task table at N = 64 with short windows, a setting whose single
step costs over a millisecond (the tippe top) at N = 8, and the SB3 rows.

The other tables follow (not with ``--quick`` unless ``--tables`` names them):

* ``integrators``: for every system and integrator (default scene, zero action), the single
  env against Pendulum-v1 as above, and the vector env for N = 1, 16, 256, 4096 against
  CartPole-v1's native vector env (constant action) at the same N; ``ns/env`` the time per
  env-step. Extra lines: the free body with rk4 on the numpy path (with the compiled/numpy
  ratio per N: what the compiler buys), and with ``info_readouts=False`` ("lean info").
* ``scaling`` (not with ``--quick``): the free body with rk4 on each path from 1 to 65536
  sub-envs, with the bytes of arrays one step moves per env.
* ``sb3`` (when stable-baselines3 is installed): SB3's ``VecEnv.step`` through the native
  adapter against ``DummyVecEnv`` of single envs, at N = 16 and 256.
* ``check``: what ``tolerance_check=True`` costs in time (rk4, ``tolerance=1e-6``, zero action): one
  step of the single env without the check, with it (its runs compiled:
  :class:`rbenvs.compiled.CheckedRuns`) and with it on floats (``compiled=False``), against
  Pendulum-v1 interleaved; and the vector env at N = 8 and 256 without the check (compiled) and
  with it, its runs compiled (one loop over the sub-envs) and on numpy, against CartPole-v1 at
  the same N. The free body, the heavy top, the tippe top
  and the hopping scene (``tippe_hop``, the check's case).

In the integrator table the time limit ends all sub-envs of the default scene together, so a
step's true cost includes 1/400 of resetting every sub-env; ``min_time`` spans several episode
ends at the larger N there.

Throughput per env grows with N while the fixed cost per call dominates (Python glue, and on
the numpy path the dispatch of each of a step's many array operations), and flattens once the
arrays a step moves stop fitting in the caches: the scaling table prints those bytes per env
beside the time, to read against the machine's L2 and L3 sizes.

Each figure is the best of ``repeat`` timings of at least ``min_time`` seconds or one call.
``--json PATH`` writes every row of every table.

The package by concern: :mod:`.runs` (timing, the integrator, scaling, SB3 and check
tables), :mod:`.tasks` (the task table) and :mod:`.command` (the command line).
"""

from __future__ import annotations

from .command import main
from .runs import (
    compiled_speedup,
    print_check,
    run_check,
    run_sb3,
    run_scaling,
    run_single,
    run_vector,
)
from .tasks import kernel_time, measure_setting, print_tasks, run_tasks, task_settings
from .timing import (
    ALTERNATIONS,
    Peers,
    counting_stepper,
    episode_stepper,
    random_actions,
    stagger_clocks,
    timed,
    timed_budget,
    timed_counting,
)

__all__ = [
    "run_tasks",
    "task_settings",
    "measure_setting",
    "kernel_time",
    "stagger_clocks",
    "random_actions",
    "counting_stepper",
    "print_tasks",
    "run_single",
    "run_vector",
    "run_scaling",
    "run_sb3",
    "run_check",
    "print_check",
    "timed",
    "timed_budget",
    "episode_stepper",
    "main",
    "ALTERNATIONS",
    "Peers",
    "compiled_speedup",
    "timed_counting",
]

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
  (on a shared host the speed drifts by tens of percent within seconds).
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
about 0.3 s per step at 4096) are timed with fewer calls: at least one full call per round,
best of as many rounds as fit a per-figure budget (one second). ``--quick`` is a smoke run
(rough figures, well under a minute here, most of it compiling kernels): the task table at
N = 64 with short windows, a setting whose single step costs over a millisecond (the tippe
top) at N = 8, and the SB3 rows.

The earlier tables follow (not with ``--quick`` unless ``--tables`` names them):

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
the numpy path about a microsecond of dispatch per array operation, some 150 of them per
free-body step), and flattens once the arrays a step moves stop fitting in the caches: the
scaling table prints those bytes per env beside the time, to read against the machine's L2
and L3 sizes.

Each figure is the best of ``repeat`` timings of at least ``min_time`` seconds or one call.
``--json PATH`` writes every row of every table.
"""

from __future__ import annotations

import json
import time
import warnings

import numpy as np

from ..compiled import available
from ..extras import ArgumentParser
from ..progress import Progress

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
]

SIZES = (1, 16, 256, 4096)
# (id, integrators, largest N measured per integrator: the reference solver is slow in bulk)
SYSTEMS = (
    ("rbenvs/FreeRigidBody-v0", ("euler", "rk4", "splitting", "exact", "dop853")),
    ("rbenvs/LagrangeTop-v0", ("euler", "rk4", "splitting", "dop853")),
    ("rbenvs/TippeTop-v0", ("euler", "rk4", "dop853")),
)
LARGEST = {"dop853": 256, "exact": 4096}


def _accuracy(integrator: str) -> dict:
    """Euler runs unchecked (``tolerance=None``): the default accuracy refuses a scheme whose
    error it cannot estimate; every other scheme runs at its default."""
    return {"tolerance": None} if integrator == "euler" else {}


def timed(fn, min_time: float, repeat: int) -> float:
    """Best seconds per call of ``fn`` over ``repeat`` rounds of at least ``min_time``."""
    best = float("inf")
    for _ in range(repeat):
        calls, start = 0, time.perf_counter()
        while True:
            fn()
            calls += 1
            elapsed = time.perf_counter() - start
            if elapsed >= min_time:
                break
        best = min(best, elapsed / calls)
    return best


def timed_budget(fn, min_time: float, repeat: int, budget: float | None = None) -> float:
    """:func:`timed`, but where one call alone outlasts ``min_time``, as many one-call rounds
    as fit ``budget`` seconds (at least one; the probing call is the first round). Without
    ``budget``, :func:`timed` itself."""
    if budget is None:
        return timed(fn, min_time, repeat)
    t = _time_once(fn)
    if t <= min_time:
        return timed(fn, min_time, repeat)
    for _ in range(_rounds(t, min_time, repeat, budget) - 1):
        t = min(t, _time_once(fn))
    return t


def _rounds(t_call: float, min_time: float, repeat: int, budget: float) -> int:
    """Rounds for a figure whose call takes ``t_call`` seconds: ``repeat``, or as many as fit
    ``budget`` where one call alone outlasts ``min_time`` (at least one)."""
    if t_call <= min_time:
        return repeat
    return max(1, min(repeat, int(budget // t_call)))


def _time_once(fn) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def episode_stepper(env, action):
    """A step function that resets the env when its episode ends (not timed separately)."""
    state = {"done": False}

    def step():
        if state["done"]:
            env.reset()
        _, _, terminated, truncated, _ = env.step(action)
        state["done"] = terminated or truncated

    return step


def run_single(systems=SYSTEMS, min_time=0.2, repeat=5, progress=None, budget=None) -> list[dict]:
    """One step of ``gymnasium.make(id, integrator=...)`` against Pendulum-v1, interleaved.
    ``budget`` (seconds): where one step outlasts a round, fewer rounds (:func:`timed_budget`)."""
    import gymnasium as gym

    import rbenvs  # noqa: F401

    pendulum = gym.make("Pendulum-v1")
    pendulum.reset(seed=0)
    p_step = episode_stepper(pendulum, np.zeros(1, dtype=np.float32))
    rows = []
    for env_id, integrators in systems:
        for integ in integrators:
            env = gym.make(env_id, integrator=integ, **_accuracy(integ))
            env.reset(seed=0)
            ours = episode_stepper(env, np.zeros(env.action_space.shape, dtype=np.float32))
            t_ours, t_pend, rounds = float("inf"), float("inf"), repeat
            if budget is not None:  # a probing call; a slow one is the first round
                t1 = _time_once(ours)
                if t1 > min_time / repeat:
                    t_ours, rounds = t1, _rounds(t1, min_time / repeat, repeat, budget) - 1
            for k in range(max(rounds, 1)):  # interleaved, so that machine load hits both alike
                if k < rounds:
                    t_ours = min(t_ours, timed(ours, min_time / repeat, 1))
                t_pend = min(t_pend, timed(p_step, min_time / repeat, 1))
            rows.append(
                {
                    "id": env_id,
                    "integrator": integ,
                    "step_us": t_ours * 1e6,
                    "pendulum_step_us": t_pend * 1e6,
                    "ratio_to_pendulum": t_ours / t_pend,
                }
            )
            if progress:
                progress()
    return rows


def run_vector(
    systems=SYSTEMS, sizes=SIZES, min_time=0.2, repeat=3, progress=None, budget=None
) -> list[dict]:
    """The vector env per system, integrator and N against CartPole-v1's (constant action).
    ``budget`` (seconds): where one step outlasts ``min_time``, fewer rounds
    (:func:`timed_budget`)."""
    import gymnasium as gym

    import rbenvs  # noqa: F401

    cart_rate = {}
    for n in sizes:
        cart = gym.make_vec("CartPole-v1", num_envs=n, vectorization_mode="vector_entry_point")
        cart.reset(seed=0)
        a = np.ones(n, dtype=np.int64)
        cart_rate[n] = n / timed(lambda: cart.step(a), min_time, repeat)
        cart.close()
    rows = []
    # (id, integrator, info read-outs, compiled): every combination on the path it takes by
    # default; the free body with rk4 also on the numpy path (the compiled kernel's
    # justification, measured) and without info's physical read-outs
    combos = [
        (env_id, integ, True, "auto") for env_id, integrators in systems for integ in integrators
    ]
    for env_id, integrators in systems:
        if env_id == SYSTEMS[0][0] and "rk4" in integrators:
            # (without numba the default rows are the numpy path already)
            combos += [(env_id, "rk4", True, False)] if available() else []
            combos += [(env_id, "rk4", False, "auto")]
    for env_id, integ, readouts, compiled in combos:
        for n in sizes:
            if n > LARGEST.get(integ, max(sizes)):
                continue
            venv = gym.make_vec(
                env_id,
                num_envs=n,
                vectorization_mode="vector_entry_point",
                integrator=integ,
                info_readouts=readouts,
                compiled=compiled,
                **_accuracy(integ),
            )
            path = "compiled" if venv.unwrapped.compiled else "numpy"
            venv.reset(seed=0)
            a = np.zeros(venv.action_space.shape, dtype=np.float32)
            venv.step(a)  # a kernel compiles on its first call: not timed
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                t = timed_budget(lambda: venv.step(a), min_time, repeat, budget)
            rate = n / t
            label = integ if readouts else f"{integ}, lean info"
            rows.append(
                {
                    "id": env_id,
                    "integrator": label,
                    "path": path,
                    "num_envs": n,
                    "env_steps_per_s": rate,
                    "ns_per_env_step": 1e9 * t / n,
                    "cartpole_env_steps_per_s": cart_rate[n],
                    "ratio_to_cartpole": rate / cart_rate[n],
                }
            )
            venv.close()
            if progress:
                progress()
    return rows


SCALING_SIZES = (1, 16, 256, 1024, 4096, 16384, 65536)


def run_scaling(sizes=SCALING_SIZES, min_time=0.2, repeat=3, progress=None) -> list[dict]:
    """The free body with rk4 from 1 to 65536 sub-envs on each path: time per env-step and
    the bytes of arrays one step reads and writes per env (state in and out, actions, every
    output array), to see where the per-env cost stops falling and why."""
    import gymnasium as gym

    import rbenvs  # noqa: F401

    env_id = SYSTEMS[0][0]
    rows = []
    for compiled in ([True] if available() else []) + [False]:
        for n in sizes:
            venv = gym.make_vec(
                env_id, num_envs=n, vectorization_mode="vector_entry_point", compiled=compiled
            )
            venv.reset(seed=0)
            a = np.zeros(venv.action_space.shape, dtype=np.float32)
            obs, reward, terminated, truncated, info = venv.step(a)
            state = sum(v.nbytes for v in venv.unwrapped.get_state().values())
            arrays = [obs, reward, terminated, truncated, a] + [
                v for v in info.values() if isinstance(v, np.ndarray)
            ]
            moved = 2 * state + sum(x.nbytes for x in arrays)
            t = timed(lambda: venv.step(a), min_time, repeat)
            rows.append(
                {
                    "path": "compiled" if compiled else "numpy",
                    "num_envs": n,
                    "ns_per_env_step": 1e9 * t / n,
                    "bytes_per_env_step": moved / n,
                    "megabytes_per_step": moved / 1e6,
                }
            )
            venv.close()
            if progress:
                progress()
    return rows


def run_sb3(sizes=(16, 256), min_time=0.2, repeat=3) -> list[dict]:
    """SB3's ``VecEnv.step`` on the native adapter against ``DummyVecEnv`` of single envs
    (the free body, rk4). Empty when stable-baselines3 (the agents extra) is not installed."""
    try:
        from stable_baselines3.common.env_util import make_vec_env

        from ..vector.sb3 import make_sb3_vec_env
    except ImportError:
        return []
    env_id = "rbenvs/FreeRigidBody-v0"
    rows = []
    for n in sizes:
        native = make_sb3_vec_env(env_id, n, seed=0)
        dummy = make_vec_env(env_id, n_envs=n, seed=0, env_kwargs={"render_mode": None})
        rates = []
        for venv in (native, dummy):
            venv.reset()
            a = np.zeros((n,) + venv.action_space.shape, dtype=np.float32)
            rates.append(n / timed(lambda: venv.step(a), min_time, repeat))
            venv.close()
        rows.append(
            {
                "id": env_id,
                "num_envs": n,
                "sb3_native_env_steps_per_s": rates[0],
                "sb3_dummy_env_steps_per_s": rates[1],
                "ratio": rates[0] / rates[1],
            }
        )
    return rows


CHECK_TOLERANCE = 1e-6
CHECK_NUM_ENVS = (8, 256)
# (label, id, scene or None): the check table's settings
CHECK_SETTINGS = (
    ("free body", "rbenvs/FreeRigidBody-v0", None),
    ("heavy top", "rbenvs/LagrangeTop-v0", None),
    ("tippe top", "rbenvs/TippeTop-v0", None),
    ("scene tippe_hop", None, "tippe_hop"),
)


def _checked_env(env_id, scene, vector: int = 0, **kw):
    """The check table's env: ``env_id`` at its defaults or the named ``scene``, with ``tolerance``
    :data:`CHECK_TOLERANCE`, rk4 (the scheme a tolerance takes) and ``kw``; the vector env of
    ``vector`` sub-envs where given."""
    import gymnasium as gym

    import rbenvs  # noqa: F401

    from ..envs import UnstableMotionWarning

    kw = dict(kw, tolerance=CHECK_TOLERANCE, integrator="rk4")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnstableMotionWarning)
        if scene is not None:
            from ..scenes import load_scene

            loaded = load_scene(scene)
            env_id, kw = loaded.env_id, dict(loaded.kwargs, **kw)
        if vector:
            return gym.make_vec(
                env_id, num_envs=vector, vectorization_mode="vector_entry_point", **kw
            )
        return gym.make(env_id, **kw)


def run_check(
    settings=CHECK_SETTINGS, min_time=0.2, repeat=3, budget=1.0, progress=None
) -> list[dict]:
    """The ``check`` table: per setting, one single-env step (us) without ``tolerance_check``,
    with it compiled and with it on floats, Pendulum-v1 timed after each; the vector env's
    env-steps/s at each N of :data:`CHECK_NUM_ENVS` without the check and with it (runs compiled,
    numpy), CartPole-v1's at the same N after each."""
    peers = Peers(min_time, repeat)
    rows = []
    with warnings.catch_warnings():
        warnings.simplefilter(
            "ignore"
        )  # (the hopping top's check ends episodes: NumericalFailureWarning)
        for label, env_id, scene in settings:
            row = {"setting": label}
            for key, kw in (
                ("plain_us", dict(tolerance_check=False)),
                ("check_us", dict(tolerance_check=True)),
                ("check_floats_us", dict(tolerance_check=True, compiled=False)),
            ):
                env = _checked_env(env_id, scene, **kw)
                env.reset(seed=0)
                zero = np.zeros(env.action_space.shape, dtype=np.float32)
                step = episode_stepper(env, zero)
                step()  # (compiles)
                row[key] = timed_budget(step, min_time, repeat, budget) * 1e6
                row["pendulum_" + key] = timed(peers.pendulum_step, min_time, repeat) * 1e6
                env.close()
                if progress:
                    progress()
            row["vector"] = []
            for size in CHECK_NUM_ENVS:
                vrow = {"num_envs": size}
                for key, compiled, check in (
                    ("plain", "auto", False),
                    ("check", "auto", True),
                    ("check_numpy", False, True),
                ):
                    venv = _checked_env(
                        env_id, scene, vector=size, tolerance_check=check, compiled=compiled
                    )
                    venv.reset(seed=0)
                    action = np.zeros(venv.action_space.shape, dtype=np.float32)
                    venv.step(action)
                    t = timed_budget(lambda: venv.step(action), min_time, repeat, budget)
                    vrow[key + "_env_steps_per_s"] = size / t
                    vrow["cartpole_" + key] = peers.cartpole_rate(size)["env_steps_per_s"]
                    venv.close()
                    if progress:
                        progress()
                row["vector"].append(vrow)
            rows.append(row)
    peers.close()
    return rows


def print_check(rows) -> None:
    print(
        f"\ntolerance_check=True in time: rk4, tolerance={CHECK_TOLERANCE:g}, zero action; "
        "one step "
        "of the single env (us) without the check, "
        "with it (its runs compiled) and with it on floats (compiled=False), against Pendulum-v1 "
        "(timed after each, same run)"
    )
    print(
        f"{'setting':<18} {'no check':>9} {'check':>9} {'floats':>10} {'floats/check':>12} "
        f"{'check/Pendulum':>14}"
    )
    for r in rows:
        print(
            f"{r['setting']:<18} {r['plain_us']:>9.1f} {r['check_us']:>9.1f} "
            f"{r['check_floats_us']:>10.1f} {r['check_floats_us'] / r['check_us']:>12.1f} "
            f"{r['check_us'] / r['pendulum_check_us']:>14.1f}"
        )
    print(
        "vector env (env-steps/s): without the check (compiled), with it (its runs compiled, one "
        "loop over the sub-envs) and with "
        "it on numpy (compiled=False), against CartPole-v1's vector env at the same N (timed after "
        "each, same run)"
    )
    print(
        f"{'setting':<18} {'num_envs':>8} {'no check':>11} {'check':>11} {'numpy':>11} "
        f"{'check/numpy':>12} {'CartPole':>11} "
        f"{'CartPole/no check':>17} {'CartPole/check':>14}"
    )
    for r in rows:
        for v in r["vector"]:
            p, c, n = (
                v["plain_env_steps_per_s"],
                v["check_env_steps_per_s"],
                v["check_numpy_env_steps_per_s"],
            )
            cart_p, cart = v["cartpole_plain"], v["cartpole_check"]
            print(
                f"{r['setting']:<18} {v['num_envs']:>8d} {p:>11.4g} {c:>11.4g} {n:>11.4g} "
                f"{c / n:>12.1f} {cart:>11.4g} {cart_p / p:>17.4g} {cart / c:>14.4g}"
            )


def compiled_speedup(vector_rows) -> list[tuple[int, float]]:
    """``(num_envs, compiled rate / numpy rate)`` for the combination measured on both paths."""
    by_path = {}
    for r in vector_rows:
        if r["integrator"] == "rk4" and r["id"] == SYSTEMS[0][0]:
            by_path[(r["path"], r["num_envs"])] = r["env_steps_per_s"]
    return [
        (n, by_path[("compiled", n)] / by_path[("numpy", n)])
        for (p, n) in sorted(by_path)
        if p == "compiled" and ("numpy", n) in by_path
    ]


# ------------------------------------------------------------------------------ task table
TASK_NUM_ENVS = 4096
QUICK_NUM_ENVS = 64
# --quick: a setting whose single step costs more than this runs its vector figures at
# QUICK_SLOW_NUM_ENVS (the tippe top today: about 3 ms a step)
QUICK_SLOW_STEP_S = 1e-3
QUICK_SLOW_NUM_ENVS = 8
ACTION_POOL = 16  # random action batches drawn beforehand, cycled
ALTERNATIONS = 3  # rounds of (ours, CartPole) per row; the best of each is kept


def env_class(env_id: str) -> type:
    """The single env class registered for ``env_id``."""
    import gymnasium as gym

    cls = gym.spec(env_id).entry_point
    if isinstance(cls, str):
        module, name = cls.split(":")
        cls = getattr(__import__(module, fromlist=[name]), name)
    return cls


def _short(env_id: str) -> str:
    return env_id.split("/", 1)[-1]


def _matches(only, *fields) -> bool:
    return not only or any(only.lower() in str(f).lower() for f in fields if f)


def task_settings(only: str | None = None, scenes: bool = True) -> tuple[list[dict], list[str]]:
    """The task table's settings and notes: every registered id with every task of its env
    class (``tasks``) at the defaults, then every named scene (its id and keyword arguments).
    ``only`` keeps the settings whose label, id, task or scene name contains it (any case).
    Each setting: ``{"setting": label, "id", "task", "scene", "kwargs"}``."""
    import rbenvs

    notes, out = [], []
    for env_id in rbenvs.ENVIRONMENTS:
        for task in env_class(env_id).tasks:
            out.append(
                {
                    "setting": f"{_short(env_id)} {task}",
                    "id": env_id,
                    "task": task,
                    "scene": None,
                    "kwargs": {"task": task},
                }
            )
    if scenes:
        from ..extras import MissingExtra
        from ..scenes import list_scenes, load_scene

        try:
            names = list_scenes()
            loaded = [load_scene(name) for name in names]
        except MissingExtra as exc:
            notes.append(f"named scenes skipped: {exc}")
            loaded = []
        if scenes and not loaded and not notes:
            notes.append("named scenes skipped: none found")
        for s in loaded:
            out.append(
                {
                    "setting": f"scene {s.name}",
                    "id": s.env_id,
                    "task": s.kwargs.get("task"),
                    "scene": s.name,
                    "kwargs": dict(s.kwargs),
                }
            )
    out = [s for s in out if _matches(only, s["setting"], s["id"], s["task"], s["scene"])]
    return out, notes


def random_actions(space, seed: int = 0, pool: int = ACTION_POOL) -> list[np.ndarray]:
    """``pool`` batches of actions uniform in [-1, 1] (the normalised actions), drawn now from
    a generator seeded ``seed``."""
    rng = np.random.default_rng(seed)
    return [rng.uniform(-1.0, 1.0, space.shape).astype(space.dtype) for _ in range(pool)]


def counting_stepper(venv, actions):
    """A step function cycling through ``actions`` and a counter of its calls and of the
    episode ends (terminated or truncated sub-envs) its steps returned."""
    count = {"calls": 0, "ends": 0}

    def step():
        _, _, terminated, truncated, _ = venv.step(actions[count["calls"] % len(actions)])
        count["calls"] += 1
        count["ends"] += int(np.count_nonzero(terminated | truncated))

    return step, count


def timed_counting(fn, count, min_time: float, repeat: int, budget: float | None = None) -> dict:
    """:func:`timed_budget` of a :func:`counting_stepper`: the best seconds per call and, for
    that round, the calls and episode ends; ``ends_total`` over every round."""
    best = {"seconds": float("inf"), "calls": 0, "ends": 0}
    ends0 = count["ends"]
    rounds = repeat
    if budget is not None:  # a probing call: where it outlasts min_time, the first round
        t = _time_once(fn)
        if t > min_time:
            best = {"seconds": t, "calls": 1, "ends": count["ends"] - ends0}
            rounds = _rounds(t, min_time, repeat, budget) - 1
    for _ in range(rounds):
        calls, ends = count["calls"], count["ends"]
        t = timed(fn, min_time, 1)
        if t < best["seconds"]:
            best = {"seconds": t, "calls": count["calls"] - calls, "ends": count["ends"] - ends}
    best["ends_total"] = count["ends"] - ends0
    return best


def stagger_clocks(venv, seed: int = 0) -> bool:
    """Reset with the sub-envs' episode clocks spread uniformly over ``max_episode_steps``
    (``reset(options={"elapsed_steps": k})``, sub-env ``i`` as if ``k_i`` steps into its
    episode): the steady state of a long run whose sub-envs have drifted apart. False (a plain
    reset) where the env has no time limit."""
    limit = venv.unwrapped.max_episode_steps
    if not limit:
        venv.reset(seed=seed)
        return False
    venv.reset(
        seed=seed,
        options={"elapsed_steps": np.random.default_rng(seed).integers(0, limit, venv.num_envs)},
    )
    return True


def no_kernel_reason(env_id: str, kwargs: dict) -> str:
    """Why ``env_id`` with ``kwargs`` has no compiled step: the vector env's own ``ValueError``
    for ``compiled=True``."""
    import gymnasium as gym

    try:
        venv = gym.make_vec(
            env_id,
            num_envs=1,
            vectorization_mode="vector_entry_point",
            **(kwargs | {"compiled": True}),
        )
    except ValueError as exc:
        return str(exc).removeprefix("compiled=True but ")
    venv.close()
    return "compiled=True works, but the default ('auto') does not take it"


def kernel_time(venv, action, min_time: float, repeat: int, budget: float | None = None) -> dict:
    """The compiled :class:`rbenvs.compiled.BatchStep` of ``venv`` alone, on the env's current
    states (``Y = np.stack(state_components)``) under the controls of ``action`` (one batch,
    mapped by ``model.actuator.control``; unactuated axes as arrays of 0.0), with the env's
    internal step and substeps, the guard checked per sub-env where the env's periods are not
    plain (as the env calls it: not where the default accuracy's gate holds every state,
    :meth:`rbenvs.core.step.Engine.gated`): ``{"seconds", "ns_per_env_step", "bad", "check",
    "state_unchanged"}``.
    ``state_unchanged``: the env's states (and ``Y``) equal what they were before the calls,
    and the kernel's new states share no memory with them."""
    env = venv.unwrapped
    batch_step = env.batch_step
    if batch_step is None:
        raise ValueError("the env runs on the numpy path: it has no compiled step")
    n = venv.num_envs
    before = tuple(env.state_components)
    saved = [np.array(c, copy=True) for c in before]
    Y = np.stack(before)
    Y_saved = Y.copy()
    columns = tuple(
        np.ascontiguousarray(np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0).T)
    )
    u_norm, u = env.model.actuator.control(columns)

    def full(cs):  # (n,) float64 arrays, as the env hands the kernel
        return tuple(
            np.ascontiguousarray(np.broadcast_to(np.asarray(c, dtype=np.float64), (n,))) for c in cs
        )

    u, u_norm = full(u), full(u_norm)
    h, substeps = env.engine.h, env.engine.substeps
    check = not env.engine.plain  # the guard per sub-env where the env runs one, as the env does
    if (
        check and env.engine.gated(before) is not None
    ):  # (the default accuracy's gate holds every state: the env's periods are plain)
        check = False

    def call():
        return batch_step(Y, u, u_norm, h, substeps, check)

    out = call()  # compiled already by the env's first step; not timed
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t = timed_budget(call, min_time, repeat, budget)
    after = tuple(env.state_components)
    unchanged = (
        len(after) == len(saved)
        and all(np.array_equal(a, b) for a, b in zip(after, saved))
        and np.array_equal(Y, Y_saved)
        and not any(np.shares_memory(out[0], c) for c in (Y, *after))
    )
    return {
        "seconds": t,
        "ns_per_env_step": 1e9 * t / n,
        "bad": int(out[1]),
        "check": check,
        "state_unchanged": bool(unchanged),
    }


class Peers:
    """Pendulum-v1's single env (one step function, zero action) and CartPole-v1's native
    vector env per N (random actions from a seeded pool, its resets included), measured once
    per N in the run that measures ours."""

    def __init__(self, min_time: float, repeat: int, seed: int = 0):
        import gymnasium as gym

        self.pendulum = gym.make("Pendulum-v1")
        self.pendulum.reset(seed=seed)
        self.pendulum_step = episode_stepper(self.pendulum, np.zeros(1, dtype=np.float32))
        self.min_time, self.repeat, self.seed = min_time, repeat, seed
        self.cartpole = {}

    def cartpole_rate(self, n: int) -> dict:
        """CartPole's rate at ``n``, measured now (one env per ``n``, kept stepping): each row's
        ratio takes the peer measured right after its own timing, so that a machine whose speed
        drifts during the run (a shared host) skews neither side."""
        if n not in self.cartpole:
            import gymnasium as gym

            cart = gym.make_vec("CartPole-v1", num_envs=n, vectorization_mode="vector_entry_point")
            cart.reset(seed=self.seed)
            rng = np.random.default_rng(self.seed)
            actions = [rng.integers(0, 2, n).astype(np.int64) for _ in range(ACTION_POOL)]
            step, count = counting_stepper(cart, actions)
            for _ in range(100):  # past the first episode ends, into the steady state
                step()
            self.cartpole[n] = (cart, step, count)
        cart, step, count = self.cartpole[n]
        best = timed_counting(step, count, self.min_time, self.repeat)
        return {"env_steps_per_s": n / best["seconds"], "episode_ends": best["ends"]}

    def close(self) -> None:
        self.pendulum.close()
        for cart, _, _ in self.cartpole.values():
            cart.close()


def measure_setting(
    setting: dict,
    peers: Peers,
    num_envs: int,
    min_time: float,
    repeat: int,
    budget: float,
    stagger: bool = True,
    slow_step_s: float | None = None,
    slow_num_envs: int | None = None,
    seed: int = 0,
    progress=None,
) -> dict:
    """One row of the task table (see the module docstring); ``progress()`` is called four
    times (single env, zero action, random actions, then the kernel and numpy path).
    ``stagger=False`` leaves the headline random-action run's clocks together too."""
    import gymnasium as gym

    env_id, kwargs = setting["id"], dict(setting["kwargs"])
    row = {k: setting[k] for k in ("setting", "id", "task", "scene")}
    row["kwargs"] = kwargs
    tick = progress or (lambda: None)
    # -- single env, interleaved with Pendulum
    env = gym.make(env_id, **kwargs)
    env.reset(seed=seed)
    row["task"] = row["task"] or env.unwrapped.task.name
    ours = episode_stepper(env, np.zeros(env.action_space.shape, dtype=env.action_space.dtype))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ours()  # the first step may generate code: not timed
        t_ours = _time_once(ours)  # a probe; where one step outlasts a round, the first round
        rounds = max(repeat, 2)
        if t_ours > min_time / rounds:
            rounds = _rounds(t_ours, min_time / rounds, rounds, budget) - 1
        else:
            t_ours = float("inf")
        t_pend = float("inf")
        for k in range(max(rounds, 1)):  # interleaved, so that machine load hits both alike
            if k < rounds:
                t_ours = min(t_ours, timed(ours, min_time / max(repeat, 2), 1))
            t_pend = min(t_pend, timed(peers.pendulum_step, min_time / max(repeat, 2), 1))
    env.close()
    row.update(
        single_step_us=t_ours * 1e6,
        pendulum_step_us=t_pend * 1e6,
        single_ratio_to_pendulum=t_ours / t_pend,
    )
    tick()
    # -- vector env: zero action from a fresh reset, then random actions with ends
    n = num_envs
    if slow_step_s is not None and slow_num_envs is not None and t_ours > slow_step_s:
        n = min(n, slow_num_envs)
    row["num_envs"] = n
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
        compiled = bool(venv.unwrapped.compiled)
        row["path"] = "compiled" if compiled else "numpy"
        row["max_episode_steps"] = venv.unwrapped.max_episode_steps
        venv.reset(seed=seed)
        zero = np.zeros(venv.action_space.shape, dtype=venv.action_space.dtype)
        venv.step(zero)  # a kernel compiles on its first call: not timed
        t = timed_budget(lambda: venv.step(zero), min_time, repeat, budget)
        row["zero_env_steps_per_s"] = n / t
        row["zero_ns_per_env_step"] = 1e9 * t / n
        tick()
        actions = random_actions(venv.action_space, seed)
        # ours and the peer in turn, the best of each: on a shared host the speed drifts by
        # tens of percent within seconds, and the best of alternating rounds compares like with like
        sync = random = cart = None
        for _ in range(ALTERNATIONS):
            s_ = _random_rate(venv, actions, min_time, repeat, budget, False, seed)
            r_ = _random_rate(venv, actions, min_time, repeat, budget, stagger, seed)
            c_ = peers.cartpole_rate(n)
            sync = s_ if sync is None or s_["rate"] > sync["rate"] else sync
            random = r_ if random is None or r_["rate"] > random["rate"] else random
            cart = c_ if cart is None or c_["env_steps_per_s"] > cart["env_steps_per_s"] else cart
        rate = cart["env_steps_per_s"]
        row.update(
            random_env_steps_per_s=random["rate"],
            random_ns_per_env_step=1e9 / random["rate"],
            episode_ends=random["ends"],
            episode_ends_total=random["ends_total"],
            random_calls_timed=random["calls"],
            clocks_staggered=random["staggered"],
            cartpole_env_steps_per_s=rate,
            cartpole_episode_ends=cart["episode_ends"],
            ratio_to_cartpole=random["rate"] / rate,
            zero_ratio_to_cartpole=row["zero_env_steps_per_s"] / rate,
            sync_random_env_steps_per_s=sync["rate"],
            sync_episode_ends=sync["ends"],
            sync_random_calls_timed=sync["calls"],
            sync_ratio_to_cartpole=sync["rate"] / rate,
        )
        tick()
        # -- the kernel alone on the states the random run left, then the numpy path
        row.update(
            kernel_ns_per_env_step=None,
            gap=None,
            gap_zero=None,
            kernel_state_unchanged=None,
            kernel_bad=None,
            kernel_guard_checked=None,
            no_kernel_reason=None,
            numpy_random_env_steps_per_s=None,
            numpy_episode_ends=None,
            compiled_over_numpy=None,
        )
        if compiled:
            k = kernel_time(venv, actions[0], min_time, repeat, budget)
            row.update(
                kernel_ns_per_env_step=k["ns_per_env_step"],
                gap=row["random_ns_per_env_step"] / k["ns_per_env_step"],
                gap_zero=row["zero_ns_per_env_step"] / k["ns_per_env_step"],
                kernel_state_unchanged=k["state_unchanged"],
                kernel_bad=k["bad"],
                kernel_guard_checked=k["check"],
            )
            venv.close()
            numpy_env = gym.make_vec(
                env_id,
                num_envs=n,
                vectorization_mode="vector_entry_point",
                **(kwargs | {"compiled": False}),
            )
            numpy_random = _random_rate(numpy_env, actions, min_time, repeat, budget, stagger, seed)
            numpy_env.close()
            row.update(
                numpy_random_env_steps_per_s=numpy_random["rate"],
                numpy_episode_ends=numpy_random["ends"],
                compiled_over_numpy=random["rate"] / numpy_random["rate"],
            )
        else:
            venv.close()
            row["no_kernel_reason"] = no_kernel_reason(env_id, kwargs)
    tick()
    return row


def _random_rate(venv, actions, min_time, repeat, budget, stagger, seed) -> dict:
    """Env-steps per second of ``venv`` under ``actions`` (cycled) from ``reset(seed)``, clocks
    staggered if asked, with the episode ends of the timed window."""
    n = venv.num_envs
    if stagger:
        staggered = stagger_clocks(venv, seed)
    else:
        venv.reset(seed=seed)
        staggered = False
    step, count = counting_stepper(venv, actions)
    step()  # a kernel compiles on its first call: not timed
    best = timed_counting(step, count, min_time, repeat, budget)
    return {
        "rate": n / best["seconds"],
        "ends": best["ends"],
        "ends_total": best["ends_total"],
        "calls": best["calls"],
        "staggered": staggered,
    }


def run_tasks(
    settings=None,
    num_envs: int = TASK_NUM_ENVS,
    min_time: float = 0.2,
    repeat: int = 3,
    budget: float = 1.0,
    only: str | None = None,
    stagger: bool = True,
    slow_step_s: float | None = None,
    slow_num_envs: int | None = None,
    seed: int = 0,
    progress=None,
) -> tuple[list[dict], list[str]]:
    """The task table: ``(rows, notes)``, one row per setting (default: :func:`task_settings`
    with ``only``), each measured by :func:`measure_setting` against the same peers."""
    import rbenvs  # noqa: F401  (registers the ids)

    notes = []
    if settings is None:
        settings, notes = task_settings(only)
    peers = Peers(min_time, repeat, seed)
    rows = [
        measure_setting(
            s,
            peers,
            num_envs,
            min_time,
            repeat,
            budget,
            stagger,
            slow_step_s,
            slow_num_envs,
            seed,
            progress,
        )
        for s in settings
    ]
    peers.close()
    return rows, notes


def _g(x, fmt=".3g"):
    return "-" if x is None else format(x, fmt)


def print_tasks(rows, notes) -> None:
    """The task table, its footnotes (why a setting has no kernel) and the scenes' arguments."""
    ns = sorted({r["num_envs"] for r in rows})
    clocks = (
        "episode clocks spread over max_episode_steps"
        if all(r["clocks_staggered"] for r in rows)
        else "episode clocks NOT spread: see the note below"
    )
    print("tasks: every (id, task) at its defaults and every named scene")
    print(
        "  single: one step of gymnasium.make against Pendulum-v1 (zero action; us, interleaved, "
        "same run)"
    )
    print(
        f"  vector: make_vec at N = {', '.join(map(str, ns)) or '-'}; env-steps/s with zero "
        "action, "
        "and with seeded random actions in [-1, 1]"
    )
    print(f"          ({clocks}; 'ends': episode ends in the timed window, resets included),")
    print(
        "          that rate over CartPole-v1's native vector env (random actions) at the same N, "
        "same run;"
    )
    print(
        "          sync/s: the same actions from reset, every episode clock together (restarts all "
        "at once, at the limit);"
    )
    print(
        "          numpy/s and c/np: the same env with compiled=False; kernel: the compiled "
        "BatchStep alone"
    )
    print("          (ns per env-step), gap = env time per env-step (random actions) / kernel time")
    w = max([25] + [len(r["setting"]) + 1 for r in rows])
    print(
        f"{'setting':<{w}} {'single us':>9} {'/Pend':>6} {'N':>5} {'path':<8} {'zero/s':>9} "
        f"{'random/s':>9} {'ends':>6} {'/Cart':>6} {'sync/s':>9} {'/Cart':>6} {'numpy/s':>9} "
        f"{'c/np':>5} {'kernel ns':>9} {'gap':>6}"
    )
    reasons = {}
    for r in rows:
        kernel, gap = _g(r["kernel_ns_per_env_step"], ".2f"), _g(r["gap"], ".2f")
        if r["no_kernel_reason"] is not None:
            mark = reasons.setdefault(r["no_kernel_reason"], len(reasons) + 1)
            kernel = f"-[{mark}]"
        if r["kernel_state_unchanged"] is False:
            kernel += "!"
        print(
            f"{r['setting']:<{w}} {r['single_step_us']:>9.2f} "
            f"{r['single_ratio_to_pendulum']:>6.3f} "
            f"{r['num_envs']:>5d} {r['path']:<8} "
            f"{r['zero_env_steps_per_s']:>9.3g} {r['random_env_steps_per_s']:>9.3g} "
            f"{r['episode_ends']:>6d} {r['ratio_to_cartpole']:>6.3f} "
            f"{r['sync_random_env_steps_per_s']:>9.3g} {r['sync_ratio_to_cartpole']:>6.3f} "
            f"{_g(r['numpy_random_env_steps_per_s']):>9} {_g(r['compiled_over_numpy'], '.2f'):>5} "
            f"{kernel:>9} {gap:>6}"
        )
    if rows:
        pend = min(r["pendulum_step_us"] for r in rows)
        carts = {}
        for r in rows:
            carts.setdefault(r["num_envs"], []).append(r["cartpole_env_steps_per_s"])
        print(
            f"peers: Pendulum-v1 step {pend:.2f} us (best of the run); CartPole-v1 vector env "
            "(measured beside each row) "
            + ", ".join(f"{min(c):.3g}-{max(c):.3g}/s at N = {n}" for n, c in sorted(carts.items()))
        )
    for reason, mark in reasons.items():
        which = ", ".join(r["setting"] for r in rows if r["no_kernel_reason"] == reason)
        print(f"[{mark}] no compiled step ({which}): {reason}")
    if any(r["kernel_state_unchanged"] is False for r in rows):
        print("! the kernel call changed the env's state (it must write new arrays only)")
    if any(r["kernel_bad"] for r in rows if r["kernel_bad"] is not None):
        print(
            "kernel: non-finite new states in "
            + ", ".join(r["setting"] for r in rows if r["kernel_bad"])
        )
    small = [r["setting"] for r in rows if r["num_envs"] < max(ns)]
    if small:
        print(f"at N = {min(ns)} (a slow single step, --quick): " + ", ".join(small))
    unspread = [r["setting"] for r in rows if not r["clocks_staggered"]]
    if unspread:
        print(
            "episode clocks not spread (not asked, or the env keeps no per-sub-env step count or "
            "has no time limit): " + ", ".join(unspread)
        )
    for note in notes:
        print(note)
    scenes = [r for r in rows if r["scene"]]
    if scenes:
        print("scenes:")
        for r in scenes:
            print(
                f"  {r['scene']}: {r['id']} "
                + ", ".join(f"{k}={v}" for k, v in r["kwargs"].items())
            )


TABLES = ("tasks", "integrators", "scaling", "sb3", "check")
QUICK_TABLES = (
    "tasks",
    "sb3",
)  # --quick: a smoke run well under a minute (the kernels' compilation is most of it)


def main(argv=None) -> int:
    parser = ArgumentParser(
        prog="rbenvs bench throughput",
        description="Env-steps per second against Pendulum-v1 and CartPole-v1's native vector env: "
        "every (id, task) and named scene, with the compiled kernel's time beside (the gap to the "
        "limit), then per integrator.",
    )
    parser.add_argument("--json", metavar="PATH", help="also write the figures as JSON")
    parser.add_argument(
        "--quick",
        action="store_true",
        help=f"shorter timings: the task table at N = {QUICK_NUM_ENVS} "
        f"(slow settings at {QUICK_SLOW_NUM_ENVS}) "
        "and the SB3 rows by default; an integrator table asked for with --tables at sizes 1 and "
        "256; never the scaling table",
    )
    parser.add_argument(
        "--num-envs",
        type=int,
        metavar="N",
        help=(
            f"task table: sub-envs of the vector env (default: {TASK_NUM_ENVS}, "
            f"{QUICK_NUM_ENVS} with --quick)"
        ),
    )
    parser.add_argument(
        "--only",
        metavar="SUBSTRING",
        help="only the rows whose id, task, scene name or integrator contains SUBSTRING (any case)",
    )
    parser.add_argument(
        "--tables",
        metavar="LIST",
        help=(
            f"comma-separated tables to run, of {', '.join(TABLES)} "
            f"(default: all; with --quick: {','.join(QUICK_TABLES)})"
        ),
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress on stderr")
    args = parser.parse_args(argv)
    tables = [
        t.strip()
        for t in (args.tables or ",".join(QUICK_TABLES if args.quick else TABLES)).split(",")
        if t.strip()
    ]
    unknown = [t for t in tables if t not in TABLES]
    if unknown:
        raise ValueError(f"--tables: unknown table {unknown[0]!r}; choose from {', '.join(TABLES)}")
    if args.num_envs is not None and args.num_envs < 1:
        raise ValueError(f"--num-envs must be >= 1, got {args.num_envs}")
    only = args.only
    num_envs = args.num_envs or (QUICK_NUM_ENVS if args.quick else TASK_NUM_ENVS)
    sizes = (1, 256) if args.quick else SIZES
    min_time = 0.05 if args.quick else 0.2
    budget = 0.2 if args.quick else 1.0
    free = SYSTEMS[0][0]
    # the earlier tables, filtered by --only on id or integrator
    systems = tuple((i, tuple(x for x in ints if _matches(only, i, x))) for i, ints in SYSTEMS)
    systems = tuple((i, ints) for i, ints in systems if ints) if "integrators" in tables else ()
    do_scaling = "scaling" in tables and not args.quick and _matches(only, free, "rk4")
    do_sb3 = "sb3" in tables and _matches(only, free, "rk4")
    settings, notes = task_settings(only) if "tasks" in tables else ([], [])
    checks = (
        tuple(c for c in CHECK_SETTINGS if _matches(only, c[0], c[1] or "", c[2] or ""))
        if "check" in tables
        else ()
    )
    if not (settings or systems or do_scaling or do_sb3 or checks):
        raise ValueError(f"--only {only!r} matches no row of the tables {', '.join(tables)}")
    n_tasks = 4 * len(settings)
    n_single = sum(len(i) for _, i in systems)
    combos_extra = (
        (2 if available() else 1) if any(i == free and "rk4" in ints for i, ints in systems) else 0
    )
    n_vector = sum(
        1 for _, ints in systems for i in ints for n in sizes if n <= LARGEST.get(i, max(sizes))
    ) + combos_extra * len(sizes)
    n_scaling = (2 if available() else 1) * len(SCALING_SIZES) if do_scaling else 0
    bar = Progress(
        n_tasks + n_single + n_vector + n_scaling + (3 + 3 * len(CHECK_NUM_ENVS)) * len(checks),
        not args.no_progress,
        "bench throughput",
    )
    tasks, task_notes = [], notes
    if settings:
        # --quick: a smoke run, its figures rough (23 settings, each timed seven ways)
        tasks, _ = run_tasks(
            settings,
            num_envs=num_envs,
            min_time=0.02 if args.quick else min_time,
            repeat=2 if args.quick else 3,
            budget=budget,
            slow_step_s=QUICK_SLOW_STEP_S if args.quick else None,
            slow_num_envs=QUICK_SLOW_NUM_ENVS if args.quick else None,
            progress=bar.update,
        )
    legacy_budget = (
        budget if args.quick else None
    )  # the full run times the earlier tables as before
    single = (
        run_single(systems, min_time=min_time, progress=bar.update, budget=legacy_budget)
        if systems
        else []
    )
    vector = (
        run_vector(
            systems, sizes=sizes, min_time=min_time, progress=bar.update, budget=legacy_budget
        )
        if systems
        else []
    )
    scaling = run_scaling(min_time=min_time, progress=bar.update) if do_scaling else []
    sb3 = run_sb3(sizes=(16, 256), min_time=min_time) if do_sb3 else []
    check = (
        run_check(checks, min_time=min_time, budget=budget, progress=bar.update) if checks else []
    )
    bar.close()
    if tasks:
        print_tasks(tasks, task_notes)
    elif task_notes:
        print("\n".join(task_notes))
    if single:
        print("\nsingle env: one step of gymnasium.make(id) against Pendulum-v1, same run (us)")
        print(f"{'id':<26} {'integrator':<10} {'ours':>9} {'Pendulum':>9} {'ratio':>7}")
        for r in single:
            print(
                f"{r['id']:<26} {r['integrator']:<10} {r['step_us']:>9.2f} "
                f"{r['pendulum_step_us']:>9.2f} {r['ratio_to_pendulum']:>7.3f}"
            )
    if vector:
        print(
            "\nvector env (vector_entry_point, zero action) against CartPole-v1's native vector "
            "env, same run"
        )
        print(
            f"{'id':<26} {'integrator':<16} {'path':<9} {'num_envs':>8} {'env-steps/s':>13} "
            f"{'ns/env':>9} {'CartPole/s':>13} {'ratio':>8}"
        )
        for r in vector:
            print(
                f"{r['id']:<26} {r['integrator']:<16} {r['path']:<9} {r['num_envs']:>8d} "
                f"{r['env_steps_per_s']:>13.4g} {r['ns_per_env_step']:>9.1f} "
                f"{r['cartpole_env_steps_per_s']:>13.4g} {r['ratio_to_cartpole']:>8.3f}"
            )
    paths = compiled_speedup(vector)
    if paths:
        print("\ncompiled step against the numpy path of the same env (free body, rk4), same run")
        for n, ratio in paths:
            print(f"  num_envs {n:>5d}: {ratio:.2f}x")
    if scaling:
        print(
            "\nscaling: the free body with rk4, time per env-step against num_envs, and the arrays "
            "one step moves"
        )
        print(f"{'path':<9} {'num_envs':>8} {'ns/env':>9} {'bytes/env':>10} {'MB/step':>9}")
        for r in scaling:
            print(
                f"{r['path']:<9} {r['num_envs']:>8d} {r['ns_per_env_step']:>9.1f} "
                f"{r['bytes_per_env_step']:>10.0f} {r['megabytes_per_step']:>9.3f}"
            )
    if sb3:
        print(
            "\nstable-baselines3 VecEnv.step: the native adapter (rbenvs.vector.sb3) against "
            "DummyVecEnv, same run"
        )
        print(f"{'id':<26} {'num_envs':>8} {'native/s':>12} {'Dummy/s':>12} {'ratio':>8}")
        for r in sb3:
            print(
                f"{r['id']:<26} {r['num_envs']:>8d} {r['sb3_native_env_steps_per_s']:>12.4g} "
                f"{r['sb3_dummy_env_steps_per_s']:>12.4g} {r['ratio']:>8.2f}"
            )
    if check:
        print_check(check)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(
                {
                    "tasks": tasks,
                    "task_notes": task_notes,
                    "single": single,
                    "vector": vector,
                    "scaling": scaling,
                    "sb3": sb3,
                    "check": check,
                },
                f,
                indent=1,
            )
    return 0

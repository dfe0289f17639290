"""``rbenvs bench throughput``: env-steps per second, with gymnasium's own envs measured beside.

For every system and integrator (default scene of each id, zero action):

* ``single``: one ``env.step`` of ``gymnasium.make(id)`` (wrappers included, as users call it)
  against ``gymnasium.make("Pendulum-v1")`` measured in the same run, interleaved, best of
  ``repeat``; the ratio ``ours / Pendulum`` is the cost of one of our steps in Pendulum steps.
* ``vector``: ``gymnasium.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``
  for N = 1, 16, 256, 4096 against CartPole-v1's own native vector env at the same N; the
  ratio is ours / CartPole in env-steps per second, and ``ns/env`` the time per env-step.
  ``path`` says whether the step ran compiled (:mod:`rbenvs.compiled`, where numba is
  installed and the setting has pure forms) or on numpy arrays. Extra lines: the free body
  with rk4 on the numpy path (with the compiled/numpy ratio per N: what the compiler buys),
  and with ``info_readouts=False`` ("lean info").
* ``scaling`` (not with ``--quick``): the free body with rk4 on each path from 1 to 65536
  sub-envs, with the bytes of arrays one step moves per env.
* ``sb3`` (when stable-baselines3 is installed): SB3's ``VecEnv.step`` through the native
  adapter against ``DummyVecEnv`` of single envs, at N = 16 and 256.

Every timing covers whole episodes' worth of steps, resets included (``min_time`` spans
several episode ends at the larger N): the time limit ends all sub-envs of the default scene
together, so a step's true cost includes 1/400 of resetting every sub-env.

Throughput per env grows with N while the fixed cost per call dominates (Python glue, and on
the numpy path about a microsecond of dispatch per array operation, some 150 of them per
free-body step), and flattens once the arrays a step moves stop fitting in the caches: the
scaling table prints those bytes per env beside the time, to read against the machine's L2
and L3 sizes.

Slow combinations (``dop853`` on large batches, the stiff tippe top) are measured with fewer
calls; each figure is the best of ``repeat`` timings of at least ``min_time`` seconds or one call.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings

import numpy as np

from ..compiled import available
from ..progress import Progress

__all__ = ["run_single", "run_vector", "run_scaling", "timed", "episode_stepper", "main"]

SIZES = (1, 16, 256, 4096)
# (id, integrators, largest N measured per integrator: the reference solver is slow in bulk)
SYSTEMS = (
    ("rbenvs/FreeRigidBody-v0", ("euler", "rk4", "splitting", "exact", "dop853")),
    ("rbenvs/LagrangeTop-v0", ("euler", "rk4", "splitting", "dop853")),
    ("rbenvs/TippeTop-v0", ("euler", "rk4", "dop853")),
)
LARGEST = {"dop853": 256, "exact": 4096}


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


def episode_stepper(env, action):
    """A step function that resets the env when its episode ends (not timed separately)."""
    state = {"done": False}

    def step():
        if state["done"]:
            env.reset()
        _, _, terminated, truncated, _ = env.step(action)
        state["done"] = terminated or truncated

    return step


def run_single(systems=SYSTEMS, min_time=0.2, repeat=5, progress=None) -> list[dict]:
    import gymnasium as gym

    import rbenvs  # noqa: F401

    pendulum = gym.make("Pendulum-v1")
    pendulum.reset(seed=0)
    p_step = episode_stepper(pendulum, np.zeros(1, dtype=np.float32))
    rows = []
    for env_id, integrators in systems:
        for integ in integrators:
            env = gym.make(env_id, integrator=integ)
            env.reset(seed=0)
            ours = episode_stepper(env, np.zeros(env.action_space.shape, dtype=np.float32))
            t_ours, t_pend = float("inf"), float("inf")
            for _ in range(repeat):  # interleaved, so that machine load hits both alike
                t_ours = min(t_ours, timed(ours, min_time / repeat, 1))
                t_pend = min(t_pend, timed(p_step, min_time / repeat, 1))
            rows.append({"id": env_id, "integrator": integ, "step_us": t_ours * 1e6, "pendulum_step_us": t_pend * 1e6, "ratio_to_pendulum": t_ours / t_pend})
            if progress:
                progress()
    return rows


def run_vector(systems=SYSTEMS, sizes=SIZES, min_time=0.2, repeat=3, progress=None) -> list[dict]:
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
    combos = [(env_id, integ, True, "auto") for env_id, integrators in systems for integ in integrators]
    for env_id, integrators in systems[:1]:
        if "rk4" in integrators:
            # (without numba the default rows are the numpy path already)
            combos += [(env_id, "rk4", True, False)] if available() else []
            combos += [(env_id, "rk4", False, "auto")]
    for env_id, integ, readouts, compiled in combos:
        for n in sizes:
            if n > LARGEST.get(integ, max(sizes)):
                continue
            venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", integrator=integ, info_readouts=readouts, compiled=compiled)
            path = "compiled" if venv.unwrapped.compiled else "numpy"
            venv.reset(seed=0)
            a = np.zeros(venv.action_space.shape, dtype=np.float32)
            venv.step(a)  # a kernel compiles on its first call: not timed
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                t = timed(lambda: venv.step(a), min_time, repeat)
            rate = n / t
            label = integ if readouts else f"{integ}, lean info"
            rows.append({"id": env_id, "integrator": label, "path": path, "num_envs": n, "env_steps_per_s": rate, "ns_per_env_step": 1e9 * t / n,
                         "cartpole_env_steps_per_s": cart_rate[n], "ratio_to_cartpole": rate / cart_rate[n]})
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
            venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", compiled=compiled)
            venv.reset(seed=0)
            a = np.zeros(venv.action_space.shape, dtype=np.float32)
            obs, reward, terminated, truncated, info = venv.step(a)
            state = sum(v.nbytes for v in venv.unwrapped.get_state().values())
            arrays = [obs, reward, terminated, truncated, a] + [v for v in info.values() if isinstance(v, np.ndarray)]
            moved = 2 * state + sum(x.nbytes for x in arrays)
            t = timed(lambda: venv.step(a), min_time, repeat)
            rows.append({"path": "compiled" if compiled else "numpy", "num_envs": n, "ns_per_env_step": 1e9 * t / n, "bytes_per_env_step": moved / n, "megabytes_per_step": moved / 1e6})
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
        rows.append({"id": env_id, "num_envs": n, "sb3_native_env_steps_per_s": rates[0], "sb3_dummy_env_steps_per_s": rates[1], "ratio": rates[0] / rates[1]})
    return rows


def compiled_speedup(vector_rows) -> list[tuple[int, float]]:
    """``(num_envs, compiled rate / numpy rate)`` for the combination measured on both paths."""
    by_path = {}
    for r in vector_rows:
        if r["integrator"] == "rk4" and r["id"] == SYSTEMS[0][0]:
            by_path[(r["path"], r["num_envs"])] = r["env_steps_per_s"]
    return [(n, by_path[("compiled", n)] / by_path[("numpy", n)]) for (p, n) in sorted(by_path) if p == "compiled" and ("numpy", n) in by_path]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="rbenvs bench throughput", description="Env-steps per second against Pendulum-v1 and CartPole-v1's native vector env.")
    parser.add_argument("--json", metavar="PATH", help="also write the figures as JSON")
    parser.add_argument("--quick", action="store_true", help="shorter timings, sizes 1 and 256 only")
    parser.add_argument("--no-progress", action="store_true")
    args = parser.parse_args(argv)
    sizes = (1, 256) if args.quick else SIZES
    min_time = 0.05 if args.quick else 0.2
    n_single = sum(len(i) for _, i in SYSTEMS)
    n_vector = sum(1 for _, ints in SYSTEMS for i in ints for n in sizes if n <= LARGEST.get(i, max(sizes))) + (2 if available() else 1) * len(sizes)
    n_scaling = 0 if args.quick else (2 if available() else 1) * len(SCALING_SIZES)
    bar = Progress(n_single + n_vector + n_scaling, not args.no_progress, "bench throughput")
    single = run_single(min_time=min_time, progress=bar.update)
    vector = run_vector(sizes=sizes, min_time=min_time, progress=bar.update)
    scaling = [] if args.quick else run_scaling(min_time=min_time, progress=bar.update)
    sb3 = run_sb3(sizes=(16, 256), min_time=min_time)
    bar.close()
    print("single env: one step of gymnasium.make(id) against Pendulum-v1, same run (us)")
    print(f"{'id':<26} {'integrator':<10} {'ours':>9} {'Pendulum':>9} {'ratio':>7}")
    for r in single:
        print(f"{r['id']:<26} {r['integrator']:<10} {r['step_us']:>9.2f} {r['pendulum_step_us']:>9.2f} {r['ratio_to_pendulum']:>7.3f}")
    print("\nvector env (vector_entry_point) against CartPole-v1's native vector env, same run")
    print(f"{'id':<26} {'integrator':<16} {'path':<9} {'num_envs':>8} {'env-steps/s':>13} {'ns/env':>9} {'CartPole/s':>13} {'ratio':>8}")
    for r in vector:
        print(f"{r['id']:<26} {r['integrator']:<16} {r['path']:<9} {r['num_envs']:>8d} {r['env_steps_per_s']:>13.4g} {r['ns_per_env_step']:>9.1f} {r['cartpole_env_steps_per_s']:>13.4g} {r['ratio_to_cartpole']:>8.3f}")
    paths = compiled_speedup(vector)
    if paths:
        print("\ncompiled step against the numpy path of the same env (free body, rk4), same run")
        for n, ratio in paths:
            print(f"  num_envs {n:>5d}: {ratio:.2f}x")
    if scaling:
        print("\nscaling: the free body with rk4, time per env-step against num_envs, and the arrays one step moves")
        print(f"{'path':<9} {'num_envs':>8} {'ns/env':>9} {'bytes/env':>10} {'MB/step':>9}")
        for r in scaling:
            print(f"{r['path']:<9} {r['num_envs']:>8d} {r['ns_per_env_step']:>9.1f} {r['bytes_per_env_step']:>10.0f} {r['megabytes_per_step']:>9.3f}")
    if sb3:
        print("\nstable-baselines3 VecEnv.step: the native adapter (rbenvs.vector.sb3) against DummyVecEnv, same run")
        print(f"{'id':<26} {'num_envs':>8} {'native/s':>12} {'Dummy/s':>12} {'ratio':>8}")
        for r in sb3:
            print(f"{r['id']:<26} {r['num_envs']:>8d} {r['sb3_native_env_steps_per_s']:>12.4g} {r['sb3_dummy_env_steps_per_s']:>12.4g} {r['ratio']:>8.2f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"single": single, "vector": vector, "scaling": scaling, "sb3": sb3}, f, indent=1)
    return 0

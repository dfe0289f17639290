"""``rbenvs bench throughput``: env-steps per second, with gymnasium's own envs measured beside.

For every system and integrator (default scene of each id, zero action):

* ``single``: one ``env.step`` of ``gymnasium.make(id)`` (wrappers included, as users call it)
  against ``gymnasium.make("Pendulum-v1")`` measured in the same run, interleaved, best of
  ``repeat``; the ratio ``ours / Pendulum`` is the cost of one of our steps in Pendulum steps.
* ``vector``: ``gymnasium.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``
  for N = 1, 16, 256, 4096 against CartPole-v1's own native vector env at the same N; the
  ratio is ours / CartPole in env-steps per second, and ``ns/env`` the time per env-step.
  One extra line, "lean info", is the free body with ``info_readouts=False``.
* ``sb3`` (when stable-baselines3 is installed): SB3's ``VecEnv.step`` through the native
  adapter against ``DummyVecEnv`` of single envs, at N = 16 and 256.

Throughput per env grows with N while the fixed cost per call (Python, numpy dispatch)
dominates, and flattens once every array operation streams its operands from memory: a
free-body RK4 step touches about 30 arrays of N doubles, so at N = 4096 (1 MB in flight) the
arrays leave the L2 cache and the cost per env stops falling.

Slow combinations (``dop853`` on large batches, the stiff tippe top) are measured with fewer
calls; each figure is the best of ``repeat`` timings of at least ``min_time`` seconds or one call.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings

import numpy as np

from ..progress import Progress

__all__ = ["run_single", "run_vector", "main"]

SIZES = (1, 16, 256, 4096)
# (id, integrators, largest N measured per integrator: the reference solver is slow in bulk)
SYSTEMS = (
    ("rbenvs/FreeRigidBody-v0", ("euler", "rk4", "splitting", "exact", "dop853")),
    ("rbenvs/LagrangeTop-v0", ("euler", "rk4", "splitting", "dop853")),
    ("rbenvs/TippeTop-v0", ("euler", "rk4", "dop853")),
)
LARGEST = {"dop853": 256, "exact": 4096}


def _timed(fn, min_time: float, repeat: int) -> float:
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


def _episode_stepper(env, action):
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
    p_step = _episode_stepper(pendulum, np.zeros(1, dtype=np.float32))
    rows = []
    for env_id, integrators in systems:
        for integ in integrators:
            env = gym.make(env_id, integrator=integ)
            env.reset(seed=0)
            ours = _episode_stepper(env, np.zeros(env.action_space.shape, dtype=np.float32))
            t_ours, t_pend = float("inf"), float("inf")
            for _ in range(repeat):  # interleaved, so that machine load hits both alike
                t_ours = min(t_ours, _timed(ours, min_time / repeat, 1))
                t_pend = min(t_pend, _timed(p_step, min_time / repeat, 1))
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
        cart_rate[n] = n / _timed(lambda: cart.step(a), min_time, repeat)
        cart.close()
    rows = []
    combos = [(env_id, integ, True) for env_id, integrators in systems for integ in integrators]
    # the cost of info's physical read-outs, shown once: the free body with rk4 without them
    combos += [(env_id, "rk4", False) for env_id, integrators in systems[:1] if "rk4" in integrators]
    for env_id, integ, readouts in combos:
        if True:
            for n in sizes:
                if n > LARGEST.get(integ, max(sizes)):
                    continue
                venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", integrator=integ, info_readouts=readouts)
                venv.reset(seed=0)
                a = np.zeros(venv.action_space.shape, dtype=np.float32)
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    t = _timed(lambda: venv.step(a), min_time, repeat)
                rate = n / t
                rows.append({"id": env_id, "integrator": integ if readouts else f"{integ}, lean info", "num_envs": n, "env_steps_per_s": rate, "ns_per_env_step": 1e9 * t / n,
                             "cartpole_env_steps_per_s": cart_rate[n], "ratio_to_cartpole": rate / cart_rate[n]})
                venv.close()
                if progress:
                    progress()
    return rows


def run_sb3(sizes=(16, 256), min_time=0.2, repeat=3) -> list[dict]:
    """SB3's ``VecEnv.step`` on the native adapter against ``DummyVecEnv`` of single envs
    (the free body, rk4). Empty when stable-baselines3 (the agents extra) is not installed."""
    try:
        from stable_baselines3.common.env_util import make_vec_env

        from rbenvs_agents.sb3_vec_env import make_sb3_vec_env
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
            rates.append(n / _timed(lambda: venv.step(a), min_time, repeat))
            venv.close()
        rows.append({"id": env_id, "num_envs": n, "sb3_native_env_steps_per_s": rates[0], "sb3_dummy_env_steps_per_s": rates[1], "ratio": rates[0] / rates[1]})
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="rbenvs bench throughput", description="Env-steps per second against Pendulum-v1 and CartPole-v1's native vector env.")
    parser.add_argument("--json", metavar="PATH", help="also write the figures as JSON")
    parser.add_argument("--quick", action="store_true", help="shorter timings, sizes 1 and 256 only")
    parser.add_argument("--no-progress", action="store_true")
    args = parser.parse_args(argv)
    sizes = (1, 256) if args.quick else SIZES
    min_time = 0.05 if args.quick else 0.2
    n_single = sum(len(i) for _, i in SYSTEMS)
    n_vector = sum(1 for _, ints in SYSTEMS for i in ints for n in sizes if n <= LARGEST.get(i, max(sizes))) + len(sizes)
    bar = Progress(n_single + n_vector, not args.no_progress, "bench throughput")
    single = run_single(min_time=min_time, progress=bar.update)
    vector = run_vector(sizes=sizes, min_time=min_time, progress=bar.update)
    sb3 = run_sb3(sizes=(16, 256), min_time=min_time)
    bar.close()
    print("single env: one step of gymnasium.make(id) against Pendulum-v1, same run (us)")
    print(f"{'id':<26} {'integrator':<10} {'ours':>9} {'Pendulum':>9} {'ratio':>7}")
    for r in single:
        print(f"{r['id']:<26} {r['integrator']:<10} {r['step_us']:>9.2f} {r['pendulum_step_us']:>9.2f} {r['ratio_to_pendulum']:>7.3f}")
    print("\nvector env (vector_entry_point) against CartPole-v1's native vector env, same run")
    print(f"{'id':<26} {'integrator':<16} {'num_envs':>8} {'env-steps/s':>13} {'ns/env':>9} {'CartPole/s':>13} {'ratio':>8}")
    for r in vector:
        print(f"{r['id']:<26} {r['integrator']:<16} {r['num_envs']:>8d} {r['env_steps_per_s']:>13.4g} {r['ns_per_env_step']:>9.1f} {r['cartpole_env_steps_per_s']:>13.4g} {r['ratio_to_cartpole']:>8.3f}")
    if sb3:
        print("\nstable-baselines3 VecEnv.step: the native adapter (rbenvs_agents.sb3_vec_env) against DummyVecEnv, same run")
        print(f"{'id':<26} {'num_envs':>8} {'native/s':>12} {'Dummy/s':>12} {'ratio':>8}")
        for r in sb3:
            print(f"{r['id']:<26} {r['num_envs']:>8d} {r['sb3_native_env_steps_per_s']:>12.4g} {r['sb3_dummy_env_steps_per_s']:>12.4g} {r['ratio']:>8.2f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"single": single, "vector": vector, "sb3": sb3}, f, indent=1)
    return 0

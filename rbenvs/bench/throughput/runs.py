"""The timing helpers and the integrator, scaling, SB3 and ``tolerance_check`` tables."""

from __future__ import annotations

import warnings

import numpy as np

from ...compiled import available
from .timing import Peers, _rounds, _time_once, episode_stepper, timed, timed_budget

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
    import rbenvs  # noqa: F401

    cart_rate = _cartpole_rates(sizes, min_time, repeat)
    rows = []
    for env_id, integ, readouts, compiled in _vector_combos(systems):
        for n in sizes:
            if n > LARGEST.get(integ, max(sizes)):
                continue
            t, path = _vector_step_time(
                env_id, integ, readouts, compiled, n, min_time, repeat, budget
            )
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
            if progress:
                progress()
    return rows


def _cartpole_rates(sizes, min_time, repeat) -> dict:
    """CartPole-v1's native vector env, env-steps/s at each N of ``sizes`` (constant action)."""
    import gymnasium as gym

    cart_rate = {}
    for n in sizes:
        cart = gym.make_vec("CartPole-v1", num_envs=n, vectorization_mode="vector_entry_point")
        cart.reset(seed=0)
        a = np.ones(n, dtype=np.int64)
        cart_rate[n] = n / timed(lambda: cart.step(a), min_time, repeat)
        cart.close()
    return cart_rate


def _vector_combos(systems) -> list[tuple]:
    """``(id, integrator, info read-outs, compiled)``: every combination on the path it takes by
    default; the free body with rk4 also on the numpy path (the compiled kernel's
    justification, measured) and without info's physical read-outs."""
    combos = [
        (env_id, integ, True, "auto") for env_id, integrators in systems for integ in integrators
    ]
    for env_id, integrators in systems:
        if env_id == SYSTEMS[0][0] and "rk4" in integrators:
            # (without numba the default rows are the numpy path already)
            combos += [(env_id, "rk4", True, False)] if available() else []
            combos += [(env_id, "rk4", False, "auto")]
    return combos


def _vector_step_time(
    env_id, integ, readouts, compiled, n, min_time, repeat, budget
) -> tuple[float, str]:
    """``(seconds, path)``: one zero-action step of the vector env of ``n`` sub-envs."""
    import gymnasium as gym

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
    venv.close()
    return t, path


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

        from ...vector.sb3 import make_sb3_vec_env
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

    from ...envs import UnstableMotionWarning

    kw = dict(kw, tolerance=CHECK_TOLERANCE, integrator="rk4")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnstableMotionWarning)
        if scene is not None:
            from ...scenes import load_scene

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

"""Timing: best-of repeats in a time budget, steppers of a vector env, and the peers (Pendulum-v1,
CartPole-v1's vector env) measured in the same run."""

from __future__ import annotations

import time

import numpy as np

ACTION_POOL = 16  # random action batches drawn beforehand, cycled


ALTERNATIONS = 3  # rounds of (ours, CartPole) per row; the best of each is kept


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

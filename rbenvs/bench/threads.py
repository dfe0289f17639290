"""``rbenvs bench threads``: the compiled vector env split over threads (``num_threads=``).

Per system, the vector env (``gymnasium.make_vec(..., vectorization_mode="vector_entry_point")``)
at ``--num-envs`` sub-envs (4096) with 1 thread, 2 threads and every core the process may use
(``num_threads="auto"``): env-steps per second under random actions with the episode clocks
staggered (the steady state of a long run; :func:`rbenvs.bench.throughput.stagger_clocks`), each
thread count timed in turn, ``ALTERNATIONS`` rounds, the best of each kept; ``speedup`` is the rate
over the one-thread rate. Beside them, CartPole-v1's native vector env at the same N, measured in
the same run. ``bits``: whether every thread count's observations, rewards, ends and info over
``BITS_STEPS`` steps from ``reset(seed)`` with short episodes (restarts included) equal the
one-thread run's, byte for byte.

A split step runs its sub-envs' arithmetic in chunks, one per thread; what a thread cannot split
is the Python around the kernel (the env's ``info``, the arrays it returns) and the two parallel
regions' launches per step, so the cheaper a system's step per sub-env, the further its speedup
stays below the thread count.
"""

from __future__ import annotations

import hashlib
import json

import numpy as np

from .. import ENVIRONMENTS
from ..extras import ArgumentParser
from ..progress import Progress
from .throughput import (
    ALTERNATIONS,
    Peers,
    counting_stepper,
    random_actions,
    stagger_clocks,
    timed_counting,
)

__all__ = ["main", "run_threads", "trajectory_digest"]

IDS = tuple(ENVIRONMENTS)
NUM_ENVS = 4096
BITS_STEPS = 30
BITS_EPISODE = 10  # (max_episode_steps of the bit check: every sub-env restarts within it)


def _make(env_id: str, n: int, threads, **kwargs):
    import gymnasium as gym

    import rbenvs  # noqa: F401  (registers the ids)

    return gym.make_vec(
        env_id, num_envs=n, vectorization_mode="vector_entry_point", num_threads=threads, **kwargs
    )


def trajectory_digest(env_id: str, n: int, threads, steps: int = BITS_STEPS, seed: int = 0) -> str:
    """SHA-256 of every array ``steps`` steps return (random actions, short episodes)."""
    env = _make(env_id, n, threads, max_episode_steps=BITS_EPISODE)
    digest = hashlib.sha256(env.reset(seed=seed)[0].tobytes())
    for a in random_actions(env.action_space, seed, steps):
        obs, reward, terminated, truncated, info = env.step(a)
        for x in (
            obs,
            reward,
            terminated,
            truncated,
            *(
                info[k]
                for k in sorted(info)
                if isinstance(info[k], np.ndarray) and info[k].dtype != object
            ),
        ):
            digest.update(np.ascontiguousarray(x).tobytes())
    env.close()
    return digest.hexdigest()


def run_threads(
    num_envs: int = NUM_ENVS,
    counts=None,
    min_time: float = 0.2,
    repeat: int = 3,
    budget: float = 1.0,
    ids=IDS,
    progress=None,
) -> list[dict]:
    """One row per id and thread count (``counts``: 1, 2 and every usable core by default)."""
    from ..vector.threads import usable_cores

    counts = sorted(set(counts or (1, 2, usable_cores())))
    peers = Peers(min_time, repeat)
    rows = []
    for env_id in ids:
        steppers = {}
        for t in counts:
            env = _make(env_id, num_envs, t)
            stagger_clocks(env, 0)
            steppers[t] = counting_stepper(env, random_actions(env.action_space, 0))
            steppers[t][0]()  # (a kernel loads or compiles on its first call: not timed)
        best = dict.fromkeys(counts, float("inf"))
        for _ in range(ALTERNATIONS):
            for t, (step, count) in steppers.items():
                best[t] = min(
                    best[t], timed_counting(step, count, min_time, repeat, budget)["seconds"]
                )
        cartpole = peers.cartpole_rate(num_envs)["env_steps_per_s"]
        reference = trajectory_digest(env_id, num_envs, counts[0])
        for t in counts:
            rate = num_envs / best[t]
            rows.append(
                {
                    "id": env_id,
                    "num_envs": num_envs,
                    "threads": t,
                    "env_steps_per_s": rate,
                    "speedup": best[counts[0]] / best[t],
                    "cartpole_env_steps_per_s": cartpole,
                    "ratio_to_cartpole": rate / cartpole,
                    "same_bits": t == counts[0]
                    or trajectory_digest(env_id, num_envs, t) == reference,
                }
            )
        if progress is not None:
            progress()
    peers.close()
    return rows


def main(argv=None) -> int:
    parser = ArgumentParser(
        prog="rbenvs bench threads",
        description="The vector env's env-steps per second with num_threads 1, 2 and every "
        "usable core, against CartPole-v1's native vector env at the same size, and whether the "
        "bits agree.",
    )
    parser.add_argument(
        "--num-envs",
        type=int,
        default=NUM_ENVS,
        metavar="N",
        help="sub-envs of each vector env (default: %(default)s)",
    )
    parser.add_argument(
        "--threads",
        metavar="LIST",
        help="comma-separated thread counts (default: 1, 2 and every usable core)",
    )
    parser.add_argument("--json", metavar="PATH", help="also write the figures as JSON")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    if args.num_envs < 1:
        raise ValueError(f"--num-envs must be >= 1, got {args.num_envs}")
    counts = None
    if args.threads:
        counts = [int(t) for t in args.threads.split(",")]
        if min(counts) < 1:
            raise ValueError(f"--threads: every count must be >= 1, got {args.threads}")
    bar = Progress(len(IDS), not args.no_progress, "bench threads")
    rows = run_threads(args.num_envs, counts, progress=bar.update)
    bar.close()
    from ..vector.threads import usable_cores

    print(
        f"Vector env at N = {args.num_envs}, random actions, staggered clocks; {usable_cores()} "
        "usable cores; speedup: over the first row's rate; "
        "bits: the same observations, rewards, ends and info as the first row's, byte for byte.\n"
    )
    from ..vector.threads import launch_us

    layer, launch = launch_us(max(2, max(r["threads"] for r in rows)))
    print(
        f"numba's threading layer: {layer}; a parallel region of empty chunks (a split step runs "
        f"two): {launch:.1f} us.\n"
    )
    print("| id | threads | env-steps/s | speedup | CartPole-v1/s | ratio | bits |")
    print("|---|---:|---:|---:|---:|---:|---|")
    for r in rows:
        print(
            f"| `{r['id']}` | {r['threads']} | {r['env_steps_per_s']:.4g} | {r['speedup']:.2f} | "
            f"{r['cartpole_env_steps_per_s']:.4g} | "
            f"{r['ratio_to_cartpole']:.3f} | {'same' if r['same_bits'] else 'DIFFER'} |"
        )
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)
    return 0 if all(r["same_bits"] for r in rows) else 1

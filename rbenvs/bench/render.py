"""``rbenvs bench render``: milliseconds per ``rgb_array`` frame.

Per system, ``env.render()`` of the default env (``gymnasium.make(id, render_mode="rgb_array")``)
at a state along its default episode (each frame after one step under random actions, the step
not timed): the frame alone, then one step plus one frame (what ``RecordVideo`` pays per step).
Beside them, measured in the same run and the same way: ``Pendulum-v1``'s frame (gymnasium's
pygame renderer, where pygame is installed); the ratio is ours over Pendulum's. Each figure is
the median over ``--frames`` frames, in ``ROUNDS`` rounds alternating the envs, the best round
kept (a busy machine slows some rounds, never speeds one up).
"""

from __future__ import annotations

import statistics
import time

import numpy as np

from ..extras import ArgumentParser
from ..progress import Progress

__all__ = ["main", "frame_ms"]

PEER = "Pendulum-v1"
ROUNDS = 3


def _pygame_installed() -> bool:
    import importlib.util

    return importlib.util.find_spec("pygame") is not None


def frame_ms(env, frames: int, rng) -> tuple[float, float]:
    """Median milliseconds of ``env.render()`` alone and of one step plus one render, over
    ``frames`` of each."""

    def step(action):  # an episode that ends starts again (the reset not timed)
        _, _, terminated, truncated, _ = env.step(action)
        return terminated or truncated

    render, both = [], []
    for _ in range(frames):
        action = env.action_space.sample()
        if step(action):
            env.reset(seed=int(rng.integers(2**31)))
        t0 = time.perf_counter()
        env.render()
        render.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        ended = step(action)
        env.render()
        both.append(time.perf_counter() - t0)
        if ended:
            env.reset(seed=int(rng.integers(2**31)))
    return 1e3 * statistics.median(render), 1e3 * statistics.median(both)


def main(argv=None) -> int:
    import gymnasium as gym

    import rbenvs  # (registers the ids)

    parser = ArgumentParser(
        prog="rbenvs bench render",
        description="Milliseconds per rgb_array frame (480x480) for every system, "
        f"beside {PEER}'s pygame frame (same run)",
    )
    parser.add_argument(
        "--frames",
        type=int,
        default=100,
        help="frames per env and round, their median taken (default: %(default)s)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    if args.frames < 1:
        parser.error("--frames must be >= 1")
    ids = list(rbenvs.ENVIRONMENTS) + ([PEER] if _pygame_installed() else [])
    envs = {}
    for env_id in ids:
        env = gym.make(env_id, render_mode="rgb_array")
        env.action_space.seed(0)
        env.reset(seed=0)
        env.render()  # (the first frame: imports, kernels)
        envs[env_id] = env
    rng = np.random.default_rng(0)
    best: dict = {}
    bar = Progress(ROUNDS * len(ids), enabled=not args.no_progress, desc="bench render")
    for _ in range(ROUNDS):
        for env_id, env in envs.items():
            render, both = frame_ms(env, args.frames, rng)
            old = best.get(env_id)
            best[env_id] = (
                (render, both) if old is None else (min(old[0], render), min(old[1], both))
            )
            bar.update()
    bar.close()
    shapes = {env_id: env.render().shape for env_id, env in envs.items()}
    for env in envs.values():
        env.close()
    peer = best.get(PEER)
    print(
        f"Milliseconds per rgb_array frame: median over {args.frames} frames along an episode "
        "under "
        f"random actions, best of {ROUNDS} rounds; "
        f"ratio: over {PEER}'s frame"
        + ("" if peer else f" ({PEER} not measured: pygame is not installed)")
        + ".\n"
    )
    print("| env | frame | render (ms) | step + render (ms) | / Pendulum |")
    print("|---|---|---:|---:|---:|")
    for env_id, (render, both) in best.items():
        h, w, _ = shapes[env_id]
        ratio = f"{render / peer[0]:.1f}" if peer and env_id != PEER else "-"
        print(f"| `{env_id}` | {h}x{w} | {render:.2f} | {both:.2f} | {ratio} |")
    return 0

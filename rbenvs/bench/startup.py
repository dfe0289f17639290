"""``rbenvs bench startup``: how long a fresh process waits for its first step.

Per system, the single env (``gymnasium.make``) and the vector env at 64 sub-envs
(``gymnasium.make_vec(..., vectorization_mode="vector_entry_point")``), each in a new Python
process: import (``gymnasium`` and ``rbenvs``), make, reset, first step, and their total;
**cold** (an empty kernel cache: every kernel compiled) and **warm** (the cache the cold run
filled: every kernel loaded; :mod:`rbenvs.kernel_cache`). Beside them, measured in the same run
and the same way: ``Pendulum-v1`` (single), CartPole-v1's native vector env at 64, and MuJoCo
(import, a model from XML, its data and first ``mj_step``) where it is installed; the ratio is
our warm total over Pendulum's. Then gymnasium's ``AsyncVectorEnv(context="spawn")`` with 4
workers of each id, on an empty cache and on the warm one: the seconds until ``reset`` returns
(every worker a new process that imports and makes its env) and then until the first ``step``
does (each worker compiles or loads its kernels).

The kernel caches live in a temporary folder the benchmark makes and deletes (``RBENVS_CACHE_DIR``
for its processes), so the user's own cache is neither read nor filled. Warm figures are the
median of ``--repeat`` processes; cold ones are one process each (a cold start compiles every
kernel). Every process reads compiled bytecode, as from an installed wheel (pip writes it at
install): the package's ``__pycache__`` is filled first and ``PYTHONDONTWRITEBYTECODE`` is not
passed on (in an editable checkout under that variable, every process would compile rbenvs'
sources again). ``--docs PAGE`` writes the table into the page's block.
"""

from __future__ import annotations

import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile

from ..extras import ArgumentParser
from ..progress import Progress

__all__ = ["main", "SYSTEMS", "VECTOR_ENVS"]

SYSTEMS = (
    ("free_body", "rbenvs/FreeRigidBody-v0"),
    ("heavy_top", "rbenvs/LagrangeTop-v0"),
    ("tippe_top", "rbenvs/TippeTop-v0"),
)
VECTOR_ENVS = 64
ASYNC_WORKERS = 4

# One fresh process: the phases of a first step, as seconds (JSON on the last line). The env is
# made as a user makes it; the first step's action is the zero action (a sample would draw).
_PROCESS = r"""
import json, sys, time
t0 = time.perf_counter()
import gymnasium as gym
import numpy as np
what, n = sys.argv[1], int(sys.argv[2])
if what.startswith("rbenvs/"):
    import rbenvs
t1 = time.perf_counter()
if n:
    env = gym.make_vec(what, num_envs=n, vectorization_mode="vector_entry_point")
else:
    env = gym.make(what)
t2 = time.perf_counter()
env.reset(seed=0)
t3 = time.perf_counter()
env.step(
    np.zeros(env.action_space.shape, dtype=env.action_space.dtype)
    if env.action_space.dtype.kind == "f"
    else env.action_space.sample()
)
t4 = time.perf_counter()
stats = {}
if what.startswith("rbenvs/"):
    from rbenvs import kernel_cache
    stats = kernel_cache.stats()
print(json.dumps({
    "import": t1 - t0, "make": t2 - t1, "reset": t3 - t2, "step": t4 - t3, "total": t4 - t0,
    "stats": stats,
}))
"""

_MUJOCO = r"""
import json, time
t0 = time.perf_counter()
import mujoco
t1 = time.perf_counter()
model = mujoco.MjModel.from_xml_string(
    '<mujoco><worldbody><body><freejoint/><geom type="box" size=".3 .2 .1"/></body>'
    '</worldbody></mujoco>'
)
data = mujoco.MjData(model)
t2 = time.perf_counter()
mujoco.mj_resetData(model, data)
t3 = time.perf_counter()
mujoco.mj_step(model, data)
t4 = time.perf_counter()
print(json.dumps({
    "import": t1 - t0, "make": t2 - t1, "reset": t3 - t2, "step": t4 - t3, "total": t4 - t0,
    "stats": {},
}))
"""

_ASYNC = r"""
import json, sys, time
import gymnasium as gym
import rbenvs
from gymnasium.vector import AsyncVectorEnv
env_id, k = sys.argv[1], int(sys.argv[2])
if __name__ == "__main__":
    t0 = time.perf_counter()
    env = AsyncVectorEnv([lambda: gym.make(env_id) for _ in range(k)], context="spawn")
    env.reset(seed=0)
    t1 = time.perf_counter()
    env.step(env.action_space.sample())
    t2 = time.perf_counter()
    env.close()
    print(json.dumps({"reset": t1 - t0, "step": t2 - t1}))
"""


def _environment() -> dict:
    env = dict(os.environ)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def _compile_bytecode() -> None:
    """rbenvs' bytecode written beside its sources: a no-op for a wheel (pip wrote it); in a
    read-only folder Python compiles the sources in every process, as it does for that user."""
    import rbenvs

    folder = os.path.dirname(rbenvs.__file__)
    subprocess.run(
        [sys.executable, "-m", "compileall", "-q", folder],
        env=_environment(),
        capture_output=True,
        timeout=600,
    )


def _run(source: str, args: list, cache: str | None, script_dir: str | None = None) -> dict:
    env = _environment()
    if cache is not None:
        env["RBENVS_CACHE_DIR"] = cache
    if script_dir is not None:  # (spawn re-imports the main module: it must be a file)
        path = os.path.join(script_dir, "async_reset.py")
        with open(path, "w") as f:
            f.write(source)
        cmd = [sys.executable, path, *map(str, args)]
    else:
        cmd = [sys.executable, "-c", source, *map(str, args)]
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=1800)
    if out.returncode != 0:
        raise RuntimeError(
            f"bench startup: {' '.join(map(str, args))} failed:\n{out.stderr[-2000:]}"
        )
    return json.loads(out.stdout.strip().splitlines()[-1])


def _mujoco_installed() -> bool:
    import importlib.util

    return importlib.util.find_spec("mujoco") is not None


def _row(
    label: str, kind: str, cold: dict | None, warm: list[dict], reference: float | None
) -> str:
    w = {
        k: statistics.median(r[k] for r in warm)
        for k in ("import", "make", "reset", "step", "total")
    }
    cold_total = f"{cold['total']:.2f}" if cold is not None else "-"
    kernels = ""
    if cold is not None and cold["stats"]:
        kernels = f"{cold['stats'].get('compiled', 0)}/{warm[0]['stats'].get('loaded', 0)}"
    ratio = f"{w['total'] / reference:.1f}" if reference else "-"
    return (
        f"| {label} | {kind} | {cold_total} | {w['import']:.2f} | {w['make']:.2f} | "
        f"{w['reset']:.3f} | {w['step']:.3f} | **{w['total']:.2f}** | "
        f"{ratio} | {kernels} |"
    )


def _parser():
    parser = ArgumentParser(
        prog="rbenvs bench startup",
        description="Seconds from a fresh process to its first step: each system's single env and "
        f"vector env at {VECTOR_ENVS}, cold and warm kernel cache, beside Pendulum-v1, "
        "CartPole-v1's vector env and MuJoCo (same run)",
    )
    parser.add_argument(
        "--system",
        action="append",
        choices=[s for s, _ in SYSTEMS],
        help="restrict to these systems (repeatable; default all)",
    )
    parser.add_argument(
        "--repeat",
        type=int,
        default=3,
        help="warm processes per row, their median taken (default: %(default)s)",
    )
    parser.add_argument(
        "--no-async",
        action="store_true",
        help=f"skip the AsyncVectorEnv(context='spawn') rows ({ASYNC_WORKERS} workers each)",
    )
    parser.add_argument("--json", metavar="PATH", help="also write the figures as JSON")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    return parser


def _measure(args, systems, mujoco: bool) -> tuple[dict, dict]:
    """Every row's processes, cold then warm (``results``), and the spawned workers' resets
    (``spawn``), each system's kernels in a cache folder of its own, deleted after."""
    n_rows = 2 * len(systems) + 2 + mujoco
    bar = Progress(
        n_rows * (1 + args.repeat) + (0 if args.no_async else 2 * len(systems)),
        enabled=not args.no_progress,
        desc="bench startup",
    )
    results: dict = {}
    spawn: dict = {}
    root = tempfile.mkdtemp(prefix="rbenvs-bench-startup-")
    _compile_bytecode()
    try:

        def measure(key, source, argv_, cache):
            # an empty cache of its own, then the same cache warm (peers: no cache, no cold row)
            cold = _run(source, argv_, cache) if cache is not None else None
            bar.update()
            warm = []
            for _ in range(args.repeat):
                warm.append(_run(source, argv_, cache))
                bar.update()
            results[key] = {"cold": cold, "warm": warm}

        measure(("Pendulum-v1", "single"), _PROCESS, ["Pendulum-v1", 0], None)
        measure(
            ("CartPole-v1", f"vector {VECTOR_ENVS}"), _PROCESS, ["CartPole-v1", VECTOR_ENVS], None
        )
        if mujoco:
            measure(("MuJoCo (XML model)", "single"), _MUJOCO, [], None)
        for name, env_id in systems:
            for n, kind in ((0, "single"), (VECTOR_ENVS, f"vector {VECTOR_ENVS}")):
                measure((env_id, kind), _PROCESS, [env_id, n], os.path.join(root, f"{name}-{n}"))
        if not args.no_async:
            for name, env_id in systems:
                # cold: an empty cache of its own, the workers compiling at once; warm: the
                # single env's kernels
                times = {}
                for when, cache in (("cold", f"{name}-spawn"), ("warm", f"{name}-0")):
                    cache = os.path.join(root, cache)
                    out = _run(_ASYNC, [env_id, ASYNC_WORKERS], cache, script_dir=root)
                    times[when] = (out["reset"], out["step"])
                    bar.update()
                spawn[env_id] = times
    finally:
        shutil.rmtree(root, ignore_errors=True)
        bar.close()
    return results, spawn


def _print_tables(results: dict, spawn: dict, repeat: int) -> None:
    reference = statistics.median(r["total"] for r in results[("Pendulum-v1", "single")]["warm"])
    print(
        "Seconds from a fresh process to its first step (import gymnasium and the package, make, "
        f"reset, one step); warm: median of {repeat} "
        "processes on the kernel cache the cold process filled; ratio: warm total over "
        "Pendulum-v1's; kernels: compiled cold / loaded warm.\n"
    )
    print(
        "| env | kind | cold total | import | make | reset | first step | warm total | "
        "/ Pendulum | kernels |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for (label, kind), r in results.items():
        print(
            _row(
                label if not label.startswith("rbenvs/") else f"`{label}`",
                kind,
                r["cold"],
                r["warm"],
                reference if label != "Pendulum-v1" else None,
            )
        )
    if spawn:
        print(
            f'\ngymnasium\'s AsyncVectorEnv(context="spawn") with {ASYNC_WORKERS} workers: '
            "seconds until reset returns, then until the first step does (where the workers "
            "compile or load their kernels), on an empty kernel cache (the workers compile at "
            "once: one compiles each kernel, the others wait for its file) and on a warm one\n"
        )
        print("| id | cold: reset | cold: first step | warm: reset | warm: first step |")
        print("|---|---:|---:|---:|---:|")
        for env_id, t in spawn.items():
            (cr, cs), (wr, ws) = t["cold"], t["warm"]
            print(f"| `{env_id}` | {cr:.2f} | {cs:.2f} | {wr:.2f} | {ws:.2f} |")


def main(argv=None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    if args.repeat < 1:
        parser.error("--repeat must be >= 1")
    systems = [(s, i) for s, i in SYSTEMS if not args.system or s in args.system]
    results, spawn = _measure(args, systems, _mujoco_installed())
    _print_tables(results, spawn, args.repeat)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(
                {
                    "rows": [
                        {"env": label, "kind": kind, **r} for (label, kind), r in results.items()
                    ],
                    "async_spawn": spawn,
                },
                f,
                indent=1,
            )
    return 0

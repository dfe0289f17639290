"""``rbenvs bench costs``: what the README's two commands cost, measured on this machine.

The README states how big the set-up is and how long the main job and the tests take; typed by
hand those figures go stale. Here each is measured, and ``--docs README.md`` writes them
into the README's block:

* **the venv**: the size of the running interpreter's environment (``sys.prefix``), the one
  ``make`` set up;
* **the main job** (``make run``): ``rbenvs-train --algo ppo --scene default --seed 0`` into a
  temporary folder, wall time;
* **the test suite** (``make test``): ``pytest -n auto --maxprocesses 8`` in the repository,
  first with an empty kernel cache (a clean clone: every kernel compiled), then again on the
  cache that run filled; wall time and CPU time (user + system of every process it ran), which
  says how much of the wall time a machine with more cores would save; then
  ``rbenvs verify --quick``, wall time.

Every step runs as a new process with this interpreter; a step that fails stops the command
(exit 1, its output's tail shown) and nothing is written. The suite's runs take most of the
time; ``--skip-tests`` measures the rest.
"""

from __future__ import annotations

import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from ..extras import ArgumentParser
from ..progress import Progress

__all__ = ["main", "folder_bytes"]


def folder_bytes(path) -> int:
    """Bytes of the files under ``path`` (links not followed)."""
    total = 0
    for root, _, files in os.walk(path):
        for name in files:
            p = os.path.join(root, name)
            if not os.path.islink(p):
                total += os.path.getsize(p)
    return total


def _timed(cmd, cwd, env=None) -> tuple[float, float, str]:
    """``(wall s, CPU s of the process and its descendants, output tail)``; raises on failure."""
    import resource  # (POSIX: the command's --help still works elsewhere)

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    out = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    tail = (out.stdout + out.stderr)[-3000:]
    if out.returncode != 0:
        raise RuntimeError(f"`{' '.join(map(str, cmd))}` failed (exit {out.returncode}):\n{tail}")
    return wall, cpu, tail


def _minutes(seconds: float) -> str:
    minutes, rest = divmod(int(round(seconds)), 60)
    return f"{minutes} min {rest:02d} s" if minutes else f"{rest} s"


def _summary(tail: str) -> str:
    """pytest's last line (``N passed, ... in ...``) without its own timing."""
    lines = [ln.strip("= ") for ln in tail.splitlines() if " passed" in ln or " failed" in ln]
    return lines[-1].split(" in ")[0] if lines else "?"


def _parser():
    parser = ArgumentParser(
        prog="rbenvs bench costs",
        description="The README's costs measured here: the venv's size, the main job's "
        "time, the test suite's wall and CPU time (empty and filled kernel cache) and verify "
        "--quick's time",
    )
    parser.add_argument(
        "--skip-tests",
        action="store_true",
        help=(
            "leave out the test suite's two runs (most of the time: the README's block says how "
            "long they took)"
        ),
    )
    parser.add_argument(
        "--root", default=".", help="the repository whose tests run (default: the current folder)"
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    return parser


def _main_job_row(bindir: Path, scratch: str) -> tuple:
    train = shutil.which("rbenvs-train", path=str(bindir)) or "rbenvs-train"
    out = os.path.join(scratch, "run")
    argv = [train, "--algo", "ppo", "--scene", "default", "--seed", "0", "--out", out]
    wall, cpu, _ = _timed([*argv, "--no-progress"], cwd=scratch)
    what = "main job: `rbenvs-train --algo ppo --scene default --seed 0`"
    return what, _minutes(wall), f"CPU {_minutes(cpu)}"


def _test_rows(root: Path, scratch: str, bar) -> list[tuple]:
    """The suite twice on a kernel cache of its own: empty, then as the first run left it."""
    env = dict(os.environ, RBENVS_CACHE_DIR=os.path.join(scratch, "kernels"))
    pytest = [sys.executable, "-m", "pytest", "-q", "-n", "auto", "--maxprocesses", "8"]
    rows = []
    for label in ("empty kernel cache (a clean clone)", "kernel cache filled by the run before"):
        wall, cpu, tail = _timed([*pytest, "-p", "no:cacheprovider"], cwd=root, env=env)
        rows.append(
            (f"test suite, {label}", _minutes(wall), f"CPU {_minutes(cpu)}; {_summary(tail)}")
        )
        bar.update()
    return rows


def _verify_row(bindir: Path, scratch: str) -> tuple:
    rbenvs = shutil.which("rbenvs", path=str(bindir)) or "rbenvs"
    report = os.path.join(scratch, "verify.json")
    wall, cpu, _ = _timed(
        [rbenvs, "verify", "--quick", "--no-progress", "--json", report], cwd=scratch
    )
    return "`rbenvs verify --quick`", _minutes(wall), f"CPU {_minutes(cpu)}"


def main(argv=None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    root = Path(args.root).resolve()
    if not args.skip_tests and not (root / "tests").is_dir():
        parser.error(
            f"{root} has no tests/ folder: run in the repository (or --root PATH), or pass "
            "--skip-tests"
        )
    bindir = Path(sys.executable).parent
    rows = [("venv (`sys.prefix`)", f"{folder_bytes(sys.prefix) / 1e9:.2f} GB", "")]
    scratch = tempfile.mkdtemp(prefix="rbenvs-bench-costs-")
    bar = Progress(
        2 + (0 if args.skip_tests else 2), enabled=not args.no_progress, desc="bench costs"
    )
    try:
        rows.append(_main_job_row(bindir, scratch))
        bar.update()
        if not args.skip_tests:
            rows += _test_rows(root, scratch, bar)
        rows.append(_verify_row(bindir, scratch))
        bar.update()
    except RuntimeError as exc:
        print(f"rbenvs bench costs: {exc}", file=sys.stderr)
        return 1
    finally:
        bar.close()
        shutil.rmtree(scratch, ignore_errors=True)
    print(
        f"What the README's two commands cost on this machine ({os.cpu_count()} cores, "
        f"{platform.machine()}); each step a new process, run once.\n"
    )
    print("| what | wall time / size | also |")
    print("|---|---:|---|")
    for what, figure, also in rows:
        print(f"| {what} | {figure} | {also} |")
    return 0

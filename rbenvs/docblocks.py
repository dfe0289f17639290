"""Figures in the docs written by the commands that measure them: ``--docs PAGE``.

Every command line of the project (``rbenvs ...``, ``rbenvs-train``, ``rbenvs-eval``,
``rbenvs-results``) takes ``--docs PAGE``: the command runs as usual, and when it succeeds its
standard output (the tables it printed; progress bars go to stderr) replaces the block of PAGE
that names the same command line::

    <!-- rbenvs:output rbenvs bench fidelity -->
    (written here by the command: a line with the command, date, machine and wall time, then
    the output in a fenced block, or as it is when it is a Markdown table or list)
    <!-- rbenvs:end -->

The command line in the marker is the one run, without ``--docs`` and ``--no-progress``. A page
without that block is refused (the command says which marker to add) before the command runs,
so that a long run never ends in a figure with nowhere to go. ``tests/test_docs.py`` holds the
other half of the rule: every fenced block without a language in the README and ``docs/`` (a
figure or a command's output) lies inside such a block, and each block's command line is one
the command accepts. Blocks of illustration (a tree, a sketch) say ``text`` on their fence.

:func:`run_with_docs` is called by :func:`rbenvs.extras.run_command`, the one entry of every
command line.
"""

from __future__ import annotations

import datetime
import os
import platform
import re
import shlex
import sys
import time
from pathlib import Path

__all__ = [
    "BEGIN",
    "END",
    "split_docs_flag",
    "command_key",
    "find_block",
    "write_block",
    "machine",
    "run_with_docs",
    "blocks",
]

BEGIN = "<!-- rbenvs:output {} -->"
END = "<!-- rbenvs:end -->"
_BLOCK = re.compile(
    r"<!-- rbenvs:output ([^\n]+?) -->\n(.*?)<!-- rbenvs:end -->", re.S
)  # (a command line is one line)
# flags that change how a command shows itself, not what it measures
_NOT_PART_OF_THE_KEY = ("--no-progress",)


def split_docs_flag(argv: list[str]) -> tuple[list[str], str | None]:
    """``argv`` without ``--docs PAGE`` (or ``--docs=PAGE``), and PAGE (None when absent)."""
    rest, page, i = [], None, 0
    while i < len(argv):
        arg = argv[i]
        if arg == "--docs":
            if i + 1 >= len(argv):
                raise ValueError("--docs needs a page: --docs docs/PAGE.md")
            page, i = argv[i + 1], i + 2
            continue
        if arg.startswith("--docs="):
            page = arg.split("=", 1)[1]
        else:
            rest.append(arg)
        i += 1
    return rest, page


def command_key(prog: str, argv: list[str]) -> str:
    """The command line as the marker names it: ``prog`` and its arguments, quoted as a shell
    would need them, without the flags of :data:`_NOT_PART_OF_THE_KEY`."""
    return " ".join([prog] + [shlex.quote(a) for a in argv if a not in _NOT_PART_OF_THE_KEY])


def blocks(text: str) -> list[tuple[str, str]]:
    """Every ``(command line, content)`` block of a page's text."""
    return [(m.group(1), m.group(2)) for m in _BLOCK.finditer(text)]


def find_block(text: str, key: str) -> re.Match | None:
    for m in _BLOCK.finditer(text):
        if m.group(1) == key:
            return m
    return None


def machine() -> str:
    """The machine in a few words: CPU model, core count, OS and Python."""
    model = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return (
        f"{os.cpu_count()} cores, {model}, {platform.system()}, Python {platform.python_version()}"
    )


def write_block(
    page: str | Path,
    key: str,
    output: str,
    seconds: float | None = None,
    when: datetime.date | None = None,
) -> None:
    """Replace the content of ``page``'s block for ``key`` with ``output`` (fenced), under a line
    naming the command, the date, the machine and the wall time."""
    path = Path(page)
    text = path.read_text()
    m = find_block(text, key)
    if m is None:
        raise ValueError(missing_block(path, key))
    when = when or datetime.date.today()
    took = f", {_duration(seconds)}" if seconds is not None else ""
    lines = [line for line in output.strip().splitlines() if line.strip()]
    if lines and (
        all(line.startswith("|") for line in lines) or all(line.startswith("- ") for line in lines)
    ):
        shown = output.strip() + "\n"  # a Markdown table or list: the page renders it as one
    else:
        fence = "````" if "```" in output else "```"
        shown = f"{fence}\n{output.rstrip()}\n{fence}\n"
    body = f"`{key}` ({when.isoformat()}, {machine()}{took}):\n\n{shown}"
    path.write_text(text[: m.start(2)] + body + text[m.end(2) :])


def missing_block(path: Path, key: str) -> str:
    return (
        f"--docs {path}: the page has no block for `{key}`; add the two lines "
        f"'{BEGIN.format(key)}' and '{END}' where its output belongs"
    )


def _duration(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.1f} min"


class _Tee:
    """Standard output that also keeps what passes through it."""

    def __init__(self, stream):
        self._stream = stream
        self.kept: list[str] = []

    def write(self, s):
        self.kept.append(s)
        return self._stream.write(s)

    def flush(self):
        self._stream.flush()

    def __getattr__(self, name):  # isatty, fileno, encoding: the real stream's
        return getattr(self._stream, name)


def run_with_docs(prog: str, body, argv: list[str]) -> int:
    """``body(argv)``; with ``--docs PAGE`` in ``argv``: ``body`` without it, its standard output
    kept and written into PAGE's block for the command line when the exit status is 0."""
    argv, page = split_docs_flag(sys.argv[1:] if argv is None else list(argv))
    if page is None:
        return body(argv)
    key = command_key(prog, argv)
    path = Path(page)
    if not path.is_file():
        raise ValueError(f"--docs {page}: no such page")
    if find_block(path.read_text(), key) is None:
        raise ValueError(missing_block(path, key))
    tee, real = _Tee(sys.stdout), sys.stdout
    start = time.perf_counter()
    sys.stdout = tee
    try:
        status = body(argv)
    finally:
        sys.stdout = real
    if status == 0:
        write_block(path, key, "".join(tee.kept), time.perf_counter() - start)
        print(f"output written into {page} (block `{key}`)")
    else:
        print(f"--docs {page}: not written (exit status {status})", file=sys.stderr)
    return status

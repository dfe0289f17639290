"""The published comparison of simulators (``rbenvs verify --simulator ... --docs PAGE``): one
table, a row per check and a column per simulator, written between two marker comments of a
page (docs/verification.md), with the command, the date and the machine that produced it."""

from __future__ import annotations

import datetime
import os
import platform
import re
import shlex

__all__ = ["BEGIN", "END", "comparison_table", "write_comparison"]

BEGIN = "<!-- rbenvs verify --docs: begin -->"
END = "<!-- rbenvs verify --docs: end -->"


def _cell(check) -> str:
    if not check.applies:
        return "n/a"
    value = check.measured
    text = f"{value:.3g}" if value == value else "nan"
    return f"{check.result} {text}"


def comparison_table(checks) -> list[str]:
    """Markdown lines: one row per (system, check) in the order first met, one column per
    simulator, each cell ``PASS|FAIL measured`` or ``n/a``; the tolerance of each cell is in the
    command's own table and JSON."""
    sims = list(dict.fromkeys(c.integrator for c in checks))
    keys = list(dict.fromkeys((c.system, c.check) for c in checks))
    cells: dict = {}
    for c in checks:  # several rows of one check (the free body's axis bodies): the worst shows
        key = (c.system, c.check, c.integrator)
        if key not in cells or (cells[key].passed and not c.passed):
            cells[key] = c
    lines = ["| system | check | " + " | ".join(f"`{s}`" for s in sims) + " |", "|---|---|" + "---|" * len(sims)]
    for system, check in keys:
        row = [_cell(cells[(system, check, s)]) if (system, check, s) in cells else "-" for s in sims]
        lines.append(f"| {system} | {check.replace('|', '&#124;')} | " + " | ".join(row) + " |")
    return lines


def write_comparison(page, checks, argv, seconds) -> None:
    """Replace what lies between :data:`BEGIN` and :data:`END` in ``page`` by the table of
    ``checks``, the command (``argv``) and where and when it ran."""
    text = open(page).read()
    if BEGIN not in text or END not in text:
        raise ValueError(f"{page} has no {BEGIN!r} ... {END!r} markers to write between")
    versions = []
    try:
        import mujoco

        versions.append(f"mujoco {mujoco.__version__}")
    except ImportError:
        pass
    date = datetime.date.today().isoformat()
    machine = f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}" + "".join(f", {v}" for v in versions)
    passed = sum(c.passed and c.applies for c in checks)
    failed = sum(not c.passed for c in checks)
    na = sum(not c.applies for c in checks)
    block = [BEGIN, "",
             f"Written by `rbenvs verify {' '.join(shlex.quote(a) for a in argv)}` on {date} ({machine}; "
             f"{seconds:.0f} s): {passed} passed, {failed} failed, {na} n/a.", ""] + comparison_table(checks) + ["", END]
    new = re.sub(re.escape(BEGIN) + ".*?" + re.escape(END), lambda m: "\n".join(block), text, count=1, flags=re.S)
    with open(page, "w") as f:
        f.write(new)

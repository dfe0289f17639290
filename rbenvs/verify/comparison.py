"""The published comparison of simulators (``rbenvs verify --simulator ... --comparison``): one
Markdown table, a row per check and a column per simulator, each cell the check's result and
measured value; ``--docs PAGE`` writes it into the page with its command, date and machine
(:mod:`rbenvs.docblocks`)."""

from __future__ import annotations

__all__ = ["comparison_table"]


def _cell(check) -> str:
    if not check.applies:
        return "n/a"
    value = check.measured
    text = f"{value:.3g}" if value == value else "nan"
    return f"{check.result} {text}"


def _versions() -> str:
    try:
        import mujoco
    except ImportError:
        return ""
    return f" (mujoco {mujoco.__version__})"


def comparison_table(checks) -> list[str]:
    """Markdown lines: one row per (system, check) in the order first met, one column per
    simulator, each cell ``PASS|FAIL measured`` or ``n/a``, and a last row counting each
    column's passes, failures and n/a; the tolerance of each cell is in the command's own table
    and JSON."""
    sims = list(dict.fromkeys(c.integrator for c in checks))
    keys = list(dict.fromkeys((c.system, c.check) for c in checks))
    cells: dict = {}
    for c in checks:  # several rows of one check (the free body's axis bodies): the worst shows
        key = (c.system, c.check, c.integrator)
        if key not in cells or (cells[key].passed and not c.passed):
            cells[key] = c
    versions = _versions()
    header = [f"`{s}`" + (versions if s.startswith("mujoco") else "") for s in sims]
    lines = ["| system | check | " + " | ".join(header) + " |", "|---|---|" + "---|" * len(sims)]
    for system, check in keys:
        row = [
            _cell(cells[(system, check, s)]) if (system, check, s) in cells else "-" for s in sims
        ]
        lines.append(f"| {system} | {check.replace('|', '&#124;')} | " + " | ".join(row) + " |")
    counts = []
    for s in sims:
        mine = [c for c in checks if c.integrator == s]
        counts.append(
            f"{sum(c.passed and c.applies for c in mine)} / {sum(not c.passed for c in mine)} / "
            f"{sum(not c.applies for c in mine)}"
        )
    lines.append("| all | passed / failed / n/a | " + " | ".join(counts) + " |")
    return lines

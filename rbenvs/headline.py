"""``rbenvs headline``: the README's headline figures, from the records the measuring commands
wrote.

The README quotes a few figures (checks passed, speed against the peers, agents that succeed).
Typed by hand they go stale the first time a measuring command runs again; so they are made
here from that command's own record (its ``--json``) and written into the README's block by
``rbenvs headline --docs README.md``, each bullet naming the command and the date of the page
block that run wrote (:mod:`rbenvs.docblocks`). A record that is missing is an error naming the
command that makes it.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from .docblocks import find_block

__all__ = ["SOURCES", "headline", "main"]

# each record: (name, the file, the command that writes it, the page whose block that command wrote)
SOURCES = {
    "verify": ("docs/verify.json", "rbenvs verify --json docs/verify.json", "docs/verification.md"),
    "throughput": (
        "docs/throughput.json",
        "rbenvs bench throughput --json docs/throughput.json",
        "docs/vector.md",
    ),
    "results": (
        "docs/results.json",
        "rbenvs-results --from-json docs/results.json",
        "docs/agents.md",
    ),
}

_DATE = re.compile(r"\((\d{4}-\d{2}-\d{2}),")
_SYSTEMS = (
    ("FreeRigidBody-v0", "free body"),
    ("LagrangeTop-v0", "heavy top"),
    ("TippeTop-v0", "tippe top"),
)
_BASELINES = ("zero action", "analytic")


def _record(root: Path, name: str):
    path, command, _ = SOURCES[name]
    file = root / path
    if not file.is_file():
        raise ValueError(f"{path} is missing: it is written by `{command}`")
    return json.loads(file.read_text())


def _date(root: Path, name: str) -> str:
    """The date in the header of the page block the record's command wrote (``?`` if none)."""
    _, command, page = SOURCES[name]
    m = find_block((root / page).read_text(), command) if (root / page).is_file() else None
    d = _DATE.search(m.group(2)) if m else None
    return d.group(1) if d else "?"


def _span(values) -> str:
    lo, hi = min(values), max(values)
    return f"{lo:.2f}" if f"{lo:.2f}" == f"{hi:.2f}" else f"{lo:.2f}-{hi:.2f}"


def _outcome(record) -> str:
    """``success / return`` of a results row (the return where the record has it)."""
    out = f"{record['success_mean']:.0%}"
    return out + (
        f" / {record['return_mean']:.1f}" if record.get("return_mean") is not None else ""
    )


def headline(root: str | Path = ".") -> str:
    """The headline bullets (Markdown) from the records under ``root`` (the repository)."""
    root = Path(root)
    return "\n".join((_verification_line(root), _speed_line(root), _agents_line(root)))


def _verification_line(root: Path) -> str:
    checks = [
        c for c in _record(root, "verify") if c.get("applies", True)
    ]  # (a row that does not apply fails nothing)
    passed = sum(1 for c in checks if c["passed"])
    systems = sorted({c["system"] for c in checks})
    return (
        f"- **Verification** (`rbenvs verify`, {_date(root, 'verify')}): {passed} of {len(checks)} "
        "checks pass, on "
        f"{', '.join(systems)} ([verification](docs/verification.md))."
    )


def _speed_line(root: Path) -> str:
    rows = [r for r in _record(root, "throughput")["tasks"] if r["scene"] is None]
    single = "; ".join(
        f"{label} {_span([r['single_ratio_to_pendulum'] for r in rows if r['id'].endswith(sid)])}"
        for sid, label in _SYSTEMS
        if any(r["id"].endswith(sid) for r in rows)
    )
    vector = ", ".join(
        f"{label} {r['task']} {r['ratio_to_cartpole']:.2f}x"
        for sid, label in _SYSTEMS[:2]
        for r in rows
        if r["id"].endswith(sid) and r.get("ratio_to_cartpole") is not None
    )
    tippe = [
        r["compiled_over_numpy"]
        for r in rows
        if r["id"].endswith(_SYSTEMS[2][0]) and r.get("compiled_over_numpy")
    ]
    n = rows[0]["num_envs"] if rows else 0
    text = (
        f"- **Speed** (`rbenvs bench throughput`, {_date(root, 'throughput')}; "
        "[throughput](docs/vector.md#throughput)): one step of the "
        f"single env against one `Pendulum-v1` step: {single}. At {n} sub-envs with random actions "
        "and restarts, against "
        f"`CartPole-v1`'s native vector env: {vector}"
    )
    if tippe:
        text += f"; the tippe top {min(tippe):.1f}-{max(tippe):.1f}x its own numpy path"
    return text + "."


def _agents_line(root: Path) -> str:
    # the evaluations on each scene's own parameters (the held-out ones are the robustness table's)
    results = [r for r in _record(root, "results") if r.get("evaluation", "nominal") == "nominal"]
    learned = [r for r in results if r["agent"] not in _BASELINES]
    seeds = max((r["seeds"] for r in results), default=0)
    scenes = list(dict.fromkeys(r["scene"] for r in results))  # (the table's order)
    covered = [s for s in scenes if any(r["scene"] == s for r in learned)]
    text = (
        f"- **Agents** (`rbenvs-results`, {_date(root, 'results')}; [baseline "
        "agents](docs/agents.md)): learned agents on "
        f"{len(covered)} of {len(scenes)} scenes, {seeds} seeds each; per scene the best learned "
        "agent's success and return "
        f"against the analytic controller's: "
    )
    best = []
    for scene in covered:
        # the best: most success, then most return (a tie in success is told apart by the return)
        top = max(
            (r for r in learned if r["scene"] == scene),
            key=lambda r: (r["success_mean"], r.get("return_mean", 0.0)),
        )
        ref = [r for r in results if r["scene"] == scene and r["agent"] == "analytic"]
        entry = f"`{scene}` {top['agent']} {_outcome(top)}"
        best.append(entry + (f" (analytic {_outcome(ref[0])})" if ref else ""))
    text += ", ".join(best) if best else "none"
    missing = sorted({(r["scene"], r["task"]) for r in results if r["scene"] not in covered})
    if missing:
        text += f"; no learned agent yet on {', '.join(f'`{s}` ({t})' for s, t in missing)}"
    return text + "."


def default_root() -> Path:
    """The current folder where it holds the records, else the checkout this package runs from
    (an editable install), else the current folder (and the error names the missing record)."""
    here = Path(".")
    if (here / SOURCES["verify"][0]).is_file():
        return here
    checkout = Path(__file__).resolve().parent.parent
    if (checkout / SOURCES["verify"][0]).is_file():
        return checkout
    return here


def main(argv=None) -> int:
    from .extras import ArgumentParser

    p = ArgumentParser(
        prog="rbenvs headline",
        description="The README's headline figures from the records the measuring commands wrote "
        "(docs/verify.json, docs/throughput.json, docs/results.json) in the repository.",
    )
    p.add_argument(
        "--root",
        default=None,
        help="the repository (default: the current folder if it holds docs/verify.json, else the "
        "checkout rbenvs runs from)",
    )
    args = p.parse_args(argv)
    root = Path(args.root) if args.root is not None else default_root()
    try:
        print(headline(root))
    except ValueError as exc:
        p.exit(
            2,
            f"rbenvs headline: {exc} (the records are the repository's docs/, not part of an "
            "installed package: run it in a clone, "
            "or pass --root PATH)\n",
        )
    return 0

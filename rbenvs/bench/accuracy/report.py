"""The tables and the figure of ``rbenvs bench accuracy``."""

from __future__ import annotations

import json
import sys

from .convergence import SCENE_SEEDS, TIPPE_HORIZON


# ------------------------------------------------------------------------------------ output
def _g(x, fmt=".1e"):
    return "-" if x is None else format(x, fmt)


def print_report(result, file=None):
    file = sys.stdout if file is None else file
    for key, info in result["cases"].items():
        chk = (
            ""
            if info["reference_check"] is None
            else f"; ref. check (rtol 1e-12 vs 1e-13): {info['reference_check']:.1e}"
        )
        print(
            f"\n{key}: {info['label']}; {info['states']} states; error after T = "
            f"{info['horizon']:g} s against the {info['reference']}{chk}",
            file=file,
        )
        print(
            f"{'integrator':<10} {'order':>6} {'declared':>8} {'rhs/step':>8} {'us/step':>8}  "
            "error at h = ...",
            file=file,
        )
        for c in (c for c in result["convergence"] if c["case"] == key):
            pts = c["points"]
            order = (
                "round-off"
                if c["integrator"] == "exact" and max(p["error"] for p in pts) < 1e-12
                else _g(c["order"], ".2f")
            )
            rhs = "adaptive" if c["integrator"] == "dop853" else _g(pts[0]["rhs_per_step"], "d")
            us = min(p["seconds_per_step"] for p in pts) * 1e6
            errs = "  ".join(f"{p['h']:.2e}:{p['error']:.1e}" for p in pts)
            print(
                f"{c['integrator']:<10} {order:>6} {c['declared_order']:>8} {rhs:>8} {us:>8.2f}  "
                f"{errs}",
                file=file,
            )
        _print_mujoco_ratios([c for c in result["convergence"] if c["case"] == key], file)
        drifts = [d for d in result["drift"] if d["case"] == key]
        names = list(drifts[0]["drift_long"])
        print(
            f"drift at h = {info['drift_h']:.4g} s (largest relative change from the start)",
            file=file,
        )
        head = "  ".join(f"{n + ' 1e3':>13} {n + ' long':>14}" for n in names)
        print(f"{'integrator':<10} {'long steps':>10}  {head}  note", file=file)
        for d in drifts:
            cols = "  ".join(
                f"{_g(d['drift_short'][n]) if d['drift_short'] else '-':>13} "
                f"{_g(d['drift_long'][n]):>14}"
                for n in names
            )
            note = f"diverged at step {d['diverged_at']}" if d["diverged_at"] else ""
            print(f"{d['integrator']:<10} {d['long_steps']:>10.0e}  {cols}  {note}", file=file)
    if result.get("scenes"):
        print_scenes(result["scenes"], file=file)


# accuracies at which the cheapest rbenvs and MuJoCo schemes are compared (relative error at T)
COST_TARGETS = (1e-3, 1e-6, 1e-9)


def cheapest(convergence_rows, tol):
    """``(integrator, seconds per simulated second)`` of the cheapest grid point with error
    ``<= tol`` among ``convergence_rows``; ``None`` if none reaches it."""
    best = None
    for c in convergence_rows:
        for p in c["points"]:
            if p["error"] <= tol and (best is None or p["seconds_per_simulated_second"] < best[1]):
                best = (c["integrator"], p["seconds_per_simulated_second"])
    return best


def _print_mujoco_ratios(rows, file):
    """With MuJoCo lines: the cost of reaching each accuracy, ours against MuJoCo's (same run)."""
    theirs = [c for c in rows if c["integrator"].startswith("mujoco")]
    if not theirs:
        return
    ours = [c for c in rows if not c["integrator"].startswith("mujoco")]
    print(
        "cost to reach a relative error at T (CPU s per simulated s, the cheapest grid point of "
        "each side):",
        file=file,
    )
    for tol in COST_TARGETS:
        a, b = cheapest(ours, tol), cheapest(theirs, tol)
        if a is None or b is None:
            print(
                f"  error <= {tol:.0e}: rbenvs {a[0] if a else 'none'}, MuJoCo "
                f"{b[0] if b else 'none on the grid'}",
                file=file,
            )
            continue
        print(
            f"  error <= {tol:.0e}: rbenvs {a[0]} {a[1]:.2e} s, MuJoCo {b[0][7:]} {b[1]:.2e} s: "
            f"MuJoCo / rbenvs = {b[1] / a[1]:.1f}",
            file=file,
        )


def print_scenes(rows, file=None):
    file = sys.stdout if file is None else file
    target = rows[0]["target"]
    print(
        f"\nscenes: worst relative state error over an episode (random actions, {SCENE_SEEDS} "
        "seeds) against dop853 at rtol 1e-13; "
        f"target {target:g}; cost = one env step (us); tippe top: first {TIPPE_HORIZON:g} s",
        file=file,
    )
    print(
        f"{'scene':<20} {'dt':>6} {'current':<14} {'error':>8} {'us':>7}   {'recommended':<14} "
        f"{'error':>8} {'us':>7}   candidates (integrator x substeps: error)",
        file=file,
    )
    for r in rows:
        cur = r["current"]
        cur_c = next(
            (
                c
                for c in r["candidates"]
                if (c["integrator"], c["substeps"]) == (cur["integrator"], cur["substeps"])
            ),
            None,
        )
        rec = r["recommended"]
        rec_c = (
            None
            if rec is None
            else next(
                c
                for c in r["candidates"]
                if (c["integrator"], c["substeps"]) == (rec["integrator"], rec["substeps"])
            )
        )
        cand = ", ".join(
            f"{c['integrator']}x{c['substeps']}:{c['error']:.0e}" for c in r["candidates"]
        )
        print(
            f"{r['scene']:<20} {r['dt']:>6g} {cur['integrator'] + ' x' + str(cur['substeps']):<14} "
            f"{_g(None if cur_c is None else cur_c['error']):>8} "
            f"{_g(None if cur_c is None else cur_c['step_us'], '.1f'):>7}   "
            f"{'none' if rec is None else rec['integrator'] + ' x' + str(rec['substeps']):<14} "
            f"{_g(None if rec_c is None else rec_c['error']):>8} "
            f"{_g(None if rec_c is None else rec_c['step_us'], '.1f'):>7}   {cand}",
            file=file,
        )


def plot(result, path):
    """Work-precision figure: error after ``T`` against seconds per simulated second, one line
    per integrator, one panel per case. Needs matplotlib (``RuntimeError`` otherwise)."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise RuntimeError("--plot needs matplotlib: pip install 'rbenvs[plot]'") from None
    keys = list(result["cases"])
    fig, axes = plt.subplots(1, len(keys), figsize=(4.2 * len(keys), 4.0), squeeze=False)
    colors = {
        "euler": "C0",
        "rk4": "C1",
        "splitting": "C2",
        "exact": "C3",
        "dop853": "C4",
        "mujoco Euler": "C5",
        "mujoco RK4": "C6",
        "mujoco implicit": "C7",
        "mujoco implicitfast": "C8",
    }
    for ax, key in zip(axes[0], keys):
        for c in (c for c in result["convergence"] if c["case"] == key):
            pts = c["points"]
            x = [p["seconds_per_simulated_second"] for p in pts]
            y = [max(p["error"], 1e-17) for p in pts]
            label = c["integrator"] + ("" if c["order"] is None else f" (order {c['order']:.2f})")
            style = "s--" if c["integrator"].startswith("mujoco") else "o-"
            ax.loglog(x, y, style, color=colors.get(c["integrator"]), label=label, ms=3)
        info = result["cases"][key]
        ax.set_title(f"{key} (T = {info['horizon']:g} s)", fontsize=9)
        ax.set_xlabel("CPU seconds per simulated second (one state)")
        ax.set_ylabel("relative error after T")
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle("rbenvs bench accuracy: work-precision", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _write_json(path, result) -> None:
    """Every figure of ``result`` as JSON at ``path`` (``--json``; nothing where ``path`` is
    None)."""
    if path:
        with open(path, "w") as f:
            json.dump(result, f, indent=1, default=float)

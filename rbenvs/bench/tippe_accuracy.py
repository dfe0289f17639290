"""``rbenvs bench accuracy --tippe``: work-precision of the tippe top, rbenvs beside MuJoCo, in one
run.

The top is the default ``TippeTop-v0`` one (Leine-Glocker's: ``m = 6 g``, ``a = 15 mm``,
``alpha = 0.2``, ``mu = 0.3``), tilt 0.1 rad, no action, from the starts of :data:`STARTS`:
``default`` (the env's: centre of mass at rest, 150 rad/s), ``leine_glocker`` (at rest, 180
rad/s) and ``rolling`` (150 rad/s, contact point at rest). Per start:

1. **References.** ``t90`` (the time to pass 90 degrees, linear in the tilt within the 10 ms
   period that crosses, as :func:`rbenvs.bench.tippe_steps.inversion` measures it) of rbenvs'
   regularised-Coulomb model at slip regularisation ``eps = 1e-3 / 2^k`` m/s, each converged in
   the step (rk4, guard off, ``n(eps) = 320 (1e-3 / eps)`` internal steps a period, and again at
   ``2 n``: ``step check`` is their difference). The hard-Coulomb limit is ``eps -> 0``: the
   successive differences of the sequence and their ratios say whether it converges (ratios
   below 1; then a Richardson extrapolation, first order in ``eps``, with the difference of the
   last two extrapolants as its error estimate) or not (ratios near 2: ``t90`` grows like
   ``1 / eps``, fitted as ``t0 + c / eps``). ``t90_same`` is the converged value at the env's
   default ``eps = 1e-3`` (the "converged value of the same model" of issue 18): the reference of
   the ``t90 err`` column.
2. **rbenvs rows.** Every scheme that takes the tippe top (``euler``, ``rk4``, ``dop853`` by
   name; ``ros2`` and ``ros34pw2``, the Rosenbrock-W instances of
   :mod:`rbenvs.integrators.rosenbrock`) with the env's guard at ``friction_bound="accuracy"``
   and ``"stability"``, and at fixed internal step counts (guard off: :data:`COUNTS`); the other
   fidelity levels (gliding with free flight, viscous friction, frictionless, rolling) at rk4
   with the guard. The env is stepped as a single env (``env.unwrapped``, compiled where numba
   is installed), zero action, until the tilt passes 90 degrees (or an end, or ``HORIZON`` times
   ``t90_same``). ``cost`` = CPU seconds per simulated second: the same periods run again from
   the same reset with nothing but ``env.step`` in the loop, best of :data:`REPEATS`.
3. **MuJoCo rows** (the ``mujoco`` extra; none without it): the tippe-top model of
   :mod:`rbenvs.verify.mujoco_adapter` (its default contact: ``solref = (2 dt, 1)``), each of
   ``implicitfast``, ``RK4``, ``implicit`` and ``Euler`` with pyramidal and elliptic cones at
   each ``dt`` of :data:`MUJOCO_DTS`, from the same start state; read every 10 ms as rbenvs
   is. ``cost``: the same periods again from the start, ``mj_step(model, data, nstep)`` per
   10 ms and nothing else in the loop, best of :data:`REPEATS`.

Columns: ``t90`` [s], ``t90 err`` = ``|t90 - t90_same|``, ``Jellett`` = the largest
``|J - J0| / |J0|`` over the periods up to 90 degrees (up to the horizon where none), ``steps``
= internal steps per 10 ms, ``cost`` [s per simulated s]. ``--quick``: the default start only,
short reference sequence, a few rows per engine (the tests' subset).
"""

from __future__ import annotations

import math
import sys
import time
import warnings

import numpy as np

from . import tippe_steps

__all__ = [
    "limit_of",
    "equivalent_eps",
    "STARTS",
    "COUNTS",
    "MUJOCO_DTS",
    "REPEATS",
    "reference",
    "rbenvs_rows",
    "mujoco_rows",
    "run",
    "print_report",
    "plot",
    "headline",
]

PERIOD = 0.01  # s, the env's control period: every run is read at this rate
STARTS = {
    "default": ("rest", 150.0),
    "leine_glocker": ("rest", 180.0),
    "rolling": ("rolling", 150.0),
}
EPS0 = 1e-3  # m/s, the env's slip regularisation
BASE_COUNT = 320  # rk4 steps a period that converge t90 at EPS0 (doubled: ``step check``)
HORIZON = 3.0  # runs stop at this multiple of t90_same
REPEATS = 5
# fixed internal steps per 10 ms (guard off), per scheme: from unstable/too few to converged
COUNTS = {
    "rk4": (20, 40, 80, 160, 320),
    "euler": (400, 1600, 6400),
    "ros2": (10, 20, 40, 80, 160),
    "ros34pw2": (10, 20, 40, 80),
}
QUICK_COUNTS = {"rk4": (40, 80), "euler": (1600,)}
MUJOCO_INTEGRATORS = ("implicitfast", "RK4", "implicit", "Euler")
MUJOCO_DTS = (1e-4, 2e-4, 5e-4, 1e-3, 2e-3)
CONES = ("pyramidal", "elliptic")
LEVELS = {  # fidelity levels beside gliding Coulomb, at rk4 with the guard (accuracy bound)
    "gliding+flight": dict(free_flight=True),
    "viscous": dict(law="viscous"),
    "frictionless": dict(fidelity="frictionless"),
    "rolling": dict(fidelity="rolling"),
}


# ------------------------------------------------------------------------------ references
def reference(start="default", ks=range(5), progress=None) -> dict:
    """The converged ``t90`` at ``eps = EPS0 / 2^k`` for ``k`` in ``ks`` and what the sequence
    says of ``eps -> 0`` (module docstring, item 1)."""
    kind, spin = STARTS[start]
    seq = []
    for k in ks:
        eps, n = EPS0 / 2**k, BASE_COUNT * 2**k
        a = tippe_steps.inversion(kind, spin, n, slip_regularization=eps, max_periods=4000)
        b = tippe_steps.inversion(kind, spin, 2 * n, slip_regularization=eps, max_periods=4000)
        seq.append(
            {
                "eps": eps,
                "count": n,
                "t90": a["t90"],
                "step_check": abs(a["t90"] - b["t90"]),
                "ended": a["ended"],
                "least_normal": a["least_normal"],
            }
        )
        if progress:
            progress()
        if a["ended"] is not None:
            break  # no inversion within 40 s: smaller eps only take longer
    out = {"start": start, "spin": spin, "kind": kind, "sequence": seq, "t90_same": seq[0]["t90"]}
    out.update(limit_of([s["eps"] for s in seq], [s["t90"] for s in seq]))
    return out


def limit_of(eps, t90) -> dict:
    """What a sequence ``t90(eps)`` at halving ``eps`` says of ``eps -> 0``: the successive
    ``differences`` and their ``ratios``; ``converges`` where every ratio is below 0.75 in
    size (then ``limit``, Richardson first order in ``eps``, and ``limit_error``, the difference
    of the last two extrapolants or, with one, the last difference), else the least-squares fit
    ``t90 = fit_t0 + fit_c / eps`` of the finite points."""
    diffs = [b - a for a, b in zip(t90, t90[1:])]
    ratios = [b / a for a, b in zip(diffs, diffs[1:]) if a != 0.0]
    out = {"differences": diffs, "ratios": ratios}
    finite = all(math.isfinite(x) for x in t90)
    if finite and len(ratios) >= 1 and all(abs(r) < 0.75 for r in ratios):
        rich = [2.0 * b - a for a, b in zip(t90, t90[1:])]
        out.update(
            converges=True,
            limit=rich[-1],
            limit_error=abs(rich[-1] - rich[-2]) if len(rich) > 1 else abs(diffs[-1]),
        )
    else:
        out.update(converges=False, limit=None, limit_error=None)
        pts = [(e, x) for e, x in zip(eps, t90) if math.isfinite(x)]
        if len(pts) >= 2:
            c, t0 = np.polyfit([1.0 / e for e, _ in pts], [x for _, x in pts], 1)
            out.update(fit_t0=float(t0), fit_c=float(c))
    return out


# ------------------------------------------------------------------------------ rbenvs
def _rbenvs_row(start, t90_same, label, scheme, setting, level="gliding", law="coulomb", **options):
    kind, spin = STARTS[start]
    substeps = {"accuracy": "accuracy", "stability": None}.get(setting, setting)
    max_periods = int(math.ceil(HORIZON * t90_same / PERIOD))
    if scheme == "dop853":
        max_periods = min(
            max_periods, int(math.ceil(1.05 * t90_same / PERIOD)) + 1
        )  # (slow: up to the turn only)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = tippe_steps.inversion(
            kind,
            spin,
            substeps,
            tippe_steps.scheme(scheme),
            law,
            max_periods=max_periods,
            timing_repeats=0 if scheme == "dop853" else REPEATS,
            **options,
        )
    per_period = r.get(
        "us_per_period_best", r["us_per_period"]
    )  # dop853 (slow, not timed again): its one measured run
    return {
        "engine": "rbenvs",
        "start": start,
        "scheme": label,
        "setting": str(setting),
        "fidelity": level,
        "t90": r["t90"],
        "ended": r["ended"],
        "t90_error": abs(r["t90"] - t90_same) if r["ended"] is None else None,
        "jellett": r["drift"],
        "steps": r["steps"],
        "cost": per_period * 1e-6 / PERIOD,
        "least_normal": r["least_normal"],
        "periods": r["periods"],
    }


def rbenvs_rows(start, t90_same, quick=False, progress=None) -> list[dict]:
    """The rbenvs rows of one start (module docstring, item 2)."""
    jobs = [("rk4", "accuracy"), ("euler", "accuracy")]
    if quick:
        jobs += [(s, n) for s, counts in QUICK_COUNTS.items() for n in counts]
    else:
        jobs += [
            ("rk4", "stability"),
            ("euler", "stability"),
            ("ros2", "accuracy"),
            ("ros34pw2", "accuracy"),
        ]
        jobs += [(s, n) for s, counts in COUNTS.items() for n in counts]
        jobs += [("dop853", 1)]
    rows = []
    for scheme, setting in jobs:
        rows.append(_rbenvs_row(start, t90_same, scheme, scheme, setting))
        if progress:
            progress()
    if not quick:
        kind = STARTS[start][0]
        for level, opts in LEVELS.items():
            opts = dict(opts)
            fidelity = opts.pop("fidelity", "gliding")
            if (fidelity == "rolling") != (kind == "rolling"):
                continue  # rolling: only from the rolling start; the others with slip
            law = opts.pop("law", "coulomb")
            rows.append(
                _rbenvs_row(
                    start,
                    t90_same,
                    "rk4",
                    "rk4",
                    "accuracy",
                    level=level,
                    law=law,
                    fidelity=fidelity,
                    **opts,
                )
            )
            if progress:
                progress()
    return rows


# ------------------------------------------------------------------------------ MuJoCo
def mujoco_rows(start, t90_same, quick=False, progress=None) -> list[dict]:
    """The MuJoCo rows of one start (module docstring, item 3); ``[]`` without mujoco."""
    try:
        import mujoco
    except ImportError:
        return []
    from ..verify.simulator import problem_of
    from ..verify.tippe_top import oracle_jellett

    kind, spin = STARTS[start]
    env = tippe_steps.make_env(kind, spin, "coulomb", "rk4", 1, "subdivide", False, 1)
    env.reset(seed=0)
    system, y0 = env.system, tuple(float(c) for c in env.state_components)
    top = _MujocoTop(mujoco, system, problem_of(system), y0, oracle_jellett(system, y0)[0])
    max_periods = int(math.ceil(HORIZON * t90_same / PERIOD))
    integrators, dts = (
        (("implicitfast", "RK4"), (1e-3,)) if quick else (MUJOCO_INTEGRATORS, MUJOCO_DTS)
    )
    rows = []
    for name in integrators:
        for cone in CONES:
            for dt in dts:
                rows.append(top.row(start, t90_same, name, cone, dt, max_periods))
                if progress:
                    progress()
    return rows


class _MujocoTop:
    """One start of the tippe top in MuJoCo: the problem, its start state ``y0`` and Jellett's
    ``j0`` there, each row run by :class:`~rbenvs.verify.mujoco_adapter.MujocoSimulator`."""

    def __init__(self, mujoco, system, problem, y0, j0):
        self.mujoco, self.system, self.problem, self.y0, self.j0 = mujoco, system, problem, y0, j0

    def row(self, start, t90_same, name, cone, dt, max_periods) -> dict:
        """Integrator ``name`` with the ``cone`` friction cone at step ``dt``: its inversion and
        its cost per simulated second."""
        from ..verify.mujoco_adapter import MujocoSimulator

        sim = MujocoSimulator(name, dt, cone=cone)
        nstep = int(round(PERIOD / dt))
        t90, ended, drift, k = self.inversion(sim, nstep, dt, max_periods)
        best = self.best_replay(sim, nstep, k)
        return {
            "engine": "mujoco",
            "start": start,
            "scheme": f"mujoco {name} {cone}",
            "setting": f"dt={dt:g}",
            "dt": dt,
            "fidelity": "soft contact",
            "t90": t90,
            "ended": ended,
            "t90_error": abs(t90 - t90_same) if ended is None else None,
            "jellett": drift,
            "steps": nstep,
            "cost": best / (k * PERIOD),
            "least_normal": None,
            "periods": k,
        }

    def inversion(self, sim, nstep, dt, max_periods):
        """``(t90, ended, drift, periods)``: ``sim`` read every :data:`PERIOD` (``nstep`` steps
        of ``dt``) until the tilt passes 90 degrees (``t90`` linear in the tilt within that
        period), the state is no longer finite, or ``max_periods`` pass; ``drift`` is Jellett's
        largest relative drift."""
        from ..verify.tippe_top import oracle_jellett

        run = sim.start(self.problem, self.y0)
        prev, drift, t90, ended, k = 0.1, 0.0, math.nan, "no inversion", 0
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for k in range(1, max_periods + 1):
                y = run.advance(nstep, None, dt)
                q = y[4:8]
                tilt = math.acos(max(-1.0, min(1.0, 1.0 - 2.0 * (q[1] ** 2 + q[2] ** 2))))
                j = oracle_jellett(self.system, y)[0]
                if not (math.isfinite(j) and math.isfinite(tilt)):
                    ended = "numerical failure"
                    break
                drift = max(drift, abs(j - self.j0) / abs(self.j0))
                if tilt > math.pi / 2:
                    t90, ended = (k - 1 + (math.pi / 2 - prev) / (tilt - prev)) * PERIOD, None
                    break
                prev = tilt
        return t90, ended, drift, k

    def best_replay(self, sim, nstep, periods) -> float:
        """The best over :data:`REPEATS` of the wall time of ``periods`` periods from the start,
        ``mj_step(model, data, nstep)`` a period and nothing else in the loop."""
        best = math.inf
        for _ in range(REPEATS):
            timing = sim.start(self.problem, self.y0)
            m, d = timing.model, timing.data
            clock = time.perf_counter()
            for _ in range(periods):
                self.mujoco.mj_step(m, d, nstep)
            best = min(best, time.perf_counter() - clock)
        return best


# ------------------------------------------------------------------------------ the run
def run(quick=False, starts=None, progress=None, mujoco=True) -> dict:
    starts = (["default"] if quick else list(STARTS)) if starts is None else starts
    out = {
        "starts": {},
        "rows": [],
        "settings": {
            "quick": quick,
            "period": PERIOD,
            "eps0": EPS0,
            "horizon": HORIZON,
            "repeats": REPEATS,
        },
    }
    for start in starts:
        ref = reference(start, range(4) if quick else range(5), progress=progress)
        out["starts"][start] = ref
        out["rows"] += rbenvs_rows(start, ref["t90_same"], quick=quick, progress=progress)
        if mujoco:
            out["rows"] += mujoco_rows(start, ref["t90_same"], quick=quick, progress=progress)
    return out


def progress_total(quick=False) -> int:
    if quick:
        return 4 + 2 + sum(len(c) for c in QUICK_COUNTS.values()) + 4
    per = (
        5
        + 6
        + sum(len(c) for c in COUNTS.values())
        + 1
        + 3
        + len(MUJOCO_INTEGRATORS) * len(CONES) * len(MUJOCO_DTS)
    )
    return per * len(STARTS)


def _g(x, fmt=".1e"):
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, fmt)


def headline(result, start="default") -> str | None:
    """The issue's comparison: rbenvs' default env (rk4, accuracy bound) against MuJoCo
    implicitfast (elliptic cone) at dt = 1e-3, per simulated second, with each one's t90 error."""
    rows = [r for r in result["rows"] if r["start"] == start]
    ours = next(
        (
            r
            for r in rows
            if r["scheme"] == "rk4" and r["setting"] == "accuracy" and r["fidelity"] == "gliding"
        ),
        None,
    )
    theirs = next(
        (
            r
            for r in rows
            if r["scheme"] == "mujoco implicitfast elliptic" and r["setting"] == "dt=0.001"
        ),
        None,
    )
    if ours is None or theirs is None:
        return None
    return (
        f"{start} start: rbenvs default env (rk4, friction_bound='accuracy') {ours['cost']:.2e} s "
        "per simulated s, "
        f"MuJoCo implicitfast (elliptic, dt = 1e-3) {theirs['cost']:.2e} s: rbenvs / MuJoCo = "
        f"{ours['cost'] / theirs['cost']:.2f}; "
        f"t90 error against t90_same: rbenvs {_g(ours['t90_error'])} s, MuJoCo "
        f"{_g(theirs['t90_error'])} s; "
        f"Jellett drift: rbenvs {ours['jellett']:.1e}, MuJoCo {theirs['jellett']:.1e}"
    )


def equivalent_eps(ref, row):
    """For a MuJoCo row that inverts, where the reference does not converge: the slip
    regularisation at which the fit ``t0 + c / eps`` of rbenvs' model gives the row's ``t90``
    (what MuJoCo's soft contact amounts to, read through that fit; ``None`` outside it)."""
    if (
        row["engine"] != "mujoco"
        or row["ended"] is not None
        or "fit_c" not in ref
        or row["t90"] <= ref["fit_t0"]
    ):
        return None
    return ref["fit_c"] / (row["t90"] - ref["fit_t0"])


def print_report(result, file=None):
    file = sys.stdout if file is None else file
    for start, ref in result["starts"].items():
        _print_sequence(start, ref, file)
        _print_limit(ref, file)
        _print_rows(result, start, ref, file)
        line = headline(result, start)
        if line:
            print(line, file=file)


def _print_sequence(start, ref, file):
    """A start's references: ``t90`` at each slip regularisation, with the step check and the
    successive differences and their ratios."""
    print(
        f"\ntippe top, start {start} ({ref['kind']}, {ref['spin']:g} rad/s, tilt 0.1 rad), no "
        "action; "
        "t90 of rbenvs' regularised Coulomb model against the slip regularisation eps (rk4 "
        "converged in the step):",
        file=file,
    )
    print(
        f"{'eps [m/s]':>10} {'steps/10ms':>10} {'t90 [s]':>14} {'step check':>10} "
        f"{'difference':>11} {'ratio':>6}",
        file=file,
    )
    for i, s in enumerate(ref["sequence"]):
        diff = ref["differences"][i - 1] if i >= 1 and i - 1 < len(ref["differences"]) else None
        ratio = ref["ratios"][i - 2] if i >= 2 and i - 2 < len(ref["ratios"]) else None
        t90 = f"{s['t90']:.9f}" if s["ended"] is None else f"({s['ended']})"
        print(
            f"{s['eps']:>10.4g} {s['count']:>10d} {t90:>14} {_g(s['step_check']):>10} "
            f"{_g(diff, '+.4f'):>11} {_g(ratio, '.2f'):>6}",
            file=file,
        )


def _print_limit(ref, file):
    """What the sequence says of the hard-Coulomb limit: its extrapolation, or why there is
    none (and the fit ``t0 + c / eps``)."""
    if ref["converges"]:
        print(
            f"hard-Coulomb limit (eps -> 0, Richardson, first order): t90 = {ref['limit']:.6f} "
            f"s, error estimate {ref['limit_error']:.1e} s",
            file=file,
        )
        return
    fit = (
        f"; fitted t90 = {ref['fit_t0']:.3f} s + {ref['fit_c']:.3e} m / eps"
        if "fit_c" in ref
        else ""
    )
    print(
        "hard-Coulomb limit: none; t90 grows as eps falls (each halving adds about twice "
        f"the last: ~1/eps){fit}. "
        "The top enters a near-rolling phase whose slip stays below eps and whose creep, "
        "at a rate proportional to eps, "
        "is what raises it; under hard Coulomb it rolls without slipping there and does "
        "not pass 90 degrees. "
        f"Errors below are against t90_same = {ref['t90_same']:.9f} s (eps = {EPS0:g}, the "
        "env's)",
        file=file,
    )


def _print_rows(result, start, ref, file):
    """A start's rows, rbenvs' and MuJoCo's: cost, t90, its error and Jellett's drift."""
    print(
        f"{'engine/scheme':<30} {'setting':<10} {'fidelity':<15} {'steps/10ms':>10} "
        f"{'cost s/s':>9} {'t90 [s]':>12} {'t90 err':>8} {'Jellett':>8}  note",
        file=file,
    )
    for r in (r for r in result["rows"] if r["start"] == start):
        t90 = f"{r['t90']:.6f}" if r["ended"] is None else "-"
        note = "" if r["ended"] is None else f"{r['ended']} (in {r['periods'] * PERIOD:.2f} s)"
        eq = equivalent_eps(ref, r)
        if eq is not None:
            note = f"t90 of rbenvs' model at eps = {eq:.1e} m/s (the fit)"
        print(
            f"{r['scheme']:<30} {r['setting']:<10} {r['fidelity']:<15} {r['steps']:>10.1f} "
            f"{r['cost']:>9.2e} {t90:>12} {_g(r['t90_error']):>8} {_g(r['jellett']):>8}  "
            f"{note}",
            file=file,
        )


def plot(result, path):
    """Two panels per start: Jellett drift and the t90 error against the cost per simulated
    second; rbenvs schemes as lines over their fixed counts (the guard's points as stars), MuJoCo
    (integrator, cone) as dashed lines over dt."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    starts = list(result["starts"])
    fig, axes = plt.subplots(len(starts), 2, figsize=(11, 4.0 * len(starts)), squeeze=False)
    for row, start in zip(axes, starts):
        rows = [
            r
            for r in result["rows"]
            if r["start"] == start and r["fidelity"] in ("gliding", "soft contact")
        ]
        groups = {}
        for r in rows:
            kind = r["setting"] if r["setting"] in ("accuracy", "stability") else "fixed"
            groups.setdefault((r["scheme"], kind), []).append(r)
        names = sorted({n for n, _ in groups})
        for (name, kind), grp in sorted(groups.items()):
            grp = sorted(grp, key=lambda r: r["cost"])
            color = matplotlib.colormaps["tab20"](
                names.index(name) % 20
            )  # (14 names: C0-C9 repeated colours)
            style = {"accuracy": "*", "stability": "^"}.get(
                kind, "s--" if name.startswith("mujoco") else "o-"
            )
            label = name if kind == "fixed" else f"{name} guard, {kind} bound"
            for ax, key, floor in ((row[0], "jellett", 1e-16), (row[1], "t90_error", 1e-12)):
                pts = [
                    (r["cost"], max(r[key], floor))
                    for r in grp
                    if r[key] is not None and math.isfinite(r[key])
                ]
                if pts:
                    x, y = zip(*pts)
                    ax.loglog(x, y, style, color=color, ms=9 if kind != "fixed" else 3, label=label)
        for ax, what in zip(row, ("Jellett drift up to 90 deg (relative)", "|t90 - t90_same| [s]")):
            ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
            ax.set_xlabel("CPU seconds per simulated second (single env / one MjData)")
            ax.set_ylabel(what)
            ax.set_title(f"{start} start", fontsize=9)
            ax.grid(True, which="major", alpha=0.3)
        row[1].legend(fontsize=6, ncol=2)
    fig.suptitle("rbenvs bench accuracy --tippe: work-precision, rbenvs and MuJoCo", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)

"""The sweep of tops across the inversion criterion (``rbenvs plot``'s tippe-top figure)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...dynamics import TippeTop, TippeTopParams
from ...integrators import get_integrator
from ..settings import TIPPE_TOP_SETTINGS
from .inversion import measured_class, prediction, settle, upright_start
from .settings import FINAL_TILT_TOL, RandomTop, oracle_jellett

# ------------------------------------------------------------------------------------------
# the sweep

SWEEP_ALPHAS = (0.1, 0.2, 0.3)
# A/C = 1 + s alpha: two below the window, four inside, two above. At s = 0.9 (inside) the
# row's J is below J_min: the criterion says partial inversion, to ~148 degrees.
SWEEP_OFFSETS = (-1.5, -1.2, -0.6, 0.0, 0.6, 0.9, 1.2, 1.5)
SWEEP_QUICK = ((0.2,), (-1.5, 0.0, 1.5))


@dataclass
class SweepPoint:
    """One grid point: the top (``alpha``, ``gamma = A/C``, ``C``, ``radius``, ``mass``), its
    ``J`` and ``spin``, the prediction and the simulation (tilts in degrees)."""

    alpha: float
    gamma: float
    C: float
    radius: float
    mass: float
    J: float
    spin: float
    predicted_class: str
    predicted_tilt: float  # deg
    simulated_tilt: float  # deg
    settled: bool
    t: float
    min_normal: float

    @property
    def difference(self) -> float:
        return abs(self.simulated_tilt - self.predicted_tilt)

    @property
    def passed(self) -> bool:
        return bool(
            math.isfinite(self.difference)
            and self.difference <= math.degrees(FINAL_TILT_TOL)
            and measured_class(math.radians(self.simulated_tilt)) == self.predicted_class
        )


def sweep(
    alphas=SWEEP_ALPHAS,
    offsets=SWEEP_OFFSETS,
    integrator="rk4",
    k=1.3,
    c=0.4,
    radius=0.015,
    mass=0.006,
    progress=None,
    system_class=TippeTop,
) -> list[SweepPoint]:
    """The final tilt over a grid of ``A/C = 1 + s alpha`` (``s`` in ``offsets``) and ``alpha``.

    Every point is the same toy top (``radius``, ``mass``, ``C = c m R^2``; the defaults those of
    Leine and Glocker's top, with ``c = 0.4``) with its own ``A``, spun upright (tilt 0.1 rad) at
    one spin per ``alpha``: ``J = k J_c`` (module docstring), so the points inside the window with
    ``|s| <= 0.6`` exceed both thresholds, those above exceed ``J_upright``, and at ``s = 0.9``
    ``J < J_min`` (a partial inversion inside the window). Viscous friction
    ``mu* = MU_STAR/alpha``; ``integrator`` (rk4) at its settling step until settled (module
    docstring). Each point is its own parameter set: one run each. Returns the points in grid
    order; a point passes when the simulated class matches the predicted one and the tilts agree
    within ``FINAL_TILT_TOL``."""
    integ = get_integrator(integrator)
    setting = TIPPE_TOP_SETTINGS[integ.name]
    out = []
    for alpha in alphas:
        for s in offsets:
            top = RandomTop("sweep", radius, mass, alpha, c, 1.0 + s * alpha, k)
            params = top.params()
            system = system_class(params, "gliding")
            J0 = float(oracle_jellett(system, upright_start(system, top.spin))[0])
            label, tilt = prediction(params, J0)
            res = settle(system, integ, top.spin, setting.settle_step, setting.settle_rtol)
            out.append(
                SweepPoint(
                    alpha,
                    top.gamma,
                    top.C,
                    radius,
                    mass,
                    J0,
                    top.spin,
                    label,
                    math.degrees(tilt),
                    math.degrees(res.tilt),
                    res.settled,
                    res.t,
                    res.min_normal,
                )
            )
            if progress:
                progress()
    return out


def print_sweep(points, file=None):
    import sys

    file = sys.stdout if file is None else file
    rows = [
        (
            "alpha",
            "A/C",
            "J [kg m^2/s]",
            "spin",
            "predicted",
            "predicted [deg]",
            "simulated [deg]",
            "|diff| [deg]",
            "settled at [s]",
            "result",
        )
    ]
    for p in points:
        rows.append(
            (
                f"{p.alpha:.2f}",
                f"{p.gamma:.3f}",
                f"{p.J:.3e}",
                f"{p.spin:.0f}",
                p.predicted_class,
                f"{p.predicted_tilt:.2f}",
                f"{p.simulated_tilt:.2f}",
                f"{p.difference:.3f}",
                f"{p.t:.1f}" if p.settled else f"> {p.t:.0f}",
                "PASS" if p.passed else "FAIL",
            )
        )
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    for n, r in enumerate(rows):
        print("  ".join(x.ljust(w) for x, w in zip(r, widths)).rstrip(), file=file)
        if n == 0:
            print("  ".join("-" * w for w in widths), file=file)
    failed = sum(not p.passed for p in points)
    print(
        f"\n{len(points) - failed} passed, {failed} failed (tolerance "
        f"{math.degrees(FINAL_TILT_TOL):.1f} deg)",
        file=file,
    )


def plot_sweep(points, path):
    """Predicted (lines, on a fine grid of ``A/C`` at each row's ``J``) and simulated (markers)
    final tilt against ``A/C``, one colour per ``alpha``, the window ``1 +- alpha`` shaded. Needs
    matplotlib (the ``plot`` extra):
    ``RuntimeError`` with a message if it is missing."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise RuntimeError("--plot needs matplotlib: pip install 'rbenvs[plot]'") from None
    fig, ax = plt.subplots(figsize=(7, 4.5))
    alphas = sorted({p.alpha for p in points})
    for i, alpha in enumerate(alphas):
        pts = sorted((p for p in points if p.alpha == alpha), key=lambda p: p.gamma)
        color = f"C{i}"
        g = [p.gamma for p in pts]
        ax.axvspan(1 - alpha, 1 + alpha, color=color, alpha=0.06)
        # the prediction on a fine grid of A/C at the row's J (the same top but for A)
        p0 = pts[0]
        lo, hi = min(g[0], 1 - 1.5 * alpha), max(g[-1], 1 + 1.5 * alpha)
        fine = np.linspace(max(lo, 0.5 + 1e-9), hi, 600)
        pred = [
            math.degrees(
                prediction(
                    TippeTopParams(
                        radius=p0.radius, mass=p0.mass, offset=alpha, inertia=(x * p0.C, p0.C)
                    ),
                    p0.J,
                )[1]
            )
            for x in fine
        ]
        ax.plot(
            fine, pred, "-", color=color, lw=1.2, label=f"alpha = {alpha:g}: argmin E* (predicted)"
        )
        ax.plot(
            g,
            [p.simulated_tilt for p in pts],
            "o",
            color=color,
            mfc="none",
            label=f"alpha = {alpha:g}: simulated",
        )
    ax.set_xlabel("A/C")
    ax.set_ylabel("final tilt [deg]")
    ax.set_ylim(-5, 185)
    ax.set_title("Tippe top: final tilt, predicted against simulated")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)

"""Figures of the three systems, simulated with the package's own environments and drawn with
the analytic results over them (``rbenvs plot``; PNG files; matplotlib, the ``plot`` extra,
imported only here and only when a figure is drawn).

* :func:`plot_free_body`: trajectories of ``Pi`` on one momentum sphere, with the intersections
  of the sphere and the energy ellipsoids (docs/physics.md §1, [MR Fig. 15.3.1]) and the
  intermediate-axis separatrix.
* :func:`plot_heavy_top`: tilt and precession rate of a fast top released without precession,
  with the fast-top nutation bounds and mean rate ([T 3.76-3.78]), and of a top started on
  its regular precession, with the slow root of [T 3.82].
* :func:`plot_tippe_top`: tilt, energy and Jellett's integral of the inverting tippe top, with
  the final tilt and the least energy ``E*`` that Jellett's integral allows (docs/physics.md §3).
* :func:`render_frames`: one ``render_mode="rgb_array"`` frame per system.
"""

from __future__ import annotations

import math

import numpy as np

from .render.common import require_matplotlib
from .render.free_body import momentum_orbit

__all__ = ["plot_free_body", "plot_heavy_top", "plot_tippe_top", "render_frames", "PLOTS"]


def _figure(figsize):
    Figure, FigureCanvasAgg = require_matplotlib()
    fig = Figure(figsize=figsize, dpi=100)
    FigureCanvasAgg(fig)
    return fig


def _save(fig, path) -> str:
    fig.savefig(str(path), format="png")
    return str(path)


def _run_zero_action(env, state, steps, stop=None):
    """Step ``env`` from ``state`` with zero action; the list of states (tuples) after reset and
    every step, stopping early when ``stop(info)`` is true."""
    env.reset(seed=0, options={"state": state} if state is not None else None)
    a = np.zeros(env.action_space.shape, dtype=np.float32)
    ys = [env.unwrapped.state_components]
    for _ in range(steps):
        _, _, _, _, info = env.step(a)
        ys.append(env.unwrapped.state_components)
        if stop is not None and stop(info):
            break
    return ys


# ---------------------------------------------------------------------------------- free body
def _visible_split(points, view_dir):
    """``(front, back)``: copies of ``points`` (n, 3) with the points on the hidden (resp.
    visible) half of the sphere replaced by nan, so a line breaks where it goes round."""
    front = np.array(points, dtype=float)
    back = front.copy()
    facing = front @ view_dir >= 0.0
    front[~facing] = np.nan
    back[facing] = np.nan
    return front, back


def _separatrix(inertia, r, n=400):
    """The two great circles of the separatrix on ``|Pi| = r`` (``2 H = r^2 / I_mid``): the
    planes through the intermediate axis where ``(1/I_max - 1/I_mid) P_max^2 +
    (1/I_min - 1/I_mid) P_min^2 = 0``."""
    inertia = np.asarray(inertia, dtype=float)
    lo, mid, hi = np.argsort(inertia)
    s = math.sqrt(
        (1.0 / inertia[mid] - 1.0 / inertia[hi]) / (1.0 / inertia[lo] - 1.0 / inertia[mid])
    )
    t = np.linspace(0.0, 2.0 * np.pi, n)
    out = []
    for sign in (1.0, -1.0):
        n_vec = np.zeros(3)
        n_vec[hi], n_vec[lo] = 1.0, sign * s
        n_vec /= np.linalg.norm(n_vec)
        e = np.zeros(3)
        e[mid] = 1.0
        out.append(r * (np.cos(t)[:, None] * e + np.sin(t)[:, None] * n_vec))
    return out


def _free_body_starts(inertia):
    """Starts on ``|Pi| = 1``: around the major and the minor axis at growing distance, and one
    just off the intermediate axis (it follows the separatrix round to the opposite side: the
    flip)."""
    lo, mid, hi = np.argsort(inertia)
    starts = []
    for axis in (hi, lo):
        for ang in (0.25, 0.5, 0.75, 1.0):
            p = np.zeros(3)
            p[axis], p[mid] = math.cos(ang), math.sin(ang)
            starts.append(p)
    p = np.zeros(3)
    p[mid], p[hi] = math.cos(0.02), math.sin(0.02)
    starts.append(p)
    return starts


def _draw_sphere_and_separatrix(ax, inertia, view_dir):
    """The unit sphere's wireframe and the separatrix on it, its hidden side faint."""
    u, v = np.mgrid[0.0 : 2.0 * np.pi : 37j, 0.0 : np.pi : 19j]
    ax.plot_wireframe(
        np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v), color="#cccccc", lw=0.3
    )
    for k, circle in enumerate(_separatrix(inertia, 1.0)):
        f, b = _visible_split(circle, view_dir)
        ax.plot(
            *f.T,
            color="k",
            lw=1.0,
            ls="--",
            label="separatrix (2H = |Pi|^2 / I_mid)" if k == 0 else None,
        )
        ax.plot(*b.T, color="k", lw=0.6, ls="--", alpha=0.25)


def _free_body_run(env, inertia, p0, dt, max_time):
    """``Pi`` (n, 3) from ``p0`` for one period of its orbit (a little over, so that it closes)
    or ``max_time`` s."""
    from .oracles import orbit_period

    period = orbit_period(inertia, p0)
    t_end = min(1.02 * period, max_time) if math.isfinite(period) else max_time
    steps = int(math.ceil(t_end / dt))
    ys = _run_zero_action(env, {"angular_momentum": p0}, steps)
    return np.array([y[0:3] for y in ys])


def _draw_free_body_runs(ax, env, inertia, starts, dt, max_time, view_dir):
    """Each start's simulated ``Pi`` (the last one, off the intermediate axis, green and bold)
    and its analytic orbit, dotted; a legend entry per family."""
    cmap_major, cmap_minor = ("#1f77b4", "#6baed6"), ("#d62728", "#fc9272")
    labels = {
        0: "simulated, around the major axis",
        4: "simulated, around the minor axis",
        len(starts) - 1: "simulated, from 0.02 rad off the intermediate axis",
    }
    for n, p0 in enumerate(starts):
        traj = _free_body_run(env, inertia, p0, dt, max_time)
        last = n == len(starts) - 1
        color = "#2ca02c" if last else (cmap_major if n < 4 else cmap_minor)[n % 2]
        front, back = _visible_split(traj, view_dir)
        ax.plot(*front.T, color=color, lw=2.4 if last else 1.8, label=labels.get(n))
        ax.plot(*back.T, color=color, lw=0.8, alpha=0.3)
        orbit = momentum_orbit(inertia, p0)
        if orbit is not None:
            f, _ = _visible_split(orbit, view_dir)
            ax.plot(
                *f.T,
                color="k",
                lw=0.8,
                ls=":",
                label="sphere cut by the energy ellipsoid" if n == 0 else None,
            )


def _draw_principal_axes(ax, inertia):
    """The body axes, each named by its place in the order of the moments."""
    lo, mid, hi = np.argsort(inertia)
    names = {hi: "major", mid: "intermediate", lo: "minor"}
    for i in range(3):
        e = np.zeros(3)
        e[i] = 1.25
        ax.plot([0, e[0]], [0, e[1]], [0, e[2]], color="#555555", lw=0.8)
        ax.text(*(1.32 * e / 1.25), f"Pi{i + 1} ({names[i]}, I={inertia[i]:g})", fontsize=8)


def _frame_free_body_axes(ax, view, inertia, integrator, dt):
    """Limits, view, labels, title and legend of the momentum-sphere panel."""
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlim(-1.1, 1.1)
    ax.set_ylim(-1.1, 1.1)
    ax.set_zlim(-1.1, 1.1)
    ax.view_init(elev=view[0], azim=view[1])
    ax.set_xlabel("Pi1")
    ax.set_ylabel("Pi2")
    ax.set_zlabel("Pi3")
    ax.set_title(
        f"Free rigid body: Pi on the sphere |Pi| = 1, inertia {inertia}\n(FreeRigidBody-v0, zero "
        f"torque, {integrator}, dt = {dt} s; hidden side faint)",
        fontsize=10,
    )
    ax.legend(loc="lower left", fontsize=7)


def plot_free_body(path, inertia=(2.0, 1.5, 1.0), dt=0.02, max_time=60.0, integrator="rk4"):
    """Trajectories of ``Pi`` on the sphere ``|Pi| = 1`` (:class:`rbenvs.envs.FreeRigidBodyEnv`,
    zero torque, each for one period of its orbit or ``max_time`` s), the analytic orbits (the
    sphere cut by the energy ellipsoid through each start, dotted) and the separatrix (black)
    through the intermediate axis. Returns ``path``."""
    from .envs import FreeRigidBodyEnv

    inertia = tuple(float(v) for v in inertia)
    env = FreeRigidBodyEnv(
        inertia=inertia,
        task="spin",
        axis=0,
        integrator=integrator,
        dt=dt,
        max_angular_velocity=10.0 / min(inertia) + 10.0,
    )
    view = (22.0, 35.0)
    el, az = np.radians(view[0]), np.radians(view[1])
    view_dir = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])

    fig = _figure((7.0, 7.0))
    ax = fig.add_subplot(projection="3d", computed_zorder=False)  # drawn in call order
    _draw_sphere_and_separatrix(ax, inertia, view_dir)
    starts = _free_body_starts(inertia)
    _draw_free_body_runs(ax, env, inertia, starts, dt, max_time, view_dir)
    _draw_principal_axes(ax, inertia)
    _frame_free_body_axes(ax, view, inertia, integrator, dt)
    return _save(fig, path)


# ---------------------------------------------------------------------------------- heavy top
def _heavy_top_env(spin_factor, dt):
    """The default Lagrange top, free to fall over, spun at ``spin_factor`` times its critical
    spin; ``(env, spin)``."""
    from .envs import LagrangeTopEnv

    n = float(spin_factor) * LagrangeTopEnv().critical_spin
    env = LagrangeTopEnv(
        task="upright",
        spin=n,
        tilt_limit=math.pi,
        dt=dt,
        max_angular_velocity=max(100.0, 4.0 * abs(n)),
    )
    return env, n


def _heavy_top_runs(env, n, tilt, p_slow, duration, dt):
    """``(label, t, tilt, precession rate)`` of the top released at ``tilt`` without precession,
    and of the top started on its slow regular precession ``p_slow``."""
    I = np.asarray(env.params.inertia, dtype=float)
    gamma = np.array([math.sin(tilt), 0.0, math.cos(tilt)])
    chi = np.array([0.0, 0.0, 1.0])
    steps = int(round(duration / dt))
    runs = []
    for label, omega in (
        ("released without precession", n * chi),
        (
            "started on the slow regular precession",
            p_slow * gamma + (n - p_slow * math.cos(tilt)) * chi,
        ),
    ):
        ys = _run_zero_action(env, {"angular_momentum": I * omega, "vertical": gamma}, steps)
        t = np.arange(len(ys)) * dt
        runs.append(
            (
                label,
                t,
                np.array([env.system.tilt(y) for y in ys]),
                np.array([env.system.precession_rate(y) for y in ys]),
            )
        )
    return runs


def _draw_heavy_top_runs(ax1, ax2, runs):
    """Each run's tilt (top panel, degrees) and precession rate (bottom panel)."""
    for (label, t, th, rate), c in zip(runs, ("#1f77b4", "#d62728")):
        ax1.plot(t, np.degrees(th), color=c, lw=1.2, label=f"simulated, {label}")
        ax2.plot(t, rate, color=c, lw=1.2, label=f"simulated, {label}")


def _draw_tilt_references(ax, tilt, nut):
    """The release tilt, the fast-top bound and the mean tilt [T 3.77, 3.79] on the tilt panel."""
    ax.axhline(
        math.degrees(tilt),
        color="k",
        ls=":",
        lw=1,
        label="release tilt alpha (upper turning point)",
    )
    ax.axhline(
        math.degrees(tilt + nut.angle_amplitude),
        color="k",
        ls="--",
        lw=1,
        label="fast-top bound beta = alpha + 2 A m g l sin(alpha)/(C n)^2 [T 3.79]",
    )
    ax.axhline(
        math.degrees(nut.mean_tilt), color="#2ca02c", ls="-.", lw=1, label="mean tilt [T 3.77]"
    )
    ax.set_ylabel("tilt [deg]")


def _draw_rate_references(ax, nut, p_slow):
    """The fast-top mean precession rate [T 3.78] and the slow regular precession [T 3.82] on
    the rate panel."""
    ax.axhline(
        nut.mean_precession_rate,
        color="k",
        ls="--",
        lw=1,
        label="fast-top mean rate m g l/(C n) [T 3.78]",
    )
    ax.axhline(
        p_slow,
        color="#ff7f0e",
        ls=":",
        lw=1.5,
        label="slow root of A p^2 cos(alpha) - C n p + m g l = 0 [T 3.82]",
    )
    ax.set_ylabel("precession rate [rad/s]")
    ax.set_xlabel("time [s]")


def plot_heavy_top(path, spin_factor=4.0, tilt=0.5, duration=3.0, dt=0.002):
    """Tilt and precession rate of the default Lagrange top (:class:`rbenvs.envs.LagrangeTopEnv`,
    zero torque, splitting) spun at ``spin_factor`` times the critical spin, (a) released at
    ``tilt`` with no precession: it nods between ``tilt`` and the fast-top bound ``beta`` [T 3.76]
    and drifts at the mean rate ``m g l/(C n)`` [T 3.78]; (b) started on its slow regular
    precession [T 3.82]: tilt and rate stay put. Returns ``path``."""
    from .oracles import fast_top_nutation, regular_precession_rates

    env, n = _heavy_top_env(spin_factor, dt)
    prm = env.params
    A, C = prm.transverse_inertia, prm.axial_inertia
    nut = fast_top_nutation(A, C, prm.mass, prm.length, prm.gravity, n, tilt)
    p_slow = regular_precession_rates(A, C, prm.mass, prm.length, prm.gravity, n, tilt).slow
    runs = _heavy_top_runs(env, n, tilt, p_slow, duration, dt)

    fig = _figure((8.0, 6.5))
    ax1, ax2 = fig.add_subplot(2, 1, 1), fig.add_subplot(2, 1, 2)
    _draw_heavy_top_runs(ax1, ax2, runs)
    _draw_tilt_references(ax1, tilt, nut)
    _draw_rate_references(ax2, nut, p_slow)
    ax1.set_title(
        f"Lagrange top (LagrangeTop-v0, zero torque), spin n = {n:.3g} rad/s = {spin_factor:g} x "
        f"critical, alpha = {tilt} rad\n"
        f"nutation period 2 pi A/(C n) = {nut.period:.3g} s, expansion parameter "
        f"{nut.expansion_parameter:.2g}",
        fontsize=9,
    )
    for ax in (ax1, ax2):
        ax.legend(fontsize=7, loc="upper right")
        ax.grid(alpha=0.3)
    ax1.set_ylim(
        math.degrees(tilt) - 0.2 * math.degrees(nut.angle_amplitude) - 0.05,
        math.degrees(tilt + 2.2 * nut.angle_amplitude),
    )
    fig.tight_layout()
    return _save(fig, path)


# ---------------------------------------------------------------------------------- tippe top
def _tippe_top_series(env, duration):
    """``(t, tilt [deg], energy, Jellett's integral)`` under zero action for ``duration`` s, or
    until lift-off or a numerical failure."""
    s = env.system
    steps = int(math.ceil(duration / env.dt))
    ys = _run_zero_action(
        env,
        None,
        steps,
        stop=lambda info: info.get("terminal_reason") in ("lift_off", "numerical_failure"),
    )
    t = np.arange(len(ys)) * env.dt
    tilt = np.degrees([s.tilt(y) for y in ys])
    energy = np.array([s.energy(y) for y in ys])
    jell = np.array([s.jellett(y) for y in ys])
    return t, tilt, energy, jell


def _tippe_top_figures(t, tilt, jell, reached, theta_f) -> dict:
    """The figures :func:`plot_tippe_top` reports (see its docstring)."""
    drift = np.abs(jell / jell[0] - 1.0)
    turn = tilt <= 120.0  # (the start, 0.1 rad, is always in it)
    return dict(
        t90=reached[90.0],
        t150=reached[150.0],
        jellett_turn_over=float(drift[turn].max()),
        jellett_run=float(drift.max()),
        duration=float(t[-1]),
        final_tilt=math.degrees(theta_f),
    )


def _draw_tippe_tilt(ax, t, tilt, theta_f, reached):
    """The tilt panel: the simulated tilt, the predicted final tilt, and a marked time where the
    tilt first reaches each of ``reached``'s angles."""
    ax.plot(t, tilt, color="#1f77b4", lw=1.3, label="simulated tilt")
    ax.axhline(
        math.degrees(theta_f),
        color="k",
        ls="--",
        lw=1,
        label="final tilt predicted from J (minimum of E*)",
    )
    for deg, when in reached.items():
        if when is not None:
            ax.axvline(when, color="#888888", ls=":", lw=1)
            ax.annotate(
                f"{deg:.0f} deg at {when:.2f} s",
                (when, deg),
                fontsize=7,
                xytext=(4, -12),
                textcoords="offset points",
            )
    ax.set_ylabel("tilt theta [deg]")


def _draw_tippe_energy(ax, t, energy, e_min):
    """The energy panel: the simulated energy over the least one Jellett's integral allows."""
    ax.plot(t, energy * 1e3, color="#d62728", lw=1.3, label="simulated energy")
    ax.axhline(
        e_min * 1e3, color="k", ls="--", lw=1, label="E*(final tilt): least energy at this J"
    )
    ax.set_ylabel("energy [mJ]")


def _draw_tippe_jellett(ax, t, jell):
    """The bottom panel: Jellett's integral's relative change, and the time axis."""
    ax.plot(t, jell / jell[0] - 1.0, color="#2ca02c", lw=1.3, label="J(t)/J(0) - 1")
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_ylabel("Jellett's integral\nrelative change")
    ax.set_xlabel("time [s]")
    ax.ticklabel_format(axis="y", style="sci", scilimits=(-2, 2))


def plot_tippe_top(path, duration=25.0, figures=None, **env_kwargs):
    """Tilt, energy and Jellett's integral of the tippe top (:class:`rbenvs.envs.TippeTopEnv`
    with ``env_kwargs``; default: the Leine-Glocker top at 150 rad/s, Coulomb friction) under
    zero action for ``duration`` s (on past the task's end at 150 deg, until lift-off or a
    numerical failure), with the final tilt and the least energy ``E*`` at that tilt allowed by
    the initial Jellett's integral (docs/physics.md §3). Returns ``path``; ``figures`` (a dict)
    receives the figures the caption states: the times the tilt first reaches 90 and 150
    degrees (None if it does not), Jellett's largest relative change through the turn-over (to
    120 degrees) and over the whole run, the simulated time and the predicted final tilt."""
    from .envs import TippeTopEnv
    from .oracles import energy_star, final_tilt

    env = TippeTopEnv(**env_kwargs)
    s, prm = env.system, env.params
    t, tilt, energy, jell = _tippe_top_series(env, duration)
    A, C = prm.inertia
    args = (prm.mass, prm.gravity, prm.radius, prm.offset, A, C)
    theta_f = final_tilt(jell[0], *args)
    e_min = energy_star(theta_f, jell[0], *args)

    # the first time the tilt reaches 90 and 150 degrees (None: not in this run), drawn and reported
    reached = {
        deg: next((float(t[k]) for k in np.flatnonzero(tilt >= deg)[:1]), None)
        for deg in (90.0, 150.0)
    }
    if figures is not None:
        figures.update(_tippe_top_figures(t, tilt, jell, reached, theta_f))

    fig = _figure((8.0, 8.0))
    ax1, ax2, ax3 = (fig.add_subplot(3, 1, k) for k in (1, 2, 3))
    _draw_tippe_tilt(ax1, t, tilt, theta_f, reached)
    _draw_tippe_energy(ax2, t, energy, e_min)
    _draw_tippe_jellett(ax3, t, jell)
    law = prm.friction_law if s.friction_law is not None else s.fidelity
    ax1.set_title(
        f"Tippe top (TippeTop-v0, zero action, {law}, {env.integrator.name}, dt = {env.dt} s)\n"
        f"A/C = {A / C:.3g}, alpha = {prm.offset}, J = {jell[0]:.4g} kg m^2/s",
        fontsize=9,
    )
    for ax in (ax1, ax2, ax3):
        ax.legend(fontsize=7, loc="best")
        ax.grid(alpha=0.3)
    fig.tight_layout()
    return _save(fig, path)


# ---------------------------------------------------------------------------------- frames
def render_frames(directory, prefix="render_"):
    """One ``rgb_array`` frame per system, at a moment that shows its motion: the free body
    mid-flip off its intermediate axis, the top precessing, the tippe top half-way up.
    Returns the paths written."""
    import os

    from .envs import FreeRigidBodyEnv, LagrangeTopEnv, TippeTopEnv

    Figure, FigureCanvasAgg = require_matplotlib()
    scenes = (
        ("free_body", FreeRigidBodyEnv(render_mode="rgb_array"), 200),
        ("heavy_top", LagrangeTopEnv(task="precess", attitude=True, render_mode="rgb_array"), 40),
        ("tippe_top", TippeTopEnv(render_mode="rgb_array"), 161),  # at 90 deg (1.61 s)
    )
    paths = []
    for name, env, steps in scenes:
        _run_zero_action(env, None, steps)
        frame = env.render()
        fig = Figure(figsize=(frame.shape[1] / 100, frame.shape[0] / 100), dpi=100)
        FigureCanvasAgg(fig)
        fig.figimage(frame)
        path = os.path.join(str(directory), f"{prefix}{name}.png")
        fig.savefig(path, dpi=100, format="png")
        env.close()
        paths.append(path)
    return paths


# name -> (function, file name) for ``rbenvs plot``
def describe_tippe_top(figures: dict) -> str:
    """The line ``rbenvs plot tippe_top`` prints: the figures :func:`plot_tippe_top` reports (its
    caption in docs/rendering.md states them)."""

    def at(x):
        return "-" if x is None else f"{x:.2f} s"

    return (
        f"tippe top, zero action, {figures['duration']:.2f} s: 90 deg at {at(figures['t90'])}, 150 "
        f"deg at {at(figures['t150'])}; "
        f"Jellett's largest relative change {figures['jellett_turn_over']:.2g} through the "
        "turn-over (to 120 deg), "
        f"{figures['jellett_run']:.2g} over the run; predicted final tilt "
        f"{figures['final_tilt']:.1f} deg"
    )


# name -> (function, file, what its run reports: a function of the figures it fills, or None)
PLOTS = {
    "free_body": (plot_free_body, "plot_free_body.png", None),
    "heavy_top": (plot_heavy_top, "plot_heavy_top.png", None),
    "tippe_top": (plot_tippe_top, "plot_tippe_top.png", describe_tippe_top),
}

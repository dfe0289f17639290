"""What every system's picture shares: the scene format, the lazy matplotlib import, the Agg
canvas that turns a scene into an ``(H, W, 3)`` uint8 frame, and the optional window of
``render_mode="human"``.

A *scene* is a plain dict of geometry in space coordinates [m, or the body's length scale],
built from one state by a system module (:mod:`rbenvs.render.free_body`, ``heavy_top``,
``tippe_top``) with numpy alone; only :func:`draw_scene` needs matplotlib. Keys (all optional
but ``center`` and ``extent``):

* ``center`` (3,), ``extent``: the view is the cube ``center +- extent``;
* ``view``: ``(elevation, azimuth)`` in degrees;
* ``title``: str; ``text``: list of str (lower left, one line each);
* ``polygons``: list of ``{"faces": [(k, 3) arrays], "colors": [colour per face], "alpha",
  "edgecolor"}`` (one collection is depth-sorted face by face: put what overlaps in one);
* ``lines``: list of ``{"points": (n, 3), "color", "width", "style", "label"}``;
* ``arrows``: list of ``{"origin": (3,), "vector": (3,), "color", "label"}`` (a shaft and a head);
* ``points``: list of ``{"position": (3,), "color", "size", "label"}``.
"""

from __future__ import annotations

import os
import sys

import numpy as np

__all__ = [
    "FRAME_SIZE",
    "COLORS",
    "require_matplotlib",
    "display_available",
    "quat_to_matrix",
    "rgba",
    "scaled_arrow",
    "draw_scene",
    "Renderer",
]

# (height, width) of an rgb_array frame in pixels: multiples of 16, as video encoders want.
FRAME_SIZE = (480, 480)
_DPI = 100

# One colour per quantity, the same in every system's picture.
COLORS = {
    "momentum": "#d62728",  # angular momentum (red)
    "angular_velocity": "#1f77b4",  # angular velocity (blue)
    "gravity": "#2ca02c",
    "axis": ("#9467bd", "#ff7f0e", "#17becf"),  # body axes 1, 2, 3
    "body": ("#f2c14e", "#c9a227"),  # two alternating shades of the body
    "body_alt": ("#8fb8de", "#5b8db8"),  # the other side of the body (tippe top: stem half)
    "table": "#d9d9d9",
    "grid": "#a0a0a0",
    "contact": "#000000",
}

_MISSING = "rendering and plots need matplotlib: install the plot extra, pip install 'rbenvs[plot]'"


def require_matplotlib():
    """Import matplotlib's object-oriented API (no pyplot, no global backend change) and
    return ``(Figure, FigureCanvasAgg)``. ``ImportError`` naming the ``plot`` extra if missing."""
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
        from mpl_toolkits.mplot3d import Axes3D  # noqa: F401  (registers the 3-D projection)
    except ImportError:
        raise ImportError(_MISSING) from None
    return Figure, FigureCanvasAgg


def plot_unavailable(command: str) -> bool:
    """Whether ``command --plot`` cannot draw (matplotlib missing); says so on stderr. A long
    command calls it before its run, so that it fails at once instead of at the end."""
    try:
        __import__("matplotlib")
    except ImportError:
        print(f"{command} --plot needs matplotlib (pip install 'rbenvs[plot]')", file=sys.stderr)
        return True
    return False


def display_available() -> bool:
    """Whether a window can be opened: a display on Linux/BSD; assumed on macOS and Windows."""
    if sys.platform.startswith(("linux", "freebsd", "openbsd", "netbsd")):
        return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    return True


def quat_to_matrix(q) -> np.ndarray:
    """Rotation matrix (3, 3) of a unit quaternion ``(w, x, y, z)`` (body -> space)."""
    w, x, y, z = (float(c) for c in q)
    n = w * w + x * x + y * y + z * z
    s = 2.0 / n if n > 0.0 else 0.0
    return np.array(
        [
            [1.0 - s * (y * y + z * z), s * (x * y - w * z), s * (x * z + w * y)],
            [s * (x * y + w * z), 1.0 - s * (x * x + z * z), s * (y * z - w * x)],
            [s * (x * z - w * y), s * (y * z + w * x), 1.0 - s * (x * x + y * y)],
        ]
    )


def rgba(color: str, alpha: float = 1.0, lighten: float = 0.0) -> tuple:
    """``#rrggbb`` as an RGBA tuple in [0, 1], mixed with white by ``lighten`` (0: unchanged)."""
    c = np.array([int(color[k : k + 2], 16) for k in (1, 3, 5)], dtype=float) / 255.0
    c = c + (1.0 - c) * lighten
    return (float(c[0]), float(c[1]), float(c[2]), float(alpha))


def scaled_arrow(vector, scale: float, max_length: float):
    """``scale * vector``, shortened to ``max_length`` if longer (the text gives the size)."""
    v = np.asarray(vector, dtype=float) * scale
    n = float(np.linalg.norm(v))
    if n > max_length:
        v = v * (max_length / n)
    return v


def draw_scene(ax, scene: dict) -> None:
    """Draw ``scene`` (see the module docstring) on a fresh 3-D axes ``ax``."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    c = np.asarray(scene["center"], dtype=float)
    e = float(scene["extent"])
    for poly in scene.get("polygons", ()):
        coll = Poly3DCollection(
            [np.asarray(f, dtype=float) for f in poly["faces"]],
            facecolors=poly["colors"],
            edgecolors=poly.get("edgecolor", "none"),
            linewidths=poly.get("linewidth", 0.3),
            alpha=poly.get("alpha"),
        )
        ax.add_collection3d(coll)
    for line in scene.get("lines", ()):
        p = np.asarray(line["points"], dtype=float)
        ax.plot(p[:, 0], p[:, 1], p[:, 2], color=line.get("color", "k"), lw=line.get("width", 1.0), ls=line.get("style", "-"), label=line.get("label"))
    for arrow in scene.get("arrows", ()):
        o = np.asarray(arrow["origin"], dtype=float)
        v = np.asarray(arrow["vector"], dtype=float)
        if not np.all(np.isfinite(v)) or float(np.linalg.norm(v)) == 0.0:
            continue
        ax.quiver(o[0], o[1], o[2], v[0], v[1], v[2], color=arrow["color"], lw=2.2, arrow_length_ratio=0.18, label=arrow.get("label"))
    for pt in scene.get("points", ()):
        p = np.asarray(pt["position"], dtype=float)
        ax.scatter([p[0]], [p[1]], [p[2]], color=pt.get("color", "k"), s=pt.get("size", 20), depthshade=False, label=pt.get("label"))
    ax.set_xlim(c[0] - e, c[0] + e)
    ax.set_ylim(c[1] - e, c[1] + e)
    ax.set_zlim(c[2] - e, c[2] + e)
    ax.set_box_aspect((1.0, 1.0, 1.0))
    elev, azim = scene.get("view", (20.0, -60.0))
    ax.view_init(elev=elev, azim=azim)
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):  # the grid box stays, numbers would clutter
        axis.set_ticklabels([])
    if scene.get("title"):
        ax.set_title(scene["title"], fontsize=10)
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        ax.legend(handles, labels, loc="upper right", fontsize=7, framealpha=0.8)
    text = scene.get("text")
    if text:
        ax.text2D(0.01, 0.01, "\n".join(text), transform=ax.transAxes, fontsize=7, family="monospace", va="bottom")


class Renderer:
    """One figure on an Agg canvas, redrawn for every frame; ``frame(scene)`` returns the
    ``FRAME_SIZE + (3,)`` uint8 image. ``show(frame, fps)`` puts a frame in a matplotlib window
    when a display exists (``render_mode="human"``); without one it does nothing."""

    def __init__(self, size=FRAME_SIZE):
        Figure, FigureCanvasAgg = require_matplotlib()
        h, w = size
        self.size = (int(h), int(w))
        self.figure = Figure(figsize=(w / _DPI, h / _DPI), dpi=_DPI)
        self.canvas = FigureCanvasAgg(self.figure)
        self.figure.subplots_adjust(left=0.0, right=1.0, bottom=0.0, top=0.94)
        # drawn in call order: the body (its faces depth-sorted), then lines, vectors and points
        # on top, so a vector that starts inside the body stays visible
        self.axes = self.figure.add_subplot(projection="3d", computed_zorder=False)
        self._window = None  # (pyplot module, figure, image) once a window is open
        self._headless = None

    def frame(self, scene: dict) -> np.ndarray:
        self.axes.cla()
        draw_scene(self.axes, scene)
        self.canvas.draw()
        rgba = np.asarray(self.canvas.buffer_rgba())
        return np.ascontiguousarray(rgba[:, :, :3])

    def can_show(self) -> bool:
        """Whether :meth:`show` can put a frame on screen (a display, an interactive backend,
        the window not closed by the user)."""
        if self._headless is None:
            self._headless = not display_available()
        return not self._headless

    def show(self, frame: np.ndarray, fps: float) -> None:
        if not self.can_show():
            return
        if self._window is None:
            try:
                import matplotlib.pyplot as plt
            except ImportError:  # pragma: no cover - matplotlib present but pyplot broken
                self._headless = True
                return
            if not _interactive_backend(plt):
                self._headless = True
                return
            plt.ion()
            fig = plt.figure(figsize=(self.size[1] / _DPI, self.size[0] / _DPI), dpi=_DPI)
            ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
            ax.set_axis_off()
            self._window = (plt, fig, ax.imshow(frame))
        plt, fig, image = self._window
        if not plt.fignum_exists(fig.number):  # the user closed the window: stop showing
            self._headless = True
            return
        image.set_data(frame)
        fig.canvas.draw_idle()
        plt.pause(1.0 / max(float(fps), 1.0))

    def close(self) -> None:
        if self._window is not None:
            plt, fig, _ = self._window
            plt.close(fig)
            self._window = None


def _interactive_backend(plt) -> bool:
    backend = str(plt.get_backend()).lower()
    return backend not in {"agg", "pdf", "ps", "svg", "pgf", "cairo", "template"} and "inline" not in backend

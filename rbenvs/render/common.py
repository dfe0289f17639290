"""What every system's picture shares: the scene format, the frame renderer (numpy alone,
:mod:`rbenvs.render.raster`), the window of ``render_mode="human"`` (matplotlib's, where it and a
display exist) and the lazy matplotlib import of the figures (``rbenvs plot``).

A *scene* is a plain dict of geometry in space coordinates [m, or the body's length scale],
built from one state by a system module (:mod:`rbenvs.render.free_body`, ``heavy_top``,
``tippe_top``) with numpy alone. Keys (all optional but ``center`` and ``extent``):

* ``center`` (3,), ``extent``: the view is the cube ``center +- extent``;
* ``view``: ``(elevation, azimuth)`` in degrees;
* ``polygons``: list of ``{"faces": [(k, 3) arrays of a convex face], "colors": [colour per
  face], "solid"}``, opaque; ``solid``: the faces close a convex body (those turned away are
  hidden), else they are drawn far to near;
* ``lines``: list of ``{"points": (n, 3), "color", "width", "style", "label"}``;
* ``arrows``: list of ``{"origin": (3,), "vector": (3,), "color", "label"}`` (a shaft and a head);
* ``points``: list of ``{"position": (3,), "color", "size", "label"}``;
* ``table``: ``{"center": (x, y), "half", "tile", "colors": (2 colours)}``, a checkered square
  on ``z = 0``;
* ``spheres``: list of ``{"center", "radius", "rotation": (3, 3) body -> space, "colors":
  ((2 shades of the half z_body < 0), (2 of the other)), "sectors"}``.

The labels name the parts for a reader of a scene; a frame has no font to draw them with (the
colours are listed in docs/rendering.md).
"""

from __future__ import annotations

import logging
import os
import sys

import numpy as np

from .raster import rgba  # (raster draws with it; the figures' modules take it from here)

__all__ = [
    "FRAME_SIZE",
    "COLORS",
    "require_matplotlib",
    "display_available",
    "quat_to_matrix",
    "rgba",
    "scaled_arrow",
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

_told: list = []  # a human-mode env that cannot show has been logged in this process

_MISSING = "plots need matplotlib: install the plot extra, pip install 'rbenvs[plot]'"


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


def scaled_arrow(vector, scale: float, max_length: float):
    """``scale * vector``, shortened to ``max_length`` if longer (the text gives the size)."""
    v = np.asarray(vector, dtype=float) * scale
    n = float(np.linalg.norm(v))
    if n > max_length:
        v = v * (max_length / n)
    return v


class Renderer:
    """``frame(scene)`` returns the ``FRAME_SIZE + (3,)`` uint8 image (numpy alone:
    :func:`rbenvs.render.raster.draw`). ``show(frame, fps)`` puts a frame in a matplotlib window
    (``render_mode="human"``) where matplotlib, an interactive backend and a display exist;
    where one is missing it warns once, saying why and how to record frames instead, and shows
    nothing."""

    def __init__(self, size=FRAME_SIZE):
        h, w = size
        self.size = (int(h), int(w))
        self._window = None  # (pyplot module, figure, image) once a window is open
        self._headless = None  # why no window can be shown (str), once known; "" when one can

    def frame(self, scene: dict) -> np.ndarray:
        from .raster import draw

        return draw(scene, self.size)

    def can_show(self) -> bool:
        """Whether :meth:`show` can put a frame on screen (a display, matplotlib with an
        interactive backend, the window not closed by the user). The first ``False`` of the
        process logs why (a logging warning, not a Python warning: a checker run with warnings
        as errors, such as gymnasium's ``check_env`` in a headless CI, still passes)."""
        if self._headless is None:
            self._headless = _why_no_window()
            if self._headless and not _told:
                _told.append(True)
                logging.getLogger("rbenvs").warning(
                    "render_mode='human' shows nothing here: %s. To watch an episode, record it: "
                    "render_mode='rgb_array' "
                    "and gymnasium.wrappers.RecordVideo (docs/rendering.md)",
                    self._headless,
                )
        return not self._headless

    def show(self, frame: np.ndarray, fps: float) -> None:
        if not self.can_show():
            return
        if self._window is None:
            import matplotlib.pyplot as plt

            plt.ion()
            fig = plt.figure(figsize=(self.size[1] / _DPI, self.size[0] / _DPI), dpi=_DPI)
            ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
            ax.set_axis_off()
            self._window = (plt, fig, ax.imshow(frame))
        plt, fig, image = self._window
        if not plt.fignum_exists(fig.number):  # the user closed the window: stop showing
            self._headless = "the window was closed"
            return
        image.set_data(frame)
        fig.canvas.draw_idle()
        plt.pause(1.0 / max(float(fps), 1.0))

    def close(self) -> None:
        if self._window is not None:
            plt, fig, _ = self._window
            plt.close(fig)
            self._window = None


def _why_no_window() -> str:
    """Why a window cannot be opened ("" when it can): no display, no matplotlib, or a
    non-interactive backend."""
    if not display_available():
        return "no display (DISPLAY and WAYLAND_DISPLAY are unset)"
    try:
        import matplotlib.pyplot as plt
    except ImportError:
        return "the window needs matplotlib, pip install 'rbenvs[plot]'"
    backend = str(plt.get_backend()).lower()
    if backend in {"agg", "pdf", "ps", "svg", "pgf", "cairo", "template"} or "inline" in backend:
        return f"matplotlib's backend {backend!r} opens no window"
    return ""

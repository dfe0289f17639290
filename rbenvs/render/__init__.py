"""Pictures of the environments' states (``render_mode="rgb_array"`` and ``"human"``).

One module per system builds a *scene*, plain numpy geometry of one state
(:mod:`rbenvs.render.free_body`, :mod:`rbenvs.render.heavy_top`,
:mod:`rbenvs.render.tippe_top`); :mod:`rbenvs.render.common` draws a scene with matplotlib's
Agg canvas into an ``(H, W, 3)`` uint8 frame. matplotlib (the ``plot`` extra) is imported only
when a frame is drawn: importing this package does not import it.
"""

from .common import FRAME_SIZE, Renderer, draw_scene, require_matplotlib

__all__ = ["FRAME_SIZE", "Renderer", "draw_scene", "require_matplotlib"]

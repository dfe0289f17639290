"""Pictures of the environments' states (``render_mode="rgb_array"`` and ``"human"``).

One module per system builds a *scene*, plain numpy geometry of one state
(:mod:`rbenvs.render.free_body`, :mod:`rbenvs.render.heavy_top`,
:mod:`rbenvs.render.tippe_top`); :mod:`rbenvs.render.raster` draws a scene into an
``(H, W, 3)`` uint8 frame with numpy alone (:mod:`rbenvs.render.common`: the format and the
renderer). matplotlib (the ``plot`` extra) serves only the ``human`` window and the figures.
"""

from .common import FRAME_SIZE, Renderer, require_matplotlib

__all__ = ["FRAME_SIZE", "Renderer", "require_matplotlib"]

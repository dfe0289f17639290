"""A scene drawn into an ``(H, W, 3)`` uint8 frame with numpy alone (no matplotlib).

Why not matplotlib's 3-D axes: they cost far more per frame (``RecordVideo`` pays one a step)
and need the ``plot`` extra, which the core install lacks; ``rbenvs bench render`` measures a
frame beside gymnasium's own pygame frame (docs/rendering.md).

The view is orthographic from ``scene["view"] = (elevation, azimuth)`` in degrees, the same
convention as matplotlib's ``view_init`` (``+z`` up on screen), scaled so that the cube
``center +- extent`` fits the frame. Drawn in this order, each over the last: the checkered
table, the polygons (opaque: a solid's hidden faces culled, others depth-sorted), the spheres
(shaded per pixel), then lines, arrows and points on top, so that a vector starting inside the
body stays visible. No text is drawn (no font without matplotlib); the colours are those of
:data:`rbenvs.render.common.COLORS`, listed in docs/rendering.md.
"""

from __future__ import annotations

import functools
import math

import numpy as np


def rgba(color: str, alpha: float = 1.0, lighten: float = 0.0) -> tuple:
    """``#rrggbb`` as an RGBA tuple in [0, 1], mixed with white by ``lighten`` (0: unchanged)."""
    c = np.array([int(color[k : k + 2], 16) for k in (1, 3, 5)], dtype=float) / 255.0
    c = c + (1.0 - c) * lighten
    return (float(c[0]), float(c[1]), float(c[2]), float(alpha))


__all__ = ["draw", "to_rgb"]

_LIGHT = np.array([0.35, -0.45, 0.82])  # world direction of the light for the spheres' shading
# the cube's projected half-width is at most sqrt(2) extents sideways; this fills the frame
_FIT = 1.25
_SHADES = 64  # the spheres' Lambert shading, quantised


def to_rgb(color) -> tuple:
    """``(r, g, b)`` in 0-255 of ``#rrggbb`` or an RGB(A) tuple in [0, 1] (frames are opaque: an
    alpha is not used)."""
    if isinstance(color, str):
        color = rgba(color)
    return tuple(int(round(255.0 * float(v))) for v in tuple(color)[:3])


class _View:
    """World -> pixel for one scene: ``(x, y)`` = (column, row)."""

    def __init__(self, scene: dict, size):
        self.h, self.w = size
        elev, azim = (math.radians(a) for a in scene.get("view", (20.0, -60.0)))
        self.eye = np.array(
            [math.cos(elev) * math.cos(azim), math.cos(elev) * math.sin(azim), math.sin(elev)]
        )
        self.right = np.array([-math.sin(azim), math.cos(azim), 0.0])
        self.up = np.cross(self.eye, self.right)
        self.center = np.asarray(scene["center"], dtype=float)
        self.scale = (
            0.5 * min(self.h, self.w) / (_FIT * float(scene["extent"]))
        )  # pixels per world unit

    def project(self, points):
        p = np.asarray(points, dtype=float) - self.center
        x = 0.5 * self.w + self.scale * (p @ self.right)
        y = 0.5 * self.h - self.scale * (p @ self.up)
        return x, y


def _pixels(frame):
    """``frame`` (H, W, 3) uint8 seen as (H, W) pixels of 3 bytes: a pixel written as one copy,
    not three through the channel axis."""
    return frame.view("V3")[..., 0]


def _pixel(rgb):
    return np.array(rgb, dtype=np.uint8).view("V3")[0]


def _paint(frame, rows, cols, mask, rgb):
    _pixels(frame)[rows, cols][mask] = _pixel(rgb)  # (views: writing them writes the frame)


def _box(x, y, h, w, pad=0.0):
    """The pixel window ``(rows, cols, xs, ys)`` covering the few points ``x, y`` (clipped), or
    ``None``."""
    c0, c1 = max(math.floor(min(x) - pad), 0), min(math.ceil(max(x) + pad) + 1, w)
    r0, r1 = max(math.floor(min(y) - pad), 0), min(math.ceil(max(y) + pad) + 1, h)
    if c0 >= c1 or r0 >= r1:
        return None
    return slice(r0, r1), slice(c0, c1), np.arange(c0, c1) + 0.5, (np.arange(r0, r1) + 0.5)[:, None]


def _fill_convex(frame, x, y, rgb):
    """Fill the convex polygon with pixel vertices ``x, y`` (lists of floats, either
    orientation)."""
    k = len(x)
    area = sum(x[i] * y[(i + 1) % k] - x[(i + 1) % k] * y[i] for i in range(k))
    box = _box(x, y, frame.shape[0], frame.shape[1])
    if box is None or area == 0.0:
        return
    rows, cols, xs, ys = box
    sign = 1.0 if area > 0.0 else -1.0
    inside = None
    for i in range(k):
        x0, y0, x1, y1 = x[i], y[i], x[(i + 1) % k], y[(i + 1) % k]
        edge = (sign * (x1 - x0)) * (ys - y0) >= (sign * (y1 - y0)) * (xs - x0)
        inside = edge if inside is None else inside & edge
    _paint(frame, rows, cols, inside, rgb)


def _polyline(frame, x, y, rgb, width=1.0, dashed=False):
    """The polyline through the pixel points ``x, y``: every segment sampled at about one point a
    pixel (all segments at once), each sample widened to ``width`` pixels across the segment."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    dx, dy = np.diff(x), np.diff(y)
    length = np.hypot(dx, dy)
    if not np.all(np.isfinite(length)):
        return
    h, w = frame.shape[:2]
    m = (
        np.ceil(np.minimum(length, 2 * (h + w))).astype(int) + 1
    )  # samples per segment, both ends included (a segment far longer than the frame: sparser)
    seg = np.repeat(np.arange(len(m)), m)
    start = np.cumsum(m) - m
    t = (np.arange(seg.size) - start[seg]) / np.maximum(m[seg] - 1, 1)
    xs, ys = x[seg] + dx[seg] * t, y[seg] + dy[seg] * t
    if dashed:  # 6 px on, 6 off, along the arc
        arc = (np.cumsum(length) - length)[seg] + length[seg] * t
        keep = (arc // 6.0) % 2.0 == 0.0
        xs, ys, seg = xs[keep], ys[keep], seg[keep]
    r = max(int(round(0.5 * (width - 1.0))), 0)
    ix, iy = np.floor(xs).astype(int), np.floor(ys).astype(int)
    steep = (
        (np.abs(dy) > np.abs(dx))[seg] if r else None
    )  # widened across the segment: sideways where it is steep
    pixels, color = _pixels(frame), _pixel(rgb)
    for o in range(-r, r + 1):
        cx, cy = (ix + o * steep, iy + o * ~steep) if o else (ix, iy)
        ok = (cx >= 0) & (cx < w) & (cy >= 0) & (cy < h)
        pixels[cy[ok], cx[ok]] = color


def _disc(frame, x, y, radius, rgb):
    box = _box([x], [y], frame.shape[0], frame.shape[1], pad=radius)
    if box is not None:
        rows, cols, xs, ys = box
        _paint(frame, rows, cols, (xs - x) ** 2 + (ys - y) ** 2 <= radius * radius, rgb)


def _checker(frame, view, table):
    """The table ``z = 0``, the square ``center +- half`` in tiles of side ``tile``, two colours:
    each pixel mapped back onto the plane (orthographic: an affine map)."""
    cx, cy = (float(v) for v in table["center"])
    half, tile = float(table["half"]), float(table["tile"])
    corners = np.array(
        [
            [cx - half, cy - half, 0.0],
            [cx + half, cy - half, 0.0],
            [cx + half, cy + half, 0.0],
            [cx - half, cy + half, 0.0],
        ]
    )
    px, py = view.project(corners)
    box = _box(px.tolist(), py.tolist(), frame.shape[0], frame.shape[1])
    if box is None:
        return
    rows, cols, xs, ys = box
    m = np.array([[view.right[0], view.right[1]], [view.up[0], view.up[1]]])
    if abs(np.linalg.det(m)) < 1e-9:  # seen edge-on
        return
    inv = np.linalg.inv(m)
    # each pixel's plane point p from (p - c) . right and (p - c) . up, in tiles from the square's
    # corner (float32: a tile's edge to a hundredth of a pixel, on half the memory)
    f32 = np.float32
    ra = ((xs - 0.5 * view.w) / view.scale + view.center @ view.right).astype(f32)
    rb = ((0.5 * view.h - ys) / view.scale + view.center @ view.up).astype(f32)
    x0, y0 = (cx - half) / tile, (cy - half) / tile
    kx, ky = math.floor(x0), math.floor(y0)  # whole tiles: the parity's offset
    u = f32(inv[0, 0] / tile) * ra + (f32(inv[0, 1] / tile) * rb - f32(kx))
    v = f32(inv[1, 0] / tile) * ra + (f32(inv[1, 1] / tile) * rb - f32(ky))
    lo_x, lo_y, n = f32(x0 - kx), f32(y0 - ky), f32(2.0 * half / tile)
    on = (u >= lo_x) & (u <= lo_x + n) & (v >= lo_y) & (v <= lo_y + n)
    odd = ((u.astype(np.int32) + v.astype(np.int32) + (kx + ky)) & 1).astype(
        bool
    )  # (u, v >= 0 on the table: truncation is the floor)
    region = _pixels(frame)[rows, cols]
    even_color, odd_color = table["colors"]
    np.copyto(region, _pixel(to_rgb(even_color)), where=on)
    np.copyto(region, _pixel(to_rgb(odd_color)), where=on & odd)


def _sphere(frame, view, sphere):
    """A sphere with a body frame ``rotation`` (body -> space): the half ``z_body > 0`` in
    ``colors[1]``, the other in ``colors[0]`` (two shades each, alternating over ``sectors``
    longitudes, so the spin shows), Lambert-shaded."""
    radius = float(sphere["radius"])
    x, y = view.project(np.asarray(sphere["center"], dtype=float)[None, :])
    rpx = radius * view.scale
    box = _box(x.tolist(), y.tolist(), frame.shape[0], frame.shape[1], pad=rpx)
    if box is None:
        return
    rows, cols, xs, ys = box
    a, b = ((xs - x[0]) / rpx).astype(np.float32), ((y[0] - ys) / rpx).astype(np.float32)
    r2 = a * a + b * b
    inside = r2 <= 1.0
    a, b = np.broadcast_to(a, r2.shape)[inside], np.broadcast_to(b, r2.shape)[inside]
    c = np.sqrt(1.0 - r2[inside])
    # the surface normal n = a right + b up + c eye (space), and R^T n (body) from R^T of each
    rot = np.asarray(sphere["rotation"], dtype=float)
    (ra, rb, rc) = (rot.T @ view.right, rot.T @ view.up, rot.T @ view.eye)
    bx, by, bz = (
        a * np.float32(ra[i]) + b * np.float32(rb[i]) + c * np.float32(rc[i]) for i in range(3)
    )
    sectors = int(sphere.get("sectors", 16))
    odd = (np.arctan2(by, bx) * np.float32(sectors / (2.0 * math.pi)) + np.float32(sectors)).astype(
        np.int32
    ) & 1
    light = _LIGHT / np.linalg.norm(_LIGHT)
    lit = (
        a * np.float32(view.right @ light)
        + b * np.float32(view.up @ light)
        + c * np.float32(view.eye @ light)
    )
    level = (np.clip(lit, 0.0, 1.0) * np.float32(_SHADES - 1)).astype(np.int32)
    index = (2 * (bz > 0.0) + odd) * _SHADES + level
    _pixels(frame)[rows, cols][inside] = _shaded_palette(
        tuple(color for half in sphere["colors"] for color in half)
    )[index]


@functools.lru_cache(maxsize=16)
def _shaded_palette(colors: tuple):
    """Each colour at ``_SHADES`` levels of light, ``0.55 + 0.45 level`` of itself, as pixels."""
    level = 0.55 + 0.45 * np.linspace(0.0, 1.0, _SHADES)
    rgb = np.array([to_rgb(c) for c in colors], dtype=float)
    return (rgb[:, None, :] * level[None, :, None]).reshape(-1, 3).astype(np.uint8).view("V3")[:, 0]


def draw(scene: dict, size) -> np.ndarray:
    """The frame ``size + (3,)`` of ``scene`` (the format of :mod:`rbenvs.render.common`)."""
    h, w = size
    frame = np.full((h, w, 3), 255, dtype=np.uint8)  # white background
    view = _View(scene, size)
    if "table" in scene:
        _checker(frame, view, scene["table"])
    for poly in scene.get("polygons", ()):
        faces = [np.asarray(f, dtype=float) for f in poly["faces"]]
        if poly.get("solid"):  # a closed convex solid: faces turned away hidden, no overlaps
            # each face's normal from its first three vertices (a convex face lies in one plane)
            p0, p1, p2 = (np.array([f[i] for f in faces]) for i in range(3))
            normal = np.cross(p1 - p0, p2 - p0)
            centre = np.array([f.mean(axis=0) for f in faces])
            outward = np.sign(
                np.einsum("ij,ij->i", normal, centre - np.mean(np.concatenate(faces), axis=0))
            )
            shown = np.flatnonzero(outward * (normal @ view.eye) > 0.0)
        else:  # far to near: the painter's order
            shown = np.argsort([float(np.mean(f @ view.eye)) for f in faces])
        for k in shown:
            x, y = view.project(faces[k])
            _fill_convex(frame, x.tolist(), y.tolist(), to_rgb(poly["colors"][k]))
    for sphere in scene.get("spheres", ()):
        _sphere(frame, view, sphere)
    for line in scene.get("lines", ()):
        x, y = view.project(line["points"])
        rgb = to_rgb(line.get("color", "#000000"))
        _polyline(frame, x, y, rgb, line.get("width", 1.0), line.get("style", "-") != "-")
    for arrow in scene.get("arrows", ()):
        o = np.asarray(arrow["origin"], dtype=float)
        v = np.asarray(arrow["vector"], dtype=float)
        if not np.all(np.isfinite(v)) or float(np.linalg.norm(v)) == 0.0:
            continue
        x, y = view.project(np.array([o, o + v]))
        rgb = to_rgb(arrow["color"])
        _polyline(frame, x, y, rgb, 3.0)
        dx, dy = x[1] - x[0], y[1] - y[0]
        n = math.hypot(dx, dy)
        if n > 1.0:  # a head of 14 px (or a third of a short arrow), as a filled triangle
            head = min(14.0, n / 3.0)
            ux, uy = dx / n, dy / n
            bx, by = x[1] - head * ux, y[1] - head * uy
            _fill_convex(
                frame,
                [x[1], bx - 0.45 * head * uy, bx + 0.45 * head * uy],
                [y[1], by + 0.45 * head * ux, by - 0.45 * head * ux],
                rgb,
            )
    for point in scene.get("points", ()):
        x, y = view.project(np.asarray(point["position"], dtype=float)[None, :])
        radius = 0.5 * math.sqrt(float(point.get("size", 20))) + 1.0
        _disc(frame, x[0], y[0], radius, to_rgb(point.get("color", "#000000")))
    return frame

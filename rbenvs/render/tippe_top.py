"""The tippe top's picture: the sphere on the table (a checkerboard fixed in the table frame, so
sliding shows), its broad half (where the centre of mass ``G`` sits, ``G = O - h k``) and stem
half in two colours with alternating longitudes (so the spin shows), the stem end ``O + a k``,
the centre of mass, the contact point ``P = O - a z_hat``, and the angular momentum about ``G``
and the angular velocity (docs/physics.md §3). The view follows the top across the table.
"""

from __future__ import annotations

import math

import numpy as np

from .common import COLORS, quat_to_matrix, rgba, scaled_arrow

__all__ = ["scene"]

_LON, _LAT = 16, 10  # sphere faces: longitudes x latitude bands
_EXTENT = 2.3  # half-width of the view, in sphere radii


def _sphere_faces(radius):
    """Faces (4, 3) of the unit-latitude grid on the sphere ``radius`` about the origin (body
    frame, pole ``+e3`` = ``k``), with a flag: on the stem half (``+k``) or not."""
    th = np.linspace(0.0, math.pi, _LAT + 1)
    ph = np.linspace(0.0, 2.0 * math.pi, _LON + 1)

    def pt(t, p):
        return radius * np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)])

    faces, flags = [], []
    for i in range(_LAT):
        for j in range(_LON):
            faces.append(np.array([pt(th[i], ph[j]), pt(th[i], ph[j + 1]), pt(th[i + 1], ph[j + 1]), pt(th[i + 1], ph[j])]))
            flags.append((i < _LAT // 2, j % 2))
    return faces, flags


def _table_tiles(cx, cy, tile, half):
    """Checkerboard tiles (4, 3) on ``z = 0`` at fixed table coordinates, clipped to the square
    ``(cx, cy) +- half``, with their colour parity."""
    x0, x1, y0, y1 = cx - half, cx + half, cy - half, cy + half
    tiles, parity = [], []
    for i in range(math.floor(x0 / tile), math.ceil(x1 / tile)):
        for j in range(math.floor(y0 / tile), math.ceil(y1 / tile)):
            a, b = max(i * tile, x0), min((i + 1) * tile, x1)
            c, d = max(j * tile, y0), min((j + 1) * tile, y1)
            if b > a and d > c:
                tiles.append(np.array([[a, c, 0.0], [b, c, 0.0], [b, d, 0.0], [a, d, 0.0]]))
                parity.append((i + j) % 2)
    return tiles, parity


def scene(system, y, u=None) -> dict:
    """Geometry of the state ``y`` of a :class:`rbenvs.dynamics.TippeTop` under the control
    ``u`` (for the normal force in the text; ``None``: a table at rest), format:
    :mod:`rbenvs.render.common`."""
    prm = system.params
    y = tuple(float(v) for v in y)
    st = system.export_state(y)
    a, h = float(prm.radius), float(prm.height)
    big_a, big_c = prm.inertia
    rot = quat_to_matrix(st["attitude"])
    k = rot[:, 2]
    g = st["position"]
    o = g + h * k
    contact = o - np.array([0.0, 0.0, a])
    half = _EXTENT * a
    tiles, parity = _table_tiles(o[0], o[1], a, half)
    faces = list(tiles)
    colors = [rgba(COLORS["table"], 1.0, lighten=0.5 if p else 0.0) for p in parity]
    sphere, flags = _sphere_faces(a)
    for f, (stem, odd) in zip(sphere, flags):
        faces.append(f @ rot.T + o)
        palette = COLORS["body_alt"] if stem else COLORS["body"]
        colors.append(rgba(palette[odd], 0.92))
    polygons = [{"faces": faces, "colors": colors, "edgecolor": "#666666", "linewidth": 0.15}]
    w_body = np.asarray(st["angular_velocity"], dtype=float)
    l_body = np.array([big_a * w_body[0], big_a * w_body[1], big_c * w_body[2]])
    l_space, w_space = rot @ l_body, rot @ w_body
    norm = float(np.linalg.norm(l_space))
    arrows = []
    if norm > 0.0:
        scale = 2.8 * a / norm
        arrows.append({"origin": g, "vector": l_space * scale, "color": COLORS["momentum"], "label": "angular momentum about G"})
        arrows.append({"origin": g, "vector": scaled_arrow(w_space, scale * big_c, 3.2 * a), "color": COLORS["angular_velocity"], "label": "angular velocity (x C)"})
    lines = [{"points": np.array([o - a * k, o + a * k]), "color": COLORS["axis"][2], "width": 1.2, "style": "--", "label": "symmetry axis k"}]
    points = [
        {"position": contact, "color": COLORS["contact"], "size": 30, "label": "contact point"},
        {"position": g, "color": COLORS["gravity"], "size": 18, "label": "centre of mass"},
        {"position": o + a * k, "color": COLORS["axis"][2], "size": 22, "label": "stem end"},
    ]
    normal, _, slip = system.contact_forces(y, u)
    text = [
        f"tilt = {math.degrees(float(system.tilt(y))):.1f} deg",
        f"spin = {float(system.spin(y)):.4g} rad/s",
        f"E = {float(system.energy(y)):.5g} J",
        f"J = {float(system.jellett(y)):.6g} kg m^2/s",
        f"slip = {float(slip):.3g} m/s, N = {float(normal):.3g} N",
    ]
    return {
        "center": np.array([o[0], o[1], 0.5 * half]),
        "extent": half,
        "view": (18.0, -60.0),
        "title": "tippe top on the table",
        "text": text,
        "polygons": polygons,
        "lines": lines,
        "arrows": arrows,
        "points": points,
    }

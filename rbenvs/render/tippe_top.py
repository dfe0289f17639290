"""The tippe top's picture: the sphere on the table (a checkerboard fixed in the table frame, so
sliding shows), its broad half (where the centre of mass ``G`` sits, ``G = O - h k``) and stem
half in two colours with alternating longitudes (so the spin shows), the stem end ``O + a k``,
the centre of mass, the contact point ``P = O - a z_hat``, and the angular momentum about ``G``
and the angular velocity (docs/physics.md §3). The view follows the top across the table.
"""

from __future__ import annotations

import numpy as np

from .common import COLORS, quat_to_matrix, rgba, scaled_arrow

__all__ = ["scene"]

_LON = 16  # the sphere's alternating longitudes (the spin shows)
_EXTENT = 2.3  # half-width of the view, in sphere radii


def _table(o, a, half) -> dict:
    """The checkered table under the top, a sphere radius per tile; a little inside the view, so
    that its corners stay in the frame."""
    return {
        "center": (o[0], o[1]),
        "half": 0.8 * half,
        "tile": a,
        "colors": (COLORS["table"], rgba(COLORS["table"], 1.0, lighten=0.5)),
    }


def _arrows(st, rot, g, a, inertia) -> list:
    """The angular momentum about ``G`` and the angular velocity (at the momentum's scale), both
    drawn from ``G``; none when the top is at rest."""
    big_a, big_c = inertia
    w_body = np.asarray(st["angular_velocity"], dtype=float)
    l_body = np.array([big_a * w_body[0], big_a * w_body[1], big_c * w_body[2]])
    l_space, w_space = rot @ l_body, rot @ w_body
    norm = float(np.linalg.norm(l_space))
    if not norm > 0.0:  # at rest, or a nan state: no arrows
        return []
    scale = 2.8 * a / norm
    return [
        {
            "origin": g,
            "vector": l_space * scale,
            "color": COLORS["momentum"],
            "label": "angular momentum about G",
        },
        {
            "origin": g,
            "vector": scaled_arrow(w_space, scale * big_c, 3.2 * a),
            "color": COLORS["angular_velocity"],
            "label": "angular velocity (x C)",
        },
    ]


def _points(o, g, k, a) -> list:
    """The contact point ``P = O - a z_hat``, the centre of mass and the stem end."""
    contact = o - np.array([0.0, 0.0, a])
    return [
        {"position": contact, "color": COLORS["contact"], "size": 30, "label": "contact point"},
        {"position": g, "color": COLORS["gravity"], "size": 18, "label": "centre of mass"},
        {"position": o + a * k, "color": COLORS["axis"][2], "size": 22, "label": "stem end"},
    ]


def scene(system, y) -> dict:
    """Geometry of the state ``y`` of a :class:`rbenvs.dynamics.TippeTop` (format:
    :mod:`rbenvs.render.common`)."""
    prm = system.params
    y = tuple(float(v) for v in y)
    st = system.export_state(y)
    a, h = float(prm.radius), float(prm.height)
    rot = quat_to_matrix(st["attitude"])
    k = rot[:, 2]
    g = st["position"]
    o = g + h * k
    half = _EXTENT * a
    # the broad half (body z < 0) yellow, the stem half blue, alternating over the longitudes
    sphere = {
        "center": o,
        "radius": a,
        "rotation": rot,
        "colors": (COLORS["body"], COLORS["body_alt"]),
        "sectors": _LON,
    }
    axis = {
        "points": np.array([o - a * k, o + a * k]),
        "color": COLORS["axis"][2],
        "width": 1.2,
        "style": "--",
        "label": "symmetry axis k",
    }
    return {
        "center": np.array([o[0], o[1], 0.5 * half]),
        "extent": half,
        "view": (18.0, -60.0),
        "table": _table(o, a, half),
        "spheres": [sphere],
        "lines": [axis],
        "arrows": _arrows(st, rot, g, a, prm.inertia),
        "points": _points(o, g, k, a),
    }

"""The heavy top's picture: a cone on its pivot (the origin) whose axis runs to the centre of
mass along ``chi``, a disc there in alternating sectors (so the spin shows), the vertical
through the pivot, gravity at the centre of mass, and the angular momentum ``Pi`` and angular
velocity ``Omega`` about the pivot (docs/physics.md §2).

The state ``(Pi, Gamma)`` fixes the attitude only up to a turn about the vertical. With an
attitude quaternion in the state (``attitude=True``) the picture is in space. Without one it is
drawn in a frame that turns with the precession: the centre-of-mass axis leans toward ``+x``
(``R chi = (sin tilt, 0, cos tilt)``), the body keeps its spin about that axis.
"""

from __future__ import annotations

import math

import numpy as np

from .common import COLORS, quat_to_matrix, scaled_arrow

__all__ = ["display_rotation", "scene"]

_SECTORS = 12
_DISC = 0.6  # disc radius over the pivot-to-centre-of-mass distance


def _perpendicular(v) -> np.ndarray:
    e = np.zeros(3)
    e[int(np.argmin(np.abs(v)))] = 1.0
    p = e - v * float(v @ e)
    return p / np.linalg.norm(p)


def display_rotation(gamma, chi) -> np.ndarray:
    """A rotation ``R`` (body -> display) with ``R^T e_z = Gamma`` and the centre-of-mass axis
    leaning toward ``+x``: the rows of ``R`` are ``u``, ``Gamma x u``, ``Gamma`` (body frame),
    ``u`` the horizontal part of ``chi``. Upright (``chi || Gamma``), ``u`` is any horizontal."""
    g = np.asarray(gamma, dtype=float)
    g = g / np.linalg.norm(g)
    x = np.asarray(chi, dtype=float)
    u = x - g * float(g @ x)
    n = float(np.linalg.norm(u))
    u = u / n if n > 1e-12 else _perpendicular(g)
    return np.array([u, np.cross(g, u), g])


def _body_basis(chi):
    chi = np.asarray(chi, dtype=float)
    t1 = _perpendicular(chi)
    return t1, np.cross(chi, t1), chi


def _body_polygons(chi, length, rot) -> dict:
    """The cone from the pivot to the disc at the centre of mass, and the disc, their sectors in
    alternating shades (so the spin shows); built in body coordinates, returned in space."""
    t1, t2, k = _body_basis(chi)
    ang = np.linspace(0.0, 2.0 * np.pi, _SECTORS + 1)
    rim = np.array(
        [length * k + _DISC * length * (math.cos(a) * t1 + math.sin(a) * t2) for a in ang]
    )
    centre = length * k
    faces, colors = [], []
    for s in range(_SECTORS):
        faces.append(np.array([np.zeros(3), rim[s], rim[s + 1]]))
        colors.append(COLORS["body"][s % 2])
        faces.append(np.array([centre, rim[s], rim[s + 1]]))
        colors.append(COLORS["body_alt"][s % 2])
    return {"faces": [f @ rot.T for f in faces], "colors": colors, "solid": True}


def _lines(chi, length, rot) -> list:
    """The vertical through the pivot, the symmetry axis, and, for depth, a ground circle under
    the pivot with the post that holds it."""
    reach = 1.9 * length
    circ = np.linspace(0.0, 2.0 * np.pi, 49)
    ground = np.stack(
        [reach * np.cos(circ), reach * np.sin(circ), -0.6 * length * np.ones_like(circ)], axis=1
    )
    return [
        {
            "points": np.array([[0.0, 0.0, 0.0], [0.0, 0.0, reach]]),
            "color": "#777777",
            "width": 1.0,
            "style": "--",
            "label": "vertical",
        },
        {
            "points": np.array([np.zeros(3), rot @ (1.35 * length * chi)]),
            "color": COLORS["axis"][2],
            "width": 2.0,
            "label": "symmetry axis",
        },
        {"points": ground, "color": COLORS["grid"], "width": 0.6},
        {
            "points": np.array([[0.0, 0.0, -0.6 * length], [0.0, 0.0, 0.0]]),
            "color": "#444444",
            "width": 3.0,
        },
    ]


def _arrows(system, y, chi, length, rot) -> list:
    """Gravity at the centre of mass, and the angular momentum and angular velocity about the
    pivot (both at the momentum's scale; none when the top is at rest)."""
    pi = np.array(y[0:3])
    omega = np.array(system.angular_velocity(y), dtype=float)
    norm = float(np.linalg.norm(pi))
    arrows = [
        {
            "origin": rot @ (length * chi),
            "vector": np.array([0.0, 0.0, -0.5 * length]),
            "color": COLORS["gravity"],
            "label": "gravity",
        }
    ]
    if norm > 0.0:
        scale = 1.6 * length / norm
        arrows.append(
            {
                "origin": np.zeros(3),
                "vector": rot @ pi * scale,
                "color": COLORS["momentum"],
                "label": "angular momentum",
            }
        )
        i_ref = float(system.params.inertia[int(np.argmax(np.abs(chi)))])
        arrows.append(
            {
                "origin": np.zeros(3),
                "vector": scaled_arrow(rot @ omega, scale * i_ref, 2.2 * length),
                "color": COLORS["angular_velocity"],
                "label": "angular velocity (x I3)",
            }
        )
    return arrows


def scene(system, y) -> dict:
    """Geometry of the state ``y`` of a :class:`rbenvs.dynamics.HeavyTop` (format:
    :mod:`rbenvs.render.common`)."""
    prm = system.params
    y = tuple(float(v) for v in y)
    chi = np.asarray(prm.com_direction, dtype=float)
    gamma = np.array(y[3:6])
    rot = quat_to_matrix(y[6:10]) if system.attitude else display_rotation(gamma, chi)
    length = float(prm.length)
    return {
        "center": np.array([0.0, 0.0, 0.3 * length]),
        "extent": 1.6 * length,
        "view": (18.0, -60.0),
        "polygons": [_body_polygons(chi, length, rot)],
        "lines": _lines(chi, length, rot),
        "arrows": _arrows(system, y, chi, length, rot),
        "points": [{"position": np.zeros(3), "color": "#000000", "size": 25, "label": "pivot"}],
    }

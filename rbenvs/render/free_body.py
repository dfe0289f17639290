"""The free rigid body's picture: a box with the body's principal moments, its principal axes,
the angular momentum ``Pi`` and angular velocity ``Omega`` (docs/physics.md §1).

Without an attitude in the state (tasks ``spin``, ``detumble``) the picture is drawn in the
**body frame**: the box stands still and ``Pi`` wanders over its orbit, the intersection of the
momentum sphere with the energy ellipsoid ([MR Fig. 15.3.1]), drawn as a thin curve. With an
attitude (``reorient``) it is drawn in **space**: the box turns and, without torque, ``R Pi``
stays fixed.
"""

from __future__ import annotations

import numpy as np

from .common import COLORS, quat_to_matrix, rgba, scaled_arrow

__all__ = ["box_half_sides", "momentum_orbit", "scene"]

# arrow length of the angular momentum, in units of the box's largest half-side
_ARROW = 1.6


def box_half_sides(inertia) -> np.ndarray:
    """Half-sides (3,) of the uniform box with the principal moments ``inertia`` (up to scale:
    ``I_i ~ a_j^2 + a_k^2``, so ``a_i^2 ~ I_j + I_k - I_i``), the largest one 1. A flat body
    (a triangle equality) gets a thin but visible side."""
    i = np.asarray(inertia, dtype=float)
    sq = np.maximum(i.sum() - 2.0 * i, 0.0)
    a = np.sqrt(sq)
    a = a / a.max() if a.max() > 0.0 else np.ones(3)
    return np.maximum(a, 0.06)


def momentum_orbit(inertia, pi, n: int = 240):
    """The torque-free orbit of ``Pi`` through ``pi``: points (n, 3) of the intersection of the
    sphere ``|Pi| = |pi|`` with the energy ellipsoid ``sum Pi_i^2 / I_i = 2 H`` (docs/physics.md §1,
    [MR Fig. 15.3.1]), on the side of ``pi``; ``None`` for a fixed point or equal moments.

    The orbit encircles the axis ``k`` of the largest moment when ``2 H < |pi|^2 / I_mid`` and
    the smallest otherwise; projected on the other two axes ``(i, j)`` it is the ellipse
    ``c_i Pi_i^2 + c_j Pi_j^2 = 2 H - |pi|^2 / I_k`` with ``c = 1/I - 1/I_k``, and
    ``Pi_k = +-sqrt(|pi|^2 - Pi_i^2 - Pi_j^2)``.
    """
    inertia = np.asarray(inertia, dtype=float)
    p = np.asarray(pi, dtype=float)
    r2 = float(p @ p)
    if r2 == 0.0:
        return None
    two_h = float(np.sum(p * p / inertia))
    order = np.argsort(inertia)  # minor, intermediate, major
    k = order[2] if two_h < r2 / inertia[order[1]] else order[0]
    i, j = [m for m in range(3) if m != k]
    ci, cj = 1.0 / inertia[i] - 1.0 / inertia[k], 1.0 / inertia[j] - 1.0 / inertia[k]
    rhs = two_h - r2 / inertia[k]
    if ci == 0.0 or cj == 0.0 or rhs / ci <= 0.0 or rhs / cj <= 0.0:
        return None
    phi = np.linspace(0.0, 2.0 * np.pi, n)
    out = np.empty((n, 3))
    out[:, i] = np.sqrt(rhs / ci) * np.cos(phi)
    out[:, j] = np.sqrt(rhs / cj) * np.sin(phi)
    out[:, k] = np.copysign(
        np.sqrt(np.maximum(r2 - out[:, i] ** 2 - out[:, j] ** 2, 0.0)), p[k] if p[k] != 0.0 else 1.0
    )
    return out


def _box_faces(half):
    """The six faces (4, 3) of the box ``+-half`` and the body axis each one is normal to."""
    faces, axes = [], []
    for ax in range(3):
        b, c = [m for m in range(3) if m != ax]
        for sign in (1.0, -1.0):
            f = np.zeros((4, 3))
            f[:, ax] = sign * half[ax]
            f[:, b] = np.array([-1, 1, 1, -1]) * half[b]
            f[:, c] = np.array([-1, -1, 1, 1]) * half[c]
            faces.append(f)
            axes.append((ax, sign))
    return faces, axes


def _box_polygons(half, rot) -> dict:
    """The box, each axis's faces in its colour, the + face lighter."""
    faces, normals = _box_faces(half)
    colors = []
    for ax, sign in normals:
        colors.append(rgba(COLORS["axis"][ax], lighten=0.55 if sign > 0 else 0.2))
    return {"faces": [f @ rot.T for f in faces], "colors": colors, "solid": True}


def _axis_lines(half, inertia, rot) -> list:
    """The three principal axes through the box, labelled with their moments."""
    lines = []
    for ax in range(3):
        e = np.zeros(3)
        e[ax] = 1.3 * max(half[ax], 0.5)
        lines.append(
            {
                "points": np.array([-e, e]) @ rot.T,
                "color": COLORS["axis"][ax],
                "width": 1.5,
                "label": f"axis {ax + 1} (I = {inertia[ax]:.3g})",
            }
        )
    return lines


def _momentum_parts(inertia, pi, omega, rot, space):
    """``(lines, arrows)``: the orbit of ``Pi`` (a body-frame curve, so drawn in the body frame
    only), and the angular momentum and angular velocity arrows; none at rest."""
    norm = float(np.linalg.norm(pi))
    if not norm > 0.0:  # at rest, or a nan state: no arrows
        return [], []
    lines, scale = [], _ARROW / norm
    orbit = momentum_orbit(inertia, pi)
    if orbit is not None and not space:
        lines.append(
            {"points": orbit * scale, "color": COLORS["momentum"], "width": 0.8, "style": ":"}
        )
    i_mean = float(inertia.mean())
    arrows = [
        {
            "origin": np.zeros(3),
            "vector": rot @ pi * scale,
            "color": COLORS["momentum"],
            "label": "angular momentum",
        },
        {
            "origin": np.zeros(3),
            "vector": scaled_arrow(rot @ omega, scale * i_mean, 2.0 * _ARROW),
            "color": COLORS["angular_velocity"],
            "label": "angular velocity (x mean I)",
        },
    ]
    return lines, arrows


def scene(system, y) -> dict:
    """Geometry of the state ``y`` of a :class:`rbenvs.dynamics.FreeBody` (see
    :mod:`rbenvs.render.common` for the format)."""
    y = tuple(float(v) for v in y)
    inertia = np.asarray(system.params.inertia, dtype=float)
    pi = np.array(y[0:3], dtype=float)
    omega = np.array(system.angular_velocity(y), dtype=float)
    space = bool(system.attitude)
    rot = quat_to_matrix(y[3:7]) if space else np.eye(3)
    half = box_half_sides(inertia)
    orbit_lines, arrows = _momentum_parts(inertia, pi, omega, rot, space)
    return {
        "center": np.zeros(3),
        "extent": 1.9,
        "view": (22.0, -55.0),
        "polygons": [_box_polygons(half, rot)],
        "lines": _axis_lines(half, inertia, rot) + orbit_lines,
        "arrows": arrows,
    }

"""The tippe top's states: the layout of each fidelity's components, and a state exported to
named arrays and imported from them, checked against the contact constraint."""

from __future__ import annotations

import numpy as np

from ..validation import did_you_mean, real_array
from .params import FIDELITIES, FRICTION_BOUNDS

__all__ = ["require_fidelity", "state_layout", "export_state", "import_state"]


def require_fidelity(fidelity: str, friction_bound: str, flight: bool, stem: bool) -> None:
    """A fidelity, friction bound, flight and stem that a top can have together."""
    if fidelity not in FIDELITIES:
        raise ValueError(
            f"fidelity must be one of {list(FIDELITIES)}, got "
            f"{fidelity!r}{did_you_mean(fidelity, FIDELITIES)}"
        )
    if friction_bound not in FRICTION_BOUNDS:
        raise ValueError(
            f"friction_bound must be one of {list(FRICTION_BOUNDS)}, got "
            f"{friction_bound!r}{did_you_mean(friction_bound, FRICTION_BOUNDS)}"
        )
    rolling = fidelity == "rolling"
    if flight and rolling:
        raise ValueError(
            "flight=True needs fidelity 'gliding' or 'frictionless' (a rolling top has no slip "
            "to resume after a touchdown)"
        )
    if stem and rolling:
        raise ValueError(
            "stem needs fidelity 'gliding' or 'frictionless' (the rolling limit has no slip to "
            "resume after the stem's touchdown)"
        )
    if stem and flight:
        raise ValueError(
            "stem with flight=True is not modelled: a touchdown from flight could meet both "
            "contacts at once, which needs a two-contact impact law (docs/physics.md §3, 'The "
            "stem')"
        )


def state_layout(stem: bool, flight: bool, rolling: bool) -> tuple[dict, int]:
    """``(layout, dim)``: each named block's ``(start, stop)`` in the state and the state's size,
    for the stem, free flight, the rolling limit or the gliding top."""
    if stem:
        layout = {
            "position": (0, 2),
            "velocity": (2, 4),
            "attitude": (4, 8),
            "angular_velocity": (8, 11),
            "contact": (11, 12),
        }
    elif flight:
        layout = {
            "position": (0, 3),
            "velocity": (3, 6),
            "attitude": (6, 10),
            "angular_velocity": (10, 13),
            "contact": (13, 14),
            "hops": (14, 15),
        }
    elif rolling:
        layout = {"position": (0, 2), "attitude": (2, 6), "angular_velocity": (6, 9)}
    else:
        layout = {
            "position": (0, 2),
            "velocity": (2, 4),
            "attitude": (4, 8),
            "angular_velocity": (8, 11),
        }
    return layout, max(stop for _, stop in layout.values())


def export_state(system, y) -> dict:
    """Named arrays: ``position`` (3, with ``z_G`` from the constraint), ``velocity`` (3,
    space, table frame), ``attitude`` (4, w x y z, body to space), ``angular_velocity`` (3,
    body)."""
    o = system.layout["attitude"][0]
    return {
        "position": np.array([y[0], y[1], system.height(y)], dtype=np.float64),
        "velocity": np.array(system.velocity(y), dtype=np.float64),
        "attitude": np.array(y[o : o + 4], dtype=np.float64),
        "angular_velocity": np.array(y[o + 4 : o + 7], dtype=np.float64),
    }


def import_state(system, state: dict) -> tuple:
    """Components from :meth:`export_state`'s dict, checked against the contact constraint:
    ``z_G = a - h cos(theta)``, ``v_z`` (and, rolling, the whole velocity) as the attitude and
    angular velocity require. ``ValueError`` naming the entry otherwise."""
    arrs = _named_arrays(state)
    q = tuple(float(c) for c in arrs["attitude"])
    w = tuple(float(c) for c in arrs["angular_velocity"])
    pos = tuple(float(c) for c in arrs["position"])
    vel = tuple(float(c) for c in arrs["velocity"])
    y = system.state(pos, q, w, vel[:2])
    prm = system.params
    if system.flight:
        return _place_flight_state(system, y, pos, vel)
    if system.stem:  # on the stem where its constraint's height is the one given
        on_stem = y[:11] + (1.0,)
        if (
            abs(pos[2] - system.height(on_stem)) <= 1e-9 * prm.radius + 1e-12
            and system.other_gap(on_stem) >= 0.0
        ):
            y = on_stem
    z = system.height(y)
    if abs(pos[2] - z) > 1e-9 * prm.radius + 1e-12:
        raise ValueError(
            f"state['position'][2] must be the contact height a - h cos(theta) = {z!r} m for "
            f"this attitude (the sphere touches the table), got {pos[2]!r}"
        )
    _require_contact_velocity(system, y, vel, w)
    return y


def _named_arrays(state) -> dict:
    """The arrays of :meth:`export_state`'s names in ``state``, checked: a dict of exactly those
    names, each real, finite and of its shape, the attitude a unit quaternion."""
    names = ("position", "velocity", "attitude", "angular_velocity")
    if not isinstance(state, dict):
        raise ValueError(
            f"options['state'] must be a dict of named arrays, got {type(state).__name__}"
        )
    unknown, missing = sorted(set(state) - set(names)), sorted(set(names) - set(state))
    if unknown or missing:
        raise ValueError(
            f"state must have exactly the names {sorted(names)}"
            + (f"; unknown: {unknown}" if unknown else "")
            + (f"; missing: {missing}" if missing else "")
        )
    arrs = {}
    for name, size in zip(names, (3, 3, 4, 3)):
        arr = real_array(f"state[{name!r}]", state[name])
        if arr.shape != (size,):
            raise ValueError(f"state[{name!r}] must have shape ({size},), got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"state[{name!r}] must be finite, got {arr}")
        arrs[name] = arr
    qn = float(np.linalg.norm(arrs["attitude"]))
    if abs(qn - 1.0) > 1e-6:
        raise ValueError(
            f"state['attitude'] must be a unit quaternion (|q| = 1 within 1e-6), got |q| = {qn}"
        )
    return arrs


def _require_contact_velocity(system, y, vel, w) -> None:
    """The given velocity ``vel`` of a top on the table at ``y``: ``v_z`` (rolling: the whole
    velocity) as the contact constraint requires at angular velocity ``w``."""
    v_need = system.velocity(y)
    scale = 1e-9 * (1.0 + system.params.radius * float(np.linalg.norm(w)))
    checked = range(3) if system.rolling else (2,)
    for i in checked:
        if abs(vel[i] - v_need[i]) > scale:
            what = (
                "the rolling velocity -omega x r"
                if system.rolling
                else "the vertical velocity the contact constraint gives"
            )
            raise ValueError(
                f"state['velocity'] must equal {what} ({list(v_need)}), got {list(vel)}"
            )


def _place_flight_state(system, y, pos, vel):
    """With flight: the given height and vertical velocity, classified. On the table (gap
    within round-off of 0, not approaching faster than round-off): in contact, ``v_z`` must
    be the constraint's; above it: in flight; below it: refused."""
    prm = system.params
    tol = 1e-9 * prm.radius + 1e-12
    air = y[:2] + (pos[2],) + y[3:5] + (vel[2],) + y[6:13] + (0.0, 0.0)
    gap = system.gap(air)
    if gap < -tol:
        raise ValueError(
            f"state['position'][2] puts the sphere {-gap!r} m into the table (z_G must be >= a "
            f"- h cos(theta) = {pos[2] - gap!r} m)"
        )
    if gap > tol:
        return air
    v_need = system.velocity(y)[2]  # y is on the table: the constraint's v_z
    scale = 1e-9 * (1.0 + prm.radius * float(np.linalg.norm(y[10:13])))
    if vel[2] - v_need > scale:  # on the table and leaving it: in flight
        return air
    if abs(vel[2] - v_need) > scale:
        raise ValueError(
            "state['velocity'][2] must be the vertical velocity the contact constraint gives "
            f"({v_need!r}) or above it (leaving the table), got {vel[2]!r}"
        )
    return y

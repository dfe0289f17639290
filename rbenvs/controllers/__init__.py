"""Analytic controllers: reference feedback laws that map observations to actions."""

from .free_body import DetumbleDamping, ReorientPD, SpinLQR, ZeroController
from .heavy_top import PrecessionTracking, UprightLQR
from .tippe_top import SlipCancelling

__all__ = ["ZeroController", "SpinLQR", "DetumbleDamping", "ReorientPD", "UprightLQR", "PrecessionTracking", "SlipCancelling", "controller_for"]

# Task names are unique across the systems, so the task alone picks the law.
_BY_TASK = {
    "spin": SpinLQR,
    "detumble": DetumbleDamping,
    "reorient": ReorientPD,
    "upright": UprightLQR,
    "precess": PrecessionTracking,
    # The tippe top inverts by itself: no action is the reference for "invert" (an analytic
    # law that inverts faster is an open problem here); "hold" removes the slip.
    "invert": ZeroController,
    "hold": SlipCancelling,
}


def controller_for(env):
    """The analytic controller for ``env``'s task."""
    return _BY_TASK[env.unwrapped.task.name](env)

"""Analytic controllers: reference feedback laws that map observations to actions."""

from .free_body import DetumbleDamping, ReorientPD, SpinLQR, ZeroController
from .heavy_top import PrecessionTracking, UprightLQR
from .tippe_top import SlipCancelling

__all__ = [
    "ZeroController",
    "SpinLQR",
    "DetumbleDamping",
    "ReorientPD",
    "UprightLQR",
    "PrecessionTracking",
    "SlipCancelling",
    "controller_for",
]


def controller_for(env):
    """The analytic controller for ``env``'s task: the one its task names (``task.controller``,
    a class of this package; the tippe top's ``invert`` names :class:`ZeroController`: it
    inverts by itself, and a law that inverts faster is an open problem here)."""
    return globals()[env.unwrapped.task.controller](env)

"""Analytic controllers: reference feedback laws that map observations to actions."""

from .free_body import DetumbleDamping, ReorientPD, SpinLQR, ZeroController, controller_for

__all__ = ["ZeroController", "SpinLQR", "DetumbleDamping", "ReorientPD", "controller_for"]

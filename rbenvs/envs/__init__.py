"""Gymnasium environment classes: spaces, seeding, state dict; glue only."""

from .base import NumericalFailureWarning, RigidBodyEnv, UnstableMotionWarning
from .free_body import FreeRigidBodyEnv
from .heavy_top import LagrangeTopEnv
from .tippe_top import TippeTopEnv

__all__ = [
    "RigidBodyEnv",
    "FreeRigidBodyEnv",
    "LagrangeTopEnv",
    "TippeTopEnv",
    "NumericalFailureWarning",
    "UnstableMotionWarning",
]

"""Gymnasium environment classes: spaces, seeding, state dict; glue only."""

from .base import NumericalFailureWarning, RigidBodyEnv
from .free_body import FreeRigidBodyEnv

__all__ = ["RigidBodyEnv", "FreeRigidBodyEnv", "NumericalFailureWarning"]

"""Tasks: initial-state distribution, observation, reward, termination (no integration)."""

from .free_body import AXIS_NAMES, DetumbleTask, ReorientTask, SpinTask
from .heavy_top import PrecessTask, UprightTask, slow_precession_rate, transverse_basis
from .tippe_top import HoldTask, InvertTask

__all__ = [
    "AXIS_NAMES",
    "SpinTask",
    "DetumbleTask",
    "ReorientTask",
    "UprightTask",
    "PrecessTask",
    "slow_precession_rate",
    "transverse_basis",
    "InvertTask",
    "HoldTask",
]

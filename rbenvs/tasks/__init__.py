"""Tasks: initial-state distribution, observation, reward, termination (no integration)."""

from .free_body import AXIS_NAMES, DetumbleTask, ReorientTask, SpinTask

__all__ = ["AXIS_NAMES", "SpinTask", "DetumbleTask", "ReorientTask"]

"""Equations of motion, one module per system (pure: no gymnasium)."""

from .free_body import FreeBody, FreeBodyOrbit, FreeBodyParams

__all__ = ["FreeBody", "FreeBodyOrbit", "FreeBodyParams"]

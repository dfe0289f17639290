"""Equations of motion, one module per system (pure: no gymnasium)."""

from .free_body import FreeBody, FreeBodyOrbit, FreeBodyParams
from .heavy_top import HeavyTop, HeavyTopParams
from .tippe_top import TippeTop, TippeTopParams

__all__ = [
    "FreeBody",
    "FreeBodyOrbit",
    "FreeBodyParams",
    "HeavyTop",
    "HeavyTopParams",
    "TippeTop",
    "TippeTopParams",
]

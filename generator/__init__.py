"""Procedural construction sites, the interactive Simulator, rendering and the batch CLI.

``from generator import Simulator`` imports Blender (bpy). The bpy-free geometry used by
the other packages lives in :mod:`generator.geometry` and never imports bpy.
"""

from __future__ import annotations

__all__ = ["Simulator"]


def __getattr__(name: str):
    if name == "Simulator":
        from .simulator import Simulator

        return Simulator
    raise AttributeError(f"module 'generator' has no attribute {name!r}")

"""Site power generators on a base frame, in the band along the fence."""

from __future__ import annotations

import numpy as np

from ..assets import Asset, Part
from ..kinds import AssetKind, register
from ..materials import Material
from ..meshes import MeshBuilder
from ..planning import Mix


def generator_set(rng: np.random.Generator) -> Asset:
    """A site generator (2-4 m x 1 m x 1.5 m) on a base frame, with an exhaust stack."""
    length = rng.uniform(2.0, 4.0)
    b = MeshBuilder()
    b.box((length, 1.1, 0.15), (0, 0, 0.075), material="steel_dark")
    b.box((length - 0.1, 1.0, 1.35), (0, 0, 0.15 + 0.675), material="generator_paint")
    b.cylinder(0.06, (length / 2 - 0.4, 0.2, 1.5), (length / 2 - 0.4, 0.2, 1.9), segments=8, material="steel_dark")
    b.box((0.03, 0.5, 0.4), (-length / 2 + 0.03, 0, 0.9), material="steel_dark")  # control panel
    return Asset("Generator", [Part("Generator", b.build())], (length + 0.1, 1.2))


register(AssetKind(
    name="Generator", classes=("Generator",), build=generator_set, place=Mix(weight=1, band=True), order=62,
    materials=(Material("generator_paint", (0.1, 0.35, 0.1), 0.5, 0.2),),
    shared_streams=True,
))

"""Portable toilets, one to four side by side, in the band along the fence."""

from __future__ import annotations

import numpy as np

from ..assets import Asset, Part
from ..kinds import AssetKind, register
from ..materials import Material
from ..meshes import MeshBuilder
from ..planning import Mix


def portable_toilets(rng: np.random.Generator) -> Asset:
    """One to four portable toilets (1.1 x 1.2 x 2.3 m) side by side."""
    count = int(rng.integers(1, 5))
    parts = []
    for k in range(count):
        b = MeshBuilder()
        b.box((1.1, 1.2, 2.2), (0, 0, 1.1), material="plastic_toilet")
        b.box((1.15, 1.2, 0.1), (0, 0, 2.25), material="plastic_white")  # roof: no wider than the 1.2 m body
        b.box((0.04, 0.8, 1.9), (0.57, 0, 1.0), material="plastic_toilet_door")
        b.cylinder(0.04, (-0.4, 0.4, 2.3), (-0.4, 0.4, 2.6), segments=8, material="plastic_white")
        parts.append(Part("PortableToilet", b.build(), location=(0, (k - (count - 1) / 2) * 1.25, 0)))
    return Asset("PortableToilet", parts, (1.3, count * 1.25))


register(AssetKind(
    name="PortableToilet", classes=("PortableToilet",), build=portable_toilets, place=Mix(weight=1, band=True), order=60,
    materials=(Material("plastic_toilet", (0.03, 0.3, 0.1), 0.4), Material("plastic_toilet_door", (0.02, 0.2, 0.07), 0.4)),
    shared_streams=True,
))

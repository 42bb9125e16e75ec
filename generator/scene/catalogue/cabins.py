"""Site cabins (offices, welfare), one or two side by side, some stacked two high with an
outside stair, in the band along the fence."""

from __future__ import annotations

import numpy as np

from ..assets import Asset, Part
from ..kinds import AssetKind, register
from ..materials import Material, Pattern
from ..meshes import MeshBuilder
from ..planning import Mix


def cabin_block(rng: np.random.Generator) -> Asset:
    """Site cabins (6.0, 3.0 or 9.0 m x 2.4 x 2.7) with windows and a door, one or two
    side by side, optionally stacked two high with an outside stair."""
    length = float(rng.choice([3.0, 6.0, 6.0, 9.0]))
    count = int(rng.integers(1, 3))
    stacked = rng.random() < 0.4 and length >= 6.0
    parts = []
    w, h = 2.4, 2.7
    for c in range(count):
        for lev in range(2 if stacked else 1):
            b = MeshBuilder()
            b.box((length, w, h - 0.1), (0, 0, (h - 0.1) / 2 + 0.1), material="cabin_paint")
            b.box((length, w, 0.1), (0, 0, 0.05), material="steel_dark")
            for k in range(int(length // 3)):
                x = -length / 2 + 1.5 + 3.0 * k
                b.box((1.2, 0.04, 1.0), (x, -w / 2 - 0.02, 1.6), material="glass")
            b.box((0.9, 0.04, 2.0), (length / 2 - 0.7, -w / 2 - 0.02, 1.1), material="door_paint")
            y = (c - (count - 1) / 2) * (w + 0.1)
            parts.append(Part("Cabin", b.build(), location=(0, y, lev * h)))
    size_y = count * (w + 0.1) - 0.1
    if stacked:
        stair = MeshBuilder()
        y0 = -size_y / 2 - 1.1
        run = 3.6
        steps = 14
        for k in range(steps):
            stair.box((run / steps, 0.9, 0.05), (-length / 2 + 0.6 + (k + 0.5) * run / steps, y0 + 0.5, (k + 1) * h / steps), material="steel_galvanized")
        for s in (0.0, 1.0):  # stringers: start 0.03 m (their radius) up so the tilted end caps stay above the ground
            stair.cylinder(0.03, (-length / 2 + 0.6, y0 + s, 0.03), (-length / 2 + 0.6 + run, y0 + s, h), segments=6, material="steel_galvanized")
        stair.box((1.2, 1.0, 0.06), (-length / 2 + 0.6 + run + 0.6, y0 + 0.5, h + 0.03), material="steel_galvanized")  # landing
        stair.cylinder(0.04, (-length / 2 + 0.6 + run + 1.1, y0 + 0.1, 0), (-length / 2 + 0.6 + run + 1.1, y0 + 0.1, h), segments=6, material="steel_galvanized")
        parts.append(Part("Cabin", stair.build()))
        size_y += 2 * 1.2
    return Asset("Cabin", parts, (length + 0.2, size_y + 0.2))


register(AssetKind(
    name="Cabin", classes=("Cabin",), build=cabin_block, place=Mix(weight=2, band=True), order=51,
    materials=(Material("cabin_paint", (0.75, 0.76, 0.74), 0.5, 0.1, Pattern(5.0, (0.5, 0.5, 0.48), 0.2)),
               Material("door_paint", (0.1, 0.2, 0.45), 0.5, 0.1)),
    shared_streams=True,
))

"""Open skips with sloped ends, sometimes part filled with rubble."""

from __future__ import annotations

import numpy as np

from ...geometry.portable_math import vector_norm
from ..assets import Asset, Part
from ..kinds import AssetKind, register
from ..materials import STREAKS, Material, Pattern
from ..meshes import MeshBuilder
from ..planning import Mix


def skip(rng: np.random.Generator) -> Asset:
    """An open skip (3.7 x 1.8 x 1.2 m) with sloped ends, sometimes partly filled."""
    b = MeshBuilder()
    length, width, height, t = 3.7, 1.8, 1.2, 0.05
    b.box((length - 1.0, width, t), (0, 0, t / 2), material="skip_paint")
    for s in (-1, 1):
        b.prism([(-(length - 1.0) / 2, 0), ((length - 1.0) / 2, 0), (length / 2, height), (-length / 2, height)], t,
                offset=(0, s * (width / 2 - t / 2), 0), material="skip_paint")
        # sloped end wall: a plate from the floor's end up to the rim
        bottom, top = np.array([s * (length - 1.0) / 2, 0, 0]), np.array([s * length / 2, 0, height])
        ex = (top - bottom) / vector_norm(top - bottom)
        ey = np.array([0.0, 1.0, 0.0])
        ez = np.cross(ex, ey)
        rot = np.column_stack([ex, ey, ez])
        lift = np.array([0.0, 0.0, abs(ez[2]) * t / 2 + 1e-3])  # the plate's lower edge stays on the ground
        b.box((vector_norm(top - bottom), width - 2 * t - 0.01, t), (bottom + top) / 2 + lift, rotation=rot, material="skip_paint")
    if rng.random() < 0.6:
        fill = rng.uniform(0.2, 0.8)
        b.box((length - 1.2, width - 2 * t - 0.05, fill), (0, 0, t + fill / 2 + 0.001), material="rubble")
    return Asset("Skip", [Part("Skip", b.build())], (length + 0.1, width + 0.1))


register(AssetKind(
    name="Skip", classes=("Skip",), build=skip, place=Mix(weight=1.5), order=61,
    materials=(Material("skip_paint", (0.7, 0.5, 0.02), 0.6, 0.2, Pattern(5.0, (0.3, 0.15, 0.05), 0.5), layers=(STREAKS,)),
               Material("rubble", (0.3, 0.27, 0.24), 0.95, 0.0, Pattern(30.0, (0.15, 0.12, 0.1), 0.6))),
    shared_streams=True,
))

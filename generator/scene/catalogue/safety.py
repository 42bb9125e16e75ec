"""Concrete jersey barriers in rows and lines of traffic cones."""

from __future__ import annotations

import numpy as np

from ..assets import Asset, Part
from ..kinds import AssetKind, register
from ..materials import Material, Pattern
from ..meshes import MeshBuilder
from ..planning import Mix


def barriers(rng: np.random.Generator) -> Asset:
    """A row of 2-6 concrete jersey barriers (2-4 m long, 0.6 m base, 0.8-1.0 m tall)."""
    count, length, height = int(rng.integers(2, 7)), rng.uniform(2.0, 4.0), rng.uniform(0.8, 1.0)
    profile = [(-0.3, 0), (0.3, 0), (0.3, 0.08), (0.18, 0.33), (0.08, height), (-0.08, height), (-0.18, 0.33), (-0.3, 0.08)]
    parts = []
    for k in range(count):
        b = MeshBuilder().prism(profile, length, material="concrete_white")
        # the prism runs along y: rotate it so the row runs along x
        parts.append(Part("Barrier", b.build(), location=((k - (count - 1) / 2) * (length + 0.03), 0, 0), rotation=(0, 0, np.pi / 2)))
    return Asset("Barrier", parts, (count * (length + 0.03), 0.62))


def traffic_cones(rng: np.random.Generator) -> Asset:
    """A line of 3-8 traffic cones (0.5-1.0 m tall, orange with white bands)."""
    count, height = int(rng.integers(3, 9)), float(rng.choice([0.5, 0.75, 0.75, 1.0]))
    spacing = rng.uniform(1.0, 2.5)
    parts = []
    for k in range(count):
        b = MeshBuilder()
        b.box((0.38 * height / 0.75, 0.38 * height / 0.75, 0.03), (0, 0, 0.015), material="plastic_orange")
        r0, r1 = 0.15 * height / 0.75, 0.03
        zs = [0.03, 0.35 * height, 0.5 * height, 0.6 * height, 0.72 * height, height]
        mats = ["plastic_orange", "reflective_white", "plastic_orange", "reflective_white", "plastic_orange"]
        for a in range(5):
            ra = r0 + (r1 - r0) * (zs[a] - 0.03) / (height - 0.03)
            rb = r0 + (r1 - r0) * (zs[a + 1] - 0.03) / (height - 0.03)
            b.cone(ra, rb, (0, 0, zs[a]), (0, 0, zs[a + 1]), segments=16, material=mats[a])
        parts.append(Part("TrafficCone", b.build(), location=((k - (count - 1) / 2) * spacing, 0, 0)))
    return Asset("TrafficCone", parts, (count * spacing, 0.6))


register(AssetKind(
    name="Barrier", classes=("Barrier",), build=barriers, place=Mix(weight=1.5), order=58,
    materials=(Material("concrete_white", (0.65, 0.64, 0.6), 0.8, 0.0, Pattern(4.0, (0.45, 0.44, 0.42), 0.4)),),
    shared_streams=True,
))
register(AssetKind(
    name="TrafficCone", classes=("TrafficCone",), build=traffic_cones, place=Mix(weight=2), order=59,
    materials=(Material("plastic_orange", (0.9, 0.2, 0.01), 0.4), Material("reflective_white", (0.9, 0.9, 0.9), 0.25, reflectivity=1.0)),
    shared_streams=True,
))

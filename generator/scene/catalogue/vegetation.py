"""Trees and hedges beyond the fence (class ``Vegetation``): broadleaf trees 6-14 m tall
with a crown of two or three overlapping ellipsoids, conifers 8-16 m tall as stacked cones,
and clipped hedges 1-1.8 m high. The surroundings place them
(:mod:`generator.scene.catalogue.surroundings`); each stands on the ground at its origin,
its trunk or base sunk ``SINK_M`` below it so that it meets sloping ground."""

from __future__ import annotations

import numpy as np

from ...geometry.portable_math import sincos
from ..assets import Asset, Part
from ..kinds import AssetKind, register
from ..materials import Material, Pattern
from ..meshes import MeshBuilder
from ..surroundings import SURROUNDINGS

SINK_M = 0.5  # metres a trunk or hedge reaches below its origin
FOLIAGE = ("foliage", "foliage_light", "foliage_dark")


def ellipsoid(b: MeshBuilder, centre, radii, material: str, segments: int = 12, rings: int = 7) -> None:
    """A closed ellipsoid of ``radii`` (rx, ry, rz) at ``centre``: ``segments`` around,
    ``rings`` from pole to pole (quads, triangles at the poles)."""
    polar = np.linspace(0.0, np.pi, rings + 1)[1:-1]
    sp, cp = sincos(polar)
    sa, ca = sincos(2 * np.pi * np.arange(segments) / segments)
    ring_pts = [np.column_stack([radii[0] * s * ca, radii[1] * s * sa, np.full(segments, radii[2] * c)]) for s, c in zip(sp, cp)]
    v = np.concatenate(ring_pts + [[[0.0, 0.0, radii[2]]], [[0.0, 0.0, -radii[2]]]])
    j = np.arange(segments)
    j2 = (j + 1) % segments
    n = segments
    quads = np.concatenate([np.stack([k * n + j, k * n + j2, (k + 1) * n + j2, (k + 1) * n + j], 1) for k in range(len(sp) - 1)])
    top, bottom, last = len(v) - 2, len(v) - 1, (len(sp) - 1) * n
    tris = np.concatenate([np.stack([j2, j, np.full(n, top)], 1), np.stack([last + j, last + j2, np.full(n, bottom)], 1)])
    b.add(v, quads, tris, material=material, offset=centre)


def tree(rng: np.random.Generator) -> Asset:
    """A broadleaf tree (70%: trunk 6-14 m tall to the crown's top, crown of 2-3 ellipsoids
    3-5 m across) or a conifer (30%: 8-16 m, 3-4 stacked cones), of one of three greens."""
    b = MeshBuilder()
    green = FOLIAGE[int(rng.integers(len(FOLIAGE)))]
    height = rng.uniform(6.0, 14.0)
    if rng.random() < 0.7:
        crown = rng.uniform(1.6, 2.6) * height / 10.0 + 0.8  # crown radius
        trunk_top = height - 1.6 * crown
        b.cone(0.12 + 0.02 * height, 0.1, (0, 0, -SINK_M), (0, 0, trunk_top + 0.5 * crown), segments=8, material="bark")
        for k in range(int(rng.integers(2, 4))):
            s, c = sincos(rng.uniform(0, 2 * np.pi))
            off = rng.uniform(0.0, 0.35) * crown
            r = crown * rng.uniform(0.75, 1.0)
            ellipsoid(b, (c * off, s * off, height - r * rng.uniform(0.85, 1.0) - k * 0.15 * crown),
                      (r, r * rng.uniform(0.85, 1.0), r * rng.uniform(0.8, 1.0)), green)
        reach = crown * 1.35 + 0.4
    else:
        height += 2.0
        base = rng.uniform(0.22, 0.3) * height
        b.cylinder(0.18, (0, 0, -SINK_M), (0, 0, base + 0.5), segments=8, material="bark")
        tiers = int(rng.integers(3, 5))
        radius = rng.uniform(0.2, 0.28) * height
        for k in range(tiers):
            z0 = base + (height - base) * k / (tiers + 0.5)
            r = radius * (1.0 - 0.7 * k / tiers)
            b.cone(r, 0.0, (0, 0, z0), (0, 0, min(height, z0 + (height - base) * 0.5)), segments=12, material="foliage_dark")
        reach = radius + 0.2
    return Asset("Tree", [Part("Vegetation", b.build())], (2 * reach, 2 * reach), info={"height": float(height)})


def hedge(rng: np.random.Generator, length: float | None = None) -> Asset:
    """A clipped hedge ``length`` metres long (drawn 4-12 m if None), 0.8-1.2 m deep,
    1.0-1.8 m high, in one box with rounded shoulders."""
    length = float(rng.uniform(4.0, 12.0) if length is None else length)
    depth, high = rng.uniform(0.8, 1.2), rng.uniform(1.0, 1.8)
    b = MeshBuilder()
    b.box((length, depth, high - 0.15 + SINK_M), (0, 0, (high - 0.15 - SINK_M) / 2), material="hedge")
    b.box((length - 0.2, depth - 0.2, 0.15), (0, 0, high - 0.075), material="hedge")
    return Asset("Hedge", [Part("Vegetation", b.build())], (length + 0.1, depth + 0.1), info={"height": float(high)})


def foliage(name: str, colour, dark) -> Material:
    """Leaves: clumps of leaves (cells of about 30 cm) and gaps of shade between them; leaves
    reflect the near infrared strongly."""
    return Material(name, colour, 0.85, 0.0, Pattern(3.0, dark, 0.7, kind="voronoi"),
                    layers=(Pattern(0.7, tuple(c * 1.3 for c in colour), 0.4, detail=3.0),), reflectivity=0.5)


register(AssetKind(
    name="Tree", classes=("Vegetation",), build=tree, place=SURROUNDINGS, scenery=True, order=2001,
    materials=(Material("bark", (0.1, 0.07, 0.05), 0.9, 0.0, Pattern(8.0, (0.05, 0.04, 0.03), 0.6, stretch=(1.0, 1.0, 6.0))),
               foliage("foliage", (0.06, 0.14, 0.03), (0.02, 0.05, 0.01)),
               foliage("foliage_light", (0.12, 0.2, 0.04), (0.04, 0.08, 0.015)),
               foliage("foliage_dark", (0.03, 0.08, 0.03), (0.01, 0.03, 0.01))),
))
register(AssetKind(
    name="Hedge", classes=("Vegetation",), build=hedge, place=SURROUNDINGS, scenery=True, order=2002,
    materials=(foliage("hedge", (0.05, 0.11, 0.025), (0.015, 0.04, 0.01)),),
))

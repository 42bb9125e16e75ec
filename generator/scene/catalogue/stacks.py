"""Material stacks: pallets of bricks or blocks, pipes, timber and rebar bundles; used up,
moved and delivered over a timeline's stages (a pallet of a row at a time)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...geometry.portable_math import cos
from ..assets import Asset, Part
from ..kinds import AssetKind, register
from ..materials import STREAKS, Material, Pattern
from ..meshes import MeshBuilder, rotation_x
from ..planning import Mix
from ..timeline import MATERIAL_STOCK


def brick_pallets(rng: np.random.Generator) -> Asset:
    """A row of EUR pallets (1.2 x 0.8 x 0.144) loaded with bricks or concrete blocks."""
    count = int(rng.integers(2, 7))
    blocks = rng.random() < 0.4
    unit = (0.44, 0.215, 0.215) if blocks else (0.215, 0.1025, 0.065)
    material = "concrete_block" if blocks else "brick"
    parts = []
    for c in range(count):
        b = MeshBuilder()
        for x in (-0.5, 0.0, 0.5):  # bottom boards, blocks, top deck
            b.box((0.1, 0.8, 0.022), (x, 0, 0.011), material="wood")
            for y in (-0.345, 0.0, 0.345):
                b.box((0.1, 0.1, 0.078), (x, y, 0.022 + 0.039), material="wood")
        b.box((1.2, 0.8, 0.044), (0, 0, 0.1 + 0.022), material="wood")
        nx, ny = int(1.2 // (unit[0] + 0.005)), int(0.8 // (unit[1] + 0.005))
        layers = int(round(rng.uniform(0.6, 1.0) / unit[2]))
        for lz in range(layers):
            for ix in range(nx):
                for iy in range(ny):
                    x = (ix - (nx - 1) / 2) * (unit[0] + 0.005)
                    y = (iy - (ny - 1) / 2) * (unit[1] + 0.005)
                    b.box(unit, (x, y, 0.144 + unit[2] / 2 + lz * (unit[2] + 0.001)), material=material)
        parts.append(Part("BrickPallet", b.build(), location=(0, (c - (count - 1) / 2) * 0.95, 0)))
    return Asset("BrickPallet", parts, (1.25, count * 0.95))


def pipe_stack(rng: np.random.Generator) -> Asset:
    """Concrete pipes (0.3-1.5 m, 2.5 m long) or steel pipes (6-12 m) stacked in a pyramid."""
    concrete = rng.random() < 0.5
    r = rng.uniform(0.3, 0.75) if concrete else rng.uniform(0.1, 0.3)
    wall = 0.12 * r if concrete else 0.02
    length = 2.5 if concrete else rng.uniform(6.0, 12.0)
    base = int(rng.integers(2, 5))
    b = MeshBuilder()
    if not concrete:
        for x in (-length / 3, length / 3):  # timber bearers under steel pipes
            b.box((0.15, base * 2 * r + 0.3, 0.1), (x, 0, 0.05), material="wood")
    z0 = 0.0 if concrete else 0.1
    segments = 28 if concrete else 16
    # one pipe along x at the origin, turned half a segment about its axis so that a flat
    # facet (not an edge) lies at the bottom: it rests on the ground or the bearers
    pipe = MeshBuilder().tube(r, r - wall, (-length / 2, 0, 0), (length / 2, 0, 0), segments=segments).build()
    turn = rotation_x(np.pi / segments)
    apothem = r * cos(np.pi / segments)
    for row in range(base):
        n = base - row
        for k in range(n):
            y = (k - (n - 1) / 2) * 2 * r * 1.001
            z = z0 + apothem + row * r * np.sqrt(3) * 1.001
            b.add(pipe.vertices, pipe.quads, pipe.tris, "concrete" if concrete else "steel_rust", rotation=turn, offset=(0, y, z))
    return Asset("PipeStack", [Part("PipeStack", b.build())], (length, base * 2 * r + 0.3))


def timber_stack(rng: np.random.Generator) -> Asset:
    """Sawn beams (0.1-0.2 m section, 4-6 m long) in layers on three bearers."""
    length, sec = rng.uniform(4.0, 6.0), rng.uniform(0.1, 0.2)
    per_layer, layers = int(rng.integers(4, 10)), int(rng.integers(2, 7))
    width = per_layer * (sec + 0.01)
    b = MeshBuilder()
    for x in (-length / 2 + 0.4, 0, length / 2 - 0.4):
        b.box((0.15, width + 0.2, 0.12), (x, 0, 0.06), material="wood_dark")
    for lz in range(layers):
        for k in range(per_layer):
            y = (k - (per_layer - 1) / 2) * (sec + 0.01)
            b.box((length, sec, sec), (0, y, 0.12 + sec / 2 + lz * (sec + 0.002)), material="wood")
    return Asset("TimberStack", [Part("TimberStack", b.build())], (length, width + 0.2))


def rebar_bundles(rng: np.random.Generator) -> Asset:
    """One to three bundles (0.3-0.5 m across) of bars (12-40 mm, 6-12 m long) lying on
    timber bearers."""
    length = rng.uniform(6.0, 12.0)
    count = int(rng.integers(1, 4))
    pitch = 0.6  # bundle centre to centre (0.5 m at most across, plus a gap)
    b = MeshBuilder()
    for x in (-length / 3, 0, length / 3):
        b.box((0.12, count * pitch + 0.2, 0.1), (x, 0, 0.05), material="wood_dark")
    for c in range(count):
        r = rng.uniform(0.006, 0.02)
        across = rng.uniform(0.3, 0.5)
        cols = int(np.ceil(across / (2.05 * r)))  # bars side by side: the bundle is ``across`` wide
        layers = max(1, cols // 2)  # and half as tall, lying flat
        for i in range(layers):
            for j in range(cols):
                y = (c - (count - 1) / 2) * pitch + (j - (cols - 1) / 2) * 2.05 * r
                z = 0.1 + r + i * 2.05 * r
                b.cylinder(r, (-length / 2, y, z), (length / 2, y, z), segments=6, material="rebar")
    return Asset("RebarBundle", [Part("Rebar", b.build())], (length, count * pitch + 0.2))


register(AssetKind(
    name="BrickPallet", classes=("BrickPallet",), build=brick_pallets, place=Mix(weight=2.5), order=54,
    materials=(Material("concrete_block", (0.4, 0.4, 0.38), 0.9, 0.0, Pattern(8.0, (0.3, 0.3, 0.29), 0.4)),),
    stage=replace(MATERIAL_STOCK, part_used=0.2), shared_streams=True,
))
register(AssetKind(
    name="PipeStack", classes=("PipeStack",), build=pipe_stack, place=Mix(weight=1.5), order=55,
    materials=(Material("steel_rust", (0.3, 0.14, 0.06), 0.75, 0.4, Pattern(6.0, (0.15, 0.12, 0.1), 0.6), layers=(STREAKS,)),),
    stage=MATERIAL_STOCK, shared_streams=True,
))
register(AssetKind(
    name="TimberStack", classes=("TimberStack",), build=timber_stack, place=Mix(weight=1.5), order=56,
    stage=MATERIAL_STOCK, shared_streams=True,
))
register(AssetKind(
    name="RebarBundle", classes=("Rebar",), build=rebar_bundles, place=Mix(weight=1.5), order=57,
    stage=MATERIAL_STOCK, shared_streams=True,
))

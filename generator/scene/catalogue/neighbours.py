"""Finished buildings beyond the fence (kind ``Neighbour``, class ``Neighbour``), in three
styles that the site's context picks (:mod:`generator.scene.contexts`):

- ``block``: a city block of 3-7 storeys (3 m each, the ground floor 3.6 m with shop
  windows), rendered or brick walls, windows 1.2-1.5 m wide on a 2.6-3.4 m grid, a flat
  roof with a coping;
- ``house``: a two-storey house (2.7 m storeys) with a pitched roof of tiles or slate
  (35-45 degrees), two windows a storey front and back, a door and a chimney;
- ``shed``: an industrial shed 6-9 m to the eaves, clad in profiled metal of one of three
  colours, a shallow roof, roller doors and a strip of high windows.

Each is built in its own frame: frontage along x, its front facing +y (the site), standing
on z = 0 with a plinth reaching ``PLINTH_M`` below, so that it meets sloping ground. The
surroundings place them (:mod:`generator.scene.catalogue.surroundings`)."""

from __future__ import annotations

import numpy as np

from ..assets import Asset, Part
from ..kinds import AssetKind, register
from ..materials import Material, Pattern
from ..meshes import MeshBuilder, rotation_z
from ..surroundings import SURROUNDINGS

PLINTH_M = 1.0  # metres a neighbour's walls reach below its origin
WALLS = ("render_white", "render_cream", "render_ochre", "render_grey", "brick")
SHEDS = ("shed_green", "shed_blue", "shed_white")


def windows(b: MeshBuilder, frontage: float, depth: float, rows, spacing: float, size, facades=(1, -1, 0)) -> None:
    """Windows (glass 3 cm proud of the wall, a sill under each) on a grid of columns every
    ``spacing`` metres along each facade, at the sill heights ``rows``; ``size`` (width,
    height); ``facades``: 1 the front (+y), -1 the back, 0 both ends (±x)."""
    w, h = size
    for facade in facades:
        along, line = (frontage, depth / 2) if facade else (depth, frontage / 2)
        count = max(1, int((along - 1.0) // spacing))
        us = (np.arange(count) - (count - 1) / 2) * spacing
        for side in ((facade,) if facade else (1, -1)):
            for z in rows:
                for u in us:
                    if facade:
                        b.box((w, 0.06, h), (u, side * (line + 0.03), z + h / 2), material="glass")
                        b.box((w + 0.1, 0.12, 0.06), (u, side * (line + 0.06), z - 0.03), material="kerb")
                    else:
                        b.box((0.06, w, h), (side * (line + 0.03), u, z + h / 2), material="glass")
                        b.box((0.12, w + 0.1, 0.06), (side * (line + 0.06), u, z - 0.03), material="kerb")


def gable_roof(b: MeshBuilder, frontage: float, depth: float, eaves: float, pitch_tan: float, material: str) -> float:
    """A duo-pitch roof over the walls, ridge along x, 0.3 m overhangs: the ridge's height."""
    half = depth / 2 + 0.3
    rise = half * pitch_tan
    profile = [(-half, 0.0), (half, 0.0), (0.0, rise)]  # in (y, z), extruded along x
    b.prism(profile, frontage + 0.6, rotation=rotation_z(np.pi / 2), offset=(0.0, 0.0, eaves - 0.3 * pitch_tan),
            material=material)
    return eaves - 0.3 * pitch_tan + rise


def block(rng: np.random.Generator, frontage: float, depth: float, storeys: int) -> tuple[MeshBuilder, float]:
    """A city block (module docstring): its mesh and its height."""
    b = MeshBuilder()
    wall = WALLS[int(rng.integers(len(WALLS)))]
    top = 3.6 + 3.0 * (storeys - 1)
    b.box((frontage, depth, top + PLINTH_M), (0, 0, (top - PLINTH_M) / 2), material=wall)
    b.box((frontage + 0.3, depth + 0.3, 0.25), (0, 0, top + 0.125), material="kerb")  # coping
    b.box((frontage - 0.4, depth - 0.4, 0.05), (0, 0, top + 0.27), material="roof_felt")
    b.box((frontage * 0.8, 0.08, 2.4), (0, depth / 2 + 0.04, 1.5), material="glass")  # shop fronts
    b.box((frontage * 0.8 + 0.2, 0.12, 0.5), (0, depth / 2 + 0.06, 3.0), material="roof_felt")  # fascia
    spacing, size = rng.uniform(2.6, 3.4), (rng.uniform(1.2, 1.5), rng.uniform(1.4, 1.6))
    windows(b, frontage, depth, [3.6 + 3.0 * k + 0.9 for k in range(storeys - 1)], spacing, size)
    return b, top + 0.25


def house(rng: np.random.Generator, frontage: float, depth: float, storeys: int) -> tuple[MeshBuilder, float]:
    """A house with a pitched roof (module docstring): its mesh and its height."""
    b = MeshBuilder()
    wall = WALLS[int(rng.integers(len(WALLS)))] if rng.random() < 0.6 else "brick"
    eaves = 2.7 * storeys
    b.box((frontage, depth, eaves + PLINTH_M), (0, 0, (eaves - PLINTH_M) / 2), material=wall)
    roof = "roof_tiles" if rng.random() < 0.6 else "roof_slate"
    ridge = gable_roof(b, frontage, depth, eaves, float(rng.uniform(0.7, 1.0)), roof)
    b.box((0.6, 0.6, 1.5), (frontage * rng.uniform(-0.3, 0.3), 0.0, ridge - 0.3), material="brick")  # chimney
    b.box((1.0, 0.08, 2.1), (-frontage / 4, depth / 2 + 0.04, 1.05), material="door")
    windows(b, frontage, depth, [0.9 + 2.7 * k for k in range(storeys)], frontage / 2, (1.2, 1.3), facades=(1, -1))
    return b, ridge + 1.2


def shed(rng: np.random.Generator, frontage: float, depth: float, storeys: int) -> tuple[MeshBuilder, float]:
    """An industrial shed (module docstring): its mesh and its height."""
    b = MeshBuilder()
    skin = SHEDS[int(rng.integers(len(SHEDS)))]
    eaves = rng.uniform(6.0, 9.0)
    b.box((frontage, depth, eaves + PLINTH_M), (0, 0, (eaves - PLINTH_M) / 2), material=skin)
    ridge = gable_roof(b, frontage, depth, eaves, float(rng.uniform(0.09, 0.18)), "shed_white" if skin != "shed_white" else "roof_slate")
    for k in range(int(rng.integers(1, 3))):  # roller doors
        x = (k - 0.5) * frontage / 3 if frontage > 20 else 0.0
        b.box((4.0, 0.08, 4.5), (x, depth / 2 + 0.04, 2.25), material="roller_door")
    b.box((frontage * 0.7, 0.06, 0.8), (0, depth / 2 + 0.03, eaves - 1.4), material="glass")  # high windows
    return b, ridge


STYLES = {"block": block, "house": house, "shed": shed}


def neighbour(rng: np.random.Generator, style: str = "block", frontage: float = 16.0, depth: float = 12.0,
              storeys: int = 4) -> Asset:
    """A finished building of ``style`` (module docstring), ``frontage`` x ``depth`` metres,
    ``storeys`` high (a shed has one)."""
    b, height = STYLES[style](rng, frontage, depth, storeys)
    return Asset("Neighbour", [Part("Neighbour", b.build())], (frontage + 0.8, depth + 0.8),
                 info={"style": style, "height": float(height)})


def wall(name: str, colour, stretch=(1.0, 1.0, 1.0)) -> Material:
    """A facade: stains of a metre or two and a fine grain (render, cladding)."""
    return Material(name, colour, 0.8, 0.0, Pattern(0.8, tuple(c * 0.75 for c in colour), 0.45, detail=3.0, stretch=stretch),
                    layers=(Pattern(20.0, tuple(min(1.0, c * 1.15) for c in colour), 0.3, detail=2.0),))


register(AssetKind(
    name="Neighbour", classes=("Neighbour",), build=neighbour, place=SURROUNDINGS, scenery=True, order=2000,
    materials=(wall("render_white", (0.7, 0.68, 0.62)), wall("render_cream", (0.62, 0.5, 0.32)),
               wall("render_ochre", (0.55, 0.3, 0.12)), wall("render_grey", (0.36, 0.36, 0.35)),
               wall("shed_green", (0.1, 0.25, 0.15), (1.0, 1.0, 30.0)), wall("shed_blue", (0.08, 0.18, 0.4), (1.0, 1.0, 30.0)),
               wall("shed_white", (0.72, 0.73, 0.72), (1.0, 1.0, 30.0)),
               Material("roof_tiles", (0.32, 0.08, 0.04), 0.7, 0.0, Pattern(4.0, (0.2, 0.05, 0.03), 0.5),
                        layers=(Pattern(3.0, (0.15, 0.04, 0.02), 0.5, kind="courses", aspect=1.5, joint=0.15),)),
               Material("roof_slate", (0.08, 0.08, 0.09), 0.6, 0.0, Pattern(5.0, (0.14, 0.14, 0.16), 0.4)),
               Material("roof_felt", (0.07, 0.07, 0.07), 0.9, 0.0, Pattern(3.0, (0.14, 0.13, 0.12), 0.5)),
               Material("roller_door", (0.4, 0.41, 0.42), 0.5, 0.6, Pattern(12.0, (0.28, 0.29, 0.3), 0.4,
                                                                              stretch=(30.0, 1.0, 1.0))),
               Material("door", (0.2, 0.1, 0.05), 0.5, 0.0, Pattern(10.0, (0.12, 0.06, 0.03), 0.4))),
))

"""Steel frames (bpy-free, type ``steel-frame``): H-section columns and I-section beams on a
grid of bays, cross-bracing in one bay of each facade, composite floors (concrete on a metal
deck) below the top level and bare deck sheets being laid on it, a mesh on part of the newest
floor, profiled metal cladding with windows two levels behind, edge protection on the open
levels. A level is a storey of steelwork."""

from __future__ import annotations

import numpy as np

from ..assets import Asset, Part
from ..building_parts import edge_protection, facades, infill_bay, modules
from ..materials import STREAKS, Material, Pattern
from ..meshes import MeshBuilder
from . import BuildingType, Growth, register_type

FLANGE = 0.3  # column flange width and section depth, metres
BEAM = 0.4  # beam depth, metres
DECK = 0.15  # composite floor thickness, metres
EDGE = 0.2  # floor edge beyond the column lines, metres
BRACE = 0.07  # bracing tube radius, metres
CLADDING = 0.1  # cladding panel thickness, metres


def h_section(b: MeshBuilder, centre, length: float, axis: str, depth: float, width: float, material: str) -> None:
    """An H (column, ``axis`` 'z') or I (beam along 'x' or 'y') section: two flanges and a web."""
    x, y, z = centre
    tf, tw = 0.02, 0.012
    if axis == "z":
        for s in (-1, 1):
            b.box((width, tf, length), (x, y + s * (depth - tf) / 2, z), material=material)
        b.box((tw, depth - 2 * tf, length), (x, y, z), material=material)
        return
    along = (length, width, tf) if axis == "x" else (width, length, tf)
    for s in (-1, 1):
        b.box(along, (x, y, z + s * (depth - tf) / 2), material=material)
    b.box((length, tw, depth - 2 * tf) if axis == "x" else (tw, length, depth - 2 * tf), (x, y, z), material=material)


def steel_frame(rng: np.random.Generator, phase: float, floors: tuple[int, int], max_length: float = 60.0,
                growth: Growth | None = None) -> Asset:
    """A steel frame under construction, centred on the origin (see the module's docstring):
    bays of 6-9 m, storeys of 3.6-4.2 m; ``phase``, ``floors``, ``max_length`` and ``growth``
    as for every building type (generator/scene/building_types/__init__.py)."""
    sx, sy = rng.uniform(6.0, 9.0), rng.uniform(6.0, 9.0)
    nx = int(rng.integers(2, max(3, min(5, int((max_length - 3.0) // sx)) + 1)))
    ny = int(rng.integers(2, max(3, min(3, int((max_length - 5.0) // sy)) + 1)))
    h = rng.uniform(3.6, 4.2)
    planned = int(rng.integers(floors[0], floors[1] + 1))
    built = own_built = max(1, int(round(phase * planned)))
    if growth is not None:
        growth.check(own_built, planned)
        built = growth.built
    gx, gy = sx * (np.arange(nx + 1) - nx / 2), sy * (np.arange(ny + 1) - ny / 2)
    x0, x1, y0, y1 = gx[0] - EDGE, gx[-1] + EDGE, gy[0] - EDGE, gy[-1] + EDGE
    braced = rng.integers(nx, size=2), rng.integers(ny, size=2)  # the braced bay of each facade
    laid = rng.random((nx, ny)) < rng.uniform(0.3, 0.8)  # top-level bays whose deck sheets are down
    mesh_bays = int(rng.integers(1, nx + 1))  # bays of the newest floor with their mesh laid
    steel, works, rebar = MeshBuilder(), MeshBuilder(), MeshBuilder()
    steel.box((x1 - x0, y1 - y0, 0.2), (0.0, 0.0, 0.1), material="concrete")  # ground-bearing slab
    top = built * h + (1.2 if built < planned else 0.6)  # the columns run on to the next splice
    add_steelwork(steel, gx, gy, h, built, top, laid)
    add_bracing(steel, gx, gy, h, built, braced)
    if built > 1:  # mesh on part of the newest poured floor
        add_mesh(rebar, gx, gy, (built - 1) * h + DECK + 0.04, mesh_bays)
    enclosed, cladding = clad(rng, (x0, x1, y0, y1), h, own_built, built, growth)
    steel.merge(cladding)
    edge_protection(works, x0, x1, y0, y1, [(k * h - BEAM, k * h + (DECK if k < built else 0.05))
                                           for k in range(max(1, enclosed), built + 1)])
    parts = [Part("Building", steel.build()), Part("Scaffolding", works.build())]
    if built > 1:
        parts.insert(1, Part("Rebar", rebar.build()))
    size = (x1 - x0 + 2 * (CLADDING + 0.3), y1 - y0 + 2 * (CLADDING + 0.3))
    return Asset("Building", parts, size, info={"floors_built": built, "floors_planned": planned,
                                                 "floors_enclosed": enclosed, "height": top, "floor_height": h})


def add_steelwork(steel: MeshBuilder, gx: np.ndarray, gy: np.ndarray, h: float, built: int, top: float,
                  laid: np.ndarray) -> None:
    """Columns up to ``top``, beams on every grid line of every level, composite floors
    (the outline of the grid lines plus EDGE) below the newest level and the ``laid`` bays'
    deck sheets on it."""
    x0, x1, y0, y1 = gx[0] - EDGE, gx[-1] + EDGE, gy[0] - EDGE, gy[-1] + EDGE
    for x in gx:
        for y in gy:
            h_section(steel, (x, y, 0.2 + (top - 0.2) / 2), top - 0.2, "z", FLANGE, FLANGE, "steel_primer")
    for k in range(1, built + 1):
        zc = k * h - BEAM / 2
        for y in gy:
            for a, b in zip(gx[:-1], gx[1:]):
                h_section(steel, ((a + b) / 2, y, zc), b - a - FLANGE, "x", BEAM, 0.18, "steel_primer")
        for x in gx:
            for a, b in zip(gy[:-1], gy[1:]):
                h_section(steel, (x, (a + b) / 2, zc), b - a - FLANGE, "y", BEAM, 0.18, "steel_primer")
        if k < built:  # poured
            steel.box((x1 - x0, y1 - y0, DECK), (0.0, 0.0, k * h + DECK / 2), material="concrete")
            continue
        for i in range(len(gx) - 1):  # deck sheets on the newest steelwork
            for j in range(len(gy) - 1):
                if laid[i, j]:
                    steel.box((gx[i + 1] - gx[i], gy[j + 1] - gy[j], 0.05),
                              ((gx[i] + gx[i + 1]) / 2, (gy[j] + gy[j + 1]) / 2, k * h + 0.025), material="metal_deck")


def add_bracing(steel: MeshBuilder, gx: np.ndarray, gy: np.ndarray, h: float, built: int, braced) -> None:
    """X-bracing in one bay of each facade (``braced``: the bays along x, then along y),
    every storey."""
    for k in range(built):
        zb, ze = k * h + (0.2 if k == 0 else 0.0), (k + 1) * h - BEAM
        for y, i in ((gy[0], braced[0][0]), (gy[-1], braced[0][1])):
            steel.cylinder(BRACE, (gx[i], y, zb), (gx[i + 1], y, ze), segments=8, material="steel_primer")
            steel.cylinder(BRACE, (gx[i + 1], y, zb), (gx[i], y, ze), segments=8, material="steel_primer")
        for x, j in ((gx[0], braced[1][0]), (gx[-1], braced[1][1])):
            steel.cylinder(BRACE, (x, gy[j], zb), (x, gy[j + 1], ze), segments=8, material="steel_primer")
            steel.cylinder(BRACE, (x, gy[j + 1], zb), (x, gy[j], ze), segments=8, material="steel_primer")


def add_mesh(rebar: MeshBuilder, gx: np.ndarray, gy: np.ndarray, z: float, bays: int) -> None:
    """A mesh at height ``z`` over the first ``bays`` bays along x: bars every 0.2 m both ways."""
    mx1 = gx[bays] - 0.1
    for y in np.arange(gy[0] + 0.1, gy[-1] - 0.05, 0.2):
        rebar.cylinder(0.006, (gx[0] + 0.1, y, z), (mx1, y, z), segments=6, material="rebar")
    for x in np.arange(gx[0] + 0.1, mx1, 0.2):
        rebar.cylinder(0.006, (x, gy[0] + 0.1, z + 0.012), (x, gy[-1] - 0.1, z + 0.012), segments=6, material="rebar")


def clad(rng: np.random.Generator, outline, h: float, own_built: int, built: int, growth: Growth | None):
    """Profiled metal cladding panels about 3 m wide with a window each on the enclosed
    levels (two behind the steelwork): (levels enclosed, mesh)."""
    x0, x1, y0, y1 = outline
    own_enclosed = max(0, own_built - 2)
    enclosed = own_enclosed if growth is None else growth.enclosed
    walls = MeshBuilder()
    for k in range(max(enclosed, own_enclosed)):
        lrng = rng if k < own_enclosed else growth.floor_rng(k)
        zb, ze = k * h + (0.2 if k == 0 else DECK), (k + 1) * h
        for along_x, line, a0, a1 in facades(x0, x1, y0, y1, 0.02, CLADDING):
            for u0, u1 in modules(a0, a1, 3.0):
                window = lrng.uniform(1.0, 2.0)
                if k < enclosed:
                    infill_bay(walls, along_x, line, u0, u1, zb, ze, window, True, thick=CLADDING, material="cladding")
    return enclosed, walls


register_type(BuildingType(
    name="steel-frame", build=steel_frame, weight=0.3, module=__name__,
    structure="steel frame (H-section columns, I-section beams, cross-bracing in one bay of each facade) with "
              "composite floors on a metal deck, profiled metal cladding with windows, edge protection on the "
              "open levels. A stage adds 1-2 storeys of steelwork; decks are poured a storey behind, the "
              "cladding two behind",
    materials=(Material("steel_primer", (0.3, 0.09, 0.05), 0.55, 0.2, Pattern(6.0, (0.22, 0.07, 0.04), 0.4),
                        layers=(STREAKS,)),
               Material("metal_deck", (0.5, 0.51, 0.52), 0.4, 0.9, Pattern(20.0, (0.36, 0.37, 0.38), 0.5,
                                                                          stretch=(1.0, 12.0, 1.0)), reflectivity=0.45),
               Material("cladding", (0.45, 0.5, 0.55), 0.45, 0.5, Pattern(5.0, (0.32, 0.36, 0.4), 0.55,
                                                                         stretch=(1.0, 1.0, 30.0)),
                        layers=(STREAKS,))),
))

"""Concrete frames closed in by a hung facade (bpy-free): storey-high precast concrete panels
with a window each (type ``precast``), or an aluminium curtain wall of glass and spandrel
panels (type ``curtain-wall``). The frame is :mod:`.concrete_frame`'s; the facade hangs 2 cm
outside the slab edges, floor by floor two floors behind the frame, and the open slab edges
above it carry edge protection (craned-in facades need no scaffolding)."""

from __future__ import annotations

import numpy as np

from ..building_parts import edge_protection, facades, infill_bay, modules
from ..materials import Material, Pattern
from ..meshes import MeshBuilder
from . import BuildingType, Growth, register_type
from .concrete_frame import Frame, frame_building

GAP = 0.02  # metres between the slab edge and the facade
PANEL = 0.15  # precast panel thickness, metres
JOINT = 0.02  # open joint between precast panels, metres
WALL = 0.12  # curtain wall depth (mullions), metres
MULLION = 0.05  # mullion and transom width, metres
SPANDREL = 1.0  # height of the opaque band at the foot of each curtain-wall floor, metres
MISSING = 0.05  # chance that a facade unit of an enclosed floor is not yet hung


def levels_drawn(rng: np.random.Generator, f: Frame, growth: Growth | None):
    """(levels enclosed, [(level, its random stream, enclosed?)]): the building's own
    levels draw from ``rng`` whether enclosed or not (so every later draw is as at stage 0),
    later ones from the growth's per-level streams; the envelope is two levels behind."""
    own_enclosed = max(0, f.own_built - 2)
    enclosed = own_enclosed if growth is None else growth.enclosed
    return enclosed, [(k, rng if k < own_enclosed else growth.floor_rng(k), k < enclosed)
                      for k in range(max(enclosed, own_enclosed))]


def precast_facade(rng: np.random.Generator, f: Frame, growth: Growth | None) -> tuple[int, MeshBuilder]:
    """Storey-high precast panels about 3-4.5 m wide (one width per building), 2 cm open
    joints, a window opening in each (glazed below the top enclosed floor)."""
    enclosed, levels = levels_drawn(rng, f, growth)
    width = rng.uniform(3.0, 4.5)
    walls = MeshBuilder()
    for k, lrng, built in levels:
        zb, ze = k * f.h + JOINT / 2, (k + 1) * f.h - JOINT / 2
        for along_x, line, a0, a1 in facades(f.x0, f.x1, f.y0, f.y1, GAP, PANEL):
            for u0, u1 in modules(a0, a1, width):
                missing, window = lrng.random() < MISSING, lrng.uniform(1.2, 2.4)
                if built and not missing:
                    infill_bay(walls, along_x, line, u0 + JOINT / 2, u1 - JOINT / 2, zb, ze, window, k < enclosed - 1,
                               thick=PANEL, material="precast")
    return enclosed, walls


def curtain_unit(b: MeshBuilder, along_x: bool, line: float, u0: float, u1: float, zb: float, ze: float) -> None:
    """One curtain-wall unit: its left mullion, transoms at its foot and atop the spandrel,
    a spandrel panel and a vision pane (2 cm glass on the wall's centre line)."""
    def box(a0, a1, z0, z1, depth, material):
        centre = ((a0 + a1) / 2, line, (z0 + z1) / 2) if along_x else (line, (a0 + a1) / 2, (z0 + z1) / 2)
        size = (a1 - a0, depth, z1 - z0) if along_x else (depth, a1 - a0, z1 - z0)
        b.box(size, centre, material=material)

    box(u0, u0 + MULLION, zb, ze, WALL, "aluminium")
    inner = u0 + MULLION
    box(inner, u1, zb, zb + MULLION, WALL * 0.6, "aluminium")
    box(inner, u1, zb + SPANDREL - MULLION / 2, zb + SPANDREL + MULLION / 2, WALL * 0.6, "aluminium")
    box(inner, u1, zb + MULLION, zb + SPANDREL - MULLION / 2, 0.02, "spandrel")
    box(inner, u1, zb + SPANDREL + MULLION / 2, ze, 0.02, "glass")


def curtain_facade(rng: np.random.Generator, f: Frame, growth: Growth | None) -> tuple[int, MeshBuilder]:
    """A stick curtain wall: units 1.2-1.8 m wide (one width per building), a closing
    mullion at the end of each run."""
    enclosed, levels = levels_drawn(rng, f, growth)
    width = rng.uniform(1.2, 1.8)
    walls = MeshBuilder()
    for k, lrng, built in levels:
        zb, ze = k * f.h, (k + 1) * f.h
        for along_x, line, a0, a1 in facades(f.x0, f.x1, f.y0, f.y1, GAP, WALL):
            units = modules(a0, a1 - MULLION, width)
            hung = [not lrng.random() < MISSING for _ in units]
            if not built:
                continue
            for (u0, u1), up in zip(units, hung):
                if up:
                    curtain_unit(walls, along_x, line, u0, u1, zb, ze)
            end = ((a1 - MULLION / 2), line, (zb + ze) / 2) if along_x else (line, a1 - MULLION / 2, (zb + ze) / 2)
            walls.box((MULLION, WALL, ze - zb) if along_x else (WALL, MULLION, ze - zb), end, material="aluminium")
    return enclosed, walls


def open_edges(rng: np.random.Generator, f: Frame, enclosed: int) -> tuple[str, MeshBuilder]:
    """Edge protection on every slab above the facade (the top slab's included)."""
    works = MeshBuilder()
    edge_protection(works, f.x0, f.x1, f.y0, f.y1, [(k * f.h, k * f.h + f.t) for k in range(max(1, enclosed), f.built + 1)])
    return "Scaffolding", works


def precast(rng, phase, floors, max_length=60.0, growth=None):
    """A concrete frame closed in by precast panels (:func:`precast_facade`)."""
    return frame_building(rng, phase, floors, max_length, growth, precast_facade, open_edges)


def curtain_wall(rng, phase, floors, max_length=60.0, growth=None):
    """A concrete frame closed in by a curtain wall (:func:`curtain_facade`)."""
    return frame_building(rng, phase, floors, max_length, growth, curtain_facade, open_edges)


register_type(BuildingType(
    name="precast", build=precast, weight=0.2, module=__name__,
    structure="reinforced-concrete frame closed in by storey-high precast concrete panels (3-4.5 m, a window "
              "each, 2 cm open joints); edge protection on the open slabs. A stage adds 1-2 floors of frame; "
              "the panels follow two floors behind",
    materials=(Material("precast", (0.56, 0.54, 0.5), 0.8, 0.0, Pattern(6.0, (0.46, 0.45, 0.42), 0.4),
                        layers=(Pattern(0.8, (0.44, 0.43, 0.4), 0.5, detail=4.0),
                                Pattern(30.0, (0.66, 0.64, 0.6), 0.35, kind="voronoi"))),),
))

register_type(BuildingType(
    name="curtain-wall", build=curtain_wall, weight=0.2, module=__name__,
    structure="reinforced-concrete frame closed in by an aluminium stick curtain wall (units 1.2-1.8 m: a "
              "spandrel panel and a vision pane); edge protection on the open slabs. A stage adds 1-2 floors of "
              "frame; the curtain wall follows two floors behind",
    materials=(Material("aluminium", (0.62, 0.63, 0.65), 0.35, 1.0, Pattern(8.0, (0.5, 0.51, 0.53), 0.3),
                        reflectivity=0.5),
               Material("spandrel", (0.05, 0.06, 0.07), 0.15, 0.0, Pattern(2.0, (0.08, 0.09, 0.1), 0.3))),
))

"""Reinforced-concrete frames (bpy-free): slabs and columns on a grid of bays, a core
running ahead of the slabs, shoring under the newest slab, starter bars, a rebar mat and
formwork on the top slab. Its envelope (how the floors are closed in) and its temporary
works (scaffolding or edge protection) are the type's: brick infill with tube scaffolding
here (type ``concrete-brick``, the first release's building); precast panels and a curtain
wall in :mod:`.clad_frame`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..assets import Asset, Part
from ..building_parts import free_spans, infill_bay, scaffold_run
from ..meshes import MeshBuilder
from . import BuildingType, Growth, register_type

@dataclass(frozen=True)
class Frame:
    """The drawn design of a building: bays ``sx`` x ``sy`` (``nx`` x ``ny`` of them),
    columns ``col`` wide, floor-to-floor ``h``, slabs ``t`` thick, ``planned`` floors of
    which ``own_built`` at stage 0 and ``built`` now; grid lines ``gx``, ``gy``; the slab's
    outline (``x0``, ``x1``, ``y0``, ``y1``), stair opening ``hole`` and core ``core``
    (x0, x1, y0, y1 each) and their bays (``hole_i``, ``core_i``)."""

    sx: float
    sy: float
    nx: int
    ny: int
    col: float
    h: float
    t: float
    planned: int
    own_built: int
    built: int
    gx: np.ndarray
    gy: np.ndarray
    x0: float
    x1: float
    y0: float
    y1: float
    hole: tuple[float, float, float, float]
    core: tuple[float, float, float, float]
    hole_i: int
    core_i: int


def draw_frame(rng: np.random.Generator, phase: float, floors: tuple[int, int], max_length: float,
               growth: Growth | None) -> Frame:
    """The frame's dimensions, floors and openings (the building's first draws)."""
    sx, sy = rng.uniform(5.5, 7.5), rng.uniform(5.5, 7.5)
    fit_x = max(2, int((max_length - 4.0) // sx))
    fit_y = max(2, int((max_length - 6.0) // sy))
    nx, ny = int(rng.integers(2, max(3, min(5, fit_x) + 1))), int(rng.integers(2, max(3, min(3, fit_y) + 1)))
    col = rng.uniform(0.35, 0.55)
    h, t = rng.uniform(3.0, 3.5), rng.uniform(0.2, 0.3)
    planned = int(rng.integers(floors[0], floors[1] + 1))
    built = own_built = max(1, int(round(phase * planned)))
    if growth is not None:
        growth.check(own_built, planned)
        built = growth.built
    lx, ly = nx * sx, ny * sy
    gx = -lx / 2 + sx * np.arange(nx + 1)
    gy = -ly / 2 + sy * np.arange(ny + 1)
    hole_i, core_i = rng.choice(nx, size=2, replace=False)
    hole_j, core_j = int(rng.integers(ny)), int(rng.integers(ny))
    hole = (gx[hole_i] + 0.6, gx[hole_i + 1] - 0.6, gy[hole_j] + 0.6, gy[hole_j] + min(3.0, sy - 1.2))
    core = (gx[core_i] + col, gx[core_i] + min(sx - col, 3.2), gy[core_j] + col, gy[core_j] + min(sy - col, 4.5))
    return Frame(sx, sy, nx, ny, col, h, t, planned, own_built, built, gx, gy, -lx / 2 - 0.3, lx / 2 + 0.3,
                 -ly / 2 - 0.3, ly / 2 + 0.3, hole, core, hole_i, core_i)


def add_slabs_and_columns(concrete: MeshBuilder, f: Frame) -> None:
    """Every built floor's slab (around the stair opening) and the columns between them."""
    hx0, hx1, hy0, hy1 = f.hole
    for k in range(f.built + 1):
        z = k * f.h + f.t / 2
        for bx0, bx1, by0, by1 in ((f.x0, hx0, f.y0, f.y1), (hx1, f.x1, f.y0, f.y1), (hx0, hx1, f.y0, hy0), (hx0, hx1, hy1, f.y1)):
            concrete.box((bx1 - bx0, by1 - by0, f.t), ((bx0 + bx1) / 2, (by0 + by1) / 2, z), material="concrete")
    for k in range(f.built):
        zb, ze = k * f.h + f.t, (k + 1) * f.h
        for x in f.gx:
            for y in f.gy:
                concrete.box((f.col, f.col, ze - zb), (x, y, (zb + ze) / 2), material="concrete")


def add_core(concrete: MeshBuilder, f: Frame) -> None:
    """The core: 3 full walls and a front wall with a door on every floor, 2 m ahead of the slabs."""
    cx0, cx1, cy0, cy1 = f.core
    wt = 0.25
    top = f.built * f.h + f.t + 2.0
    concrete.box((cx1 - cx0, wt, top), ((cx0 + cx1) / 2, cy1 - wt / 2, top / 2), material="concrete_dark")
    concrete.box((wt, cy1 - cy0 - wt, top), (cx0 + wt / 2, (cy0 + cy1 - wt) / 2, top / 2), material="concrete_dark")
    concrete.box((wt, cy1 - cy0 - wt, top), (cx1 - wt / 2, (cy0 + cy1 - wt) / 2, top / 2), material="concrete_dark")
    door = min(1.0, cx1 - cx0 - 2 * wt - 0.4)
    dmid = (cx0 + cx1) / 2
    for k in range(int(np.ceil(top / f.h))):
        zb, ze = k * f.h, min((k + 1) * f.h, top)
        if ze - zb < 0.3:
            break
        left, right = (cx0 + wt, dmid - door / 2), (dmid + door / 2, cx1 - wt)
        for a, b in (left, right):
            concrete.box((b - a, wt, ze - zb), ((a + b) / 2, cy0 + wt / 2, (zb + ze) / 2), material="concrete_dark")
        door_top = min(zb + 2.1, ze - 0.05)
        concrete.box((door, wt, ze - door_top), (dmid, cy0 + wt / 2, (door_top + ze) / 2), material="concrete_dark")


def add_shoring(formwork: MeshBuilder, f: Frame) -> None:
    """Shoring props under the most recent slab (every 1.2 m, clear of columns, core and opening)."""
    if f.built < 1:
        return
    cx0, cx1, cy0, cy1 = f.core
    hx0, hx1, hy0, hy1 = f.hole
    zb, ze = (f.built - 1) * f.h + f.t, f.built * f.h
    for x in np.arange(f.x0 + 0.8, f.x1 - 0.5, 1.2):
        for y in np.arange(f.y0 + 0.8, f.y1 - 0.5, 1.2):
            near_col = np.min(np.abs(f.gx - x)) < f.col / 2 + 0.15 and np.min(np.abs(f.gy - y)) < f.col / 2 + 0.15
            in_core = cx0 - 0.3 < x < cx1 + 0.3 and cy0 - 0.3 < y < cy1 + 0.3
            in_hole = hx0 - 0.2 < x < hx1 + 0.2 and hy0 - 0.2 < y < hy1 + 0.2
            if near_col or in_core or in_hole:
                continue
            formwork.box((0.15, 0.15, 0.008), (x, y, zb + 0.004), material="steel_painted")
            formwork.cylinder(0.03, (x, y, zb + 0.008), (x, y, ze - 0.6), segments=8, material="steel_painted")
            formwork.cylinder(0.024, (x, y, ze - 0.6), (x, y, ze - 0.008), segments=8, material="steel_galvanized")
            formwork.box((0.15, 0.15, 0.008), (x, y, ze - 0.004), material="steel_painted")


def infill(rng: np.random.Generator, f: Frame, growth: Growth | None) -> tuple[int, MeshBuilder]:
    """Brick infill with window openings on completed floors (all but the top two), glazed
    below: (floors enclosed, walls)."""
    own_enclosed = max(0, f.own_built - 2)
    enclosed = own_enclosed if growth is None else growth.enclosed
    walls = MeshBuilder()
    gx, gy = f.gx, f.gy
    for k in range(max(enclosed, own_enclosed)):  # the building's own floors draw from rng even when not built
        zb, ze = k * f.h + f.t, (k + 1) * f.h
        glazed = k < enclosed - 1
        frng = rng if k < own_enclosed else growth.floor_rng(k)
        for along_x, line, ticks in ((True, gy[0], gx), (True, gy[-1], gx), (False, gx[0], gy), (False, gx[-1], gy)):
            for a0, a1 in zip(ticks[:-1], ticks[1:]):
                if frng.random() < 0.1:
                    continue  # a bay left open (deliveries)
                win = frng.uniform(1.2, 2.4)
                if k < enclosed:
                    infill_bay(walls, along_x, line, a0 + f.col / 2, a1 - f.col / 2, zb, ze, win, glazed)
    return enclosed, walls


def add_starter_bars(rng: np.random.Generator, rebar: MeshBuilder, formwork: MeshBuilder, f: Frame) -> None:
    """Starter bars on every column of the top slab (a cage of 8 bars with stirrups), formwork
    around some of them."""
    cx0, cx1, cy0, cy1 = f.core
    top_z = f.built * f.h + f.t
    bar_h = rng.uniform(1.0, 1.5)
    boxed = rng.random((len(f.gx), len(f.gy))) < 0.3
    for a, x in enumerate(f.gx):
        for b, y in enumerate(f.gy):
            if cx0 - 0.5 < x < cx1 + 0.5 and cy0 - 0.5 < y < cy1 + 0.5:
                continue
            c = f.col / 2 - 0.05
            for px, py in ((-c, -c), (c, -c), (c, c), (-c, c), (0, -c), (c, 0), (0, c), (-c, 0)):
                rebar.cylinder(0.012, (x + px, y + py, top_z), (x + px, y + py, top_z + bar_h), segments=6, material="rebar")
            for zs in np.arange(top_z + 0.15, top_z + bar_h - 0.05, 0.2):
                for dx, dy, sx_, sy_ in ((0, -c - 0.02, 2 * c + 0.052, 0.012), (0, c + 0.02, 2 * c + 0.052, 0.012),
                                         (-c - 0.02, 0, 0.012, 2 * c + 0.016), (c + 0.02, 0, 0.012, 2 * c + 0.016)):
                    rebar.box((sx_, sy_, 0.012), (x + dx, y + dy, zs), material="rebar")
            if boxed[a, b]:
                # panels 2 cm off the column's faces: twice the timeline's point tolerance
                # (changes.POINT_TOLERANCE), so the next floor's column faces, poured where the
                # panels stood, are 'added' without a tie at the tolerance
                panel_h, th, gap = 2.7, 0.06, 0.02
                half = f.col / 2 + th / 2 + gap
                for dx, dy, w in ((half, 0, (th, f.col + 2 * th + 2 * gap)), (-half, 0, (th, f.col + 2 * th + 2 * gap)),
                                  (0, half, (f.col, th)), (0, -half, (f.col, th))):
                    formwork.box((w[0], w[1], panel_h), (x + dx, y + dy, top_z + panel_h / 2), material="formwork")


def add_rebar_mat(rng: np.random.Generator, rebar: MeshBuilder, f: Frame) -> None:
    """A rebar mat being laid on part of the top slab: bars every 0.2 m both ways on chairs,
    kept clear of the stair opening and the core."""
    cx0, cx1, cy0, cy1 = f.core
    hx0, hx1, hy0, hy1 = f.hole
    top_z = f.built * f.h + f.t
    mat_x0, mat_x1 = f.x0 + 0.5, f.x0 + rng.uniform(0.3, 0.7) * (f.x1 - f.x0)
    mat_y0, mat_y1 = f.y0 + 0.5, f.y1 - 0.5
    keep_out = [(hx0 - 0.1, hx1 + 0.1, hy0 - 0.1, hy1 + 0.1), (cx0 - 0.2, cx1 + 0.2, cy0 - 0.2, cy1 + 0.2)]
    z_bar = top_z + 0.05
    for y in np.arange(mat_y0, mat_y1, 0.2):
        for a, b in free_spans(mat_x0, mat_x1, [(r[0], r[1]) for r in keep_out if r[2] < y < r[3]]):
            rebar.cylinder(0.008, (a, y, z_bar), (b, y, z_bar), segments=6, material="rebar")
    for x in np.arange(mat_x0, mat_x1, 0.2):
        for a, b in free_spans(mat_y0, mat_y1, [(r[2], r[3]) for r in keep_out if r[0] < x < r[1]]):
            rebar.cylinder(0.008, (x, a, z_bar + 0.016), (x, b, z_bar + 0.016), segments=6, material="rebar")
    for x in np.arange(mat_x0 + 0.1, mat_x1, 1.0):
        for y in np.arange(mat_y0 + 0.1, mat_y1, 1.0):
            if not any(r[0] < x < r[1] and r[2] < y < r[3] for r in keep_out):
                rebar.box((0.04, 0.04, 0.042), (x, y, top_z + 0.021), material="plastic_white")  # bar chairs


def add_spare_panels(rng: np.random.Generator, formwork: MeshBuilder, f: Frame) -> None:
    """A stack of spare formwork panels (2.4 x 0.9) in the middle of a free bay of the top slab."""
    gx, gy, nx = f.gx, f.gy, f.nx
    top_z = f.built * f.h + f.t
    fx = (gx[(f.hole_i + 1) % nx] + gx[(f.hole_i + 1) % nx + 1]) / 2 if (f.hole_i + 1) % nx != f.core_i else (gx[0] + gx[1]) / 2
    fy = (gy[0] + gy[1]) / 2
    for k in range(int(rng.integers(3, 9))):
        formwork.box((2.4, 0.9, 0.12), (fx, fy, top_z + 0.06 + 0.121 * k), material="formwork")


def scaffolding(rng: np.random.Generator, f: Frame) -> MeshBuilder:
    """Scaffolding on one or both long facades, and on a short one half the time."""
    scaffold = MeshBuilder()
    sides = [-1] if rng.random() < 0.4 else [-1, 1]
    height = f.built * f.h + f.t + 1.0
    for side in sides:
        scaffold_run(scaffold, f.x0, f.x1, side * (f.y1 + 0.3), side, height)
    if rng.random() < 0.5:  # also on a short facade, between the long runs
        end = MeshBuilder()
        scaffold_run(end, f.y0 + 0.9, f.y1 - 0.9, f.x1 + 0.3, 1, height)
        # built along x at y = x1 + 0.3 facing +y: turn it to run along y at x = x1 + 0.3
        scaffold.merge(end, rotation=np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]).T)
    return scaffold



# (rng, frame, growth) -> (levels enclosed, the envelope's mesh): how the floors are closed in
Envelope = Callable[[np.random.Generator, Frame, "Growth | None"], tuple[int, MeshBuilder]]
# (rng, frame, levels enclosed) -> (taxonomy class, mesh) of the temporary works around the frame
Temporary = Callable[[np.random.Generator, Frame, int], tuple[str, MeshBuilder]]


def frame_building(rng: np.random.Generator, phase: float, floors: tuple[int, int], max_length: float,
                   growth: Growth | None, envelope: Envelope, temporary: Temporary) -> Asset:
    """A reinforced-concrete frame under construction, centred on the origin, closed in by
    ``envelope`` and surrounded by ``temporary`` works.

    Bays of 5.5-7.5 m, floor-to-floor 3.0-3.5 m, slabs 0.2-0.3 m with a stair opening,
    columns 0.35-0.55 m, a core with door openings running ahead of the slabs, starter bars
    and column formwork on the top slab. ``phase`` in [0, 1] is the share of the planned
    floors already built (at least one); the footprint, temporary works included, stays
    within ``max_length`` metres. ``growth`` builds a later stage of the same building: every
    random draw is made as at stage 0, so what a stage has in common with the previous one
    is the same geometry.
    """
    f = draw_frame(rng, phase, floors, max_length, growth)
    concrete, formwork, rebar = MeshBuilder(), MeshBuilder(), MeshBuilder()
    add_slabs_and_columns(concrete, f)
    add_core(concrete, f)
    add_shoring(formwork, f)
    enclosed, walls = envelope(rng, f, growth)
    add_starter_bars(rng, rebar, formwork, f)
    add_rebar_mat(rng, rebar, f)
    add_spare_panels(rng, formwork, f)
    temporary_label, works = temporary(rng, f, enclosed)
    if enclosed:
        concrete.merge(walls)
    parts = [Part("Building", concrete.build()), Part("Rebar", rebar.build()), Part("Formwork", formwork.build()),
             Part(temporary_label, works.build())]
    top_z = f.built * f.h + f.t
    depth = 2 * (f.y1 + 0.3 + 0.73 + 0.3)
    return Asset("Building", parts, (f.x1 - f.x0 + 0.6, depth), info={"floors_built": f.built, "floors_planned": f.planned,
                                                                        "floors_enclosed": enclosed,
                                                                        "height": top_z + 2.0, "floor_height": f.h})


def tube_scaffolding(rng: np.random.Generator, f: Frame, enclosed: int) -> tuple[str, MeshBuilder]:
    """Scaffolding (:func:`scaffolding`) as a type's temporary works."""
    return "Scaffolding", scaffolding(rng, f)


def concrete_brick(rng: np.random.Generator, phase: float, floors: tuple[int, int], max_length: float = 60.0,
                   growth: Growth | None = None) -> Asset:
    """The first release's building: a concrete frame with brick infill (window openings,
    glazed below the top enclosed floor, two floors behind the frame) and tube scaffolding on
    one or two long facades (and a short one half the time)."""
    return frame_building(rng, phase, floors, max_length, growth, infill, tube_scaffolding)


register_type(BuildingType(
    name="concrete-brick", build=concrete_brick, weight=0.3, module=__name__,
    structure="reinforced-concrete frame (slabs, columns, a core ahead of the slabs) with red brick infill and "
              "windows; tube scaffolding on the long facades. A stage adds 1-2 floors of frame; the infill "
              "follows two floors behind",
))

"""Pieces of a building under construction (bpy-free): brick infill bays and tube
scaffolding along a facade, and the free spans of a line between obstacles. Used by the
Building kind (:mod:`generator.scene.catalogue.buildings`)."""

from __future__ import annotations

import numpy as np

from .meshes import MeshBuilder

TUBE = 0.0483 / 2  # scaffold tube radius, metres
TUBE_SEGMENTS = 10


def free_spans(a: float, b: float, blocked: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Parts of [a, b] outside the ``blocked`` intervals, each at least 0.3 m long."""
    spans = [(a, b)]
    for u, v in blocked:
        spans = [piece for s0, s1 in spans for piece in ((s0, min(s1, u)), (max(s0, v), s1))]
    return [(s0, s1) for s0, s1 in spans if s1 - s0 >= 0.3]


def infill_bay(b: MeshBuilder, along_x: bool, line: float, a0: float, a1: float, zb: float, ze: float,
                window: float, glazed: bool, thick: float = 0.2, material: str = "brick") -> None:
    """A ``thick`` wall of ``material`` (0.2 m of brick) between two columns, or a facade
    panel, with a window opening (sill 0.9 m, head 2.2 m) ``window`` metres wide (at most the
    span less 1 m), optionally glazed. ``along_x``: the wall runs along x at y = ``line``."""
    span = a1 - a0
    win = min(span - 1.0, window)
    sill, head = zb + 0.9, min(zb + 2.2, ze - 0.2)
    pieces = [((a0, a1), (zb, sill)), ((a0, a1), (head, ze))]
    if win > 0.4:
        w0 = a0 + (span - win) / 2
        pieces += [((a0, w0), (sill, head)), ((w0 + win, a1), (sill, head))]
    else:
        pieces += [((a0, a1), (sill, head))]
    for (u0, u1), (v0, v1) in pieces:
        if u1 - u0 < 1e-3 or v1 - v0 < 1e-3:
            continue
        centre = ((u0 + u1) / 2, line, (v0 + v1) / 2) if along_x else (line, (u0 + u1) / 2, (v0 + v1) / 2)
        size = (u1 - u0, thick, v1 - v0) if along_x else (thick, u1 - u0, v1 - v0)
        b.box(size, centre, material=material)
    if glazed and win > 0.4:
        w0 = a0 + (span - win) / 2
        centre = ((w0 + win / 2), line, (sill + head) / 2) if along_x else (line, w0 + win / 2, (sill + head) / 2)
        size = (win - 0.002, 0.02, head - sill - 0.002) if along_x else (0.02, win - 0.002, head - sill - 0.002)
        b.box(size, centre, material="glass")


def scaffold_run(b: MeshBuilder, x0: float, x1: float, y_inner: float, side: int, height: float) -> None:
    """Tube-and-fitting scaffolding along a facade: standards every 2.07 m bay, 0.73 m deep,
    ledgers and transoms every 2 m lift, planks on each lift, a diagonal brace every 3 bays."""
    bays = max(1, int(np.floor((x1 - x0) / 2.07)))
    xs = x0 + (x1 - x0 - bays * 2.07) / 2 + 2.07 * np.arange(bays + 1)
    yi, yo = y_inner, y_inner + side * 0.73
    lifts = np.arange(2.0, height + 1e-6, 2.0)
    for x in xs:
        for y in (yi, yo):
            b.cylinder(TUBE, (x, y, 0.0), (x, y, height), segments=TUBE_SEGMENTS, material="steel_galvanized")
            b.box((0.15, 0.15, 0.01), (x, y, 0.005), material="steel_galvanized")  # base plate
    for z in lifts:
        for y in (yi, yo):
            b.cylinder(TUBE, (xs[0] - 0.1, y + side * 0.06, z), (xs[-1] + 0.1, y + side * 0.06, z), segments=TUBE_SEGMENTS, material="steel_galvanized")
        # guard rails at 0.5 m and 1.0 m above the platform, toe board on the outside
        for dz in (0.55, 1.05):
            if z + dz < height:
                b.cylinder(TUBE, (xs[0] - 0.1, yo + side * 0.05, z + dz), (xs[-1] + 0.1, yo + side * 0.05, z + dz), segments=TUBE_SEGMENTS, material="steel_galvanized")
        b.box((xs[-1] - xs[0], 0.03, 0.15), ((xs[0] + xs[-1]) / 2, yo - side * 0.05, z + 0.06 + 2 * TUBE + 0.04 + 0.075), material="wood")
        for k, x in enumerate(xs):
            b.cylinder(TUBE, (x + 0.06, yi - side * 0.1, z + 0.06), (x + 0.06, yo + side * 0.1, z + 0.06), segments=TUBE_SEGMENTS, material="steel_galvanized")
            if k < bays:  # a platform of three 0.225 m boards
                for j in (-1, 0, 1):
                    b.box((2.0, 0.22, 0.04), (x + 1.035, (yi + yo) / 2 + j * 0.225, z + 0.06 + TUBE + 0.021), material="wood")
    for k in range(0, bays, 3):
        for z in lifts[:-1]:
            b.cylinder(TUBE, (xs[k] + 0.05, yo + side * 0.06, z - 1.9), (xs[k + 1] - 0.05, yo + side * 0.06, z + 0.0),
                       segments=TUBE_SEGMENTS, material="steel_galvanized")


def facades(x0: float, x1: float, y0: float, y1: float, gap: float, thick: float) -> list[tuple[bool, float, float, float]]:
    """The four facades of a cladding ``thick`` metres deep hung ``gap`` outside the slab
    outline x0..x1, y0..y1: (along_x, line, a0, a1) each, the long runs (along x) covering
    the corners and the short ones fitting between them, so no two overlap."""
    out = gap + thick
    return [(True, y0 - gap - thick / 2, x0 - out, x1 + out), (True, y1 + gap + thick / 2, x0 - out, x1 + out),
            (False, x0 - gap - thick / 2, y0 - gap, y1 + gap), (False, x1 + gap + thick / 2, y0 - gap, y1 + gap)]


def modules(a0: float, a1: float, width: float) -> list[tuple[float, float]]:
    """[a0, a1] cut into equal modules about ``width`` long (at least one)."""
    n = max(1, int(round((a1 - a0) / width)))
    edges = a0 + (a1 - a0) * np.arange(n + 1) / n
    return list(zip(edges[:-1], edges[1:]))


def edge_protection(b: MeshBuilder, x0: float, x1: float, y0: float, y1: float, levels: list[tuple[float, float]]) -> None:
    """Edge protection round open slab edges: posts every 2.4 m or less, clamped 8 cm
    outside the slab outline x0..x1, y0..y1, from each level's slab soffit to 1.1 m above
    its top, and rails 0.5 and 1.0 m above the top. ``levels``: (soffit z, top z) each."""
    e = 0.08
    xs = [a for a, _ in modules(x0 - e, x1 + e, 2.4)] + [x1 + e]
    ys = [a for a, _ in modules(y0 - e, y1 + e, 2.4)] + [y1 + e]
    for soffit, top in levels:
        for y in (y0 - e, y1 + e):
            for x in xs:
                b.cylinder(TUBE, (x, y, soffit), (x, y, top + 1.1), segments=8, material="steel_painted")
        for x in (x0 - e, x1 + e):
            for y in ys[1:-1]:
                b.cylinder(TUBE, (x, y, soffit), (x, y, top + 1.1), segments=8, material="steel_painted")
        for dz in (0.5, 1.0):
            z = top + dz
            for y in (y0 - e, y1 + e):
                b.cylinder(TUBE, (x0 - e, y, z), (x1 + e, y, z), segments=8, material="steel_galvanized")
            for x in (x0 - e, x1 + e):
                b.cylinder(TUBE, (x, y0 - e, z), (x, y1 + e, z), segments=8, material="steel_galvanized")

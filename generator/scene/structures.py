"""Buildings under construction (with scaffolding, formwork, rebar) and tower cranes."""

from __future__ import annotations

import numpy as np

from dataclasses import dataclass
from typing import Callable

from .assets import Asset, Keyframes, Part
from .meshes import MeshBuilder

TUBE = 0.0483 / 2  # scaffold tube radius, metres
TUBE_SEGMENTS = 10


@dataclass(frozen=True)
class Growth:
    """A later stage of a building (docs/phases.md): ``built`` floors of concrete frame and
    ``enclosed`` floors of brick infill (from the ground up), at least the building's own at
    stage 0. ``floor_rng(k)`` gives the random stream of infill floor ``k`` for floors beyond
    those the building drew itself, so the draws of every other part stay as at stage 0."""

    built: int
    enclosed: int
    floor_rng: Callable[[int], np.random.Generator]


def building(rng: np.random.Generator, phase: float, floors: tuple[int, int], max_length: float = 60.0,
             growth: Growth | None = None) -> Asset:
    """A reinforced-concrete frame under construction, centred on the origin.

    Bays of 5.5-7.5 m, floor-to-floor 3.0-3.5 m, slabs 0.2-0.3 m with a stair opening,
    columns 0.35-0.55 m, a core with door openings running ahead of the slabs, starter bars
    and column formwork on the top slab, and scaffolding on one or two long facades.
    ``phase`` in [0, 1] is the share of the planned floors already built (at least one);
    the footprint, scaffolding included, stays within ``max_length`` metres. ``growth``
    builds a later stage of the same building: every random draw is made as at stage 0, so
    what a stage has in common with the previous one is the same geometry.
    """
    sx, sy = rng.uniform(5.5, 7.5), rng.uniform(5.5, 7.5)
    fit_x = max(2, int((max_length - 4.0) // sx))
    fit_y = max(2, int((max_length - 6.0) // sy))
    nx, ny = int(rng.integers(2, max(3, min(5, fit_x) + 1))), int(rng.integers(2, max(3, min(3, fit_y) + 1)))
    col = rng.uniform(0.35, 0.55)
    h, t = rng.uniform(3.0, 3.5), rng.uniform(0.2, 0.3)
    planned = int(rng.integers(floors[0], floors[1] + 1))
    built = own_built = max(1, int(round(phase * planned)))
    if growth is not None:
        if not own_built <= growth.built <= planned or not max(0, own_built - 2) <= growth.enclosed <= growth.built:
            raise ValueError(f"building growth {growth.built} floors built, {growth.enclosed} enclosed is outside "
                             f"[{own_built}, {planned}] built and [{max(0, own_built - 2)}, built] enclosed")
        built = growth.built
    lx, ly = nx * sx, ny * sy
    x0, x1, y0, y1 = -lx / 2 - 0.3, lx / 2 + 0.3, -ly / 2 - 0.3, ly / 2 + 0.3
    gx = -lx / 2 + sx * np.arange(nx + 1)
    gy = -ly / 2 + sy * np.arange(ny + 1)
    hole_i, core_i = rng.choice(nx, size=2, replace=False)
    hole_j, core_j = int(rng.integers(ny)), int(rng.integers(ny))
    hx0, hx1 = gx[hole_i] + 0.6, gx[hole_i + 1] - 0.6
    hy0, hy1 = gy[hole_j] + 0.6, gy[hole_j] + min(3.0, sy - 1.2)

    concrete = MeshBuilder()
    formwork_props = MeshBuilder()
    for k in range(built + 1):
        z = k * h + t / 2
        for bx0, bx1, by0, by1 in ((x0, hx0, y0, y1), (hx1, x1, y0, y1), (hx0, hx1, y0, hy0), (hx0, hx1, hy1, y1)):
            concrete.box((bx1 - bx0, by1 - by0, t), ((bx0 + bx1) / 2, (by0 + by1) / 2, z), material="concrete")
    for k in range(built):
        zb, ze = k * h + t, (k + 1) * h
        for x in gx:
            for y in gy:
                concrete.box((col, col, ze - zb), (x, y, (zb + ze) / 2), material="concrete")
    # core: 3 full walls and a front wall with a door on every floor, 2 m ahead of the slabs
    cx0, cx1 = gx[core_i] + col, gx[core_i] + min(sx - col, 3.2)
    cy0, cy1 = gy[core_j] + col, gy[core_j] + min(sy - col, 4.5)
    wt = 0.25
    top = built * h + t + 2.0
    concrete.box((cx1 - cx0, wt, top), ((cx0 + cx1) / 2, cy1 - wt / 2, top / 2), material="concrete_dark")
    concrete.box((wt, cy1 - cy0 - wt, top), (cx0 + wt / 2, (cy0 + cy1 - wt) / 2, top / 2), material="concrete_dark")
    concrete.box((wt, cy1 - cy0 - wt, top), (cx1 - wt / 2, (cy0 + cy1 - wt) / 2, top / 2), material="concrete_dark")
    door = min(1.0, cx1 - cx0 - 2 * wt - 0.4)
    dmid = (cx0 + cx1) / 2
    for k in range(int(np.ceil(top / h))):
        zb, ze = k * h, min((k + 1) * h, top)
        if ze - zb < 0.3:
            break
        left, right = (cx0 + wt, dmid - door / 2), (dmid + door / 2, cx1 - wt)
        for a, b in (left, right):
            concrete.box((b - a, wt, ze - zb), ((a + b) / 2, cy0 + wt / 2, (zb + ze) / 2), material="concrete_dark")
        door_top = min(zb + 2.1, ze - 0.05)
        concrete.box((door, wt, ze - door_top), (dmid, cy0 + wt / 2, (door_top + ze) / 2), material="concrete_dark")

    # shoring props under the most recent slab (every 1.2 m, clear of columns, core and opening)
    if built >= 1:
        zb, ze = (built - 1) * h + t, built * h
        for x in np.arange(x0 + 0.8, x1 - 0.5, 1.2):
            for y in np.arange(y0 + 0.8, y1 - 0.5, 1.2):
                near_col = np.min(np.abs(gx - x)) < col / 2 + 0.15 and np.min(np.abs(gy - y)) < col / 2 + 0.15
                in_core = cx0 - 0.3 < x < cx1 + 0.3 and cy0 - 0.3 < y < cy1 + 0.3
                in_hole = hx0 - 0.2 < x < hx1 + 0.2 and hy0 - 0.2 < y < hy1 + 0.2
                if near_col or in_core or in_hole:
                    continue
                formwork_props.box((0.15, 0.15, 0.008), (x, y, zb + 0.004), material="steel_painted")
                formwork_props.cylinder(0.03, (x, y, zb + 0.008), (x, y, ze - 0.6), segments=8, material="steel_painted")
                formwork_props.cylinder(0.024, (x, y, ze - 0.6), (x, y, ze - 0.008), segments=8, material="steel_galvanized")
                formwork_props.box((0.15, 0.15, 0.008), (x, y, ze - 0.004), material="steel_painted")

    # brick infill with window openings on completed floors (all but the top two), glazed below
    own_enclosed = max(0, own_built - 2)
    enclosed = own_enclosed if growth is None else growth.enclosed
    walls = MeshBuilder()
    for k in range(max(enclosed, own_enclosed)):  # the building's own floors draw from rng even when not built
        zb, ze = k * h + t, (k + 1) * h
        glazed = k < enclosed - 1
        frng = rng if k < own_enclosed else growth.floor_rng(k)
        for along_x, line, ticks in ((True, gy[0], gx), (True, gy[-1], gx), (False, gx[0], gy), (False, gx[-1], gy)):
            for a0, a1 in zip(ticks[:-1], ticks[1:]):
                if frng.random() < 0.1:
                    continue  # a bay left open (deliveries)
                win = frng.uniform(1.2, 2.4)
                if k < enclosed:
                    _infill_bay(walls, along_x, line, a0 + col / 2, a1 - col / 2, zb, ze, win, glazed)

    # top slab: starter bars on every column, formwork around some of them
    top_z = built * h + t
    rebar, formwork = MeshBuilder(), formwork_props
    bar_h = rng.uniform(1.0, 1.5)
    boxed = rng.random((len(gx), len(gy))) < 0.3
    for a, x in enumerate(gx):
        for b, y in enumerate(gy):
            if cx0 - 0.5 < x < cx1 + 0.5 and cy0 - 0.5 < y < cy1 + 0.5:
                continue
            # column cage: 8 bars and a stirrup every 0.2 m
            c = col / 2 - 0.05
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
                half = col / 2 + th / 2 + gap
                for dx, dy, w in ((half, 0, (th, col + 2 * th + 2 * gap)), (-half, 0, (th, col + 2 * th + 2 * gap)),
                                  (0, half, (col, th)), (0, -half, (col, th))):
                    formwork.box((w[0], w[1], panel_h), (x + dx, y + dy, top_z + panel_h / 2), material="formwork")
    # a rebar mat being laid on part of the top slab: bars every 0.2 m both ways on chairs,
    # kept clear of the stair opening and the core
    mat_x0, mat_x1 = x0 + 0.5, x0 + rng.uniform(0.3, 0.7) * (x1 - x0)
    mat_y0, mat_y1 = y0 + 0.5, y1 - 0.5
    keep_out = [(hx0 - 0.1, hx1 + 0.1, hy0 - 0.1, hy1 + 0.1), (cx0 - 0.2, cx1 + 0.2, cy0 - 0.2, cy1 + 0.2)]
    z_bar = top_z + 0.05
    for y in np.arange(mat_y0, mat_y1, 0.2):
        for a, b in _free_spans(mat_x0, mat_x1, [(r[0], r[1]) for r in keep_out if r[2] < y < r[3]]):
            rebar.cylinder(0.008, (a, y, z_bar), (b, y, z_bar), segments=6, material="rebar")
    for x in np.arange(mat_x0, mat_x1, 0.2):
        for a, b in _free_spans(mat_y0, mat_y1, [(r[2], r[3]) for r in keep_out if r[0] < x < r[1]]):
            rebar.cylinder(0.008, (x, a, z_bar + 0.016), (x, b, z_bar + 0.016), segments=6, material="rebar")
    for x in np.arange(mat_x0 + 0.1, mat_x1, 1.0):
        for y in np.arange(mat_y0 + 0.1, mat_y1, 1.0):
            if not any(r[0] < x < r[1] and r[2] < y < r[3] for r in keep_out):
                rebar.box((0.04, 0.04, 0.042), (x, y, top_z + 0.021), material="plastic_white")  # bar chairs

    # a stack of spare panels (2.4 x 0.9) in the middle of a free bay
    fx = (gx[(hole_i + 1) % nx] + gx[(hole_i + 1) % nx + 1]) / 2 if (hole_i + 1) % nx != core_i else (gx[0] + gx[1]) / 2
    fy = (gy[0] + gy[1]) / 2
    for k in range(int(rng.integers(3, 9))):
        formwork.box((2.4, 0.9, 0.12), (fx, fy, top_z + 0.06 + 0.121 * k), material="formwork")

    scaffold = MeshBuilder()
    sides = [-1] if rng.random() < 0.4 else [-1, 1]
    height = top_z + 1.0
    for side in sides:
        _scaffold_run(scaffold, x0, x1, side * (y1 + 0.3), side, height)
    if rng.random() < 0.5:  # also on a short facade, between the long runs
        end = MeshBuilder()
        _scaffold_run(end, y0 + 0.9, y1 - 0.9, x1 + 0.3, 1, height)
        # built along x at y = x1 + 0.3 facing +y: turn it to run along y at x = x1 + 0.3
        scaffold.merge(end, rotation=np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]).T)
    if enclosed:
        concrete.merge(walls)
    parts = [Part("Building", concrete.build()), Part("Rebar", rebar.build()), Part("Formwork", formwork.build()),
             Part("Scaffolding", scaffold.build())]
    depth = 2 * (y1 + 0.3 + 0.73 + 0.3)
    return Asset("Building", parts, (x1 - x0 + 0.6, depth), info={"floors_built": built, "floors_planned": planned,
                                                                      "floors_enclosed": enclosed,
                                                                      "height": top_z + 2.0, "floor_height": h})


def _free_spans(a: float, b: float, blocked: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Parts of [a, b] outside the ``blocked`` intervals, each at least 0.3 m long."""
    spans = [(a, b)]
    for u, v in blocked:
        spans = [piece for s0, s1 in spans for piece in ((s0, min(s1, u)), (max(s0, v), s1))]
    return [(s0, s1) for s0, s1 in spans if s1 - s0 >= 0.3]


def _infill_bay(b: MeshBuilder, along_x: bool, line: float, a0: float, a1: float, zb: float, ze: float,
                window: float, glazed: bool) -> None:
    """A 0.2 m brick wall between two columns with a window opening (sill 0.9 m, head
    2.2 m) ``window`` metres wide (at most the span less 1 m), optionally glazed. ``along_x``:
    the wall runs along x at y = ``line``."""
    thick = 0.2
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
        b.box(size, centre, material="brick")
    if glazed and win > 0.4:
        w0 = a0 + (span - win) / 2
        centre = ((w0 + win / 2), line, (sill + head) / 2) if along_x else (line, w0 + win / 2, (sill + head) / 2)
        size = (win - 0.002, 0.02, head - sill - 0.002) if along_x else (0.02, win - 0.002, head - sill - 0.002)
        b.box(size, centre, material="glass")


def _scaffold_run(b: MeshBuilder, x0: float, x1: float, y_inner: float, side: int, height: float) -> None:
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


def _lattice_member(b: MeshBuilder, p0, p1, radius: float, material: str) -> None:
    b.cylinder(radius, p0, p1, segments=8, material=material)


# A tower crane's trolley runs along the jib at up to 1-1.7 m/s; ours at 1 m/s, stopping
# 2 s at each stop (hooking or setting down a load), whatever the animation's length.
TROLLEY_SPEED = 1.0  # m/s
TROLLEY_DWELL = 2.0  # s


def trolley_travel(stops: np.ndarray, frames: int, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Keys (frames (K,) float, positions (K,) metres along the jib) of a trolley starting at
    ``stops[0]`` at frame 1 and visiting the other stops in turn at :data:`TROLLEY_SPEED`,
    waiting :data:`TROLLEY_DWELL` at each arrival; cut at frame ``frames`` (``fps`` frames a
    second)."""
    times, xs = [0.0], [float(stops[0])]
    for x in stops[1:]:
        arrive = times[-1] + abs(float(x) - xs[-1]) / TROLLEY_SPEED
        times += [arrive, arrive + TROLLEY_DWELL]
        xs += [float(x), float(x)]
    end = (frames - 1) / fps
    keep = [i for i, t in enumerate(times) if t < end] or [0]
    times_kept, xs_kept = [times[i] for i in keep], [xs[i] for i in keep]
    if end > times_kept[-1]:
        times_kept.append(end)
        xs_kept.append(float(np.interp(end, times, xs)))
    return 1.0 + np.array(times_kept) * fps, np.array(xs_kept)


def tower_crane(rng: np.random.Generator, hook_height: float, jib_length: float, frames: int, fps: float,
                slew_offset: float = 0.0) -> Asset:
    """A flat-top tower crane: lattice mast on a concrete foundation, slewing jib and
    counter-jib with concrete counterweights, cab, a trolley moving along the jib and a hook
    block hanging at ``hook_height`` metres. It slews at 0.3-0.9 turns per minute, starting
    ``slew_offset`` radians from its drawn heading (a later stage of a timeline)."""
    side = rng.uniform(1.6, 2.2)
    section = rng.uniform(3.0, 5.0)
    mast_top = hook_height + 6.0
    a = side / 2
    mast = MeshBuilder()
    mast.box((6.0, 6.0, 1.0), (0, 0, 0.5), material="concrete")
    for sx in (-a, a):
        for sy in (-a, a):
            mast.box((0.18, 0.18, mast_top - 1.0), (sx, sy, (mast_top + 1.0) / 2), material="crane_paint")
    levels = np.arange(1.0, mast_top + 1e-6, section)
    corners = [(-a, -a), (a, -a), (a, a), (-a, a)]
    for k, z in enumerate(levels):
        for c in range(4):
            p, q = corners[c], corners[(c + 1) % 4]
            _lattice_member(mast, (p[0], p[1], z), (q[0], q[1], z), 0.05, "crane_paint")
            if k + 1 < len(levels):
                z2 = levels[k + 1]
                zm = (z + z2) / 2
                _lattice_member(mast, (p[0], p[1], z), (q[0], q[1], zm), 0.045, "crane_paint")  # K-bracing
                _lattice_member(mast, (q[0], q[1], zm), (p[0], p[1], z2), 0.045, "crane_paint")

    jib_h = rng.uniform(1.4, 2.0)
    counter = rng.uniform(12.0, 18.0)
    slew = MeshBuilder()
    slew.cylinder(side * 0.8, (0, 0, 0), (0, 0, 1.0), segments=20, material="crane_paint")
    slew.box((2.0, 1.6, 2.2), (0.3, -(a + 0.9), 1.1 + 0.2), material="crane_paint")  # cab
    slew.box((0.05, 1.4, 1.2), (1.31, -(a + 0.9), 1.6), material="glass")  # cab window
    bl, br, tp = (0, -0.8, 1.0), (0, 0.8, 1.0), (0, 0, 1.0 + jib_h)
    xs = np.arange(0.0, jib_length + 1e-6, 2.0)
    for chord in (bl, br, tp):
        slew.box((jib_length + counter, 0.14, 0.14), ((jib_length - counter) / 2, chord[1], chord[2]), material="crane_paint")
    for k in range(len(xs) - 1):
        x, x2 = xs[k], xs[k + 1]
        for p, q in ((bl, tp), (br, tp), (bl, br)):
            _lattice_member(slew, (x, p[1], p[2]), (x2, q[1], q[2]), 0.04, "crane_paint")
    slew.box((counter, 1.9, 0.12), (-counter / 2, 0, 0.96), material="steel_painted")  # walkway
    n_weights = int(rng.integers(3, 6))
    for k in range(n_weights):  # concrete slabs (0.95 x 1.8 x 0.5), two high, on the bottom chords:
        for lev in range(2):  # between the railings (|y| < 0.925) and under the top chord
            slew.box((0.95, 1.8, 0.49), (-counter + 0.6 + k * 1.0, 0, 1.07 + 0.25 + lev * 0.5), material="concrete")
    slew.box((counter, 0.05, 1.0), (-counter / 2, 0.95, 1.5), material="steel_painted")  # railing panels
    slew.box((counter, 0.05, 1.0), (-counter / 2, -0.95, 1.5), material="steel_painted")

    trolley = MeshBuilder()
    trolley.box((1.4, 1.8, 0.5), (0, 0, -0.25), material="crane_paint")
    drop = (mast_top + 1.0 - 0.07 - 0.5) - hook_height  # trolley bottom to hook block top
    hook = MeshBuilder()
    for y in (-0.25, 0.25):
        hook.cylinder(0.018, (0, y, -0.01), (0, y, -drop), segments=6, material="steel_cable")
    hook.box((0.7, 0.7, 0.9), (0, 0, -drop - 0.45), material="crane_hook")
    hook.cone(0.12, 0.05, (0, 0, -drop - 0.9), (0, 0, -drop - 1.4), segments=10, material="steel_painted")

    # animation: slewing (linear), trolley travel (piecewise linear, seeded)
    omega = rng.uniform(0.3, 0.9) * 2 * np.pi / 60 * rng.choice([-1, 1])  # rad/s, under 1 turn/min
    yaw0 = rng.uniform(0, 2 * np.pi) + slew_offset
    slew_keys = Keyframes(np.array([1, frames]), rotation=np.array([[0, 0, yaw0], [0, 0, yaw0 + omega * (frames - 1) / fps]]))
    key_frames, xs_trolley = trolley_travel(rng.uniform(6.0, jib_length - 2.0, 4), frames, fps)
    n_keys = len(key_frames)
    trolley_keys = Keyframes(key_frames, location=np.stack([xs_trolley, np.zeros(n_keys), np.full(n_keys, 1.0 - 0.07)], 1))
    parts = [
        Part("Crane", mast.build()),
        Part("", None, location=(0, 0, mast_top), keys=slew_keys),  # slewing pivot (an empty)
        Part("Crane", slew.build(), parent=1),
        Part("Crane", trolley.build(), location=(xs_trolley[0], 0, 1.0 - 0.07), parent=2, keys=trolley_keys),
        Part("Crane", hook.build(), parent=3),
    ]
    return Asset("Crane", parts, (6.0, 6.0), moves=False, footprint_from_geometry=False,
                 info={"hook_height": hook_height, "jib_length": jib_length, "counter_jib": counter, "mast_top": mast_top,
                       "top": mast_top + 1.0 + jib_h + 0.07,
                       "slew_rad_per_s": omega})

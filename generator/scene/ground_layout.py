"""The ground's faces (bpy-free): the working level at z = 0 with the site's relief, cut
into the regions that are made of different things, each face naming its material.

- the haul road loop: a band ``width`` wide along a rounded square centre line (half-side
  ``road_half``, corner radius ``corner``), in five strips across it: road, a tyre track,
  road, a tyre track, road (tracks about 0.5 m wide, ``TRACK_OFFSET_M`` either side of the
  centre line, wandering a little along the road); on an unpaved road the tracks are ruts,
  sunk ``ruts`` metres with sides ``RUT_SIDE_M`` wide;
- the gate access: the strip between the road and the gate in the south fence (x in
  ``gate``), road with two tracks (level);
- the site inside the road loop, with the ``digs`` of :mod:`.relief` cut into it (their
  floors and sides of the ``excavated`` material), and between the road and the fence: the
  site's surface;
- beyond the fence (``margin`` metres on every side): grass and weeds, on the ``terrain`` of
  :mod:`.relief` (level when None), in rows ``VERGE_STEP_M`` apart.

Every face is turned towards the open air (normals up on the level). Neighbouring regions
share their vertices along their borders (no T-junctions), so the ground is watertight.
"""

from __future__ import annotations

from dataclasses import dataclass

import mapbox_earcut
import numpy as np

from ..geometry.portable_math import sin, sincos, vector_norm
from .meshes import MeshBuilder, MeshData
from .relief import Dig, Terrain

TRACK_OFFSET_M = 1.1  # a tyre track's distance from the centre line (a truck's half track width)
TRACK_HALF_WIDTH_M = 0.25
RUT_SIDE_M = 0.08  # a rut's sloping side, across the road
VERGE_STEP_M = 2.0  # rows of the terrain beyond the fence
STEP_M = 2.0  # most length of a straight road piece between vertices
ARC_STEP_DEG = 15  # corner arcs in steps of this (a multiple that holds 45: the ray to the square's corner)


@dataclass(frozen=True)
class GroundRegions:
    """Where the ground's regions lie (metres, the site's frame), and each one's material."""

    half: float  # the fence line's half-side
    road_half: float  # the road loop's centre line half-side
    corner: float  # its corner radius
    width: float  # the road's width
    gate: tuple[float, float]  # x range of the gate access (south side)
    margin: float  # ground beyond the fence
    surface: str  # material names: the site's surface,
    road: str  # the road's,
    tracks: str  # the tyre tracks',
    verge: str  # beyond the fence
    excavated: str = "ground-spoil"  # the digs' floors and sides
    ruts: float = 0.0  # metres the tyre tracks are sunk (0: level)
    digs: tuple[Dig, ...] = ()
    terrain: Terrain | None = None


def centre_line(r: GroundRegions) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(points (N, 2), outward unit normals (N, 2), arc length from the first point (N,)) of
    the road's centre line, counter-clockwise from its south-west corner's end. Straight sides
    have a vertex at least every STEP_M metres, the south side also at the gate's edges and
    its tracks' edges; arcs every ARC_STEP_DEG degrees."""
    a = r.road_half - r.corner
    breaks = [r.gate[0], r.gate[1]] + [s * TRACK_OFFSET_M + d for s in (-1, 1) for d in (-TRACK_HALF_WIDTH_M, TRACK_HALF_WIDTH_M)]
    pts, nrm = [], []
    sides = (((0.0, -1.0), (1.0, 0.0)), ((1.0, 0.0), (0.0, 1.0)), ((0.0, 1.0), (-1.0, 0.0)), ((-1.0, 0.0), (0.0, -1.0)))
    for k, (n, t) in enumerate(sides):
        n, t = np.array(n), np.array(t)
        start = n * r.road_half - t * a  # the side runs from -a to a along its tangent
        stops = np.linspace(0.0, 2 * a, int(np.ceil(2 * a / STEP_M)) + 1)
        if k == 0:  # the south side (tangent +x): vertices at the gate's and its tracks' edges
            stops = np.union1d(stops, [x + a for x in breaks if -a < x < a])
        for s in stops[:-1]:
            pts.append(start + t * s)
            nrm.append(n)
        centre = t * a + n * (r.road_half - r.corner)  # the corner arc after this side
        base = (-90 + 90 * k)
        angles = np.radians(np.arange(base, base + 90, ARC_STEP_DEG, dtype=np.float64))
        s_, c_ = sincos(angles)
        for si, ci in zip(np.atleast_1d(s_), np.atleast_1d(c_)):
            d = np.array([ci, si])
            pts.append(centre + r.corner * d)
            nrm.append(d)
    p, n = np.array(pts), np.array(nrm)
    seg = vector_norm(np.roll(p, -1, axis=0) - p)
    return p, n, np.concatenate([[0.0], np.cumsum(seg)[:-1]])


def _wander(along: np.ndarray) -> np.ndarray:
    """Lateral wander of the tyre tracks (metres, within +-0.22) at arc length ``along``."""
    return 0.15 * sin(along * (2 * np.pi / 17.0)) + 0.07 * sin(along * (2 * np.pi / 5.3))


def _to_square(q: np.ndarray, n: np.ndarray, half: float) -> np.ndarray:
    """Where the rays from ``q`` along ``n`` (outward) meet the square of half-side ``half``."""
    with np.errstate(divide="ignore", invalid="ignore"):
        tx = np.where(np.abs(n[:, 0]) > 1e-12, (half - np.abs(q[:, 0])) / np.abs(n[:, 0]), np.inf)
        ty = np.where(np.abs(n[:, 1]) > 1e-12, (half - np.abs(q[:, 1])) / np.abs(n[:, 1]), np.inf)
    return q + n * np.minimum(tx, ty)[:, None]


def _lift(xy: np.ndarray, z) -> np.ndarray:
    return np.column_stack([xy, np.broadcast_to(np.asarray(z, dtype=np.float64), (len(xy),))])


def _ring(builder: MeshBuilder, inner: np.ndarray, outer: np.ndarray, materials) -> None:
    """Two triangles between each pair of neighbours of two closed rows of points (N, 3),
    counter-clockwise seen from above, ``outer`` outside ``inner``; the pair from point i of
    material ``materials[i]``."""
    m = len(inner)
    nxt = (np.arange(m) + 1) % m
    verts = np.concatenate([inner, outer])
    i, o = np.arange(m), m + np.arange(m)
    tris = np.concatenate([np.column_stack([i, o, m + nxt]), np.column_stack([i, m + nxt, nxt])])
    mats = list(materials) * 2
    for name in dict.fromkeys(materials):
        pick = np.array([x == name for x in mats])
        builder.add(verts, tris=tris[pick], material=name)


def _road_rows(r: GroundRegions, p: np.ndarray, n: np.ndarray, along: np.ndarray):
    """The rows of points (N, 3) across the road, inside out, and each strip's material."""
    t, h, e = TRACK_OFFSET_M, TRACK_HALF_WIDTH_M, RUT_SIDE_M
    if r.ruts > 0:
        offsets = [-r.width / 2, -(t + h), -(t + h) + e, -(t - h) - e, -(t - h), t - h, t - h + e, t + h - e, t + h, r.width / 2]
        depth = [0, 0, 1, 1, 0, 0, 1, 1, 0, 0]
        strips = [r.road, r.tracks, r.tracks, r.tracks, r.road, r.tracks, r.tracks, r.tracks, r.road]
    else:
        offsets = [-r.width / 2, -(t + h), -(t - h), t - h, t + h, r.width / 2]
        depth = [0] * 6
        strips = [r.road, r.tracks, r.road, r.tracks, r.road]
    wander = _wander(along)
    last = len(offsets) - 1
    rows = [_lift(p + n * (o + (wander if 0 < k < last else np.zeros(len(p))))[:, None], 0.0 - r.ruts * depth[k]) for k, o in enumerate(offsets)]
    return rows, strips


def _restore_dropped(points: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Triangles ``tris`` (T, 3) over ``points`` (N, 2) with the border points earcut dropped
    (those on a straight run) put back: each splits the triangle whose edge it lies on, so
    the neighbouring regions' vertices along the border are this region's too (no T-junction)."""
    tris = [tuple(t) for t in tris]
    used = np.zeros(len(points), dtype=bool)
    used[np.asarray(tris, dtype=np.int64).ravel()] = True
    for p in np.flatnonzero(~used):
        t = np.asarray(tris, dtype=np.int64)
        for k in range(3):
            a, b = points[t[:, k]], points[t[:, (k + 1) % 3]]
            ab, ap = b - a, points[p] - a
            length2 = (ab * ab).sum(axis=1)
            along = (ab * ap).sum(axis=1)
            off = ab[:, 0] * ap[:, 1] - ab[:, 1] * ap[:, 0]
            on = np.flatnonzero((np.abs(off) <= 1e-9 * length2) & (along > 0) & (along < length2))
            if len(on):
                i, j, o = (int(x) for x in t[on[0], [k, (k + 1) % 3, (k + 2) % 3]])
                tris[on[0]] = (i, int(p), o)
                tris.append((int(p), j, o))
                break
        else:
            raise ValueError(f"ground layout: border point {points[p]} lies on no triangle's edge")
    return np.asarray(tris, dtype=np.int64)


def _inside(b: MeshBuilder, r: GroundRegions, rim: np.ndarray) -> None:
    """The level inside the road loop (its edge ``rim`` (N, 2), counter-clockwise) with the
    digs cut out of it, and the digs' faces."""
    holes = [d.outline() for d in r.digs]
    flat = np.concatenate([rim] + holes)
    ends = np.cumsum([len(rim)] + [len(h) for h in holes]).astype(np.uint32)
    tris = _restore_dropped(flat, mapbox_earcut.triangulate_float64(flat, ends).reshape(-1, 3).astype(np.int64))
    a, b_, c = (flat[tris[:, k]] for k in range(3))
    clockwise = (b_[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b_[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]) < 0
    tris[clockwise] = tris[clockwise][:, [0, 2, 1]]  # normals up
    b.add(_lift(flat, 0.0), tris=tris, material=r.surface)
    for d in r.digs:
        verts, faces = d.faces()
        b.add(verts, tris=faces, material=r.excavated)


def _verge(b: MeshBuilder, r: GroundRegions, edge: np.ndarray) -> None:
    """Grass beyond the fence: rows pushed out from the fence line's points ``edge`` (N, 2),
    each perpendicular to its side (corners diagonally), on the terrain."""
    out = np.where(np.abs(edge) >= r.half - 1e-9, np.sign(edge), 0.0)
    rows = int(np.ceil(r.margin / VERGE_STEP_M))
    prev = _lift(edge, 0.0)
    for k in range(1, rows + 1):
        beyond = r.margin * k / rows
        xy = edge + out * beyond
        z = np.zeros(len(xy)) if r.terrain is None else r.terrain.height(xy, np.full(len(xy), beyond))
        row = np.column_stack([xy, z])
        _ring(b, prev, row, [r.verge] * len(edge))
        prev = row


def ground_mesh(r: GroundRegions) -> MeshData:
    """The ground's faces (module docstring)."""
    p, n, along = centre_line(r)
    rows, strips = _road_rows(r, p, n, along)
    b = MeshBuilder()
    m = len(p)
    _inside(b, r, rows[0][:, :2])
    for k, material in enumerate(strips):
        _ring(b, rows[k], rows[k + 1], [material] * m)
    outer = rows[-1][:, :2]
    edge = _to_square(outer, n, r.half)
    mid = (outer + np.roll(outer, -1, axis=0)) / 2
    south = (n[:, 1] < -0.999) & (np.roll(n[:, 1], -1) < -0.999)
    gate = south & (mid[:, 0] > r.gate[0]) & (mid[:, 0] < r.gate[1])
    on_track = np.abs(np.abs(mid[:, 0]) - TRACK_OFFSET_M) < TRACK_HALF_WIDTH_M
    _ring(b, rows[-1], _lift(edge, 0.0), [(r.tracks if on_track[i] else r.road) if gate[i] else r.surface for i in range(m)])
    _verge(b, r, edge)
    return b.build()

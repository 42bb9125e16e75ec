"""The ground's faces (bpy-free): one flat surface at z = 0, cut into the regions that are
made of different things, each face naming its material.

- the haul road loop: a band ``width`` wide along a rounded square centre line (half-side
  ``road_half``, corner radius ``corner``), in five strips across it: road, a tyre track,
  road, a tyre track, road (tracks about 0.5 m wide, ``TRACK_OFFSET_M`` either side of the
  centre line, wandering a little along the road);
- the gate access: the strip between the road and the gate in the south fence (x in
  ``gate``), road with two tracks;
- the site inside the road loop and between the road and the fence: the site's surface;
- beyond the fence (``margin`` metres on every side): grass and weeds.

Every face is flat at z = 0 with its normal up: the regions only choose the material, so the
ground truth (depth, labels, points, contact faces) is that of one plane.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.portable_math import sin, sincos, vector_norm
from .meshes import MeshBuilder, MeshData

TRACK_OFFSET_M = 1.1  # a tyre track's distance from the centre line (a truck's half track width)
TRACK_HALF_WIDTH_M = 0.25
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


def _ring(builder: MeshBuilder, inner: np.ndarray, outer: np.ndarray, materials) -> None:
    """Quads between two closed rows of points (counter-clockwise, ``outer`` outside
    ``inner``), quad i of material ``materials[i]``."""
    m = len(inner)
    nxt = (np.arange(m) + 1) % m
    verts = np.concatenate([inner, outer])
    xyz = np.column_stack([verts, np.zeros(len(verts))])
    quads = np.column_stack([np.arange(m), m + np.arange(m), m + nxt, nxt])
    for name in dict.fromkeys(materials):
        pick = np.array([x == name for x in materials])
        builder.add(xyz, quads=quads[pick], material=name)


def ground_mesh(r: GroundRegions) -> MeshData:
    """The ground's faces (module docstring), all at z = 0 with their normals up."""
    p, n, along = centre_line(r)
    t, h = TRACK_OFFSET_M, TRACK_HALF_WIDTH_M
    offsets = [-r.width / 2, -(t + h), -(t - h), t - h, t + h, r.width / 2]
    wander = _wander(along)
    rows = [p + n * (o + (wander if 0 < k < 5 else np.zeros(len(p))))[:, None] for k, o in enumerate(offsets)]
    b = MeshBuilder()
    inner = rows[0]
    xyz = np.column_stack([np.vstack([[0.0, 0.0], inner]), np.zeros(len(inner) + 1)])
    m = len(inner)
    b.add(xyz, tris=np.column_stack([np.zeros(m, dtype=int), 1 + np.arange(m), 1 + (np.arange(m) + 1) % m]),
          material=r.surface)
    for k in range(5):
        _ring(b, rows[k], rows[k + 1], [r.tracks if k in (1, 3) else r.road] * m)
    edge = _to_square(rows[5], n, r.half)
    mid = (rows[5] + np.roll(rows[5], -1, axis=0)) / 2
    south = (n[:, 1] < -0.999) & (np.roll(n[:, 1], -1) < -0.999)
    gate = south & (mid[:, 0] > r.gate[0]) & (mid[:, 0] < r.gate[1])
    on_track = np.abs(np.abs(mid[:, 0]) - t) < h
    _ring(b, rows[5], edge, [(r.tracks if on_track[i] else r.road) if gate[i] else r.surface for i in range(m)])
    corners = np.array([(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)])
    _ring(b, corners * r.half, corners * (r.half + r.margin), [r.verge] * 4)
    return b.build()

"""Which surface points a pinhole camera sees (the single visibility rule of the project).

A point is visible when all of these hold:
1. it projects inside the image (0 <= x < W, 0 <= y < H in continuous pixel coordinates);
2. its planar depth z satisfies near < z <= far, with far = min(clip_end, max_depth);
3. it is not on the back side of a closed part (a solid) whose bounding box does not
   contain the camera: such a point is always hidden by the solid's own front side, so
   it is settled without a ray (at a silhouette this can hide a point whose ray enters
   the solid less than ``tol`` before it, which rule 4 alone would let through);
4. the segment from the camera centre to the point hits no triangle closer than
   ``d - tol`` (see ``raycast.OCCLUSION_TOL_*``), tested against static and dynamic parts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .raycast import OCCLUSION_TOL_ABS, OCCLUSION_TOL_REL, SceneGeometry


# Occlusion rays are cast in screen tiles of TILE pixels (row by row), so that neighbouring
# rays traverse the same part of the acceleration structure (about 2x faster than in
# storage order, where points are scattered at random over each part).
TILE = 16

# Points per block of PointBlocks (the unit of the frustum test before any per-point work).
BLOCK = 64


@dataclass(frozen=True)
class ViewLimits:
    """Depth limits in metres (planar z): visible points have near < z <= far."""

    near: float = 0.0
    far: float = np.inf


@dataclass
class VisibilityStats:
    """Counts from the last call, to understand where the time goes."""

    tested: int = 0
    in_view: int = 0
    culled_backfacing: int = 0
    rays: int = 0
    visible: int = 0


def visible_points(
    geometry: SceneGeometry,
    points: np.ndarray,
    normals: np.ndarray | None,
    part_index: np.ndarray | None,
    world_from_camera: np.ndarray,
    K: np.ndarray,
    width: int,
    height: int,
    limits: ViewLimits = ViewLimits(),
    stats: VisibilityStats | None = None,
    ray_per_point: bool = False,
) -> np.ndarray:
    """Visibility mask (N,) of world points (N, 3) from a camera pose.

    ``normals`` (N, 3) are the world-space outward unit normals of the points' surfaces and
    ``part_index`` (N,) the index of the part each point lies on; both are optional and
    only enable rule 3 (a shortcut that never changes the answer for solids seen from outside).
    With ``part_index``, the points are grouped once into small spatial blocks (cached on
    ``geometry`` for this pair of arrays) and only the blocks whose bounding box meets the
    view frustum are tested point by point. One occlusion ray per remaining point (rule 4),
    cast block by block; with ``ray_per_point`` every point is tested and rays are cast in
    storage order (the same answer: the plain reference).
    """
    points = np.asarray(points)
    n = len(points)
    r, centre = world_from_camera[:3, :3], world_from_camera[:3, 3]
    if part_index is not None and not ray_per_point and n:
        blocks = PointBlocks.for_points(geometry, points, normals, part_index)
        cand = blocks.candidates(r, centre, K, width, height, limits)  # positions in block order
        sub = blocks.sorted_points[cand]
    else:
        cand, sub = None, points
    # Camera coordinates axis by axis: three matrix-vector products are ~15x faster than
    # an (N, 3) x (3, 3) product. The frustum test is done without dividing by z.
    x = sub @ r[:, 0] - centre @ r[:, 0]
    y = sub @ r[:, 1] - centre @ r[:, 1]
    z = sub @ r[:, 2] - centre @ r[:, 2]
    ok = (z > limits.near) & (z <= limits.far)
    u = K[0, 0] * x + K[0, 1] * y + K[0, 2] * z  # = pixel x * z
    ok &= (u >= 0) & (u < width * z)
    v = K[1, 1] * y + K[1, 2] * z  # = pixel y * z
    ok &= (v >= 0) & (v < height * z)
    idx = np.flatnonzero(ok)  # into sub
    in_view = len(idx)
    reused = np.zeros(0, dtype=np.int64)
    if cand is not None:
        # rules 3 and 4 depend on the camera centre, not on its orientation: answers found
        # earlier from this centre (same geometry state) are reused (1 visible, 2 hidden)
        answers = blocks.answers(centre, geometry.version, normals is not None)
        known = answers[cand[idx]]
        reused = idx[known == 1]
        idx = idx[known == 0]

    culled = 0
    if normals is not None and part_index is not None and len(idx):
        bounds = geometry.world_bounds()
        cam_outside = np.any((centre < bounds[:, 0]) | (centre > bounds[:, 1]), axis=1)
        cullable_part = geometry.closed & cam_outside
        if cullable_part.any():
            if cand is None:
                idx_normals, idx_part = normals[idx], part_index[idx]
            else:
                idx_normals, idx_part = blocks.sorted_normals[cand[idx]], blocks.part[cand[idx]]
            # n . (p - c) in camera coordinates: the normals rotated once per call
            facing = idx_normals @ r
            facing_away = facing[:, 0] * x[idx] + facing[:, 1] * y[idx] + facing[:, 2] * z[idx] > 0
            drop = cullable_part[idx_part] & facing_away
            culled = int(drop.sum())
            if cand is not None:
                answers[cand[idx[drop]]] = 2
            idx = idx[~drop]

    if len(idx) > 1 and not ray_per_point and cand is None:
        idx = idx[_tile_order(u[idx] / z[idx], v[idx] / z[idx], width)]
    xs, ys, zs = x[idx], y[idx], z[idx]
    dist = np.sqrt(xs * xs + ys * ys + zs * zs)
    blocked = geometry.segments_blocked(centre, sub[idx], OCCLUSION_TOL_ABS + OCCLUSION_TOL_REL * dist)
    rays = len(idx)
    mask = np.zeros(n, dtype=bool)
    seen = idx[~blocked]
    if cand is None:
        mask[seen] = True
    else:
        answers[cand[idx]] = np.where(blocked, 2, 1).astype(np.int8)
        mask[blocks.order[cand[seen]]] = True
        mask[blocks.order[cand[reused]]] = True
    if stats is not None:
        stats.tested, stats.in_view, stats.culled_backfacing = n, in_view, culled
        stats.rays, stats.visible = rays, int(mask.sum())
    return mask


class PointBlocks:
    """The points grouped into blocks of at most BLOCK points, part by part, in Morton
    (z-curve) order of their coordinates, with each block's axis-aligned bounding box.

    Built once per (points, part_index) pair; when the caller hands a new ``points`` array
    with the same ``part_index`` (dynamic parts moved), only the boxes are recomputed. A
    block whose box lies entirely outside one of the frustum's half-spaces holds no point
    in view, so its points are never looked at.
    """

    def __init__(self, points: np.ndarray, part_index: np.ndarray):
        n = len(points)
        part = np.asarray(part_index, dtype=np.int64)
        lo, hi = points.min(axis=0), points.max(axis=0)
        scale = 1023.0 / max(float(np.max(hi - lo)), 1e-9)
        q = ((points - lo) * scale).astype(np.int64)
        key = _spread_bits(q[:, 0]) | (_spread_bits(q[:, 1]) << 1) | (_spread_bits(q[:, 2]) << 2)
        self.order = np.lexsort((key, part))
        sorted_part = part[self.order]
        # a block starts where the part changes or every BLOCK points within a part
        part_start = np.flatnonzero(np.r_[True, sorted_part[1:] != sorted_part[:-1]])
        run = np.diff(np.r_[part_start, n])
        offset = np.arange(n) - np.repeat(part_start, run)
        self.starts = np.flatnonzero(offset % BLOCK == 0)
        self.sizes = np.diff(np.r_[self.starts, n])
        self.part_index, self.part = part_index, np.asarray(part_index)[self.order]
        self.points = self.normals = None
        self._answers, self._answers_key = None, None
        self.set_points(points, None)

    @classmethod
    def for_points(cls, geometry: SceneGeometry, points: np.ndarray, normals: np.ndarray | None,
                   part_index: np.ndarray) -> "PointBlocks":
        """The blocks of these arrays, from ``geometry.point_blocks`` when they match."""
        blocks = geometry.point_blocks
        if not isinstance(blocks, cls) or blocks.part_index is not part_index or len(blocks.order) != len(points):
            blocks = geometry.point_blocks = cls(points, part_index)
        if blocks.points is not points or blocks.normals is not normals:
            blocks.set_points(points, normals)
        return blocks

    def set_points(self, points: np.ndarray, normals: np.ndarray | None) -> None:
        """Take new coordinates (and normals) of the same points: copies in block order
        (so that gathering the points of a block reads contiguous memory) and the boxes."""
        if points is not self.points:
            self.sorted_points = points[self.order]
            lo = np.minimum.reduceat(self.sorted_points, self.starts, axis=0)
            hi = np.maximum.reduceat(self.sorted_points, self.starts, axis=0)
            self.centre, self.half = (lo + hi) / 2, (hi - lo) / 2
        self.sorted_normals = None if normals is None else normals[self.order]
        self.points, self.normals = points, normals
        self._answers_key = None

    def answers(self, centre: np.ndarray, version: int, with_normals: bool) -> np.ndarray:
        """Per position in block order, rules 3 and 4 from ``centre`` as found so far (0
        unknown, 1 visible, 2 hidden); forgotten when the centre, the geometry's state
        (``version``), the points, their normals or the use of normals change."""
        key = (tuple(np.asarray(centre, np.float64).tolist()), version, with_normals)
        if key != self._answers_key:
            self._answers = np.zeros(len(self.order), dtype=np.int8)
            self._answers_key = key
        return self._answers

    def candidates(self, r: np.ndarray, c: np.ndarray, K: np.ndarray, width: int, height: int,
                   limits: ViewLimits) -> np.ndarray:
        """Positions (in block order: ``order[positions]`` are the point indices) of the
        points in the blocks whose box meets the view frustum."""
        # each frustum half-space as a . p + b >= 0 over world points p
        a_u = K[0, 0] * r[:, 0] + K[0, 1] * r[:, 1] + K[0, 2] * r[:, 2]
        a_v = K[1, 1] * r[:, 1] + K[1, 2] * r[:, 2]
        planes = [r[:, 2], a_u, width * r[:, 2] - a_u, a_v, height * r[:, 2] - a_v]
        offsets = [-limits.near, 0.0, 0.0, 0.0, 0.0]
        if np.isfinite(limits.far):
            planes.append(-r[:, 2])
            offsets.append(limits.far)
        a = np.array(planes)
        b = np.array(offsets) - a @ c
        # the largest value of a . p + b over each box
        reach = self.centre @ a.T + self.half @ np.abs(a).T + b
        keep = np.flatnonzero(np.all(reach >= 0, axis=1))
        sizes = self.sizes[keep]
        total = int(sizes.sum())
        # positions of the kept blocks' points in self.order, without a Python loop
        shift = np.repeat(self.starts[keep] - (np.cumsum(sizes) - sizes), sizes)
        return np.arange(total) + shift


def _spread_bits(v: np.ndarray) -> np.ndarray:
    """Spread the low 10 bits of v so that two zero bits separate each (for Morton codes)."""
    v = v & 0x3FF
    v = (v | (v << 16)) & 0x030000FF
    v = (v | (v << 8)) & 0x0300F00F
    v = (v | (v << 4)) & 0x030C30C3
    v = (v | (v << 2)) & 0x09249249
    return v


def _tile_order(px: np.ndarray, py: np.ndarray, width: int) -> np.ndarray:
    """Order (M,) of points by screen tile (TILE x TILE pixels, row by row) from their pixel
    coordinates (>= 0); a stable radix sort on small integer keys."""
    cols = int(width) // TILE + 1
    key = (py * (1.0 / TILE)).astype(np.int32) * cols + (px * (1.0 / TILE)).astype(np.int32)
    if key.max(initial=0) < np.iinfo(np.int16).max:
        key = key.astype(np.int16)
    return np.argsort(key, kind="stable")

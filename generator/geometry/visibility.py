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

Each rule is evaluated point by point by the functions of :mod:`.visibility_rules`; the
fast path (:class:`.point_blocks.PointBlocks`: most decisions of rules 1-3 per group of
points, with margins) and the reference (every point tested, one ray each) give the same bits.
"""

from __future__ import annotations

import numpy as np

from .camera import world_to_camera
from .lens import PINHOLE, Lens
from .point_blocks import PointBlocks
from .raycast import SceneGeometry
from .visibility_rules import (
    ViewLimits,
    VisibilityStats,
    cullable_parts,
    facing_away,
    in_view,
    segments_blocked,
)

__all__ = ["ViewLimits", "VisibilityStats", "visible_points"]

# Without point groups, occlusion rays are cast in screen tiles of TILE pixels (row by row),
# so that neighbouring rays traverse the same part of the acceleration structure (about 2x
# faster than in storage order, where points are scattered at random over each part).
TILE = 16


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
    lens: Lens = PINHOLE,
) -> np.ndarray:
    """Visibility mask (N,) of world points (N, 3) from a camera pose.

    ``normals`` (N, 3) are the world-space outward unit normals of the points' surfaces and
    ``part_index`` (N,) the index of the part each point lies on; both are optional and
    only enable rule 3 (a shortcut that never changes the answer for solids seen from outside).
    With ``part_index``, the points are grouped once into small spatial groups (cached on
    ``geometry`` for this pair of arrays) and rules 1-3 are decided per group wherever the
    group's box and normal cone settle them (:meth:`.point_blocks.PointBlocks.visible`).
    With ``ray_per_point`` (or without ``part_index``) every point is tested and gets its own
    ray (the same answer: the plain reference). With a ``lens`` (generator/geometry/lens.py),
    rule 1 asks whether the point projects into the image through it.
    """
    if not lens.ideal:  # rule 1 through a pinhole holding the lens's view, then exactly through the lens
        cover, cover_w, cover_h = lens.covering_pinhole(K, width, height)
        visible = visible_points(geometry, points, normals, part_index, world_from_camera, cover, cover_w, cover_h,
                                 limits, stats, ray_per_point)
        rows = np.flatnonzero(visible)
        uv, _ = lens.project(K, world_to_camera(np.asarray(points)[rows], world_from_camera))
        visible[rows[~((uv[:, 0] >= 0) & (uv[:, 0] < width) & (uv[:, 1] >= 0) & (uv[:, 1] < height))]] = False
        return visible
    points = np.asarray(points)
    n = len(points)
    r, centre = world_from_camera[:3, :3], world_from_camera[:3, 3]
    if part_index is not None and not ray_per_point and n:
        blocks = PointBlocks.for_points(geometry, points, normals, part_index)
        return blocks.visible(geometry, r, centre, K, width, height, limits, stats)

    px, py, pz = (points[:, k] for k in range(3))
    ok = in_view(px - centre[0], py - centre[1], pz - centre[2], r, K, width, height, limits)
    idx = np.flatnonzero(ok)
    count_in_view = len(idx)
    dx, dy, dz = px[idx] - centre[0], py[idx] - centre[1], pz[idx] - centre[2]
    culled = 0
    if normals is not None and part_index is not None and len(idx):
        cullable_part = cullable_parts(geometry, centre)
        if cullable_part.any():
            nx, ny, nz = (normals[idx, k] for k in range(3))
            drop = cullable_part[part_index[idx]] & facing_away(nx, ny, nz, dx, dy, dz)
            culled = int(drop.sum())
            keep = np.flatnonzero(~drop)
            idx, dx, dy, dz = idx[keep], dx[keep], dy[keep], dz[keep]
    if len(idx) > 1 and not ray_per_point:
        order = _tile_order(dx, dy, dz, r, K, width)
        idx, dx, dy, dz = idx[order], dx[order], dy[order], dz[order]
    blocked = segments_blocked(geometry, centre, dx, dy, dz)
    mask = np.zeros(n, dtype=bool)
    mask[idx[~blocked]] = True
    if stats is not None:
        stats.tested, stats.in_view, stats.culled_backfacing = n, count_in_view, culled
        stats.tested_one_by_one = n
        stats.rays, stats.visible = len(idx), int(mask.sum())
    return mask


def _tile_order(dx: np.ndarray, dy: np.ndarray, dz: np.ndarray, r: np.ndarray, K: np.ndarray,
                width: int) -> np.ndarray:
    """Order (M,) of points in view (offsets from the camera centre) by screen tile (TILE x
    TILE pixels, row by row); a stable radix sort on small integer keys."""
    z = dx * r[0, 2] + dy * r[1, 2] + dz * r[2, 2]
    x = dx * r[0, 0] + dy * r[1, 0] + dz * r[2, 0]
    y = dx * r[0, 1] + dy * r[1, 1] + dz * r[2, 1]
    px = (K[0, 0] * x + K[0, 1] * y) / z + K[0, 2]
    py = K[1, 1] * y / z + K[1, 2]
    cols = int(width) // TILE + 1
    key = np.clip((py * (1.0 / TILE)).astype(np.int32), 0, None) * cols + np.clip(
        (px * (1.0 / TILE)).astype(np.int32), 0, cols - 1)
    if key.max(initial=0) < np.iinfo(np.int16).max:
        key = key.astype(np.int16)
    return np.argsort(key, kind="stable")

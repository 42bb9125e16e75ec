"""The visibility rules point by point (see :mod:`.visibility` for the rules themselves).

Every path that decides visibility, the fast one (:mod:`.point_blocks`) and the reference
(:func:`.visibility.visible_points` with ``ray_per_point``), evaluates each rule with these
functions, so both give the same bits. Points are handed as offsets (dx, dy, dz) from the
camera centre along the world axes, one array per axis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .raycast import OCCLUSION_TOL_ABS, OCCLUSION_TOL_REL, SceneGeometry


@dataclass(frozen=True)
class ViewLimits:
    """Depth limits in metres (planar z): visible points have near < z <= far."""

    near: float = 0.0
    far: float = np.inf


@dataclass
class VisibilityStats:
    """Counts from the last call, to understand where the time goes: points in all
    (``tested``), passing rules 1-2 (``in_view``), then hidden by rule 3 without a ray
    (``culled_backfacing``), occlusion rays cast (``rays``; answers reused from the same
    camera centre are not counted) and visible points; ``tested_one_by_one``: points
    whose rules 1-3 were tested point by point (with point groups, those of the groups that
    their box and normal cone did not settle; without, all)."""

    tested: int = 0
    in_view: int = 0
    culled_backfacing: int = 0
    rays: int = 0
    visible: int = 0
    tested_one_by_one: int = 0


def view_planes(r: np.ndarray, K: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The rows (world axes) of planar depth z, u = pixel x * z and v = pixel y * z as linear
    functions of the offset from the camera centre: each (3,)."""
    a_z = r[:, 2]
    a_u = K[0, 0] * r[:, 0] + K[0, 1] * r[:, 1] + K[0, 2] * r[:, 2]
    a_v = K[1, 1] * r[:, 1] + K[1, 2] * r[:, 2]
    return a_z, a_u, a_v


def in_view(dx: np.ndarray, dy: np.ndarray, dz: np.ndarray, r: np.ndarray, K: np.ndarray, width: int, height: int,
            limits: ViewLimits) -> np.ndarray:
    """Rules 1 and 2 (M,) bool: 0 <= u < width z, 0 <= v < height z, near < z <= far
    (pixel coordinates times z: no division)."""
    a_z, a_u, a_v = view_planes(r, K, width, height)
    z = dx * a_z[0] + dy * a_z[1] + dz * a_z[2]
    ok = (z > limits.near) & (z <= limits.far)
    u = dx * a_u[0] + dy * a_u[1] + dz * a_u[2]
    ok &= (u >= 0) & (u < width * z)
    v = dx * a_v[0] + dy * a_v[1] + dz * a_v[2]
    ok &= (v >= 0) & (v < height * z)
    return ok


def facing_away(nx: np.ndarray, ny: np.ndarray, nz: np.ndarray, dx: np.ndarray, dy: np.ndarray,
                dz: np.ndarray) -> np.ndarray:
    """Rule 3's test (M,) bool: n . (p - c) > 0 (the camera is behind the point's surface)."""
    return nx * dx + ny * dy + nz * dz > 0


def cullable_parts(geometry: SceneGeometry, centre: np.ndarray) -> np.ndarray:
    """(P,) bool: the parts rule 3 applies to from ``centre``: solids whose bounding box
    leaves the camera out."""
    bounds = geometry.world_bounds()
    return geometry.closed & np.any((centre < bounds[:, 0]) | (centre > bounds[:, 1]), axis=1)


def segments_blocked(geometry: SceneGeometry, centre: np.ndarray, dx: np.ndarray, dy: np.ndarray,
                     dz: np.ndarray) -> np.ndarray:
    """Rule 4 (M,) bool: the segment from the camera centre toward each point, cut ``tol``
    before it, hits a triangle (a point closer than ``tol`` is never hidden)."""
    rays, empty = occlusion_rays(centre, dx, dy, dz)
    blocked = geometry.rays_blocked(rays)
    blocked[empty] = False
    return blocked


def occlusion_rays(centre: np.ndarray, dx: np.ndarray, dy: np.ndarray, dz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rule 4's segments as float32 rays (M, 6) for ``SceneGeometry.rays_blocked``: from the
    camera centre toward the points, cut ``tol = OCCLUSION_TOL_ABS + OCCLUSION_TOL_REL * d``
    before them (the direction scaled so that the segment ends at t = 1); and the indices
    of the empty segments (points closer than ``tol``)."""
    dist = np.sqrt(dx * dx + dy * dy + dz * dz)
    with np.errstate(divide="ignore", invalid="ignore"):
        keep = 1.0 - (OCCLUSION_TOL_ABS + OCCLUSION_TOL_REL * dist) / dist
    keep = np.maximum(keep, 0.0, out=keep)  # also turns NaN (a point at the centre) into 0
    rays = np.empty((len(dx), 6), dtype=np.float32)
    for k in range(3):  # column by column: ~4x faster than rays[:, :3] = centre
        rays[:, k] = centre[k]
    np.multiply(dx, keep, out=rays[:, 3], casting="same_kind")
    np.multiply(dy, keep, out=rays[:, 4], casting="same_kind")
    np.multiply(dz, keep, out=rays[:, 5], casting="same_kind")
    return rays, np.flatnonzero(keep == 0)

"""Boxes of rigid parts, bpy-free: oriented 3D boxes and 2D image boxes.

- :func:`upright_box`: the box of a point set whose third axis is the frame's Z axis and
  whose footprint is the minimum-area rectangle around the points' projection on the XY
  plane (site objects stand upright, so in the world frame this is the tightest upright
  box; its yaw is that of a hull edge, a standard property of minimum-area rectangles).
- :meth:`Box3D.transformed`: the same box carried by an object's world_from_object matrix;
  :func:`moved_box`: a moving part's box at its matrix (refitted under a non-uniform scale).
- :func:`amodal_box`: the 2D box of a whole triangle mesh projected into the image, clipped
  to the image (what the object would cover if nothing occluded it).
- :func:`mask_box`: the tight box of a pixel mask.

2D boxes are (x0, y0, x1, y1) in pixels, with the image's top-left corner at (0, 0) and the
top-left pixel's centre at (0.5, 0.5) (docs/conventions.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .camera import apply_affine, matmul_exact, orthogonal_factor, rows_times, world_to_camera
from .portable_math import vector_norm

NEAR = 1e-6  # metres: geometry at planar depth below this is treated as behind the camera
# relative spread of an object matrix's axis lengths below which its scale counts as uniform:
# Blender stores matrices in float32 (axis lengths of a pure rotation differ by ~1e-7), and
# a box carried under a spread of 1e-6 is off by at most a millionth of its size
UNIFORM = 1e-6


@dataclass(frozen=True)
class Box3D:
    """An oriented box: ``centre`` (3,) metres, ``size`` (3,) metres (full edge lengths along
    the box's own axes), ``rotation`` (3, 3) whose columns are the box axes in the outer frame
    (outer_from_box). A point p is inside when ``|rotation.T @ (p - centre)| <= size / 2``."""

    centre: np.ndarray
    size: np.ndarray
    rotation: np.ndarray

    def corners(self) -> np.ndarray:
        """(8, 3) corners; corner k lies at -size/2 or +size/2 along the box's x, y, z axes
        as bits 2, 1, 0 of k are 0 or 1."""
        signs = np.array([[(k >> 2) & 1, (k >> 1) & 1, k & 1] for k in range(8)], float) * 2 - 1
        return self.centre + rows_times(signs * (self.size / 2), self.rotation.T)

    def contains(self, points: np.ndarray, tolerance: float = 1e-6) -> np.ndarray:
        """(n,) bool: the points lie in the box, within ``tolerance`` metres."""
        local = rows_times(np.asarray(points, float) - self.centre, self.rotation)
        return np.all(np.abs(local) <= self.size / 2 + tolerance, axis=1)

    def transformed(self, matrix: np.ndarray) -> "Box3D":
        """The box in the frame ``matrix`` maps to (e.g. world_from_object). Scale in the
        matrix is folded into ``size``; the matrix must not shear (rigid times axis scale).
        BLAS- and LAPACK-free: the same bits on every CPU (docs/guarantees.md)."""
        m = np.asarray(matrix, float)
        axes = matmul_exact(m[:3, :3], self.rotation)
        lengths = vector_norm(axes.T)
        rotation = orthogonal_factor(axes / np.where(lengths > 0, lengths, 1.0))  # exact when m does not shear
        return Box3D(apply_affine(m, self.centre), self.size * lengths, rotation)


def moved_box(local: Box3D, vertices: np.ndarray, matrix: np.ndarray) -> Box3D:
    """The box of a moving part at ``matrix`` (world_from_object: rigid times axis scale)
    whose box in the object frame is ``local`` (:func:`upright_box` of ``vertices``, object
    frame). Under a uniform scale that box carried by the matrix; under a non-uniform one a
    box turned in the object frame would come out sheared, so the box is fitted again to the
    scaled vertices and carried by the rigid part alone."""
    m = np.asarray(matrix, float)
    scale = vector_norm(m[:3, :3].T)  # the length of each object axis in the world
    if scale.max() - scale.min() <= UNIFORM * scale.max():
        return local.transformed(m)
    rigid = m.copy()
    rigid[:3, :3] = m[:3, :3] / np.where(scale > 0, scale, 1.0)
    return upright_box(np.asarray(vertices, float) * scale).transformed(rigid)


def upright_box(points: np.ndarray) -> Box3D:
    """The upright box of ``points`` (n, 3) with the minimum footprint area (see the module
    docstring). Its x axis has a yaw in [0, 90) degrees; an empty set gives a zero box."""
    p = np.asarray(points, float)
    if len(p) == 0:
        return Box3D(np.zeros(3), np.zeros(3), np.eye(3))
    xy = _hull_2d(p[:, :2])
    c, s = _min_area_axis(xy)
    x, y = xy[:, 0], xy[:, 1]
    local = np.column_stack([x * c + y * s, y * c - x * s])  # coordinates along the box axes
    lo, hi = local.min(axis=0), local.max(axis=0)
    z0, z1 = p[:, 2].min(), p[:, 2].max()
    mid = (lo + hi) / 2
    centre = np.array([mid[0] * c - mid[1] * s, mid[0] * s + mid[1] * c, (z0 + z1) / 2])
    rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return Box3D(centre, np.append(hi - lo, z1 - z0), rotation)


def _hull_2d(xy: np.ndarray) -> np.ndarray:
    """Vertices of the convex hull of 2D points (Qhull; the distinct points themselves when
    they are too few or collinear, which gives the same rectangles)."""
    from scipy.spatial import ConvexHull, QhullError

    if len(xy) >= 3:
        try:
            return xy[ConvexHull(xy).vertices]
        except QhullError:  # collinear or repeated points: keep the distinct ones
            pass
    return np.unique(xy, axis=0)


def _min_area_axis(hull: np.ndarray) -> tuple[float, float]:
    """(cos, sin) of the yaw in [0, pi/2) of the minimum-area rectangle around a convex
    polygon: one of its sides lies along a hull edge, so only the edge directions are tried
    (ties: smallest yaw). Each edge is turned by quarter turns (exact) into the first quadrant
    and normalised: no trigonometry and no BLAS, so the same bits on every CPU."""
    edges = np.roll(hull, -1, axis=0) - hull
    ex, ey = edges[:, 0], edges[:, 1]
    keep = (ex != 0) | (ey != 0)
    ex, ey = ex[keep], ey[keep]
    if len(ex) == 0:
        return 1.0, 0.0
    # quarter turns: (x, y) -> (y, -x) when x <= 0 < y; (-x, -y) when x < 0, y <= 0; (-y, x) when y < 0 <= x
    q1, q2, q3 = (ex <= 0) & (ey > 0), (ex < 0) & (ey <= 0), (ex >= 0) & (ey < 0)
    fx = np.select([q1, q2, q3], [ey, -ex, -ey], ex)
    fy = np.select([q1, q2, q3], [-ex, -ey, ex], ey)
    length = vector_norm(np.column_stack([fx, fy]))
    c, s = fx / length, fy / length
    order = np.lexsort((-c, s))  # by yaw: sin grows with it on [0, pi/2)
    c, s = c[order], s[order]
    x, y = hull[:, 0, None], hull[:, 1, None]
    u, v = x * c + y * s, y * c - x * s  # (n, a): coordinates along each candidate's axes
    area = (u.max(0) - u.min(0)) * (v.max(0) - v.min(0))
    best = np.flatnonzero(area <= area.min() * (1 + 1e-12) + 1e-18)[0]
    return float(c[best]), float(s[best])


def part_world_matrices(parts: list, dynamic_objects: list[str], object_matrices: np.ndarray) -> list[np.ndarray]:
    """world_from_part (4, 4) of every part at one frame: the identity for static parts (their
    vertices are in world coordinates), ``object_matrices[k]`` for ``dynamic_objects[k]``."""
    index = {name: k for k, name in enumerate(dynamic_objects)}
    eye = np.eye(4)
    return [np.asarray(object_matrices[index[p.name]], float) if p.dynamic else eye for p in parts]


# ---- 2D boxes --------------------------------------------------------------------------------

def mask_box(mask: np.ndarray) -> tuple[int, int, int, int] | None:
    """Tight box (x0, y0, x1, y1) of a boolean (H, W) mask, pixel edges (x1, y1 exclusive:
    the pixels x0 <= col < x1, y0 <= row < y1); None for an empty mask."""
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if len(rows) == 0:
        return None
    return int(cols[0]), int(rows[0]), int(cols[-1]) + 1, int(rows[-1]) + 1


def used_vertices(faces: np.ndarray) -> np.ndarray:
    """Sorted ids of the vertices that some triangle uses (for :func:`amodal_box`)."""
    faces = np.asarray(faces, np.int64)
    used = np.zeros(int(faces.max(initial=-1)) + 1, bool)
    used[faces.ravel()] = True
    return np.flatnonzero(used)


def tight_boxes(ids_map: np.ndarray, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tight boxes (n, 4) (x0, y0, x1, y1) float64, pixel edges as :func:`mask_box`, and pixel
    counts (n,) of ``ids_map == ids[k]`` for every k, in one pass over the (H, W) map; an id
    with no pixel gets count 0 and the box (0, 0, 0, 0)."""
    ids = np.asarray(ids)
    n = len(ids)
    if n == 0:
        return np.zeros((0, 4)), np.zeros(0, np.int64)
    order = np.argsort(ids, kind="stable")
    sorted_ids, flat = ids[order], ids_map.ravel()
    pos = np.minimum(np.searchsorted(sorted_ids, flat), n - 1)
    hit = sorted_ids[pos] == flat
    k = order[pos[hit]]
    pix = np.flatnonzero(hit)
    rows, cols = pix // ids_map.shape[1], pix % ids_map.shape[1]
    x0, y0 = np.full(n, np.iinfo(np.int64).max), np.full(n, np.iinfo(np.int64).max)
    x1, y1 = np.full(n, -1), np.full(n, -1)
    np.minimum.at(x0, k, cols)
    np.minimum.at(y0, k, rows)
    np.maximum.at(x1, k, cols)
    np.maximum.at(y1, k, rows)
    counts = np.bincount(k, minlength=n)
    boxes = np.column_stack([x0, y0, x1 + 1, y1 + 1]).astype(np.float64)
    boxes[counts == 0] = 0.0
    return boxes, counts


def amodal_box(vertices: np.ndarray, faces: np.ndarray, world_from_camera: np.ndarray, K: np.ndarray,
               width: int, height: int, used: np.ndarray | None = None,
               near: float = NEAR) -> tuple[float, float, float, float] | None:
    """Box (x0, y0, x1, y1) pixels of the projection of the triangles (world ``vertices``
    (V, 3), ``faces`` (F, 3)) clipped to the view: the part of each triangle in front of
    the camera (planar depth >= ``near`` metres, at least :data:`NEAR`; e.g. the camera's
    clip start) and inside the image; there is no far limit. Exact: the clipped
    polygons' corners are the triangle vertices inside the view, the crossings of triangle
    edges with the view's five bounding planes, the crossings of the triangles' cuts by the
    near plane with the image border, and the image corners a triangle covers.
    None when no triangle reaches the view. Occlusion is ignored (amodal). ``used``:
    :func:`used_vertices` of ``faces``, when the caller keeps it between calls. Only the
    triangles that straddle a plane of the view are clipped (vertex outcodes pick them)."""
    faces = np.asarray(faces, np.int64)
    if len(faces) == 0:
        return None
    near = max(float(near), NEAR)
    used = used_vertices(faces) if used is None else used
    pc = world_to_camera(np.asarray(vertices, float), world_from_camera)
    h = rows_times(pc, np.asarray(K, float).T)  # (u z, v z, z): the view is 0 <= u <= W, 0 <= v <= H, z >= near
    planes = np.stack([h[:, 0], width * h[:, 2] - h[:, 0], h[:, 1], height * h[:, 2] - h[:, 1], h[:, 2] - near], 1)
    codes = (planes < 0).astype(np.uint8) @ np.array([1, 2, 4, 8, 16], np.uint8)  # the view planes each vertex is beyond
    inside = used[codes[used] == 0]
    if len(inside) == len(used):  # the whole mesh in view (the usual case): the box of its vertices
        return _box(h[inside, :2] / h[inside, 2:3], width, height)
    fc = codes[faces]
    straddle = faces[((fc[:, 0] | fc[:, 1] | fc[:, 2]) != 0) & ((fc[:, 0] & fc[:, 1] & fc[:, 2]) == 0)]
    # faces wholly in view add only their vertices; faces wholly beyond one plane add nothing
    found = [h[inside, :2] / h[inside, 2:3]]
    if len(straddle):
        edges = straddle[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
        ga, gb = planes[edges[:, 0]], planes[edges[:, 1]]
        for k in range(5):
            cross = np.flatnonzero((ga[:, k] < 0) != (gb[:, k] < 0))
            if len(cross):
                t = (ga[cross, k] / (ga[cross, k] - gb[cross, k]))[:, None]
                hp = h[edges[cross, 0]] + t * (h[edges[cross, 1]] - h[edges[cross, 0]])
                gp = ga[cross] + t * (gb[cross] - ga[cross])
                gp[:, k] = 0.0
                found.append(_inside(hp, gp))
        gf = planes[straddle]  # (n, 3, 5): the planes' values at each triangle's vertices
        lo, hi = gf.min(axis=1), gf.max(axis=1)
        cut = straddle[(lo[:, 4] < 0) & (hi[:, 4] >= 0)]
        if len(cut):
            found.append(_near_crossings(pc, cut, K, width, height, near))
        found.append(_covered_corners(pc, straddle, lo, hi, K, width, height, near))
    xy = np.concatenate(found)
    return _box(xy, width, height) if len(xy) else None


def _box(xy: np.ndarray, width: int, height: int) -> tuple[float, float, float, float]:
    x0, y0 = np.clip(xy.min(axis=0), 0, [width, height])
    x1, y1 = np.clip(xy.max(axis=0), 0, [width, height])
    return float(x0), float(y0), float(x1), float(y1)


def _inside(h: np.ndarray, g: np.ndarray, tolerance: float = 1e-9) -> np.ndarray:
    """Image positions (n, 2) of the homogeneous points inside every plane of the view."""
    scale = np.maximum(np.abs(h[:, 2:3]), 1.0)
    keep = np.all(g >= -tolerance * scale, axis=1) & (h[:, 2] > 0)
    return h[keep, :2] / h[keep, 2:3]


def _near_crossings(pc: np.ndarray, faces: np.ndarray, K: np.ndarray, width: int, height: int, near: float) -> np.ndarray:
    """Where the segments cutting triangles at the near plane (depth ``near``) cross the image
    border (Liang-Barsky clipping of each projected segment to the image rectangle)."""
    g = pc[:, 2] - near
    ends = []
    for i, j in ((0, 1), (1, 2), (2, 0)):
        a, b = faces[:, i], faces[:, j]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = g[a] / (g[a] - g[b])
        crossing = (g[a] < 0) != (g[b] < 0)
        ends.append((crossing, pc[a] + np.where(crossing, t, 0.0)[:, None] * (pc[b] - pc[a])))
    flags = np.stack([e[0] for e in ends], 1)
    cut = np.flatnonzero(flags.sum(axis=1) == 2)
    if len(cut) == 0:
        return np.zeros((0, 2))
    points = np.stack([e[1] for e in ends], 1)[cut]                      # (n, 3 edges, 3)
    order = np.argsort(~flags[cut], axis=1, kind="stable")[:, :2]        # the two crossing edges
    p0 = points[np.arange(len(cut)), order[:, 0]]
    p1 = points[np.arange(len(cut)), order[:, 1]]
    K = np.asarray(K, float)
    q0 = rows_times(p0, K.T)[:, :2] / near
    q1 = rows_times(p1, K.T)[:, :2] / near
    d = q1 - q0
    lo, hi = np.zeros(len(cut)), np.ones(len(cut))
    for axis, limit in ((0, width), (1, height)):
        for p, q in ((-d[:, axis], q0[:, axis]), (d[:, axis], limit - q0[:, axis])):
            with np.errstate(divide="ignore", invalid="ignore"):
                r = q / p
            lo = np.where(p < 0, np.maximum(lo, r), lo)
            hi = np.where(p > 0, np.minimum(hi, r), hi)
            lo = np.where((p == 0) & (q < 0), 2.0, lo)  # parallel to this border and outside it
    keep = lo <= hi
    segs = np.concatenate([q0[keep] + lo[keep, None] * d[keep], q0[keep] + hi[keep, None] * d[keep]])
    return np.clip(segs, 0, [width, height])


def _covered_corners(pc: np.ndarray, faces: np.ndarray, lo: np.ndarray, hi: np.ndarray, K: np.ndarray, width: int,
                     height: int, near: float) -> np.ndarray:
    """The image corners whose viewing ray meets a triangle at depth >= near. Only triangles
    straddling both view planes through a corner (``lo``/``hi``: per-triangle minimum and
    maximum of the plane values) can meet its ray."""
    corners = np.array([[0.0, 0.0], [width, 0.0], [0.0, height], [width, height]])
    K = np.asarray(K, float)
    out = []
    for corner, (i, j) in zip(corners, ((0, 2), (1, 2), (0, 3), (1, 3))):
        sel = (lo[:, i] <= 0) & (hi[:, i] >= 0) & (lo[:, j] <= 0) & (hi[:, j] >= 0) & (hi[:, 4] >= 0)
        if not sel.any():
            continue
        f = faces[sel]
        a, b, c = pc[f[:, 0]], pc[f[:, 1]], pc[f[:, 2]]
        e1, e2 = b - a, c - a
        y = (corner[1] - K[1, 2]) / K[1, 1]  # K^-1 (u, v, 1) by back-substitution: no LAPACK
        d = np.array([(corner[0] - K[0, 1] * y - K[0, 2]) / K[0, 0], y, 1.0])
        # Moller-Trumbore from the camera centre (origin of the camera frame)
        p = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, p)
        ok = np.abs(det) > 1e-15
        inv = np.divide(1.0, det, out=np.zeros_like(det), where=ok)
        s = -a
        u = np.einsum("ij,ij->i", s, p) * inv
        q = np.cross(s, e1)
        v = np.einsum("ij,j->i", q, d) * inv
        t = np.einsum("ij,ij->i", e2, q) * inv
        if np.any(ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t * d[2] >= near)):
            out.append(corner)
    return np.array(out).reshape(-1, 2)

"""Surface points grouped into small spatial groups, so that most visibility decisions of
rules 1-3 (:mod:`.visibility`) are taken per group, and rays are cast in a coherent order.

Points are sorted part by part, then by the direction of their normal (96 cells), then in
Morton (z-curve) order of their coordinates. Consecutive runs of at most SUB points of one
part are the *groups* (each with an axis-aligned box and the cone of its normals); runs
of BLOCK / SUB groups of one part are the *blocks* (with the box of their groups), used
only to cull the groups of blocks that are wholly outside the view. A decision is taken
for a whole group or block only with a margin far above the round-off of the per-point
test, so the answer is the same as testing every point (tests/test_visibility.py).
"""

from __future__ import annotations

import numpy as np

from . import point_block_kernels as kernels
from .point_block_kernels import MARGIN
from .raycast import SceneGeometry
from .visibility_rules import ViewLimits, VisibilityStats, cullable_parts, view_planes

# Points per group (the unit of the rule 1-3 decisions) and per block (of whole groups:
# the unit of the first cull).
SUB = 16
BLOCK = 128

# without normals: no part for rule 3, no cones
_NO_PARTS = np.zeros(0, dtype=bool)
_NO_CONE = (np.zeros((3, 0)), np.zeros(0), np.zeros((3, 0)))


class PointBlocks:
    """The groups and blocks of one point set (see the module docstring), with per-call
    answers of rule 4 kept while the camera centre and the geometry stay.

    Built once per (points, part_index) pair; when the caller hands a new ``points`` array
    with the same ``part_index`` (dynamic parts moved), the coordinates in group order, the
    boxes and the cones are recomputed.
    """

    def __init__(self, points: np.ndarray, normals: np.ndarray | None, part_index: np.ndarray):
        part = np.asarray(part_index, dtype=np.int64)
        lo, hi = points.min(axis=0), points.max(axis=0)
        scale = 1023.0 / max(float(np.max(hi - lo)), 1e-9)
        q = ((points - lo) * scale).astype(np.int64)
        key = spread_bits(q[:, 0]) | (spread_bits(q[:, 1]) << 1) | (spread_bits(q[:, 2]) << 2)
        # normals first: groups on flat faces are planar (one normal: rule 3 per group)
        self.by_normal = normals is not None
        self.order = np.lexsort((key, direction_cell(normals), part) if self.by_normal else (key, part))
        sorted_part = part[self.order]
        self.part_index = part_index
        # groups: start where the part changes or every SUB points within a part
        self.start, self.size = _runs(sorted_part, SUB)
        self.group_part = sorted_part[self.start]
        # blocks: every BLOCK // SUB groups of one part
        self.block_first, self.block_groups = _runs(self.group_part, BLOCK // SUB)
        self.points = self.normals = None
        self._answers, self._answers_key, self._known = None, None, 0
        self._rays = self._pos = None  # buffers of select_rays, made at the first call
        self.set_points(points, normals)

    @classmethod
    def for_points(cls, geometry: SceneGeometry, points: np.ndarray, normals: np.ndarray | None,
                   part_index: np.ndarray) -> "PointBlocks":
        """The groups of these arrays, from ``geometry.point_blocks`` when they match."""
        blocks = geometry.point_blocks
        if (not isinstance(blocks, cls) or blocks.part_index is not part_index or len(blocks.order) != len(points)
                or blocks.by_normal != (normals is not None)):
            blocks = geometry.point_blocks = cls(points, normals, part_index)
        if blocks.points is not points or blocks.normals is not normals:
            blocks.set_points(points, normals)
        return blocks

    def set_points(self, points: np.ndarray, normals: np.ndarray | None) -> None:
        """Take new coordinates and normals of the same points (dynamic parts moved):
        copies in group order, one contiguous array per axis (gathers read contiguous
        memory), the boxes and the normal cones."""
        self.xyz = np.ascontiguousarray(points[self.order].T)  # (3, N)
        lo = np.minimum.reduceat(self.xyz, self.start, axis=1).T  # (groups, 3)
        hi = np.maximum.reduceat(self.xyz, self.start, axis=1).T
        self.group_box = _Boxes(lo, hi)
        self.block_box = _Boxes(np.minimum.reduceat(lo, self.block_first), np.maximum.reduceat(hi, self.block_first))
        if normals is None:
            self.nxyz = self.cone_axis = self.cone_spread = None
        else:
            self.nxyz = np.ascontiguousarray(normals[self.order].T)  # (3, N)
            first = self.nxyz[:, self.start]
            gap = self.nxyz - np.repeat(first, self.size, axis=1)
            spread = np.maximum.reduceat(np.sqrt(np.einsum("ij,ij->j", gap, gap)), self.start)
            self.cone_axis = np.ascontiguousarray(first)  # (3, groups)
            self.cone_spread = spread * (1 + 1e-9) + 1e-12  # covers its own round-off
        self.points, self.normals = points, normals
        self._answers_key = None

    def visible(self, geometry: SceneGeometry, r: np.ndarray, centre: np.ndarray, K: np.ndarray, width: int,
                height: int, limits: ViewLimits, stats: VisibilityStats | None = None) -> np.ndarray:
        """Visibility mask (N,) in the caller's point order (see :func:`.visibility.visible_points`)."""
        n = len(self.order)
        centre = np.ascontiguousarray(centre, dtype=np.float64)
        view = _View(r, centre, K, width, height, limits)
        cullable = cullable_parts(geometry, centre) if self.nxyz is not None else _NO_PARTS
        # rules 3 and 4 depend on the camera centre, not on its orientation: ray answers
        # found earlier from this centre (same geometry state) are reused
        answers = self._answers_for(centre, geometry.version)
        mask = np.zeros(n, dtype=bool)
        counts = np.zeros(4, dtype=np.int64)
        if self._rays is None:
            self._rays, self._pos = np.empty((n, 6), dtype=np.float32), np.empty(n, dtype=np.int64)
        group, block, cone = self.group_box, self.block_box, self._cone()
        m = kernels.select_rays(
            self.block_first, self.block_groups, block.centre, block.half, block.extent,
            self.start, self.size, self.group_part, group.centre, group.half, group.extent, group.radius,
            cone[0], cone[1], self.xyz, cone[2], self.order, cullable,
            view.a, view.b, view.slack, centre, *view.rows, float(limits.near), float(limits.far), int(width),
            int(height), answers, self._known > 0, mask, self._pos, self._rays, counts)
        pos = self._pos[:m]
        kernels.store_answers(geometry.rays_blocked(self._rays[:m]), pos, self.order, answers, mask)
        self._known += m + int(counts[kernels.SETTLED])
        if stats is not None:
            stats.tested, stats.in_view, stats.culled_backfacing = n, int(counts[kernels.IN_VIEW]), int(
                counts[kernels.CULLED])
            stats.tested_one_by_one = int(counts[kernels.ONE_BY_ONE])
            stats.rays, stats.visible = m, int(np.count_nonzero(mask))
        return mask

    def _cone(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(cone axes (3, groups), spreads (groups,), normals (3, N)); empty without normals."""
        if self.nxyz is None:
            return _NO_CONE
        return self.cone_axis, self.cone_spread, self.nxyz

    def _answers_for(self, centre: np.ndarray, version: int) -> np.ndarray:
        """Per position in group order, rule 4 from ``centre`` as found so far (0 unknown,
        1 visible, 2 hidden); forgotten when the centre, the geometry's state
        (``version``), the points or their normals change."""
        key = (tuple(np.asarray(centre, np.float64).tolist()), version)
        if key != self._answers_key:
            self._answers = np.zeros(len(self.order), dtype=np.int8)
            self._answers_key, self._known = key, 0
        return self._answers


class _Boxes:
    """Axis-aligned boxes from their corners (M, 3), stored axis by axis (3, M): centre,
    half extents, the largest |coordinate| per axis (for margins) and the radius."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray):
        self.centre = np.ascontiguousarray(((lo + hi) / 2).T)
        self.half = np.ascontiguousarray(((hi - lo) / 2).T)
        self.extent = np.abs(self.centre) + self.half
        self.radius = np.sqrt((self.half * self.half).sum(axis=0))


class _View:
    """The view's half-spaces a . p + b >= 0 over world points p (rules 1 and 2)."""

    def __init__(self, r: np.ndarray, c: np.ndarray, K: np.ndarray, width: int, height: int, limits: ViewLimits):
        a_z, a_u, a_v = view_planes(r, K, width, height)
        planes = [a_z, a_u, width * a_z - a_u, a_v, height * a_z - a_v]
        offsets = [-limits.near, 0.0, 0.0, 0.0, 0.0]
        if np.isfinite(limits.far):
            planes.append(-a_z)
            offsets.append(limits.far)
        self.a = np.array(planes)  # (planes, 3)
        self.abs_a = np.abs(self.a)
        self.b = np.array(offsets) - self.a @ c
        self.slack = MARGIN * (self.abs_a @ np.abs(c) + np.abs(offsets))
        self.rows = (a_z, a_u, a_v)  # of the per-point test (visibility_rules.in_view)


def _runs(keys: np.ndarray, length: int) -> tuple[np.ndarray, np.ndarray]:
    """Starts and lengths of runs of equal ``keys`` cut every ``length`` items."""
    n = len(keys)
    key_start = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
    offset = np.arange(n) - np.repeat(key_start, np.diff(np.r_[key_start, n]))
    starts = np.flatnonzero(offset % length == 0)
    return starts, np.diff(np.r_[starts, n])


def direction_cell(normals: np.ndarray) -> np.ndarray:
    """(N,) int: which of 96 direction cells each normal falls in (the cube face of its
    largest coordinate, then a 4 x 4 grid on that face); zero normals share one cell."""
    v = np.asarray(normals, dtype=np.float64)
    axis = np.argmax(np.abs(v), axis=1)
    rows = np.arange(len(v))
    major = v[rows, axis]
    face = axis * 2 + (major < 0)
    scale = np.divide(1.0, np.abs(major), out=np.zeros(len(v)), where=major != 0)
    cell = [np.clip(((v[rows, (axis + k) % 3] * scale + 1) * 2).astype(np.int64), 0, 3) for k in (1, 2)]
    return face * 16 + cell[0] * 4 + cell[1]


def spread_bits(v: np.ndarray) -> np.ndarray:
    """Spread the low 10 bits of v so that two zero bits separate each (for Morton codes)."""
    v = v & 0x3FF
    v = (v | (v << 16)) & 0x030000FF
    v = (v | (v << 8)) & 0x0300F00F
    v = (v | (v << 4)) & 0x030C30C3
    v = (v | (v << 2)) & 0x09249249
    return v

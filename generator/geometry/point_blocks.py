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

from .raycast import SceneGeometry
from .visibility_rules import (
    ViewLimits,
    VisibilityStats,
    cullable_parts,
    facing_away,
    in_view,
    segments_blocked,
    view_planes,
)

# Points per group (the unit of the rule 1-3 decisions) and per block (of whole groups:
# the unit of the first cull).
SUB = 16
BLOCK = 128

# A group counts as wholly inside a half-space (or wholly facing one way) only if it is so
# by this share of the magnitudes involved: far above the round-off of the per-point tests
# (~1e-15 relative), so that skipping them never changes an answer.
MARGIN = 1e-9


class PointBlocks:
    """The groups and blocks of one point set (see the module docstring), with per-call
    answers of rule 4 kept while the camera centre and the geometry stay.

    Built once per (points, part_index) pair; when the caller hands a new ``points`` array
    with the same ``part_index`` (dynamic parts moved), the coordinates in group order, the
    boxes and the cones are recomputed.
    """

    def __init__(self, points: np.ndarray, normals: np.ndarray | None, part_index: np.ndarray):
        n = len(points)
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
        pos, counts = self._rules_1_to_3(geometry, r, centre, K, width, height, limits)
        # rules 3 and 4 depend on the camera centre, not on its orientation: ray answers
        # found earlier from this centre (same geometry state) are reused (1 visible, 2 hidden)
        answers = self._answers_for(centre, geometry.version)
        reused = pos[:0]
        if self._known:
            known = answers[pos]
            if known.any():
                reused = np.take(pos, np.flatnonzero(known == 1))
                pos = np.take(pos, np.flatnonzero(known == 0))
        blocked = segments_blocked(geometry, centre, *self._offsets(pos, centre))
        answers[pos] = np.where(blocked, np.int8(2), np.int8(1))
        self._known += len(pos)
        mask = np.zeros(n, dtype=bool)
        mask[np.take(self.order, np.take(pos, np.flatnonzero(~blocked)))] = True
        if len(reused):
            mask[np.take(self.order, reused)] = True
        if stats is not None:
            stats.tested, (stats.in_view, stats.culled_backfacing, stats.tested_one_by_one) = n, counts
            stats.rays, stats.visible = len(pos), int(np.count_nonzero(mask))
        return mask

    def _rules_1_to_3(self, geometry: SceneGeometry, r: np.ndarray, centre: np.ndarray, K: np.ndarray, width: int,
                      height: int, limits: ViewLimits) -> tuple[np.ndarray, tuple[int, int, int]]:
        """Positions (group order) of the points that pass rules 1-3, and the counts (in
        view, hidden by rule 3, tested one by one)."""
        groups, edge = self._groups_in_view(_View(r, centre, K, width, height, limits))
        away = mixed = None
        if self.nxyz is not None and len(groups):
            cullable = cullable_parts(geometry, centre)[self.group_part[groups]]
            if cullable.any():
                away, mixed = self._groups_facing_away(groups, centre)
                away &= cullable
                mixed &= cullable
        # clean groups (wholly in view, rule 3 settled as "facing the camera" or moot) need no
        # per-point test; groups wholly in view and on the back of a solid are only counted
        todo = edge if away is None else edge | away | mixed
        clean = np.take(groups, np.flatnonzero(~todo))
        pos_clean = positions(self.start[clean], self.size[clean])
        in_view_count = len(pos_clean)
        culled = 0
        if away is not None:
            settled = np.take(groups, np.flatnonzero(away & ~edge))
            culled = in_view_count_away = int(self.size[settled].sum())
            in_view_count += in_view_count_away
            todo &= ~(away & ~edge)
        which = np.flatnonzero(todo)
        if len(which) == 0:
            return pos_clean, (in_view_count, culled, 0)
        groups, edge = np.take(groups, which), np.take(edge, which)
        sizes = self.size[groups]
        pos = positions(self.start[groups], sizes)
        keep = np.ones(len(pos), dtype=bool)
        if edge.any():  # rules 1 and 2 point by point in the groups on the view's edges
            test = np.flatnonzero(np.repeat(edge, sizes))
            keep[test] = in_view(*self._offsets(np.take(pos, test), centre), r, K, width, height, limits)
        in_view_count += int(np.count_nonzero(keep))
        if away is not None:
            away, mixed = np.take(away, which), np.take(mixed, which)
            if away.any():  # on the view's edges, on the back of a solid
                back = np.repeat(away, sizes) & keep
                culled += int(np.count_nonzero(back))
                keep &= ~back
            if mixed.any():  # rule 3 point by point
                test = np.flatnonzero(np.repeat(mixed, sizes) & keep)
                p = np.take(pos, test)
                back = facing_away(*(np.take(self.nxyz[k], p) for k in range(3)), *self._offsets(p, centre))
                culled += int(np.count_nonzero(back))
                keep[test] = ~back
        counts = (in_view_count, culled, len(pos))
        return np.concatenate([pos_clean, np.take(pos, np.flatnonzero(keep))]), counts

    def _offsets(self, pos: np.ndarray, centre: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The points at ``pos`` (group order) minus the camera centre, axis by axis."""
        return tuple(np.take(self.xyz[k], pos) - centre[k] for k in range(3))

    def _answers_for(self, centre: np.ndarray, version: int) -> np.ndarray:
        """Per position in group order, rule 4 from ``centre`` as found so far (0 unknown,
        1 visible, 2 hidden); forgotten when the centre, the geometry's state
        (``version``), the points or their normals change."""
        key = (tuple(np.asarray(centre, np.float64).tolist()), version)
        if key != self._answers_key:
            self._answers = np.zeros(len(self.order), dtype=np.int8)
            self._answers_key, self._known = key, 0
        return self._answers

    def _groups_in_view(self, view: "_View") -> tuple[np.ndarray, np.ndarray]:
        """The groups whose box meets the view (rules 1 and 2), and for each whether it is
        on the view's edge (its points need the per-point test)."""
        blocks, block_edge = view.boxes(self.block_box)
        counts = self.block_groups[blocks]
        groups = positions(self.block_first[blocks], counts)
        edge = np.repeat(block_edge, counts)
        check = np.flatnonzero(edge)
        if len(check):  # the groups of the blocks on the view's edge, box by box
            meets, group_edge = view.boxes(self.group_box, groups[check], keep_all=True)
            edge[check] = group_edge
            if not meets.all():
                live = np.ones(len(groups), dtype=bool)
                live[check[~meets]] = False
                live = np.flatnonzero(live)
                groups, edge = groups[live], edge[live]
        return groups, edge

    def _groups_facing_away(self, groups: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For these groups: all their points face away from ``c`` (n . (p - c) > 0 for
        every point: rule 3 hides them if on a solid), or some may (mixed: test them one by
        one). From the box and the normal cone: n . (p - c) lies within
        m . (p - c) +- spread * |p - c| for the cone's axis m."""
        box = self.group_box
        axis = np.take(self.cone_axis, groups, axis=1)
        half = np.take(box.half, groups, axis=1)
        rel = np.take(box.centre, groups, axis=1) - c[:, None]
        mid = (axis * rel).sum(axis=0)
        reach = (np.abs(axis) * half).sum(axis=0)
        far = np.sqrt((rel * rel).sum(axis=0)) + box.radius[groups]
        slack = self.cone_spread[groups] * far + MARGIN * (far + np.abs(c).sum() + 1.0)
        away = mid - reach > slack
        toward = mid + reach < -slack
        return away, ~(away | toward)


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
        self.b = (np.array(offsets) - self.a @ c)[:, None]
        self.slack = (MARGIN * (self.abs_a @ np.abs(c) + np.abs(offsets)))[:, None]

    def boxes(self, boxes: _Boxes, which: np.ndarray | None = None, keep_all: bool = False):
        """For the boxes ``which`` (default: all): those meeting every half-space (their
        indices, or with ``keep_all`` a mask over ``which``) and whether each is on the
        view's edge (not inside every half-space by the margin)."""
        if which is None:
            which = np.arange(boxes.centre.shape[1])
            centre, half, extent = boxes.centre, boxes.half, boxes.extent
        else:
            centre, half, extent = (np.take(x, which, axis=1) for x in (boxes.centre, boxes.half, boxes.extent))
        mid = self.a @ centre + self.b  # (planes, M)
        spread = self.abs_a @ half
        margin = MARGIN * (self.abs_a @ extent) + self.slack
        # culled only if outside some half-space by the margin; inside only if inside all by it
        meets = np.logical_and.reduce(mid + spread >= -margin, axis=0)
        if not keep_all:
            live = np.flatnonzero(meets)
            which, mid, spread, margin = which[live], mid[:, live], spread[:, live], margin[:, live]
        edge = ~np.logical_and.reduce(mid - spread > margin, axis=0)
        return (meets if keep_all else which), edge


def _runs(keys: np.ndarray, length: int) -> tuple[np.ndarray, np.ndarray]:
    """Starts and lengths of runs of equal ``keys`` cut every ``length`` items."""
    n = len(keys)
    key_start = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
    offset = np.arange(n) - np.repeat(key_start, np.diff(np.r_[key_start, n]))
    starts = np.flatnonzero(offset % length == 0)
    return starts, np.diff(np.r_[starts, n])


def positions(starts: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """The ranges [start, start + size) concatenated."""
    total = int(sizes.sum())
    return np.arange(total) + np.repeat(starts - (np.cumsum(sizes) - sizes), sizes)


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

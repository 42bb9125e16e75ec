"""Ray casting and distance queries on a set of rigid mesh parts (open3d / Embree).

Static parts go into one acceleration structure built once; dynamic parts into a second
one rebuilt only when their matrices change (the paper's two BVH trees).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .camera import rows_times
from .parts import MeshPart
from .portable_math import vector_norm
from .structure import Structure, tensor

# A point counts as visible if nothing is hit closer than ``d - tol`` along the segment
# from the camera centre, with tol = OCCLUSION_TOL_ABS + OCCLUSION_TOL_REL * d (metres).
# It absorbs float32 round-off of the hit on the point's own triangle at grazing angles.
# The kernels of point_block_kernels.py compile these values in and numba's disk cache
# does not see a change here: after changing them, delete generator/geometry/__pycache__.
OCCLUSION_TOL_ABS = 1e-3
OCCLUSION_TOL_REL = 1e-4
# A cast of this many rays or more asks the moving parts' structure only about the rays whose
# static hit lies past the moving parts' nearest box (a test that costs more than it saves on
# a few rays).
REACH_TEST_RAYS = 256
def _build(parts: Sequence[MeshPart], first_hits: bool = True) -> Structure | None:
    structure = Structure(parts, first_hits)
    return structure if structure.count else None


class SceneGeometry:
    """Triangles of a scene as rigid parts, with vectorised ray and distance queries.

    Call :meth:`set_matrices` when dynamic parts move; static structures are never rebuilt.
    """

    def __init__(self, parts: Sequence[MeshPart]):
        self.parts = list(parts)
        self.static_index = [i for i, p in enumerate(self.parts) if not p.dynamic]
        self.dynamic_index = [i for i, p in enumerate(self.parts) if p.dynamic]
        for i in self.static_index:
            if not np.allclose(self.parts[i].matrix, np.eye(4)):
                raise ValueError(f"static part {self.parts[i].name!r} must be stored in world coordinates")
        self._static = _build([self.parts[i] for i in self.static_index])
        self._static_closed = None
        self._static_closed_built = False
        self._dynamic = None
        self._dynamic_closed = None
        self._dynamic_closed_built = False
        self._dynamic_dirty = True
        # visibility.PointBlocks of the last point set tested against this scene (a cache)
        self.point_blocks = None
        # incremented whenever a dynamic part moves (for caches of query answers)
        self.version = 0
        self._bounds, self._bounds_version = None, -1
        self._owners = None  # the parts of the structures' geometry ids (built on first use)
        # (P,) bool: the part is a closed mesh (a solid)
        self.closed = np.array([p.closed for p in self.parts], dtype=bool)
        self.local_bounds = np.array(
            [
                [p.vertices.min(axis=0), p.vertices.max(axis=0)] if len(p.vertices) else [[np.inf] * 3, [-np.inf] * 3]
                for p in self.parts
            ]
        ).reshape(len(self.parts), 2, 3)

    # ---- dynamic state ---------------------------------------------------------------
    def set_matrices(self, matrices: dict[int, np.ndarray]) -> None:
        """Set world_from_object of dynamic parts, keyed by part index."""
        changed = False
        for i, m in matrices.items():
            part = self.parts[i]
            if not part.dynamic:
                raise ValueError(f"part {part.name!r} is static")
            m = np.asarray(m, dtype=np.float64)
            if not np.array_equal(m, part.matrix):
                part.matrix = m.copy()
                changed = True
        if changed:
            self._dynamic_dirty = True
            self.version += 1

    def _dynamic_structure(self) -> Structure | None:
        """The moving parts' structure at their current matrices (rebuilt when they moved)."""
        if self._dynamic_dirty:
            self._dynamic = _build([self.parts[i] for i in self.dynamic_index])
            self._dynamic_closed, self._dynamic_closed_built = None, False
            self._dynamic_dirty = False
        return self._dynamic

    def _scenes(self, closed_only: bool = False):
        self._dynamic_structure()
        if closed_only:
            if not self._dynamic_closed_built:  # built when first asked for: a cast never needs it
                self._dynamic_closed = _build([self.parts[i] for i in self.dynamic_index if self.parts[i].closed],
                                              first_hits=False)
                self._dynamic_closed_built = True
            if not self._static_closed_built:
                self._static_closed = _build([self.parts[i] for i in self.static_index if self.parts[i].closed], False)
                self._static_closed_built = True
            scenes = [self._static_closed, self._dynamic_closed]
        else:
            scenes = [self._static, self._dynamic]
        return [s.scene for s in scenes if s is not None]

    def world_bounds(self) -> np.ndarray:
        """Axis-aligned bounds (P, 2, 3) of every part at the current matrices (a new array)."""
        if self._bounds_version != self.version:
            out = self.local_bounds.copy()
            moving = [i for i in self.dynamic_index if np.all(self.local_bounds[i, 0] <= self.local_bounds[i, 1])]
            if moving:  # (parts without vertices keep their empty box)
                lo, hi = self.local_bounds[moving, 0], self.local_bounds[moving, 1]
                m = np.stack([self.parts[i].matrix for i in moving])
                # the box of the transformed box: centre moved, half extents through |R|
                # (R v as rows_times(v, R^T): BLAS-free, the same bits on every CPU)
                rotation_t = np.ascontiguousarray(m[:, :3, :3].transpose(0, 2, 1))
                centre = rows_times((lo + hi) / 2, rotation_t) + m[:, :3, 3]
                half = rows_times((hi - lo) / 2, np.abs(rotation_t))
                out[moving, 0], out[moving, 1] = centre - half, centre + half
            self._bounds, self._bounds_version = out, self.version
        return self._bounds.copy()

    # ---- queries ------------------------------------------------------------------------
    def segments_blocked(self, origin: np.ndarray, targets: np.ndarray, stop_short: np.ndarray | float = 0.0) -> np.ndarray:
        """For each target (N, 3): does the segment from ``origin`` (3,) to the target, cut
        ``stop_short`` metres before the target, hit any triangle? Returns (N,) bool."""
        targets = np.asarray(targets, dtype=np.float64)
        n = len(targets)
        if n == 0:
            return np.zeros(0, dtype=bool)
        delta = targets - origin
        dist = np.sqrt(np.einsum("ij,ij->i", delta, delta))
        keep = np.clip(1.0 - np.divide(stop_short, dist, out=np.zeros(n), where=dist > 0), 0.0, 1.0)
        rays = np.empty((n, 6), dtype=np.float32)
        rays[:, :3] = origin
        np.multiply(delta, keep[:, None], out=rays[:, 3:], casting="same_kind")
        return self.rays_blocked(rays) & (keep > 0)

    def rays_blocked(self, rays: np.ndarray) -> np.ndarray:
        """For each float32 ray (N, 6) [origin, direction]: does the segment from the origin
        to origin + direction (t in [0, 1]) hit any triangle? Returns (N,) bool."""
        blocked = np.zeros(len(rays), dtype=bool)
        if len(rays) == 0:
            return blocked
        open_ = None  # rays not blocked yet (None: all); each scene tests only those
        for scene in self._scenes():
            if open_ is not None and len(open_) == 0:
                break
            t_rays = tensor(rays if open_ is None else np.take(rays, open_, axis=0))
            hit = scene.test_occlusions(t_rays, tnear=0.0, tfar=1.0).numpy().view(bool)
            if open_ is None:
                blocked = hit.copy()
                open_ = np.flatnonzero(~hit)
            else:
                blocked[open_[hit]] = True
                open_ = open_[~hit]
        return blocked

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Unsigned distance (N,) in metres from each point to the nearest triangle."""
        points = np.asarray(points, dtype=np.float64)
        out = np.full(len(points), np.inf)
        if len(points) == 0:
            return out
        q = tensor(points)
        for scene in self._scenes():
            out = np.minimum(out, scene.compute_distance(q).numpy().astype(np.float64))
        return out

    def inside_solid(self, points: np.ndarray) -> np.ndarray:
        """(N,) bool: the point lies inside a closed part (majority vote of ray parities
        along three skew directions, robust to rays grazing an edge)."""
        points = np.asarray(points, dtype=np.float64)
        n = len(points)
        scenes = self._scenes(closed_only=True)
        if n == 0 or not scenes:
            return np.zeros(n, dtype=bool)
        directions = np.array([[0.5377, 0.1829, 0.8230], [-0.7071, 0.3536, -0.6124], [0.1, -0.9849, 0.1414]])
        votes = np.zeros(n, dtype=np.int32)
        for d in directions:
            rays = np.empty((n, 6), dtype=np.float32)
            rays[:, :3] = points
            rays[:, 3:] = d / vector_norm(d)
            t_rays = tensor(rays)
            count = np.zeros(n, dtype=np.int64)
            for scene in scenes:
                count += scene.count_intersections(t_rays).numpy().astype(np.int64)
            votes += (count % 2).astype(np.int32)
        return votes >= 2

    def crossings(self, origins: np.ndarray, directions: np.ndarray, limit: np.ndarray) -> np.ndarray:
        """(N,) int64: how many triangles each ray meets at 0 <= t < ``limit`` (N,) (in units of
        its direction's length; inf: all), by Embree's float32 distances (every face counted,
        front or back)."""
        n = len(origins)
        count = np.zeros(n, dtype=np.int64)
        if n == 0:
            return count
        from .exact_kernels import float32_rays

        rays = np.empty((n, 6), dtype=np.float32)
        float32_rays(np.ascontiguousarray(origins, dtype=np.float64),
                     np.ascontiguousarray(directions, dtype=np.float64), rays)
        t_rays = tensor(rays)
        for scene in self._scenes():
            found = scene.list_intersections(t_rays)
            ray, t = found["ray_ids"].numpy().astype(np.int64), found["t_hit"].numpy()
            count += np.bincount(ray[t < limit[ray]], minlength=n)
        return count

    def cast(self, origins: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First hit along rays: returns (t (N,) in units of ``directions``' length, inf for a
        miss; part index (N,) int64, -1 for a miss)."""
        return self._first_hits(origins, directions, normals=False)[:2]

    def cast_with_normals(self, origins: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """As :meth:`cast`, plus the unit normal (N, 3) float32 of the triangle hit, world
        frame, either side (zero for a miss)."""
        t, part, _, normal = self._first_hits(origins, directions, normals=True)
        return t, part, normal

    def cast_faces(self, origins: np.ndarray, directions: np.ndarray):
        """As :meth:`cast_with_normals`, returning (t, part, face, normal): ``face`` (N,) int64
        the index of the triangle hit in its part's ``faces`` (-1 for a miss)."""
        return self._first_hits(origins, directions, normals=True)

    def _first_hits(self, origins: np.ndarray, directions: np.ndarray, normals: bool):
        # each structure decides its own hits in float64 (structure.Structure.first_hits); the
        # nearer of the static and the dynamic answer wins. The dynamic structure is asked only
        # about rays whose static hit lies past the moving parts' nearest box (a nearer static
        # hit wins whatever the dynamic one would be).
        from .exact_kernels import farther_than, float32_rays, take_rays
        origins = np.ascontiguousarray(origins, dtype=np.float64)
        directions = np.ascontiguousarray(directions, dtype=np.float64)
        n = len(origins)
        rays = np.empty((n, 6), dtype=np.float32)
        float32_rays(origins, directions, rays)
        if self._static is not None:
            t, gid, face, unit = self._static.first_hits(origins, directions, rays, normals)
            part = self._owner(static=True)[gid]
            rows = None  # every ray
            if self.dynamic_index and n >= REACH_TEST_RAYS:
                reach = self._dynamic_reach(origins)
                if reach > 0:
                    rows = np.flatnonzero(farther_than(t, directions, reach))
        else:
            t, part = np.full(n, np.inf), np.full(n, -1, dtype=np.int64)
            face, unit = np.full(n, -1, dtype=np.int64), (np.zeros((n, 3), dtype=np.float32) if normals else None)
            rows = None
        if rows is None:
            rows = np.arange(n)
        dynamic = self._dynamic_structure() if len(rows) else None  # built only when asked
        if dynamic is not None:
            sub = (origins, directions, rays) if len(rows) == n else take_rays(rows, origins, directions, rays)
            t2, gid2, face2, unit2 = dynamic.first_hits(*sub, normals)
            closer = np.flatnonzero(t2 < t[rows])
            at = rows[closer]
            t[at], part[at], face[at] = t2[closer], self._owner(static=False)[gid2[closer]], face2[closer]
            if normals:
                unit[at] = unit2[closer]
        return t, part, face, unit

    def _owner(self, static: bool) -> np.ndarray:
        """(G + 1,) the part index of each geometry id of the static (or the dynamic) structure,
        then -1 (a miss's id -1 reads the last)."""
        if self._owners is None:
            self._owners = {kind: np.asarray(self._geometry_to_part(index) + [-1], dtype=np.int64)
                            for kind, index in ((True, self.static_index), (False, self.dynamic_index))}
        return self._owners[static]

    def _dynamic_reach(self, origins: np.ndarray) -> float:
        """A distance (metres) within which no moving part lies from any of ``origins``: the gap
        between the origins' box and the nearest moving part's box, less a millimetre and
        1e-4 of it (the float32 triangles' round-off); 0 when they touch."""
        bounds = self.world_bounds()[self.dynamic_index]
        from .exact_kernels import box_of
        lo, hi = box_of(origins)
        gap = np.maximum(0.0, np.maximum(bounds[:, 0] - hi, lo - bounds[:, 1]))
        valid = np.all(bounds[:, 0] <= bounds[:, 1], axis=1)  # parts with vertices
        if not valid.any():
            return 0.0
        g = gap[valid]
        nearest = float(np.sqrt(np.min(g[:, 0] * g[:, 0] + g[:, 1] * g[:, 1] + g[:, 2] * g[:, 2])))
        return max(0.0, nearest - 1e-3 - 1e-4 * nearest)

    def _geometry_to_part(self, index: list[int]) -> list[int]:
        # geometry ids follow insertion order, skipping parts without faces
        return [i for i in index if len(self.parts[i].faces)]

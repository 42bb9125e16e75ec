"""Which surface points a camera could ever see: the ``observable`` mask of the ground truth.

A point is observable when it is visible, under the simulator's own visibility rules
(generator/geometry/visibility.py, with no depth limit), from at least one of
``DEFAULT_VIEWPOINTS`` viewpoints spread through the camera spawn volume, looking in every
direction. With every direction allowed the image condition (rule 1) never excludes a
point (some view frames it) and the depth condition (rule 2) reduces to "in front of the
camera", which some view always satisfies; what is left is rule 3 (not on the back of a
solid) and rule 4 (a free segment), which :func:`visible_from` applies with the same
tolerances. :func:`cube_map_visible` is the literal version (six 90-degree pinhole views
through ``visible_points``), and the two agree (tests/test_observability.py).

The viewpoints are free camera positions (the Simulator's spawn points: uniform in the
spawn volume, clear of geometry by the collision radius, drawn from the seed), taken in
farthest-point order, so the mask is deterministic. It is an estimate from below (a point
seen only from places no viewpoint hit stays unobservable); docs/scenes.md measures how it
converges with the number of viewpoints. Dynamic parts are judged where they are when
asked (the ground truth uses the first animation frame)."""

from __future__ import annotations

import numpy as np

from .portable_math import vector_norm
from .raycast import SceneGeometry
from .visibility import ViewLimits, visible_points
from .point_block_kernels import omni_rays
from .visibility_rules import cullable_parts

DEFAULT_VIEWPOINTS = 256
_HALF_FOV_TAN = 1.0 + 1e-3  # each cube face sees a hair more than 90 degrees
_FACE_SIZE = 2  # pixels; any size gives the same frustum
_FACE_K = np.array([[_FACE_SIZE / (2 * _HALF_FOV_TAN), 0.0, _FACE_SIZE / 2],
                    [0.0, _FACE_SIZE / (2 * _HALF_FOV_TAN), _FACE_SIZE / 2], [0.0, 0.0, 1.0]])


def _cube_rotations() -> np.ndarray:
    """(6, 3, 3) camera-to-world rotations (OpenCV axes) looking along +-x, +-y, +-z."""
    out = []
    for forward in np.vstack([np.eye(3), -np.eye(3)]):
        helper = np.array([0.0, 0.0, 1.0]) if abs(forward[2]) < 0.5 else np.array([1.0, 0.0, 0.0])
        right = np.cross(forward, helper)
        right /= vector_norm(right)
        down = np.cross(forward, right)
        out.append(np.stack([right, down, forward], axis=1))
    return np.array(out)


CUBE_ROTATIONS = _cube_rotations()


def default_viewpoints(spawn_points: np.ndarray, count: int = DEFAULT_VIEWPOINTS) -> np.ndarray:
    """The viewpoints (K, 3) of the mask: ``count`` of the spawn points (a uniform, seeded
    sample of free camera positions in the spawn volume), in farthest-point order from the
    first one, so that any prefix is spread through the whole volume. Deterministic."""
    if count < 1:
        raise ValueError(f"the observability mask needs at least one viewpoint, got count={count}")
    pool = np.asarray(spawn_points, dtype=np.float64).reshape(-1, 3)
    count = min(count, len(pool))
    order = [0]
    gap = np.linalg.norm(pool - pool[0], axis=1)
    for _ in range(count - 1):
        k = int(np.argmax(gap))  # first index among ties: deterministic
        order.append(k)
        gap = np.minimum(gap, np.linalg.norm(pool - pool[k], axis=1))
    return pool[order].copy()


def cube_map_visible(geometry: SceneGeometry, points: np.ndarray, normals: np.ndarray | None,
                     part_index: np.ndarray | None, centre: np.ndarray) -> np.ndarray:
    """(N,) bool: points visible from ``centre`` (3,) in one of six 90-degree pinhole views
    (a cube map), by :func:`.visibility.visible_points` itself with one ray per point and no
    depth limit. The reference that :func:`visible_from` must equal (tested)."""
    points = np.asarray(points, dtype=np.float64)
    seen = np.zeros(len(points), dtype=bool)
    pose = np.eye(4)
    pose[:3, 3] = centre
    for rotation in CUBE_ROTATIONS:
        pose[:3, :3] = rotation
        seen |= visible_points(geometry, points, normals, part_index, pose, _FACE_K, _FACE_SIZE, _FACE_SIZE,
                               ViewLimits(0.0, np.inf), ray_per_point=True)
    return seen


class OmniSweep:
    """Points (N, 3) with their outward ``normals`` (N, 3) and ``part_index`` (N,) (both
    optional, as :func:`.visibility.visible_points` takes them: without them rule 3 is not
    applied), laid out once for :meth:`visible` from many viewpoints."""

    def __init__(self, points: np.ndarray, normals: np.ndarray | None, part_index: np.ndarray | None):
        points = np.asarray(points, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError(f"points must have shape (N, 3), got {points.shape}")
        n = len(points)
        self.xyz = np.ascontiguousarray(points.T)
        rule3 = normals is not None and part_index is not None
        self.nxyz, self.part = np.zeros((3, 0)), np.zeros(0, np.int64)
        if rule3:
            normals, part_index = np.asarray(normals, dtype=np.float64), np.asarray(part_index)
            if normals.shape != (n, 3) or part_index.shape != (n,):
                raise ValueError(f"normals must have shape ({n}, 3) and part_index ({n},), got {normals.shape} "
                                 f"and {part_index.shape}")
            if n and part_index.min() < 0:
                raise ValueError("part_index must hold part indices >= 0")
            self.nxyz, self.part = np.ascontiguousarray(normals.T), np.ascontiguousarray(part_index, dtype=np.int64)
        self.rule3 = rule3
        self.parts_needed = int(self.part.max()) + 1 if len(self.part) else 0
        self.rays = np.empty((n, 6), dtype=np.float32)  # buffers, reused by every call
        self.pos = np.empty(n, dtype=np.int64)

    def visible(self, geometry: SceneGeometry, centre: np.ndarray, todo: np.ndarray) -> np.ndarray:
        """(M,) bool: which of the points ``todo`` (M,) (indices) are visible from ``centre``
        (3,) looking in any direction (:func:`visible_from`)."""
        centre = np.asarray(centre, dtype=np.float64).reshape(3)
        todo = np.asarray(todo, dtype=np.int64)
        if len(todo) and (todo.min() < 0 or todo.max() >= self.xyz.shape[1]):
            raise ValueError(f"todo must index the {self.xyz.shape[1]} points")
        cullable = cullable_parts(geometry, centre) if self.rule3 else np.zeros(0, dtype=bool)
        if self.rule3 and self.parts_needed > len(cullable):
            raise ValueError(f"part_index goes up to {self.parts_needed - 1}; the geometry has {len(cullable)} parts")
        seen = np.zeros(len(todo), dtype=bool)
        m = omni_rays(self.xyz, self.nxyz, self.part, cullable, todo, centre, seen, self.pos, self.rays)
        if m:
            blocked = geometry.rays_blocked(self.rays[:m])
            seen[self.pos[:m][~blocked]] = True
        return seen


def visible_from(geometry: SceneGeometry, points: np.ndarray, normals: np.ndarray | None,
                 part_index: np.ndarray | None, centre: np.ndarray) -> np.ndarray:
    """(N,) bool: points visible from ``centre`` (3,) looking in any direction, no depth
    limit: the visibility rules with rule 1 dropped (some direction always frames the point)
    and rule 2 reduced to z > 0 (some direction always has it in front): rule 3 (not on the
    back of a solid whose bounding box leaves the camera out) and rule 4 (free segment, with
    the same tolerance), by the kernel ``point_block_kernels.omni_rays``. Equal to
    :func:`cube_map_visible`, at a fraction of its cost."""
    sweep = OmniSweep(points, normals, part_index)
    return sweep.visible(geometry, centre, np.arange(sweep.xyz.shape[1]))


def observable_mask(geometry: SceneGeometry, points: np.ndarray, normals: np.ndarray | None,
                    part_index: np.ndarray | None, viewpoints: np.ndarray, counts: list | None = None,
                    progress=None) -> np.ndarray:
    """(N,) bool: points (N, 3) world metres visible from at least one of ``viewpoints``
    (K, 3) in some direction (:func:`visible_from`), with the geometry at its current
    matrices. ``normals`` and ``part_index`` as :func:`.visibility.visible_points` takes
    them. ``counts``: if a list, receives the number of observable points after each
    viewpoint (the convergence curve). Only points not yet seen are tested from the next
    viewpoint."""
    sweep = OmniSweep(points, normals, part_index)
    n = sweep.xyz.shape[1]
    observable = np.zeros(n, dtype=bool)
    viewpoints = np.asarray(viewpoints, dtype=np.float64).reshape(-1, 3)
    todo = np.arange(n)
    order = range(len(viewpoints)) if progress is None else progress(range(len(viewpoints)))
    for k in order:
        if len(todo):
            seen = sweep.visible(geometry, viewpoints[k], todo)
            if seen.any():
                observable[todo[seen]] = True
                todo = todo[~seen]
        if counts is not None:
            counts.append(n - len(todo))
    return observable

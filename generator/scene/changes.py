"""What changed between two stages of a site's timeline (bpy-free; definitions in docs/phases.md).

Three levels, all computed from what the stages' folders hold (``ground_truth/scene.h5``,
``points.ply``, the frames' depth and instance maps):

- **instances**: every object of either stage, by its name (the same in every stage,
  :func:`generator.scene.timeline.object_name`), is ``added``, ``removed``, ``unchanged``
  (the same world vertices and faces, bit for bit, at the first animation frame), ``moved``
  (the same faces, vertices related by a rigid transform to within ``RIGID_TOLERANCE``) or
  ``grown`` (any other change of its geometry);
- **points**: a ground-truth point of stage k is *added* if the surface of stage k - 1 is
  farther than ``POINT_TOLERANCE`` from it; a point of stage k - 1 is *removed* if the
  surface of stage k is farther than that from it (exact point-to-triangle distances);
- **pixels**: a pixel of a frame changed if the object it sees is not the same object in
  both stages, or the planar depths differ by more than ``DEPTH_TOLERANCE`` (a surface seen
  in one stage and none in the other is a change).
"""

from __future__ import annotations

import numpy as np

from exporters.changes import STATUS  # codes 0..4 in changes.h5

from ..geometry.camera import apply_affine, orthonormalize, rows_times

ABSENT = -1  # the status of an object in neither stage
POINT_TOLERANCE = 0.01  # metres: a point is unchanged if the other stage's surface is within this
DEPTH_TOLERANCE = 0.01  # metres of planar depth at a pixel
RIGID_TOLERANCE = 1e-4  # metres: largest vertex residual of a rigid fit for "moved"


def union_table(stage_names: list[list[str]]) -> tuple[list[str], list[np.ndarray]]:
    """The objects of all stages (sorted names) and, per stage, its instance id -> union id."""
    union = sorted(set().union(*map(set, stage_names)))
    index = {n: i for i, n in enumerate(union)}
    return union, [np.array([index[n] for n in names], np.int32) for names in stage_names]


def rigid_fit(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, float]:
    """4x4 rigid transform T (rotation, translation) minimising |T a - b| over matched rows,
    and the largest residual in metres (Kabsch: the rotation is the polar factor of the
    cross-covariance's transpose; where that is singular, badly conditioned or mirrored, as
    for flat or nearly flat parts, the rotation nearest to it by Horn's method). Without BLAS
    or LAPACK, so the same bits on every CPU (docs/guarantees.md)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    da, db = a - ca, b - cb
    h = np.array([[np.sum(da[:, i] * db[:, j]) for j in range(3)] for i in range(3)])  # (a - ca)^T (b - cb)
    r = orthonormalize(h.T)  # polar factor, else (flat, degenerate or mirrored sets) Horn's method
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = r, cb - rows_times(ca, r.T)
    residual = float(np.max(np.linalg.norm(apply_affine(t, a) - b, axis=1))) if len(a) else 0.0
    return t, residual


def classify_instances(parts_a: list, parts_b: list, union_a: np.ndarray, union_b: np.ndarray,
                       n_union: int) -> tuple[np.ndarray, np.ndarray]:
    """Status code per union object (STATUS index, ABSENT if in neither stage) and, for moved
    ones, world_from_world transform taking the object in stage a to stage b (identity
    otherwise). ``parts_*`` with matrices of the first animation frame."""
    status = np.full(n_union, ABSENT, np.int8)
    transform = np.tile(np.eye(4), (n_union, 1, 1))
    in_b = {int(u): p for u, p in zip(union_b, parts_b)}
    for u, p in zip(union_a, parts_a):
        status[u] = STATUS.index("removed")
    for u, q in in_b.items():
        status[u] = STATUS.index("added")
    for u, p in zip(union_a, parts_a):
        q = in_b.get(int(u))
        if q is None:
            continue
        va, vb = p.world_vertices(), q.world_vertices()
        same_faces = p.faces.shape == q.faces.shape and np.array_equal(p.faces, q.faces)
        if same_faces and va.shape == vb.shape and np.array_equal(va, vb):
            status[u] = STATUS.index("unchanged")
            continue
        if same_faces and va.shape == vb.shape:
            t, residual = rigid_fit(va, vb)
            if residual <= RIGID_TOLERANCE:
                status[u], transform[u] = STATUS.index("moved"), t
                continue
        status[u] = STATUS.index("grown")
    return status, transform


REFINE = 0.1  # metres: distances up to the tolerance + REFINE are exact (float64)
EMBREE_ERROR = 0.03  # metres: the most Embree's float32 distance is off by (measured: 2.6 cm, a crane jib's face)


def surface_distance(points: np.ndarray, parts: list, tolerance: float = POINT_TOLERANCE) -> np.ndarray:
    """(N,) float32 distance in metres from each point to the nearest triangle of ``parts``
    (placed at their matrices). Embree's float32 closest-point query (open3d) is too far by
    up to a few centimetres on needle triangles (measured: 2.6 cm on a 43 m x 0.14 m face of a
    crane jib, 8 mm for points on scaffold tubes), so every point it puts within tolerance +
    REFINE + EMBREE_ERROR gets the exact float64 distance of
    :func:`generator.geometry.near_distance.near_distances` instead (tests/test_phases.py
    checks the result against an independent float64 point-to-triangle distance)."""
    from ..geometry.near_distance import near_distances
    from ..geometry.raycast import SceneGeometry

    points = np.asarray(points, np.float64)
    if len(points) == 0:
        return np.zeros(0, np.float32)
    d = np.asarray(SceneGeometry(parts).distance(points), np.float64)
    reach = tolerance + REFINE + EMBREE_ERROR
    near = np.flatnonzero(d <= reach)
    if len(near):
        tri = [p.world_vertices()[p.faces] for p in parts if len(p.faces)]
        exact = near_distances(points[near], np.concatenate(tri), reach + EMBREE_ERROR)
        d[near] = np.where(exact <= reach + EMBREE_ERROR, exact, d[near])
    return d.astype(np.float32)


def stage_distance(points: np.ndarray, unchanged: np.ndarray, parts: list) -> np.ndarray:
    """(N,) float32 distance in metres from each point of one stage to the other stage's
    surface ``parts``: 0 for the points of objects ``unchanged`` (N,) bool between the two
    stages (their triangles are in both, bit for bit), :func:`surface_distance` for the rest."""
    d = np.zeros(len(points), np.float32)
    rest = np.flatnonzero(~np.asarray(unchanged, bool))
    d[rest] = surface_distance(np.asarray(points)[rest], parts)
    return d


def frame_change_mask(depth_a: np.ndarray, union_a: np.ndarray, depth_b: np.ndarray, union_b: np.ndarray,
                      tolerance: float = DEPTH_TOLERANCE) -> np.ndarray:
    """(H, W) bool: the visible surface changed. ``union_*`` are the frames' instance maps in
    union ids (-1: no object), ``depth_*`` planar depth in metres (+inf: no surface)."""
    fa, fb = np.isfinite(depth_a), np.isfinite(depth_b)
    with np.errstate(invalid="ignore"):
        far = np.abs(np.where(fa & fb, depth_a - depth_b, 0.0)) > tolerance
    return (union_a != union_b) | (fa != fb) | far


def to_union(instance: np.ndarray, table: np.ndarray) -> np.ndarray:
    """A frame's instance map (stage ids, -1 none) in union ids (-1 none)."""
    out = np.full(instance.shape, -1, np.int32)
    ok = (instance >= 0) & (instance < len(table))
    out[ok] = table[instance[ok]]
    return out

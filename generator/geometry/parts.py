"""Rigid mesh parts: the numpy description of a scene's geometry, shared by every consumer."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np



@dataclass
class MeshPart:
    """One object's triangles in its own frame.

    ``vertices`` (V, 3) metres in the object frame, ``faces`` (F, 3) vertex indices.
    Static parts are stored in world coordinates (``matrix`` is the identity); dynamic parts
    keep their object frame and ``matrix`` (4x4, world_from_object) follows the animation.
    ``closed`` means every edge is shared by exactly two consistently oriented faces, so the
    part bounds a solid; ``outward`` is +1 if face normals (right-hand rule) point out of
    that solid, -1 if they point in. ``scenery``: the part is scenery (its Blender object's
    ``buildee_scenery`` property: the surroundings beyond a generated site's fence): it is
    rendered, seen in every per-pixel ground truth and takes part in visibility and
    collisions, but carries no surface or scoring points. ``face_reflectivity`` (F,)
    float32: each face's diffuse reflectivity at a LiDAR's 905 nm, in [0, 1], and
    ``face_transparent`` (F,) bool: the face is clear glass, which a laser beam passes
    through (docs/lidar.md); None: every face the LiDAR's defaults (an opaque surface of
    :data:`generator.lidar.physics.DEFAULT_REFLECTIVITY`).
    """

    name: str
    label: str
    vertices: np.ndarray
    faces: np.ndarray
    dynamic: bool = False
    matrix: np.ndarray = field(default_factory=lambda: np.eye(4))
    closed: bool = False
    outward: int = 1
    source: str = ""  # name of the Blender object the triangles come from
    scenery: bool = False
    face_reflectivity: np.ndarray | None = None
    face_transparent: np.ndarray | None = None

    def radius(self) -> float:
        """The largest distance of the part's vertices from its own origin (metres, in its own
        frame: how far a point of it may swing when it turns)."""
        if not len(self.vertices):
            return 0.0
        v = np.asarray(self.vertices, dtype=np.float64)
        return float(np.sqrt(np.max(v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1] + v[:, 2] * v[:, 2])))

    def world_vertices(self) -> np.ndarray:
        """(V, 3) float64 world positions, the same bits on every CPU (camera.rows_times)."""
        from .camera import apply_affine

        return apply_affine(self.matrix, self.vertices)


def closed_and_orientation(vertices: np.ndarray, faces: np.ndarray) -> tuple[bool, int]:
    """Whether a triangle mesh bounds a solid (watertight, consistently oriented, non-zero
    volume), and the sign of its signed volume (+1: normals point outward)."""
    faces = np.asarray(faces, dtype=np.int64)
    if len(faces) < 4:
        return False, 1
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    nv = int(faces.max()) + 1
    codes = directed[:, 0] * nv + directed[:, 1]
    reverse = directed[:, 1] * nv + directed[:, 0]
    codes_sorted = np.sort(codes)
    if np.any(codes_sorted[1:] == codes_sorted[:-1]):
        return False, 1  # a directed edge used twice: inconsistent orientation or non-manifold
    if not np.array_equal(codes_sorted, np.sort(reverse)):
        return False, 1  # an edge with no opposite half-edge: a boundary
    v = np.asarray(vertices, dtype=np.float64)
    v = v - v.mean(axis=0)
    a, b, c = v[faces[:, 0]], v[faces[:, 1]], v[faces[:, 2]]
    volume = float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum()) / 6.0
    scale = float(np.abs(v).max()) if len(v) else 0.0
    s = max(scale, 1e-9)
    if abs(volume) <= 1e-9 * (s * s * s):
        return False, 1
    return True, 1 if volume > 0 else -1


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit normals (F, 3) by the right-hand rule; zero for degenerate faces."""
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    n = np.cross(b - a, c - a)
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)

"""Area-weighted, seeded sampling of points on triangle surfaces, and which faces carry
surface points (all but the faces of solids resting on the working level: docs/scenes.md)."""

from __future__ import annotations

import numpy as np

from .camera import turn_normals
from .parts import MeshPart, face_normals


def triangle_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Areas (T,) in square metres of the triangles ``faces`` (T, 3) over ``vertices`` (V, 3)."""
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


def sample_triangles(
    vertices: np.ndarray, faces: np.ndarray, density: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Sample points uniformly on a triangle mesh at ``density`` points per square metre.

    The number of points is ``floor(density * area + u)`` with ``u`` uniform in [0, 1), so
    its expectation is exactly ``density * area`` even for small objects. Returns
    ``(points (n, 3) float64, face_index (n,) int64)``.
    """
    faces = np.asarray(faces, dtype=np.int64)
    vertices = np.asarray(vertices, dtype=np.float64)
    if len(faces) == 0:
        return np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
    areas = triangle_areas(vertices, faces)
    total = float(areas.sum())
    n = int(np.floor(density * total + rng.random()))
    if n == 0 or total <= 0:
        return np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
    cdf = np.cumsum(areas)
    face = np.searchsorted(cdf, rng.random(n) * cdf[-1], side="right")
    face = np.minimum(face, len(faces) - 1)
    r1 = np.sqrt(rng.random(n))
    r2 = rng.random(n)
    a, b, c = (vertices[faces[face, k]] for k in range(3))
    points = (1 - r1)[:, None] * a + (r1 * (1 - r2))[:, None] * b + (r1 * r2)[:, None] * c
    return points, face


# ---- which faces carry surface points -------------------------------------------------
GROUND_LABEL = "Ground"
CONTACT_TOLERANCE = 0.01  # metres: a face this close to the working level lies on it
CONTACT_COS = 0.999  # a contact face's outward normal is within ~2.6 degrees of straight down


def ground_height(parts: list[MeshPart]) -> float | None:
    """z (metres) of the scene's working level: the height of the largest area of level,
    upward-facing faces of the parts labelled ``Ground`` (faces within ``CONTACT_TOLERANCE``
    of one height, normals within ~2.6 degrees of straight up; a site's ground beside its
    digs, ruts and terrain; within that 1 cm band, the one height holding the most area).
    None when the ground has no level face."""
    heights, areas = [], []
    for p in parts:
        if p.label != GROUND_LABEL or not len(p.faces):
            continue
        v = p.world_vertices()
        f = np.asarray(p.faces, dtype=np.int64)
        a, b, c = (v[f[:, k]] for k in range(3))
        cross = np.cross(b - a, c - a)
        area = 0.5 * np.linalg.norm(cross, axis=1)
        z = v[f][:, :, 2]
        up = cross[:, 2] * (p.outward if p.closed else 1) >= CONTACT_COS * 2 * area
        level = up & (area > 0) & (z.max(axis=1) - z.min(axis=1) <= CONTACT_TOLERANCE)
        heights.append(z[level].max(axis=1))
        areas.append(area[level])
    if not heights or not len(np.concatenate(heights)):
        return None
    h, a = np.concatenate(heights), np.concatenate(areas)
    bins = np.round(h / CONTACT_TOLERANCE).astype(np.int64)
    _, inverse = np.unique(bins, return_inverse=True)
    best = inverse == int(np.argmax(np.bincount(inverse, weights=a)))
    exact, where = np.unique(h[best], return_inverse=True)  # in that band, the height holding the most area
    return float(exact[int(np.argmax(np.bincount(where, weights=a[best])))])


def contact_faces(part: MeshPart, ground_z: float | None) -> np.ndarray:
    """(F,) bool: faces of ``part`` resting on the ground, which no camera can see: faces of
    a closed part (a solid) whose outward normal points straight down and whose three
    vertices lie within ``CONTACT_TOLERANCE`` of the working level (:func:`ground_height`),
    at the part's current matrix; a spoil heap's base too (a solid labelled ``Ground``). The
    ground's open surface and other open surfaces have none."""
    faces = np.asarray(part.faces, dtype=np.int64)
    out = np.zeros(len(faces), dtype=bool)
    if ground_z is None or not part.closed or len(faces) == 0:
        return out
    m = np.asarray(part.matrix, dtype=np.float64)
    world_z = part.world_vertices()[:, 2]
    low = np.all(np.abs(world_z[faces] - ground_z) <= CONTACT_TOLERANCE, axis=1)
    if not low.any():
        return out
    n = face_normals(np.asarray(part.vertices, np.float64), faces[low]) * part.outward
    nz = turn_normals(m, n)[:, 2]  # normals move with the inverse-transpose (mirrors included)
    out[np.flatnonzero(low)[nz <= -CONTACT_COS]] = True
    return out


def sample_part(part: MeshPart, density: float, rng: np.random.Generator,
                ground_z: float | None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`sample_triangles` on a part's faces minus its :func:`contact_faces`, in the
    part's own frame. Returns ``(points (n, 3), face_index (n,) into part.faces)``; none on
    a scenery part (:class:`~.parts.MeshPart`)."""
    if part.scenery:
        return np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
    keep = np.flatnonzero(~contact_faces(part, ground_z))
    pts, face = sample_triangles(part.vertices, np.asarray(part.faces)[keep], density, rng)
    return pts, keep[face]


def outward_normals(part: MeshPart, face_index: np.ndarray) -> np.ndarray:
    """Unit normals (n, 3) in the part's frame of points on faces ``face_index``: outward
    on closed parts (the visibility rules' back-face test uses them), zero on open ones."""
    if not part.closed:
        return np.zeros((len(face_index), 3))
    return face_normals(np.asarray(part.vertices, np.float64), np.asarray(part.faces, np.int64))[face_index] * part.outward

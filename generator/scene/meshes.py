"""A small numpy mesh builder for procedural assets (bpy-free).

Every primitive is a closed, outward-oriented surface in metres (boxes, capped cylinders,
cones, extruded profiles), so assets are solids and the simulator can use back-face rules.
Faces are quads or triangles with a material slot index each.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.camera import rows_times
from ..geometry.portable_math import sincos, vector_norm


@dataclass
class MeshData:
    """vertices (V, 3) float64; faces as quads (Q, 4) and triangles (T, 3); a material
    slot per face (quads first); ``materials`` names the slots."""

    vertices: np.ndarray
    quads: np.ndarray
    tris: np.ndarray
    face_material: np.ndarray
    materials: list[str]

    @property
    def triangle_count(self) -> int:
        return 2 * len(self.quads) + len(self.tris)

    def faces_where(self, keep: np.ndarray) -> "MeshData":
        """The faces selected by ``keep`` (a bool per face, quads first), their vertices
        only, materials kept by name."""
        keep = np.asarray(keep, bool)
        nq = len(self.quads)
        b = MeshBuilder()
        for k, name in enumerate(self.materials):
            q = self.quads[keep[:nq] & (self.face_material[:nq] == k)]
            t = self.tris[keep[nq:] & (self.face_material[nq:] == k)]
            if len(q) or len(t):
                used = np.unique(np.concatenate([q.ravel(), t.ravel()]))
                remap = np.full(len(self.vertices), -1)
                remap[used] = np.arange(len(used))
                b.add(self.vertices[used], remap[q], remap[t], name)
        return b.build()


def rotation_z(yaw: float) -> np.ndarray:
    s, c = sincos(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rotation_x(a: float) -> np.ndarray:
    s, c = sincos(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rotation_y(a: float) -> np.ndarray:
    s, c = sincos(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def frame_along(direction: np.ndarray) -> np.ndarray:
    """A rotation whose z axis is ``direction`` (normalised)."""
    z = np.asarray(direction, dtype=np.float64)
    z = z / vector_norm(z)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= vector_norm(x)
    return np.stack([x, np.cross(z, x), z], axis=1)


def _axis_and_ring(p0, p1, segments: int):
    """Start point, axis vector, length and a unit circle (segments, 3) in the z = 0 plane."""
    p0 = np.asarray(p0, float)
    axis = np.asarray(p1, float) - p0
    a = 2 * np.pi * np.arange(segments) / segments
    s, c = sincos(a)
    return p0, axis, vector_norm(axis), np.stack([c, s, np.zeros(segments)], axis=1)


class MeshBuilder:
    """Accumulates primitives into one mesh. Material names map to slots on first use."""

    def __init__(self):
        self._verts: list[np.ndarray] = []
        self._quads: list[np.ndarray] = []
        self._tris: list[np.ndarray] = []
        self._qmat: list[np.ndarray] = []
        self._tmat: list[np.ndarray] = []
        self._n = 0
        self.materials: list[str] = []

    def _slot(self, material: str) -> int:
        if material not in self.materials:
            self.materials.append(material)
        return self.materials.index(material)

    def add(self, verts, quads=None, tris=None, material: str = "default", rotation=None, offset=None) -> "MeshBuilder":
        """Add raw geometry (local vertices, optionally rotated then offset)."""
        v = np.asarray(verts, dtype=np.float64).reshape(-1, 3)
        if rotation is not None:
            v = rows_times(v, np.asarray(rotation, dtype=np.float64).T)  # v R^T without BLAS
        if offset is not None:
            v = v + np.asarray(offset, dtype=np.float64)
        slot = self._slot(material)
        self._verts.append(v)
        if quads is not None and len(quads):
            q = np.asarray(quads, dtype=np.int64).reshape(-1, 4) + self._n
            self._quads.append(q)
            self._qmat.append(np.full(len(q), slot))
        if tris is not None and len(tris):
            t = np.asarray(tris, dtype=np.int64).reshape(-1, 3) + self._n
            self._tris.append(t)
            self._tmat.append(np.full(len(t), slot))
        self._n += len(v)
        return self

    def merge(self, other: "MeshBuilder | MeshData", rotation=None, offset=None) -> "MeshBuilder":
        data = other.build() if isinstance(other, MeshBuilder) else other
        for k, name in enumerate(data.materials):
            nq = len(data.quads)
            qsel = data.face_material[:nq] == k
            tsel = data.face_material[nq:] == k
            if not qsel.any() and not tsel.any():
                continue
            used = np.unique(np.concatenate([data.quads[qsel].ravel(), data.tris[tsel].ravel()]))
            remap = np.full(len(data.vertices), -1)
            remap[used] = np.arange(len(used))
            self.add(data.vertices[used], remap[data.quads[qsel]], remap[data.tris[tsel]], name, rotation, offset)
        return self

    # ---- primitives ---------------------------------------------------------------------
    def box(self, size, center=(0, 0, 0), rotation=None, material: str = "default") -> "MeshBuilder":
        """Box of ``size`` (sx, sy, sz) centred at ``center`` (rotation about its centre)."""
        sx, sy, sz = (float(s) / 2 for s in size)
        v = np.array([[x, y, z] for x in (-sx, sx) for y in (-sy, sy) for z in (-sz, sz)])
        q = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
        return self.add(v, q, None, material, rotation, center)

    def cylinder(self, radius: float, p0, p1, segments: int = 8, material: str = "default") -> "MeshBuilder":
        """Capped cylinder (or tube member) from point p0 to point p1."""
        return self.cone(radius, radius, p0, p1, segments, material)

    def cone(self, r0: float, r1: float, p0, p1, segments: int = 16, material: str = "default") -> "MeshBuilder":
        """Capped truncated cone: radius r0 at p0, r1 at p1 (r1 may be 0 for a tip)."""
        p0, axis, length, ring = _axis_and_ring(p0, p1, segments)
        if r1 <= 0:
            v = np.concatenate([ring * r0, [[0, 0, length]], [[0, 0, 0]]])
            k = np.arange(segments)
            k2 = (k + 1) % segments
            tris = np.concatenate([np.stack([k, k2, np.full(segments, segments)], 1),
                                   np.stack([k2, k, np.full(segments, segments + 1)], 1)])
            return self.add(v, None, tris, material, frame_along(axis), p0)
        v = np.concatenate([ring * r0, ring * r1 + [0, 0, length], [[0, 0, 0]], [[0, 0, length]]])
        k = np.arange(segments)
        k2 = (k + 1) % segments
        quads = np.stack([k, k2, k2 + segments, k + segments], 1)
        tris = np.concatenate([np.stack([k2, k, np.full(segments, 2 * segments)], 1),
                               np.stack([k + segments, k2 + segments, np.full(segments, 2 * segments + 1)], 1)])
        return self.add(v, quads, tris, material, frame_along(axis), p0)

    def tube(self, r_out: float, r_in: float, p0, p1, segments: int = 24, material: str = "default") -> "MeshBuilder":
        """Hollow pipe (closed solid: outer wall, inner wall, two annular ends)."""
        p0, axis, length, ring = _axis_and_ring(p0, p1, segments)
        top = np.array([0, 0, length])
        v = np.concatenate([ring * r_out, ring * r_out + top, ring * r_in, ring * r_in + top])
        k = np.arange(segments)
        k2 = (k + 1) % segments
        n = segments
        quads = np.concatenate([
            np.stack([k, k2, k2 + n, k + n], 1),                      # outer wall
            np.stack([k + 2 * n, k + 3 * n, k2 + 3 * n, k2 + 2 * n], 1),  # inner wall (facing the bore)
            np.stack([k2, k, k + 2 * n, k2 + 2 * n], 1),              # bottom ring
            np.stack([k + n, k2 + n, k2 + 3 * n, k + 3 * n], 1),      # top ring
        ])
        return self.add(v, quads, None, material, frame_along(axis), p0)

    def prism(self, profile, length: float, rotation=None, offset=None, material: str = "default") -> "MeshBuilder":
        """Extrude a simple counter-clockwise 2D polygon (in x, z) along +y by ``length``,
        centred on y = 0. Caps are fanned from the polygon's centroid (profile must be
        star-shaped from it)."""
        p = np.asarray(profile, dtype=np.float64)
        n = len(p)
        c = p.mean(axis=0)
        y0, y1 = -length / 2, length / 2
        v = np.concatenate([
            np.stack([p[:, 0], np.full(n, y0), p[:, 1]], 1),
            np.stack([p[:, 0], np.full(n, y1), p[:, 1]], 1),
            [[c[0], y0, c[1]], [c[0], y1, c[1]]],
        ])
        k = np.arange(n)
        k2 = (k + 1) % n
        quads = np.stack([k, k + n, k2 + n, k2], 1)
        tris = np.concatenate([np.stack([k, k2, np.full(n, 2 * n)], 1), np.stack([k + n, np.full(n, 2 * n + 1), k2 + n], 1)])
        return self.add(v, quads, tris, material, rotation, offset)

    def heightfield(self, heights: np.ndarray, extent_x: float, extent_y: float, center=(0, 0, 0), material: str = "default", skirt: bool = True) -> "MeshBuilder":
        """A closed solid whose top is a regular grid of ``heights`` (ny, nx) over a
        rectangle of ``extent_x`` x ``extent_y`` and whose bottom is flat at z = 0."""
        h = np.asarray(heights, dtype=np.float64)
        ny, nx = h.shape
        xs = np.linspace(-extent_x / 2, extent_x / 2, nx)
        ys = np.linspace(-extent_y / 2, extent_y / 2, ny)
        gx, gy = np.meshgrid(xs, ys)
        top = np.stack([gx.ravel(), gy.ravel(), h.ravel()], 1)
        idx = np.arange(nx * ny).reshape(ny, nx)
        quads = np.stack([idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()], 1)
        if not skirt:
            return self.add(top, quads, None, material, None, center)
        ring = np.concatenate([idx[0, :], idx[1:, -1], idx[-1, -2::-1], idx[-2:0:-1, 0]])  # CCW from above
        bottom = top[ring].copy()
        bottom[:, 2] = 0.0
        nb = len(ring)
        base = nx * ny
        verts = np.concatenate([top, bottom, [[0.0, 0.0, 0.0]]])
        k = np.arange(nb)
        k2 = (k + 1) % nb
        side = np.stack([ring[k], base + k, base + k2, ring[k2]], 1)
        tris = np.stack([base + k2, base + k, np.full(nb, base + nb)], 1)
        return self.add(verts, np.concatenate([quads, side]), tris, material, None, center)

    def build(self) -> MeshData:
        v = np.concatenate(self._verts) if self._verts else np.zeros((0, 3))
        q = np.concatenate(self._quads) if self._quads else np.zeros((0, 4), np.int64)
        t = np.concatenate(self._tris) if self._tris else np.zeros((0, 3), np.int64)
        qm = np.concatenate(self._qmat) if self._qmat else np.zeros(0, np.int64)
        tm = np.concatenate(self._tmat) if self._tmat else np.zeros(0, np.int64)
        return MeshData(v, q, t, np.concatenate([qm, tm]).astype(np.int32), list(self.materials))

"""The scene's surface point cloud: sampled once, moved with dynamic parts every frame."""

from __future__ import annotations

import numpy as np

from .parts import MeshPart, face_normals
from .sampling import sample_triangles
from .seeding import stream


class SurfacePoints:
    """Points sampled on every part, stored part by part in contiguous ranges.

    ``local`` (N, 3) metres: world coordinates for static parts, object coordinates for
    dynamic ones (the paper's convention). ``local_normals`` (N, 3): outward unit normals
    in the same frame for points on closed parts, zero elsewhere. ``part`` (N,) int32 is the
    part (instance) index, ``labels`` (N,) int32 the label id, ``ranges`` (P, 2) the
    [start, end) of each part's points.
    """

    def __init__(self, parts: list[MeshPart], label_ids: dict[str, int], density: float, seed: int):
        locals_, normals, part_idx = [], [], []
        ranges = np.zeros((len(parts), 2), dtype=np.int64)
        start = 0
        for i, p in enumerate(parts):
            rng = stream(seed, "surface-points", p.name)
            pts, face = sample_triangles(p.vertices, p.faces, density, rng)
            if p.closed:
                nrm = face_normals(p.vertices, p.faces)[face] * p.outward
            else:
                nrm = np.zeros_like(pts)
            locals_.append(pts)
            normals.append(nrm)
            part_idx.append(np.full(len(pts), i, dtype=np.int32))
            ranges[i] = start, start + len(pts)
            start += len(pts)
        self.local = np.concatenate(locals_) if locals_ else np.zeros((0, 3))
        self.local_normals = np.concatenate(normals) if normals else np.zeros((0, 3))
        self.part = np.concatenate(part_idx) if part_idx else np.zeros(0, dtype=np.int32)
        label_of_part = np.array([label_ids[p.label] for p in parts], dtype=np.int32)
        self.labels = label_of_part[self.part] if len(parts) else np.zeros(0, dtype=np.int32)
        self.ranges = ranges
        self.dynamic_parts = [i for i, p in enumerate(parts) if p.dynamic]
        self.world = self.local.copy()
        self.world_normals = self.local_normals.copy()
        self.labels.flags.writeable = False
        self.update(parts)

    def __len__(self) -> int:
        return len(self.local)

    @property
    def dynamic_mask(self) -> np.ndarray:
        mask = np.zeros(len(self), dtype=bool)
        for i in self.dynamic_parts:
            a, b = self.ranges[i]
            mask[a:b] = True
        return mask

    def update(self, parts: list[MeshPart]) -> None:
        """Recompute world positions and normals of dynamic points from the parts' matrices.

        ``world`` is replaced by a new read-only array (copy on write), so arrays handed out
        earlier keep describing the frame they were taken at.
        """
        if not self.dynamic_parts:
            self.world.flags.writeable = False
            return
        self.world = self.world.copy()
        for i in self.dynamic_parts:
            a, b = self.ranges[i]
            if a == b:
                continue
            m = parts[i].matrix
            self.world[a:b] = self.local[a:b] @ m[:3, :3].T + m[:3, 3]
            n = self.local_normals[a:b] @ np.linalg.inv(m[:3, :3])  # inverse-transpose
            norm = np.linalg.norm(n, axis=1, keepdims=True)
            self.world_normals[a:b] = np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)
        self.world.flags.writeable = False

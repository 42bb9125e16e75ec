"""The scene's surface point cloud: sampled once, moved with dynamic parts every frame."""

from __future__ import annotations

import numpy as np

from .camera import apply_affine, turn_normals
from .parts import MeshPart
from .sampling import ground_height, outward_normals, sample_part, triangle_areas
from .seeding import stream

# a guard against clouds no machine holds (~220 bytes a point at the peak, measured: ~11 GB):
# twice the batch job's budget (batch/config.py MAX_SCORING_POINTS), so that the budget, checked
# before rendering on the points actually sampled, stays the one a run meets
MAX_POINTS = 50_000_000


class SurfacePoints:
    """Points sampled on every part (but not on faces resting on the ground:
    :func:`.sampling.contact_faces`, judged at the parts' current matrices), stored part by
    part in contiguous ranges.

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
        ground_z = ground_height(parts)
        area = sum(float(triangle_areas(np.asarray(p.vertices, np.float64), np.asarray(p.faces, np.int64)).sum())
                   for p in parts if len(p.faces) and not p.scenery)
        if density * area > MAX_POINTS:
            raise ValueError(f"points density {density:g} per m^2: this scene has {area:,.0f} m^2 of surface, so about "
                             f"{density * area:,.0f} points; the limit is {MAX_POINTS:,} (lower the density)")
        for i, p in enumerate(parts):
            rng = stream(seed, "surface-points", p.name)
            pts, face = sample_part(p, density, rng, ground_z)
            nrm = outward_normals(p, face)
            locals_.append(pts)
            normals.append(nrm)
            part_idx.append(np.full(len(pts), i, dtype=np.int32))
            ranges[i] = start, start + len(pts)
            start += len(pts)
        label_of_part = np.array([label_ids[p.label] for p in parts], dtype=np.int32)
        part = np.concatenate(part_idx) if part_idx else np.zeros(0, dtype=np.int32)
        self._init_arrays(parts, np.concatenate(locals_) if locals_ else np.zeros((0, 3)),
                          np.concatenate(normals) if normals else np.zeros((0, 3)), part,
                          label_of_part[part] if len(parts) else np.zeros(0, dtype=np.int32), ranges)

    @classmethod
    def from_arrays(cls, parts: list[MeshPart], local: np.ndarray, local_normals: np.ndarray, part: np.ndarray,
                    labels: np.ndarray) -> "SurfacePoints":
        """Points stored earlier (e.g. in ground_truth/scene.h5), part by part in order."""
        part = np.asarray(part, dtype=np.int32)
        if np.any(np.diff(part) < 0):
            raise ValueError("surface points must be stored part by part, in part order")
        edges = np.searchsorted(part, np.arange(len(parts) + 1))
        ranges = np.column_stack([edges[:-1], edges[1:]]).astype(np.int64)
        self = cls.__new__(cls)
        self._init_arrays(parts, np.asarray(local, np.float64), np.asarray(local_normals, np.float64), part,
                          np.asarray(labels, np.int32), ranges)
        return self

    def _init_arrays(self, parts, local, local_normals, part, labels, ranges) -> None:
        self.local, self.local_normals, self.part, self.labels, self.ranges = local, local_normals, part, labels, ranges
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

    def table(self) -> dict:
        """Copies of ``local``, ``labels``, ``part`` (as ``instance``) and ``dynamic_object``
        (N,) int32: the point's index among the dynamic parts in part order (-1: static)."""
        dyn_index = np.full(len(self.ranges), -1, dtype=np.int32)
        dyn_index[self.dynamic_parts] = np.arange(len(self.dynamic_parts), dtype=np.int32)
        return {"local": self.local.copy(), "labels": self.labels.copy(), "instance": self.part.copy(),
                "dynamic_object": dyn_index[self.part]}

    def sample(self) -> dict:
        """Copies of ``local``, ``local_normals``, ``part`` and ``labels`` (writable)."""
        return {"local": self.local.copy(), "local_normals": self.local_normals.copy(), "part": self.part.copy(),
                "labels": np.array(self.labels)}

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
            self.world[a:b] = apply_affine(m, self.local[a:b])
            self.world_normals[a:b] = turn_normals(m, self.local_normals[a:b])
        self.world.flags.writeable = False

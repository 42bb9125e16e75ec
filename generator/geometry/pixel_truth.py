"""The surface at every pixel centre, by ray casting the scene's own triangles: the source
of ``Simulator.render()``'s depth, labels and instance ids (``ground_truth="geometry"``,
the default) and of ``render_geometry()`` (normals, optical flow). bpy-free.

One ray per pixel centre (generator/geometry/raycam.py) into the simulated parts and, when
the Simulator filters objects out (``filter_object_names``), into those objects too: they
are not simulated (no points, no label, no collisions) but are still surfaces in the image,
so a pixel whose nearest surface is a filtered object has its depth and part index -1
(unlabelled), as in the renderer's own passes.

The answer depends only on the triangles, the pose and the camera: never on the render
engine, its device (CPU or GPU), its samples or its seed (docs/rendering.md). The last
answer is kept while the pose, the camera and the geometry stay, so ``render()`` and the
geometry modalities of one frame cast once.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .lens import PINHOLE, Lens
from .raycam import PixelHits, RayCamera
from .raycast import SceneGeometry

# Where the Simulator's ground truth comes from (``Simulator(ground_truth=...)``):
# "geometry": ray casting the scene's triangles at the pixel centres (this module);
# "renderer": the renderer's own passes (Cycles' Depth and Object Index, the paper's way).
GROUND_TRUTH_SOURCES = ("geometry", "renderer")


def check_ground_truth(source: str) -> str:
    """``source`` if it is one of GROUND_TRUTH_SOURCES, else a one-line ValueError."""
    if source not in GROUND_TRUTH_SOURCES:
        raise ValueError(f"ground_truth must be one of {', '.join(map(repr, GROUND_TRUTH_SOURCES))}, got {source!r}")
    return source


@dataclass(frozen=True)
class CameraModel:
    """What a pixel ray depends on besides the pose: intrinsics (3, 3), image size, the
    clip range (planar metres) and the lens model."""

    K: np.ndarray
    width: int
    height: int
    clip_start: float
    clip_end: float
    lens: Lens = PINHOLE


def nearer(hits: PixelHits, other: PixelHits) -> PixelHits:
    """Per pixel, the nearer surface of two casts of the same rays; a surface of ``other``
    counts as unlabelled (part -1). Ties go to ``hits``."""
    closer = other.depth < hits.depth
    normal = None
    if hits.normal is not None and other.normal is not None:
        normal = np.where(closer[..., None], other.normal, hits.normal)
    return PixelHits(np.where(closer, other.depth, hits.depth), np.where(closer, -1, hits.part), normal)


class PixelTruth:
    """Pixel-centre hits of ``geometry`` (the simulated parts) and ``occluders`` (filtered
    objects; None if there are none), with the last answer kept."""

    def __init__(self, geometry: SceneGeometry, occluders: SceneGeometry | None = None):
        self.geometry, self.occluders = geometry, occluders
        self._camera: RayCamera | None = None
        self._key, self._hits = None, None

    def hits(self, camera: CameraModel, world_from_camera: np.ndarray, normals: bool) -> PixelHits:
        """First surface through every pixel centre from the pose ``world_from_camera`` (4x4,
        OpenCV): depth (H, W) float32 planar metres (+inf: none), part (H, W) int64 (-1: none
        or a filtered object), normal (H, W, 3) camera frame or None without ``normals``.
        The arrays are shared with the next call at the same state: copy before changing."""
        self._ray_camera(camera)
        pose = np.asarray(world_from_camera, dtype=np.float64)
        key = (pose.tobytes(), self.geometry.version, self.occluders.version if self.occluders else 0)
        if self._hits is not None and self._key == key and (self._hits.normal is not None or not normals):
            return self._hits if normals or self._hits.normal is None else replace(self._hits, normal=None)
        hits = self._camera.cast(self.geometry, pose, normals=normals)
        if self.occluders is not None:
            hits = nearer(hits, self._camera.cast(self.occluders, pose, normals=normals))
        self._key, self._hits = key, hits
        return hits


    def _ray_camera(self, camera: CameraModel) -> RayCamera:
        """The pixel-centre rays of ``camera`` (made again when the camera changed)."""
        args = (camera.K, camera.width, camera.height, camera.clip_start, camera.clip_end, camera.lens)
        if self._camera is None or not self._camera.matches(*args):
            self._camera, self._hits = RayCamera(*args), None
        return self._camera

    def rolling_hits(self, camera: CameraModel, rolling, index: int, part_of_object: list[int],
                     normals: bool) -> tuple[PixelHits, np.ndarray, np.ndarray, float]:
        """Frame ``index`` of a trajectory through a rolling shutter (``rolling``: a
        generator/geometry/rolling.py ``RollingCamera``): every row cast from the camera's pose
        at the row's time, the moving objects (object d is part ``part_of_object[d]``) placed
        at the middle time of each band of rows (``rolling.slices``), then put back. Returns
        (the hits as :meth:`hits`, row poses (H, 4, 4), every row's objects' matrices
        (H, D, 4, 4), the bands' motion bound in metres). The answer is kept as the one of
        the frame's pose: the render of this view reads it (:meth:`hold`)."""
        rays = self._ray_camera(camera)
        poses = rolling.row_poses(index)
        bands, bound = rolling.slices(index)
        rows_objects = np.zeros((camera.height, len(part_of_object), 4, 4))
        kept = {i: self.geometry.parts[i].matrix.copy() for i in part_of_object}
        pieces = []
        placements = rolling.objects_at(index, [middle for _, _, middle in bands])  # (bands, D, 4, 4)
        try:
            for (first, end, _), placed in zip(bands, placements):
                rows_objects[first:end] = placed
                self.geometry.set_matrices({i: placed[d] for d, i in enumerate(part_of_object)})
                hits = rays.cast_rows(self.geometry, poses[first:end], first, end, normals)
                if self.occluders is not None:
                    hits = nearer(hits, rays.cast_rows(self.occluders, poses[first:end], first, end, normals))
                pieces.append(hits)
        finally:
            self.geometry.set_matrices(kept)
        hits = PixelHits(np.concatenate([h.depth for h in pieces]), np.concatenate([h.part for h in pieces]),
                         np.concatenate([h.normal for h in pieces]) if normals else None)
        return hits, poses, rows_objects, bound

    def forget(self) -> None:
        """Drop the kept answer (the camera's shutter changed: a held rolling-shutter cast is
        no longer the view's)."""
        self._key, self._hits = None, None

    def hold(self, hits: PixelHits, world_from_camera: np.ndarray) -> None:
        """Keep ``hits`` as the answer for the pose ``world_from_camera`` at the current state
        (a rolling-shutter cast, which the render of that view reads)."""
        pose = np.asarray(world_from_camera, dtype=np.float64)
        self._key = (pose.tobytes(), self.geometry.version, self.occluders.version if self.occluders else 0)
        self._hits = hits

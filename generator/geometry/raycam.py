"""A geometric camera: depth, labels, instances and normals by ray casting, no renderer.

One ray leaves the camera centre through each pixel centre (x, y) = (j + 0.5, i + 0.5),
bent by the camera's lens model where it has one (generator/geometry/lens.py), and stops at the first triangle of the scene's geometry (open3d / Embree, on the same
rigid parts as the Simulator's visibility and collisions). The conventions are those of
``Simulator.render()`` (docs/conventions.md):

- depth: (H, W) float32 planar depth (camera-frame z) in metres, +inf where no surface;
  like Cycles, surfaces are clipped by planar depth at ``clip_start`` (the ray starts
  there, so a surface nearer than it is seen through) and ``clip_end`` (no surface past it);
- seg: (H, W) int32 label ids (index into ``Simulator.labels``), -1 where no surface;
- instance: (H, W) int32 object ids (index into ``Simulator.object_names``), -1 = none;
- normal: (H, W, 3) float32 unit normal of the triangle hit, in the OpenCV camera frame
  (x right, y down, z forward), turned to face the camera; zero where no surface.

There is no RGB (``rgb`` and ``rgb_linear`` are None): colour needs a renderer. Labels are
those of the surface at the pixel centre, as ``render()`` with ``segmentation_sensitivity``
0. bpy-free (numpy and open3d).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..passes import RenderOutput
from .camera import rows_times
from .lens import PINHOLE, Lens
from .raycast import SceneGeometry


@dataclass
class GeometricRender(RenderOutput):
    """What ``Simulator.render(engine="raycast")`` returns: a :class:`RenderOutput` (it
    unpacks as ``rgb, depth, seg``) with ``rgb`` and ``rgb_linear`` None and, in addition,
    ``normal`` (H, W, 3) float32 (see the module's docstring for every convention)."""

    normal: np.ndarray | None = None


@dataclass(frozen=True)
class PixelHits:
    """First surface through each pixel centre: ``depth`` (H, W) float32 planar metres (+inf
    for none), ``part`` (H, W) int64 part index (-1 for none), ``normal`` (H, W, 3) float32
    camera-frame unit normals facing the camera (zero for none) or None if not asked."""

    depth: np.ndarray
    part: np.ndarray
    normal: np.ndarray | None


class RayCamera:
    """Casts the pixel-centre rays of a pinhole camera ``K`` (3x3, pixels) with an image of
    ``width`` x ``height`` pixels and the clip range ``[clip_start, clip_end]`` (planar
    metres). The camera-frame rays are computed once."""

    def __init__(self, K: np.ndarray, width: int, height: int, clip_start: float = 0.0, clip_end: float = np.inf,
                 lens: Lens = PINHOLE):
        K = np.asarray(K, dtype=np.float64)
        if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0:
            raise ValueError(f"K must be a finite 3x3 pinhole matrix with positive focal lengths, got {K.tolist()}")
        if int(width) < 1 or int(height) < 1:
            raise ValueError(f"image size must be at least 1x1 pixels, got {width}x{height}")
        if not (0.0 <= clip_start < clip_end):
            raise ValueError(f"clip range must satisfy 0 <= clip_start < clip_end, got {clip_start}, {clip_end}")
        self.K, self.width, self.height = K.copy(), int(width), int(height)
        self.clip_start, self.clip_end = float(clip_start), float(clip_end)
        lens.check(K, self.width, self.height)
        self.lens = lens
        self._rays = np.ascontiguousarray(lens.rays(K, self.width, self.height).reshape(-1, 3))  # camera z = 1

    def matches(self, K: np.ndarray, width: int, height: int, clip_start: float, clip_end: float,
                lens: Lens = PINHOLE) -> bool:
        """True if this camera was built for these intrinsics, size, clip range and lens."""
        return (int(width), int(height), float(clip_start), float(clip_end), lens) == (
            self.width, self.height, self.clip_start, self.clip_end, self.lens) and np.array_equal(K, self.K)

    def cast(self, geometry: SceneGeometry, world_from_camera: np.ndarray, normals: bool = True) -> PixelHits:
        """First hits of every pixel-centre ray from the pose ``world_from_camera`` (4x4)."""
        pose = np.asarray(world_from_camera, dtype=np.float64)
        rot = pose[:3, :3]
        dirs = rows_times(self._rays, rot.T)  # world directions with unit camera-frame z: t = planar depth
        origins = pose[:3, 3] + self.clip_start * dirs  # the ray starts on the near clip plane
        return self._hits(geometry, origins, dirs, lambda n: rows_times(n, rot), self._rays, normals)

    def cast_rows(self, geometry: SceneGeometry, row_poses: np.ndarray, first: int, end: int,
                  normals: bool = True) -> PixelHits:
        """First hits of the pixel-centre rays of rows ``first`` to ``end`` - 1, row r's from
        its own pose ``row_poses[r - first]`` (a rolling shutter: generator/geometry/rolling.py);
        the (end - first, W) images of :meth:`cast`, planar depth in each row's camera."""
        from .rolling import pixel_rows_times

        poses = np.asarray(row_poses, dtype=np.float64)
        rays = self._rays[first * self.width:end * self.width]
        dirs = pixel_rows_times(rays, poses[:, :3, :3].transpose(0, 2, 1), self.width)
        origins = np.repeat(poses[:, :3, 3], self.width, axis=0) + self.clip_start * dirs
        to_camera = lambda n: pixel_rows_times(n, poses[:, :3, :3], self.width)  # noqa: E731
        return self._hits(geometry, origins, dirs, to_camera, rays, normals, end - first)

    def _hits(self, geometry, origins, dirs, to_camera, rays, normals: bool, rows: int | None = None) -> PixelHits:
        """The images of a cast of the world rays (``origins``, ``dirs``) of ``rows`` rows
        (default: all); ``to_camera`` turns world normals into the camera frame."""
        if normals:
            t, part, normal = geometry.cast_with_normals(origins, dirs)
        else:
            t, part = geometry.cast(origins, dirs)
        depth = t + self.clip_start
        hit = (part >= 0) & np.isfinite(t) & (depth <= self.clip_end)
        h, w = self.height if rows is None else rows, self.width
        depth_img = np.where(hit, depth, np.inf).astype(np.float32).reshape(h, w)
        part_img = np.where(hit, part, -1).reshape(h, w)
        normal_img = None
        if normals:
            n = to_camera(normal)  # world -> camera frame
            n *= np.where((n * rays).sum(axis=1) > 0, -1.0, 1.0)[:, None]  # face the camera
            normal_img = np.where(hit[:, None], n, 0.0).astype(np.float32).reshape(h, w, 3)
        return PixelHits(depth_img, part_img, normal_img)


def labels_of_parts(part_labels: list[str], label_ids: dict[str, int]) -> np.ndarray:
    """Label id (P,) int32 of each part, from the part's label name."""
    return np.array([label_ids[name] for name in part_labels], dtype=np.int32).reshape(-1)


def geometric_render(hits: PixelHits, label_of_part: np.ndarray, K: np.ndarray, world_from_camera: np.ndarray,
                     frame: int) -> GeometricRender:
    """A :class:`GeometricRender` from pixel hits; ``label_of_part`` (P,) int32 maps part
    indices (= instance ids) to label ids."""
    inst = hits.part.astype(np.int32)
    seg = np.where(inst >= 0, label_of_part[np.maximum(inst, 0)], -1).astype(np.int32)
    return GeometricRender(rgb=None, depth=hits.depth.copy(), seg=seg, instance=inst, rgb_linear=None,
                           K=np.array(K, dtype=np.float64), world_from_camera=np.array(world_from_camera, dtype=np.float64),
                           frame=int(frame), normal=None if hits.normal is None else hits.normal.copy())

"""The surface seen at each pixel centre, and where it goes: normals and optical flow (bpy-free).

:class:`PixelGeometry` holds, for one frame of a trajectory, the first surface hit by the ray
through every pixel centre (x, y) = (j + 0.5, i + 0.5) (``generator.geometry.raycam``), the
camera poses of every frame and the dynamic objects' matrices at every frame (all known up
front). The geometry modalities (``exporters.modalities``) are computed from it:

- ``world_normals()``: (H, W, 3) float32 unit normals of the triangle hit, world frame,
  turned toward the camera; 0 where there is no surface. Objects in the Simulator's
  ``filter_object_names`` are surfaces too (unlabelled: part -1, depth and normal kept).
- ``flow_to(t)``: (H, W, 2) float32 pixels: where the surface point seen at the pixel centre,
  moving rigidly with its object (static surfaces do not move), projects in frame ``t``,
  minus the pixel centre. NaN where there is no surface, no frame ``t``, or the point is not
  in front of camera ``t`` (planar depth <= 0), and on filtered objects (their motion is not
  tracked). Occlusion in frame ``t`` does not matter.

Through a rolling shutter (``rolling``: generator/geometry/rolling.py) each row's hits were
cast from the camera's pose at the row's time, with the moving objects where they stood then
(``row_poses``, ``row_objects``); the surface points are those, and ``flow_to(t)`` is where
each lands in frame t's rolling-shutter image (``RollingCamera.project``).
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

from .camera import affine_inverse, matmul_exact, rows_times
from .lens import PINHOLE, Lens
from .rolling import pixel_rows_times


class PixelGeometry:
    """One frame's pixel-centre hits with the trajectory's motion.

    K (3, 3), width, height: the camera; index: this frame's index into ``poses``.
    poses (T, 4, 4): OpenCV world_from_camera of every frame.
    depth (H, W): planar depth of the hit (inf: none); part (H, W) int: part index hit (-1: none).
    normal_camera (H, W, 3): camera-frame unit normals facing the camera (0: none).
    dynamic_slot (P,) int: for each part, its index into ``object_matrices``' second axis
    (-1 for static parts); object_matrices (T, D, 4, 4): world_from_object at every frame.
    lens: the camera's lens model (generator/geometry/lens.py; default the ideal pinhole).
    rolling: a rolling shutter's (RollingCamera, row poses (H, 4, 4), row objects' matrices
    (H, D, 4, 4)) or None (a global shutter).
    """

    def __init__(self, K, width: int, height: int, index: int, poses, depth, part, normal_camera,
                 dynamic_slot, object_matrices, lens: Lens = PINHOLE, rolling=None):
        self.K, self.lens = np.asarray(K, np.float64), lens
        self.width, self.height, self.index = int(width), int(height), int(index)
        self.poses = np.asarray(poses, np.float64)
        self.depth, self.part = np.asarray(depth), np.asarray(part)
        self.normal_camera = np.asarray(normal_camera) if normal_camera is not None else None
        self.dynamic_slot = np.asarray(dynamic_slot, np.int64)
        self.object_matrices = np.asarray(object_matrices, np.float64)
        self.rolling = rolling

    @property
    def surface(self) -> np.ndarray:
        """(H, W) bool: a surface is seen at the pixel centre (filtered objects included)."""
        return np.isfinite(self.depth)

    @property
    def hit(self) -> np.ndarray:
        """(H, W) bool: a simulated part is seen at the pixel centre (its motion is known)."""
        return (self.part >= 0) & np.isfinite(self.depth)

    @cached_property
    def world_points(self) -> np.ndarray:
        """(H, W, 3) float64 world positions of the surface points at this frame (NaN: none)."""
        rays = self.lens.rays(self.K, self.width, self.height)  # camera frame, z = 1
        cam = rays * np.where(self.hit, self.depth, np.nan)[..., None]
        if self.rolling is not None:  # each row from its own pose
            poses = self.rolling[1]
            world = pixel_rows_times(cam.reshape(-1, 3), poses[:, :3, :3].transpose(0, 2, 1), self.width)
            return (world + np.repeat(poses[:, :3, 3], self.width, axis=0)).reshape(cam.shape)
        pose = self.poses[self.index]
        return rows_times(cam, pose[:3, :3].T) + pose[:3, 3]

    def world_normals(self) -> np.ndarray:
        """(H, W, 3) float32 unit normals in the world frame, facing the camera (0: none)."""
        if self.normal_camera is None:
            raise ValueError("these pixel hits were cast without normals")
        if self.rolling is not None:
            rotations = self.rolling[1][:, :3, :3].transpose(0, 2, 1)
            n = pixel_rows_times(self.normal_camera.reshape(-1, 3), rotations, self.width).reshape(self.normal_camera.shape)
        else:
            n = rows_times(self.normal_camera, self.poses[self.index][:3, :3].T)
        return np.where(self.surface[..., None], n, 0.0).astype(np.float32)

    def points_at(self, t: int) -> np.ndarray:
        """(H, W, 3) world positions at frame ``t`` of the surface points seen at this frame,
        each moved rigidly with its object (NaN: none)."""
        x = self.world_points
        if t == self.index or self.object_matrices.shape[1] == 0:
            return x.copy()
        m_now, m_then = self.object_matrices[self.index], self.object_matrices[t]
        moves = matmul_exact(m_then, affine_inverse(m_now))  # (D, 4, 4): this frame's world -> frame t's world
        slot = np.where(self.part >= 0, self.dynamic_slot[np.maximum(self.part, 0)], -1)
        out = x.copy()
        dyn = slot >= 0
        if dyn.any():
            m = moves[slot[dyn]]
            out[dyn] = rows_times(x[dyn], m[:, :3, :3].transpose(0, 2, 1)) + m[:, :3, 3]
        return out

    def flow_to(self, t: int) -> np.ndarray:
        """(H, W, 2) float32 optical flow in pixels to frame ``t`` (NaN: no surface, no frame
        ``t``, or behind camera ``t``)."""
        shape = (self.height, self.width, 2)
        if not 0 <= t < len(self.poses):
            return np.full(shape, np.nan, np.float32)
        if self.rolling is not None:
            return self._rolling_flow_to(t)
        x = self.points_at(t)
        pose = self.poses[t]
        cam = rows_times(x - pose[:3, 3], pose[:3, :3])  # world -> camera t (rotation transposed)
        z = cam[..., 2]
        with np.errstate(invalid="ignore", divide="ignore"):
            front = z > 0
            if self.lens.ideal:
                uvw = rows_times(cam, self.K.T)
                u, v = uvw[..., 0] / z, uvw[..., 1] / z
            else:
                uv, _ = self.lens.project(self.K, cam.reshape(-1, 3))
                u, v = uv[:, 0].reshape(z.shape), uv[:, 1].reshape(z.shape)
        jj, ii = np.meshgrid(np.arange(self.width) + 0.5, np.arange(self.height) + 0.5)
        flow = np.stack([u - jj, v - ii], axis=-1)
        flow[~(front & self.hit)] = np.nan
        return flow.astype(np.float32)

    def _rolling_flow_to(self, t: int) -> np.ndarray:
        """:meth:`flow_to` through a rolling shutter: each surface point in its object's frame
        (at its row's time), landed in frame ``t``'s image by ``RollingCamera.project``."""
        camera, _, row_objects = self.rolling
        x = self.world_points.reshape(-1, 3)
        slot = np.where(self.part >= 0, self.dynamic_slot[np.maximum(self.part, 0)], -1).reshape(-1)
        local = x.copy()
        rows = np.repeat(np.arange(self.height), self.width)
        for d in np.unique(slot[slot >= 0]):
            at = np.flatnonzero(slot == d)
            for r in np.unique(rows[at]):  # the object's matrix at the row's time, inverted
                sel = at[rows[at] == r]
                inverse = affine_inverse(row_objects[r, d])
                local[sel] = rows_times(x[sel], inverse[:3, :3].T) + inverse[:3, 3]
        seen = np.flatnonzero(self.hit.reshape(-1))
        uv = np.full((len(x), 2), np.nan)
        z = np.full(len(x), np.nan)
        uv[seen], z[seen] = camera.project(t, local[seen], slot[seen], self.K, self.lens)
        jj, ii = np.meshgrid(np.arange(self.width) + 0.5, np.arange(self.height) + 0.5)
        flow = np.stack([uv[:, 0].reshape(jj.shape) - jj, uv[:, 1].reshape(ii.shape) - ii], axis=-1)
        with np.errstate(invalid="ignore"):
            flow[~((z.reshape(jj.shape) > 0) & self.hit)] = np.nan
        return flow.astype(np.float32)

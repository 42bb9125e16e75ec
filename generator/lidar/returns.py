"""What one LiDAR sweep gives (:class:`Scan`), bpy-free. Conventions (docs/lidar.md):

- the sensor frame is KITTI's Velodyne frame: x forward, y left, z up, metres, origin at the
  sensor's optical centre;
- a sweep starts at ``start_time_s`` (seconds on the trajectory's clock: 0 at its first
  frame); every return carries ``time``, seconds after that start, when its beam was fired;
- ``world_from_sensor`` (4x4) is the sensor's pose at the sweep's start, its reference time;
- ``xyz`` is what the sensor reports: each return in the sensor frame at its own time (the
  sweep is skewed by the sensor's motion and by the objects' motion); ``xyz_deskewed`` is
  the sweep with the scene frozen at the reference time: each return's surface point where
  it was at the sweep's start (moved with its object if the object moves), in the sensor
  frame at that time (world = world_from_sensor @ xyz_deskewed);
- ``label`` is the class id of the surface hit (generator/scene/taxonomy.py: the
  Simulator's label ids), ``instance`` its object's id (the ``instance`` modality's: index
  into the run's instances table); every return hits a surface, so neither is ever unset;
- ``xyz_exact`` (ground truth, None where not kept): the surface point each beam met, without
  the range noise, in the frame of ``xyz_deskewed`` (the scene frozen at the reference time);
- ``change``: on a timeline's stage k > 0, the change status of the object hit since stage
  k - 1 (exporters.changes.STATUS codes: 0 unchanged, 1 added, 2 removed, 3 moved, 4 grown);
  None elsewhere.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Scan:
    """One sweep of one sensor: N returns, ordered by firing time."""

    sensor: str  # the sensor's name (a preset's, or a user-built sensor's)
    index: int  # the sweep's number within its trajectory, from 0
    start_time_s: float
    world_from_sensor: np.ndarray  # (4, 4) float64
    xyz: np.ndarray  # (N, 3) float32, metres, sensor frame at each return's time
    xyz_deskewed: np.ndarray  # (N, 3) float32, metres, sensor frame at the reference time
    intensity: np.ndarray  # (N,) float32 in [0, 1] (docs/lidar.md, "Intensity")
    ring: np.ndarray  # (N,) uint16 beam index (0: the sensor's lowest beam)
    time: np.ndarray  # (N,) float32 seconds after start_time_s
    label: np.ndarray  # (N,) uint16 class id
    instance: np.ndarray  # (N,) uint16 object id
    change: np.ndarray | None = None  # (N,) int8 change status, or None
    xyz_exact: np.ndarray | None = None  # (N, 3) float32: xyz_deskewed without the range noise (ground truth)

    def __post_init__(self):
        n = len(self.xyz)
        for name in ("xyz_deskewed", "intensity", "ring", "time", "label", "instance"):
            if len(getattr(self, name)) != n:
                raise ValueError(f"Scan: {name} has {len(getattr(self, name))} rows, xyz has {n}")
        for name in ("change", "xyz_exact"):
            value = getattr(self, name)
            if value is not None and len(value) != n:
                raise ValueError(f"Scan: {name} has {len(value)} rows, xyz has {n}")

    def __len__(self) -> int:
        return len(self.xyz)

    def world_points(self) -> np.ndarray:
        """(N, 3) float64 world positions of the returns (from the de-skewed points and the
        reference pose)."""
        from ..geometry.camera import apply_affine

        return apply_affine(self.world_from_sensor, self.xyz_deskewed.astype(np.float64))

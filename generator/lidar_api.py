"""``Simulator.scan(sensor)``: a LiDAR sweep from the Simulator's camera, on its public API (a
mixin, bpy-free; docs/lidar.md).

The sensor rides on the camera's body (its centre, heading along its view turned level:
generator/geometry/motion.py ``body_pose``) with its mount; the scene holds still at the
Simulator's current frame (a Simulator shows one frame at a time: the batch job's
``--lidar`` sweeps through the animation, with the machines moving during each sweep).
"""

from __future__ import annotations

import numpy as np

from .checks import check_flag, check_integer


class LidarScans:
    """Adds :meth:`scan` to the Simulator."""

    def scan(self, sensor="vlp16", index: int = 0, noise: bool = True):
        """One sweep of ``sensor`` (a preset's name, ``NAME@drone``, or a
        :class:`generator.lidar.sensors.Lidar`) from the current camera at the current frame:
        a :class:`generator.lidar.scanner.Sweep` (``.scan``: the returns as written to files,
        :class:`generator.lidar.returns.Scan`; ``.world``: their float64 world positions).
        ``index`` picks the sweep's noise stream (and a rosette's part of its pattern);
        ``noise=False`` gives exact ranges. Label ids are ``labels``' and object ids
        ``object_names``' (as ``render()``'s)."""
        from .geometry.motion import MotionTrack, body_pose
        from .lidar.sensors import Lidar, lidar

        if not isinstance(sensor, Lidar):
            sensor = lidar(sensor)
        index = check_integer("index", index, 0, 1 << 31)
        scanner = self._lidar_scanner()
        dynamic = scanner.geometry.dynamic_index  # the dynamic parts, in dynamic_objects order
        scanner.geometry.set_matrices(dict(zip(dynamic, self.dynamic_object_matrices())))
        body = MotionTrack(np.zeros(1), body_pose(self.get_world_from_camera())[None])
        return scanner.sweep(sensor, index, 0.0, body, noise=check_flag("noise", noise))

    def _lidar_scanner(self):
        """The Scanner over this Simulator's parts (built on first use: its own two Embree
        structures over the same triangles)."""
        from .lidar.scanner import Scanner

        if getattr(self, "_lidar", None) is None:
            parts = self.scene_parts()
            self._lidar = Scanner.of_parts(parts, [self.label_ids[p.label] for p in parts], self.seed)
        return self._lidar

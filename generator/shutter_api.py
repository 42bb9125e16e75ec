"""``Simulator.set_shutter``: motion blur and a rolling shutter, on the Simulator's public API (a
mixin; docs/cameras.md, "Motion blur" and "Rolling shutter").

With the shutter open for S seconds, Cycles renders the colour (``rgb``, ``rgb_linear``)
exposed from t - S/2 to t + S/2 around the frame's time t: moving objects by their animation,
and the camera along its trajectory when the render knows it (``render_outputs`` with
``poses``: the batch job). Every geometry modality (depth, labels, ids, normals, flow,
tracks, boxes) stays that of the frame time t, the middle of the exposure.

With a rolling-shutter readout of R seconds, row r (0 at the top) is exposed around
t + ((r + 1) / H - 1/2) R (generator/geometry/rolling.py), the colour by Cycles and the
ground truth by casting each row from the camera's pose at that time with the machines where
they stood then; views are rendered along a trajectory (``render_outputs`` with ``poses``).
"""

from __future__ import annotations

import contextlib

import numpy as np

from .checks import check_number


class Shutters:
    """Adds :meth:`set_shutter`, :attr:`shutter_s` and :meth:`camera_motion` to the Simulator."""

    shutter_s: float = 0.0
    readout_s: float = 0.0

    def set_shutter(self, seconds: float = 0.0, readout_s: float = 0.0) -> float:
        """Open the shutter for ``seconds`` (0: no motion blur, as by default; at most one frame
        interval, 1 / fps), centred on each frame's time; ``readout_s``: a rolling shutter
        reading the rows top to bottom over this many seconds (0: a global shutter; at most
        one frame interval). Motion blur needs ``ground_truth="geometry"`` (the renderer's own
        depth and id passes would be blurred). Returns the shutter."""
        from .blender.shutter import apply_shutter

        self._check_current()
        seconds = check_number("shutter seconds", seconds, 0.0, 1.0 / self.fps)
        readout_s = check_number("rolling-shutter readout seconds", readout_s, 0.0, 1.0 / self.fps)
        if seconds > 0 and self.ground_truth != "geometry":
            raise ValueError("motion blur needs ground_truth='geometry': the renderer's depth and id passes would be "
                             "blurred")
        apply_shutter(seconds, self.fps, readout_s)
        self.shutter_s, self.readout_s = seconds, readout_s
        self._rolling_view = None  # no view cast through this shutter yet
        self._views.pixel_truth.forget()  # nor kept for the next render
        return seconds

    def rolling_geometry(self, poses: np.ndarray, object_matrices: np.ndarray, index: int, normals: bool = True):
        """View ``index`` of the trajectory ``poses`` (T, 4, 4) with its moving objects'
        ``object_matrices`` (T, D, 4, 4), frame k at k / fps seconds, through the rolling
        shutter: (PixelHits, RollingCamera, row poses (H, 4, 4), row objects' matrices
        (H, D, 4, 4), the objects' placement bound in metres). The render of this view then
        takes its depth, labels and ids from these hits."""
        from .frame_outputs import dynamic_slots
        from .geometry.rolling import RollingCamera, RollingShutter

        self._check_current()
        if not np.allclose(poses[index], self.get_world_from_camera(), atol=1e-9):
            raise ValueError(f"poses[{index}] is not the Simulator's current pose")
        slots = dynamic_slots(self.object_names, self.dynamic_objects)
        part_of_object = [int(np.flatnonzero(slots == d)[0]) for d in range(len(self.dynamic_objects))]
        poses, object_matrices = np.asarray(poses, np.float64), np.asarray(object_matrices, np.float64)
        key = (self.readout_s, self.height, self.fps, poses.tobytes(), object_matrices.tobytes())
        cached = getattr(self, "_rolling_camera", None)
        if cached is None or cached[0] != key:  # one per trajectory: its motion tracks are made once
            radius = [self._parts[i].radius() for i in part_of_object]
            times = np.arange(len(poses), dtype=np.float64) / self.fps
            cached = (key, RollingCamera(RollingShutter(self.readout_s, self.height), times, poses, object_matrices,
                                         radius))
            self._rolling_camera = cached
        camera = cached[1]
        truth = self._views.pixel_truth
        hits, row_poses, row_objects, bound = truth.rolling_hits(self._camera_model(), camera, index, part_of_object,
                                                                 normals)
        truth.hold(hits, self.get_world_from_camera())
        self._rolling_view = (self.get_world_from_camera().tobytes(), self.frame)
        return hits, camera, row_poses, row_objects, bound

    def _check_rolling_view(self) -> None:
        """ValueError unless the current view's rows were cast (:meth:`rolling_geometry`) when
        a rolling shutter is set."""
        if self.readout_s > 0 and getattr(self, "_rolling_view", None) != (self.get_world_from_camera().tobytes(),
                                                                          self.frame):
            raise ValueError("a rolling shutter renders views along a trajectory (each row at its own time): call "
                             "render_outputs(names, poses, object_matrices, index)")

    def camera_motion(self, poses: np.ndarray, index: int):
        """A context for rendering view ``index`` of the trajectory ``poses`` (T, 4, 4) with the
        camera moving as it does around it (the current frame is that view's; the neighbours are
        the frames before and after); nothing to do while the shutter is closed."""
        if (self.shutter_s == 0 and self.readout_s == 0) or len(poses) < 2:
            return contextlib.nullcontext()
        from .blender.shutter import CameraPath

        if not np.allclose(poses[index], self.get_world_from_camera(), atol=1e-9):
            raise ValueError(f"poses[{index}] is not the Simulator's current pose")
        path = {self.frame + k: poses[index + k] for k in (-1, 0, 1) if 0 <= index + k < len(poses)}
        return CameraPath(self._camera, path, self.get_world_from_camera())

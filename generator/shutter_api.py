"""``Simulator.set_shutter``: motion blur, on the Simulator's public API (a mixin; docs/cameras.md,
"Motion blur").

With the shutter open for S seconds, Cycles renders the colour (``rgb``, ``rgb_linear``)
exposed from t - S/2 to t + S/2 around the frame's time t: moving objects by their animation,
and the camera along its trajectory when the render knows it (``render_outputs`` with
``poses``: the batch job). Every geometry modality (depth, labels, ids, normals, flow,
tracks, boxes) stays that of the frame time t, the middle of the exposure.
"""

from __future__ import annotations

import contextlib

import numpy as np

from .checks import check_number


class Shutters:
    """Adds :meth:`set_shutter`, :attr:`shutter_s` and :meth:`camera_motion` to the Simulator."""

    shutter_s: float = 0.0

    def set_shutter(self, seconds: float = 0.0) -> float:
        """Open the shutter for ``seconds`` (0: no motion blur, as by default; at most one frame
        interval, 1 / fps), centred on each frame's time. Needs ``ground_truth="geometry"``
        (the renderer's own depth and id passes would be blurred). Returns the shutter."""
        from .blender.shutter import apply_shutter

        self._check_current()
        seconds = check_number("shutter seconds", seconds, 0.0, 1.0 / self.fps)
        if seconds > 0 and self.ground_truth != "geometry":
            raise ValueError("motion blur needs ground_truth='geometry': the renderer's depth and id passes "
                             "would be blurred")
        apply_shutter(seconds, self.fps)
        self.shutter_s = seconds
        return seconds

    def camera_motion(self, poses: np.ndarray, index: int):
        """A context for rendering view ``index`` of the trajectory ``poses`` (T, 4, 4) with the
        camera moving as it does around it (the current frame is that view's; the neighbours are
        the frames before and after); nothing to do while the shutter is closed."""
        if self.shutter_s == 0 or len(poses) < 2:
            return contextlib.nullcontext()
        from .blender.shutter import CameraPath

        if not np.allclose(poses[index], self.get_world_from_camera(), atol=1e-9):
            raise ValueError(f"poses[{index}] is not the Simulator's current pose")
        path = {self.frame + k: poses[index + k] for k in (-1, 0, 1) if 0 <= index + k < len(poses)}
        return CameraPath(self._camera, path, self.get_world_from_camera())

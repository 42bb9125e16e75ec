"""Motion blur in Blender: the shutter, and the camera's motion around the frame being rendered
(docs/cameras.md, "Motion blur").

Cycles blurs what moves while the shutter is open: the objects by their animation, the camera
by its own. The Simulator places its camera with a matrix, not an animation, so for a render
of frame f of a known trajectory the camera is keyframed at f - 1, f and f + 1 with the
trajectory's poses there (linear interpolation) and the keys are removed after the render.
"""

from __future__ import annotations

import bpy
import numpy as np

from ..geometry.camera import blender_from_world_from_camera
from .animation import object_fcurves


def apply_shutter(seconds: float, fps: float, readout_s: float = 0.0) -> None:
    """Open the shutter for ``seconds`` centred on each frame's time (0: no motion blur), with
    a rolling shutter reading the rows top to bottom over ``readout_s`` (0: none). Cycles'
    rolling shutter spreads the rows over ``(1 - duration)`` of the shutter window and
    exposes each for ``duration`` of it: the window is seconds + readout_s and duration
    seconds / (seconds + readout_s) (generator/geometry/rolling.py gives the rows' times)."""
    scene = bpy.context.scene
    window = seconds + readout_s
    scene.render.use_motion_blur = window > 0
    if window > 0:
        scene.render.motion_blur_shutter = window * fps  # Blender counts it in frames
        scene.render.motion_blur_position = "CENTER"
        scene.cycles.rolling_shutter_type = "TOP" if readout_s > 0 else "NONE"
        scene.cycles.rolling_shutter_duration = seconds / window


class CameraPath:
    """A context: the camera keyframed at ``poses`` ({frame: OpenCV world_from_camera}),
    location and rotation (a quaternion, each key's sign the previous one's so that the path
    turns the short way) interpolated linearly; on exit the keys are removed and the camera is
    back at ``rest`` (the current pose) in its own rotation mode."""

    def __init__(self, cam, poses: dict[int, np.ndarray], rest: np.ndarray):
        self.cam, self.poses, self.rest = cam, poses, rest
        self.mode = cam.rotation_mode

    def __enter__(self):
        from mathutils import Matrix

        self.cam.rotation_mode = "QUATERNION"
        previous = None
        for frame, pose in sorted(self.poses.items()):
            location, rotation, _ = Matrix(blender_from_world_from_camera(pose).tolist()).decompose()
            if previous is not None and previous.dot(rotation) < 0:
                rotation.negate()
            self.cam.location, self.cam.rotation_quaternion, previous = location, rotation, rotation
            self.cam.keyframe_insert("location", frame=frame)
            self.cam.keyframe_insert("rotation_quaternion", frame=frame)
        for curve in object_fcurves(self.cam):
            for key in curve.keyframe_points:
                key.interpolation = "LINEAR"
        return self

    def __exit__(self, *exc):
        from mathutils import Matrix

        self.cam.animation_data_clear()
        self.cam.rotation_mode = self.mode
        self.cam.matrix_world = Matrix(blender_from_world_from_camera(self.rest).tolist())
        return False


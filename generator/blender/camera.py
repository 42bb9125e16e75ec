"""Read and write the scene camera: intrinsics from render settings, OpenCV poses."""

from __future__ import annotations

import bpy
import numpy as np

from ..geometry.camera import (
    Intrinsics,
    blender_from_world_from_camera,
    intrinsics_from_blender,
    world_from_camera_from_blender,
)
from . import session


class CameraError(ValueError):
    """The scene has no usable camera."""


def scene_camera():
    """The scene's active camera object, or raise CameraError."""
    scene = bpy.context.scene
    cam = scene.camera
    if cam is None:
        cams = sorted((o for o in scene.objects if o.type == "CAMERA"), key=lambda o: o.name)
        if not cams:
            raise CameraError("the scene has no camera; add one (Blender: Add > Camera) and make it active")
        cam = cams[0]
        scene.camera = cam
    if cam.type != "CAMERA":
        raise CameraError(f"the scene's active camera {cam.name!r} is not a camera object")
    if cam.data.type != "PERSP":
        raise CameraError(f"camera {cam.name!r} is {cam.data.type}; only perspective cameras are supported")
    return cam


def read_intrinsics(cam=None) -> Intrinsics:
    """K and image size of the render the scene is set up for (resolution percentage applied)."""
    cam = cam or scene_camera()
    r = bpy.context.scene.render
    width = int(r.resolution_x * r.resolution_percentage / 100)
    height = int(r.resolution_y * r.resolution_percentage / 100)
    d = cam.data
    return intrinsics_from_blender(
        width, height, d.lens, d.sensor_width, d.sensor_height, d.sensor_fit,
        d.shift_x, d.shift_y, r.pixel_aspect_x, r.pixel_aspect_y,
    )


def detach_camera(cam) -> None:
    """Make the camera the Simulator's: drop its animation and parent, keeping its current
    pose; drop the animation and drivers of its lens, shift, sensor and clip range (camera
    data), keeping their values at the current frame; and unbind cameras from timeline
    markers, so that no frame switches the render to another camera than ``cam``."""
    scene = bpy.context.scene
    if cam.data.animation_data is not None:
        session.set_frame(scene.frame_current)  # this frame's animated values written to the data
    world = cam.matrix_world.copy()
    cam.animation_data_clear()
    cam.data.animation_data_clear()
    cam.parent = None
    cam.constraints.clear()
    cam.matrix_world = world
    for marker in scene.timeline_markers:
        marker.camera = None
    scene.camera = cam


def read_pose(cam=None) -> np.ndarray:
    cam = cam or scene_camera()
    return world_from_camera_from_blender(np.array(cam.matrix_world))


def write_pose(world_from_camera: np.ndarray, cam=None) -> None:
    from mathutils import Matrix

    cam = cam or scene_camera()
    cam.matrix_world = Matrix(blender_from_world_from_camera(world_from_camera).tolist())


def clip_range(cam=None) -> tuple[float, float]:
    cam = cam or scene_camera()
    return float(cam.data.clip_start), float(cam.data.clip_end)

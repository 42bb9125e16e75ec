"""K and poses agree with Blender's own projection; project/unproject round trips."""

import math

import bpy
import numpy as np
import pytest
from bpy_extras.object_utils import world_to_camera_view

import scenes
from generator.blender import camera as bcam
from generator.geometry import camera as cm

CASES = [
    # width, height, sensor_fit, shift_x, shift_y, pixel_aspect_x, pixel_aspect_y
    (640, 480, "AUTO", 0.0, 0.0, 1, 1),
    (480, 640, "AUTO", 0.0, 0.0, 1, 1),
    (640, 480, "HORIZONTAL", 0.0, 0.0, 1, 1),
    (480, 640, "HORIZONTAL", 0.0, 0.0, 1, 1),
    (640, 480, "VERTICAL", 0.0, 0.0, 1, 1),
    (480, 640, "VERTICAL", 0.0, 0.0, 1, 1),
    (640, 480, "AUTO", 0.12, -0.07, 1, 1),
    (480, 640, "VERTICAL", -0.2, 0.15, 1, 1),
    # non-square pixels (Blender scales the vertical sensor by pixel_aspect_y / pixel_aspect_x)
    (640, 480, "VERTICAL", 0.0, 0.0, 1, 2),
    (640, 480, "VERTICAL", 0.1, -0.05, 3, 2),
    (480, 640, "AUTO", 0.1, -0.05, 1, 2),
    (640, 480, "AUTO", -0.1, 0.05, 2, 1),
    (640, 480, "HORIZONTAL", 0.1, 0.1, 1, 2),
]


def _random_points_in_view(rng, n=200):
    # points in front of a camera at the origin looking along +Y, spread widely
    return np.stack([rng.uniform(-6, 6, n), rng.uniform(3, 20, n), rng.uniform(-6, 6, n)], axis=1)


@pytest.mark.parametrize("width,height,fit,shift_x,shift_y,pixel_x,pixel_y", CASES)
def test_projection_matches_blender(width, height, fit, shift_x, shift_y, pixel_x, pixel_y):
    scenes.new_scene(width, height)
    bpy.context.scene.render.pixel_aspect_x, bpy.context.scene.render.pixel_aspect_y = pixel_x, pixel_y
    cam = scenes.add_camera((0.3, -0.2, 0.1), (math.radians(80), math.radians(5), math.radians(-10)), lens=28)
    cam.data.sensor_fit = fit
    cam.data.sensor_width = 36
    cam.data.sensor_height = 20
    cam.data.shift_x, cam.data.shift_y = shift_x, shift_y
    bpy.context.view_layer.update()
    intr = bcam.read_intrinsics(cam)
    pose = bcam.read_pose(cam)
    pts = _random_points_in_view(np.random.default_rng(0))
    uv, z = cm.project(pts, pose, intr.K)
    from mathutils import Vector

    scene = bpy.context.scene
    ref = np.array([tuple(world_to_camera_view(scene, cam, Vector(p))) for p in pts])
    ref_uv = np.stack([ref[:, 0] * width, (1 - ref[:, 1]) * height], axis=1)
    assert np.all(z > 0)
    np.testing.assert_allclose(uv, ref_uv, atol=1e-3)
    np.testing.assert_allclose(z, ref[:, 2], rtol=1e-6)


def test_pose_roundtrip_through_blender():
    scenes.new_scene()
    cam = scenes.add_camera((1, 2, 3), (0.3, -0.4, 1.1))
    pose = bcam.read_pose(cam)
    # OpenCV camera: z forward is Blender's -Z, y down is Blender's -Y
    bl = np.array(cam.matrix_world)
    np.testing.assert_allclose(pose[:3, 2], -bl[:3, 2], atol=1e-6)
    np.testing.assert_allclose(pose[:3, 1], -bl[:3, 1], atol=1e-6)
    np.testing.assert_allclose(pose[:3, 0], bl[:3, 0], atol=1e-6)
    target = np.eye(4)
    target[:3, :3] = cm.orthonormalize(np.random.default_rng(1).normal(size=(3, 3)))
    target[:3, 3] = [4, -5, 6]
    bcam.write_pose(target, cam)
    bpy.context.view_layer.update()
    np.testing.assert_allclose(bcam.read_pose(cam), target, atol=1e-6)


def test_project_unproject_roundtrip():
    rng = np.random.default_rng(3)
    intr = cm.intrinsics_from_blender(80, 60, 30, 36, 24, "AUTO", 0.05, -0.03)
    pose = np.eye(4)
    pose[:3, :3] = cm.orthonormalize(rng.normal(size=(3, 3)))
    pose[:3, 3] = rng.normal(size=3)
    depth = rng.uniform(0.5, 30, size=(60, 80)).astype(np.float32)
    depth[5, 7] = np.inf
    world = cm.depth_to_world_points(depth, intr.K, pose)
    assert np.all(np.isnan(world[5, 7]))
    valid = np.isfinite(depth)
    uv, z = cm.project(world[valid], pose, intr.K)
    ii, jj = np.nonzero(valid)
    np.testing.assert_allclose(uv[:, 0], jj + 0.5, atol=1e-6)  # pixel centres (j + 0.5, i + 0.5)
    np.testing.assert_allclose(uv[:, 1], ii + 0.5, atol=1e-6)
    np.testing.assert_allclose(z, depth[valid], rtol=1e-6)


@pytest.mark.parametrize(
    "matrix,message",
    [
        (np.eye(3), "4x4"),
        (np.diag([2.0, 1, 1, 1]), "orthonormal"),
        (np.diag([-1.0, 1, 1, 1]), "reflection"),
        (np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1.0]]), "last row"),
        (np.full((4, 4), np.nan), "NaN"),
    ],
)
def test_validate_rigid_rejects(matrix, message):
    with pytest.raises(ValueError, match=message):
        cm.validate_rigid(matrix)

"""Motion blur (Simulator.set_shutter): the colour is exposed around the frame's time with the
camera moving along its trajectory and the truck along its animation, while the geometry
stays that of the frame's time; the camera is left as it was."""

import bpy
import numpy as np
import pytest

from generator import Simulator
from generator.geometry.camera import look_at, world_from_camera_from_blender
from test_modalities import animated_scene

T = 3


def sharpness(rgb: np.ndarray) -> float:
    """Mean absolute horizontal gradient of the luminance, smoothed first (the render's noise
    is not an edge; the camera moves sideways)."""
    import cv2

    y = (rgb[..., 0] * 0.2126 + rgb[..., 1] * 0.7152 + rgb[..., 2] * 0.0722).astype(np.float32)
    return float(np.abs(cv2.Sobel(cv2.GaussianBlur(y, (0, 0), 1.5), cv2.CV_32F, 1, 0)).mean())


def flight(sim):
    """Three frames flown sideways at 3 m a frame, looking at the wall and the truck; the
    Simulator at the middle one. Returns the poses (T, 4, 4) and the truck's matrices
    (T, D, 4, 4)."""
    eyes = [(-5.0 + 3.0 * t, -12.0, 3.0) for t in range(T)]
    poses = np.stack([look_at(e, (-5.0 + 3.0 * t, 0.0, 1.0)) for t, e in enumerate(eyes)])
    matrices = []
    for t in range(T):
        sim.set_frame(1 + t)
        matrices.append(sim.dynamic_object_matrices())
    sim.set_frame(2)
    sim.set_world_from_camera(poses[1], check_collisions=False)
    return poses, np.stack(matrices)


@pytest.fixture(scope="module")
def renders(tmp_path_factory):
    sim = Simulator(animated_scene(tmp_path_factory.mktemp("blur") / "scene.blend"), points_density=2,
                    render_preset="preview")
    sim.configure_render(samples=16, denoise=False)
    poses, matrices = flight(sim)
    names = ["rgb", "rgb_linear", "depth", "label", "instance"]
    sharp = sim.render_outputs(names, poses, matrices, 1)
    sim.set_shutter(1.0 / sim.fps)  # a whole frame interval
    blurred = sim.render_outputs(names, poses, matrices, 1)
    camera = bpy.context.scene.camera
    left = (world_from_camera_from_blender(np.array(camera.matrix_world)), camera.animation_data)
    objects_only = sim.render()  # no trajectory given: only the truck moves during the exposure
    sim.set_shutter(0.0)
    return sim, poses, sharp, blurred, left, objects_only


def test_the_geometry_is_that_of_the_frame_time_whatever_the_shutter(renders):
    _, _, sharp, blurred, _, objects_only = renders
    for name in ("depth", "label", "instance"):
        assert np.array_equal(sharp[name], blurred[name]) and np.array_equal(sharp[name], objects_only[name]), name


def test_the_colour_is_blurred_by_the_camera_motion_and_the_truck_by_its_own(renders):
    import cv2

    sim, _, sharp, blurred, _, objects_only = renders
    assert sharpness(blurred.rgb) < 0.7 * sharpness(sharp.rgb)
    assert sharpness(objects_only.rgb) > 0.85 * sharpness(sharp.rgb)  # a still camera: only the truck smears
    truck = (sharp.instance == sim.object_names.index("Truck")).astype(np.uint8)
    near = cv2.dilate(truck, np.ones((9, 9), np.uint8)) > 0  # the truck moves 0.5 m in the exposure
    change = np.abs(objects_only.rgb - sharp.rgb).mean(axis=-1)
    assert change[near].mean() > 3 * change[~near].mean()


def test_the_camera_is_left_at_its_pose_without_keys(renders):
    sim, poses, _, _, (pose, animation), _ = renders
    assert animation is None
    assert np.allclose(pose, poses[1], atol=1e-6) and np.allclose(sim.get_world_from_camera(), poses[1])


def test_a_shutter_longer_than_a_frame_or_with_the_renderers_ground_truth_is_refused(renders):
    sim = renders[0]
    with pytest.raises(ValueError, match="shutter seconds"):
        sim.set_shutter(1.5 / sim.fps)
    sim.ground_truth = "renderer"
    try:
        with pytest.raises(ValueError, match="motion blur needs ground_truth='geometry'"):
            sim.set_shutter(0.5 / sim.fps)
    finally:
        sim.ground_truth = "geometry"
    assert sim.shutter_s == 0.0

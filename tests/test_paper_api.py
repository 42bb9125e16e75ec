"""The paper's Simulator API on ours: a script written against upstream ``buildee`` runs
unchanged except for its import, on a small scene built in code (docs/simulator-api.md)."""

import math

import bpy
import numpy as np
import pytest

import scenes
from generator import Simulator

# Written in the paper's API (its README, section 3.1 and its baselines), not in ours.
UPSTREAM_SCRIPT = """
import numpy as np
from buildee import Simulator

sim = Simulator(blend_file=BLEND, points_density=20.0, segmentation_sensitivity=0.1, max_pcl_depth=20.0)
init_world_from_camera = sim.get_world_from_camera()
sim.observed_points_mask = np.zeros(sim.n_points, dtype=bool)

rgb, depth, seg = sim.render()
render = sim.render()
n_outputs = len(render)
first, rest = render[0], render[1:]
h, w = depth.shape
label_name = sim.labels[seg[h // 2, w // 2]]
points3D = sim.depth_to_world_points(depth)
pcl, labels, mask = sim.compute_point_cloud(update_mask=True)
coverages = [sim.observed_points_mask.mean()]
K = sim.get_camera_matrix()

collided_forward = sim.move_camera_forward(1.0)
after_forward = sim.get_world_from_camera()
sim.move_camera_right(0.5)
sim.move_camera_right(-0.5)
sim.turn_camera_right(22.5, degrees=True)
after_turn = sim.get_world_from_camera()
sim.turn_camera_right(-np.pi / 8, degrees=False)
collided_up = sim.move_camera_down(-0.5)
after_up = sim.get_world_from_camera()
camera_from_next_camera = np.eye(4)
camera_from_next_camera[2, 3] = 1.0
collided_next = sim.set_camera_from_next_camera(camera_from_next_camera)
after_next = sim.get_world_from_camera()
collided_wall = sim.move_camera_forward(10.0)
after_wall = sim.get_world_from_camera()

pcl, labels, mask = sim.compute_point_cloud(update_mask=True, imshow=True)
coverages.append(sim.observed_points_mask.mean())
sim.step_frame()
moved_pcl, _, _ = sim.compute_point_cloud(update_mask=False)
sim.respawn_camera()
respawned = sim.get_world_from_camera()
sim.set_world_from_camera(init_world_from_camera, check_collisions=False)
colors = sim.point_cloud_colors
n_labels = sim.n_labels
camera_matrix = sim.camera_matrix
"""


def paper_scene(path):
    """Ground, a wall 5 m ahead of a level camera at (0, 0, 1.5) looking along +Y, a crate
    that slides 1 m per frame, a spawn volume behind the camera; Cycles at 1 sample."""
    scenes.new_scene(64, 48)
    scenes.add_plane("Ground", (60, 60), (0, 10, 0))
    scenes.add_box("Wall", (4, 0.2, 3), (0, 5, 1.5))
    crate = scenes.add_box("Crate", (1, 1, 1), (3, 8, 0.5))
    crate.keyframe_insert("location", frame=1)
    crate.location.x = 13.0
    crate.keyframe_insert("location", frame=11)
    scenes.add_box("CameraSpawn", (8, 4, 2), (0, -4, 2.0)).hide_render = True
    scenes.look_along_y((0, 0, 1.5))
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 1
    scene.cycles.use_denoising = False
    return scenes.save(path)


@pytest.fixture(scope="module")
def blend(tmp_path_factory):
    return paper_scene(tmp_path_factory.mktemp("paper") / "paper.blend")


def run_upstream(blend) -> dict:
    code = UPSTREAM_SCRIPT.replace("from buildee import Simulator", "from generator import Simulator")
    assert sum(a != b for a, b in zip(code.splitlines(), UPSTREAM_SCRIPT.splitlines())) == 1  # only the import
    ns = {"BLEND": str(blend)}
    exec(compile(code, "upstream_script.py", "exec"), ns)
    return ns


def test_upstream_script_runs_unchanged(blend):
    ns = run_upstream(blend)
    sim = ns["sim"]
    # render() is the 3-tuple (rgb, depth, seg)
    assert ns["n_outputs"] == 3
    assert ns["first"].shape == (48, 64, 3)
    depth, seg = ns["rest"]
    assert depth.shape == seg.shape == (48, 64) and seg.dtype == np.int32
    assert ns["label_name"] == "Wall"
    np.testing.assert_allclose(depth[24, 32], 4.9, atol=1e-3)  # the wall's near face, planar depth
    np.testing.assert_allclose(ns["points3D"][24, 32, 1], 4.9, atol=1e-3)
    # compute_point_cloud and the observation history
    assert len(ns["pcl"]) == sim.n_points == len(ns["labels"]) == len(ns["mask"])
    assert 0 < ns["coverages"][0] <= ns["coverages"][1] < 1
    assert ns["colors"].shape == (sim.n_points, 3) and ns["colors"].dtype == np.uint8
    assert ns["colors"].min() == 0 and ns["colors"].max() == 255
    img = sim.point_cloud_image
    assert img.shape == (48, 64, 3) and np.count_nonzero(img.any(axis=2)) > 50  # imshow drew the visible points
    # the intrinsics: focal length from the 35 mm lens on Blender's 36 mm sensor width
    f = 64 * 35.0 / 36.0
    np.testing.assert_allclose(ns["K"], [[f, 0, 32], [0, f, 24], [0, 0, 1]], atol=1e-9)
    np.testing.assert_array_equal(ns["camera_matrix"], ns["K"])
    # motion: forward 1 m along +Y; the turn right by 22.5 degrees and back; up 0.5 m
    start = ns["init_world_from_camera"]
    assert ns["collided_forward"] is False
    np.testing.assert_allclose(ns["after_forward"][:3, 3], start[:3, 3] + [0, 1, 0], atol=1e-6)
    a = math.radians(22.5)
    np.testing.assert_allclose(ns["after_turn"][:3, 2], [math.sin(a), math.cos(a), 0], atol=1e-6)
    assert ns["collided_up"] is False
    np.testing.assert_allclose(ns["after_up"][:3, 3], [0, 1, 2.0], atol=1e-6)
    np.testing.assert_allclose(ns["after_up"][:3, 2], [0, 1, 0], atol=1e-6)
    # set_camera_from_next_camera is a move in the camera's own frame: 1 m forward
    assert ns["collided_next"] is False
    np.testing.assert_allclose(ns["after_next"], ns["after_up"] @ ns["camera_from_next_camera"], atol=1e-9)
    np.testing.assert_allclose(ns["after_next"][:3, 3], [0, 2, 2.0], atol=1e-6)
    # 10 m forward goes through the wall: refused, the pose stays
    assert ns["collided_wall"] is True
    np.testing.assert_array_equal(ns["after_wall"], ns["after_next"])
    # step_frame slides the crate's points together along +X (keyframed x: 3 m to 13 m)
    crate = ns["labels"] == sim.labels.index("Crate")
    shift = ns["moved_pcl"][crate] - ns["pcl"][crate]
    assert shift[0, 0] > 0.01
    np.testing.assert_allclose(shift, np.broadcast_to([shift[0, 0], 0, 0], shift.shape), atol=1e-5)
    np.testing.assert_array_equal(ns["moved_pcl"][~crate], ns["pcl"][~crate])
    # respawn_camera: a point of the spawn volume (x in [-4, 4], y in [-6, -2], z in [1, 3])
    p = ns["respawned"][:3, 3]
    assert -4 <= p[0] <= 4 and -6 <= p[1] <= -2 and 1 <= p[2] <= 3
    assert ns["n_labels"] == len(sim.labels) == 3  # Crate, Ground, Wall


def test_counts_and_object_tables(blend):
    sim = Simulator(blend, points_density=20.0)
    assert sim.n_static_points + sim.n_dynamic_points == sim.n_points == sim.num_points
    assert list(sim.dynamic_point_clouds) == ["Crate"] and set(sim.static_point_clouds) == {"Ground", "Wall"}
    assert len(sim.dynamic_point_clouds["Crate"]) == sim.n_dynamic_points
    # the crate's points are in its own frame: a 1 m box centred on its origin
    assert np.abs(sim.dynamic_point_clouds["Crate"]).max() <= 0.5 + 1e-9
    assert sim.objects == {"Crate": True, "Ground": False, "Wall": False}
    assert sim.object_labels == {"Crate": "Crate", "Ground": "Ground", "Wall": "Wall"}
    assert sim.n_vertices == sim.n_static_vertices + sim.n_dynamic_vertices == 4 + 8 + 8
    # the surface area: 60 x 60 ground, the 4 x 0.2 x 3 wall, the 1 m crate, at 20 points/m^2
    assert sim.n_points == pytest.approx(20 * (3600 + 2 * (4 * 0.2 + 4 * 3 + 0.2 * 3) + 6), rel=0.03)


def test_filter_object_names(blend):
    sim = Simulator(blend, points_density=20.0, filter_object_names=["Wall"])
    assert "Wall" not in sim.labels and "Wall" not in sim.objects
    rgb, depth, seg = sim.render()
    assert seg[24, 32] == -1 and abs(depth[24, 32] - 4.9) < 1e-3  # still rendered, unlabelled
    assert sim.move_camera_forward(10.0) is False  # the filtered wall is no obstacle
    with pytest.raises(ValueError, match="filter_object_names"):
        Simulator(blend, filter_object_names="Wall")


def test_render_output_is_a_three_tuple_with_extras(blend):
    sim = Simulator(blend, points_density=1.0)
    out = sim.render()
    rgb, depth, seg = out
    assert out[-1] is seg and out[0] is rgb and len(out[::2]) == 2 and tuple(out)[1] is depth
    assert out.instance.shape == seg.shape and out.rgb_linear.shape == rgb.shape  # the extra fields stay
    with pytest.raises(IndexError):
        out[3]

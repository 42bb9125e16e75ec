"""Simulator core on real Blender scenes: loading, labels, motion, collisions, spawn, errors."""

import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import bpy
import numpy as np
import pytest

import scenes
from generator import Simulator
from generator.blender.camera import CameraError
from generator.blender.session import BlendFileError
from generator.simulator import SceneError

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def walls(walls_blend):
    return walls_blend


# ---- loading and labels -------------------------------------------------------------------
def test_labels_strip_suffix_and_sort(walls):
    sim = Simulator(walls, points_density=5)
    assert sim.labels == ["Crate", "Ground", "Wall"]
    assert sorted(sim.object_names) == ["Crate", "Crate.001", "Ground", "Wall"]
    _, labels, _ = sim.compute_point_cloud(update_mask=False)
    crate = sim.labels.index("Crate")
    inst = sim.point_instances
    on_crates = {sim.object_names[i] for i in np.unique(inst[labels == crate])}
    assert on_crates == {"Crate", "Crate.001"}
    assert sim.coverage == 0.0  # update_mask=False leaves the history alone


def test_evaluated_modifiers_instances_and_render_visibility(tmp_path):
    scenes.new_scene()
    fence = scenes.add_box("Fence", (2, 0.1, 1), (0, 5, 0.5))
    arr = fence.modifiers.new("Array", "ARRAY")
    arr.count = 3  # three panels side by side: 3x the area
    hidden = scenes.add_box("Ghost", (1, 1, 1), (5, 5, 0.5))
    hidden.hide_render = True
    viewport_hidden = scenes.add_box("Shy", (1, 1, 1), (-5, 5, 0.5))
    viewport_hidden.hide_viewport = True  # still rendered, so still simulated
    coll = bpy.data.collections.new("PalletSet")
    pallet = bpy.data.objects.new("Pallet", bpy.data.meshes.new("Pallet"))
    pallet.data.from_pydata([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [], [(0, 1, 2, 3)])
    coll.objects.link(pallet)
    for k in range(2):
        empty = bpy.data.objects.new(f"PalletInstance.{k:03d}", None)
        empty.instance_type = "COLLECTION"
        empty.instance_collection = coll
        empty.location = (10 + 3 * k, 0, 0)
        bpy.context.scene.collection.objects.link(empty)
    scenes.look_along_y((0, 0, 1.5))
    sim = Simulator(scenes.save(tmp_path / "eval.blend"), points_density=200)
    assert sim.labels == ["Fence", "Pallet", "Shy"]
    assert sum(name.endswith("Pallet#0") or "/Pallet#" in name for name in sim.object_names) == 2
    inst = sim.point_instances
    fence_idx = sim.object_names.index("Fence")
    fence_area = 3 * 2 * (2 * 0.1 + 2 * 1 + 0.1 * 1)  # three boxes of 2 x 0.1 x 1
    assert (inst == fence_idx).sum() == pytest.approx(200 * fence_area, rel=0.05)
    pts, labels, _ = sim.compute_point_cloud(update_mask=False)
    pallet_pts = pts[labels == sim.labels.index("Pallet")]
    assert pallet_pts[:, 0].min() >= 10 - 1e-9 and pallet_pts[:, 0].max() <= 14 + 1e-9
    assert np.any(pallet_pts[:, 0] > 13)  # the second instance is there too


def test_fixed_instance_table_keeps_ids_and_adds_empty_objects(walls):
    """instance_names (a timeline's shared object table): id = index in the table everywhere;
    a name the scene lacks is an empty object: no points, never seen."""
    plain = Simulator(walls, points_density=5)
    pose = plain.get_world_from_camera()
    names = sorted(plain.object_names + ["Absent.0001", "Crate.000"])
    geo_plain = plain.render_geometry(normals=False)
    seen_plain, seg_plain = geo_plain.instance, geo_plain.seg
    pts_plain, inst_plain = plain.point_positions.copy(), plain.point_instances
    sim = Simulator(walls, points_density=5, instance_names=names)
    assert sim.object_names == names and [r["object"] for r in sim.instance_table] == names
    assert sim.labels == ["Absent", "Crate", "Ground", "Wall"]  # labels of the whole table: the same in every stage
    absent = [names.index("Absent.0001"), names.index("Crate.000")]
    inst = sim.point_instances
    assert not np.isin(inst, absent).any()
    # every object keeps its points (sampling is seeded by name), now under its table id
    as_names = lambda table, ids: np.array(table, dtype=object)[ids]  # noqa: E731
    assert np.array_equal(as_names(names, inst), as_names(plain.object_names, inst_plain))
    assert np.array_equal(sim.point_positions, pts_plain)
    sim.set_world_from_camera(pose)
    geo = sim.render_geometry(normals=False)
    seen = geo.instance
    hit = seen >= 0
    assert hit.any() and np.array_equal(hit, seen_plain >= 0)
    assert np.array_equal(as_names(names, seen[hit]), as_names(plain.object_names, seen_plain[hit]))
    assert np.array_equal(np.array(sim.labels)[geo.seg[hit]], np.array(plain.labels)[seg_plain[hit]])
    assert not np.isin(seen, absent).any()
    with pytest.raises(ValueError, match="instance_names lacks"):
        Simulator(walls, instance_names=["Crate", "Ground", "Wall"])
    with pytest.raises(ValueError, match="instance_names has repeated"):
        Simulator(walls, instance_names=names + ["Wall"])


# ---- motion -------------------------------------------------------------------------------
def moving_truck_scene(path):
    scenes.new_scene()
    scenes.add_plane("Ground", (100, 100), (0, 0, 0))
    truck = scenes.add_box("Truck", (3, 2, 1), (0, 0, 1.0))
    truck.keyframe_insert("location", frame=1)
    truck.location.x = 10.0  # 1 m per frame
    truck.keyframe_insert("location", frame=11)
    scenes.make_linear(truck)
    wheel = scenes.add_cylinder("Wheel", 0.5, 0.2, (0, -1.1, 0.5), rotation=(math.pi / 2, 0, 0))
    wheel.parent = truck
    wheel.matrix_parent_inverse = truck.matrix_world.inverted()
    wheel.keyframe_insert("rotation_euler", frame=1)
    wheel.rotation_euler[1] = 20.0  # 2 rad per frame about the axle: rolling, radius 0.5 m
    wheel.keyframe_insert("rotation_euler", frame=11)
    scenes.make_linear(wheel)
    still = scenes.add_box("Cone", (0.3, 0.3, 0.7), (5, 5, 0.35))
    still.keyframe_insert("location", frame=1)  # keyframed but constant: static
    still.keyframe_insert("location", frame=11)
    scenes.add_camera((0, -15, 3), (math.radians(80), 0, 0))
    return scenes.save(path)


def test_moving_object_and_rolling_wheel(tmp_path):
    sim = Simulator(moving_truck_scene(tmp_path / "truck.blend"), points_density=100)
    assert sorted(sim.dynamic_objects) == ["Truck", "Wheel"]
    inst = sim.point_instances
    truck_i, wheel_i, cone_i = (sim.object_names.index(n) for n in ("Truck", "Wheel", "Cone"))
    p1, _, _ = sim.compute_point_cloud()
    centre1 = np.array([0.0, -1.1, 0.5])
    for k in range(1, 6):
        sim.step_frame()
        pk, _, _ = sim.compute_point_cloud()
        np.testing.assert_allclose(pk[inst == truck_i], p1[inst == truck_i] + [k, 0, 0], atol=1e-5)
        np.testing.assert_array_equal(pk[inst == cone_i], p1[inst == cone_i])
        phi = 2.0 * k
        ry = np.array([[math.cos(phi), 0, math.sin(phi)], [0, 1, 0], [-math.sin(phi), 0, math.cos(phi)]])
        expected = centre1 + [k, 0, 0] + (p1[inst == wheel_i] - centre1) @ ry.T
        np.testing.assert_allclose(pk[inst == wheel_i], expected, atol=1e-5)
    # rolling without slipping: a rim point traces a cycloid x = r (phi - sin phi), z = r (1 - cos phi)
    assert sim.frame == 6


# ---- collisions ---------------------------------------------------------------------------
def test_collisions(walls):
    sim = Simulator(walls, points_density=1, collision_radius=0.3)
    start = sim.get_world_from_camera()
    assert sim.move_camera_forward(3.0) is False  # y = 3, 1.9 m from the wall
    np.testing.assert_allclose(sim.get_world_from_camera()[:3, 3], start[:3, 3] + [0, 3, 0], atol=1e-6)
    before = sim.get_world_from_camera()
    assert sim.move_camera_forward(1.7) is True  # would end 0.2 m from the wall
    np.testing.assert_array_equal(sim.get_world_from_camera(), before)
    assert sim.move_camera_forward(10.0) is True  # straight through the wall
    np.testing.assert_array_equal(sim.get_world_from_camera(), before)
    # sliding along the wall's face: 0.35 m clearance passes, 0.25 m does not
    assert sim.can_move([-3, 4.55, 1.5], [3, 4.55, 1.5])
    assert not sim.can_move([-3, 4.65, 1.5], [3, 4.65, 1.5])
    assert not sim.is_free([0, 5.0, 1.5])  # inside the wall
    assert sim.is_free([0, 2.0, 1.5])
    assert sim.turn_camera_right(90) is False
    fwd = sim.get_world_from_camera()[:3, 2]
    np.testing.assert_allclose(fwd, [1, 0, 0], atol=1e-6)  # looking along +Y, turned right: +X
    assert sim.move_camera_right(-1.0) is False  # camera right is now -Y
    np.testing.assert_allclose(sim.get_world_from_camera()[:3, 3], before[:3, 3] + [0, 1, 0], atol=1e-6)


def test_thin_sheet_cannot_be_crossed(tmp_path):
    scenes.new_scene()
    scenes.add_plane("Sheet", (10, 10), (0, 3, 0), rotation=(math.pi / 2, 0, 0))  # vertical, open, at y = 3
    scenes.look_along_y((0, 0, 0))
    sim = Simulator(scenes.save(tmp_path / "sheet.blend"), points_density=1)
    assert sim.move_camera_forward(6.0) is True
    assert sim.move_camera_forward(2.5) is False
    assert sim.move_camera_forward(-2.5) is False


# ---- spawn --------------------------------------------------------------------------------
def test_spawn_volume(tmp_path):
    scenes.new_scene()
    scenes.add_plane("Ground", (40, 40), (0, 0, 0))
    scenes.add_box("Tower", (4, 4, 20), (0, 0, 10))
    spawn = scenes.add_box("CameraSpawn", (20, 20, 6), (0, 0, 5))
    spawn.hide_render = False  # even if render-visible, the spawn volume is not scene geometry
    scenes.look_along_y((0, -15, 3))
    sim = Simulator(scenes.save(tmp_path / "spawn.blend"), points_density=1, collision_radius=0.5, seed=3)
    assert "CameraSpawn" not in sim.labels
    sp = sim.spawn_points
    assert len(sp) > 100
    assert np.all(np.abs(sp[:, :2]) <= 10) and np.all((sp[:, 2] >= 2) & (sp[:, 2] <= 8))
    assert np.all(sp[:, 2] >= 0.5)  # clear of the ground by the radius
    # the tower occupies |x|, |y| <= 2 up to z = 20: every spawn point keeps 0.5 m from it
    gap = np.linalg.norm(np.maximum(np.abs(sp[:, :2]) - 2.0, 0.0), axis=1)
    assert gap.min() >= 0.5 - 1e-6
    for _ in range(5):
        pose = sim.respawn_camera()
        assert np.any(np.all(np.isclose(sp, pose[:3, 3]), axis=1))
        np.testing.assert_allclose(np.linalg.det(pose[:3, :3]), 1.0, atol=1e-9)
        assert abs(pose[2, 0]) < 1e-9  # no roll: camera x axis horizontal


def test_without_spawn_volume_respawn_returns_to_start(walls):
    sim = Simulator(walls, points_density=1)
    start = sim.get_world_from_camera()
    sim.move_camera_forward(1.0)
    np.testing.assert_allclose(sim.respawn_camera(), start)


# ---- bad input ----------------------------------------------------------------------------
def test_bad_files(tmp_path):
    with pytest.raises(BlendFileError, match="not found"):
        Simulator(tmp_path / "missing.blend")
    junk = tmp_path / "junk.blend"
    junk.write_bytes(b"this is not a blend file")
    with pytest.raises(BlendFileError, match="bad header"):
        Simulator(junk)
    good = scenes.walls_scene(tmp_path / "good.blend")
    truncated = tmp_path / "truncated.blend"
    truncated.write_bytes(good.read_bytes()[:3000])
    with pytest.raises(BlendFileError):
        Simulator(truncated)


def test_scene_without_camera_or_meshes(tmp_path):
    scenes.new_scene()
    scenes.add_box("Box", (1, 1, 1), (0, 5, 0))
    with pytest.raises(CameraError, match="no camera"):
        Simulator(scenes.save(tmp_path / "nocam.blend"))
    scenes.new_scene()
    scenes.look_along_y((0, 0, 0))
    with pytest.raises(SceneError, match="no render-visible mesh"):
        Simulator(scenes.save(tmp_path / "nomesh.blend"))


@pytest.mark.parametrize(
    "kwargs,message",
    [
        ({"points_density": 0}, "points_density"),
        ({"points_density": -1}, "points_density"),
        ({"points_density": float("inf")}, "points_density"),
        ({"points_density": "dense"}, "points_density"),
        ({"segmentation_sensitivity": -0.1}, "segmentation_sensitivity"),
        ({"segmentation_sensitivity": 1.5}, "segmentation_sensitivity"),
        ({"max_pcl_depth": 0}, "max_pcl_depth"),
        ({"seed": -1}, "seed"),
        ({"seed": True}, "seed must be an integer from 0 to"),
        ({"seed": 2.0}, "seed must be an integer from 0 to"),
        ({"seed": 2**64}, "seed must be an integer from 0 to 9223372036854775807"),
        ({"points_density": 1e9}, r"points density 1e\+09 per m\^2: this scene has .* the limit is 50,000,000"),
        ({"collision_radius": -0.1}, "collision_radius"),
        ({"points_density": "1.0"}, r"^points_density must be a finite number > 0, got '1.0'$"),
        ({"points_density": float("inf")}, r"^points_density must be a finite number > 0, got inf$"),
        ({"segmentation_sensitivity": 1.5}, r"^segmentation_sensitivity must be a number in \[0, 1\], got 1.5$"),
        ({"max_pcl_depth": float("nan")}, r"^max_pcl_depth must be a number > 0 \(inf allowed\), got nan$"),
        ({"collision_radius": float("inf")}, r"^collision_radius must be a finite number >= 0, got inf$"),
    ],
)
def test_bad_parameters(walls, kwargs, message):
    with pytest.raises(ValueError, match=message):
        Simulator(walls, **kwargs)


def test_moves_and_depth_limits_are_checked(walls):
    sim = Simulator(walls, points_density=1)
    start = sim.get_world_from_camera()
    for call, message in ((lambda: sim.move_camera_forward(math.inf), "^distance must be a finite number, got inf$"),
                          (lambda: sim.move_camera_right("1"), "^distance must be a finite number, got '1'$"),
                          (lambda: sim.turn_camera_right(math.nan), "^angle must be a finite number, got nan$"),
                          (lambda: sim.compute_point_cloud(max_depth=0), r"^max_depth must be a number > 0 \(inf allowed\)")):
        with pytest.raises(ValueError, match=message):
            call()
    np.testing.assert_array_equal(sim.get_world_from_camera(), start)  # nothing moved
    assert sim.compute_point_cloud(max_depth=math.inf)[2].any()  # math.inf: no depth limit


def test_settings_assigned_later_and_frames_are_checked_too(walls):
    """Assigning a setting after construction is checked as the constructor checks it, and
    a bad frame, pose, point array or flag is refused in one line before anything changes."""
    sim = Simulator(walls, points_density=1)
    start, frame = sim.get_world_from_camera(), sim.frame
    cases = [
        (lambda: setattr(sim, "max_pcl_depth", math.nan), r"^max_pcl_depth must be a number > 0 \(inf allowed\), got nan$"),
        (lambda: setattr(sim, "max_pcl_depth", -5), "^max_pcl_depth must be a number > 0"),
        (lambda: setattr(sim, "max_pcl_depth", "x"), "^max_pcl_depth must be a number > 0"),
        (lambda: setattr(sim, "segmentation_sensitivity", 2), r"^segmentation_sensitivity must be a number in \[0, 1\]"),
        (lambda: setattr(sim, "collision_radius", -1), "^collision_radius must be"),
        (lambda: setattr(sim, "ground_truth", "cycles"), "ground_truth"),
        (lambda: setattr(sim, "observed_points_mask", np.zeros(5, bool)),
         rf"^observed_points_mask must be an \({sim.num_points},\) array of bools"),
        (lambda: sim.set_frame(1.5), "^frame must be an integer from -1,048,574 to 1,048,574, got 1.5$"),
        (lambda: sim.set_frame("3"), "^frame must be an integer"),
        (lambda: sim.set_frame(10**7), "^frame must be an integer"),
        (lambda: sim.project(np.zeros(3)), r"^points must be an \(N, 3\) array of world coordinates in metres, got shape \(3,\)$"),
        (lambda: sim.project(np.zeros((5, 2))), r"^points must be an \(N, 3\) array"),
        (lambda: sim.set_world_from_camera("eye"), "^pose must be a 4x4 matrix of real numbers, got 'eye'$"),
        (lambda: sim.is_free("a"), r"^position must be three numbers \(x, y, z\) in metres, got 'a'$"),
        (lambda: sim.turn_camera_right(10, degrees="yes"), "^degrees must be True or False, got 'yes'$"),
        (lambda: sim.set_world_from_camera(start, check_collisions="no"), "^check_collisions must be True or False"),
        (lambda: sim.move_camera_forward(1e12), "^distance 1e\\+12 m would take the camera farther than 1e\\+10 m"),
        (lambda: sim.render_outputs(["flow"], start[None], np.zeros((1, 2, 4, 4)), 0),
         r"^object_matrices must be a \(1 x 0 x 4 x 4\) array \(T frames\), got shape \(1, 2, 4, 4\)$"),
        (lambda: sim.render_outputs(["flow"], start[None], np.zeros((1, 0, 4, 4)), 1), "^index must be an integer from 0 to 0"),
        (lambda: sim.render_outputs(["flow"], start, np.zeros((1, 0, 4, 4)), 0), r"^poses must be a \(T x 4 x 4\) array"),
    ]
    far = start.copy()
    far[0, 3] = 1e12
    cases.append((lambda: sim.set_world_from_camera(far, check_collisions=False), "farther than 1e\\+10 m from the origin"))
    for call, message in cases:
        with pytest.raises(ValueError, match=message):
            call()
    np.testing.assert_array_equal(sim.get_world_from_camera(), start)  # nothing moved
    assert sim.frame == frame and sim.max_pcl_depth == math.inf and sim.collision_radius == 0.3
    sim.max_pcl_depth = 1e-3  # a valid assignment takes effect
    assert not sim.compute_point_cloud(update_mask=False)[2].any()
    sim.max_pcl_depth = math.inf
    assert sim.compute_point_cloud(update_mask=False)[2].any()
    mine = np.zeros(sim.num_points, bool)
    sim.observed_points_mask = mine  # the paper's scripts keep their array and read it after each call
    sim.compute_point_cloud()
    assert mine.any() and sim.observed_points_mask is mine and sim.coverage == mine.mean()
    assert np.isnan(sim.render_outputs(["flow"], start[None], None, 0)["flow"]).all()  # a still scene needs no matrices
    # any finite angle turns by its remainder of whole turns
    sim.turn_camera_right(1e300)
    assert np.isfinite(sim.get_world_from_camera()).all()


def test_a_filter_name_the_scene_lacks_is_named_in_a_warning(walls):
    with pytest.warns(UserWarning, match=r"^filter_object_names: .*walls.blend has no mesh object 'Fense'; nothing is "
                                         r"filtered for it$"):
        sim = Simulator(walls, points_density=1, filter_object_names=["Fense"])
    assert sim.num_points > 0


def test_non_rigid_pose_rejected(walls):
    sim = Simulator(walls, points_density=1)
    scaled = sim.get_world_from_camera()
    scaled[:3, :3] *= 2
    with pytest.raises(ValueError, match="orthonormal"):
        sim.set_world_from_camera(scaled)


def test_stale_simulator_refuses(walls):
    old = Simulator(walls, points_density=1)
    Simulator(walls, points_density=1)
    with pytest.raises(RuntimeError, match="another Simulator"):
        old.compute_point_cloud()


# ---- determinism across processes ---------------------------------------------------------
_DIGEST = textwrap.dedent(
    """
    import hashlib, sys
    from generator import Simulator
    sim = Simulator(sys.argv[1], points_density=30, seed=int(sys.argv[2]))
    pts, labels, vis = sim.compute_point_cloud()
    h = hashlib.sha256(pts.tobytes() + labels.tobytes() + vis.tobytes())
    h.update(repr((sim.labels, sim.object_names)).encode())
    print(h.hexdigest(), repr(sim.labels))
    """
)


def _digest(path, seed, hashseed):
    env = {"PYTHONHASHSEED": str(hashseed), "PATH": "/usr/bin:/bin", "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-c", _DIGEST, str(path), str(seed)], capture_output=True, text=True, env=env, cwd=ROOT)
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout.strip()


def test_same_seed_same_points_across_processes(walls):
    a = _digest(walls, 0, 1)
    b = _digest(walls, 0, 12345)
    c = _digest(walls, 1, 1)
    assert a == b
    assert a.split()[0] != c.split()[0]
    assert a.split(" ", 1)[1] == c.split(" ", 1)[1]  # labels do not depend on the seed


def test_bpy_free_packages_do_not_import_bpy():
    code = (
        "import sys, generator, generator.geometry.visibility, generator.geometry.collision, "
        "generator.geometry.spawn, generator.geometry.surface_points, trajectories, exporters, evaluation, datasets, "
        "exporters.ground_truth, exporters.nerfstudio, exporters.previews, exporters.tracks, exporters.colmap, "
        "evaluation.api, evaluation.report, datasets.tasks, generator.cli_args, generator.batch.config\n"
        "assert 'bpy' not in sys.modules, 'bpy was imported'\n"
        "import bpy\n"  # and bpy still imports after open3d was loaded by our helper
        "print('ok')"
    )
    env = {k: v for k, v in os.environ.items() if k != "OCIO"}  # set by bpy in this process
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, env=env)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-2000:]


def test_drivers_make_objects_dynamic_only_when_they_drive_the_transform(tmp_path):
    scenes.new_scene()
    scenes.add_plane("Ground", (50, 50), (0, 0, 0))
    slider = scenes.add_box("Slider", (1, 1, 1), (0, 5, 0.5))
    fc = slider.driver_add("location", 0)
    fc.driver.type = "SCRIPTED"
    fc.driver.expression = "frame * 0.25"  # x = 0.25 m per frame
    for fm in list(fc.modifiers):
        fc.modifiers.remove(fm)
    painted = scenes.add_box("Painted", (1, 1, 1), (3, 5, 0.5))
    painted["weight"] = 0.0
    fc2 = painted.driver_add('["weight"]')
    fc2.driver.expression = "frame"  # drives a custom property, not the transform
    scenes.look_along_y((0, -5, 1))
    sim = Simulator(scenes.save(tmp_path / "drivers.blend"), points_density=20)
    assert sim.dynamic_objects == ["Slider"]
    inst = sim.point_instances
    s = sim.object_names.index("Slider")
    p1 = np.array(sim.compute_point_cloud()[0][inst == s])
    np.testing.assert_allclose(p1[:, 0].mean(), 0.25 * sim.frame, atol=0.05)
    sim.step_frame()
    p2 = sim.compute_point_cloud()[0][inst == s]
    np.testing.assert_allclose(p2, p1 + [0.25, 0, 0], atol=1e-5)


def test_a_camera_placed_too_close_to_a_surface_can_leave(tmp_path):
    """A .blend camera 0.2 m above the ground (inside the 0.3 m collision sphere): turning in
    place and moving away to a free position are allowed (the paper's code, a ray test, allows
    them); moving along the ground, or back into it, is refused."""
    scenes.new_scene(32, 24)
    scenes.add_plane("Ground", (50, 50), (0, 0, 0))
    scenes.look_along_y((0, 0, 0.2))
    sim = Simulator(scenes.save(tmp_path / "low.blend"), points_density=1)
    start = sim.get_world_from_camera()
    assert not sim.is_free(start[:3, 3])
    along = start.copy()
    along[1, 3] += 1.0
    assert sim.set_world_from_camera(along) is True  # refused: still touching the ground
    turned = start.copy()
    turned[:3, :3] = start[:3, :3] @ np.array([[0, 0, 1.0], [0, 1, 0], [-1, 0, 0]])
    assert sim.set_world_from_camera(turned) is False  # a turn in place
    up = turned.copy()
    up[2, 3] = 1.2
    assert sim.set_world_from_camera(up) is False and sim.is_free(up[:3, 3])  # away from the ground
    assert sim.set_world_from_camera(start) is True  # back into it: refused
    through = up.copy()
    through[2, 3] = -1.0
    assert sim.can_move(start[:3, 3], through[:3, 3]) is False  # through the ground, never

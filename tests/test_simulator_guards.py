"""Simulator arguments that used to slip through: a bad constructor argument must not replace
the loaded scene, a replaced Simulator must say so everywhere, flags are booleans, and
respawns never land in geometry."""

import bpy
import numpy as np
import pytest

import scenes
from generator import Simulator
from generator.geometry.spawn import SpawnVolumeError


@pytest.fixture(scope="module")
def walls(tmp_path_factory):
    return scenes.walls_scene(tmp_path_factory.mktemp("guards") / "walls.blend", 24, 16)


@pytest.mark.parametrize("kw, message", [
    ({"render_preset": "fast"}, "unknown render preset 'fast'"),
    ({"instance_names": ["Crate", 3]}, "instance_names must be a list of object names"),
    ({"geometry_nodes_objects": None}, "geometry_nodes_objects must be a list of object names, got None"),
    ({"filter_object_names": 7}, "filter_object_names must be a list of object names, got 7"),
    ({"verbose": "no"}, "verbose must be True or False"),
])
def test_a_refused_constructor_leaves_the_loaded_simulator_alive(walls, kw, message):
    sim = Simulator(walls, points_density=2)
    before = sim.compute_point_cloud(update_mask=False)[2]
    with pytest.raises(ValueError, match=message):
        Simulator(walls, points_density=2, **kw)
    np.testing.assert_array_equal(sim.compute_point_cloud(update_mask=False)[2], before)


def test_a_replaced_simulator_refuses_frame_facts(walls, tmp_path):
    old = Simulator(walls, points_density=2)
    assert old.frame_range != (1, 7) and old.fps != 30.0
    scenes.walls_scene(tmp_path / "other.blend", 24, 16)
    bpy.context.scene.frame_end, bpy.context.scene.render.fps = 7, 30
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "other.blend"))
    new = Simulator(tmp_path / "other.blend", points_density=2)
    assert new.frame_range == (1, 7) and new.fps == 30.0
    for fact in ("frame_range", "fps"):
        with pytest.raises(RuntimeError, match="another Simulator"):
            getattr(old, fact)


def test_flags_are_booleans(walls):
    sim = Simulator(walls, points_density=2)
    for kw in ({"update_mask": "False"}, {"imshow": 1}):
        with pytest.raises(ValueError, match=f"^{next(iter(kw))} must be True or False"):
            sim.compute_point_cloud(**kw)
    assert sim.coverage == 0.0  # the refused call did not update the mask
    with pytest.raises(ValueError, match="^normals must be True or False"):
        sim.render_geometry(normals="no")


def test_render_geometry_without_normals_after_a_call_with_them(walls):
    sim = Simulator(walls, points_density=2)
    with_normals = sim.render_geometry(normals=True)
    assert with_normals.normal is not None
    without = sim.render_geometry(normals=False)
    assert without.normal is None
    np.testing.assert_array_equal(without.depth, with_normals.depth)


def test_respawn_never_lands_in_geometry(tmp_path):
    scenes.new_scene(24, 16)
    scenes.add_plane("Ground", (40, 40), (0, 0, 0))
    scenes.add_box("Tower", (4, 4, 20), (0, 0, 10))
    scenes.add_box("CameraSpawn", (12, 12, 4), (0, 0, 3))
    scenes.look_along_y((0, -15, 3))
    sim = Simulator(scenes.save(tmp_path / "spawn.blend"), points_density=1, collision_radius=0.3, seed=3)
    sim.collision_radius = 2.5  # larger than when the spawn points were sampled
    free = np.array([sim.is_free(p) for p in sim.spawn_points])
    assert 0 < free.sum() < len(free)  # some spawn points are now too close to the tower or ground
    for _ in range(20):
        assert sim.is_free(sim.respawn_camera()[:3, 3])
    sim.collision_radius = 50.0  # nothing is free any more
    with pytest.raises(SpawnVolumeError, match="none of the .* spawn points is free"):
        sim.respawn_camera()

"""Blender numbers objects with a 15-bit pass index: a scene needing more than 32,767 is
refused in one line, from the file's index before the file is loaded (issue #36, item 8), and
the count of the objects that need one is right (instanced copies share their object's)."""

import numpy as np
import pytest

import scenes
from generator import Simulator
from generator.blender import session
from generator.blender.extract import MAX_PASS_INDEX, pass_index_owners, too_many_objects
from generator.blender.objects import SceneError
from generator.geometry.parts import MeshPart

TRIANGLE = np.array([[0, 0, 0], [0.5, 0, 0], [0, 0, 0.5]], np.float64), np.array([[0, 1, 2]], np.int64)


def _many_triangles(path, count: int):
    """``count`` one-triangle objects sharing one mesh, and a camera."""
    bpy = session.bpy
    scenes.new_scene(16, 12)
    mesh = bpy.data.meshes.new("Tri")
    mesh.from_pydata(TRIANGLE[0].tolist(), [], TRIANGLE[1].tolist())
    for i in range(count):
        obj = bpy.data.objects.new(f"Tri{i}", mesh)
        obj.location = (i % 200 - 100, 10 + i // 200, 0)
        bpy.context.scene.collection.objects.link(obj)
    scenes.look_along_y((0, 0, 1.0))
    session.save_blend(path, compress=False)
    return path


def test_a_file_over_the_limit_is_refused_before_it_is_loaded(tmp_path):
    big = _many_triangles(tmp_path / "many.blend", MAX_PASS_INDEX + 1)
    small = scenes.walls_scene(tmp_path / "walls.blend", 24, 16)
    sim = Simulator(small, points_density=2)
    visible = sim.compute_point_cloud(update_mask=False)[2]
    loaded = session.generation()
    with pytest.raises(SceneError) as err:
        Simulator(big)
    message = str(err.value)
    assert len(message.splitlines()) == 1
    assert f"{MAX_PASS_INDEX + 2} objects" in message and str(MAX_PASS_INDEX) in message and "join objects" in message
    assert session.generation() == loaded  # never opened: the Simulator loaded before still works
    np.testing.assert_array_equal(sim.compute_point_cloud(update_mask=False)[2], visible)


def _parts(sources: list[str], faces: bool = True) -> list[MeshPart]:
    verts, tri = TRIANGLE
    return [MeshPart(f"{s}#{i}", s, verts, tri if faces else tri[:0], source=s) for i, s in enumerate(sources)]


@pytest.mark.parametrize("objects, copies, faceless, refused", [
    (MAX_PASS_INDEX, 1, 0, False),
    (MAX_PASS_INDEX + 1, 1, 0, True),
    (40_000, 1, 0, True),
    (20_000, 3, 0, False),  # 60,000 parts, copies of 20,000 objects
    (MAX_PASS_INDEX, 1, 5_000, False),  # objects of an instance table the scene lacks need none
])
def test_objects_that_need_a_pass_index_are_counted_once(objects, copies, faceless, refused):
    parts = _parts([f"Obj{i}" for i in range(objects) for _ in range(copies)])
    parts += _parts([f"Gone{i}" for i in range(faceless)], faces=False)
    owners = pass_index_owners(parts)
    assert len(owners) == objects
    assert all(parts[first].source == name for name, first in owners.items())
    message = too_many_objects(len(owners), "scene.blend")
    assert (message is not None) == refused
    if refused:
        assert message.startswith(f"scene.blend has {objects} objects") and "\n" not in message


@pytest.mark.parametrize("with_h", [False, True], ids=["", "and an object hidden with H"])
def test_viewport_flags_copied_in_bulk_show_what_a_render_shows(with_h, tmp_path):
    """The loader writes viewport visibility for all objects and collections at once (one
    re-sync instead of one per object): hidden in the viewport only still means simulated."""
    bpy = session.bpy
    scenes.new_scene(16, 12)
    scenes.add_plane("Ground", (60, 60), (0, 10, 0))
    root = bpy.context.scene.collection
    cases = ["eye", "monitor", "render off", "object off", "object render off", "shown"] + ["h"] * with_h
    for k, case in enumerate(cases):
        coll = bpy.data.collections.new(f"Coll {case}")
        root.children.link(coll)
        box = scenes.add_box(f"Box {case}", (1, 1, 1), (2 * k - 6, 8, 0.5))
        root.objects.unlink(box)
        coll.objects.link(box)
        layer = bpy.context.view_layer.layer_collection.children[coll.name]
        layer.hide_viewport = case == "eye"
        coll.hide_viewport = case == "monitor"
        coll.hide_render = case == "render off"
        box.hide_viewport = case == "object off"
        box.hide_render = case == "object render off"
        box.hide_set(case == "h")
    scenes.look_along_y((0, 0, 1.0))
    sim = Simulator(scenes.save(tmp_path / "flags.blend"))
    shown = ["Box eye", "Box monitor", "Box object off", "Box shown", "Ground"] + ["Box h"] * with_h
    assert sim.object_names == sorted(shown)

"""What of a .blend the ground truth honours (docs/rendering.md, "What of a .blend is honoured"):
each scene below differs between Blender's viewport and its render, or moves in a way that
is not an object's own transform animation. The default ground truth (rays into the scene's
triangles) must show what Cycles' own Object Index pass shows, or the scene is refused in
one line. Scenes are 48x32 pixels, one Cycles sample."""

import math

import bpy
import numpy as np
import pytest

import scenes
from generator import Simulator
from generator.blender.objects import SceneError


def _yard():
    """Ground, a wall, a crate and a pole, seen by a camera 10 m back."""
    scenes.new_scene(48, 32)
    scenes.add_plane("Ground", (100, 100), (0, 0, 0))
    scenes.add_box("Wall", (3, 0.2, 3), (-2, 0, 1.5))
    scenes.add_box("Crate", (1, 1, 1), (1.5, -1, 0.5))
    scenes.add_cylinder("Pole", 0.15, 4, (2.5, 1, 2), segments=8)
    scenes.add_sun()
    return scenes.add_camera((0, -10, 2), (math.radians(80), 0, 0))


def _load(path) -> Simulator:
    sim = Simulator(path, segmentation_sensitivity=0.0)
    sim.configure_render(engine="CYCLES", samples=1, denoise=False, bounces=0, threads=2)
    return sim


def _pixels(sim, label: str) -> tuple[int, int, float]:
    """(pixels of ``label`` in our ground truth, in Cycles' Object Index pass, share of
    pixels whose labels differ)."""
    sim.ground_truth = "renderer"
    cycles = sim.render().seg
    sim.ground_truth = "geometry"
    ours = sim.render().seg
    k = sim.labels.index(label) if label in sim.labels else -2
    return int((ours == k).sum()), int((cycles == k).sum()), float((ours != cycles).mean())


def _assert_as_rendered(sim, label: str) -> None:
    ours, cycles, differ = _pixels(sim, label)
    assert abs(ours - cycles) <= 2 and differ < 0.01, (label, ours, cycles, differ)


def _obj(name):
    return bpy.data.objects[name]


def _hair(emitter_name="Emitter", **settings):
    """A hair system on a 4x2 m plane in front of the wall, instancing the pole 40 times."""
    em = scenes.add_plane(emitter_name, (4, 2), (0, -4, 0.05))
    em.modifiers.new("ps", "PARTICLE_SYSTEM")
    ps = em.particle_systems[0].settings
    ps.type, ps.count, ps.render_type, ps.instance_object = "HAIR", 40, "OBJECT", _obj("Pole")
    ps.particle_size, ps.use_advanced_hair = 0.1, True
    for key, value in settings.items():
        setattr(ps, key, value)
    return em


def _still_emitter(**settings):
    """Emitter particles born before the first frame, alive past the last, without physics."""
    em = _hair(type="EMITTER", count=30, frame_start=-50, frame_end=-40, lifetime=1000, physics_type="NO")
    for key, value in settings.items():
        setattr(em.particle_systems[0].settings, key, value)
    return em


def _in_collection(obj, name="C"):
    coll = bpy.data.collections.new(name)
    bpy.context.scene.collection.children.link(coll)
    bpy.context.scene.collection.objects.unlink(obj)
    coll.objects.link(obj)
    return bpy.context.view_layer.layer_collection.children[name]


def _verts_child():
    _obj("Wall").instance_type = "VERTS"
    _obj("Crate").parent = _obj("Wall")


VIEWPORT_VS_RENDER = {  # scene change -> the label whose pixels are compared
    "particles display_percentage 25": (lambda: _hair(display_percentage=25), "Pole"),
    "hair children 1 in viewport, 5 rendered": (lambda: _hair(child_type="SIMPLE", child_percent=1,
                                                              rendered_child_count=5), "Pole"),
    "emitter particles displayed as dots": (lambda: _still_emitter(display_method="DOT"), "Pole"),
    "instancer hidden in renders only": (lambda: setattr(_hair(), "show_instancer_for_render", False), "Emitter"),
    "child of a vertex instancer": (_verts_child, "Crate"),
    "Visibility > Camera off": (lambda: setattr(_obj("Crate"), "visible_camera", False), "Crate"),
    "indirect-only collection": (lambda: setattr(_in_collection(_obj("Crate")), "indirect_only", True), "Crate"),
    # emitted on frame 1 only, drawn before birth and after death: still copies (accepted)
    "still emitter particles shown unborn and dead": (lambda: _still_emitter(frame_start=1, frame_end=1, lifetime=10,
                                                                             show_unborn=True, use_dead=True), "Pole"),
}


@pytest.mark.parametrize("case", list(VIEWPORT_VS_RENDER))
def test_ground_truth_shows_what_the_render_camera_sees(case, tmp_path):
    change, label = VIEWPORT_VS_RENDER[case]
    _yard()
    change()
    _assert_as_rendered(_load(scenes.save(tmp_path / "s.blend")), label)


def test_is_viewport_node_is_named_in_a_warning(tmp_path):
    _yard()
    tree = bpy.data.node_groups.new("ViewportSwitch", "GeometryNodeTree")
    tree.nodes.new("GeometryNodeIsViewport")
    _obj("Crate").modifiers.new("GN", "NODES").node_group = tree
    with pytest.warns(UserWarning, match="'ViewportSwitch' use 'Is Viewport'"):
        Simulator(scenes.save(tmp_path / "s.blend"))


REFUSED = {  # scene change -> words of the one-line SceneError
    "holdout object": (lambda: setattr(_obj("Crate"), "is_holdout", True), "'Crate' is a holdout"),
    "holdout collection": (lambda: setattr(_in_collection(_obj("Pole")), "holdout", True), "'Pole' is a holdout"),
    "keyframed hide_render": (lambda: _keyframed(_obj("Crate"), "hide_render", True, False),
                              "'Crate' has animated render visibility (hide_render)"),
    "moving emitter particles": (lambda: _hair(type="EMITTER", count=5), "particles of 'Emitter'"),
    "animated object instanced by particles": (lambda: (_hair(), _keyframed(_obj("Pole"), "location", (2.5, 1, 2),
                                                                            (3, 1, 2))), "'Pole' moves"),
    "animated shape keys": (lambda: _shape_keys(_obj("Crate")), "'Crate' has animated shape keys"),
    "mesh deformed by an animated armature": (lambda: _deformed(_obj("Crate")), "deformed by the animated armature"),
    "mesh with an armature parent": (lambda: setattr(_obj("Crate"), "parent", _rig()) or setattr(
        _obj("Crate"), "parent_type", "ARMATURE"), "deformed by the animated armature 'Rig'"),
}


@pytest.mark.parametrize("case", list(REFUSED))
def test_what_cannot_be_simulated_is_refused_in_one_line(case, tmp_path):
    change, words = REFUSED[case]
    _yard()
    change()
    with pytest.raises(SceneError) as err:
        Simulator(scenes.save(tmp_path / "s.blend"))
    assert words in str(err.value) and "\n" not in str(err.value), str(err.value)


def _keyframed(obj, path, first, last, data=None):
    target = data or obj
    setattr(target, path, first)
    target.keyframe_insert(path, frame=1)
    setattr(target, path, last)
    target.keyframe_insert(path, frame=10)
    bpy.context.scene.frame_set(1)


def _shape_keys(obj):
    obj.shape_key_add(name="Basis")
    key = obj.shape_key_add(name="Squash")
    key.data[0].co.z -= 0.3
    _keyframed(obj, "value", 0.0, 1.0, data=key)


def _rig(name="Rig"):
    """An armature with one bone (head at the origin, along +Z) whose pose moves 3 m down
    between frames 1 and 10."""
    arm = bpy.data.objects.new(name, bpy.data.armatures.new(name))
    bpy.context.scene.collection.objects.link(arm)
    bpy.context.view_layer.objects.active = arm
    bpy.ops.object.mode_set(mode="EDIT")
    bone = arm.data.edit_bones.new("Bone")
    bone.head, bone.tail = (0, 0, 0), (0, 0, 1)
    bpy.ops.object.mode_set(mode="OBJECT")
    _keyframed(arm, "location", (0, 0, 0), (0, 0, -3.0), data=arm.pose.bones["Bone"])
    return arm


def _deformed(obj):
    obj.modifiers.new("Armature", "ARMATURE").object = _rig()


def test_animated_lens_is_frozen_and_the_camera_stays_the_simulators(tmp_path):
    cam = _yard()
    _keyframed(cam, "lens", 35.0, 60.0, data=cam.data)
    other = scenes.add_camera((0, -20, 2), (math.radians(80), 0, 0), name="Other")
    bpy.context.scene.timeline_markers.new("switch", frame=5).camera = other
    bpy.context.scene.camera = cam
    sim = _load(scenes.save(tmp_path / "s.blend"))
    K = sim.K.copy()
    sim.set_frame(10)
    assert sim.scene.camera == sim.camera and sim.camera.data.lens == 35.0
    assert np.array_equal(sim.K, K)
    _assert_as_rendered(sim, "Crate")


def test_bone_parented_object_moves_with_the_pose(tmp_path):
    _yard()
    crate, arm = _obj("Crate"), _rig()
    world = crate.matrix_world.copy()
    crate.parent, crate.parent_type, crate.parent_bone = arm, "BONE", "Bone"
    bpy.context.view_layer.update()
    crate.matrix_world = world
    sim = _load(scenes.save(tmp_path / "s.blend"))
    assert sim.dynamic_objects == ["Crate"]
    sim.set_frame(10)
    _assert_as_rendered(sim, "Crate")


def test_animated_object_of_an_instanced_collection_moves(tmp_path):
    _yard()
    crate = _obj("Crate")
    _in_collection(crate, "Vehicle").exclude = True  # only the instance is rendered
    _keyframed(crate, "location", (0, 0, 0.5), (3, 0, 0.5))
    inst = bpy.data.objects.new("VehicleInst", None)
    inst.instance_type, inst.instance_collection = "COLLECTION", bpy.data.collections["Vehicle"]
    inst.location = (-1, -4, 0)
    bpy.context.scene.collection.objects.link(inst)
    sim = _load(scenes.save(tmp_path / "s.blend"))
    assert sim.dynamic_objects == ["VehicleInst/Crate#0"]
    sim.set_frame(10)
    _assert_as_rendered(sim, "Crate")


def test_objects_outside_the_scene_do_not_refuse_it(tmp_path):
    """An object of no scene (an orphan kept in the file) with keyed visibility is not the
    scene's: the scene loads."""
    _yard()
    orphan = bpy.data.objects.new("Orphan", bpy.data.meshes.new("Orphan"))
    orphan.use_fake_user = True
    _keyframed(orphan, "hide_render", True, False)
    sim = Simulator(scenes.save(tmp_path / "s.blend"))
    assert "Orphan" not in sim.labels


def test_an_armature_constraint_on_a_posed_bone_moves_the_object(tmp_path):
    _yard()
    crate, arm = _obj("Crate"), _rig()
    con = crate.constraints.new("ARMATURE")
    target = con.targets.new()
    target.target, target.subtarget = arm, "Bone"
    sim = _load(scenes.save(tmp_path / "s.blend"))
    assert sim.dynamic_objects == ["Crate"]
    sim.set_frame(10)
    _assert_as_rendered(sim, "Crate")

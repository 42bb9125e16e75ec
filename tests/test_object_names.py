"""Any object name works: keys in ``object_names`` never collide (issue #36, item 6), any name
renders with its labels and Cryptomatte coverage (item 7), and an object with NaN or infinite
coordinates is refused at load in one line that names it (lesser item)."""

import math

import bpy
import numpy as np
import pytest

import scenes
from generator import Simulator
from generator.blender.keys import instance_key, key_names, object_key, owner_name
from generator.blender.objects import SceneError

W, H = 64, 48


def _instancer(name: str, collection, location):
    empty = bpy.data.objects.new(name, None)
    empty.instance_type, empty.instance_collection = "COLLECTION", collection
    empty.location = location
    bpy.context.scene.collection.objects.link(empty)
    return empty


def _kit(object_name: str):
    """A collection, not in the scene, holding one 1 m box named ``object_name``."""
    box = scenes.add_box(object_name, (1, 1, 1), (0, 0, 0.5))
    bpy.context.scene.collection.objects.unlink(box)
    kit = bpy.data.collections.new("Kit")
    kit.objects.link(box)
    return kit


# (instancer, instanced object, plain objects whose names read as that instance's key)
COLLISIONS = {
    "issue": ("Inst", "Cube", ["Inst/Cube#0"]),
    "escaped lookalike too": ("Inst", "Cube", ["Inst/Cube#0", "Inst%2FCube%230"]),
    "slash in the instancer": ("A/B", "Cube", ["A/B/Cube#0"]),
    "hash in the object": ("I", "X#1", ["I/X#1#0", "I/X"]),
}


@pytest.mark.parametrize("case", COLLISIONS)
def test_an_object_named_like_an_instance_key_keeps_its_own_key(case, tmp_path):
    instancer, inner, lookalikes = COLLISIONS[case]
    scenes.new_scene(W, H)
    scenes.add_plane("Ground", (60, 60), (0, 10, 0))
    _instancer(instancer, _kit(inner), (3, 8, 1))  # boxes off the ground: every face carries points
    for k, name in enumerate(lookalikes):
        scenes.add_box(name, (1, 1, 1), (-3 + 1.5 * k, 8, 1.5 + 2 * k))
    scenes.look_along_y((0, 0, 1.0))
    sim = Simulator(scenes.save(tmp_path / "keys.blend"), points_density=50)
    copy = instance_key(instancer, inner, "0")
    assert sorted(sim.object_names) == sorted(["Ground", copy] + [object_key(n) for n in lookalikes])
    assert len(set(sim.object_names)) == len(sim.object_names) == 2 + len(lookalikes)
    clouds, labels = sim.static_point_clouds, sim.object_labels
    assert labels[copy] == inner.split(".")[0]
    np.testing.assert_allclose(clouds[copy].mean(axis=0), [3, 8, 1.5], atol=0.1)  # the instanced box
    for k, name in enumerate(lookalikes):
        assert labels[object_key(name)] == name
        np.testing.assert_allclose(clouds[object_key(name)].mean(axis=0), [-3 + 1.5 * k, 8, 1.5 + 2 * k], atol=0.1)
    assert set(sim.labels) == {"Ground", inner, *lookalikes}


def test_filter_object_names_takes_the_names_not_the_keys(tmp_path):
    scenes.new_scene(W, H)
    scenes.add_plane("Ground", (60, 60), (0, 10, 0))
    _instancer("A/B", _kit("Cube"), (3, 8, 0))
    scenes.add_box("A/B/Cube#0", (1, 1, 1), (-3, 8, 0.5))
    scenes.look_along_y((0, 0, 1.0))
    path = scenes.save(tmp_path / "filter.blend")
    assert Simulator(path, filter_object_names=["A/B"]).object_names == ["A%2FB%2FCube%230", "Ground"]
    assert Simulator(path, filter_object_names=["A/B/Cube#0"]).object_names == ["A%2FB/Cube#0", "Ground"]


def test_an_instance_table_name_the_scene_lacks_is_labelled_by_its_object_name(tmp_path):
    scenes.new_scene(W, H)
    scenes.add_plane("Ground", (60, 60), (0, 10, 0))
    scenes.look_along_y((0, 0, 1.0))
    table = ["Ground", "Gone%2FCrate.002", "Yard/Pipe%25.001#3-1"]
    sim = Simulator(scenes.save(tmp_path / "table.blend"), instance_names=table)
    assert sim.object_names == table
    assert [sim.object_labels[n] for n in table] == ["Ground", "Gone/Crate", "Pipe%"]


NAMES = ["plain", "Crate.001", 'say "hi"\\', "a/b#c%d", "%2F%23%25", "/", "#", "%", "", "x/y/z##", "ü/日本#\n"]


@pytest.mark.parametrize("name", NAMES)
def test_keys_decode_to_the_names_they_were_made_of(name):
    plain, copy = object_key(name), instance_key(name, name, "5-2")
    assert key_names(plain) == (None, name) and key_names(copy) == (name, name)
    assert owner_name(plain) == owner_name(copy) == name
    if not set(name) & set("%/#"):
        assert plain == name and copy == f"{name}/{name}#5-2"  # ordinary names keep their keys
    others = [object_key(n) for n in NAMES if n != name] + [instance_key(a, b, "5-2") for a in NAMES for b in NAMES]
    assert others.count(plain) == 0 and others.count(copy) == 1


# names Blender's Cryptomatte manifest (JSON in the EXR header) writes unescaped
ODD_NAMES = ['say "hi"\\', "new\nline", "tab\there", "ctl\x01\x1f\x7f", "Ünïcødé 日本.003", "Inst/Cube#0",
             '{"json": [1]}', "L" * 200]


@pytest.mark.parametrize("ground_truth", ["geometry", "renderer"])
def test_any_object_name_renders_with_its_labels_and_coverage(ground_truth, tmp_path):
    scenes.new_scene(W, H)
    scenes.add_plane("Ground", (100, 100), (0, 0, 0))
    for k, name in enumerate(ODD_NAMES):  # two rows of four boxes
        scenes.add_box(name, (1.6, 1.6, 1.6), (-3.3 + 2.2 * (k % 4), 6, 1.0 + 2.2 * (k // 4)))
    scenes.add_sun()
    scenes.add_camera((0, -1, 2.1), (math.radians(90), 0, 0), lens=20)
    sim = Simulator(scenes.save(tmp_path / "odd.blend"), render_preset="preview", segmentation_sensitivity=0.0,
                    ground_truth=ground_truth)
    hard = sim.render()
    sim.segmentation_sensitivity = 0.5  # reads each object's Cryptomatte coverage, found by its name
    soft = sim.render()
    for name in ODD_NAMES:
        key = object_key(name)
        label = sim.labels.index(name.removesuffix(".003"))
        pixels = hard.instance == sim.object_names.index(key)
        assert pixels.sum() > 20, repr(name)
        assert np.all(hard.seg[pixels] == label), repr(name)
        assert np.mean(soft.seg[pixels] == label) > 0.7, repr(name)  # covered: keeps the label


@pytest.mark.parametrize("case", ["nan vertex", "inf vertex", "nan location", "nan in an odd name"])
def test_non_finite_coordinates_are_refused_at_load_naming_the_object(case, tmp_path):
    scenes.new_scene(W, H)
    scenes.add_plane("Ground", (60, 60), (0, 10, 0))
    name = 'Crate "7"/#' if case == "nan in an odd name" else "Crate.004"
    box = scenes.add_box(name, (1, 1, 1), (0, 8, 0.5))
    if case == "nan location":
        box.location = (math.nan, 8, 0.5)
    else:  # foreach_set: Blender clamps an infinity assigned to one vertex to the largest float
        co = np.zeros(3 * len(box.data.vertices), np.float32)
        box.data.vertices.foreach_get("co", co)
        co[9] = np.inf if case == "inf vertex" else np.nan
        box.data.vertices.foreach_set("co", co)
    scenes.look_along_y((0, 0, 1.0))
    with pytest.raises(SceneError) as err:
        Simulator(scenes.save(tmp_path / "nan.blend"))
    message = str(err.value)
    assert len(message.splitlines()) == 1 and f"object {name!r}" in message and "NaN or infinite" in message
    assert ("world matrix" if case == "nan location" else "vertices") in message


def _library(path, name: str):
    scenes.new_scene(W, H)
    scenes.add_box(name, (1, 1, 1), (0, 0, 0.5))
    return scenes.save(path)


@pytest.mark.parametrize("local", [True, False], ids=["local and linked", "linked from two libraries"])
def test_two_rendered_objects_of_one_name_are_refused_in_one_line(local, tmp_path):
    libraries = [_library(tmp_path / f"lib{k}.blend", "Crate") for k in range(1 if local else 2)]
    scenes.new_scene(W, H)
    scenes.add_plane("Ground", (60, 60), (0, 10, 0))
    if local:
        scenes.add_box("Crate", (1, 1, 1), (2, 8, 0.5))
    for k, lib in enumerate(libraries):
        with bpy.data.libraries.load(str(lib), link=True) as (_, linked):
            linked.objects = ["Crate"]
        bpy.context.scene.collection.objects.link(linked.objects[0])
    scenes.look_along_y((0, 0, 1.0))
    with pytest.raises(SceneError) as err:
        Simulator(scenes.save(tmp_path / "main.blend"))
    message = str(err.value)
    assert len(message.splitlines()) == 1 and "two rendered objects are named 'Crate'" in message
    assert "'lib0.blend'" in message and ("of this file" if local else "'lib1.blend'") in message

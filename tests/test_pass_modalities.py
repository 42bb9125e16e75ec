"""Modalities made from Blender passes, declared in their registry entry alone
(exporters/modalities.py ``BlenderPass``): the renderer switches a pass on exactly for the
renders that ask for a modality declaring it, a modality declared in a new module of
``exporters`` is found and goes through the real loop into the frame files, and the batch
job refuses an unknown one in one line that lists those registered."""

import subprocess
import sys

import bpy
import numpy as np
import pytest

import scenes
from conftest import ROOT, assert_refused
from exporters.frames import FrameReader
from exporters.modalities import (MODALITIES, BlenderPass, Modality, blender_passes, import_modality_modules,
                                  register_modality, stack, unregister_modality)
from generator import Simulator
from generator.batch.fly import fly
from generator.geometry.camera import look_at
from generator.passes import FIELD_OF_MODALITY, decode_passes
from trajectories import Trajectory

W, H = 32, 24
NAME = "diffuse_color"
# a modality module as a contributor drops it into exporters/: Cycles' Diffuse Color pass
MODULE = '''"""The surfaces' diffuse colour (albedo) from Cycles' Diffuse Color pass."""
from exporters.modalities import BlenderPass, Modality, register_modality, stack

CHANNELS = ("Diffuse Color.R", "Diffuse Color.G", "Diffuse Color.B")
DIFFUSE_COLOR = BlenderPass("Diffuse Color", CHANNELS, stack(*CHANNELS), switches=("use_pass_diffuse_color",))

register_modality(Modality(
    "diffuse_color", "diffuse colour (albedo), linear RGB; 0 = no surface", "render",
    ("diffuse_color.R", "diffuse_color.G", "diffuse_color.B"), "HALF", "colour", "area", passes=(DIFFUSE_COLOR,)))
'''


def write_module(folder) -> None:
    (folder / f"{NAME}.py").write_text(MODULE)


@pytest.fixture(scope="module")
def dropped_in(tmp_path_factory):
    """The module above in a folder of the ``exporters`` package (as if dropped into
    exporters/, without touching the checkout), found by the modalities' scan."""
    import exporters

    folder = tmp_path_factory.mktemp("exporters_extra")
    write_module(folder)
    exporters.__path__.append(str(folder))
    try:
        yield import_modality_modules()
    finally:
        exporters.__path__.remove(str(folder))
        unregister_modality(NAME)
        sys.modules.pop(f"exporters.{NAME}", None)


@pytest.fixture(scope="module")
def sim(tmp_path_factory, dropped_in):
    scenes.new_scene(W, H)
    scenes.add_plane("Ground", (40, 40), (0, 10, 0))
    scenes.add_box("Wall", (4, 0.3, 3), (0, 6, 1.5))
    scenes.add_sun()
    scenes.look_along_y((0, 0, 1.5))
    s = Simulator(scenes.save(tmp_path_factory.mktemp("passes") / "scene.blend"), points_density=5,
                  render_preset="preview")
    s.configure_render(samples=1)
    return s


def switched_on(p: BlenderPass) -> bool:
    """Whether every switch of ``p`` is on in every view layer of the open scene."""
    def value(vl, path):
        *groups, name = path.split(".")
        for g in groups:
            vl = getattr(vl, g)
        return getattr(vl, name)

    return all(value(vl, path) for vl in bpy.context.scene.view_layers for path in p.switches)


def test_a_module_dropped_into_exporters_is_found(dropped_in):
    assert f"exporters.{NAME}" in dropped_in
    assert MODALITIES[NAME].passes[0].name == "Diffuse Color"
    assert list(blender_passes())[-1] == "Diffuse Color"


def test_every_declared_pass_is_on_exactly_when_its_modality_is_asked_for(sim):
    every = blender_passes()
    assert len([p for p in every.values() if p.switches]) >= 4  # Depth, Object Index, Cryptomatte, Diffuse Color
    always = blender_passes(tuple(FIELD_OF_MODALITY))  # what every render() holds
    asks = [()] + [(n,) for n, m in MODALITIES.items() if m.source == "render"] + [()]
    for outputs in asks:
        out = sim.render(outputs=outputs)
        wanted = blender_passes(tuple(FIELD_OF_MODALITY) + outputs)
        for name, p in every.items():
            if p.switches:
                assert switched_on(p) == (name in wanted), (outputs, name)
        assert set(out.outputs) == set(FIELD_OF_MODALITY) | set(outputs)
        assert set(wanted) == set(always) | {p.name for n in outputs for p in MODALITIES[n].passes}
    for vl in bpy.context.scene.view_layers:  # a pass's settings hold while it is on
        assert vl.pass_cryptomatte_depth == every["CryptoObject"].settings["pass_cryptomatte_depth"]


def test_the_dropped_in_modality_is_rendered_and_written_end_to_end(sim, tmp_path):
    poses = np.stack([look_at((0.0, -1.0 + 0.2 * t, 1.5), (0.0, 6.0, 1.5)) for t in range(2)])
    names = ("rgb", "depth", "label", "instance", NAME)
    fly(sim, Trajectory(poses, np.arange(2) / 10.0, "test"), tmp_path / "test", seed=0, outputs=names)
    reader = FrameReader(tmp_path / "test")
    assert reader.modalities == names
    for i in range(2):
        frame = reader.read(i)
        albedo, depth = frame[NAME].astype(np.float32), frame["depth"]
        assert albedo.shape == (H, W, 3) and frame[NAME].dtype == np.float16
        surface = np.isfinite(depth)
        assert surface.any() and (~surface).any()
        # Blender's default surface (no material): grey base colour 0.8, less what its specular
        # layer reflects (Fresnel: more at grazing angles); no surface has no diffuse colour
        grey = albedo[surface]
        assert np.all(grey == grey[:, :1]) and grey.min() > 0.6 and grey.max() <= 0.8
        assert np.all(albedo[~surface] == 0)
    assert switched_on(MODALITIES[NAME].passes[0])
    assert NAME not in sim.render().outputs and not switched_on(MODALITIES[NAME].passes[0])  # asked for no more


def test_a_switch_blender_does_not_have_is_named(sim):
    bad = BlenderPass("Bad", ("Bad.X",), stack("Bad.X"), switches=("use_pass_no_such_thing",))
    register_modality(Modality("bad_pass", "test", "render", ("bad",), "FLOAT", "data", "bilinear", passes=(bad,)))
    try:  # every render switches a registered pass it does not need off: a bad declaration shows at once
        with pytest.raises(ValueError, match="Blender pass 'Bad': cannot set view-layer property 'use_pass_no_such_thing'"):
            sim.render()
    finally:
        unregister_modality("bad_pass")
    assert sim.render().rgb.shape == (H, W, 3)


def test_an_unknown_output_is_refused_in_one_line_listing_the_registered_ones(tmp_path):
    """In a fresh process, with the module dropped into a folder of ``exporters``: the list
    holds the built-in modalities and the one found."""
    write_module(tmp_path)
    code = ("import sys, runpy, exporters; exporters.__path__.append(sys.argv.pop(1)); "
            "runpy.run_module('generator', run_name='__main__', alter_sys=True)")
    r = subprocess.run([sys.executable, "-c", code, str(tmp_path), "--out", str(tmp_path / "out"),
                        "--outputs", "rgb,bogus"], capture_output=True, text=True, cwd=ROOT)
    line = assert_refused(r, "unknown output bogus")
    listed = line.split("choose from ", 1)[1].split(" (")[0].split(", ")
    assert listed == ["rgb", "rgb_linear", "depth", "label", "instance", "normal", "flow", "backward_flow", NAME]


def test_declarations_are_checked_and_missing_passes_named():
    grey = BlenderPass("Grey", ("Grey.V",), stack("Grey.V"), switches=("use_pass_grey",))
    with pytest.raises(ValueError, match="a render modality needs passes"):
        Modality("grey", "test", "render", ("grey",), "FLOAT", "data", "bilinear")
    with pytest.raises(ValueError, match="needs compute and no Blender passes"):
        Modality("grey", "test", "geometry", ("grey",), "FLOAT", "data", "bilinear", compute=len, passes=(grey,))
    with pytest.raises(ValueError, match="channels must be names '<layer>.<channel>'"):
        BlenderPass("Grey", ("V",), stack("V"))
    twin = BlenderPass("Depth", ("Depth.Z",), stack("Depth.Z"), switches=("use_pass_z",))
    with pytest.raises(ValueError, match="Blender pass 'Depth' is already declared"):
        register_modality(Modality("depth_twin", "test", "render", ("Z",), "FLOAT", "data", "bilinear", passes=(twin,)))
    assert "depth_twin" not in MODALITIES
    m = Modality("grey", "test", "render", ("grey",), "FLOAT", "data", "bilinear", passes=(grey,))
    plane = np.full((2, 3), 0.5, np.float32)
    decoded = decode_passes({"ViewLayer.Grey.V": plane}, [grey])
    assert m.from_render(decoded).dtype == np.float32 and np.array_equal(m.from_render(decoded), plane)
    with pytest.raises(ValueError, match="needs Blender's Grey pass, which this render engine did not write"):
        m.from_render(decode_passes({"ViewLayer.Depth.Z": plane}, [grey]))

"""Surface materials (issue #38): every declared material's texture layers are valid, and a
textured material changes what the camera sees, never what the labels, depth and normals say."""

from __future__ import annotations

import math

import numpy as np
import pytest

import scenes
from generator import Simulator
from generator.scene.catalogue.ground import SURFACES, surface_material
from generator.scene.kinds import all_materials
from generator.scene.materials import PATTERN_KINDS, Material, Pattern

PATCH = 8


def test_every_material_declares_valid_layers():
    materials = all_materials()
    for surface in SURFACES:
        ground = materials[surface_material(surface)]
        assert len(ground.patterns()) >= 4 and ground.planar  # texture from tens of metres to centimetres
        scales = sorted(p.scale for p in ground.patterns())
        assert scales[0] <= 0.1 and scales[-1] >= 20  # features per metre
    for name, m in materials.items():
        for p in m.patterns():
            assert p.kind in PATTERN_KINDS and p.scale > 0 and 0 <= p.strength <= 1, name
            assert all(0 <= c <= 1 for c in p.colour), name
    with pytest.raises(ValueError, match="Pattern kind 'wave' is unknown; choose one of noise, voronoi, courses"):
        Pattern(1.0, (0.5, 0.5, 0.5), 0.5, kind="wave")
    with pytest.raises(ValueError, match=r"^Pattern stretch must be three positive factors \(x, y, z\), got \(1.0, 0.0, 1.0\)$"):
        Pattern(1.0, (0.5, 0.5, 0.5), 0.5, stretch=(1.0, 0.0, 1.0))


def ground_view(path, material: str | None):
    """A 200 m plane seen from 2 m up, looking 30 degrees down, its material ``material``
    (a site material of seed 5) or none."""
    from generator.blender.materials import make_material

    scenes.new_scene(96, 64)
    plane = scenes.add_plane("Ground", (200, 200), (0, 0, 0))
    if material is not None:
        plane.data.materials.append(make_material(material, 5))
    scenes.add_sun()
    scenes.add_camera((0, -10, 2.0), (math.radians(60), 0, 0))
    return scenes.save(path)


def patch_std(rgb: np.ndarray, mask: np.ndarray) -> float:
    """Median over the patches lying wholly on ``mask`` of the intensity's standard deviation."""
    h, w = mask.shape
    grey = rgb.mean(axis=2)[: h // PATCH * PATCH, : w // PATCH * PATCH]
    on = mask[: h // PATCH * PATCH, : w // PATCH * PATCH]
    blocks = grey.reshape(h // PATCH, PATCH, w // PATCH, PATCH)
    whole = on.reshape(h // PATCH, PATCH, w // PATCH, PATCH).all(axis=(1, 3))
    return float(np.median(blocks.std(axis=(1, 3))[whole]))


def test_every_material_states_a_lidar_reflectivity():
    """In [0, 1]; declared where the colour misleads (glass, rubber, bare metal, retroreflective
    hi-vis), else 0.05 + 0.9 x the colour's Rec. 709 luminance."""
    materials = all_materials()
    for m in materials.values():
        assert 0.0 <= m.lidar_reflectivity <= 1.0, m.name
        if m.reflectivity is None:
            r, g, b = m.colour
            assert m.lidar_reflectivity == pytest.approx(0.05 + 0.9 * (0.2126 * r + 0.7152 * g + 0.0722 * b))
    assert materials["glass"].lidar_reflectivity < 0.05 < materials["concrete"].lidar_reflectivity
    assert materials["reflective_white"].lidar_reflectivity == 1.0 and materials["hivis"].lidar_reflectivity >= 0.9
    assert materials["default"].lidar_reflectivity == pytest.approx(0.5)  # mid grey
    with pytest.raises(ValueError, match=r"^material 'x': reflectivity must be in \[0, 1\], got 1.5$"):
        Material("x", (0.5, 0.5, 0.5), 0.5, reflectivity=1.5)


def test_the_ground_material_textures_the_image_and_leaves_the_ground_truth_alone(tmp_path):
    """Its colour layers change the pixels; depth, labels, normals and points stay."""
    views = {}
    for material in (None, "ground-compacted-soil"):
        sim = Simulator(ground_view(tmp_path / f"{material}.blend", material), points_density=0.5,
                        segmentation_sensitivity=0.0)
        sim.configure_render(engine="CYCLES", samples=16, denoise=False)
        pose = sim.get_world_from_camera()
        names = ["rgb_linear", "depth", "label", "normal"]
        out = sim.render_outputs(names, pose[None], np.zeros((1, 0, 4, 4)), 0)
        views[material] = {k: np.asarray(out[k]) for k in names}
        views[material]["points"] = sim.compute_point_cloud(update_mask=False)[0]
    plain, textured = views[None], views["ground-compacted-soil"]
    for key in ("depth", "label", "normal", "points"):
        np.testing.assert_array_equal(plain[key], textured[key], err_msg=key)
    ground = np.isfinite(plain["depth"]) & (plain["label"] >= 0)
    assert ground.mean() > 0.5
    rgb_plain, rgb_textured = plain["rgb_linear"], textured["rgb_linear"]
    # 16 samples leave some noise on the plain plane; the texture's contrast is well above it
    assert patch_std(rgb_textured, ground) > 3 * patch_std(rgb_plain, ground) + 0.001, (
        patch_std(rgb_textured, ground), patch_std(rgb_plain, ground))


def test_brick_shows_its_mortar_courses_at_their_true_size(tmp_path):
    """A brick wall 0.95 m in front of the camera: the image rows' brightness repeats once a
    course (75 mm: 13.3 courses per metre), as many pixels as 0.075 m spans at that distance."""
    from generator.blender.materials import make_material

    scenes.new_scene(96, 96)
    wall = scenes.add_box("Wall", (4.0, 0.1, 3.0), (0.0, 1.0, 0.0))
    wall.data.materials.append(make_material("brick", 5))
    scenes.add_sun(rotation=(1.2, 0.0, 0.3))
    scenes.look_along_y((0.0, 0.0, 0.0))
    sim = Simulator(scenes.save(tmp_path / "wall.blend"), points_density=0.5)
    sim.configure_render(engine="CYCLES", samples=16, denoise=False)
    out = sim.render_outputs(["rgb_linear", "depth"], sim.get_world_from_camera()[None], np.zeros((1, 0, 4, 4)), 0)
    depth, rgb = np.asarray(out["depth"]), np.asarray(out["rgb_linear"])
    assert np.allclose(depth, 0.95, atol=1e-4)  # the wall fills the view, square on
    rows = rgb.mean(axis=(1, 2))
    spectrum = np.abs(np.fft.rfft(rows - rows.mean()))
    period = len(rows) / (np.argmax(spectrum[2:]) + 2)
    expected = 0.075 * sim.K[1, 1] / 0.95
    assert abs(period - expected) < 0.1 * expected, (period, expected)


@pytest.mark.parametrize("material, along, distance", [("steel_painted", "z", 2.0), ("wood", "x", 1.0)])
def test_stretched_layers_run_along_their_axis(tmp_path, material, along, distance):
    """Painted steel's dirt streaks run down (stretched along z) and timber's grain along the
    beam (x): on a wall square to the camera, less its smooth shading (a Gaussian blur of 8
    px), neighbours 4 px apart differ several times more across the features than along them."""
    from scipy.ndimage import gaussian_filter

    from generator.blender.materials import make_material

    scenes.new_scene(96, 96)
    wall = scenes.add_box("Wall", (8.0, 0.1, 6.0), (0.0, distance + 0.05, 0.0))
    wall.data.materials.append(make_material(material, 5))
    scenes.add_sun(rotation=(1.2, 0.0, 0.3))
    scenes.look_along_y((0.0, 0.0, 0.0))
    sim = Simulator(scenes.save(tmp_path / "wall.blend"), points_density=0.5)
    sim.configure_render(engine="CYCLES", samples=16, denoise=True)
    out = sim.render_outputs(["rgb_linear", "depth"], sim.get_world_from_camera()[None], np.zeros((1, 0, 4, 4)), 0)
    assert np.allclose(np.asarray(out["depth"]), distance, atol=1e-4)  # the wall fills the view, square on
    grey = np.asarray(out["rgb_linear"]).mean(axis=2)
    detail = grey - gaussian_filter(grey, 8)
    sideways = np.mean((detail[:, 4:] - detail[:, :-4]) ** 2)  # along the image's x: the world's x
    upright = np.mean((detail[4:] - detail[:-4]) ** 2)  # along the image's y: the world's -z
    ratio = sideways / upright if along == "z" else upright / sideways
    assert ratio > 3.0, (material, sideways, upright)

"""Rendering with real Cycles on tiny images: depth, labels, RGB and files are exact. The render
settings (presets, engines, devices, resolution, temporary files, stdout) are in
test_render_settings.py; both render conftest's plane_blend (tests/scenes.py's tilted plane)."""

import math

import numpy as np
import OpenEXR
import pytest

import scenes
from exporters.exr import read_frame_exr, write_frame_exr
from generator import Simulator
from generator.blender import egl
from generator.geometry.raycast import SceneGeometry

W, H = scenes.TILTED_PLANE_SIZE


@pytest.fixture(scope="module", params=["geometry", "renderer"])
def rendered(plane_blend, request):
    """A render with each ground-truth source: the ray cast (default) and Cycles' passes."""
    sim = Simulator(plane_blend, points_density=50, segmentation_sensitivity=0.0, render_preset="preview",
                    ground_truth=request.param)
    return sim, sim.render()


def _plane_depth(sim):
    """Analytic planar depth of the Board plane through every pixel centre."""
    from generator.geometry.camera import pixel_rays

    rx, rz = math.radians(60), math.radians(20)
    n_local = np.array([0, 0, 1.0])
    Rx = np.array([[1, 0, 0], [0, math.cos(rx), -math.sin(rx)], [0, math.sin(rx), math.cos(rx)]])
    Rz = np.array([[math.cos(rz), -math.sin(rz), 0], [math.sin(rz), math.cos(rz), 0], [0, 0, 1]])
    n = Rz @ Rx @ n_local
    pose = sim.get_world_from_camera()
    dirs = pixel_rays(sim.K, sim.width, sim.height) @ pose[:3, :3].T  # camera z = 1
    return (n @ (np.array([0, 10, 0]) - pose[:3, 3])) / (dirs @ n)


def test_depth_of_tilted_plane_is_analytic(rendered):
    sim, out = rendered
    expected = _plane_depth(sim)
    board = sim.labels.index("Board")
    on_board = (out.instance == sim.object_names.index("Board")) & (out.seg == board)
    assert on_board.sum() > 0.5 * W * H
    rel = np.abs(out.depth[on_board] - expected[on_board]) / expected[on_board]
    assert rel.max() < 1e-4, f"max relative depth error {rel.max():.2e}"
    assert out.depth.dtype == np.float32 and out.depth.shape == (H, W)


def test_unprojected_depth_lands_on_surfaces(rendered):
    sim, out = rendered
    from exact_geometry import distance_to_mesh, scene_triangles

    pts = sim.depth_to_world_points(out.depth)
    valid = np.isfinite(out.depth)
    # exact float64 distances (open3d's float32 distance query is off by ~0.3 mm on thin triangles)
    d = distance_to_mesh(pts[valid], scene_triangles(sim.scene_parts()))
    assert (d < 1e-3).mean() >= 0.999, f"{(d >= 1e-3).sum()} of {valid.sum()} pixels off the surfaces"


def test_labels_match_the_surface_at_pixel_centres(rendered):
    sim, out = rendered
    from generator.geometry.camera import pixel_rays

    pose = sim.get_world_from_camera()
    dirs = (pixel_rays(sim.K, W, H) @ pose[:3, :3].T).reshape(-1, 3)
    parts = sim.scene_parts()
    t, part = SceneGeometry(parts).cast(np.broadcast_to(pose[:3, 3], dirs.shape), dirs)
    labels = np.array([sim.label_ids[p.label] for p in parts])
    expected = np.where(part >= 0, labels[np.maximum(part, 0)], -1).reshape(H, W)
    agree = (out.seg == expected).mean()
    assert agree >= 0.999, f"labels agree on {agree:.4%} of pixels"
    expected_depth = np.where(part >= 0, t, np.inf).reshape(H, W)
    assert np.array_equal(np.isinf(out.depth), np.isinf(expected_depth))
    assert set(np.unique(out.seg)) == {sim.labels.index(n) for n in ("Board", "Crate", "Pole")}


def test_visible_points_agree_with_rendered_depth(rendered):
    sim, out = rendered
    pts, _, vis = sim.compute_point_cloud(update_mask=False)
    uv, z = sim.project(pts[vis])
    j, i = np.floor(uv[:, 0]).astype(int), np.floor(uv[:, 1]).astype(int)
    depth = out.depth
    # pixels on depth edges (any 3x3 neighbour differs by more than 5%) are excluded
    pad = np.pad(depth, 1, mode="edge")
    neigh = np.stack([pad[1 + di : 1 + di + H, 1 + dj : 1 + dj + W] for di in (-1, 0, 1) for dj in (-1, 0, 1)])
    with np.errstate(invalid="ignore"):
        edge = np.any(~np.isfinite(neigh), axis=0) | (np.nanmax(neigh, axis=0) > 1.05 * np.nanmin(neigh, axis=0))
    keep = ~edge[i, j]
    assert keep.sum() > 500
    # the point is within the pixel, so its depth matches the pixel's up to the surface slope
    agree = np.abs(z[keep] - depth[i, j][keep]) <= 0.02 * depth[i, j][keep]
    assert agree.mean() >= 0.99, f"{agree.mean():.4%} of visible points agree with the depth map"


def test_display_rgb_matches_blenders_own_png(rendered, tmp_path):
    sim, out = rendered
    import bpy
    from PIL import Image

    from generator.blender import session

    scene = bpy.context.scene
    fmt = scene.render.image_settings
    fmt.media_type, fmt.file_format, fmt.color_depth = "IMAGE", "PNG", "8"
    scene.render.dither_intensity = 0.0  # Blender dithers 8-bit output by default
    try:
        with session.quiet():
            bpy.data.images["Render Result"].save_render(str(tmp_path / "ref.png"), scene=scene)
    finally:
        fmt.media_type, fmt.file_format, fmt.color_depth = "MULTI_LAYER_IMAGE", "OPEN_EXR_MULTILAYER", "32"
    ref = np.asarray(Image.open(tmp_path / "ref.png").convert("RGB"), dtype=np.float32) / 255
    assert out.rgb.dtype == np.float32 and out.rgb.shape == (H, W, 3)
    assert 0.05 < out.rgb.mean() < 0.95  # lit, not black or blown out
    assert np.abs(out.rgb - ref).max() <= 0.5 / 255 + 1e-4  # ours rounded to 8 bits is Blender's PNG
    assert out.rgb_linear.dtype == np.float32 and not np.allclose(out.rgb_linear, out.rgb, atol=0.05)


def test_segmentation_sensitivity_masks_thin_pole(plane_blend):
    sim = Simulator(plane_blend, points_density=1, segmentation_sensitivity=0.0, render_preset="preview")
    sim.configure_render(samples=16)
    pole = sim.labels.index("Pole")
    hard = sim.render().seg
    sim.segmentation_sensitivity = 0.9
    soft = sim.render().seg
    assert (hard == pole).sum() >= 10  # the 6 cm pole is under one pixel wide but keeps its labels
    assert (soft == pole).sum() < 0.5 * (hard == pole).sum()  # mixed pixels lose the label
    assert np.all(np.isin(soft[soft != hard], [-1]))  # sensitivity only ever drops labels
    board = sim.labels.index("Board")
    assert (soft == board).sum() > 0.8 * (hard == board).sum()  # large surfaces keep theirs


def test_cryptomatte_pixel_ids_clamp_the_exponent():
    from generator.passes import cryptomatte_pixel_id

    assert cryptomatte_pixel_id(0x8018FECD) == 0x8098FECD  # exponent 0 -> 1 (no denormal)
    assert cryptomatte_pixel_id(0x7FC00001) == 0x7F400001  # exponent 255 -> 254 (no NaN or inf)
    assert cryptomatte_pixel_id(0x3F80ABCD) == 0x3F80ABCD  # every other hash is its own id


def test_sensitivity_keeps_the_labels_of_every_object_name(tmp_path):
    """murmur3("Crate.070") has a float exponent of 0, which Blender's Cryptomatte pixels
    clamp: with the default sensitivity (0.1) its pixels used to lose their label."""
    scenes.new_scene(64, 48)
    scenes.add_plane("Ground", (100, 100), (0, 0, 0))
    scenes.add_box("Crate.001", (2, 2, 2), (-2, -5, 1))
    scenes.add_box("Crate.070", (2, 2, 2), (2, -5, 1))
    scenes.add_sun()
    scenes.add_camera((0, -15, 3), (math.radians(80), 0, 0))
    sim = Simulator(scenes.save(tmp_path / "crates.blend"), render_preset="preview")
    assert sim.segmentation_sensitivity == 0.1
    out = sim.render()
    for name in ("Crate.001", "Crate.070"):
        pixels = out.instance == sim.object_names.index(name)
        assert pixels.sum() > 100, name
        assert np.mean(out.seg[pixels] == sim.labels.index("Crate")) > 0.9, name


def test_frame_exr_round_trip_and_other_readers(rendered, tmp_path):
    sim, out = rendered
    path = write_frame_exr(tmp_path / "f.exr", out.rgb, out.depth, out.seg, out.instance, compression="zip")
    back = read_frame_exr(path)
    np.testing.assert_array_equal(back["rgb"], out.rgb.astype(np.float16))
    np.testing.assert_array_equal(back["depth"], out.depth)
    np.testing.assert_array_equal(back["label"], out.seg)
    np.testing.assert_array_equal(back["instance"], out.instance)
    # the plain OpenEXR API sees the documented channels and types
    with OpenEXR.File(str(path), separate_channels=True) as f:  # one part per component type
        types = {n: c.pixels.dtype for p in f.parts for n, c in p.channels.items()}
    assert types == {"R": np.float16, "G": np.float16, "B": np.float16, "Z": np.float32,
                     "label": np.uint32, "instance": np.uint32}
    # and Blender's own image reader gets the same colours from a colour-only frame EXR (one
    # part; bpy's loader gives no pixels for multi-part files, docs/format.md)
    import bpy

    img = bpy.data.images.load(str(write_frame_exr(tmp_path / "colour.exr", out.rgb)))
    px = np.array(img.pixels[:], dtype=np.float32).reshape(H, W, 4)[::-1, :, :3]  # bottom-up rows
    np.testing.assert_allclose(px, out.rgb.astype(np.float16).astype(np.float32), atol=1e-3)


@pytest.mark.parametrize("compression", ["none", "rle", "zips", "zip", "piz"])
def test_exr_round_trip_all_compressions(tmp_path, compression):
    rng = np.random.default_rng(7)
    rgb = rng.random((9, 11, 3)).astype(np.float16)
    depth = rng.uniform(0.1, 500, (9, 11)).astype(np.float32)
    depth[0, :3] = np.inf
    label = rng.integers(-1, 40, (9, 11)).astype(np.int32)
    inst = rng.integers(-1, 2**31 - 1, (9, 11)).astype(np.int32)
    back = read_frame_exr(write_frame_exr(tmp_path / "x.exr", rgb, depth, label, inst, compression=compression))
    for key, arr in (("rgb", rgb), ("depth", depth), ("label", label), ("instance", inst)):
        assert back[key].dtype == arr.dtype
        np.testing.assert_array_equal(back[key], arr)


def test_workbench_depth_and_labels(plane_blend):
    """EEVEE/Workbench have no object-index pass: labels come from rays through pixel centres."""
    ok, reason = egl.gpu_context_available()
    if not ok:
        pytest.fail(f"tools/bootstrap.sh installs EGL, yet the probe failed: {reason}")
    sim = Simulator(plane_blend, points_density=1, segmentation_sensitivity=0.0)
    sim.configure_render(engine="BLENDER_WORKBENCH")
    out = sim.render()
    expected = _plane_depth(sim)
    on_board = out.seg == sim.labels.index("Board")
    assert on_board.sum() > 0.5 * W * H
    rel = np.abs(out.depth[on_board] - expected[on_board]) / expected[on_board]
    assert np.median(rel) < 1e-4
    assert set(np.unique(out.seg)) == {sim.labels.index(n) for n in ("Board", "Crate", "Pole")}

"""A Simulator rendering through a lens model (Simulator.set_lens): Blender's colour through
the custom camera, the ground truth through the same model at the pixel centres, both checked
against OpenCV's own inverse of the model (cv2.undistortPointsIter, cv2.fisheye)."""

import cv2
import numpy as np
import pytest

from generator import Simulator

OPENCV = (-0.3, 0.08, 0.002, -0.0015, 0.0)
FISHEYE = (0.02, -0.01, 0.003, -0.0005)
CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14)


def _opencv_rays(model, K, w, h):
    """OpenCV's normalised (a, b) (H, W, 2) through every pixel centre."""
    j, i = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    pix = np.stack([j, i], -1).reshape(-1, 1, 2)
    if model == "opencv":
        ab = cv2.undistortPointsIter(pix, K, np.array(OPENCV), None, None, CRITERIA)
    else:
        ab = cv2.fisheye.undistortPoints(pix, K, np.array(FISHEYE), criteria=CRITERIA)
    return ab[:, 0].reshape(h, w, 2)


@pytest.fixture(scope="module")
def renders(walls_blend):
    sim = Simulator(walls_blend, points_density=2.0, render_preset="preview")
    sim.configure_render(samples=16, resolution=(96, 72), denoise=False)
    plain = sim.render()
    out = {}
    for model, coefficients in (("opencv", OPENCV), ("fisheye", FISHEYE)):
        sim.set_lens(model, coefficients)
        render = sim.render()
        finite = np.isfinite(render.depth)
        # through the Simulator's own projection while the lens is set
        out[model] = (render, sim.K.copy(), sim.project(sim.depth_to_world_points(render.depth)[finite]))
    sim.set_lens("pinhole")
    back = sim.render()
    return sim, plain, out, back


@pytest.mark.parametrize("model", ["opencv", "fisheye"])
def test_depth_is_the_surface_along_opencvs_ray_through_each_pixel(renders, model):
    """An independent cast (open3d, float64 check) along OpenCV's own ray of every pixel centre
    gives the stored planar depth."""
    import open3d as o3d

    sim, _, out, _ = renders
    render, K, _ = out[model]
    h, w = render.depth.shape
    ab = _opencv_rays(model, K, w, h)
    scene = o3d.t.geometry.RaycastingScene()
    for p in sim.scene_parts():
        scene.add_triangles(o3d.core.Tensor(p.world_vertices().astype(np.float32)),
                            o3d.core.Tensor(p.faces.astype(np.uint32)))
    pose = sim.get_world_from_camera()
    cam = np.concatenate([ab, np.ones((h, w, 1))], -1).reshape(-1, 3)  # z = 1: t is planar depth
    rays = np.concatenate([np.broadcast_to(pose[:3, 3], cam.shape), cam @ pose[:3, :3].T], 1)
    t = scene.cast_rays(o3d.core.Tensor(rays.astype(np.float32)))["t_hit"].numpy().reshape(h, w)
    finite = np.isfinite(render.depth)
    assert finite.mean() > 0.5 and np.array_equal(finite, np.isfinite(t))  # the rest is sky
    assert np.max(np.abs(render.depth[finite] - t[finite]) / t[finite]) < 1e-5


@pytest.mark.parametrize("model", ["opencv", "fisheye"])
def test_points_unprojected_through_the_lens_project_back_onto_their_pixels(renders, model):
    _, _, out, _ = renders
    render, _, (uv, z) = out[model]
    h, w = render.depth.shape
    finite = np.isfinite(render.depth)
    j, i = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    assert np.max(np.abs(uv - np.stack([j[finite], i[finite]], -1))) < 1e-6
    assert np.allclose(z, render.depth[finite], rtol=1e-6)


@pytest.mark.parametrize("model", ["opencv", "fisheye"])
def test_the_colour_is_the_pinhole_colour_remapped_by_opencv(renders, model):
    """Blender's render through the lens equals its pinhole render resampled at OpenCV's
    rays (cv2.remap): the custom camera bends the rays as OpenCV's model says, the right way
    up; and its labels are those of the pinhole labels there, away from object edges."""
    _, plain, out, _ = renders
    render, K, _ = out[model]
    h, w = render.depth.shape
    ab = _opencv_rays(model, K, w, h)
    map_x = (K[0, 0] * ab[..., 0] + K[0, 2] - 0.5).astype(np.float32)  # remap: pixel centres at integers
    map_y = (K[1, 1] * ab[..., 1] + K[1, 2] - 0.5).astype(np.float32)
    inside = (map_x >= 1) & (map_x <= w - 2) & (map_y >= 1) & (map_y <= h - 2)
    assert inside.mean() > 0.5
    warped = cv2.remap(plain.rgb.astype(np.float32), map_x, map_y, cv2.INTER_LINEAR)
    diff = np.abs(warped - render.rgb.astype(np.float32)).mean(axis=-1)[inside]
    assert np.median(diff) < 4 and diff.mean() < 8  # 8-bit levels: sampling noise and edges
    seg = cv2.remap(plain.seg.astype(np.float32), map_x, map_y, cv2.INTER_NEAREST)
    flat = cv2.erode((cv2.Laplacian(plain.seg.astype(np.float32), cv2.CV_32F) == 0).astype(np.uint8),
                     np.ones((3, 3), np.uint8))
    away = inside & (cv2.remap(flat, map_x, map_y, cv2.INTER_NEAREST) > 0)
    assert away.mean() > 0.3 and np.mean(seg[away] == render.seg[away]) > 0.99


def test_back_to_the_pinhole_renders_as_before(renders):
    _, plain, _, back = renders
    assert np.array_equal(plain.depth, back.depth) and np.array_equal(plain.seg, back.seg)


def test_a_lens_that_folds_inside_the_image_is_refused_and_the_camera_kept(renders):
    sim = renders[0]
    with pytest.raises(ValueError, match="folds back inside the 96x72 image"):
        sim.set_lens("opencv", (-2.0, 0.0, 0.0, 0.0))
    assert sim.lens.model == "pinhole"


@pytest.mark.parametrize("model", ["opencv", "fisheye"])
def test_undistorting_on_load_gives_the_pinhole_render_of_the_same_pose(renders, model):
    """datasets.Undistort on the distorted render = the pinhole render with the same K: labels
    equal away from edges, depth to 0.2% on surfaces, colour close (both path-traced with
    noise); flow-free, so only the maps are checked here."""
    from datasets import Undistort
    from generator.geometry.lens import lens_of

    _, plain, out, _ = renders
    render, K, _ = out[model]
    lens = lens_of(model, OPENCV if model == "opencv" else FISHEYE)
    sample = {"rgb": render.rgb, "depth": render.depth, "label": render.seg, "instance": render.instance, "K": K}
    u = Undistort(lens)(sample)
    assert np.array_equal(u["K"], K) and u["depth"].shape == plain.depth.shape
    seen = u["label"] >= 0
    flat = cv2.erode((cv2.Laplacian(plain.seg.astype(np.float32), cv2.CV_32F) == 0).astype(np.uint8),
                     np.ones((3, 3), np.uint8)) > 0
    away = seen & flat & np.isfinite(plain.depth)
    assert away.mean() > 0.3 and np.mean(u["label"][away] == plain.seg[away]) > 0.99
    both = away & np.isfinite(u["depth"])
    assert np.median(np.abs(u["depth"][both] / plain.depth[both] - 1)) < 2e-3
    assert np.abs(u["rgb"][away] - plain.rgb[away]).mean() < 0.05

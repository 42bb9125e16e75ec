"""Lens models against OpenCV's own (cv2.projectPoints, cv2.fisheye), and the rays through the
pixel centres against the projection (generator/geometry/lens.py)."""

import argparse

import cv2
import numpy as np
import pytest

from generator.cli_args import coefficients
from generator.geometry.lens import Lens, lens_of


def parse_lens(model, text):
    """What ``--camera-model MODEL --distortion TEXT`` gives (generator/cli_args.py parses the text)."""
    return lens_of(model, coefficients(text) if text else ())

K = np.array([[300.0, 0.0, 161.3], [0.0, 310.0, 118.7], [0.0, 0.0, 1.0]])
W, H = 320, 240
OPENCV = (-0.28, 0.09, 0.0012, -0.0008, -0.012)
FISHEYE = (0.05, -0.012, 0.004, -0.0009)


def _points(n=2000, seed=0, spread=0.9):
    rng = np.random.default_rng(seed)
    z = rng.uniform(0.5, 40.0, n)
    return np.stack([rng.uniform(-spread, spread, n) * z, rng.uniform(-spread, spread, n) * z, z], axis=1)


def test_the_opencv_model_projects_as_cv2_project_points():
    p = _points()
    ours, z = Lens("opencv", OPENCV).project(K, p)
    theirs, _ = cv2.projectPoints(p, np.zeros(3), np.zeros(3), K, np.array(OPENCV))
    assert np.allclose(z, p[:, 2])
    assert np.max(np.abs(ours - theirs[:, 0])) < 1e-6


def test_the_fisheye_model_projects_as_cv2_fisheye():
    p = _points(spread=2.5)  # up to 74 degrees off axis
    ours, _ = Lens("fisheye", FISHEYE).project(K, p)
    theirs, _ = cv2.fisheye.projectPoints(p[:, None], np.zeros(3), np.zeros(3), K, np.array(FISHEYE))
    assert np.max(np.abs(ours - theirs[:, 0])) < 1e-6


@pytest.mark.parametrize("lens", [Lens(), Lens("opencv", OPENCV), Lens("fisheye", FISHEYE)], ids=str)
def test_a_ray_through_a_pixel_centre_projects_back_onto_it(lens):
    rays = lens.rays(K, W, H)
    assert np.all(rays[..., 2] == 1.0)
    uv, _ = lens.project(K, rays.reshape(-1, 3) * 7.5)
    j, i = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    assert np.max(np.abs(uv - np.stack([j, i], -1).reshape(-1, 2))) < 1e-6


def test_the_rays_agree_with_cv2_undistort_points():
    """OpenCV's own inverse (iterative, to its default tolerance) finds the same directions."""
    lens = Lens("opencv", OPENCV)
    rays = lens.rays(K, W, H)
    j, i = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    pix = np.stack([j, i], -1).reshape(-1, 1, 2)
    theirs = cv2.undistortPointsIter(pix, K, np.array(OPENCV), None, None,
                                     (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14))
    assert np.max(np.abs(rays[..., :2].reshape(-1, 2) - theirs[:, 0])) < 1e-7
    fish = Lens("fisheye", FISHEYE).rays(K, W, H)
    theirs = cv2.fisheye.undistortPoints(pix, K, np.array(FISHEYE),
                                         criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14))
    assert np.max(np.abs(fish[..., :2].reshape(-1, 2) - theirs[:, 0])) < 1e-7


def test_points_behind_the_camera_have_no_image():
    uv, z = Lens("fisheye", FISHEYE).project(K, np.array([[1.0, 0.0, -2.0], [0.0, 0.0, 0.0]]))
    assert np.all(np.isnan(uv)) and list(z) == [-2.0, 0.0]


def test_a_lens_that_folds_inside_the_image_is_refused_in_one_line():
    Lens("opencv", OPENCV).check(K, W, H)
    with pytest.raises(ValueError, match="folds back inside the 320x240 image") as e:
        Lens("opencv", (-0.9, 0.0, 0.0, 0.0, 0.0)).check(K, W, H)  # r (1 - 0.9 r^2) peaks at r = 0.61
    assert "\n" not in str(e.value)
    with pytest.raises(ValueError, match="folds back"):
        Lens("fisheye", (0.0, 0.0, 0.0, 0.0)).check(np.array([[50.0, 0, 160], [0, 50.0, 120], [0, 0, 1]]), W, H)


@pytest.mark.parametrize("model,text,words", [
    ("opencv", "0.1,0.2", "a opencv lens takes 5 (k1, k2, p1, p2, k3) coefficients, got 2"),
    ("fisheye", "0.1,0.2,0.3,0.4,0.5", "takes 4 (k1, k2, k3, k4)"),
    ("pinhole", "0.1", "a pinhole lens takes no coefficients, got 1"),
    ("kannala", None, "lens model 'kannala' is unknown: use one of pinhole, opencv, fisheye"),
    ("opencv", "0.1,x,0,0", "expected comma-separated finite numbers"),
    ("opencv", "0.1,nan,0,0", "expected comma-separated finite numbers"),
])
def test_bad_lenses_are_refused_in_one_line(model, text, words):
    with pytest.raises((ValueError, argparse.ArgumentTypeError), match=words.replace("(", r"\(").replace(")", r"\)")):
        parse_lens(model, text)


def test_four_opencv_coefficients_mean_k3_zero_and_the_lens_is_written_by_name():
    lens = parse_lens("opencv", "-0.1,0.02,0.001,0")
    assert lens.coefficients == (-0.1, 0.02, 0.001, 0.0, 0.0)
    assert lens.as_dict() == {"model": "opencv", "k1": -0.1, "k2": 0.02, "p1": 0.001, "p2": 0.0, "k3": 0.0}
    assert parse_lens("opencv", None).ideal and not parse_lens("fisheye", None).ideal
    assert parse_lens("pinhole", None) == Lens()


def test_flow_through_a_lens_lands_where_opencv_projects_the_point():
    """PixelGeometry's flow with a lens: a surface point seen at a pixel centre, projected by
    cv2.projectPoints into the next camera, minus that pixel centre."""
    from generator.geometry.pixels import PixelGeometry

    lens = Lens("opencv", OPENCV)
    depth = np.full((H, W), 9.0, np.float32)
    poses = np.stack([np.eye(4), np.eye(4)])
    poses[1, :3, 3] = (0.4, -0.1, 0.3)
    g = PixelGeometry(K, W, H, 0, poses, depth, np.zeros((H, W), np.int64), None, np.zeros(1, np.int64) - 1,
                      np.zeros((2, 0, 4, 4)), lens)
    flow = g.flow_to(1)
    world = g.world_points.reshape(-1, 3)
    theirs, _ = cv2.projectPoints(world - poses[1, :3, 3], np.zeros(3), np.zeros(3), K, np.array(OPENCV))
    j, i = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    expected = theirs[:, 0] - np.stack([j, i], -1).reshape(-1, 2)
    assert np.max(np.abs(flow.reshape(-1, 2) - expected)) < 1e-3  # float32 flow


@pytest.mark.parametrize("lens", [Lens("opencv", (-0.3, 0.08, 0.002, -0.0015, 0.0)), Lens("fisheye", (0.02, -0.01, 0.003, -0.0005))])
def test_undistorting_a_sample_moves_tracks_and_flow_to_their_pinhole_positions(lens):
    """datasets.Undistort: a track at the lens's projection of a point goes to OpenCV's pinhole
    projection of it (cv2.projectPoints without distortion); a zero flow stays zero (each new
    pixel's source position maps back onto its own centre)."""
    from datasets import Undistort

    K = np.array([[60.0, 0, 40], [0, 60, 30], [0, 0, 1]])
    rng = np.random.default_rng(3)
    pts = np.column_stack([rng.uniform(-2, 2, 50), rng.uniform(-1.5, 1.5, 50), rng.uniform(4, 9, 50)])
    xy, _ = lens.project(K, pts)
    pinhole, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), K, None)
    sample = {"depth": np.ones((60, 80), np.float32), "flow": np.zeros((60, 80, 2), np.float32), "K": K,
              "tracks": {"xy": xy, "visible": np.ones(len(xy), bool)}}
    out = Undistort(lens)(sample)
    assert np.allclose(out["tracks"]["xy"], pinhole[:, 0], atol=1e-6)
    inside = (pinhole[:, 0, 0] >= 0) & (pinhole[:, 0, 0] < 80) & (pinhole[:, 0, 1] >= 0) & (pinhole[:, 0, 1] < 60)
    assert np.array_equal(out["tracks"]["visible"], inside)
    finite = np.isfinite(out["flow"]).all(-1)
    assert finite.mean() > 0.9 and np.abs(out["flow"][finite]).max() < 1e-5

"""``python -m generator --stereo B``: every trajectory also flown by a camera B metres to its
right, in ``<kind>_right/``; the pair is rectified, so a point tracked in both images sits on
the same row, fx B / Z pixels apart (checked from the tracks and the poses, with numpy)."""

import json

import h5py
import numpy as np
import pytest

from conftest import run_generator

BASELINE = 0.12


@pytest.fixture(scope="module")
def seed(tmp_path_factory):
    out = tmp_path_factory.mktemp("stereo")
    r = run_generator(out, "--seeds", "2", "--trajectory", "orbit", "--stereo", str(BASELINE),
                      "--outputs", "rgb,depth,label,instance")
    assert r.returncode == 0, r.stderr[-3000:]
    return out / "seed_000002"


def tracks(folder):
    from exporters.tracks import read_tracks_file, world_positions

    with h5py.File(folder / "tracks.h5") as f:
        data = read_tracks_file(f)
    return data, world_positions


@pytest.mark.pipeline
def test_the_right_camera_is_the_left_one_moved_along_its_own_x_axis(seed):
    from datasets import Scene

    scene = Scene(seed)
    assert scene.trajectories == ["orbit", "orbit_right"]
    left, right = scene["orbit"], scene["orbit_right"]
    assert len(left) == len(right) and np.array_equal(left.K, right.K)
    assert np.array_equal(left.timestamps, right.timestamps)
    assert np.allclose(right.poses[:, :3, :3], left.poses[:, :3, :3], atol=1e-12)
    assert np.allclose(right.poses[:, :3, 3], left.poses[:, :3, 3] + BASELINE * left.poses[:, :3, 0], atol=1e-9)
    assert json.loads((seed / "manifest.json").read_text())["config"]["stereo_baseline_m"] == BASELINE


@pytest.mark.pipeline
def test_a_point_seen_by_both_cameras_is_on_the_same_row_fx_b_over_z_apart(seed):
    left, world_positions = tracks(seed / "orbit")
    right, _ = tracks(seed / "orbit_right")
    fx = left["K"][0, 0]
    both = 0
    for t in range(len(left["world_from_camera"])):
        li = left["index"][left["offsets"][t]:left["offsets"][t + 1]]
        ri = right["index"][right["offsets"][t]:right["offsets"][t + 1]]
        common, a, b = np.intersect1d(li, ri, return_indices=True)
        if not len(common):
            continue
        xl = left["xy"][left["offsets"][t]:][a].astype(np.float64)
        xr = right["xy"][right["offsets"][t]:][b].astype(np.float64)
        pose = left["world_from_camera"][t]
        world = world_positions(left, t, common)
        z = (world - pose[:3, 3]) @ pose[:3, 2]  # planar depth in the left camera
        assert np.allclose(xl[:, 1], xr[:, 1], atol=2e-3)  # the same row
        assert np.allclose(xl[:, 0] - xr[:, 0], fx * BASELINE / z, atol=2e-3)  # disparity fx B / Z
        both += len(common)
    assert both > 100


def test_a_stereo_pair_needs_the_pinhole_in_one_line(tmp_path):
    r = run_generator(tmp_path, "--seeds", "2", "--stereo", "0.1", "--camera-model", "fisheye",
                      "--distortion=0.01,0,0,0")
    assert r.returncode == 2 and "--stereo makes a rectified pinhole pair" in r.stderr
    assert "Traceback" not in r.stderr and not list(tmp_path.iterdir())

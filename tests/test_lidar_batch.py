"""``python -m generator --lidar NAME`` (exporters/lidar_scans.py): a real tiny run writes each
trajectory's sweeps in the SemanticKITTI layout (and a terrestrial scanner's as LAS), listed
in the manifest; the returns agree with the rendered depth and labels of the frame taken at
the sweep's start; a bad sensor name is one line and exit 2."""

import json

import numpy as np
import pytest

from conftest import assert_refused, built_once, run_generator
from exporters.exr import read_frame_exr
from exporters.manifest import check_files, load_manifest
from exporters.semantickitti import read_lidar_json, read_scans
from exporters.tracks import read_tracks

pytestmark = pytest.mark.pipeline


@pytest.fixture(scope="module")
def lidar_seed(tmp_path_factory):
    out, _ = built_once(tmp_path_factory, "lidar", lambda out: run_generator(
        out, "--seeds", "2", "--trajectory", "orbit", "--resolution", "96x64", "--lidar", "vlp16", "--lidar", "tls",
        timeout=900))
    return out / "seed_000002"


def test_sweeps_are_written_in_the_semantickitti_layout_and_listed_in_the_manifest(lidar_seed):
    folder = lidar_seed / "orbit" / "lidar" / "vlp16"
    doc = read_lidar_json(folder)
    scans = read_scans(folder)
    assert doc["sensor"] == "vlp16" and doc["sensor_summary"]["range_noise_sigma_m"] > 0
    assert len(scans) == 2  # 3 frames at 10 fps: 0.2 s, two whole 0.1 s sweeps
    assert [s.start_time_s for s in scans] == [0.0, 0.1]
    assert all(len(s) > 1000 for s in scans)
    velodyne = np.fromfile(folder / "velodyne" / "000001.bin", dtype=np.float32).reshape(-1, 4)
    label = np.fromfile(folder / "labels" / "000001.label", dtype=np.uint32)
    assert np.array_equal(velodyne[:, :3], scans[1].xyz) and np.array_equal(label & 0xFFFF, scans[1].label)
    manifest = load_manifest(lidar_seed)
    rel = "orbit/lidar/vlp16/velodyne/000000.bin"
    assert rel in manifest["files"] and "orbit/lidar/tls/las/000000.las" in manifest["files"]
    assert manifest["config"]["lidar"] == ["vlp16", "tls"]
    assert not check_files(lidar_seed, manifest)
    assert all(row["motion_bound_m"] is not None for row in doc["scans"])


def test_returns_agree_with_the_frame_rendered_at_the_scan_s_start(lidar_seed):
    """The terrestrial scanner's first station stands at frame 0's camera centre, and its
    de-skewed scan is the scene at t = 0, frame 0's instant: projected into frame 0, returns
    meet the rendered depth where it is smooth (a pixel of 96x64 spans about a degree) and
    carry the rendered label. (A spinning sensor on this 3-frame orbit moves tens of metres
    in a sweep: it sees from elsewhere than the frame.) Where the renderer shows glass the
    beam went on to what lies behind: a few per cent of the returns."""
    from scipy.ndimage import maximum_filter, minimum_filter

    folder = lidar_seed / "orbit"
    tracks = read_tracks(folder / "tracks.h5")
    K, pose = tracks["K"], tracks["world_from_camera"][0]
    frame = read_frame_exr(folder / "frame_000000.exr")
    scan = read_scans(folder / "lidar" / "tls")[0]
    assert np.allclose(scan.world_from_sensor[:3, 3], pose[:3, 3])
    camera = (scan.world_points() - pose[:3, 3]) @ pose[:3, :3]
    ahead = np.flatnonzero(camera[:, 2] > 0.5)
    uv = camera[ahead, :2] / camera[ahead, 2:] @ K[:2, :2].T + K[:2, 2]
    depth = frame["depth"]
    h, w = depth.shape
    inside = (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
    cols, rows, seen = uv[inside, 0].astype(int), uv[inside, 1].astype(int), ahead[inside]
    finite = np.where(np.isfinite(depth), depth, 1e6)
    smooth = ((maximum_filter(finite, 3) - minimum_filter(finite, 3)) < 0.05 * finite)[rows, cols]
    gap = depth[rows, cols] - camera[seen, 2]
    assert smooth.sum() > 5000
    assert np.mean(np.abs(gap[smooth]) < 0.25 * np.maximum(1.0, camera[seen, 2][smooth] / 20)) > 0.75
    close = smooth & (np.abs(gap) < 0.5)
    assert np.mean(frame["label"][rows, cols][close] == scan.label[seen][close]) > 0.95


def test_a_terrestrial_scan_is_also_las_with_world_coordinates(lidar_seed):
    import laspy

    folder = lidar_seed / "orbit" / "lidar" / "tls"
    scans = read_scans(folder)
    assert 1 <= len(scans) <= 4 and json.loads((folder / "lidar.json").read_text())["sensor"] == "tls"
    las = laspy.read(folder / "las" / "000000.las")
    world = np.column_stack([las.x, las.y, las.z])
    assert len(world) == len(scans[0]) > 10_000
    assert np.abs(world - scans[0].world_points()).max() < 1e-4
    assert np.array_equal(np.asarray(las.label), scans[0].label) and np.array_equal(np.asarray(las.instance), scans[0].instance)


def test_an_unknown_lidar_is_one_line_and_exit_2(tmp_path):
    r = run_generator(tmp_path / "out", "--seeds", "1", "--lidar", "velodyne-9000", timeout=120)
    assert_refused(r, "velodyne-9000", "vlp16")

"""A rolling shutter (``Simulator.set_shutter(readout_s=R)``, ``--rolling-shutter R``): row r
of the image shows the scene at the frame's time + ((r + 1) / H - 1/2) R, the colour by
Cycles and the ground truth by casting each row from the camera's pose at that time with the
machines where they stood then; points land in the image at the row that sees them.
Checked against Cycles' own object-index pass of the same rolling-shutter render, against
global-shutter casts from the rows' poses, and with OpenCV's projection."""

import json

import cv2
import numpy as np
import pytest

from conftest import assert_refused, run_generator
from generator import Simulator
from generator.geometry.camera import look_at
from generator.geometry.motion import MotionTrack
from generator.geometry.rolling import RollingCamera, RollingShutter
from test_modalities import animated_scene
from test_motion_blur import T, flight


@pytest.fixture(scope="module")
def renders(tmp_path_factory):
    blend = animated_scene(tmp_path_factory.mktemp("rolling") / "scene.blend")
    out = {}
    for truth in ("renderer", "geometry"):  # Cycles' own passes, and ours
        sim = Simulator(blend, points_density=2, render_preset="preview", ground_truth=truth)
        sim.configure_render(samples=4, denoise=False)
        poses, matrices = flight(sim)
        names = ["rgb", "depth", "label", "instance"] + (["flow"] if truth == "geometry" else [])
        out[truth, "global"] = sim.render_outputs(names, poses, matrices, 1)
        sim.set_shutter(0.0, 1.0 / sim.fps)  # the rows read over a whole frame interval
        out[truth, "rolling"] = sim.render_outputs(names, poses, matrices, 1)
        out[truth, "sim"] = sim
    return out, poses, matrices


def test_each_row_is_what_cycles_renders_at_the_rows_time(renders):
    out, _, _ = renders
    cycles, ours = out["renderer", "rolling"].instance, out["geometry", "rolling"].instance
    still = out["geometry", "global"].instance
    assert np.array_equal(out["renderer", "global"].instance, still)  # the same scene, the same ids
    assert (cycles == ours).mean() > 0.999  # Cycles' own rolling-shutter pass: the rows agree (edges aside)
    assert (cycles == still).mean() < 0.99  # and a global shutter does not
    both = np.isfinite(out["renderer", "rolling"].depth) & (cycles == ours)
    assert np.median(np.abs(out["renderer", "rolling"].depth[both] - out["geometry", "rolling"].depth[both])
                     / out["geometry", "rolling"].depth[both]) < 1e-3


def test_row_r_is_the_global_cast_from_the_pose_at_the_rows_time(renders):
    out, poses, matrices = renders
    sim = out["geometry", "sim"]
    rolling = out["geometry", "rolling"]
    times = np.arange(T) / sim.fps
    track = MotionTrack(times, poses)
    h = sim.height
    static = ~np.isin(rolling.instance, [sim.object_names.index("Truck")])
    for r in (h // 2, 3 * h // 4, h - 1):  # rows that see the wall and the ground
        pose = track.at(times[1] + ((r + 1) / h - 0.5) / sim.fps)[0]
        sim.set_shutter(0.0, 0.0)
        sim.set_world_from_camera(pose, check_collisions=False)
        cast = sim.render_geometry()
        keep = static[r] & np.isfinite(cast.depth[r])
        assert keep.sum() > 20
        assert np.array_equal(cast.instance[r][keep], rolling.instance[r][keep])
        assert np.allclose(cast.depth[r][keep], rolling.depth[r][keep], rtol=1e-5)
    sim.set_world_from_camera(poses[1], check_collisions=False)


def test_a_point_lands_where_opencv_projects_it_from_its_rows_pose():
    poses = np.stack([look_at((-5.0 + 3.0 * t, -12.0, 3.0), (-5.0 + 3.0 * t, 0.0, 1.0)) for t in range(T)])
    shutter = RollingShutter(0.05, 96)
    camera = RollingCamera(shutter, np.arange(T) / 10.0, poses, np.zeros((T, 0, 4, 4)))
    K = np.array([[100.0, 0, 64], [0, 100.0, 48], [0, 0, 1]])
    points = np.random.default_rng(1).uniform([-6, -2, 0], [4, 6, 3], (300, 3))
    uv, z = camera.project(1, points, -np.ones(300, int), K, None)
    inside = np.isfinite(uv).all(1) & (uv[:, 1] >= 0) & (uv[:, 1] <= 96)
    assert inside.sum() > 100
    for p, (u, v) in zip(points[inside], uv[inside]):
        pose = camera.camera.at(0.1 + ((v + 0.5) / 96 - 0.5) * 0.05)[0]  # the time of the row it lands on
        rvec, _ = cv2.Rodrigues(pose[:3, :3].T)
        theirs, _ = cv2.projectPoints(p[None], rvec, -pose[:3, :3].T @ pose[:3, 3], K, None)
        assert np.allclose(theirs[0, 0], (u, v), atol=1e-6)
    global_uv = np.stack([(K @ ((p - poses[1][:3, 3]) @ poses[1][:3, :3]))[:2] / ((p - poses[1][:3, 3]) @ poses[1][:3, 2])
                          for p in points[inside]])
    assert np.abs(global_uv[:, 0] - uv[inside, 0]).max() > 1.0  # the readout moves them


def test_the_flow_of_a_still_surface_ends_where_its_point_lands_in_the_next_frame(renders):
    out, poses, matrices = renders
    sim = out["geometry", "sim"]
    rolling = out["geometry", "rolling"]
    camera = RollingCamera(RollingShutter(1.0 / sim.fps, sim.height), np.arange(T) / sim.fps, poses, matrices)
    ground = np.flatnonzero((rolling.instance == sim.object_names.index("Ground")).reshape(-1))[::37]
    flow = rolling.extra["flow"].reshape(-1, 2)[ground]
    i, j = np.divmod(ground, sim.width)
    row_poses = camera.row_poses(1)
    rays = np.stack([(j + 0.5 - sim.K[0, 2]) / sim.K[0, 0], (i + 0.5 - sim.K[1, 2]) / sim.K[1, 1], np.ones(len(i))], 1)
    cam = rays * rolling.depth.reshape(-1)[ground][:, None]
    world = np.einsum("nij,nj->ni", row_poses[i, :3, :3], cam) + row_poses[i, :3, 3]
    assert np.allclose(world[:, 2], 0.0, atol=1e-4)  # the ground plane, seen from each row's pose
    uv, _ = camera.project(2, world, -np.ones(len(world), int), sim.K, None)
    ok = np.isfinite(flow).all(1)
    assert ok.sum() > 20
    assert np.allclose(np.stack([j + 0.5, i + 0.5], 1)[ok] + flow[ok], uv[ok], atol=1e-3)


def test_a_lone_render_with_a_rolling_shutter_is_refused(renders):
    out, poses, matrices = renders
    sim = out["geometry", "sim"]
    sim.set_shutter(0.0, 0.02)
    with pytest.raises(ValueError, match="along a trajectory"):
        sim.render()
    with pytest.raises(ValueError, match="at least two frames"):
        sim.render_outputs(["rgb"])
    with pytest.raises(ValueError, match="readout"):
        sim.set_shutter(0.0, 1.0)
    sim.set_shutter(0.0, 0.0)


def test_the_batch_job_records_the_readout_and_places_tracks_at_their_rows(tmp_path):
    from datasets import Scene
    from exporters.tracks import TrackReader

    r = run_generator(tmp_path, "--seeds", "2", "--trajectory", "spline", "--frames", "4",
                      "--rolling-shutter", "0.03", "--outputs", "rgb,depth,instance,flow")
    assert r.returncode == 0, r.stderr[-3000:]
    seed = tmp_path / "seed_000002"
    doc = json.loads((seed / "spline" / "frames.json").read_text())
    assert doc["rolling_shutter"]["readout_s"] == 0.03
    assert json.loads((seed / "manifest.json").read_text())["config"]["readout_s"] == 0.03
    sequence = Scene(seed)["spline"]
    assert sequence.readout_s == 0.03
    reader = TrackReader(seed / "spline" / "tracks.h5")
    local, dynamic = reader.read("points/local"), reader.read("points/dynamic_object")
    track = MotionTrack(sequence.timestamps, sequence.poses)
    checked = 0
    for t in range(len(sequence)):
        index = reader.read("visibility/index", np.s_[reader.offsets[t]:reader.offsets[t + 1]])
        xy = reader.read("visibility/xy", np.s_[reader.offsets[t]:reader.offsets[t + 1]]).astype(np.float64)
        # static points in the image (a point seen at the frame's time may land past the border,
        # where it takes the edge row's time)
        static = (dynamic[index] < 0) & (xy[:, 1] >= 0) & (xy[:, 1] <= sequence.height)
        for p, (u, v) in zip(local[index[static]], xy[static]):
            pose = track.at(sequence.timestamps[t] + ((v + 0.5) / sequence.height - 0.5) * 0.03)[0]
            rvec, _ = cv2.Rodrigues(pose[:3, :3].T)
            theirs, _ = cv2.projectPoints(p[None], rvec, -pose[:3, :3].T @ pose[:3, 3], sequence.K, None)
            assert np.allclose(theirs[0, 0], (u, v), atol=2e-3)  # stored float32
            checked += 1
        # the loaders place every visible point as tracks.h5 does
        placed, _ = sequence.project_points(t, index)
        assert np.allclose(placed, xy, atol=1e-3, equal_nan=True)
    assert checked > 100


def test_a_rolling_shutter_with_a_rig_or_too_long_a_readout_is_refused(tmp_path):
    assert_refused(run_generator(tmp_path / "a", "--seeds", "2", "--rolling-shutter", "0.5"), "--rolling-shutter")
    assert_refused(run_generator(tmp_path / "b", "--seeds", "2", "--rolling-shutter", "0.02", "--stereo", "0.1"),
                   "leave out --stereo")

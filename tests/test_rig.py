"""Camera rigs (``python -m generator --rig FILE``, ``--stereo B``): every trajectory also flown
by cameras fixed to its own, in ``<kind>_<name>/``; a camera moved along the reference's x axis
is its rectified partner (a point tracked in both images sits on the same row, fx B / Z pixels
apart); the rig's joint COLMAP model (pycolmap: rig, frames, every camera's images) and
multi-camera transforms.json in ``rigs/<kind>/``. Checked from the tracks, the poses and the
files, with numpy, pycolmap and OpenCV."""

import json

import cv2
import h5py
import numpy as np
import pytest

from conftest import assert_refused, run_generator
from generator.batch.config import RunConfig
from generator.batch.rig import Rig, RigError, read_rig, stereo_rig

BASELINE = 0.12


def rig_document() -> dict:
    """Two cameras: ``right``, the reference's stereo partner, and ``down``, turned 30 degrees
    about the reference's x axis and moved off it."""
    c, s = np.cos(np.radians(30)), np.sin(np.radians(30))
    down = np.eye(4)
    down[:3, :3] = [[1, 0, 0], [0, c, -s], [0, s, c]]
    down[:3, 3] = (-0.05, 0.1, 0.02)
    right = np.eye(4)
    right[0, 3] = BASELINE
    return {"cameras": [{"name": "right", "rig_from_camera": right.tolist()},
                        {"name": "down", "rig_from_camera": down.tolist()}]}


@pytest.fixture(scope="module")
def seed(tmp_path_factory):
    out = tmp_path_factory.mktemp("rig")
    (out / "rig.json").write_text(json.dumps(rig_document()))
    r = run_generator(out / "data", "--seeds", "2", "--trajectory", "orbit", "--rig", str(out / "rig.json"),
                      "--outputs", "rgb,depth,label,instance")
    assert r.returncode == 0, r.stderr[-3000:]
    return out / "data" / "seed_000002"


def tracks(folder):
    from exporters.tracks import read_tracks_file, world_positions

    with h5py.File(folder / "tracks.h5") as f:
        data = read_tracks_file(f)
    return data, world_positions


@pytest.mark.pipeline
def test_each_rig_camera_is_the_reference_moved_by_its_extrinsics(seed):
    from datasets import Scene

    scene = Scene(seed)
    assert scene.trajectories == ["orbit", "orbit_right", "orbit_down"]
    reference = scene["orbit"]
    for camera in rig_document()["cameras"]:
        other, m = scene["orbit_" + camera["name"]], np.array(camera["rig_from_camera"])
        assert len(other) == len(reference) and np.array_equal(other.K, reference.K)
        assert np.array_equal(other.timestamps, reference.timestamps)
        assert np.allclose(other.poses, reference.poses @ m, atol=1e-12)
    assert np.allclose(scene["orbit_right"].poses[:, :3, 3],
                       reference.poses[:, :3, 3] + BASELINE * reference.poses[:, :3, 0], atol=1e-9)
    assert json.loads((seed / "manifest.json").read_text())["config"]["rig"] == rig_document()


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


@pytest.mark.pipeline
def test_the_disparity_map_is_fx_b_over_the_left_depth_and_only_for_the_rectified_camera(seed):
    from datasets import DatasetError, Scene

    scene = Scene(seed)
    left = scene["orbit"]
    for t in range(len(left)):
        depth = left.read(t, ["depth"])["depth"].astype(np.float64)
        disparity = scene.disparity("orbit_right", t)
        seen = np.isfinite(depth)
        assert disparity.dtype == np.float32 and seen.any() and np.all(disparity[~seen] == 0)
        assert np.allclose(disparity[seen], left.K[0, 0] * BASELINE / depth[seen], rtol=1e-6)
    with pytest.raises(DatasetError, match="orbit_right"):
        scene.disparity("orbit_down", 0)


@pytest.mark.pipeline
def test_the_rig_colmap_model_holds_the_rig_its_frames_and_every_cameras_images(seed):
    import pycolmap

    from datasets import Scene

    rec = pycolmap.Reconstruction(str(seed / "rigs" / "orbit" / "sparse" / "0"))
    scene = Scene(seed)
    folders = ["orbit", "orbit_right", "orbit_down"]
    assert (rec.num_rigs(), rec.num_cameras(), rec.num_frames(), rec.num_images()) == (1, 3, 3, 9)
    rig = rec.rigs[1]
    assert rig.ref_sensor_id.id == 1
    for k, camera in enumerate(rig_document()["cameras"]):
        sensor = rec.cameras[k + 2].sensor_id
        sensor_from_rig = np.vstack([rig.sensor_from_rig(sensor).matrix(), [0, 0, 0, 1]])
        assert np.allclose(sensor_from_rig, np.linalg.inv(np.array(camera["rig_from_camera"])), atol=1e-12)
    cross = 0
    for point in rec.points3D.values():
        cameras = {rec.images[e.image_id].camera_id for e in point.track.elements}
        cross += len(cameras) > 1
        for e in point.track.elements:  # every keypoint is OpenCV's projection of its 3D point
            image = rec.images[e.image_id]
            pose = scene[folders[image.camera_id - 1]].poses[image.frame_id - 1]
            K = scene["orbit"].K
            rvec, _ = cv2.Rodrigues(np.linalg.inv(pose)[:3, :3])
            uv, _ = cv2.projectPoints(point.xyz[None], rvec, np.linalg.inv(pose)[:3, 3], K, None)
            assert np.allclose(image.points2D[e.point2D_idx].xy, uv[0, 0], atol=1e-6)
    assert cross > 50  # points tracked across cameras of the rig
    for t in range(3):
        for c, folder in enumerate(folders):
            image = rec.find_image_with_name(f"{folder}/rgb_{t:06d}.png")
            assert image.frame_id == t + 1 and image.camera_id == c + 1 and (seed / image.name).is_file()
            world_from_camera = np.linalg.inv(np.vstack([image.cam_from_world().matrix(), [0, 0, 0, 1]]))
            assert np.allclose(world_from_camera, scene[folder].poses[t], atol=1e-9)
            own = pycolmap.Reconstruction(str(seed / folder / "sparse" / "0")).find_image_with_name(f"rgb_{t:06d}.png")
            assert np.array_equal([p.xy for p in image.points2D], [p.xy for p in own.points2D])
    assert rec.compute_mean_reprojection_error() < 1e-9


@pytest.mark.pipeline
def test_the_rig_transforms_json_lists_every_cameras_frames_with_its_intrinsics(seed):
    from datasets import Scene

    doc = json.loads((seed / "rigs" / "orbit" / "transforms.json").read_text())
    scene = Scene(seed)
    assert len(doc["frames"]) == 9 and (seed / "rigs" / "orbit" / doc["ply_file_path"]).is_file()
    for frame in doc["frames"]:
        sequence = scene[frame["camera"]]
        t = int(frame["file_path"][-10:-4])
        assert (seed / "rigs" / "orbit" / frame["file_path"]).resolve() == (seed / frame["camera"] / f"rgb_{t:06d}.png").resolve()
        assert (frame["fl_x"], frame["cx"], frame["w"]) == (sequence.K[0, 0], sequence.K[0, 2], sequence.width)
        opengl = np.array(frame["transform_matrix"]) @ np.diag([1.0, -1, -1, 1])
        assert np.allclose(opengl, sequence.poses[t], atol=1e-12)
        assert (seed / "rigs" / "orbit" / frame["depth_file_path"]).is_file()


def test_stereo_is_the_rig_of_one_camera_moved_along_x():
    rig = RunConfig(stereo_baseline_m=0.3).camera_rig()
    m = np.eye(4)
    m[0, 3] = 0.3
    assert rig.names == ("right",) and np.array_equal(rig.rig_from_camera[0], m) and rig.baseline(0) == 0.3
    same = Rig.from_dict({"cameras": [{"name": "right", "rig_from_camera": m.tolist()}]})
    assert same.names == rig.names and np.array_equal(same.rig_from_camera, rig.rig_from_camera)
    assert Rig.from_dict(rig_document()).baseline(1) is None and stereo_rig(0.3).baseline(0) == 0.3


@pytest.mark.parametrize("doc, words", [
    ({"cameras": []}, "at least one camera"),
    ({"cameras": [{"name": "Right", "rig_from_camera": np.eye(4).tolist()}]}, "lower-case"),
    ({"cameras": [{"name": "a", "rig_from_camera": np.eye(4).tolist()}] * 2}, "two cameras are named"),
    ({"cameras": [{"name": "a", "rig_from_camera": (2 * np.eye(4)).tolist()}]}, "last row"),
    ({"cameras": [{"name": "a", "rig_from_camera": np.diag([2.0, 1, 1, 1]).tolist()}]}, "orthonormal"),
    ({"cameras": [{"name": "a", "rig_from_camera": np.diag([-1.0, 1, 1, 1]).tolist()}]}, "reflection"),
    ({"cameras": [{"name": "a", "rig_from_camera": [[1, 0, 0, 20], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}]},
     "at most 10 m"),
    ({"cameras": [{"name": "a", "rig_from_camera": [[1, 0], [0, 1]]}]}, "4x4"),
])
def test_a_bad_rig_is_refused_naming_the_problem(doc, words):
    with pytest.raises(RigError, match=words):
        Rig.from_dict(doc)


def test_bad_rig_files_and_combinations_are_refused_in_one_line(tmp_path):
    (tmp_path / "broken.json").write_text("{not json")
    with pytest.raises(RigError, match="not JSON"):
        read_rig(tmp_path / "broken.json")
    (tmp_path / "rig.json").write_text(json.dumps(rig_document()))
    for args, words in ((["--rig", str(tmp_path / "missing.json")], ["cannot read the rig file"]),
                        (["--rig", str(tmp_path / "rig.json"), "--stereo", "0.1"], ["--rig", "leave out --stereo"]),
                        (["--rig", str(tmp_path / "rig.json"), "--phases", "2"], ["leave out --phases"])):
        r = run_generator(tmp_path / "out", "--seeds", "2", *args)
        assert_refused(r, *words)
        assert not (tmp_path / "out").exists()


def test_a_stereo_pair_needs_the_pinhole_in_one_line(tmp_path):
    r = run_generator(tmp_path, "--seeds", "2", "--stereo", "0.1", "--camera-model", "fisheye",
                      "--distortion=0.01,0,0,0")
    assert r.returncode == 2 and "--stereo makes a rectified pinhole pair" in r.stderr
    assert "Traceback" not in r.stderr and not list(tmp_path.iterdir())

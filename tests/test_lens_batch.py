"""``python -m generator --camera-model opencv --distortion ... --exposure auto --sensor-noise
...``: every file that holds a camera carries the lens, and every projection in them goes
through it (checked with OpenCV and pycolmap, not with our own projection); the image sensor
(with its gain per frame) and the shutter (``--shutter``: motion blur) are recorded."""

import json

import cv2
import numpy as np
import pytest

from conftest import run_generator

DISTORTION = (-0.22, 0.05, 0.0015, -0.001)


@pytest.fixture(scope="module")
def seed(tmp_path_factory):
    out = tmp_path_factory.mktemp("lens")
    r = run_generator(out, "--seeds", "2", "--trajectory", "orbit", "--camera-model", "opencv",
                      "--distortion=" + ",".join(map(str, DISTORTION)), "--exposure", "auto",
                      "--sensor-noise", "6000,3", "--shutter", "0.05")
    assert r.returncode == 0, r.stderr[-3000:]
    return out / "seed_000002"


@pytest.mark.pipeline
def test_track_pixels_are_opencvs_projection_through_the_lens(seed):
    from exporters.tracks import TrackReader, read_tracks_file, world_positions
    import h5py

    reader = TrackReader(seed / "orbit" / "tracks.h5")
    assert reader.lens.model == "opencv" and reader.lens.coefficients[:4] == DISTORTION
    with h5py.File(seed / "orbit" / "tracks.h5") as f:
        data = read_tracks_file(f)
    K = data["K"]
    for t in range(len(data["world_from_camera"])):
        idx = data["index"][data["offsets"][t]:data["offsets"][t + 1]]
        xy = data["xy"][data["offsets"][t]:data["offsets"][t + 1]]
        pose = data["world_from_camera"][t]
        world = world_positions(data, t, idx)
        rvec, _ = cv2.Rodrigues(pose[:3, :3].T)
        theirs, _ = cv2.projectPoints(world, rvec, -pose[:3, :3].T @ pose[:3, 3], K, np.array(DISTORTION))
        assert len(idx) > 50
        assert np.max(np.abs(xy - theirs[:, 0])) < 1e-3  # stored float32
        assert np.all((xy >= 0) & (xy < [reader.width, reader.height]))  # in view through the lens


@pytest.mark.pipeline
def test_colmap_holds_the_opencv_camera_and_reprojects_its_points(seed):
    import pycolmap

    rec = pycolmap.Reconstruction(str(seed / "orbit" / "sparse" / "0"))
    cam = rec.cameras[1]
    assert cam.model.name == "OPENCV" and np.allclose(list(cam.params)[4:], DISTORTION)
    errors = []
    for image in rec.images.values():
        for p2 in image.points2D:
            if p2.has_point3D():
                xyz = rec.points3D[p2.point3D_id].xyz
                uv = cam.img_from_cam(image.cam_from_world() * xyz)
                errors.append(np.linalg.norm(uv - p2.xy))
    assert len(errors) > 100 and max(errors) < 1e-6
    from exporters.colmap import read_colmap_model

    assert read_colmap_model(seed / "orbit" / "sparse" / "0").lens.coefficients[:4] == DISTORTION  # our reader too


@pytest.mark.pipeline
def test_frames_transforms_and_ground_truth_carry_the_lens(seed):
    from exporters.frames import FrameReader
    from exporters.ground_truth import read_ground_truth

    frames = FrameReader(seed / "orbit")
    assert frames.lens.model == "opencv" and frames.lens.coefficients[:4] == DISTORTION
    doc = json.loads((seed / "orbit" / "transforms.json").read_text())
    assert doc["camera_model"] == "OPENCV" and [doc[k] for k in ("k1", "k2", "p1", "p2")] == list(DISTORTION)
    assert read_ground_truth(seed / "ground_truth").lens == frames.lens
    manifest = json.loads((seed / "manifest.json").read_text())
    assert manifest["config"]["camera_model"] == "opencv" and manifest["config"]["distortion"][:4] == list(DISTORTION)


@pytest.mark.pipeline
def test_the_image_sensor_and_the_shutter_are_recorded(seed):
    from exporters.frames import FrameReader
    from generator.image_sensor import ImageSensor

    frames = FrameReader(seed / "orbit")
    assert frames.image_sensor == ImageSensor(None, 6000.0, 3.0, None)
    assert frames.exposure_gain.shape == (frames.frames,) and np.all((frames.exposure_gain >= 1 / 8)
                                                                     & (frames.exposure_gain <= 8))
    assert len(set(frames.exposure_gain.tolist())) > 1  # metered per frame
    config = json.loads((seed / "manifest.json").read_text())["config"]
    assert config["exposure"] == "auto" and config["sensor_noise"] == [6000.0, 3.0] and "jpeg_quality" not in config
    assert config["shutter_s"] == 0.05 and frames.shutter_s == 0.05
    from datasets import Scene

    seq = Scene(seed)["orbit"]
    assert seq.image_sensor == frames.image_sensor and np.array_equal(seq.exposure_gain, frames.exposure_gain)
    rgb = frames.read(0, ["rgb"])["rgb"]
    assert rgb.shape == (frames.height, frames.width, 3) and 0 < rgb.mean() < 1


@pytest.mark.pipeline
def test_coco_masks_follow_the_lens_and_no_amodal_box_is_claimed(seed):
    """The masks are the instance map's (cast through the lens); the amodal box, exact only
    for straight edges, is left out and read back as NaN."""
    from exporters.coco import CocoReader
    from exporters.frames import FrameReader

    coco = CocoReader(seed / "orbit" / "coco.json")
    frame = coco.frame(0)
    assert len(frame["instance_id"]) > 0 and np.isnan(frame["amodal_bbox"]).all()
    instance = FrameReader(seed / "orbit").read(0, ["instance"])["instance"]
    for k, iid in enumerate(frame["instance_id"]):
        assert frame["area"][k] == np.count_nonzero(instance == iid)

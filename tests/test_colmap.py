"""COLMAP export read back with pycolmap: exact projections, poses, tracks."""

import numpy as np
import pycolmap

from exporters.colmap import write_colmap_model
from generator.geometry.camera import look_at, project


def test_colmap_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    K = np.array([[300.0, 0, 160], [0, 300.0, 120], [0, 0, 1]])
    pts = rng.uniform(-5, 5, (500, 3))
    poses = np.stack([look_at((12 * np.cos(a), 12 * np.sin(a), 4.0), (0, 0, 0)) for a in np.linspace(0, 1.5, 6)])
    obs = []
    for pose in poses:
        uv, z = project(pts, pose, K)
        keep = np.flatnonzero((z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < 320) & (uv[:, 1] >= 0) & (uv[:, 1] < 240))
        keep = keep[rng.random(len(keep)) < 0.7]
        obs.append((keep, uv[keep]))
    colors = rng.integers(0, 256, (500, 3)).astype(np.uint8)
    names = [f"rgb_{t:06d}.png" for t in range(len(poses))]
    write_colmap_model(tmp_path / "sparse" / "0", K, 320, 240, poses, names, obs, pts, colors, text=True)
    rec = pycolmap.Reconstruction(str(tmp_path / "sparse" / "0"))
    assert rec.num_reg_images() == 6 and rec.num_cameras() == 1
    cam = rec.cameras[1]
    assert cam.model.name == "PINHOLE" and np.allclose(cam.params, [300, 300, 160, 120])
    seen = np.bincount(np.concatenate([o[0] for o in obs]), minlength=500)
    assert rec.num_points3D() == int((seen >= 2).sum())
    for image in rec.images.values():
        t = names.index(image.name)
        cam_from_world = np.eye(4)
        cam_from_world[:3, :4] = image.cam_from_world().matrix()
        np.testing.assert_allclose(np.linalg.inv(cam_from_world), poses[t], atol=1e-9)
        for p2d in image.points2D:
            if p2d.has_point3D():
                xyz = rec.points3D[p2d.point3D_id].xyz
                uv, _ = project(xyz[None], poses[t], K)
                assert np.linalg.norm(uv[0] - p2d.xy) < 0.01
    for point in rec.points3D.values():
        assert point.track.length() >= 2
    assert rec.compute_mean_reprojection_error() < 1e-6


def test_points3d_carry_their_real_reprojection_error(tmp_path):
    """COLMAP's per-point error is the mean pixel distance between the point's projection and
    its keypoints: recomputed here from the written keypoints and our own poses and K (with
    keypoints moved off their exact projections, so the errors are far from zero)."""
    rng = np.random.default_rng(3)
    K = np.array([[200.0, 0, 80], [0, 200.0, 60], [0, 0, 1]])
    pts = rng.uniform(-3, 3, (200, 3))
    poses = np.stack([look_at((10 * np.cos(a), 10 * np.sin(a), 3.0), (0, 0, 0)) for a in np.linspace(0, 1, 4)])
    obs = []
    for pose in poses:
        uv, z = project(pts, pose, K)
        keep = np.flatnonzero((z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < 160) & (uv[:, 1] >= 0) & (uv[:, 1] < 120))
        obs.append((keep, uv[keep] + rng.normal(0, 0.7, (len(keep), 2))))
    names = [f"rgb_{t:06d}.png" for t in range(len(poses))]
    folder = tmp_path / "sparse" / "0"
    write_colmap_model(folder, K, 160, 120, poses, names, obs, pts, np.zeros((200, 3), np.uint8), text=True)
    rec = pycolmap.Reconstruction(str(folder))
    residuals: dict[int, list] = {}
    for image in rec.images.values():
        pose = poses[names.index(image.name)]
        for p2d in image.points2D:
            if p2d.has_point3D():
                uv, _ = project(pts[None, _point_index(rec, p2d.point3D_id, pts)], pose, K)
                residuals.setdefault(p2d.point3D_id, []).append(np.linalg.norm(uv[0] - p2d.xy))
    assert len(residuals) == rec.num_points3D() > 100
    errors = np.array([rec.points3D[i].error for i in residuals])
    expected = np.array([np.mean(r) for r in residuals.values()])
    assert np.all(errors > 0.05), "points must not carry COLMAP's 'unknown' error (-1) or zero"
    np.testing.assert_allclose(errors, expected, rtol=1e-9, atol=1e-9)
    # the text model states the same errors (column ERROR of points3D.txt)
    text_errors = {int(line.split()[0]): float(line.split()[7]) for line in (folder / "points3D.txt").read_text().splitlines()
                   if line and not line.startswith("#")}
    np.testing.assert_allclose([text_errors[i] for i in residuals], expected, rtol=1e-6)
    assert abs(rec.compute_mean_reprojection_error() - expected.mean()) < 1e-9


def _point_index(rec, point3d_id: int, pts: np.ndarray) -> int:
    """Which of our points a COLMAP 3D point is (its coordinates are ours, exactly)."""
    return int(np.flatnonzero(np.all(pts == rec.points3D[point3d_id].xyz, axis=1))[0])


def test_reader_knows_every_camera_model_of_colmap(tmp_path):
    """A binary model may hold cameras of any of COLMAP's models: an unused one is ignored,
    and the images' own camera must be a pinhole or one of the lens models (others are refused as
    a model, not as a damaged file)."""
    import pytest

    from exporters.colmap import ColmapError, read_colmap_model

    K = np.array([[300.0, 0, 160], [0, 300.0, 120], [0, 0, 1]])
    poses = np.stack([look_at((12 * np.cos(a), 12 * np.sin(a), 4.0), (0, 0, 0)) for a in (0.0, 0.5)])
    empty = [(np.zeros(0, int), np.zeros((0, 2)))] * 2
    base = tmp_path / "base"
    write_colmap_model(base, K, 320, 240, poses, ["a.png", "b.png"], empty, np.zeros((0, 3)), np.zeros((0, 3), np.uint8),
                       text=True)
    for model_id in range(18):  # every model pycolmap knows
        model = pycolmap.CameraModelId(model_id)
        camera = pycolmap.Camera.create_from_model_id(2, model, 200.0, 320, 240)
        extra = tmp_path / f"extra{model_id}"  # the pinhole camera and an unused one of this model
        extra.mkdir()
        rec = pycolmap.Reconstruction(str(base))
        rec.add_camera(camera)
        rec.write_binary(str(extra))
        np.testing.assert_allclose(read_colmap_model(extra).K, K)
        if model.name in ("PINHOLE", "SIMPLE_PINHOLE"):
            continue
        lenses = {"OPENCV": "opencv", "FULL_OPENCV": "opencv", "OPENCV_FISHEYE": "fisheye"}
        used = tmp_path / f"used{model_id}"  # the images' camera is of this model
        used.mkdir()
        lines = (base / "cameras.txt").read_text().splitlines()
        lines[-1] = " ".join(["1", model.name, "320", "240", *map(str, camera.params)])
        (used / "cameras.txt").write_text("\n".join(lines) + "\n")
        for name in ("images.txt", "points3D.txt"):
            (used / name).write_bytes((base / name).read_bytes())
        rec = pycolmap.Reconstruction(str(used))
        for name in ("cameras.txt", "images.txt", "points3D.txt"):
            (used / name).unlink()
        rec.write_binary(str(used))
        if model.name in lenses:  # a lens model the project writes and reads (tests/test_lens.py)
            assert read_colmap_model(used).lens.model == lenses[model.name]
            continue
        with pytest.raises(ColmapError, match=f"camera model {model.name} with {len(camera.params)} parameters; "
                                              "PINHOLE, SIMPLE_PINHOLE, OPENCV, FULL_OPENCV"):
            read_colmap_model(used)

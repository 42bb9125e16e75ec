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

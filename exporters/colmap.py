"""COLMAP sparse model of a trajectory (written with pycolmap, read by COLMAP and pycolmap).

One PINHOLE camera; one registered image per frame, named like the PNGs, with pose
``camera_from_world`` (the inverse of our world_from_camera; COLMAP's pixel convention is
ours: the top-left pixel's centre is (0.5, 0.5)); keypoints at the exact projections of the
static surface points visible in that frame; 3D points = static points seen in at least two
frames, with their tracks and the colour of the rendered pixel where first seen.
Dynamic points never enter the model.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pycolmap


def write_colmap_model(folder: str | Path, K: np.ndarray, width: int, height: int, poses: np.ndarray,
                       image_names: list[str], observations: list[tuple[np.ndarray, np.ndarray]],
                       points: np.ndarray, colors: np.ndarray, text: bool = False) -> pycolmap.Reconstruction:
    """Write ``folder`` (binary cameras.bin, images.bin, points3D.bin, rig and frame files;
    plus .txt with ``text``). ``observations[t]`` = (point indices (n,), pixel xy (n, 2)) of
    frame t; ``points`` (N, 3) world metres; ``colors`` (N, 3) uint8."""
    rec = pycolmap.Reconstruction()
    camera = pycolmap.Camera(model="PINHOLE", width=int(width), height=int(height),
                             params=[K[0, 0], K[1, 1], K[0, 2], K[1, 2]], camera_id=1)
    rec.add_camera_with_trivial_rig(camera)
    tracks: dict[int, list] = {}
    for t, ((idx, uv), pose, name) in enumerate(zip(observations, poses, image_names)):
        image_id = t + 1
        image = pycolmap.Image(name=name, keypoints=np.asarray(uv, dtype=np.float64).reshape(-1, 2), camera_id=1, image_id=image_id)
        cam_from_world = np.linalg.inv(pose)[:3, :4]
        rec.add_image_with_trivial_frame(image, pycolmap.Rigid3d(cam_from_world))
        for k, p in enumerate(np.asarray(idx)):
            tracks.setdefault(int(p), []).append(pycolmap.TrackElement(image_id, k))
    for p in sorted(tracks):
        elements = tracks[p]
        if len(elements) >= 2:
            rec.add_point3D(np.asarray(points[p], dtype=np.float64), pycolmap.Track(elements), np.asarray(colors[p], dtype=np.uint8))
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    rec.write(str(folder))
    if text:
        rec.write_text(str(folder))
    return rec

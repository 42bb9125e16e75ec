"""``transforms.json`` in the nerfstudio / instant-NGP convention, with depth images.

Poses are camera-to-world in the OpenGL camera convention (x right, y up, z backward):
``transform_matrix = world_from_camera @ diag(1, -1, -1, 1)`` with our OpenCV
world_from_camera. Intrinsics in pixels; nerfstudio's pixel convention is ours (the
top-left pixel's centre is at (0.5, 0.5)). Depth images are 16-bit PNGs of planar depth in
millimetres (``depth_unit_scale_factor`` 0.001); 0 means no surface or farther than 65.535 m.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from PIL import Image

OPENCV_TO_OPENGL = np.diag([1.0, -1.0, -1.0, 1.0])
DEPTH_SCALE = 0.001  # metres per depth PNG unit


def depth_png_name(index: int) -> str:
    return f"depth_{index:06d}.png"


def write_depth_png(path: str | Path, depth: np.ndarray) -> None:
    """Planar depth (H, W) metres -> 16-bit PNG in millimetres (0 = none or beyond range)."""
    mm = np.round(np.nan_to_num(np.asarray(depth, np.float64), nan=0.0, posinf=0.0) / DEPTH_SCALE)
    mm[(mm < 0) | (mm > 65535)] = 0
    Image.fromarray(mm.astype(np.uint16)).save(path, compress_level=1)


def read_depth_png(path: str | Path) -> np.ndarray:
    """16-bit depth PNG -> planar depth (H, W) float32 metres, +inf where 0."""
    mm = np.asarray(Image.open(path)).astype(np.float64)
    return np.where(mm > 0, mm * DEPTH_SCALE, np.inf).astype(np.float32)


def opengl_from_opencv(world_from_camera: np.ndarray) -> np.ndarray:
    """Camera-to-world (..., 4, 4) with OpenCV camera axes -> OpenGL camera axes."""
    return np.asarray(world_from_camera, np.float64) @ OPENCV_TO_OPENGL


def write_transforms(path: str | Path, K: np.ndarray, width: int, height: int, poses: np.ndarray,
                     image_names: list[str], depth_names: list[str] | None = None,
                     timestamps: np.ndarray | None = None) -> Path:
    """Write transforms.json for frames with ``poses`` (T, 4, 4) OpenCV world_from_camera."""
    frames = []
    for t, (pose, name) in enumerate(zip(poses, image_names)):
        frame = {"file_path": name, "transform_matrix": opengl_from_opencv(pose).tolist()}
        if depth_names is not None:
            frame["depth_file_path"] = depth_names[t]
        if timestamps is not None:
            frame["time"] = float(timestamps[t])
        frames.append(frame)
    doc = {"camera_model": "OPENCV", "fl_x": float(K[0, 0]), "fl_y": float(K[1, 1]), "cx": float(K[0, 2]),
           "cy": float(K[1, 2]), "w": int(width), "h": int(height), "k1": 0.0, "k2": 0.0, "p1": 0.0, "p2": 0.0,
           "depth_unit_scale_factor": DEPTH_SCALE, "frames": frames}
    path = Path(path)
    path.write_text(json.dumps(doc, indent=1))
    return path

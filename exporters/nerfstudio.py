"""``transforms.json`` for nerfstudio, instant-NGP and splatting trainers, with depth PNGs.

Poses are camera-to-world in the OpenGL camera convention (x right, y up, z backward):
``transform_matrix = world_from_camera @ diag(1, -1, -1, 1)`` with our OpenCV
world_from_camera. Intrinsics in pixels; nerfstudio's pixel convention is ours (the
top-left pixel's centre is (0.5, 0.5)). Depth PNGs are 16-bit planar depth in units of
``depth_unit`` metres (``integer_depth_scale`` for instant-NGP; ``depth_unit_scale_factor``
too, which nerfstudio's parser does not read from the file: pass it as its
``--depth-unit-scale-factor`` option), chosen per trajectory so that 65,535 units cover the deepest surface any
frame can see; 0 means no surface (docs/format.md).
"""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
from PIL import Image

from generator.geometry.lens import PINHOLE, Lens

from .frames import checked_png_bytes
from .jsonfile import read_checked_bytes
from .sinks import FrameRecord, TrajectoryContext, register_sink

OPENCV_TO_OPENGL = np.diag([1.0, -1.0, -1.0, 1.0])
DEPTH_UNITS = (0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0)  # metres per PNG unit
DEPTH_MAX_UNITS = 65535
POINTS_PLY = "points3D.ply"  # the COLMAP points with colours (exporters.colmap.ColmapSink)
TRANSFORMS = "transforms.json"


def depth_png_name(index: int) -> str:
    return f"depth_{index:06d}.png"


def depth_unit_for(max_depth: float) -> float:
    """The finest unit of :data:`DEPTH_UNITS` whose 65,535 steps reach ``max_depth`` metres."""
    for unit in DEPTH_UNITS:
        if DEPTH_MAX_UNITS * unit >= max_depth:
            return unit
    raise ValueError(f"depth up to {max_depth:.0f} m does not fit a 16-bit PNG even in metres; "
                     "lower the camera's clip end")


def max_planar_depth(poses: np.ndarray, bounds: np.ndarray, far: float = np.inf) -> float:
    """Upper bound (metres) on the planar depth of any surface inside the axis-aligned
    ``bounds`` (2, 3) seen from any of ``poses`` (T, 4, 4), capped at ``far``: planar depth
    is linear, so its largest value on the box is at a corner."""
    lo, hi = np.asarray(bounds, np.float64)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    poses = np.asarray(poses, np.float64)
    z = np.einsum("ti,tci->tc", poses[:, :3, 2], corners[None] - poses[:, None, :3, 3])
    return float(min(max(z.max(), 0.0), far))


def write_depth_png(path: str | Path, depth: np.ndarray, unit: float) -> None:
    """Planar depth (H, W) metres -> 16-bit PNG of ``round(depth / unit)`` (at least 1 on a
    surface; 0 = no surface). A surface deeper than 65,535 units raises ValueError: no
    surface is ever dropped."""
    d = np.asarray(depth, np.float64)
    surface = np.isfinite(d) & (d > 0)
    steps = np.zeros(d.shape, np.float64)
    steps[surface] = np.maximum(np.round(d[surface] / unit), 1)
    if surface.any() and steps.max() > DEPTH_MAX_UNITS:
        raise ValueError(f"{path}: depth {d[surface].max():.2f} m exceeds the PNG range "
                         f"{DEPTH_MAX_UNITS * unit:.2f} m of unit {unit} m")
    Image.fromarray(steps.astype(np.uint16)).save(path, compress_level=1)


def read_depth_png(path: str | Path, unit: float | None = None) -> np.ndarray:
    """16-bit depth PNG -> planar depth (H, W) float32 metres, +inf where 0. ``unit``
    defaults to ``integer_depth_scale`` of the transforms.json beside the file."""
    path = Path(path)
    if unit is None:
        try:
            unit = float(json.loads(read_checked_bytes(path.parent / TRANSFORMS))["integer_depth_scale"])
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise ValueError(f"{path}: no depth unit ({path.parent / TRANSFORMS}: {exc.__class__.__name__}); "
                             "pass unit= (metres per step)") from None
    try:
        with Image.open(io.BytesIO(checked_png_bytes(path))) as im:
            data = np.asarray(im)
    except ValueError as exc:
        raise ValueError(f"{exc}; regenerate the seed") from None
    except OSError as exc:
        raise ValueError(f"{path}: unreadable PNG ({exc}); regenerate the seed") from None
    if data.ndim != 2 or data.dtype != np.uint16:
        raise ValueError(f"{path}: a {data.dtype} PNG of shape {data.shape}, not a 16-bit grey depth image")
    steps = data.astype(np.float64)
    return np.where(steps > 0, steps * unit, np.inf).astype(np.float32)


def opengl_from_opencv(world_from_camera: np.ndarray) -> np.ndarray:
    """Camera-to-world (..., 4, 4) with OpenCV camera axes -> OpenGL camera axes."""
    return np.asarray(world_from_camera, np.float64) @ OPENCV_TO_OPENGL


def instant_ngp_box(poses: np.ndarray, bounds: np.ndarray | None) -> dict:
    """instant-NGP's ``scale``, ``offset`` (``p * scale + offset`` in this file's world axes)
    and ``aabb_scale``: the camera positions' bounding box fills the unit cube (centred at
    0.5) and the power-of-two ``aabb_scale`` (at most 128) covers the scene ``bounds``."""
    centres = np.asarray(poses, np.float64)[:, :3, 3]
    lo, hi = centres.min(0), centres.max(0)
    extent = max(float((hi - lo).max()), 1e-3) * 1.2
    scale = 1.0 / extent
    centre = (lo + hi) / 2
    aabb = 1
    if bounds is not None:
        reach = 2 * float(np.abs(np.asarray(bounds, np.float64) - centre).max()) * scale
        while aabb < reach and aabb < 128:
            aabb *= 2
    return {"scale": scale, "offset": (0.5 - scale * centre).tolist(), "aabb_scale": aabb}


def write_transforms(path: str | Path, K: np.ndarray, width: int, height: int, poses: np.ndarray,
                     image_names: list[str], depth_names: list[str] | None = None,
                     timestamps: np.ndarray | None = None, depth_unit: float = DEPTH_UNITS[0],
                     bounds: np.ndarray | None = None, ply_file: str | None = None, lens: Lens = PINHOLE) -> Path:
    """Write transforms.json for frames with ``poses`` (T, 4, 4) OpenCV world_from_camera, seen
    through ``lens`` (its camera model and coefficients in nerfstudio's fields)."""
    frames = []
    for t, (pose, name) in enumerate(zip(poses, image_names)):
        frame = {"file_path": name, "transform_matrix": opengl_from_opencv(pose).tolist()}
        if depth_names is not None:
            frame["depth_file_path"] = frame["depth_path"] = depth_names[t]  # nerfstudio, instant-NGP
        if timestamps is not None:
            frame["time"] = float(timestamps[t])
        frames.append(frame)
    doc = {"camera_model": "OPENCV", "fl_x": float(K[0, 0]), "fl_y": float(K[1, 1]), "cx": float(K[0, 2]),
           "cy": float(K[1, 2]), "w": int(width), "h": int(height), "k1": 0.0, "k2": 0.0, "p1": 0.0, "p2": 0.0}
    if not lens.ideal:
        doc |= lens.nerfstudio_fields()
    if depth_names is not None:
        doc |= {"depth_unit_scale_factor": depth_unit, "integer_depth_scale": depth_unit}
    doc |= instant_ngp_box(poses, bounds)
    if ply_file is not None:
        doc["ply_file_path"] = ply_file
    doc["frames"] = frames
    path = Path(path)
    path.write_text(json.dumps(doc, indent=1))
    return path


@register_sink("nerfstudio")
class NerfstudioSink:
    """Depth PNGs per frame (when ``depth`` is written) and transforms.json at the end."""

    def __init__(self, context: TrajectoryContext):
        self.context = context
        self.folder = Path(context.folder)
        self.depth = "depth" in context.modalities
        bounds = context.scene_bounds
        far = context.clip[1]
        deepest = max_planar_depth(context.poses, bounds, far) if bounds is not None else far
        self.unit = depth_unit_for(deepest) if self.depth else None

    def add_frame(self, frame: FrameRecord) -> None:
        if self.depth:
            write_depth_png(self.folder / depth_png_name(frame.index), frame.outputs["depth"], self.unit)

    def close(self) -> None:
        c = self.context
        T = len(c.poses)
        write_transforms(self.folder / TRANSFORMS, c.K, c.width, c.height, c.poses,
                         [f"rgb_{i:06d}.png" for i in range(T)],
                         [depth_png_name(i) for i in range(T)] if self.depth else None, c.timestamps,
                         self.unit or DEPTH_UNITS[0], c.scene_bounds, POINTS_PLY, c.lens)

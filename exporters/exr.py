"""Per-frame EXR files: RGB, depth, semantic labels and instance ids in one file.

Channels (single part, scanline, documented in docs/format.md):

| channel    | type   | content                                                          |
|------------|--------|------------------------------------------------------------------|
| R, G, B    | HALF   | colour; display-referred sRGB in [0, 1] unless the header says    |
| Z          | FLOAT  | planar depth in metres (camera z), +inf where no surface         |
| label      | UINT   | semantic label id; 4294967295 (= -1 as int32) means unlabelled   |
| instance   | UINT   | object (instance) id; 4294967295 (= -1 as int32) means none      |

Any subset of the channels may be written. Header attributes ``buildee/*`` state units and
conventions. The reader returns exactly the arrays that were written (RGB as float16,
depth as float32, label and instance as int32 with -1).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import OpenEXR

COMPRESSIONS = {
    "none": OpenEXR.NO_COMPRESSION,
    "rle": OpenEXR.RLE_COMPRESSION,
    "zips": OpenEXR.ZIPS_COMPRESSION,
    "zip": OpenEXR.ZIP_COMPRESSION,
    "piz": OpenEXR.PIZ_COMPRESSION,
}
RGB_CHANNELS = ("R", "G", "B")
DEPTH_CHANNEL = "Z"
LABEL_CHANNEL = "label"
INSTANCE_CHANNEL = "instance"
ATTRIBUTES = {
    "buildee/format": "frame-exr-1",
    "buildee/depth": "Z: planar depth (camera z) in metres, float32, +inf = no surface",
    "buildee/label": "label: uint32 label id, 4294967295 (-1 as int32) = unlabelled",
    "buildee/instance": "instance: uint32 object id, 4294967295 (-1 as int32) = none",
    "buildee/pixels": "pixel (row i, col j) has its centre at (x, y) = (j + 0.5, i + 0.5)",
}


def _ids_to_uint32(ids: np.ndarray, name: str) -> np.ndarray:
    ids = np.asarray(ids)
    if ids.ndim != 2 or not np.issubdtype(ids.dtype, np.integer):
        raise ValueError(f"{name} must be a 2D integer array, got {ids.dtype} {ids.shape}")
    if ids.size and (ids.min() < -1 or ids.max() > np.iinfo(np.int32).max):
        raise ValueError(f"{name} ids must lie in [-1, 2^31 - 1]")
    return np.ascontiguousarray(ids.astype(np.int64).astype(np.int32).view(np.uint32))


def write_frame_exr(
    path: str | Path,
    rgb: np.ndarray | None = None,
    depth: np.ndarray | None = None,
    label: np.ndarray | None = None,
    instance: np.ndarray | None = None,
    compression: str = "zip",
    rgb_meaning: str = "display-referred sRGB in [0, 1]",
    attributes: dict[str, str] | None = None,
) -> Path:
    """Write one frame's arrays (all (H, W) or (H, W, 3), same H and W) to an EXR file."""
    if compression not in COMPRESSIONS:
        raise ValueError(f"unknown EXR compression {compression!r}; choose one of {', '.join(COMPRESSIONS)}")
    channels: dict[str, np.ndarray] = {}
    if rgb is not None:
        rgb = np.asarray(rgb)
        if rgb.ndim != 3 or rgb.shape[2] != 3:
            raise ValueError(f"rgb must have shape (H, W, 3), got {rgb.shape}")
        for k, c in enumerate(RGB_CHANNELS):
            channels[c] = np.ascontiguousarray(rgb[..., k], dtype=np.float16)
    if depth is not None:
        depth = np.asarray(depth)
        if depth.ndim != 2:
            raise ValueError(f"depth must have shape (H, W), got {depth.shape}")
        channels[DEPTH_CHANNEL] = np.ascontiguousarray(depth, dtype=np.float32)
    if label is not None:
        channels[LABEL_CHANNEL] = _ids_to_uint32(label, "label")
    if instance is not None:
        channels[INSTANCE_CHANNEL] = _ids_to_uint32(instance, "instance")
    if not channels:
        raise ValueError("nothing to write: pass at least one of rgb, depth, label, instance")
    shapes = {c.shape[:2] for c in channels.values()}
    if len(shapes) != 1:
        raise ValueError(f"all arrays must share one (H, W), got {sorted(shapes)}")
    header = {"compression": COMPRESSIONS[compression], "type": OpenEXR.scanlineimage}
    header.update(ATTRIBUTES)
    if rgb is not None:
        header["buildee/rgb"] = rgb_meaning
    for key, value in (attributes or {}).items():
        header[key] = value if isinstance(value, str) else json.dumps(value)
    path = Path(path)
    with OpenEXR.File(header, dict(channels)) as f:  # the library replaces the dict's arrays
        f.write(str(path))
    return path


def read_frame_exr(path: str | Path) -> dict[str, np.ndarray]:
    """Read a frame EXR: returns the written arrays under 'rgb', 'depth', 'label', 'instance'
    (only those present) plus 'header' (the file's attributes)."""
    with OpenEXR.File(str(path), separate_channels=True) as f:
        ch = {name: c.pixels for name, c in f.channels().items()}
        header = dict(f.header())
    out: dict = {"header": header}
    if all(c in ch for c in RGB_CHANNELS):
        out["rgb"] = np.stack([ch[c] for c in RGB_CHANNELS], axis=-1)
    if DEPTH_CHANNEL in ch:
        out["depth"] = ch[DEPTH_CHANNEL]
    for key, name in (("label", LABEL_CHANNEL), ("instance", INSTANCE_CHANNEL)):
        if name in ch:
            out[key] = np.ascontiguousarray(ch[name], dtype=np.uint32).view(np.int32)
    return out

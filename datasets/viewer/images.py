"""A frame's per-pixel arrays as Rerun images (docs/viewer.md, "What is in a recording").

Only the modalities the frame holds are logged (a seed made with ``--outputs rgb`` has no
depth, labels or instances). ``rgb``, ``depth``, ``label`` and ``instance`` are logged as
Rerun's own image types; every other modality as an 8-bit RGB image coloured as its contact
sheet colours it (``exporters.previews.preview_tile``: normals as (n + 1) / 2, flow on the
colour wheel), and one with no preview colouring as its finite min..max mapped to 0..255.
"""

from __future__ import annotations

import numpy as np

from exporters.modalities import MODALITIES
from exporters.previews import preview_tile

from .common import class_ids

DISPLAYABLE_CHANNELS = (1, 3, 4)  # what rr.Image shows


def log_images(rec, path: str, frame, labels: list[str]) -> list[str]:
    """Log every per-pixel array of ``frame`` under ``path``; returns the names logged."""
    logged = []
    for name, value in frame.outputs.items():
        image = rerun_image(name, value, labels)
        if image is not None:
            rec.log(f"{path}/{name}", image)
            logged.append(name)
    return logged


def rerun_image(name: str, value: np.ndarray, labels: list[str]):
    """The Rerun archetype showing modality ``name``, or None for an array no image can show
    (neither a preview colouring nor 1, 3 or 4 channels)."""
    import rerun as rr

    if name == "rgb":  # 8-bit sRGB, rounded as the frames' PNGs
        return rr.Image(np.round(np.clip(value.astype(np.float32), 0, 1) * 255).astype(np.uint8))
    if name == "depth":  # metres, 0 where there is no surface (stored as +inf)
        return rr.DepthImage(np.where(np.isfinite(value), value, 0).astype(np.float32), meter=1.0)
    if name in ("label", "instance"):
        return rr.SegmentationImage(class_ids(value))
    modality = MODALITIES.get(name)
    if modality is not None and modality.preview is not None:
        return rr.Image(preview_tile(name, value, labels))
    channels = 1 if value.ndim == 2 else value.shape[2]
    if value.ndim not in (2, 3) or channels not in DISPLAYABLE_CHANNELS:
        return None
    return rr.Image(scaled_to_range(value))


def scaled_to_range(a: np.ndarray) -> np.ndarray:
    """An array of any type as 8-bit, its finite min..max mapped to 0..255 (non-finite: 0)."""
    a = a.astype(np.float64)
    ok = np.isfinite(a)
    if not ok.any():
        return np.zeros(a.shape, np.uint8)
    lo, hi = a[ok].min(), a[ok].max()
    out = np.where(ok, (a - lo) / (hi - lo if hi > lo else 1.0), 0)
    return np.round(out * 255).astype(np.uint8)

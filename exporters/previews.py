"""Preview images of a trajectory: a contact sheet of frames (RGB | depth | labels)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from .palette import colorize_labels


# an inferno-like ramp: near (0) bright yellow -> orange -> magenta -> far (1) dark blue
_RAMP = np.array([[252, 255, 164], [250, 193, 39], [245, 125, 21], [212, 72, 66], [159, 42, 99],
                  [101, 21, 110], [40, 11, 84], [0, 0, 40]], np.float64)


def colorize_depth(depth: np.ndarray, far: float | None = None) -> np.ndarray:
    """(H, W, 3) uint8: near = bright yellow, far = dark blue (square-root scale up to
    ``far``), no surface = black. ``far`` defaults to the 98th percentile of the finite depths."""
    finite = np.isfinite(depth)
    if not finite.any():
        return np.zeros(depth.shape + (3,), np.uint8)
    far = far or float(np.percentile(depth[finite], 98)) or 1.0
    s = np.clip(np.where(finite, depth, far) / far, 0, 1) ** 0.5 * (len(_RAMP) - 1)
    k = np.minimum(s.astype(np.int64), len(_RAMP) - 2)
    t = (s - k)[..., None]
    rgb = _RAMP[k] * (1 - t) + _RAMP[k + 1] * t
    rgb[~finite] = 0
    return (rgb + 0.5).astype(np.uint8)


def contact_sheet(path: str | Path, frames: list[dict], labels: list[str], max_width: int = 320) -> Path:
    """One row per frame: RGB, depth, labels, each scaled to at most ``max_width`` pixels
    wide. ``frames``: dicts with ``index``, ``rgb`` (H, W, 3) in [0, 1], ``depth`` (H, W)
    metres, ``label`` (H, W) int."""
    if not frames:
        raise ValueError("contact_sheet needs at least one frame")
    h, w = frames[0]["depth"].shape
    scale = min(1.0, max_width / w)
    tw, th = max(1, int(w * scale)), max(1, int(h * scale))
    finite = np.concatenate([f["depth"][np.isfinite(f["depth"])] for f in frames])
    far = float(np.percentile(finite, 98)) if len(finite) else 1.0
    pad, top = 4, 14
    sheet = Image.new("RGB", (3 * tw + 4 * pad, len(frames) * (th + top) + pad), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for r, f in enumerate(frames):
        tiles = [(np.clip(f["rgb"], 0, 1) * 255 + 0.5).astype(np.uint8), colorize_depth(f["depth"], far),
                 colorize_labels(np.asarray(f["label"]), labels)]
        y = r * (th + top) + top
        draw.text((pad, y - top + 1), f"frame {f['index']}   depth 0-{far:.0f} m", fill=(0, 0, 0))
        for c, tile in enumerate(tiles):
            sheet.paste(Image.fromarray(tile).resize((tw, th), Image.NEAREST), (pad + c * (tw + pad), y))
    path = Path(path)
    sheet.save(path)
    return path

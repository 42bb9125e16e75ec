"""Optional transforms of training samples that keep the geometry consistent.

A sample is a dict with any of ``rgb`` (H, W, 3), ``depth``, ``label``, ``instance`` (H, W),
``K`` (3, 3), and ``tracks`` (a dict with ``xy`` (..., 2) pixel positions). Pixel
convention: the top-left pixel's centre is (0.5, 0.5), so a crop shifts positions by the
crop's origin and a resize scales them by the size ratio, exactly; ``K`` changes the same way.
Depth, labels and instances are resampled by nearest neighbour (values are never mixed),
RGB by area averaging (PIL's box filter) when shrinking, bilinear when enlarging.
"""

from __future__ import annotations

import numpy as np
from PIL import Image

_IMAGE_KEYS = ("rgb", "depth", "label", "instance")


def _tracks(sample: dict, fn) -> None:
    for key in ("tracks", "tracks_next"):
        if key in sample and sample[key] is not None and "xy" in sample[key]:
            sample[key] = dict(sample[key]) | {"xy": fn(np.asarray(sample[key]["xy"], np.float64))}


class Crop:
    """Keep the window x in [x0, x0 + width), y in [y0, y0 + height) (pixels)."""

    def __init__(self, x0: int, y0: int, width: int, height: int):
        if min(width, height) <= 0 or min(x0, y0) < 0:
            raise ValueError(f"crop window must have a non-negative origin and a positive size, got {(x0, y0, width, height)}")
        self.x0, self.y0, self.width, self.height = int(x0), int(y0), int(width), int(height)

    def __call__(self, sample: dict) -> dict:
        out = dict(sample)
        for key in _IMAGE_KEYS:
            if key in out:
                img = out[key]
                if self.y0 + self.height > img.shape[0] or self.x0 + self.width > img.shape[1]:
                    raise ValueError(f"crop window {(self.x0, self.y0, self.width, self.height)} exceeds the "
                                     f"{img.shape[1]}x{img.shape[0]} image")
                out[key] = img[self.y0:self.y0 + self.height, self.x0:self.x0 + self.width]
        if "K" in out:
            K = np.array(out["K"], np.float64)
            K[0, 2] -= self.x0
            K[1, 2] -= self.y0
            out["K"] = K
        _tracks(out, lambda xy: xy - [self.x0, self.y0])
        return out


class Resize:
    """Resize to ``width`` x ``height`` pixels."""

    def __init__(self, width: int, height: int):
        if min(width, height) <= 0:
            raise ValueError(f"resize needs a positive size, got {width}x{height}")
        self.width, self.height = int(width), int(height)

    def __call__(self, sample: dict) -> dict:
        out = dict(sample)
        ref = next((out[k] for k in _IMAGE_KEYS if k in out), None)
        if ref is None:
            return out
        h, w = ref.shape[:2]
        sx, sy = self.width / w, self.height / h
        # nearest neighbour: output pixel centre (j + 0.5) / sx maps to source column floor(.)
        cols = np.minimum(((np.arange(self.width) + 0.5) / sx).astype(np.int64), w - 1)
        rows = np.minimum(((np.arange(self.height) + 0.5) / sy).astype(np.int64), h - 1)
        for key in ("depth", "label", "instance"):
            if key in out:
                out[key] = out[key][rows[:, None], cols[None, :]]
        if "rgb" in out:
            rgb = np.asarray(out["rgb"], np.float32)
            method = Image.BOX if sx <= 1 and sy <= 1 else Image.BILINEAR
            out["rgb"] = np.stack([np.asarray(Image.fromarray(rgb[..., c], mode="F").resize((self.width, self.height), method))
                                   for c in range(rgb.shape[2])], axis=-1)
        if "K" in out:
            out["K"] = np.diag([sx, sy, 1.0]) @ np.asarray(out["K"], np.float64)
        _tracks(out, lambda xy: xy * [sx, sy])
        return out


def srgb_to_linear(rgb: np.ndarray) -> np.ndarray:
    """Display sRGB in [0, 1] -> linear (the IEC 61966-2-1 curve)."""
    c = np.asarray(rgb, np.float32)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def linear_to_srgb(rgb: np.ndarray) -> np.ndarray:
    c = np.clip(np.asarray(rgb, np.float32), 0, None)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * c ** (1 / 2.4) - 0.055).astype(np.float32)


class ToLinear:
    """RGB from display sRGB to linear light (the frames hold display-referred sRGB)."""

    def __call__(self, sample: dict) -> dict:
        return dict(sample) | ({"rgb": srgb_to_linear(sample["rgb"])} if "rgb" in sample else {})


class Compose:
    def __init__(self, *transforms):
        self.transforms = transforms

    def __call__(self, sample: dict) -> dict:
        for t in self.transforms:
            sample = t(sample)
        return sample

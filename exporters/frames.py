"""Per-frame image files of one trajectory: ``frame_NNNNNN.exr`` (RGB, depth, labels,
instances; see exr.py) and ``rgb_NNNNNN.png`` (8-bit sRGB for tools that do not read EXR)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from PIL import Image

from .exr import write_frame_exr


def frame_names(index: int) -> tuple[str, str]:
    return f"frame_{index:06d}.exr", f"rgb_{index:06d}.png"


class FrameWriter:
    """Writes the frames of one trajectory into ``folder``."""

    def __init__(self, folder: str | Path, labels: list[str], compression: str = "zip"):
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.compression = compression
        self.attributes = {"buildee/labels": json.dumps(labels)}

    def write(self, index: int, rgb: np.ndarray, depth: np.ndarray, seg: np.ndarray, instance: np.ndarray) -> None:
        exr, png = frame_names(index)
        write_frame_exr(self.folder / exr, rgb, depth, seg, instance, compression=self.compression,
                        attributes=self.attributes)
        Image.fromarray((np.clip(rgb, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)).save(self.folder / png, compress_level=1)

"""``seed_N/changes.png``: a timeline at a glance (docs/phases.md).

Top row: frame 0 of one trajectory in every stage, side by side (the same pose; its display
RGB, or without the rgb output its label, instance or depth PNG). Bottom
row, one panel per consecutive pair k-1 -> k: the ground-truth clouds seen from above (north
up), unchanged surface grey, added surface (stage k) green, removed surface (stage k-1) red;
where both fall on one pixel the change is drawn over the rest."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from .changes import read_changes
from .ground_truth import read_points

COLOURS = {"unchanged": (150, 150, 150), "added": (30, 170, 60), "removed": (210, 40, 40)}


def change_map(xyz_before: np.ndarray, removed: np.ndarray, xyz_after: np.ndarray, added: np.ndarray,
               size: int, bounds: np.ndarray) -> np.ndarray:
    """(size, size, 3) uint8 top-down picture of one pair's change clouds over ``bounds``
    ((2, 2) metres, min and max of x and y)."""
    img = np.full((size, size, 3), 255, np.uint8)
    span = float(max(bounds[1] - bounds[0]))

    def draw(xyz, colour):
        if len(xyz) == 0:
            return
        col = ((xyz[:, 0] - bounds[0, 0]) / span * (size - 1)).astype(int)
        row = ((bounds[1, 1] - xyz[:, 1]) / span * (size - 1)).astype(int)
        ok = (col >= 0) & (col < size) & (row >= 0) & (row < size)
        img[row[ok], col[ok]] = colour

    draw(xyz_after[~added], COLOURS["unchanged"])
    draw(xyz_before[removed], COLOURS["removed"])
    draw(xyz_after[added], COLOURS["added"])
    return img


SHOWN = ("rgb", "label", "instance", "depth")  # the frame image of the top row: the first written


def _first_image(trajectory: Path) -> str:
    """The first of SHOWN whose PNG the trajectory folder holds (--outputs may leave rgb out)."""
    for name in SHOWN:
        if (trajectory / f"{name}_000000.png").is_file():
            return name
    raise FileNotFoundError(f"{trajectory}: no {', '.join(SHOWN)} PNG of frame 0 to show")


def timeline_preview(folder: str | Path, stages: int, kind: str, size: int = 360) -> Path:
    folder = Path(folder)
    changes = read_changes(folder, masks=False)
    clouds = [read_points(folder / f"phase_{k}" / "ground_truth").points for k in range(stages)]
    shown = _first_image(folder / "phase_0" / kind)
    frames = [np.asarray(Image.open(folder / f"phase_{k}" / kind / f"{shown}_000000.png").convert("RGB"))
              for k in range(stages)]
    h = size * frames[0].shape[0] // frames[0].shape[1]
    both = np.concatenate(clouds)
    bounds = np.array([both[:, :2].min(0), both[:, :2].max(0)])
    sheet = Image.new("RGB", (size * stages, h + size + 40), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for k, rgb in enumerate(frames):
        sheet.paste(Image.fromarray(rgb).resize((size, h), Image.BILINEAR), (k * size, 20))
        draw.text((k * size + 4, 4), f"stage {k} ({kind}, frame 0{'' if shown == 'rgb' else ', ' + shown})",
                  fill=(0, 0, 0))
    for k in range(1, stages):
        pair = changes.pair(k - 1, k)
        panel = change_map(clouds[k - 1], pair.points_removed, clouds[k], pair.points_added, size - 8, bounds)
        x = (k - 1) * size + size // 2
        sheet.paste(Image.fromarray(panel), (x + 4, h + 36))
        draw.text((x + 4, h + 22), f"{k - 1} -> {k}: green added, red removed", fill=(0, 0, 0))
    path = folder / "changes.png"
    sheet.save(path, optimize=True)
    return path

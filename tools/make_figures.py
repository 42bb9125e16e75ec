"""Make the documentation figures (docs/images/*.png) from scenes built in code.

Usage: .venv/bin/python tools/make_figures.py
"""

from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

import numpy as np  # noqa: E402
from PIL import Image, ImageDraw  # noqa: E402

import scenes  # noqa: E402
from generator import Simulator  # noqa: E402

PALETTE = np.array([[230, 159, 0], [86, 180, 233], [0, 158, 115], [240, 228, 66], [0, 114, 178], [213, 94, 0], [204, 121, 167]], np.uint8)


def colorize(seg: np.ndarray) -> np.ndarray:
    out = np.zeros(seg.shape + (3,), np.uint8)
    out[seg >= 0] = PALETTE[seg[seg >= 0] % len(PALETTE)]
    return out


def sensitivity_figure(path: Path) -> None:
    tmp = Path(tempfile.mkdtemp())
    scenes.new_scene(240, 160)
    scenes.add_plane("Ground", (80, 80), (0, 10, 0))
    scenes.add_box("Container", (6, 2.4, 2.6), (1.5, 9, 1.3), rotation=(0, 0, 0.4))
    for k in range(5):
        scenes.add_cylinder("Scaffold", 0.024, 4, (-3.5 + 0.6 * k, 6 + 0.3 * k, 2), segments=12)
    scenes.add_box("Rebar", (4, 0.012, 0.012), (-1.5, 5, 2.5), rotation=(0, 0.2, 0.1))
    scenes.add_sun()
    scenes.add_camera((0, -2, 2.2), (math.radians(85), 0, 0), lens=28)
    sim = Simulator(scenes.save(tmp / "fig.blend"), points_density=1, segmentation_sensitivity=0.0, render_preset="default")
    panels = [("RGB", (np.clip(sim.render().rgb, 0, 1) * 255).astype(np.uint8))]
    for s in (0.0, 0.5, 0.9):
        sim.segmentation_sensitivity = s
        panels.append((f"segmentation_sensitivity={s}", colorize(sim.render().seg)))
    w, h = 240, 160
    sheet = Image.new("RGB", (2 * w + 10, 2 * (h + 20) + 10), "white")
    draw = ImageDraw.Draw(sheet)
    for k, (title, img) in enumerate(panels):
        x, y = (k % 2) * (w + 10), (k // 2) * (h + 20 + 10)
        draw.text((x + 4, y + 3), title, fill="black")
        sheet.paste(Image.fromarray(img), (x, y + 20))
    sheet.save(path, optimize=True)


if __name__ == "__main__":
    out = ROOT / "docs" / "images"
    out.mkdir(parents=True, exist_ok=True)
    sensitivity_figure(out / "segmentation_sensitivity.png")
    print("wrote", out / "segmentation_sensitivity.png")

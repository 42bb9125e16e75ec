"""Previews for the diversity report (imports bpy through build_site): ``python -m
generator.scene --survey A-B --previews --out DIR`` builds every surveyed seed, keeps its
preview (480x320, the scene camera, the preview render preset) as
``DIR/previews/seed_NNNNNN.png``, measures its colour and lays the previews out on
``DIR/contact_sheet.png``. docs/scenes.md, "Survey".

Colour of a preview: the mean of each channel of its 8-bit sRGB pixels, in [0, 1]. Colour
spread of a set of seeds: the standard deviation (population) over the seeds of each
channel's mean, and the mean of the three: how much a seed's overall look varies from seed
to seed (issue #39 compares it between checkouts: benchmarks/diversity.py).
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

SHEET_COLUMNS = 4
THUMB = (240, 160)  # contact-sheet cell, pixels (half a preview)


def preview_colour(png: Path) -> list[float]:
    """Mean R, G, B of the 8-bit image ``png``, in [0, 1]."""
    with Image.open(png) as im:
        rgb = np.asarray(im.convert("RGB"), dtype=np.float64) / 255.0
    return [float(c) for c in rgb.reshape(-1, 3).mean(axis=0)]


def colour_spread(means: list[list[float]]) -> dict[str, float]:
    """Standard deviation over seeds of each channel's mean colour, and their mean."""
    a = np.asarray(means, dtype=np.float64).reshape(-1, 3)
    std = a.std(axis=0)
    return {"r": float(std[0]), "g": float(std[1]), "b": float(std[2]), "mean": float(std.mean())}


def contact_sheet(previews: list[tuple[int, Path]], out: Path, columns: int = SHEET_COLUMNS) -> Path:
    """A grid of the ``previews`` ((seed, png) each), ``columns`` wide, each labelled with its seed."""
    rows = max(1, -(-len(previews) // columns))
    sheet = Image.new("RGB", (columns * THUMB[0], rows * THUMB[1]), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for i, (seed, png) in enumerate(previews):
        x, y = (i % columns) * THUMB[0], (i // columns) * THUMB[1]
        with Image.open(png) as im:
            sheet.paste(im.convert("RGB").resize(THUMB, Image.Resampling.LANCZOS), (x, y))
        draw.rectangle((x, y, x + 62, y + 13), fill=(0, 0, 0))
        draw.text((x + 3, y + 1), f"seed {seed}", fill=(255, 255, 255))
    sheet.save(out)
    return out


def preview_seeds(seeds: list[int], out: Path, preset: str, progress=None, **overrides) -> dict[int, Path]:
    """Build each seed's site in a scratch folder and keep its preview as
    ``out/previews/seed_NNNNNN.png``; {seed: that path}. ``progress`` wraps the iteration."""
    from . import build_site

    folder = out / "previews"
    folder.mkdir(parents=True, exist_ok=True)
    kept = {}
    with tempfile.TemporaryDirectory(prefix="survey-") as scratch:
        for seed in (progress(seeds) if progress else seeds):
            result = build_site(seed, preset, Path(scratch) / str(seed), preview=True, **overrides)
            kept[seed] = Path(shutil.copyfile(result.preview, folder / f"seed_{seed:06d}.png"))
            shutil.rmtree(Path(scratch) / str(seed))
    return kept

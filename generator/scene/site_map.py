"""Top-down map of a site plan (PNG), drawn from the plan with no rendering."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from .kinds import kind as kind_named
from .site import SitePlan
from .taxonomy import CLASS_COLORS


def draw_map(plan: SitePlan, path: str | Path, pixels_per_metre: float | None = None, trajectory: np.ndarray | None = None) -> Path:
    """Draw footprints (their kind's class colours), the road and truck route, the circles of
    crane jibs (assets with a ``jib_length``), the start of every asset that drives (a square)
    and the fence; optionally a camera trajectory (K, 2 or 3) in world metres. North (+y) is up."""
    size = plan.params.size
    ppm = pixels_per_metre or max(4.0, 800.0 / size)
    w = int(size * ppm) + 40
    img = Image.new("RGB", (w, w), (215, 205, 185))
    draw = ImageDraw.Draw(img)

    def px(xy):
        xy = np.atleast_2d(np.asarray(xy, dtype=float))
        return [(20 + (x + size / 2) * ppm, 20 + (size / 2 - y) * ppm) for x, y in xy[:, :2]]

    if plan.road is not None:
        road = px(np.vstack([plan.road, plan.road[:1]]))
        draw.line(road, fill=(150, 145, 140), width=max(2, int(plan.road_width * ppm)), joint="curve")
        draw.line(road, fill=(240, 240, 240), width=1)
    for a, b in plan.fence_runs:
        draw.line(px([a, b]), fill=(90, 90, 100), width=2)
    for dig in (plan.relief.digs if plan.relief is not None else ()):
        draw.polygon(px(dig.outline()), fill=(110, 80, 50), outline=(40, 40, 40))

    def colour(placed):
        return CLASS_COLORS.get(kind_named(placed.asset.kind).label, (0, 0, 0))

    for placed in plan.placed:
        if placed.asset.moves:
            continue
        if "jib_length" in placed.asset.info:
            r = placed.asset.info["jib_length"] * ppm
            cx, cy = px(placed.position)[0]
            draw.ellipse((cx - r, cy - r, cx + r, cy + r), outline=colour(placed), width=1)
        draw.polygon(px(placed.footprint.corners()), fill=colour(placed), outline=(40, 40, 40))
    for placed in plan.placed:
        if placed.asset.moves and placed.asset.parts[0].keys is not None:
            start = placed.asset.parts[0].keys.location[0]
            cx, cy = px(start[:2])[0]
            draw.rectangle((cx - 4, cy - 4, cx + 4, cy + 4), fill=colour(placed), outline=(0, 0, 0))
    if trajectory is not None and len(trajectory) > 1:
        draw.line(px(trajectory), fill=(200, 0, 0), width=2)
        cx, cy = px(trajectory[0])[0]
        draw.ellipse((cx - 4, cy - 4, cx + 4, cy + 4), fill=(200, 0, 0))
    bar = 10.0 if size <= 120 else 50.0  # scale bar
    draw.line([(20, w - 12), (20 + bar * ppm, w - 12)], fill=(0, 0, 0), width=3)
    draw.text((24 + bar * ppm, w - 19), f"{bar:.0f} m", fill=(0, 0, 0))
    draw.text((24, 4), f"seed {plan.seed}, {size:.0f} m site, N up", fill=(0, 0, 0))
    path = Path(path)
    img.save(path, optimize=True)
    return path

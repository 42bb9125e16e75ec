"""Procedural construction sites (the paper's section 4.1), deterministic by seed.

``build_site(seed, preset="medium", out_dir=...)`` plans a site (bpy-free, see
:mod:`.site`), builds it in Blender, and writes ``site.blend`` (zstd-compressed, loads in
``Simulator``), ``preview.png`` (a render), ``map.png`` (top-down layout) and
``site.json`` (parameters and counts). See docs/scenes.md.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from ..checks import check_seed
from .site import LAYOUTS, PRESETS, SiteParams, SitePlan, plan_site, site_params  # noqa: F401
from .taxonomy import CLASS_ID, CLASSES  # noqa: F401


@dataclass
class SiteResult:
    """What :func:`build_site` made: the saved files, ``site.json``'s contents and the plan
    the site was built from (so no caller plans it a second time)."""

    blend: Path
    preview: Path | None
    map: Path
    info: dict
    plan: SitePlan


def build_site(seed: int, preset: str = "medium", out_dir: str | Path = ".", preview: bool = True,
               resolution: tuple[int, int] = (640, 480), stage: int = 0, stages: int = 1, **overrides) -> SiteResult:
    """Build and save the site of ``seed``. ``overrides`` are :class:`SiteParams` fields
    (size, density, layout, phase, frames, fps, ...); ``stage`` of ``stages`` picks a stage
    of the seed's timeline (docs/phases.md). Imports bpy."""
    from ..blender import session
    from ..blender.build import build_in_blender
    from .site_map import draw_map

    seed = check_seed("seed", seed)
    params = site_params(preset, **overrides)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    plan = plan_site(seed, params, stage, stages)
    counts = build_in_blender(plan, resolution)
    blend = out / "site.blend"
    session.save_blend(blend)
    info = plan.summary() | counts | {"preset": preset}
    (out / "site.json").write_text(json.dumps(info, indent=1, default=float))
    map_path = draw_map(plan, out / "map.png")
    preview_path = None
    if preview:
        from .. import Simulator

        sim = Simulator(blend, points_density=0.01, seed=seed, render_preset="preview")
        sim.configure_render(resolution=(480, 320))
        import numpy as np
        from PIL import Image

        rgb = sim.render().rgb
        preview_path = out / "preview.png"
        Image.fromarray((np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8)).save(preview_path)
        session.open_blend(blend)  # leave Blender with the saved file, untouched by the preview
    return SiteResult(blend, preview_path, map_path, info, plan)


__all__ = ["build_site", "site_params", "plan_site", "SiteParams", "SitePlan", "PRESETS", "LAYOUTS", "CLASSES", "CLASS_ID", "SiteResult"]

"""Site generation cost per preset: build time (plan + Blender objects + save), triangles,
objects. Writes the preview and map images of the medium sites into docs/images/.

Usage: .venv/bin/python benchmarks/scenes.py [--seeds 0 137 281] [--presets small medium large]
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from generator.blender import session  # noqa: E402,F401  (bpy first)
from generator.scene import build_site  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 137, 281])
    ap.add_argument("--presets", nargs="+", default=["small", "medium", "large"])
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp())
    images = ROOT / "docs" / "images"
    print("| preset | seed | build s (no preview) | triangles | objects | .blend MB |")
    print("|---|---|---|---|---|---|")
    for preset in args.presets:
        for seed in args.seeds:
            out = tmp / f"{preset}_{seed}"
            t0 = time.perf_counter()
            r = build_site(seed, preset, out, preview=False)
            dt = time.perf_counter() - t0
            size = r.blend.stat().st_size / 1e6
            print(f"| {preset} | {seed} | {dt:.1f} | {r.info['triangles']:,} | {r.info['objects']} | {size:.1f} |", flush=True)
            if preset == "medium":
                r = build_site(seed, preset, out, preview=True)
                shutil.copy(r.preview, images / f"site_medium_{seed}_preview.png")
                shutil.copy(r.map, images / f"site_medium_{seed}_map.png")
    shutil.rmtree(tmp)


if __name__ == "__main__":
    main()

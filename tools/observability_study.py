"""Measure the observability mask of a site: how the observable share converges with the
number of viewpoints, what it costs, and where the never-observable points lie.

Usage:
  .venv/bin/python tools/observability_study.py --seed 0 [--blend site.blend] [--density 10]
      [--viewpoints 1024] [--json out.json]
  .venv/bin/python tools/observability_study.py --plot docs/images/observability_convergence.png a.json b.json ...

Without ``--blend`` the medium site of the seed is built in a temporary folder. The scoring
cloud is sampled as exporters.ground_truth does (at ``--density`` points/m^2; the share does
not depend on the density, only its noise does). A site built by an older checkout (ground
slab, sampled contact faces) is measured the same way: its slab is not flat, so no face
counts as a contact face and every face is sampled, as that checkout did.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402


def study(blend: Path, seed: int, density: float, viewpoints: int, size: float) -> dict:
    from generator import Simulator  # bpy before open3d
    from exporters.ground_truth import sample_scoring_points
    from generator.geometry.observability import default_viewpoints, observable_mask
    from generator.geometry.raycast import SceneGeometry

    sim = Simulator(blend, points_density=0.01, seed=seed)
    sim.set_frame(sim.frame_range[0])
    parts = sim.scene_parts()
    pts = sample_scoring_points(parts, sim.label_ids, density, seed)
    views = default_viewpoints(sim.spawn_points, viewpoints)
    t0 = time.perf_counter()
    geometry = SceneGeometry(parts)
    counts: list[int] = []
    mask = observable_mask(geometry, pts["xyz"], pts["normals"], pts["instance"], views, counts)
    seconds = time.perf_counter() - t0
    n = len(mask)
    xyz, label = pts["xyz"], pts["label"]
    ground = label == sim.label_ids["Ground"]
    below = xyz[:, 2] < -0.05
    outside = ground & (np.abs(xyz[:, :2]).max(axis=1) > size / 2)

    def share(sel):
        return {"points": int(sel.sum()), "share_of_all": float(sel.sum() / n),
                "never_observable_share_of_all": float((sel & ~mask).sum() / n),
                "observable_share_of_these": float((sel & mask).sum() / max(sel.sum(), 1))}

    per_label = {}
    for i, name in enumerate(sim.labels):
        sel = label == i
        if sel.any():
            per_label[name] = share(sel)
    return {"blend": str(blend), "seed": seed, "density": density, "points": n,
            "viewpoints": len(views), "observable": int(mask.sum()), "observable_share": float(mask.mean()),
            "never_observable_share": float(1 - mask.mean()), "seconds": seconds,
            "curve": counts, "below_ground": share(below), "ground_outside_site": share(outside),
            "per_label": per_label}


def plot(path: Path, results: list[dict]) -> Path:
    """Observable share against the number of viewpoints (log2 axis), one curve per result."""
    from PIL import Image, ImageDraw

    W, H, left, right, top, bottom = 720, 420, 60, 20, 30, 50
    img = Image.new("RGB", (W, H), "white")
    d = ImageDraw.Draw(img)
    x0, x1, y0, y1 = left, W - right, H - bottom, top
    kmax = max(len(r["curve"]) for r in results)
    lo, hi = 0.0, 1.0
    d.rectangle([x0, y1, x1, y0], outline=(0, 0, 0))
    for k in range(11):
        y = y0 + (y1 - y0) * k / 10
        d.line([(x0, y), (x1, y)], fill=(230, 230, 230))
        d.text((x0 - 32, y - 6), f"{lo + (hi - lo) * k / 10:.1f}", fill=(0, 0, 0))
    xs = lambda k: x0 + (x1 - x0) * np.log2(k) / np.log2(kmax)  # noqa: E731
    k = 1
    while k <= kmax:
        d.line([(xs(k), y0), (xs(k), y1)], fill=(230, 230, 230))
        d.text((xs(k) - 8, y0 + 6), str(k), fill=(0, 0, 0))
        k *= 2
    d.text((W // 2 - 90, H - 22), "viewpoints (log scale)", fill=(0, 0, 0))
    d.text((x0, 8), "share of ground-truth points observable (medium sites)", fill=(0, 0, 0))
    colours = [(31, 119, 180), (214, 39, 40), (44, 160, 44), (255, 127, 14), (148, 103, 189), (140, 86, 75)]
    for j, r in enumerate(results):
        c = np.asarray(r["curve"], float) / r["points"]
        pts = [(xs(k + 1), y0 + (y1 - y0) * (c[k] - lo) / (hi - lo)) for k in range(len(c))]
        colour = colours[j % len(colours)]
        d.line(pts, fill=colour, width=2)
        d.text((x1 - 260, y0 - 20 - 14 * (len(results) - j)), r.get("name", f"seed {r['seed']}"), fill=colour)
    img.save(path)
    return path


def main() -> None:
    if len(sys.argv) > 2 and sys.argv[1] == "--plot":
        results = []
        for f in sys.argv[3:]:
            r = json.loads(Path(f).read_text())
            r["name"] = f"seed {r['seed']}" + (" (before)" if "before" in Path(f).name else "")
            results.append(r)
        print(plot(Path(sys.argv[2]), results))
        return
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--blend", type=Path)
    ap.add_argument("--preset", default="medium")
    ap.add_argument("--density", type=float, default=10.0)
    ap.add_argument("--viewpoints", type=int, default=1024)
    ap.add_argument("--json", type=Path)
    a = ap.parse_args()
    from generator.scene import site_params

    size = site_params(a.preset).size
    with tempfile.TemporaryDirectory() as tmp:
        blend = a.blend
        if blend is None:
            from generator.scene import build_site

            blend = build_site(a.seed, a.preset, tmp, preview=False).blend
        r = study(blend, a.seed, a.density, a.viewpoints, size)
    r["preset"] = a.preset
    text = json.dumps(r, indent=1)
    if a.json:
        a.json.write_text(text)
    c = r["curve"]
    print(f"seed {a.seed}: {r['points']:,} points, observable {r['observable_share']:.4f} after {r['viewpoints']} "
          f"viewpoints ({r['seconds']:.1f} s); after 1/4/16/64/256: "
          + ", ".join(f"{c[k - 1] / r['points']:.4f}" for k in (1, 4, 16, 64, 256) if k <= len(c)))


if __name__ == "__main__":
    main()

"""Observability mask speed (the ground truth's ``observable`` flags): ours against numpy.

On the medium site of ``--seed`` (built once and cached under ``--cache``, shared with
benchmarks/render.py), the ground truth's scoring cloud (``--density`` points per m2, the
batch job's 100 by default) and its 256 observability viewpoints, dynamic objects at the
first frame, as ``python -m generator`` writes them:
- ours: ``generator.geometry.observability.observable_mask`` (rules 3 and 4 per viewpoint
  in one numba pass, open3d/Embree rays);
- numpy: the same rules evaluated per viewpoint with numpy over the points not seen yet
  (``visibility_rules.facing_away``, ``cullable_parts``, ``segments_blocked``: the
  implementation before the kernel), the same rays into the same structures.
The two take turns going first; both must give the same mask, bit for bit.

Usage: .venv/bin/python benchmarks/observability.py [--rounds 2] [--density 100] [--seed 0]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from generator.blender import session  # noqa: E402,F401  (bpy first)
import numpy as np  # noqa: E402

from generator import Simulator  # noqa: E402


def numpy_mask(geometry, points, normals, part, viewpoints) -> np.ndarray:
    """The observability mask with numpy per viewpoint (the reference)."""
    from generator.geometry.visibility_rules import cullable_parts, facing_away, segments_blocked

    observable = np.zeros(len(points), dtype=bool)
    todo = np.arange(len(points))
    pts, nrm, prt = points, normals, part
    for centre in viewpoints:
        if not len(todo):
            break
        dx, dy, dz = (pts[:, k] - centre[k] for k in range(3))
        keep = ~(cullable_parts(geometry, centre)[prt] & facing_away(nrm[:, 0], nrm[:, 1], nrm[:, 2], dx, dy, dz))
        idx = np.flatnonzero(keep)
        seen = np.zeros(len(pts), dtype=bool)
        seen[idx] = ~segments_blocked(geometry, centre, dx[idx], dy[idx], dz[idx])
        observable[todo[seen]] = True
        todo, pts, nrm, prt = todo[~seen], pts[~seen], nrm[~seen], prt[~seen]
    return observable


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=2, help="timed runs of each approach")
    ap.add_argument("--density", type=float, default=100.0, help="scoring points per square metre")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cache", type=Path, default=Path("/tmp/buildee-render-bench"),
                    help="where the site is built once and reused")
    args = ap.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from render import medium_site

    from exporters.ground_truth import sample_scoring_points
    from generator.geometry.observability import default_viewpoints, observable_mask
    from generator.geometry.raycast import SceneGeometry

    sim = Simulator(medium_site(args.seed, args.cache), points_density=0.1, seed=args.seed)
    sim.set_frame(sim.frame_range[0])
    parts = sim.scene_parts()
    pts = sample_scoring_points(parts, sim.label_ids, args.density, args.seed)
    xyz, normals, part = pts["xyz"], pts["normals"], pts["instance"]
    views = default_viewpoints(sim.spawn_points)
    geometry = SceneGeometry(parts)
    observable_mask(geometry, xyz[:100], normals[:100], part[:100], views[:1])  # structures, kernel load
    times = {"ours": [], "numpy": []}
    masks = {}
    for r in range(args.rounds):
        for who in ("ours", "numpy") if r % 2 == 0 else ("numpy", "ours"):
            t0 = time.perf_counter()
            run = observable_mask if who == "ours" else numpy_mask
            masks[who] = run(geometry, xyz, normals, part, views)
            times[who].append(time.perf_counter() - t0)
        if not np.array_equal(masks["ours"], masks["numpy"]):
            raise SystemExit("the two masks differ")
    ours, ref = np.median(times["ours"]), np.median(times["numpy"])
    print(f"medium site of seed {args.seed}: {len(xyz):,} scoring points ({args.density:g}/m2), {len(views)} viewpoints, "
          f"{masks['ours'].mean():.1%} observable (same mask, bit for bit)")
    print(f"ours {ours:.1f} s (runs {', '.join(f'{t:.1f}' for t in times['ours'])}); numpy {ref:.1f} s "
          f"(runs {', '.join(f'{t:.1f}' for t in times['numpy'])}): {ref / ours:.2f}x")


if __name__ == "__main__":
    main()

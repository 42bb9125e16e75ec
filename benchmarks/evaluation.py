"""Speed of the evaluation package.

1. The full reconstruction suite (Chamfer, precision/recall/F at tau and a sweep, semantic
   Chamfer both ways, both mIoUs, the paper's Manhattan block) on 1 M predicted against
   1 M ground-truth points, side by side with the strong reference: scipy cKDTree on all
   cores, one Euclidean and one Manhattan query each way, every metric derived from those
   four. Each runs in its own process (peak memory = that process's maximum resident size),
   timed from before its imports to its result; our k-d tree's compiled code (numba) is
   cached on disk by a warm-up process first (its one-time compile time is printed).
2. Coverage scoring of a 500-pose random walk on a medium site with 1 M surface points
   (needs Blender to build the site; --skip-coverage to leave it out).

Usage: .venv/bin/python benchmarks/evaluation.py [--points 1000000] [--poses 500] [--skip-coverage]
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import resource
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

TAU, SWEEP = 0.1, (0.01, 0.02, 0.05, 0.1, 0.2, 0.5)


def synthetic(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A site-like GT (ground plane + 40 boxes, 8 classes) and a noisy, partial, mislabelled prediction."""
    rng = np.random.default_rng(seed)
    k = n // 2
    ground = np.column_stack([rng.uniform(0, 100, (k, 2)), np.zeros(k)])
    centres = rng.uniform(10, 90, (40, 3)) * [1, 1, 0] + [0, 0, 4]
    box = rng.integers(0, 40, n - k)
    face = rng.uniform(-1, 1, (n - k, 3))
    axis = rng.integers(0, 3, n - k)
    face[np.arange(n - k), axis] = np.sign(face[np.arange(n - k), axis])
    boxes = centres[box] + face * 4
    gt = np.concatenate([ground, boxes])
    gt_lab = np.concatenate([np.zeros(k, int), 1 + box % 7])
    keep = rng.random(n) < 0.8
    pred = gt[keep] + rng.normal(0, 0.03, (keep.sum(), 3))
    pred_lab = gt_lab[keep].copy()
    flip = rng.random(len(pred_lab)) < 0.05
    pred_lab[flip] = rng.integers(0, 8, flip.sum())
    extra = rng.uniform(0, 100, (n - len(pred), 3))  # outliers to reach n predicted points
    return np.concatenate([pred, extra]), np.concatenate([pred_lab, rng.integers(0, 8, len(extra))]), gt, gt_lab


def reference(pred, pred_lab, gt, gt_lab) -> dict:
    """The strong reference: scipy cKDTree on all cores, one Euclidean and one Manhattan query
    each way, every metric derived from those four queries."""
    from scipy.spatial import cKDTree

    # balanced_tree=False: sliding-midpoint trees, faster to build and query here than the default
    tg, tp = cKDTree(gt, balanced_tree=False), cKDTree(pred, balanced_tree=False)
    d1, i1 = tg.query(pred, k=1, workers=-1)
    d2, i2 = tp.query(gt, k=1, workers=-1)
    out = {"accuracy": d1.mean(), "completeness": d2.mean(), "chamfer_l2": (np.mean(d1 ** 2) + np.mean(d2 ** 2)) / 2}
    p, r = np.mean(d1 < TAU), np.mean(d2 < TAU)
    out |= {"precision": p, "recall": r, "fscore": 2 * p * r / (p + r)}
    out["sweep"] = [(np.mean(d1 < t), np.mean(d2 < t)) for t in SWEEP]
    out["sem_pg"] = np.mean((d1 < TAU) & (pred_lab == gt_lab[i1]))
    out["sem_gp"] = np.mean((d2 < TAU) & (gt_lab == pred_lab[i2]))
    transferred = np.where(d2 < TAU, pred_lab[i2], -1)
    ious = []
    for c in range(8):
        tp_ = np.sum((gt_lab == c) & (transferred == c))
        ious.append(tp_ / (np.sum(gt_lab == c) + np.sum(transferred == c) - tp_))
    out["miou"] = np.mean(ious)
    close = d1 < TAU
    a, b = gt_lab[i1[close]], pred_lab[close]
    out["miou_paper"] = np.mean([np.sum((a == c) & (b == c)) / (np.sum(a == c) + np.sum(b == c) - np.sum((a == c) & (b == c)))
                                 for c in range(8)])
    out["l1_pg"] = tg.query(pred, k=1, p=1, workers=-1)[0].mean()
    out["l1_gp"] = tp.query(gt, k=1, p=1, workers=-1)[0].mean()
    return out


def ours(pred, pred_lab, gt, gt_lab) -> dict:
    from evaluation.metrics import reconstruction_metrics

    return reconstruction_metrics(pred, gt, pred_lab, gt_lab, TAU, SWEEP, [str(c) for c in range(8)])


def warm_up() -> float:
    """Seconds to compile (or load from the on-disk cache) our k-d tree's code."""
    from evaluation.kdtree import KDTree

    t0 = time.perf_counter()
    tree = KDTree(np.random.default_rng(0).uniform(0, 1, (100, 3)))
    queries = np.zeros((2, 3))
    tree.nearest(queries)
    tree.nearest_manhattan(queries, np.full(2, np.inf))
    return time.perf_counter() - t0


def _child(name, n, queue):
    if name == "warm-up":
        queue.put((warm_up(), 0.0, None))
        return
    data = synthetic(n, 0)
    t0 = time.perf_counter()
    result = {"reference": reference, "ours": ours}[name](*data)
    seconds = time.perf_counter() - t0
    queue.put((seconds, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, result))


def run_isolated(name: str, n: int):
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    proc = ctx.Process(target=_child, args=(name, n, queue))
    proc.start()
    out = queue.get()
    proc.join()
    return out


def coverage_benchmark(points: int, poses: int) -> None:
    from generator import Simulator  # bpy first
    from generator.geometry.sampling import triangle_areas
    from generator.scene import build_site
    from trajectories import random_walk

    from evaluation.coverage import CoverageScorer, Poses
    from exporters.ground_truth import read_ground_truth, write_simulator_ground_truth
    from generator.geometry.seeding import stream

    tmp = Path(tempfile.mkdtemp())
    site = build_site(0, "medium", tmp / "scene", preview=False)
    probe = Simulator(site.blend, points_density=0.01, seed=0)
    area = sum(triangle_areas(p.vertices, p.faces).sum() for p in probe.scene_parts())
    sim = Simulator(site.blend, points_density=points / area, seed=0, max_pcl_depth=20.0)
    write_simulator_ground_truth(sim, tmp / "ground_truth", 0, scoring_density=1.0)
    traj = random_walk(sim, sim.respawn_camera(), poses - 1, stream(0, "bench"), step=1.0, angle=15.0)
    scene = read_ground_truth(tmp)
    t0 = time.perf_counter()
    scorer = CoverageScorer(scene)
    t_build = time.perf_counter() - t0
    t0 = time.perf_counter()
    curve, _ = scorer.curve(Poses(traj.poses))
    seconds = time.perf_counter() - t0
    print(f"\ncoverage: {len(scene.surface['local']):,} GT points, {scene.far:g} m range, {len(traj)} poses: "
          f"{seconds:.1f} s = {len(traj) / seconds:.1f} poses/s (+ {t_build:.1f} s to load the mesh); final coverage {curve[-1]:.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=1_000_000)
    ap.add_argument("--poses", type=int, default=500)
    ap.add_argument("--skip-coverage", action="store_true")
    args = ap.parse_args()
    t_warm, _, _ = run_isolated("warm-up", 0)
    print(f"warm-up: our k-d tree code compiled or loaded from numba's cache in {t_warm:.1f} s (not timed below)")
    t_ref, mem_ref, ref = run_isolated("reference", args.points)
    t_ours, mem_ours, res = run_isolated("ours", args.points)
    sem = res["semantic"]
    checks = {"accuracy": (ref["accuracy"], res["accuracy"]), "completeness": (ref["completeness"], res["completeness"]),
              "fscore": (ref["fscore"], res["fscore"]), "semantic pred->gt": (ref["sem_pg"], sem["semantic_chamfer_pred_to_gt"]),
              "mIoU": (ref["miou"], sem["miou"]), "mIoU paper": (ref["miou_paper"], sem["miou_paper"]),
              "L1 pred->gt": (ref["l1_pg"], res["paper"]["chamfer_l1_manhattan_pred_to_gt"]),
              "L1 gt->pred": (ref["l1_gp"], res["paper"]["chamfer_l1_manhattan_gt_to_pred"])}
    for k, (a, b) in checks.items():
        assert abs(a - b) < 1e-9, f"{k}: reference {a} vs ours {b}"
    print(f"{args.points:,} predicted vs {args.points:,} GT points, full suite (results agree to 1e-9):")
    print("| approach | seconds | peak memory |")
    print("|---|---|---|")
    print(f"| reference: cKDTree on all cores, one Euclidean + one Manhattan query each way | {t_ref:.1f} | {mem_ref:,.0f} MB |")
    print(f"| ours: `reconstruction_metrics` (one exact Euclidean and one L1 query each way in k-d trees with tight node boxes on all cores, each L1 query bounded by the L1 distance to the Euclidean nearest neighbour; every metric derived from them) | {t_ours:.1f} | {mem_ours:,.0f} MB |")
    print(f"ratio: {t_ref / t_ours:.1f}x")
    if not args.skip_coverage:
        coverage_benchmark(args.points, args.poses)


if __name__ == "__main__":
    main()

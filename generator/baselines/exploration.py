"""Table 2 and figure 8: random walk and modified random walk, coverage AUC per seed.

Geometry only (no rendering): each pose's visible surface points come from
``Simulator.compute_point_cloud`` with points visible within ``max_depth`` metres (planar
depth), the scene held at its first animation frame, as in the paper. Runs start at a
spawn point with a level camera (so 'forward' is horizontal) and stay inside the site's
camera spawn volume (its faces count as obstacles; the ground plane is unbounded).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

PAPER_TABLE2 = {  # AUC mean and standard deviation over 10 runs (the paper's table 2)
    0: {"random_walk": (0.22, 0.05), "modified_random_walk": (0.38, 0.02)},
    137: {"random_walk": (0.26, 0.07), "modified_random_walk": (0.46, 0.04)},
    281: {"random_walk": (0.19, 0.05), "modified_random_walk": (0.35, 0.07)},
}
METHODS = ("random_walk", "modified_random_walk")


def coverage_along(sim, poses: np.ndarray) -> np.ndarray:
    """Coverage after each pose (T,), from an empty observation history."""
    sim.reset_observations()
    out = np.empty(len(poses))
    for t, pose in enumerate(poses):
        sim.set_world_from_camera(pose, check_collisions=False)
        sim.compute_point_cloud()
        out[t] = sim.coverage
    return out


def run_exploration(seeds: list[int], steps: int, runs: int, out: Path, scene_preset: str = "medium",
                    max_depth: float = 20.0, points_density: float = 10.0, step: float = 1.0,
                    angle: float = 22.5) -> dict:
    """Run both walks ``runs`` times on each seed's site; write trajectories, curves, plots
    and ``exploration.json`` into ``out``; return the results."""
    from trajectories import BoundedChecker, modified_random_walk, random_walk

    from evaluation.coverage import coverage_auc
    from evaluation.report import coverage_plot

    from .. import Simulator
    from ..geometry.camera import levelled
    from ..geometry.seeding import stream
    from ..scene import build_site, plan_site, site_params
    from ..scene.site_map import draw_map

    walks = {"random_walk": random_walk, "modified_random_walk": modified_random_walk}
    out.mkdir(parents=True, exist_ok=True)
    results = {"task": "exploration", "parameters": {
        "seeds": seeds, "steps": steps, "runs": runs, "scene_preset": scene_preset, "max_depth_m": max_depth,
        "points_density_per_m2": points_density, "step_m": step, "turn_deg": angle, "frame": "first (static scene)",
        "start": "random spawn point, random heading, level camera", "bounds": "camera spawn volume",
        "auc": "trapezoid over x normalised to [0, 1] across the steps + 1 poses (start included)",
        "std": "sample standard deviation (ddof=1) over the runs"}, "seeds": {}}
    bar = tqdm(total=len(seeds) * len(METHODS) * runs, desc="runs", unit="run")
    for seed in seeds:
        t0 = time.perf_counter()
        site_dir = out / f"site_{seed}"
        site = build_site(seed, scene_preset, site_dir, preview=False)
        sim = Simulator(site.blend, points_density=points_density, seed=seed, max_pcl_depth=max_depth)
        starts = [levelled(sim.respawn_camera()) for _ in range(runs)]  # both methods start from the same poses
        checker = BoundedChecker(sim, sim.spawn_points.min(axis=0), sim.spawn_points.max(axis=0))
        curves = {m: [] for m in METHODS}
        trajectories = {}
        for method in METHODS:
            for r in range(runs):
                traj = walks[method](checker, starts[r], steps, stream(seed, "baseline-exploration", method, r),
                                     step=step, angle=angle)
                traj.save(site_dir / f"{method}_run{r:02d}.npz")
                curves[method].append(coverage_along(sim, traj.poses))
                trajectories[(method, r)] = traj
                bar.update()
        aucs = {m: [coverage_auc(c) for c in curves[m]] for m in METHODS}
        np.savez_compressed(site_dir / "coverage_curves.npz", **{m: np.array(curves[m]) for m in METHODS})
        coverage_plot(out / f"coverage_seed_{seed}.png",
                      {f"{m} (mean of {runs})": np.mean(curves[m], axis=0) for m in METHODS},
                      f"seed {seed}: coverage within {max_depth:g} m, {steps} steps")
        plan = plan_site(seed, site_params(scene_preset))
        best = trajectories[("modified_random_walk", 0)]
        draw_map(plan, out / f"figure8_seed_{seed}.png", trajectory=best.poses[:, :3, 3])
        results["seeds"][str(seed)] = {
            m: {"auc_mean": float(np.mean(aucs[m])), "auc_std": float(np.std(aucs[m], ddof=1)) if runs > 1 else 0.0,
                "auc_runs": aucs[m], "final_coverage_mean": float(np.mean([c[-1] for c in curves[m]])),
                "paper_auc": PAPER_TABLE2.get(seed, {}).get(m)} for m in METHODS} | {
            "points": sim.num_points, "seconds": time.perf_counter() - t0}
    bar.close()
    results["modified_beats_random_on_every_seed"] = all(
        s["modified_random_walk"]["auc_mean"] > s["random_walk"]["auc_mean"] for s in results["seeds"].values())
    (out / "exploration.json").write_text(json.dumps(results, indent=1))
    return results


def table(results: dict) -> str:
    lines = ["| seed | random walk AUC | modified random walk AUC | paper: random | paper: modified |", "|---|---|---|---|---|"]
    for seed, r in results["seeds"].items():
        paper = [r[m]["paper_auc"] for m in METHODS]
        cells = [f"{r[m]['auc_mean']:.3f} ± {r[m]['auc_std']:.3f}" for m in METHODS]
        cells += [f"{p[0]:.2f} ± {p[1]:.2f}" if p else "-" for p in paper]
        lines.append(f"| {seed} | " + " | ".join(cells) + " |")
    return "\n".join(lines)

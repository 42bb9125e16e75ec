"""Table 2 and figure 8: random walk and modified random walk, coverage AUC per seed.

The paper's evaluation protocol (its repository's evaluation branch), geometry only (no
rendering): 3 m moves, 22.5 degree turns, surface points at 5 per m², a point counts as
seen when it is visible within ``max_depth`` metres (planar depth), the scene held at its
first animation frame. Every run of a seed starts from one fixed pose (a low, level camera
at the site's entrance looking in: :mod:`.start_pose`) and stays inside the site's camera
spawn volume (its faces count as walls). Coverage is reported over all surface points (the
paper's figure) and over the observable ones (``Simulator.observable_points_mask``).
"""

from __future__ import annotations

import json
import re
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

PAPER_TABLE2 = {  # AUC mean and standard deviation over 10 runs (the paper's table 2, its medium-sized sites)
    0: {"random_walk": (0.22, 0.05), "modified_random_walk": (0.38, 0.02)},
    137: {"random_walk": (0.26, 0.07), "modified_random_walk": (0.46, 0.04)},
    281: {"random_walk": (0.19, 0.05), "modified_random_walk": (0.35, 0.07)},
}
METHODS = ("random_walk", "modified_random_walk")


def coverage_along(sim, poses: np.ndarray, subsets: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Coverage after each pose (T,) of each subset of points (name -> (N,) bool mask),
    from an empty observation history."""
    sim.reset_observations()
    sizes = {k: max(int(m.sum()), 1) for k, m in subsets.items()}
    out = {k: np.empty(len(poses)) for k in subsets}
    for t, pose in enumerate(poses):
        sim.set_world_from_camera(pose, check_collisions=False)
        sim.compute_point_cloud()
        for k, m in subsets.items():
            out[k][t] = np.count_nonzero(sim.observed_points_mask & m) / sizes[k]
    return out


def _summary(aucs: list[float]) -> dict:
    return {"auc_mean": float(np.mean(aucs)), "auc_std": float(np.std(aucs, ddof=1)) if len(aucs) > 1 else 0.0,
            "auc_runs": [float(a) for a in aucs]}


def run_exploration(seeds: list[int], steps: int, runs: int, out: Path, scene_preset: str = "medium",
                    max_depth: float = 20.0, points_density: float = 5.0, step: float = 3.0,
                    angle: float = 22.5, paper_code_actions: bool = False) -> dict:
    """Run both walks ``runs`` times on each seed's site; write trajectories, curves, plots
    and ``exploration.json`` into ``out``; return the results. ``paper_code_actions``: the
    random walk draws the paper's code's actions as written (two lefts, no right)."""
    from functools import partial

    from trajectories import ACTIONS, PAPER_CODE_ACTIONS, BoundedChecker, modified_random_walk, random_walk

    from evaluation.coverage import coverage_auc
    from evaluation.report import coverage_plot

    from .. import Simulator
    from ..geometry.seeding import stream
    from ..scene import build_site
    from ..scene.site_map import draw_map
    from .start_pose import site_start

    rw_actions = PAPER_CODE_ACTIONS if paper_code_actions else ACTIONS
    walks = {"random_walk": partial(random_walk, actions=rw_actions), "modified_random_walk": modified_random_walk}
    out.mkdir(parents=True, exist_ok=True)
    results = {"task": "exploration", "parameters": {
        "seeds": seeds, "steps": steps, "runs": runs, "scene_preset": scene_preset, "max_depth_m": max_depth,
        "points_density_per_m2": points_density, "step_m": step, "turn_deg": angle, "frame": "first (static scene)",
        "random_walk_actions": list(rw_actions),
        "start": "one fixed pose per seed: level camera at the site's entrance, lowest spawn height, looking in",
        "bounds": "camera spawn volume (site plan's spawn box)",
        "modified_walk": "forward every step; a blocked forward draws headings uniform in [-180, 180) deg in the same step",
        "auc": "trapezoid over x normalised to [0, 1] across the steps + 1 poses (start included)",
        "std": "sample standard deviation (ddof=1) over the runs"}, "seeds": {}}
    bar = tqdm(total=len(seeds) * len(METHODS) * runs, desc="runs", unit="run")
    for seed in seeds:
        t0 = time.perf_counter()
        site_dir = out / f"site_{seed}"
        for old in site_dir.glob("*_run*.npz"):  # an earlier run's walks (another --runs, preset...), ours only
            if re.fullmatch(rf"({'|'.join(METHODS)})_run\d+\.npz", old.name):
                old.unlink()
        site = build_site(seed, scene_preset, site_dir, preview=False)
        sim = Simulator(site.blend, points_density=points_density, seed=seed, max_pcl_depth=max_depth)
        start, (lo, hi) = site_start(site.plan)
        if not sim.is_free(start[:3, 3]):
            raise RuntimeError(f"seed {seed}: the entrance start pose {start[:3, 3]} is not free of geometry")
        subsets = {"all": np.ones(sim.num_points, dtype=bool), "observable": sim.observable_points_mask}
        t_ready = time.perf_counter()
        checker = BoundedChecker(sim, lo, hi)
        curves = {m: {k: [] for k in subsets} for m in METHODS}
        trajectories = {}
        for method in METHODS:
            for r in range(runs):
                traj = walks[method](checker, start, steps, stream(seed, "baseline-exploration", method, r),
                                     step=step, angle=angle)
                traj.save(site_dir / f"{method}_run{r:02d}.npz")
                for k, c in coverage_along(sim, traj.poses, subsets).items():
                    curves[method][k].append(c)
                trajectories[(method, r)] = traj
                bar.update()
        np.savez_compressed(site_dir / "coverage_curves.npz",
                            **{f"{m}_{k}" if k != "all" else m: np.array(curves[m][k]) for m in METHODS for k in subsets})
        coverage_plot(out / f"coverage_seed_{seed}.png",
                      {f"{m} (mean of {runs})": np.mean(curves[m]["all"], axis=0) for m in METHODS},
                      f"seed {seed}: coverage within {max_depth:g} m, {steps} steps")
        draw_map(site.plan, out / f"figure8_seed_{seed}.png", trajectory=trajectories[("modified_random_walk", 0)].positions)
        entry = {}
        for m in METHODS:
            entry[m] = _summary([coverage_auc(c) for c in curves[m]["all"]]) | {
                "final_coverage_mean": float(np.mean([c[-1] for c in curves[m]["all"]])),
                # the paper's figure only where its site is comparable: the medium preset
                "paper_auc": PAPER_TABLE2.get(seed, {}).get(m) if scene_preset == "medium" else None}
            entry[m]["observable"] = _summary([coverage_auc(c) for c in curves[m]["observable"]]) | {
                "final_coverage_mean": float(np.mean([c[-1] for c in curves[m]["observable"]]))}
        entry |= {"points": sim.num_points, "start_pose": start.tolist(),
                  "observable_points": int(subsets["observable"].sum()),
                  "seconds": time.perf_counter() - t0, "seconds_walks": time.perf_counter() - t_ready}
        results["seeds"][str(seed)] = entry
    bar.close()
    results["modified_beats_random_on_every_seed"] = all(
        s["modified_random_walk"]["auc_mean"] > s["random_walk"]["auc_mean"] for s in results["seeds"].values())
    (out / "exploration.json").write_text(json.dumps(results, indent=1))
    return results


def table(results: dict) -> str:
    lines = ["| seed | random walk AUC | modified random walk AUC | observable: random | observable: modified | "
             "paper: random | paper: modified |", "|---|---|---|---|---|---|---|"]
    for seed, r in results["seeds"].items():
        cells = [f"{r[m]['auc_mean']:.3f} ± {r[m]['auc_std']:.3f}" for m in METHODS]
        cells += [f"{r[m]['observable']['auc_mean']:.3f} ± {r[m]['observable']['auc_std']:.3f}" for m in METHODS]
        paper = [r[m]["paper_auc"] for m in METHODS]
        cells += [f"{p[0]:.2f} ± {p[1]:.2f}" if p else "-" for p in paper]
        lines.append(f"| {seed} | " + " | ".join(cells) + " |")
    return "\n".join(lines)

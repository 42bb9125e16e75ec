"""Steps per second of ``buildee/Exploration-v0``, one process, geometry only vs Cycles.

    .venv/bin/python benchmarks/envs.py [--seed 0] [--preset medium] [--steps 1000] [--cycles-steps 10]

Ours: 128x128 depth + label observations from the geometric camera
(``Simulator.render(engine="raycast")``) and the coverage reward (visibility of every
surface point at 5 points/m², within 20 m), random discrete actions drawn from a fixed seed.
Reference, the paper's way: the same environment and actions with the observation also
rendered by Cycles ``render()`` (``rgb=True``, the 'preview' preset, 128x128), timed on a
few steps. The site is built once into --cache-dir (not timed).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def run(env, actions) -> list[float]:
    """Seconds per step of ``env`` along ``actions`` (an episode reset first, not timed)."""
    env.reset(seed=0)
    out = []
    for a in actions:
        t0 = time.perf_counter()
        _, _, _, trunc, _ = env.step(int(a))
        out.append(time.perf_counter() - t0)
        if trunc:
            env.reset()
    return out


def stages(env, actions) -> dict[str, float]:
    """Median milliseconds of each stage of a step, measured on the Simulator directly."""
    sim = env.unwrapped.sim
    times = {"move (collision check)": [], "geometric camera 128x128": [], "visibility + coverage": []}
    for a in actions:
        t0 = time.perf_counter()
        if a == 0:
            sim.move_camera_forward(3.0)
        else:
            sim.turn_camera_right(22.5)
        t1 = time.perf_counter()
        sim.render_geometry(normals=False)
        t2 = time.perf_counter()
        sim.compute_point_cloud()
        t3 = time.perf_counter()
        for k, dt in zip(times, (t1 - t0, t2 - t1, t3 - t2)):
            times[k].append(dt)
    return {k: 1000 * statistics.median(v) for k, v in times.items()}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--preset", default="medium")
    p.add_argument("--steps", type=int, default=1000)
    p.add_argument("--cycles-steps", type=int, default=10)
    p.add_argument("--cache-dir", type=Path, default=Path("/tmp/buildee-bench-sites"))
    args = p.parse_args()

    import gymnasium as gym

    from generator.envs import EXPLORATION_ID

    print(f"load average before: {os.getloadavg()[0]:.2f} (1 min)")
    actions = np.random.default_rng(0).integers(0, 5, args.steps)
    kw = dict(seeds=[args.seed], scene_preset=args.preset, cache_dir=args.cache_dir, points_density=5.0,
              max_depth=20.0, resolution=(128, 128), max_steps=500)
    t0 = time.perf_counter()
    env = gym.make(EXPLORATION_ID, **kw)
    env.reset(seed=0)
    sim = env.unwrapped.sim
    print(f"site {args.preset} seed {args.seed}: {sim.num_points:,} surface points, "
          f"{sum(len(p.faces) for p in sim.scene_parts()):,} triangles; env ready in {time.perf_counter() - t0:.1f} s")
    geo = run(env, actions)
    print(f"ours (geometry): {len(geo)} steps, {1 / statistics.median(geo):.1f} steps/s (median), "
          f"{len(geo) / sum(geo):.1f} steps/s (mean), final coverage {env.unwrapped.coverage:.3f}")
    print("  stages (ms, median):", {k: round(v, 2) for k, v in stages(env, actions[:100]).items()})
    env.close()

    env = gym.make(EXPLORATION_ID, **kw, rgb=True, render_preset="preview")
    cyc = run(env, actions[: args.cycles_steps])
    env.close()
    print(f"reference (Cycles render() per step, preview, 128x128): {len(cyc)} steps, "
          f"{1 / statistics.median(cyc):.2f} steps/s (median {statistics.median(cyc):.2f} s a step), "
          f"{len(cyc) / sum(cyc):.2f} steps/s (mean)")
    print(f"ratio of medians: {statistics.median(cyc) / statistics.median(geo):.0f}x; "
          f"ratio of means: {sum(cyc) / len(cyc) / (sum(geo) / len(geo)):.0f}x")
    print(f"load average after: {os.getloadavg()[0]:.2f} (1 min)")


if __name__ == "__main__":
    main()

"""Run the baseline policies through ``buildee/Exploration-v0`` and print their coverage.

    .venv/bin/python docs/examples/explore.py --seeds 0 --episodes 2 --steps 500

Policies: a random agent (``env.action_space.sample()``), the paper's random walk and its
modified random walk (generator/envs/policies.py). Geometry only: no Blender render.
"""

import argparse
from pathlib import Path

import gymnasium as gym
import numpy as np

from generator.envs import EXPLORATION_ID
from generator.envs.policies import ModifiedRandomWalk, RandomWalk


def episode(env, policy, seed: int) -> tuple[float, float, int]:
    """(return, final coverage, collisions) of one episode."""
    obs, info = env.reset(seed=seed)
    total, collisions, done = 0.0, 0, False
    while not done:
        obs, reward, terminated, truncated, info = env.step(policy(obs, info))
        total, collisions, done = total + reward, collisions + info["collided"], terminated or truncated
    return total, info["coverage"], collisions


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--seeds", type=int, nargs="+", default=[0], help="procedural site seeds")
    p.add_argument("--episodes", type=int, default=2)
    p.add_argument("--steps", type=int, default=500)
    p.add_argument("--cache-dir", type=Path, default=Path("/tmp/buildee-sites"))
    args = p.parse_args()
    env = gym.make(EXPLORATION_ID, seeds=args.seeds, cache_dir=args.cache_dir, max_steps=args.steps)
    env.action_space.seed(100)  # a stream of its own (seed 0 would repeat RandomWalk(seed=0))
    policies = {"random agent": lambda obs, info: env.action_space.sample(),
                "random walk": RandomWalk(seed=0), "modified random walk": ModifiedRandomWalk(angle=22.5, seed=0)}
    for name, policy in policies.items():
        runs = [episode(env, policy, seed) for seed in range(args.episodes)]
        ret, cov, col = (np.mean([r[k] for r in runs]) for k in range(3))
        print(f"{name:>22}: return {ret:6.2f}, final coverage {cov:.3f}, collisions {col:.0f} per episode")
    env.close()


if __name__ == "__main__":
    main()

"""Train a PPO agent on ``buildee/Exploration-v0`` with Stable-Baselines3 (optional).

Not a project dependency and not run in CI:

    .venv/bin/pip install "stable-baselines3>=2.4"
    .venv/bin/python docs/examples/train_ppo.py --seeds 0 1 2 --envs 2 --timesteps 200000

One environment per process (Blender holds one scene per process), in SB3's
``SubprocVecEnv`` started with 'spawn'. The observation is the depth (clipped to
``max_depth`` and scaled to [0, 1], +inf = far) and the label map as two image channels,
plus the coverage so far, fed to SB3's ``MultiInputPolicy``.
"""

import argparse
from pathlib import Path

import gymnasium as gym
import numpy as np

ENV_ID = "generator.envs:buildee/Exploration-v0"  # the module prefix registers it in every worker
MAX_DEPTH = 20.0


class ImageObservation(gym.ObservationWrapper):
    """Depth and labels as a (2, H, W) uint8 image (CHW, as SB3's CNN expects) + coverage."""

    def __init__(self, env):
        super().__init__(env)
        h, w = env.observation_space["depth"].shape
        self.observation_space = gym.spaces.Dict({
            "image": gym.spaces.Box(0, 255, (2, h, w), np.uint8),
            "coverage": env.observation_space["coverage"]})

    def observation(self, obs):
        depth = np.clip(np.nan_to_num(obs["depth"], posinf=MAX_DEPTH), 0, MAX_DEPTH) / MAX_DEPTH
        label = (obs["label"] + 1).clip(0, 255)
        image = np.stack([(depth * 255).astype(np.uint8), label.astype(np.uint8)])
        return {"image": image, "coverage": obs["coverage"].astype(np.float32)}


def make_env(seeds, cache_dir):
    def thunk():
        return ImageObservation(gym.make(ENV_ID, seeds=seeds, cache_dir=cache_dir, max_depth=MAX_DEPTH))
    return thunk


def main() -> None:
    p = argparse.ArgumentParser(description="PPO on buildee/Exploration-v0 (needs stable-baselines3 and torch)")
    p.add_argument("--seeds", type=int, nargs="+", default=[0])
    p.add_argument("--envs", type=int, default=2)
    p.add_argument("--timesteps", type=int, default=200_000)
    p.add_argument("--cache-dir", type=Path, default=Path("/tmp/buildee-sites"))
    p.add_argument("--out", type=Path, default=Path("ppo_exploration.zip"))
    args = p.parse_args()
    try:
        from stable_baselines3 import PPO
        from stable_baselines3.common.vec_env import SubprocVecEnv
    except ImportError:
        raise SystemExit("error: this example needs stable-baselines3 (and torch): pip install stable-baselines3")
    # each worker builds (or loads from --cache-dir) its sites at its first reset; a file lock in
    # the cache makes one worker build each site while the others wait for it
    venv = SubprocVecEnv([make_env(args.seeds, args.cache_dir) for _ in range(args.envs)], start_method="spawn")
    model = PPO("MultiInputPolicy", venv, n_steps=512, batch_size=128, verbose=1, seed=0)
    model.learn(total_timesteps=args.timesteps)
    model.save(args.out)
    venv.close()


if __name__ == "__main__":
    main()

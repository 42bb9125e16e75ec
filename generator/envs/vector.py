"""``gymnasium.make_vec("buildee/Exploration-v0", num_envs=N, ...)``: N environments, each in
its own process (bpy-free here).

Blender holds one scene per process, so Gymnasium's default for an id without a vector
entry point, ``SyncVectorEnv`` (all environments in the calling process), cannot work: this
module is the id's ``vector_entry_point``, which ``make_vec`` uses when no
``vectorization_mode`` is given. It returns an ``AsyncVectorEnv`` whose workers are started
with ``spawn`` (a forked worker would inherit the parent's Blender and open3d threads).
``vectorization_mode="async"`` with ``vector_kwargs`` gives the same with other options.
"""

from __future__ import annotations

from functools import partial

import gymnasium as gym

from ..checks import check_integer
from . import EXPLORATION_ID
from .exploration import check_keywords

MAKE_ARGS = ("max_episode_steps", "disable_env_checker")  # gymnasium.make's own keywords


def make_async(num_envs: int = 1, **kwargs) -> gym.vector.AsyncVectorEnv:
    """``num_envs`` environments of ``kwargs`` (the environment's keywords, and
    ``gymnasium.make``'s ``max_episode_steps``), one process each, started with ``spawn``.
    The keywords are checked first (:func:`.exploration.check_keywords`), before any environment
    or worker is made; ``AsyncVectorEnv`` then builds one environment here to read its spaces
    (no scene is loaded until ``reset()``)."""
    check_integer("num_envs", num_envs, 1)
    check_keywords(**{k: v for k, v in kwargs.items() if k not in MAKE_ARGS})  # bad keywords fail here, in one line
    make_one = partial(gym.make, f"generator.envs:{EXPLORATION_ID}", **kwargs)
    return gym.vector.AsyncVectorEnv([make_one] * num_envs, context="spawn")

"""Gymnasium environments on the Simulator (``import generator.envs`` registers them).

``gymnasium.make("buildee/Exploration-v0", seeds=[0], cache_dir="/tmp/sites")``, or with the
module named in the id, ``gymnasium.make("generator.envs:buildee/Exploration-v0", ...)``,
which also works in the workers of ``gymnasium.vector.AsyncVectorEnv``.
``gymnasium.make_vec("buildee/Exploration-v0", num_envs=N, ...)`` runs each environment in
its own process (:mod:`.vector`). Importing this package does not import Blender; creating
an environment does. See docs/envs.md.
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

EXPLORATION_ID = "buildee/Exploration-v0"

if EXPLORATION_ID not in registry:
    register(id=EXPLORATION_ID, entry_point="generator.envs.exploration:make_env",
             vector_entry_point="generator.envs.vector:make_async")

__all__ = ["EXPLORATION_ID"]

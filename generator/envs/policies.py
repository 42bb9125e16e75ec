"""Baseline policies for ``buildee/Exploration-v0`` with discrete actions (bpy-free).

Each policy is called as ``action = policy(observation, info)`` and draws from its own
``numpy.random.Generator``, so a run is reproducible from its seed.

- :class:`RandomWalk`: the paper's random walk, one of the five actions uniformly.
- :class:`ModifiedRandomWalk`: the paper's modified random walk as a policy: forward every
  step; after a refused forward move it turns towards a heading drawn uniformly in
  [-180, 180) degrees (rounded to whole turns of the environment's ``angle``), one turn
  action per step, then goes forward again. The paper's walk (trajectories/walks.py) makes
  all its turns inside the blocked step; through an environment each turn costs a step.
"""

from __future__ import annotations

import numpy as np

from ..checks import check_number

FORWARD, LEFT, RIGHT, TURN_LEFT, TURN_RIGHT = range(5)


class RandomWalk:
    def __init__(self, seed: int = 0):
        self.rng = np.random.default_rng(seed)

    def __call__(self, observation, info) -> int:
        return int(self.rng.integers(5))


class ModifiedRandomWalk:
    def __init__(self, angle: float = 22.5, seed: int = 0):
        self.angle = check_number("angle", angle, 0, 180, open_low=True, valid="a number of degrees in (0, 180]")
        self.rng = np.random.default_rng(seed)
        self.turns_left = 0  # turn actions still to take (negative: to the left)
        self.last = None

    def __call__(self, observation, info) -> int:
        if self.last == FORWARD and info.get("collided", False):
            # a heading that rounds to the blocked one would collide again: draw again (the
            # paper's walk redraws after each refused try), so every turn count is as likely
            self.turns_left = 0
            while self.turns_left == 0:
                self.turns_left = int(round(self.rng.uniform(-180.0, 180.0) / self.angle))
        if self.turns_left:
            step = 1 if self.turns_left > 0 else -1
            self.turns_left -= step
            self.last = TURN_RIGHT if step > 0 else TURN_LEFT
        else:
            self.last = FORWARD
        return self.last

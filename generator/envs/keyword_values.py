"""The values of ``ExplorationEnv``'s keywords, checked (bpy-free): each function returns the
value as the environment keeps it or raises a one-line ValueError naming the keyword
(generator/envs/exploration.py ``check_keywords`` calls them)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..checks import check_seed, items
from ..render_settings import check_side

MAX_RESOLUTION = 4096  # pixels, width and height of the observations


def lidar_sensor(value):
    """None, or the LiDAR named ``value`` (generator/lidar/sensors.py)."""
    if value is None:
        return None
    from ..lidar.sensors import lidar

    if not isinstance(value, str):
        raise ValueError(f"lidar must be None or a LiDAR's name (e.g. 'vlp16'), got {value!r}")
    return lidar(value)


def choice(name: str, value, choices) -> str:
    """``value`` if it is one of ``choices``; a one-line ValueError otherwise."""
    if value not in choices:
        raise ValueError(f"{name} must be one of {', '.join(repr(c) for c in choices)}, got {value!r}")
    return value


def flag(name: str, value) -> bool:
    """``value`` as a bool if it is one; a one-line ValueError otherwise."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False, got {value!r}")
    return bool(value)


def resolution(value) -> tuple[int, int]:
    """(width, height) in pixels, each 1..MAX_RESOLUTION; a one-line ValueError otherwise."""
    try:
        w, h = value
    except (TypeError, ValueError):
        raise ValueError(f"resolution must be (width, height) in pixels, got {value!r}") from None
    return check_side("resolution width", w, MAX_RESOLUTION), check_side("resolution height", h, MAX_RESOLUTION)


def sources(seeds, blend_files) -> list[tuple[str, object]]:
    """The scenes: ("seed", seed) per seed, then ("blend", path) per .blend file; one-line
    errors for anything else, or for none."""
    lists = [items(value) for value in (seeds, blend_files)]
    for value, listed in zip((seeds, blend_files), lists):
        if listed is None:
            raise ValueError("seeds and blend_files must be lists (e.g. seeds=[0], blend_files=['site.blend']), "
                             f"got {value!r}")
    seeds, blend_files = lists
    out: list[tuple[str, object]] = []
    for i, s in enumerate(seeds):
        out.append(("seed", check_seed(f"seeds[{i}]", s)))
    for i, p in enumerate(blend_files):
        if not isinstance(p, (str, os.PathLike)):
            raise ValueError(f"blend_files[{i}] must be a path (str or os.PathLike), got {p!r}")
        if not Path(p).is_file():
            raise FileNotFoundError(f"blend_files: {p} is not a file; pass paths of existing .blend files")
        out.append(("blend", Path(p)))
    if not out:
        raise ValueError("no scenes: pass seeds=[...] (procedural sites) and/or blend_files=[...]")
    return out

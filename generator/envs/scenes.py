"""Scenes of the exploration environment: procedural sites built once and kept on disk, or
.blend files, each with the camera's start pose and the box it must stay in.

A procedural site of ``(preset, seed)`` is built by :func:`generator.scene.build_site`
(without preview) into ``cache_dir/<preset>_seed<seed>/`` the first time any process asks
for it; a lock file keeps two processes (e.g. the workers of an ``AsyncVectorEnv``) from
building it twice, and the folder appears only complete (built under a temporary name,
then renamed). ``scene.json`` beside ``site.blend`` holds the start pose and the bounds
(the site's camera spawn volume), so later episodes need no planning.
"""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

SCENE_FILE = "scene.json"  # written next to a cached site.blend; read by load_site_scene
SCENE_FORMAT = 1


@dataclass(frozen=True)
class SceneSpec:
    """One scene of the environment: a .blend file, with its start pose (4x4 OpenCV
    world_from_camera; None: the camera stored in the file) and the axis-aligned box
    ``bounds = (lo, hi)`` (world metres) the camera must stay inside (None: no box, only
    the scene's geometry stops the camera)."""

    name: str
    blend: Path
    start: np.ndarray | None = None
    bounds: tuple[np.ndarray, np.ndarray] | None = None
    seed: int = 0  # seeds the Simulator's surface points

    def inside(self, position) -> bool:
        if self.bounds is None:
            return True
        p = np.asarray(position, dtype=np.float64)
        return bool(np.all(p >= self.bounds[0]) and np.all(p <= self.bounds[1]))


def default_cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "buildee" / "sites"


def blend_scene(path: str | os.PathLike) -> SceneSpec:
    """A .blend file as a scene: the file's camera is the start pose, no bounds."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"blend_files: {p} is not a file; pass paths of existing .blend files")
    return SceneSpec(name=str(p), blend=p)


def site_scene(seed: int, preset: str, cache_dir: str | os.PathLike) -> SceneSpec:
    """The procedural site of ``seed`` (built and cached on first use; imports bpy then)."""
    folder = Path(cache_dir) / f"{preset}_seed{seed}"
    if not (folder / SCENE_FILE).is_file():
        _build_locked(seed, preset, folder)
    return load_site_scene(folder)


def load_site_scene(folder: Path) -> SceneSpec:
    """Read a cached site's ``scene.json`` (written by :func:`_build_locked`)."""
    path = folder / SCENE_FILE
    try:
        meta = json.loads(path.read_text())
        if meta.get("format") != SCENE_FORMAT:
            raise ValueError(f"format {meta.get('format')!r}, expected {SCENE_FORMAT}")
        start = np.array(meta["start"], dtype=np.float64).reshape(4, 4)
        lo, hi = (np.array(v, dtype=np.float64).reshape(3) for v in meta["bounds"])
        seed = int(meta["seed"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{path} is not a usable cached scene ({exc}); delete {folder} to rebuild it") from None
    return SceneSpec(name=f"{meta['preset']}_seed{seed}", blend=folder / "site.blend", start=start, bounds=(lo, hi),
                     seed=seed)


def _build_locked(seed: int, preset: str, folder: Path) -> None:
    folder.parent.mkdir(parents=True, exist_ok=True)
    with open(folder.parent / f".{folder.name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if (folder / SCENE_FILE).is_file():
            return  # another process built it while we waited
        tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}-", dir=folder.parent))
        try:
            _build(seed, preset, tmp)
            if folder.exists():
                shutil.rmtree(folder)  # an incomplete folder left by a killed build
            os.rename(tmp, folder)
        finally:
            if tmp.exists():
                shutil.rmtree(tmp, ignore_errors=True)


def _build(seed: int, preset: str, out: Path) -> None:
    from ..baselines.start_pose import site_start
    from ..scene import build_site, plan_site, site_params

    plan = plan_site(seed, site_params(preset))
    start, (lo, hi) = site_start(plan)
    build_site(seed, preset, out, preview=False)
    meta = {"format": SCENE_FORMAT, "seed": seed, "preset": preset, "start": start.tolist(),
            "bounds": [lo.tolist(), hi.tolist()],
            "start_rule": "level camera at the site's entrance, lowest spawn height, looking in (baselines)",
            "bounds_rule": "the site plan's camera spawn volume"}
    (out / SCENE_FILE).write_text(json.dumps(meta, indent=1))  # last: marks the folder complete

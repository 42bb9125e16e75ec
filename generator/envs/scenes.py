"""Scenes of the exploration environment: procedural sites built once and kept on disk, or
.blend files, each with the camera's start pose and the box it must stay in.

A procedural site of ``(preset, seed)`` is built by :func:`generator.scene.build_site`
(without preview) into the entry ``cache_dir/<preset>_seed<seed>/`` of the site cache
(:mod:`.site_cache`) the first time any process asks for it: one build at a time (a lock
file), the folder appears only complete, its files are checked against their recorded
hashes before every use (a damaged entry is rebuilt, with a warning), and a folder the cache
did not make is never replaced. ``scene.json`` beside ``site.blend`` holds the start pose and
the bounds (the site's camera spawn volume), so later episodes need no planning, and the
:func:`site_code_key` it was built with: an entry built by other code (another version of
the site generator, of Blender or of numpy) is rebuilt in place rather than reused. A
``cache_dir`` inside a generated dataset is refused.
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from exporters.write_guard import WriteRefused, check_not_in_dataset

from .code_key import import_closure
from .site_cache import cached_entry, entry_state

SCENE_FILE = "scene.json"  # written next to a cached site.blend; read by load_site_scene
SCENE_FORMAT = 2
PACKAGE_ROOT = Path(__file__).resolve().parents[1]  # generator/
# the modules that build a site, its start pose and its bounds (relative to generator/): the
# key covers them and every module of the package they import (code_key.import_closure),
# and the versions of the packages that build it
SITE_ENTRIES = ("scene/__init__.py", "blender/build.py", "baselines/start_pose.py", "envs/scenes.py")
SITE_PACKAGES = ("bpy", "numpy")


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


def site_code_key(root: Path = PACKAGE_ROOT) -> str:
    """SHA-256 (hex) of the site generator's source files under ``root`` (path and bytes of
    SITE_ENTRIES and of every module of the package they import) and of the versions of
    SITE_PACKAGES: it changes whenever the code that builds a cached site may have changed."""
    try:
        files = import_closure(root, SITE_ENTRIES)
    except FileNotFoundError as e:
        raise FileNotFoundError(f"site_code_key: {e} (SITE_ENTRIES in {__file__} lists it)") from None
    h = hashlib.sha256()
    for f in files:
        data = f.read_bytes()
        h.update(f"{f.relative_to(root).as_posix()}\0{len(data)}\0".encode())
        h.update(data)
    for name in SITE_PACKAGES:
        h.update(f"{name}=={importlib.metadata.version(name)}\0".encode())
    return h.hexdigest()


def check_cache_dir(value) -> Path:
    """``cache_dir`` as the environment takes it (None: :func:`default_cache_dir`): a folder
    path, not an existing file, and not inside a generated dataset (a seed, a timeline seed,
    one of its stages, a folder being generated); else a one-line ValueError."""
    if value is None:
        value = default_cache_dir()
    if not isinstance(value, (str, os.PathLike)) or not str(value):
        raise ValueError(f"cache_dir must be a folder path (str or os.PathLike) or None, got {value!r}")
    path = Path(value)
    if path.exists() and not path.is_dir():
        raise ValueError(f"cache_dir: {path} exists and is not a folder; pass a folder for the built sites")
    try:
        check_not_in_dataset(path, "cache_dir")
    except WriteRefused as exc:
        raise ValueError(str(exc)) from None
    return path


def site_scene(seed: int, preset: str, cache_dir: str | os.PathLike) -> SceneSpec:
    """The procedural site of ``seed``, from the cache (built on first use, rebuilt when
    :func:`site_code_key` has changed since or its files differ from their recorded hashes;
    imports bpy then). Its files are checked against their hashes at every call. A folder
    the cache did not make raises :class:`.site_cache.ForeignEntry` (a ValueError)."""
    folder = check_cache_dir(cache_dir) / f"{preset}_seed{seed}"
    key = site_code_key()
    cached_entry(folder, lambda entry: _is_current(entry, key), lambda out: _build(seed, preset, out, key))
    return load_site_scene(folder)


def site_is_intact(spec: SceneSpec) -> bool:
    """Whether the cache entry of the site ``spec`` (from :func:`site_scene`) still holds
    exactly the files it recorded, with their hashes (checked before every load of a site
    already in use: cheaper than :func:`site_scene`, which also computes the code key). An
    entry replaced by a folder the cache did not make raises :class:`.site_cache.ForeignEntry`."""
    return entry_state(spec.blend.parent)[0] == "intact"


def _is_current(folder: Path, key: str) -> bool:
    """True if the entry ``folder`` holds a site built by code of ``key``."""
    try:
        meta = json.loads((folder / SCENE_FILE).read_text())
    except (OSError, ValueError):
        return False
    return isinstance(meta, dict) and meta.get("format") == SCENE_FORMAT and meta.get("code_key") == key


def load_site_scene(folder: Path) -> SceneSpec:
    """Read a cached site's ``scene.json`` (written by :func:`_build`)."""
    path = folder / SCENE_FILE
    try:
        meta = json.loads(path.read_text())
        if meta.get("format") != SCENE_FORMAT:
            raise ValueError(f"format {meta.get('format')!r}, expected {SCENE_FORMAT}")
        start = np.array(meta["start"], dtype=np.float64).reshape(4, 4)
        lo, hi = (np.array(v, dtype=np.float64).reshape(3) for v in meta["bounds"])
        seed = int(meta["seed"])
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise ValueError(f"{path} is not a usable cached scene ({exc}); delete {folder} to rebuild it") from None
    return SceneSpec(name=f"{meta['preset']}_seed{seed}", blend=folder / "site.blend", start=start, bounds=(lo, hi),
                     seed=seed)


def _build(seed: int, preset: str, out: Path, key: str) -> None:
    from ..baselines.start_pose import site_start
    from ..scene import build_site

    start, (lo, hi) = site_start(build_site(seed, preset, out, preview=False).plan)
    meta = {"format": SCENE_FORMAT, "code_key": key, "seed": seed, "preset": preset, "start": start.tolist(),
            "bounds": [lo.tolist(), hi.tolist()],
            "start_rule": "level camera at the site's entrance, lowest spawn height, looking in (baselines)",
            "bounds_rule": "the site plan's camera spawn volume"}
    (out / SCENE_FILE).write_text(json.dumps(meta, indent=1))

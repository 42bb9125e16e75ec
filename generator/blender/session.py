"""The one place that owns Blender's global state: importing bpy, loading files, silencing logs.

Blender holds a single open file per process. :func:`open_blend` loads one and bumps a
generation counter so that objects built on an older file can tell they are stale.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

_o3d = sys.modules.get("generator.geometry.o3d")
if "open3d" in sys.modules and "bpy" not in sys.modules and not getattr(_o3d, "bpy_tbb_loaded", False):
    # open3d's libtbb is already loaded and bpy would fail with an undefined TBB symbol (unless
    # generator.geometry.o3d.import_open3d loaded bpy's own libtbb first).
    raise ImportError(
        "open3d was imported before bpy; import generator (or bpy) first, or load open3d "
        "through generator.geometry.o3d.import_open3d()"
    )

_generation = 0
_log_path: Path | None = None
_libc = ctypes.CDLL(None)

BLEND_MAGIC = (b"BLENDER", b"\x28\xb5\x2f\xfd", b"\x1f\x8b")  # plain, zstd, gzip


class BlendFileError(ValueError):
    """A .blend file is missing, unreadable or unusable."""


def log_path() -> Path:
    """File that receives Blender's own log output (per process)."""
    global _log_path
    if _log_path is None:
        env = os.environ.get("BUILDEE_BLENDER_LOG")
        _log_path = Path(env) if env else Path(tempfile.gettempdir()) / f"buildee-blender-{os.getpid()}.log"
    return _log_path


def set_log_path(path: str | os.PathLike) -> None:
    """Send Blender's log output to ``path`` from now on (e.g. a seed's output folder)."""
    global _log_path
    _log_path = Path(path)


@contextlib.contextmanager
def quiet():
    """Redirect the process's stdout and stderr file descriptors to the Blender log file.

    Blender writes its log lines from C straight to fd 1 and 2; Python's own streams are
    flushed first so nothing is lost or reordered.
    """
    sys.stdout.flush()
    sys.stderr.flush()
    _libc.fflush(None)
    saved = os.dup(1), os.dup(2)
    with open(log_path(), "ab") as log:
        os.dup2(log.fileno(), 1)
        os.dup2(log.fileno(), 2)
        try:
            yield
        finally:
            with contextlib.suppress(Exception):
                sys.stdout.flush()
                sys.stderr.flush()
            _libc.fflush(None)  # Blender's C stdio buffers hold log lines too
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])


with quiet():
    import bpy  # noqa: E402  (its colour-management log line goes to the log file)


def generation() -> int:
    """Counter of files loaded in this process."""
    return _generation


def check_blend_file(path: str | os.PathLike) -> Path:
    """``path`` as a Path if it is a file with a .blend header; else BlendFileError."""
    p = Path(path)
    if not p.exists():
        raise BlendFileError(f"blend file not found: {p}")
    if not p.is_file():
        raise BlendFileError(f"blend file path is not a file: {p}")
    with open(p, "rb") as f:
        head = f.read(8)
    if not any(head.startswith(m) for m in BLEND_MAGIC):
        raise BlendFileError(f"not a Blender file (bad header): {p}")
    return p


def objects_in_file(path: str | os.PathLike) -> int | None:
    """How many objects of its own a .blend file holds (not those it links from libraries),
    read from the file's index without loading it: about 1 s for 40,000 objects, which take
    about 10 s to load. None for the file Blender has open (Blender reads no index of it).
    The open file is left as it was. Raises BlendFileError."""
    p = check_blend_file(path)
    if bpy.data.filepath and Path(bpy.data.filepath).resolve() == p.resolve():
        return None
    try:
        with quiet(), bpy.data.libraries.load(str(p.resolve())) as (found, _):
            return len(found.objects)
    except OSError as exc:
        raise BlendFileError(f"Blender could not read {p}: {str(exc).strip().splitlines()[-1]}") from None


def open_blend(path: str | os.PathLike) -> None:
    """Load a .blend file, replacing whatever Blender had open. Raises BlendFileError."""
    global _generation
    p = check_blend_file(path)
    try:
        with quiet():
            bpy.ops.wm.open_mainfile(filepath=str(p.resolve()), load_ui=False)
    except RuntimeError as exc:
        raise BlendFileError(f"Blender could not read {p}: {str(exc).strip().splitlines()[-1]}") from None
    _generation += 1


def new_empty_file() -> None:
    """Reset Blender to an empty file (used to build scenes in code)."""
    global _generation
    with quiet():
        bpy.ops.wm.read_factory_settings(use_empty=True)
    _generation += 1


def save_blend(path: str | os.PathLike, compress: bool = True) -> None:
    """Save the open file to ``path`` (zstd-compressed by default), replacing a file there
    without keeping Blender's ``.blend1`` backup of it."""
    paths = bpy.context.preferences.filepaths
    saved, paths.save_version = paths.save_version, 0
    try:
        with quiet():
            bpy.ops.wm.save_as_mainfile(filepath=str(Path(path).resolve()), compress=compress, copy=True)
    finally:
        paths.save_version = saved


def set_frame(frame: int) -> None:
    """Move the scene to ``frame`` and re-evaluate animation."""
    with quiet():
        bpy.context.scene.frame_set(int(frame))


def make_viewport_match_render() -> None:
    """Make the (viewport) evaluated depsgraph hold exactly what a render would show.

    In background mode Python only gets the viewport depsgraph, so render-visibility and
    render settings are copied onto their viewport counterparts: object and collection
    visibility, whether an instancer shows itself, modifier enablement, subdivision levels,
    particle amounts and display, and simplify settings. Geometry nodes' "Is Viewport" cannot
    be matched: a warning names the node groups that use it (docs/rendering.md).
    """
    scene = bpy.context.scene
    _copy_flag(bpy.data.objects, "hide_render", "hide_viewport")
    _copy_flag(bpy.data.objects, "show_instancer_for_render", "show_instancer_for_viewport")
    for obj in bpy.data.objects:
        for mod in obj.modifiers:
            if mod.show_viewport != mod.show_render:
                mod.show_viewport = mod.show_render
            if hasattr(mod, "render_levels") and hasattr(mod, "levels") and mod.levels != mod.render_levels:
                mod.levels = mod.render_levels
    for settings in bpy.data.particles:
        _particles_as_rendered(settings)
    _copy_flag(bpy.data.collections, "hide_render", "hide_viewport")
    for view_layer in scene.view_layers:
        _show_layer_collections(view_layer)
        for obj in view_layer.objects:
            if obj.hide_get(view_layer=view_layer):  # no bulk way: each call re-syncs the view layer
                obj.hide_set(False, view_layer=view_layer)
    r = scene.render
    r.simplify_subdivision = r.simplify_subdivision_render
    r.simplify_child_particles = r.simplify_child_particles_render
    bpy.context.view_layer.update()
    _warn_unmatched()


def _copy_flag(items, source: str, target: str) -> None:
    """Every item's ``target`` flag set to its ``source`` flag (``items``: a collection of
    Blender's, e.g. ``bpy.data.objects``), in time linear in their number: each assignment of a
    visibility flag re-syncs every collection and object of the file, so the flags are written
    at once (``foreach_set``, which skips that) and the update runs once, by assigning one
    changed item's flag again."""
    want, have = np.zeros(len(items), bool), np.zeros(len(items), bool)
    items.foreach_get(source, want)
    items.foreach_get(target, have)
    changed = np.flatnonzero(want != have)
    if len(changed):
        items.foreach_set(target, want)
        setattr(items[int(changed[0])], target, bool(want[changed[0]]))


def _show_layer_collections(view_layer) -> None:
    """Clear the viewport hide flag of every layer collection of ``view_layer``, in bulk
    (as :func:`_copy_flag`: each assignment re-syncs the view layer)."""
    root = view_layer.layer_collection
    if root.hide_viewport:
        root.hide_viewport = False
    changed, stack = [], [root]
    while stack:
        children = stack.pop().children
        hidden = np.zeros(len(children), bool)
        children.foreach_get("hide_viewport", hidden)
        if hidden.any():
            children.foreach_set("hide_viewport", np.zeros(len(children), bool))
            changed.append(children[int(np.flatnonzero(hidden)[0])])
        stack.extend(children)
    if changed:
        changed[0].hide_viewport = False  # the update, once


def _particles_as_rendered(settings) -> None:
    """Viewport particles as the render makes them: every particle, the render's children
    and path steps, drawn as rendered (a 'DOT' or 'NONE' display instances nothing)."""
    settings.display_percentage = 100
    settings.display_method = "RENDER"
    settings.child_percent = settings.rendered_child_count
    settings.display_step = settings.render_step


def _warn_unmatched() -> None:
    """Warn about what a render shows that the ground truth cannot match (docs/rendering.md)."""
    groups = sorted(g.name for g in bpy.data.node_groups
                    if any(n.bl_idname == "GeometryNodeIsViewport" for n in getattr(g, "nodes", ())))
    if groups:
        warnings.warn(f"geometry node group(s) {', '.join(map(repr, groups))} use 'Is Viewport': the ground truth "
                      "takes its viewport branch, the render its render branch (docs/rendering.md)", stacklevel=3)
    strands = sorted(o.name for o in bpy.data.objects if not o.hide_render and any(
        m.type == "PARTICLE_SYSTEM" and m.show_render and m.particle_system.settings.render_type == "PATH"
        for m in o.modifiers))
    if strands:
        warnings.warn(f"{', '.join(map(repr, strands))} render(s) particle strands (render type Path), which have no "
                      "triangles: the ground truth lacks them (docs/rendering.md)", stacklevel=3)

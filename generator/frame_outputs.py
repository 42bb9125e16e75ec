"""Every modality of the current view, by name (exporters/modalities.py), from the Simulator's
public API: one Blender render for the ``render`` modalities (with their passes), one pixel-centre ray cast
(``render(engine="raycast")``) for the ``geometry`` ones (normals, optical flow, ...), which
the render's depth, labels and ids share (generator/geometry/pixel_truth.py)."""

from __future__ import annotations

import contextlib

import numpy as np

from exporters.modalities import MODALITIES, resolve

from .checks import check_integer
from .geometry.pixels import PixelGeometry
from .passes import RenderOutput


def dynamic_slots(object_names: list[str], dynamic_objects: list[str]) -> np.ndarray:
    """(P,) int64: each object's index into ``dynamic_objects`` (-1 for static objects)."""
    where = {name: k for k, name in enumerate(dynamic_objects)}
    return np.array([where.get(n, -1) for n in object_names], np.int64)


def pixel_geometry(sim, poses: np.ndarray | None = None, object_matrices: np.ndarray | None = None,
                   index: int = 0) -> PixelGeometry:
    """The surface at every pixel centre of the current view, with the trajectory's motion:
    ``poses`` (T, 4, 4) and ``object_matrices`` (T, D, 4, 4) of ``sim.dynamic_objects`` at
    every frame (default: the current pose and matrices only, T = 1); the current view is
    frame ``index`` of them."""
    if poses is None:
        poses, object_matrices, index = sim.get_world_from_camera()[None], sim.dynamic_object_matrices()[None], 0
    poses, object_matrices, index = check_trajectory(poses, object_matrices, index, len(sim.dynamic_objects))
    if not np.allclose(poses[index], sim.get_world_from_camera(), atol=1e-9):
        raise ValueError(f"poses[{index}] is not the Simulator's current pose")
    if sim.readout_s > 0:  # a rolling shutter: each row at its own time (generator/geometry/rolling.py)
        hits, camera, row_poses, row_objects, _ = sim.rolling_geometry(poses, object_matrices, index)
        return PixelGeometry(sim.K, sim.width, sim.height, index, poses, hits.depth, hits.part, hits.normal,
                             dynamic_slots(sim.object_names, sim.dynamic_objects), object_matrices, sim.lens,
                             rolling=(camera, row_poses, row_objects))
    g = sim.render_geometry(normals=True)
    return PixelGeometry(sim.K, sim.width, sim.height, index, poses, g.depth, g.instance, g.normal,
                         dynamic_slots(sim.object_names, sim.dynamic_objects), object_matrices, sim.lens)


def check_trajectory(poses, object_matrices, index, dynamic: int) -> tuple[np.ndarray, np.ndarray, int]:
    """``poses`` (T, 4, 4), ``object_matrices`` (T, D, 4, 4) for ``dynamic`` = D moving objects
    (None allowed when D = 0) and ``index`` in [0, T) as float64 arrays and an int; else a
    one-line ValueError."""
    def array(name, value, shape):
        try:
            a = np.asarray(value, np.float64)
        except (TypeError, ValueError):
            a = None
        if a is None or a.ndim != len(shape) or any(w is not None and n != w for n, w in zip(a.shape, shape)):
            words = " x ".join("T" if w is None else str(w) for w in shape)
            got = "None" if value is None else f"shape {a.shape}" if a is not None else repr(value)[:60]
            raise ValueError(f"{name} must be a ({words}) array (T frames), got {got}")
        return a

    poses = array("poses", poses, (None, 4, 4))
    if object_matrices is None and dynamic == 0:
        object_matrices = np.zeros((len(poses), 0, 4, 4))  # nothing moves: no matrices to give
    matrices = array("object_matrices", object_matrices, (len(poses), dynamic, 4, 4))
    return poses, matrices, check_integer("index", index, 0, len(poses) - 1)


def render_outputs(sim, names=None, poses=None, object_matrices=None, index: int = 0) -> RenderOutput:
    """A :class:`RenderOutput` holding the modalities ``names`` (default: all registered) of
    the current view; Blender renders only if a ``render`` modality is asked for, with the
    passes of those asked for (and of the ones every render holds)."""
    names = resolve(names)
    if poses is not None:
        poses, object_matrices, index = check_trajectory(poses, object_matrices, index, len(sim.dynamic_objects))
    computed = [n for n in names if MODALITIES[n].source == "geometry"]
    rendered = [n for n in names if MODALITIES[n].source == "render"]
    if sim.readout_s > 0 and (poses is None or len(poses) < 2):
        raise ValueError("a rolling shutter renders views along a trajectory: give poses and object_matrices of at "
                         "least two frames")
    if sim.readout_s > 0 and rendered and not computed:
        sim.rolling_geometry(poses, object_matrices, index, normals=False)  # the render's depth, labels, ids
    # one pixel-centre cast for the render's depth, labels and ids and the geometry modalities:
    # with a global shutter it runs beside Blender's render (with normals when a geometry
    # modality needs them) and the geometry reuses it; a rolling shutter's rows are cast
    # first and the render reuses them
    rows_first = sim.readout_s > 0 or not rendered
    g = pixel_geometry(sim, poses, object_matrices, index) if computed and rows_first else None
    if rendered:
        moving = sim.camera_motion(poses, index) if poses is not None else contextlib.nullcontext()
        with moving:  # the camera moves along the trajectory while the shutter is open
            out = sim.render(outputs=rendered, normals=bool(computed) and not rows_first)
    else:
        out = RenderOutput(None, None, None, None, None, sim.K.copy(), sim.get_world_from_camera(), sim.frame)
    if computed and g is None:
        g = pixel_geometry(sim, poses, object_matrices, index)
    out.extra.update({n: MODALITIES[n].compute(g) for n in computed})
    return out

"""The trajectory loop: render every frame and hand it to every export (exporters/sinks.py).

``fly`` only orchestrates: it builds the :class:`~exporters.sinks.TrajectoryContext`, makes
one sink per registered export (every ``@register_sink`` of exporters/: frames, tracks,
COLMAP, nerfstudio, COCO, 3D boxes, coverage, previews, map, and whatever else registers
itself), hands each sink every :class:`FrameRecord`, and closes them. What each file holds
is the sink's business; the values of the exports' own options reach them in
``TrajectoryContext.options``."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .overlap import SinkThread


def object_matrices_over(sim, frames: int) -> np.ndarray:
    """(T, D, 4, 4) world_from_object of the dynamic objects at trajectory frames 0..T-1
    (animation frames 1..T); the Simulator is left at animation frame 1."""
    out = []
    for i in range(frames):
        sim.set_frame(1 + i)
        out.append(sim.dynamic_object_matrices())
    sim.set_frame(1)
    return np.stack(out) if out else np.zeros((0, 0, 4, 4))


def rolling_camera(sim, poses: np.ndarray, matrices: np.ndarray):
    """The trajectory's rows and motion through the Simulator's rolling shutter (frame k at
    k / fps seconds, as ``Simulator.rolling_geometry`` takes them), None without one."""
    if sim.readout_s == 0:
        return None
    from ..geometry.rolling import RollingCamera, RollingShutter

    return RollingCamera(RollingShutter(sim.readout_s, sim.height), np.arange(len(poses)) / sim.fps, poses, matrices)


def scene_bounds(parts, object_matrices: np.ndarray, dynamic_objects: list[str]) -> np.ndarray:
    """(2, 3) world bounds of every part at every frame (dynamic parts moved)."""
    slot = {name: k for k, name in enumerate(dynamic_objects)}
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for p in parts:
        if len(p.vertices) == 0:
            continue
        if p.dynamic:
            box = np.array([p.vertices.min(0), p.vertices.max(0)])
            corners = np.array([[x, y, z] for x in box[:, 0] for y in box[:, 1] for z in box[:, 2]])
            m = object_matrices[:, slot[p.name]]
            v = np.einsum("tij,cj->tci", m[:, :3, :3], corners) + m[:, None, :3, 3]
            lo, hi = np.minimum(lo, v.reshape(-1, 3).min(0)), np.maximum(hi, v.reshape(-1, 3).max(0))
        else:
            lo, hi = np.minimum(lo, p.vertices.min(0)), np.maximum(hi, p.vertices.max(0))
    return np.array([lo, hi])


def fly(sim, traj, out: Path, seed: int, plan=None, exports: dict | None = None, outputs=None,
        on_frame=None, overlap: bool | None = None) -> tuple[list[float], int]:
    """Render every frame of ``traj`` with the modalities ``outputs`` (default: all) and hand
    them to every registered sink, writing into ``out``; then ``trajectory.npz``. ``exports``:
    values of the exports' options (RunConfig.exports; the others at their defaults).
    ``on_frame()`` is called after each frame (progress). ``overlap``: the sinks write frame t
    in a thread of their own while frame t + 1 renders (generator/batch/overlap.py; False:
    in this thread, between renders; the same bytes either way; default: when Cycles renders
    on a GPU, whose CPU cores would otherwise wait, not when it renders on every CPU core).
    Returns
    (coverage per frame, visible point observations)."""
    from exporters.modalities import resolve
    from exporters.sinks import FrameRecord, TrajectoryContext, load_sinks

    from .config import export_values

    names = resolve(outputs or None)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    T = len(traj)
    matrices = object_matrices_over(sim, T)
    parts = sim.scene_parts()
    context = TrajectoryContext(
        folder=out, kind=out.name, seed=seed, K=sim.K.copy(), width=sim.width, height=sim.height,
        poses=np.asarray(traj.poses), timestamps=np.asarray(traj.timestamps), labels=list(sim.labels),
        instances=sim.instance_table, parts=parts, dynamic_objects=sim.dynamic_objects, point_table=sim.point_table(),
        modalities=names, object_matrices=matrices,
        options=export_values(exports or {}) | {"plan": plan, "ground_truth": sim.ground_truth,
                                                "segmentation_sensitivity": float(sim.segmentation_sensitivity),
                                                "shutter_s": float(sim.shutter_s), "readout_s": float(sim.readout_s)},
        clip=(float(sim.clip_start), float(sim.clip_end)),
        scene_bounds=scene_bounds(parts, matrices, sim.dynamic_objects), lens=sim.lens, image_sensor=sim.image_sensor,
        rolling=rolling_camera(sim, np.asarray(traj.poses), matrices))
    if overlap is None:
        overlap = sim.render_device != "CPU"
    sinks = SinkThread([factory(context) for factory in load_sinks().values()], threaded=overlap)
    sim.reset_observations()
    coverage, tracks = [], 0
    try:
        for i, pose in enumerate(context.poses):
            sim.set_frame(1 + i)
            sim.set_world_from_camera(pose, check_collisions=False)
            r = sim.render_outputs(names, context.poses, matrices, i)
            sim.compute_point_cloud()  # coverage: points seen within the Simulator's max_pcl_depth
            # tracks and COLMAP observations: every point the image shows, at any depth
            points, _, visible = sim.compute_point_cloud(update_mask=False, max_depth=math.inf)
            sinks.put(FrameRecord(i, float(context.timestamps[i]), pose, {n: r.outputs[n] for n in names}, points,
                                  visible, sim.dynamic_object_matrices(), sim.coverage, r.exposure_gain))
            coverage.append(sim.coverage)
            tracks += int(visible.sum())
            if on_frame is not None:
                on_frame()
    except BaseException:
        sinks.abandon()
        raise
    sinks.close()
    traj.save(out / "trajectory.npz")
    return coverage, tracks


def fly_scene(sim, trajectories, folder: Path, seed: int, plan, cfg, on_frame=None) -> tuple[dict, int]:
    """Fly each ``(kind, trajectory)`` of ``trajectories`` into ``folder/kind`` (all planned
    before the first is flown: config.plan_trajectories), then write the scene's ground truth and
    ``labels.json`` into ``folder``. Returns ({kind: {"frames", "final_coverage"}}, visible
    point observations)."""
    import json

    from exporters.ground_truth import write_simulator_ground_truth

    per_kind, tracks = {}, 0
    for kind, traj in trajectories:
        coverage, visible = fly(sim, traj, Path(folder) / kind, seed, plan, cfg.exports, cfg.outputs,
                                on_frame=on_frame)
        tracks += visible
        per_kind[kind] = {"frames": len(traj), "final_coverage": coverage[-1]}
    write_simulator_ground_truth(sim, Path(folder) / "ground_truth", seed, cfg.scoring_density)
    (Path(folder) / "labels.json").write_text(json.dumps(sim.labels))
    return per_kind, tracks

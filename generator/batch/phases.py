"""One seed as a timeline of K stages (``python -m generator --phases K``; docs/phases.md).

Called by the worker for ``phases`` > 1, in the seed's process, into the seed's partial
folder (the runner commits it whole with one manifest, as any seed):

    seed_N/phase_0 .. phase_{K-1}/   each a complete seed folder's content (scene/, ground_truth/,
                                     labels.json, one folder per trajectory)
    seed_N/changes.h5                instances, points and pixels that changed (exporters/changes.py)
    seed_N/changes.png               the stages side by side and the change clouds (preview)

Every stage is flown along the same trajectories: they are planned once, against the
geometry of all stages at once (a move is allowed only if it is free in every stage), so
the poses of frame t are identical in every stage.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

def phase_folder(folder: Path, k: int) -> Path:
    return Path(folder) / f"phase_{k}"


class AllStages:
    """A MotionChecker (trajectories.base) that allows a move only if it is free in every
    stage's geometry (spheres of ``radius`` metres, the Simulator's rules)."""

    def __init__(self, geometries: list, radius: float):
        self.geometries, self.radius = geometries, radius

    def is_free(self, position) -> bool:
        from ..geometry.collision import position_is_free

        return all(position_is_free(g, np.asarray(position, np.float64), self.radius) for g in self.geometries)

    def can_move(self, start, end) -> bool:
        from ..geometry.collision import segment_is_free

        a, b = np.asarray(start, np.float64), np.asarray(end, np.float64)
        return all(segment_is_free(g, a, b, self.radius) for g in self.geometries)


def run_phases(cfg, seed: int, folder: Path, emit, executor: str = "") -> dict:
    """Generate the K stages of ``seed`` into ``folder`` and its changes; manifest last
    (``executor``: the name of the executor running it, for the manifest's timing)."""
    from exporters import FORMAT_VERSION
    from exporters.manifest import write_manifest

    from .. import Simulator
    from ..blender import session
    from ..geometry.raycast import SceneGeometry
    from ..scene import build_site
    from .config import check_point_budget, run_timing
    from .fly import fly_scene

    t0 = time.perf_counter()
    K, anim = cfg.phases, max(250, cfg.frames)

    def simulator(blend, instance_names=None):
        return Simulator(blend, points_density=cfg.points_density, seed=seed, max_pcl_depth=cfg.max_depth,
                         render_preset=cfg.render_preset, instance_names=instance_names)

    blends, plans, geometries, names = [], [], [], set()
    for k in range(K):  # build every stage; keep its geometry for planning the trajectories
        site = build_site(seed, cfg.scene_preset, phase_folder(folder, k) / "scene", frames=anim, stage=k, stages=K,
                          **cfg.site_overrides())
        blends.append(site.blend)
        plans.append(site.plan)
        sim = simulator(site.blend)
        check_point_budget(cfg, sim.num_points)
        geometries.append(SceneGeometry(sim.scene_parts()))
        names.update(sim.object_names)
        if k == 0:
            spawn, start, radius = sim.spawn_points, sim.respawn_camera(), sim.collision_radius
    checker = AllStages(geometries, radius)
    free = spawn[[checker.is_free(p) for p in spawn]]
    if len(free) == 0:
        raise RuntimeError(f"seed {seed}: no camera spawn point is free in all {K} stages")
    if not checker.is_free(start[:3, 3]):
        start = start.copy()
        start[:3, 3] = free[0]
    trajectories = {kind: _plan(kind, checker, free, start, seed, cfg.frames) for kind in cfg.trajectories}
    emit(event="start", frames=K * cfg.frames * len(cfg.trajectories), points=0)

    table = sorted(names)  # every stage's objects (the order Simulator gives one scene's objects)
    summary: dict = {"phases": K, "trajectories": {}, "stages": []}
    tracks = 0
    for k in range(K):
        out = phase_folder(folder, k)
        sim = simulator(blends[k], table)  # one object table: an object's instance id is the same in every stage
        sim.configure_render(resolution=cfg.resolution, device=cfg.device)
        sim.set_lens(cfg.camera_model, cfg.lens().coefficients)
        sim.image_sensor = cfg.image_sensor()  # exposure, noise, JPEG of the display colour
        sim.set_shutter(cfg.shutter_s, cfg.readout_s)  # motion blur, rolling shutter (0: none)
        per_kind, visible = fly_scene(sim, trajectories.items(), out, seed, plans[k], cfg, lambda: emit(event="frame"))
        tracks += visible
        stage = {"points": sim.num_points, "trajectories": per_kind}
        summary["stages"].append(stage)
        summary["render_device"] = sim.render_device
    summary["trajectories"] = {kind: {"frames": len(t)} for kind, t in trajectories.items()}
    summary["changes"] = write_timeline_changes(folder, K, list(cfg.trajectories))
    from .scan_changes import label_scan_changes

    summary["changes"]["scans_labelled"] = label_scan_changes(folder, [phase_folder(folder, k) for k in range(K)],
                                                              list(cfg.trajectories))
    from exporters.phase_previews import timeline_preview

    timeline_preview(folder, K, cfg.trajectories[0])
    summary |= {"frames": K * cfg.frames * len(cfg.trajectories), "points": summary["stages"][0]["points"],
                "visible_tracks": tracks}
    versions = {"buildee-sites": _version(), "bpy": session.bpy.app.version_string, "numpy": np.__version__}
    write_manifest(folder, {"format_version": FORMAT_VERSION, "seed": seed, "config": cfg.to_dict(), "versions": versions,
                            "summary": summary, "timing": run_timing(t0, executor)})
    return summary


def _plan(kind, checker, spawn, start, seed, frames):
    from .config import plan_trajectory

    return plan_trajectory(kind, checker, spawn, start, seed, frames, 10.0)


def write_timeline_changes(folder: Path, stages: int, kinds: list[str]) -> dict:
    """Compute and write ``folder/changes.h5`` from the stages' folders (bpy-free); returns
    counts per pair for the manifest's summary."""
    from exporters.changes import STATUS, ChangePair, write_changes
    from exporters.frames import FrameReader
    from exporters.ground_truth import read_ground_truth

    from ..scene import changes as ch

    gts = [read_ground_truth(phase_folder(folder, k)) for k in range(stages)]
    # the stages share one object table (run_phases); an object a stage lacks is an empty part there
    present = [[i for i, p in enumerate(gt.parts) if len(p.faces)] for gt in gts]
    names, tables = ch.union_table([[p.name for p in gt.parts] for gt in gts])
    labels = gts[0].labels
    by_name = {p.name: labels.index(p.label) for gt in gts for p in gt.parts}
    clouds = [gt.scoring_points() for gt in gts]
    pairs, counts = [], []
    for k in range(1, stages):
        a, b = gts[k - 1], gts[k]
        ia, ib = present[k - 1], present[k]
        status, transform = ch.classify_instances([a.parts[i] for i in ia], [b.parts[i] for i in ib],
                                                  tables[k - 1][ia], tables[k][ib], len(names))
        ca, cb = clouds[k - 1], clouds[k]
        same = status == STATUS.index("unchanged")
        d_added = ch.stage_distance(cb.points, same[tables[k][cb.vertex["instance"]]], a.parts)
        d_removed = ch.stage_distance(ca.points, same[tables[k - 1][ca.vertex["instance"]]], b.parts)
        masks = {}
        for kind in kinds:
            ra, rb = FrameReader(phase_folder(folder, k - 1) / kind), FrameReader(phase_folder(folder, k) / kind)
            frames = []
            for i in range(ra.frames):
                fa, fb = ra.read(i, ["depth", "instance"]), rb.read(i, ["depth", "instance"])
                frames.append(ch.frame_change_mask(fa["depth"], ch.to_union(fa["instance"], tables[k - 1]),
                                                   fb["depth"], ch.to_union(fb["instance"], tables[k])))
            masks[kind] = np.stack(frames)
        pair = ChangePair(k, status, transform, d_added > ch.POINT_TOLERANCE, d_added,
                          d_removed > ch.POINT_TOLERANCE, d_removed, masks)
        pairs.append(pair)
        counts.append({"stages": [k - 1, k], "instances": {s: int((status == i).sum()) for i, s in enumerate(STATUS)},
                       "points_added": int(pair.points_added.sum()), "points_removed": int(pair.points_removed.sum()),
                       "changed_pixels": {kind: float(m.mean()) for kind, m in masks.items()}})
    parameters = {"point_tolerance_m": ch.POINT_TOLERANCE, "depth_tolerance_m": ch.DEPTH_TOLERANCE,
                  "rigid_tolerance_m": ch.RIGID_TOLERANCE, "trajectories": kinds,
                  "point_rule": "added: distance from a stage-k point to the stage k-1 surface > point_tolerance_m; "
                                "removed: from a stage k-1 point to the stage-k surface",
                  "pixel_rule": "changed: union instance differs, or one stage sees a surface and the other none, "
                                "or |depth_k - depth_k-1| > depth_tolerance_m"}
    write_changes(folder / "changes.h5", labels=labels, names=names, instance_labels=[by_name[n] for n in names],
                  stage_tables=tables, pairs=pairs, parameters=parameters)
    return {"pairs": counts}


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("buildee-sites")
    except PackageNotFoundError:
        return "unknown"

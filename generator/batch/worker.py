"""One seed of the batch job, in its own process: ``python -m generator.batch.worker
CONFIG_JSON SEED FOLDER``. Builds the site, flies each trajectory rendering every frame,
writes everything into FOLDER and finally its manifest. Progress goes to stdout as lines
``@@{json}``; Blender's log goes to FOLDER/blender.log."""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path


def emit(**event) -> None:
    print("@@" + json.dumps(event), flush=True)


PREVIEW_FRAMES = 6  # rows of each trajectory's contact sheet


def fly(sim, traj, out: Path, seed: int, plan=None, colmap_text: bool = False) -> tuple[list[float], int]:
    """Render and track every frame of ``traj`` into ``out``: frames (EXR + PNG + depth PNG),
    tracks.h5, trajectory.npz, sparse/0 (COLMAP), transforms.json, coverage.json and the
    previews (contact_sheet.png; map.png when the site ``plan`` is given). Returns
    (coverage per frame, visible point observations)."""
    import numpy as np

    from exporters.colmap import write_colmap_model
    from exporters.frames import FrameWriter, frame_names
    from exporters.nerfstudio import depth_png_name, write_depth_png, write_transforms
    from exporters.previews import contact_sheet
    from exporters.tracks import TrackWriter

    writer = FrameWriter(out, sim.labels)
    sim.reset_observations()
    coverage: list[float] = []
    tracks = 0
    static = ~sim.dynamic_points_mask
    observations = []  # per frame: visible static point indices and their pixel positions
    colors = np.zeros((sim.num_points, 3), dtype=np.uint8)
    coloured = np.zeros(sim.num_points, dtype=bool)
    tracks_out = TrackWriter(out / "tracks.h5", sim.point_table(), sim.dynamic_objects, sim.labels, sim.K,
                             sim.width, sim.height, seed=seed)
    sheet_frames = set(np.linspace(0, len(traj) - 1, min(PREVIEW_FRAMES, len(traj))).round().astype(int).tolist())
    sheet = []
    for i, pose in enumerate(traj.poses):
        sim.set_frame(1 + i)
        sim.set_world_from_camera(pose, check_collisions=False)
        r = sim.render()
        points, _, visible = sim.compute_point_cloud()
        writer.write(i, r.rgb, r.depth, r.seg, r.instance)
        write_depth_png(out / depth_png_name(i), r.depth)
        if i in sheet_frames:
            sheet.append({"index": i, "rgb": r.rgb, "depth": r.depth, "label": r.seg})
        tracks_out.add_frame(float(traj.timestamps[i]), pose, points, visible, sim.dynamic_object_matrices(), sim.coverage)
        seen = np.flatnonzero(visible & static)
        uv, _ = sim.project(points[seen])
        observations.append((seen, uv))
        new = ~coloured[seen]
        rgb8 = (np.clip(r.rgb, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)  # the PNG's pixels
        px = np.minimum(np.floor(uv[new]).astype(int), [sim.width - 1, sim.height - 1])
        colors[seen[new]] = rgb8[px[:, 1], px[:, 0]]
        coloured[seen[new]] = True
        coverage.append(sim.coverage)
        tracks += int(visible.sum())
        emit(event="frame")
    tracks_out.close()
    traj.save(out / "trajectory.npz")
    names = [frame_names(i)[1] for i in range(len(traj))]
    # static points never move, so the last frame's positions are theirs
    write_colmap_model(out / "sparse" / "0", sim.K, sim.width, sim.height, traj.poses, names, observations, points,
                       colors, text=colmap_text)
    write_transforms(out / "transforms.json", sim.K, sim.width, sim.height, traj.poses, names,
                     [depth_png_name(i) for i in range(len(traj))], traj.timestamps)
    (out / "coverage.json").write_text(json.dumps({
        "coverage": coverage, "units": "share of surface points observed at least once, after each frame (0..1)",
        "auc": float(np.trapezoid(coverage, np.linspace(0, 1, len(coverage)))) if len(coverage) > 1 else coverage[0]}))
    contact_sheet(out / "contact_sheet.png", sheet, sim.labels)
    if plan is not None:
        from ..scene.site_map import draw_map

        draw_map(plan, out / "map.png", trajectory=traj.poses[:, :3, 3])
    return coverage, tracks


def run(config: dict, seed: int, folder: Path) -> dict:
    """Generate ``seed`` into ``folder`` (made and marked by the runner), manifest last."""
    from ..blender import session

    folder.mkdir(parents=True, exist_ok=True)
    session.set_log_path(folder / "blender.log")
    import numpy as np

    from exporters.ground_truth import write_simulator_ground_truth
    from exporters.manifest import write_manifest

    from .. import Simulator
    from ..scene import build_site, plan_site, site_params
    from .config import RunConfig, check_point_budget, plan_trajectory

    cfg = RunConfig.from_dict(config).validated()
    t0 = time.perf_counter()
    site = build_site(seed, cfg.scene_preset, folder / "scene", frames=max(250, cfg.frames))
    sim = Simulator(site.blend, points_density=cfg.points_density, seed=seed, max_pcl_depth=cfg.max_depth,
                    render_preset=cfg.render_preset)
    check_point_budget(cfg, sim.num_points)  # before any rendering
    sim.configure_render(resolution=cfg.resolution, device=cfg.device)
    start = sim.respawn_camera()
    plan = plan_site(seed, site_params(cfg.scene_preset, frames=max(250, cfg.frames)))
    emit(event="start", frames=cfg.frames * len(cfg.trajectories), points=sim.num_points)
    fps = 10.0
    tracks = 0
    summary = {"trajectories": {}, "render_device": sim.render_device}
    for kind in cfg.trajectories:
        traj = plan_trajectory(kind, sim, sim.spawn_points, start, seed, cfg.frames, fps)
        coverage, visible_tracks = fly(sim, traj, folder / kind, seed, plan, cfg.colmap_text)
        tracks += visible_tracks
        summary["trajectories"][kind] = {"frames": len(traj), "final_coverage": coverage[-1]}
    write_simulator_ground_truth(sim, folder / "ground_truth", seed, cfg.scoring_density)
    (folder / "labels.json").write_text(json.dumps(sim.labels))
    summary |= {"frames": cfg.frames * len(cfg.trajectories), "points": sim.num_points, "visible_tracks": tracks}
    versions = {"buildee-sites": _version(), "bpy": session.bpy.app.version_string, "numpy": np.__version__}
    from exporters import FORMAT_VERSION

    write_manifest(folder, {"format_version": FORMAT_VERSION, "seed": seed, "config": cfg.to_dict(), "versions": versions, "summary": summary,
                            "timing": {"seconds": time.perf_counter() - t0}})
    return summary


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("buildee-sites")
    except PackageNotFoundError:
        return "unknown"


def _die_with_parent() -> None:
    """Linux: get SIGKILL when the runner dies, so no worker outlives a killed job."""
    import ctypes
    import signal

    try:
        ctypes.CDLL("libc.so.6").prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except OSError:
        pass


def main(argv: list[str]) -> int:
    _die_with_parent()
    config, seed, folder = json.loads(argv[0]), int(argv[1]), Path(argv[2])
    try:
        # testing hook: BUILDEE_FAIL_SEEDS="5,7" makes those seeds fail after the site is built
        if str(seed) in os.environ.get("BUILDEE_FAIL_SEEDS", "").split(","):
            folder.mkdir(parents=True, exist_ok=True)
            raise RuntimeError(f"seed {seed} failed on purpose (BUILDEE_FAIL_SEEDS)")
        summary = run(config, seed, folder)
    except Exception as exc:  # reported to the runner as one line; details in the log
        import traceback

        (folder / "error.log").write_text(traceback.format_exc())
        emit(event="error", message=f"{exc.__class__.__name__}: {str(exc).strip().splitlines()[0] if str(exc).strip() else ''}")
        return 1
    emit(event="done", summary=summary)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

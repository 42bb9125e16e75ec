"""One seed of the batch job, in its own process: ``python -m generator.batch.worker
CONFIG_JSON SEED FOLDER [EXECUTOR]``. Builds the site, flies each trajectory rendering every
frame, writes everything into FOLDER and finally its manifest (whose timing names the
EXECUTOR that ran it, when given). Progress goes to stdout as lines ``@@{json}``; Blender's
log goes to FOLDER/blender.log."""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path


def emit(**event) -> None:
    print("@@" + json.dumps(event), flush=True)


from .fly import fly_scene  # noqa: E402  (the trajectory loop)


def run(config: dict, seed: int, folder: Path, executor: str = "") -> dict:
    """Generate ``seed`` into ``folder`` (made and marked by the runner), manifest last;
    ``executor``: the name of the executor running it, for the manifest's timing."""
    from ..blender import session

    folder.mkdir(parents=True, exist_ok=True)
    session.set_log_path(folder / "blender.log")
    import numpy as np

    from exporters.manifest import write_manifest

    from .. import Simulator
    from ..scene import build_site
    from .config import RunConfig, check_point_budget, plan_trajectories, run_timing
    from .rig import with_rig_cameras

    cfg = RunConfig.from_dict(config).validated()
    if cfg.phases > 1:  # a timeline of the site: phase_K/ folders and changes.h5 (docs/phases.md)
        from .phases import run_phases

        return run_phases(cfg, seed, folder, emit, executor)
    t0 = time.perf_counter()
    site = build_site(seed, cfg.scene_preset, folder / "scene", frames=max(250, cfg.frames), **cfg.site_overrides())
    sim = Simulator(site.blend, points_density=cfg.points_density, seed=seed, max_pcl_depth=cfg.max_depth,
                    render_preset=cfg.render_preset)
    check_point_budget(cfg, sim.num_points)  # before any rendering
    sim.configure_render(resolution=cfg.resolution, device=cfg.device)
    sim.set_lens(cfg.camera_model, cfg.lens().coefficients)
    sim.image_sensor = cfg.image_sensor()  # exposure, noise, JPEG of the display colour
    sim.set_shutter(cfg.shutter_s, cfg.readout_s)  # motion blur, rolling shutter (0: none)
    start = sim.respawn_camera()
    # every trajectory planned before the first frame is rendered: one that cannot be planned
    # (too many frames for the site: docs/trajectories.md) fails the seed in seconds
    planned = plan_trajectories(sim, cfg.trajectories, start, seed, cfg.frames, fps=10.0)
    references = [kind for kind, _ in planned]
    rig = cfg.camera_rig()
    planned = with_rig_cameras(planned, rig)  # --stereo, --rig: each one's rig cameras too
    plan = site.plan
    emit(event="start", frames=cfg.frames * len(planned), points=sim.num_points)
    summary = {"trajectories": {}, "render_device": sim.render_device}
    summary["trajectories"], tracks = fly_scene(sim, planned, folder, seed, plan, cfg, lambda: emit(event="frame"))
    if rig is not None:  # the rig's joint COLMAP model and transforms.json, from what its cameras wrote
        from exporters.colmap_rig import write_rig_models

        write_rig_models(folder, references, rig, text=bool(cfg.exports.get("colmap_text")))
    summary |= {"frames": cfg.frames * len(planned), "points": sim.num_points, "visible_tracks": tracks}
    versions = {"buildee-sites": _version(), "bpy": session.bpy.app.version_string, "numpy": np.__version__}
    from exporters import FORMAT_VERSION

    write_manifest(folder, {"format_version": FORMAT_VERSION, "seed": seed, "config": cfg.to_dict(), "versions": versions, "summary": summary,
                            "timing": run_timing(t0, executor)})
    return summary


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("buildee-sites")
    except PackageNotFoundError:
        return "unknown"


def _die_with_parent() -> None:
    """Linux: get SIGKILL when the runner dies, so no worker outlives a killed job. A parent
    that died before this ran (the interpreter's start-up, ~0.3 s) left the worker to init:
    then it exits at once (exit 3), before touching the seed's folder."""
    import ctypes
    import signal

    try:
        ctypes.CDLL("libc.so.6").prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except OSError:
        pass
    from .executors.seed import PARENT_ENV

    parent = os.environ.get(PARENT_ENV)
    if parent and os.getppid() != int(parent):
        os._exit(3)


def main(argv: list[str]) -> int:
    _die_with_parent()
    config, seed, folder = json.loads(argv[0]), int(argv[1]), Path(argv[2])
    executor = argv[3] if len(argv) > 3 else ""
    try:
        # testing hook: BUILDEE_FAIL_SEEDS="5,7" makes those seeds fail after the site is built
        if str(seed) in os.environ.get("BUILDEE_FAIL_SEEDS", "").split(","):
            folder.mkdir(parents=True, exist_ok=True)
            raise RuntimeError(f"seed {seed} failed on purpose (BUILDEE_FAIL_SEEDS)")
        summary = run(config, seed, folder, executor)
    except Exception as exc:  # reported to the runner as one line; details in the log
        import traceback

        (folder / "error.log").write_text(traceback.format_exc())
        emit(event="error", message=f"{exc.__class__.__name__}: {str(exc).strip().splitlines()[0] if str(exc).strip() else ''}")
        return 1
    emit(event="done", summary=summary)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

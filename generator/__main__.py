"""``python -m generator --seeds 0 137 281``: build, fly and render one site per seed;
``python -m generator verify DIR``: check seed folders against their manifests.

The main process never imports bpy; every seed runs in its own worker process.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
from pathlib import Path

from trajectories import TRAJECTORY_KINDS

from .batch.config import MAX_FRAMES, MAX_PHASES, MAX_SCORING_POINTS, RunConfig
from .batch.executors import add_executor_arguments, executor_arguments_problem
from .checks import MAX_SEED
from .cli_args import (OneLineParser, check_out_folder, coefficients, exposure, first_repeated, int_at_least,
                       out_folder, positive_float, resolution)
from .geometry.lens import MODELS as LENS_MODELS
from .render_settings import DEVICES, NO_GPU_MESSAGE, probe_gpu
from .render_settings import PRESETS as RENDER_PRESETS
from .scene.site import PRESETS as SCENE_PRESETS
from .scene.building_types import all_types
from .scene.catalogue.ground import SURFACES
from .scene.contexts import CONTEXTS
from .scene.weather import SEASONS, WEATHERS
from exporters.modalities import MODALITIES
from exporters.sinks import export_options

DEFAULTS = RunConfig()


def _outputs(text: str | None) -> tuple[str, ...]:
    """--outputs: the listed modality names (checked by RunConfig.validated), all by default."""
    return tuple(n.strip() for n in text.split(",") if n.strip()) if text is not None else tuple(MODALITIES)


def _shard(text: str) -> tuple[int, int]:
    try:
        k, n = (int(v) for v in text.split("/"))
    except ValueError:
        k, n = -1, 0
    if n < 1 or not 0 <= k < n:
        raise argparse.ArgumentTypeError(f"shard must be K/N with 0 <= K < N, e.g. 0/4; got {text!r}")
    return k, n


def _add_site_arguments(p) -> None:
    """What every seed's site is: its timeline's stages, its weather, its ground."""
    p.add_argument("--phases", type=int_at_least(1, "phases", MAX_PHASES), default=1,
                   help=f"stages of each site's timeline, 1 to {MAX_PHASES}: phase_K/ folders flown along the same "
                        "trajectories plus changes.h5 (default: 1, one site as before; docs/phases.md)")
    p.add_argument("--weather", choices=WEATHERS, default=None,
                   help="sky and weather of every seed: " + ", ".join(WEATHERS) + " (default: drawn per seed; "
                        "docs/scenes.md)")
    p.add_argument("--ground", choices=SURFACES, default=None,
                   help="the ground's surface on every seed: " + ", ".join(SURFACES) + " (default: drawn per seed; "
                        "docs/scenes.md)")
    types = [t.name for t in all_types()]
    p.add_argument("--building-type", choices=types, default=None,
                   help="the type of every building: " + ", ".join(types) + " (default: drawn per building; "
                        "docs/scenes.md)")
    p.add_argument("--context", choices=list(CONTEXTS), default=None,
                   help="what surrounds every site: " + ", ".join(CONTEXTS) + " (default: drawn per seed; docs/scenes.md)")
    p.add_argument("--season", choices=list(SEASONS), default=None,
                   help="the season of every site: " + ", ".join(SEASONS) + " (snow: a winter with snow lying; default: "
                        "drawn per seed; docs/scenes.md)")


def _add_rerun_arguments(p) -> None:
    """Which seeds this run takes, and what it does with seeds already there."""
    p.add_argument("--shard", type=_shard, default=(0, 1),
                   help="K/N: process only the seeds at positions K, K+N, K+2N, ... of --seeds (default: 0/1)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace seeds that are already complete (the old folder stays until the new one is complete)")
    p.add_argument("--verify", action="store_true",
                   help="hash every file of complete seeds before skipping them (default: check sizes, and hash "
                        "files whose modification time changed)")
    p.add_argument("--repair", action="store_true",
                   help="hash every file of complete seeds (as --verify) and redo those whose files fail the check")
    p.add_argument("--wait", action="store_true",
                   help="wait for seeds another run is writing (default: skip them, exit code 4)")


def _add_camera_arguments(p) -> None:
    """The cameras' options: lens, image sensor, shutter, stereo pair and rig (docs/cameras.md)."""
    p.add_argument("--camera-model", choices=list(LENS_MODELS), default=DEFAULTS.camera_model,
                   help="the cameras' lens model: pinhole, opencv (radial-tangential) or fisheye (equidistant), "
                        "with OpenCV's definitions (default: pinhole; docs/cameras.md)")
    p.add_argument("--distortion", type=coefficients, default=DEFAULTS.distortion,
                   help="the lens's coefficients, comma-separated: k1,k2,p1,p2[,k3] for opencv, k1,k2,k3,k4 for "
                        "fisheye (default: all zero)")
    p.add_argument("--exposure", type=exposure, default=DEFAULTS.exposure,
                   help="the cameras' exposure: 'auto' (average metering to mid-grey, per frame), a compensation in "
                        "stops (-10 to 10), or as-rendered (default; docs/cameras.md)")
    p.add_argument("--sensor-noise", type=coefficients, default=DEFAULTS.sensor_noise, metavar="FULL_WELL,READ",
                   help="shot and read noise on the display colour: electrons at saturation and read noise sigma in "
                        "electrons, e.g. 6000,3 (default: none)")
    p.add_argument("--jpeg-quality", type=int_at_least(1, "jpeg-quality", 100), default=DEFAULTS.jpeg_quality,
                   help="JPEG-compress the display colour at this quality, 1 to 100 (default: none)")
    p.add_argument("--shutter", type=positive_float(zero=True), default=DEFAULTS.shutter_s, metavar="SECONDS",
                   help="motion blur: the shutter's time in seconds, 0 to 0.1 (one frame), centred on each frame; "
                        "the colour is blurred by the camera's and the machines' motion, the ground truth stays "
                        "that of the frame's time (default: 0, none; docs/cameras.md)")
    p.add_argument("--rolling-shutter", type=positive_float(zero=True), default=DEFAULTS.readout_s, metavar="SECONDS",
                   dest="readout_s",
                   help="a rolling shutter reading the rows top to bottom over this many seconds, 0 to 0.1: every "
                        "row's colour and ground truth at its own time (default: 0, a global shutter; "
                        "docs/cameras.md)")
    p.add_argument("--stereo", type=positive_float(zero=True), default=DEFAULTS.stereo_baseline_m, metavar="METRES",
                   help="a stereo pair: every trajectory also flown by a camera this many metres to the right "
                        "(0 to 1), in <kind>_right/; rectified, disparity = fx x baseline / depth (default: 0, "
                        "none; docs/cameras.md)")
    p.add_argument("--rig", type=rig_file, default=DEFAULTS.rig, metavar="FILE",
                   help="a camera rig (JSON: cameras with their names and 4x4 rig_from_camera): every trajectory "
                        "also flown by each camera, in <kind>_<name>/, and the rig's joint COLMAP model and "
                        "transforms.json in rigs/<kind>/ (default: none; docs/cameras.md)")


def rig_file(text: str) -> dict:
    """An argparse type: a rig file (generator/batch/rig.py), as the document the config stores."""
    from .batch.rig import RigError, read_rig

    try:
        return read_rig(text).as_dict()
    except RigError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def parse_args(argv=None) -> argparse.Namespace:
    p = OneLineParser(
        prog="python -m generator",
        description="Build one procedural construction site per seed, fly camera trajectories through it and "
                    "write, per frame, RGB/depth/labels/instances (EXR), RGB (PNG), plus each trajectory, its "
                    "coverage and a manifest. Finished seeds are checked and skipped on rerun. Nothing in --out "
                    "that this run did not create is deleted or replaced unless --overwrite (or --repair) says so. "
                    "Exit codes: 0 every seed complete; 1 a seed failed; 2 bad input; 3 a seed was left alone "
                    "(its folder holds something else, a seed made with other parameters, or a corrupt seed); "
                    "4 a seed was skipped because another run is writing it. "
                    "'python -m generator verify DIR' checks a dataset (see its --help).")
    p.add_argument("--seeds", type=int_at_least(0, "seed", MAX_SEED), nargs="+", default=[0, 137, 281],
                   help="scene seeds, integers from 0 to 2**63-1 (default: 0 137 281)")
    p.add_argument("--out", type=out_folder, default=Path("output"), help="output folder (default: ./output)")
    p.add_argument("--scene-preset", choices=sorted(SCENE_PRESETS), default=DEFAULTS.scene_preset,
                   help=f"site size and content (default: {DEFAULTS.scene_preset})")
    p.add_argument("--render-preset", choices=list(RENDER_PRESETS), default=DEFAULTS.render_preset,
                   help=f"render quality (default: {DEFAULTS.render_preset}: Cycles, 4 samples, denoised)")
    p.add_argument("--device", choices=DEVICES, default=DEFAULTS.device,
                   help="Cycles device: cpu, gpu (a CUDA/OptiX GPU; an error without one) or auto (a GPU when "
                        f"there is one, else the CPU; default: {DEFAULTS.device})")
    p.add_argument("--resolution", type=resolution, default=DEFAULTS.resolution,
                   help="image size WxH in pixels, sides 4 to 16384, at most 3840x2160 pixels (default: 640x480)")
    p.add_argument("--frames", type=int_at_least(2, "frames", MAX_FRAMES), default=DEFAULTS.frames,
                   help=f"frames per trajectory, 2 to {MAX_FRAMES}, at 10 frames per second of scene time "
                        f"(default: {DEFAULTS.frames})")
    p.add_argument("--trajectory", choices=TRAJECTORY_KINDS.names(), action="append", dest="trajectories",
                   help="trajectory kind, repeatable (default: orbit and spline)")
    p.add_argument("--points-density", type=positive_float(), default=DEFAULTS.points_density,
                   help=f"surface points per square metre for tracking and coverage (default: {DEFAULTS.points_density})")
    p.add_argument("--scoring-density", type=positive_float(), default=DEFAULTS.scoring_density,
                   help=f"points per square metre of the ground-truth cloud for scoring, at most "
                        f"{MAX_SCORING_POINTS // 10**6} million points in all (default: {DEFAULTS.scoring_density:g})")
    for option in export_options():  # each export's own options (--colmap-text), declared beside its sink
        option.add_to(p)
    _add_camera_arguments(p)  # the lens, the sensor, the shutter, a stereo pair (docs/cameras.md)
    p.add_argument("--outputs", default=None,
                   help="per-frame modalities to write, comma-separated, from: " + ", ".join(MODALITIES)
                        + " (default: all; docs/format.md)")
    _add_site_arguments(p)
    add_executor_arguments(p)  # --executor and each executor's own options (generator/batch/executors/)
    _add_rerun_arguments(p)
    args = p.parse_args(argv)
    twice = first_repeated(args.seeds)
    if twice is not None:
        p.error(f"--seeds lists seed {twice} twice")
    outputs = _outputs(args.outputs)
    if not outputs:
        p.error("--outputs names no modality; list some of: " + ", ".join(MODALITIES) + " (or leave it out: all)")
    if first_repeated(outputs) is not None:
        p.error(f"--outputs lists {first_repeated(outputs)} twice")
    check_out_folder(p, args.out)
    problem = executor_arguments_problem(args)
    if problem:
        p.error(problem)
    args.config = RunConfig(args.scene_preset, args.render_preset, args.resolution, args.frames,
                            tuple(args.trajectories or DEFAULTS.trajectories), args.points_density,
                            DEFAULTS.max_depth, args.scoring_density, device=args.device, outputs=outputs,
                            phases=args.phases, weather=args.weather, ground=args.ground,
                            building_type=args.building_type, context=args.context, season=args.season,
                            camera_model=args.camera_model, distortion=args.distortion,
                            exposure=args.exposure, sensor_noise=args.sensor_noise, jpeg_quality=args.jpeg_quality,
                            shutter_s=args.shutter, readout_s=args.readout_s, stereo_baseline_m=args.stereo, rig=args.rig,
                            exports={o.dest: getattr(args, o.dest) for o in export_options()})
    try:
        args.config.validated()
    except ValueError as exc:
        p.error(str(exc))
    if args.device == "gpu" and probe_gpu() is None:
        p.error(NO_GPU_MESSAGE)
    return args


def _stopped(what: str) -> int:
    """Print the signal's word and ``what`` (which starts with its own separator) on stderr;
    return the exit code: 130 Ctrl-C, 143 SIGTERM."""
    from .batch.runner import stopped_by

    code, word = stopped_by()
    print(f"{word}{what}", file=sys.stderr)
    return code


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["verify"]:
        from .batch.verify import main as verify

        return verify(argv[1:])
    args = parse_args(argv)
    cfg = args.config
    try:
        args.out.mkdir(parents=True, exist_ok=True)
        probe = args.out / f".write-test-{os.getpid()}"
        probe.write_text("")
        probe.unlink()
    except OSError as exc:
        print(f"error: cannot write to output folder {args.out}: {exc.strerror}", file=sys.stderr)
        return 2
    from .batch import folders
    from .batch.executors import ExecutorError, make_executor
    from .batch.runner import INTERRUPTED, SIGNALS, Options, exit_code, interrupt, run_seeds

    k, n = args.shard
    seeds = [s for i, s in enumerate(args.seeds) if i % n == k]
    # --repair hashes every file: a repair that trusted modification times could leave what
    # `verify` reported (bytes changed with their time put back) and call the seed complete
    opts = Options(args.overwrite, args.repair, True if args.verify or args.repair else None, args.wait)
    # Ctrl-C is remembered from the start (Ray's start-up swallows it); SIGTERM gets our handler
    # once the executor is up (Ray's own start-up handler aborts if a Python one was set)
    signal.signal(signal.SIGINT, interrupt)
    INTERRUPTED.clear()
    SIGNALS.clear()
    try:
        executor = make_executor(args.executor, args.out, args)
    except ExecutorError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return _stopped(" before any seed started; nothing was written")
    for sig in (signal.SIGTERM, signal.SIGINT):  # a polite kill cleans up like Ctrl-C
        signal.signal(sig, interrupt)
    if INTERRUPTED.is_set():  # a signal that a library swallowed while the executor started
        executor.close()
        return _stopped(" before any seed started; nothing was written")
    try:
        results = run_seeds(args.out, seeds, cfg, opts, executor)
    except KeyboardInterrupt:
        return _stopped(": unfinished seeds were removed; rerun the same command to finish them")
    finally:
        executor.close()
    results = sorted(results, key=lambda r: seeds.index(r.seed))
    print(f"\n{'seed':>8}  {'status':<8} {'frames':>6} {'points':>10} {'visible tracks':>15} {'time':>7}")
    for r in results:
        s = r.summary
        print(f"{r.seed:>8}  {r.status:<8} {s.get('frames', '-'):>6} {s.get('points', 0):>10,} "
              f"{s.get('visible_tracks', 0):>15,} {r.seconds:>6.0f}s" + (f"  {r.message}" if r.message else ""))
    failed = [r for r in results if r.status == "failed"]
    kept = [r.seed for r in failed if folders.partial_folder(args.out, r.seed).is_dir()]
    if failed:
        where = f"; their partial output is in {args.out}/.seed_*.partial" if kept else ""
        print(f"{len(failed)} seed(s) failed{where}", file=sys.stderr)
    return exit_code(results)


if __name__ == "__main__":
    sys.exit(main())

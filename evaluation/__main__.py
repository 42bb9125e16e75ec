"""``python -m evaluation``: score point clouds and exploration trajectories offline.

  python -m evaluation reconstruction --gt SEED_FOLDER|GT.ply --pred CLOUD [--tau 0.1] [--json out.json] [--rrd out.rrd] ...
  python -m evaluation coverage --gt SEED_FOLDER --trajectory trajectory.npz|COLMAP_DIR [--json out.json] [--plot out.png]
  python -m evaluation tracks --gt SEED_FOLDER/orbit/tracks.h5 --pred my_tracks.npz [--resize-to 256x256] [--json out.json]
  python -m evaluation change --gt SEED_FOLDER --stages K-1 K --pred changes.npz|changes.ply [--tau 0.1] [--kind orbit] [--json out.json]
  python -m evaluation scans --gt SEED_FOLDER/orbit/lidar/os1-128 --pred PREDICTIONS_FOLDER [--change] [--json out.json]

Bad input: one line on stderr, exit code 2, nothing written. Outputs (--json, --ply, --plot, --rrd)
never land on an input of the run or inside an input folder, inside a generated seed folder,
on a folder, or on an existing file this project did not write (exporters.write_guard); that
is checked before any scoring starts.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from generator.cli_args import OneLineParser, positive_float, resolution


def parse_args(argv=None) -> argparse.Namespace:
    p = OneLineParser(prog="python -m evaluation", description="Score reconstructions and explorations against the "
                "ground truth written by python -m generator (no Blender needed).")
    sub = p.add_subparsers(dest="task", required=True, parser_class=OneLineParser)
    r = sub.add_parser("reconstruction", help="score a point cloud (geometry and, with labels, semantics)")
    r.add_argument("--gt", type=Path, required=True, help="seed folder, its ground_truth/ folder, or a labelled cloud")
    r.add_argument("--pred", type=Path, required=True, help="predicted cloud: PLY, NPY, NPZ or text x y z [label]")
    r.add_argument("--pred-labels", type=Path, help="separate label file for --pred (one id or class name per line, or NPY)")
    r.add_argument("--tau", type=positive_float("a positive number of metres"), default=0.1, help="distance threshold in metres (default 0.1, strict <)")
    r.add_argument("--sweep", type=positive_float("a positive number of metres"), nargs="+", default=[0.01, 0.02, 0.05, 0.1, 0.2, 0.5],
                   help="thresholds of the precision/recall sweep, metres")
    r.add_argument("--crop", action="store_true", help="drop predicted points outside the GT's bounding box (+ margin)")
    r.add_argument("--crop-margin", type=positive_float("a number of metres >= 0", zero=True),
                   help="margin of --crop in metres (default: tau)")
    r.add_argument("--voxel", type=positive_float("a positive number of metres"), help="voxel-downsample both clouds to this size (metres) first")
    r.add_argument("--static-only", action="store_true", help="score against the static part of the GT only")
    r.add_argument("--json", type=Path, help="write every number, parameter and version here")
    r.add_argument("--ply", type=Path, help="write the GT cloud coloured by match (paper's figure 9)")
    r.add_argument("--rrd", type=Path, help="write a Rerun recording: the prediction beside the GT coloured "
                   "by match (figure 9), see docs/viewer.md")
    c = sub.add_parser("coverage", help="score an exploration trajectory by the surface it observes")
    c.add_argument("--gt", type=Path, required=True, help="seed folder (or its ground_truth/ folder)")
    c.add_argument("--trajectory", type=Path, required=True, help="trajectory .npz (generator) or COLMAP model folder")
    c.add_argument("--frames", choices=["auto", "timestamps", "first"], default="auto",
                   help="animation frame per pose: from timestamps (auto, when present) or the first frame")
    c.add_argument("--max-depth", type=positive_float("a positive number of metres"),
                   help="points count as seen within this planar depth (default: the generator's, in scene.h5)")
    c.add_argument("--json", type=Path, help="write the curve, AUC, parameters and versions here")
    c.add_argument("--plot", type=Path, help="write a PNG of the coverage curve")
    k = sub.add_parser("tracks", help="score point tracks on a trajectory's TAP-Vid query subset")
    k.add_argument("--gt", type=Path, required=True, help="a trajectory's tracks.h5 (or its folder)")
    k.add_argument("--pred", type=Path, required=True, help="NPZ with tracks (Q, T, 2) (x, y) and occluded (Q, T)")
    k.add_argument("--query-mode", choices=["first", "strided"], default="first",
                   help="evaluate the frames after each query (first) or all but the query frame (strided)")
    k.add_argument("--resize-to", type=resolution, help="scale positions to WxH first (TAP-Vid uses 256x256)")
    k.add_argument("--json", type=Path, help="write the scores, parameters and versions here")
    ch = sub.add_parser("change", help="score predicted changes between two stages of a timeline (docs/phases.md)")
    ch.add_argument("--gt", type=Path, required=True, help="seed folder made with python -m generator --phases K")
    ch.add_argument("--stages", type=int, nargs=2, required=True, metavar=("K-1", "K"), help="two consecutive stages")
    ch.add_argument("--pred", type=Path, required=True, help="NPZ/PLY change cloud (xyz, change: 1 added, 2 removed) "
                    "or NPZ with masks (T, H, W) bool")
    ch.add_argument("--tau", type=positive_float("a positive number of metres"), default=0.1,
                    help="change clouds: match distance in metres (default 0.1, strict <)")
    ch.add_argument("--kind", help="change masks: the trajectory they are for (default: the only one)")
    ch.add_argument("--json", type=Path, help="write the scores and every parameter here")
    s = sub.add_parser("scans", help="score a labelling of LiDAR sweeps: IoU per class over every return (docs/lidar.md)")
    s.add_argument("--gt", type=Path, required=True, help="a scan folder: SEED/<trajectory>/lidar/<NAME> (--lidar NAME)")
    s.add_argument("--pred", type=Path, required=True, help="folder of NNNNNN.label (uint32 per return, class id in "
                   "the low 16 bits), or holding them in predictions/")
    s.add_argument("--change", action="store_true", help="score NNNNNN.change (int8 change status per return) "
                   "against a timeline stage's change labels instead")
    s.add_argument("--json", type=Path, help="write the scores and every parameter here")
    args, extra = p.parse_known_args(argv)
    if extra:  # said by the task's own parser, so that its --help is the one pointed to
        {"reconstruction": r, "coverage": c, "tracks": k, "change": ch, "scans": s}[args.task].error(
            f"unrecognized arguments: {' '.join(extra)}")
    if args.task == "reconstruction" and args.crop_margin is not None and not args.crop:
        r.error("--crop-margin applies to --crop; add --crop, or leave --crop-margin out")
    return args


# output flag -> kind of file (exporters.write_guard.KINDS: the signature an existing file must carry)
OUTPUTS = {"json": "json", "ply": "ply", "plot": "png", "rrd": "rrd"}


def _inputs(args) -> list[Path]:
    """The files and folders this run reads: the outputs must stay clear of them."""
    paths = [getattr(args, k, None) for k in ("gt", "pred", "pred_labels", "trajectory")]
    paths = [Path(p) for p in paths if p is not None and Path(p).exists()]
    for p in list(paths):  # label tables read beside a ground-truth file
        base = p if p.is_dir() else p.parent
        paths += [c for c in (base / "labels.json", base.parent / "labels.json", base / "tracks.h5") if c.is_file()]
    return paths


def check_outputs(args) -> None:
    """Refuse, before any work, outputs that would land on an input or inside an input folder,
    inside a generated seed, on a folder or a file this project did not write, twice, or where
    nothing can be written (exporters.write_guard)."""
    from exporters.write_guard import WriteRefused, check_output_file

    from .inputs import InputError

    inputs = _inputs(args)
    seen: dict[Path, str] = {}
    for key, kind in OUTPUTS.items():
        if getattr(args, key, None) is None:
            continue
        flag, path = f"--{key}", Path(getattr(args, key))
        real = Path(os.path.realpath(path))
        if real in seen:
            raise InputError(f"{flag} {path}: the same file as {seen[real]}; give each output its own name")
        seen[real] = flag
        try:
            check_output_file(path, flag, kind, inputs)
        except WriteRefused as exc:
            raise InputError(str(exc)) from None


def main(argv=None) -> int:
    args = parse_args(argv)
    from exporters.hdf5 import DamagedFileError

    from .api import colour_ply, score_coverage, score_reconstruction, score_tracks
    from .inputs import InputError
    from .report import coverage_plot, coverage_table, reconstruction_table, tracks_table, write_json

    try:
        check_outputs(args)
        if args.task == "reconstruction":
            results, ctx = score_reconstruction(args.pred, args.gt, args.tau, tuple(args.sweep), args.crop,
                                                args.crop_margin, args.voxel, args.pred_labels, not args.static_only)
            print(reconstruction_table(results))
            if args.ply:
                _write(args.ply, colour_ply, ctx, args.tau)
            if args.rrd:
                from datasets.viewer.common import quiet_rerun

                quiet_rerun()
                from datasets.viewer.match import write_match_recording

                _write(args.rrd, write_match_recording, ctx, args.tau)
        elif args.task == "change":
            from .change import change_table, score_change

            results = score_change(args.gt, args.stages[0], args.stages[1], args.pred, args.tau, args.kind)
            print(change_table(results))
        elif args.task == "scans":
            from .scans import scans_table, score_scans

            results = score_scans(args.gt, args.pred, args.change)
            print(scans_table(results))
        elif args.task == "tracks":
            results = score_tracks(args.gt, args.pred, args.query_mode, args.resize_to)
            print(tracks_table(results))
        else:
            from tqdm import tqdm

            results = score_coverage(args.gt, args.trajectory, args.frames,
                                     progress=lambda it: tqdm(it, desc="poses", leave=False, file=sys.stderr),
                                     max_depth=args.max_depth)
            print(coverage_table(results))
            if args.plot:
                _write(args.plot, coverage_plot, {Path(str(args.trajectory)).name: results["coverage"]},
                       f"coverage of {args.gt.name}, AUC {results['auc']:.3f}")
        if args.json:
            _write(args.json, write_json, results)
    except (InputError, DamagedFileError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # e.g. a folder on the way that this user may not look into
        print(f"error: {exc.filename or 'input'}: {exc.strerror or exc}; check the path and its permissions", file=sys.stderr)
        return 2
    except MemoryError:
        print("error: out of memory; voxel-downsample the clouds (--voxel) or score a smaller cloud", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("error: interrupted; nothing more was written", file=sys.stderr)
        return 130
    return 0


def _write(path: Path, writer, *args) -> None:
    """Run one output writer; a failure to write is one line naming the file."""
    from .inputs import InputError

    try:
        writer(path, *args)
    except OSError as exc:
        raise InputError(f"{path}: cannot write it ({exc.strerror or exc.__class__.__name__})") from None


if __name__ == "__main__":
    sys.exit(main())

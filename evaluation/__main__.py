"""``python -m evaluation``: score point clouds and exploration trajectories offline.

  python -m evaluation reconstruction --gt SEED_FOLDER|GT.ply --pred CLOUD [--tau 0.1] [--json out.json] ...
  python -m evaluation coverage --gt SEED_FOLDER --trajectory trajectory.npz|COLMAP_DIR [--json out.json] [--plot out.png]
  python -m evaluation tracks --gt SEED_FOLDER/orbit/tracks.h5 --pred my_tracks.npz [--resize-to 256x256] [--json out.json]

Bad input: one line on stderr, exit code 2, nothing written.
"""

from __future__ import annotations

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
    r.add_argument("--crop-margin", type=positive_float("a positive number of metres"), help="margin of --crop in metres (default: tau)")
    r.add_argument("--voxel", type=positive_float("a positive number of metres"), help="voxel-downsample both clouds to this size (metres) first")
    r.add_argument("--static-only", action="store_true", help="score against the static part of the GT only")
    r.add_argument("--json", type=Path, help="write every number, parameter and version here")
    r.add_argument("--ply", type=Path, help="write the GT cloud coloured by match (paper's figure 9)")
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
    return p.parse_args(argv)


def _check_output(path: Path | None) -> None:
    if path is not None and not path.parent.is_dir():
        from .inputs import InputError

        raise InputError(f"{path}: its folder does not exist; create it first")


def main(argv=None) -> int:
    args = parse_args(argv)
    from .api import colour_ply, score_coverage, score_reconstruction, score_tracks
    from .inputs import InputError
    from .report import coverage_plot, coverage_table, reconstruction_table, tracks_table, write_json

    try:
        for out in (getattr(args, "json", None), getattr(args, "ply", None), getattr(args, "plot", None)):
            _check_output(out)
        if args.task == "reconstruction":
            results, ctx = score_reconstruction(args.pred, args.gt, args.tau, tuple(args.sweep), args.crop,
                                                args.crop_margin, args.voxel, args.pred_labels, not args.static_only)
            print(reconstruction_table(results))
            if args.ply:
                colour_ply(args.ply, ctx, args.tau)
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
                coverage_plot(args.plot, {Path(str(args.trajectory)).name: results["coverage"]},
                              f"coverage of {args.gt.name}, AUC {results['auc']:.3f}")
        if args.json:
            write_json(args.json, results)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except MemoryError:
        print("error: out of memory; voxel-downsample the clouds (--voxel)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())

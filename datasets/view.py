"""``python -m datasets.view SEED_FOLDER``: everything a seed holds, as a Rerun recording.

  python -m datasets.view output/seed_000000                       # writes ./seed_000000.rrd
  python -m datasets.view output/seed_000000 --trajectory orbit --out seed0.rrd
  python -m datasets.view output/seed_000000 --spawn               # opens the Rerun viewer (needs a display)

Open a recording with ``rerun seed0.rrd`` (desktop) or ``rerun --web-viewer seed0.rrd``
(browser). What is logged, and the subsampling rule of large clouds: docs/viewer.md.
Bad input: one line on stderr, exit code 2, no .rrd written.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from exporters.manifest import seed_folder_containing
from generator.cli_args import OneLineParser, int_at_least

from .viewer.common import MAX_POINTS


def parse_args(argv=None) -> argparse.Namespace:
    p = OneLineParser(prog="python -m datasets.view", description="Write a Rerun recording of a generated seed: "
                      "labelled GT cloud, site mesh, cameras with their images, point tracks, coverage.")
    p.add_argument("seed", type=Path, help="a seed folder written by python -m generator (output/seed_NNNNNN)")
    p.add_argument("--trajectory", action="append", metavar="KIND",
                   help="log only this trajectory (repeatable; default: all of the seed's)")
    p.add_argument("--out", type=Path, help="the .rrd file to write (default: ./<seed folder name>.rrd)")
    p.add_argument("--spawn", action="store_true", help="open the Rerun viewer instead of writing a file "
                   "(needs a display)")
    p.add_argument("--max-points", type=int_at_least(1, "--max-points"), default=MAX_POINTS,
                   help=f"GT cloud cap: points[::ceil(N / max_points)] are logged (default {MAX_POINTS:,})")
    return p.parse_args(argv)


class ViewError(ValueError):
    """Bad input to the viewer (one line: what is wrong, what to do)."""


def check_out(out: Path, seed: Path) -> None:
    """Refuse an output that is a folder, lies inside the seed folder, or cannot be written."""
    if out.suffix != ".rrd":
        raise ViewError(f"--out {out}: name a .rrd file")
    if out.is_dir():
        raise ViewError(f"--out {out}: is a folder; name a .rrd file")
    try:
        inside = seed_folder_containing(out.parent)
    except OSError as exc:
        raise ViewError(f"--out {out}: cannot look at its folder ({exc.strerror}); choose another") from None
    if inside is not None:
        raise ViewError(f"--out {out}: lies inside the seed folder {inside}; write the recording elsewhere")
    if not out.parent.is_dir():
        raise ViewError(f"--out {out}: its folder does not exist; create it first")
    if not os.access(out.parent, os.W_OK):
        raise ViewError(f"--out {out}: cannot write in {out.parent}; choose a writable folder")


def has_display() -> bool:
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")) or sys.platform in ("darwin", "win32")


def run(args) -> Path | None:
    from tqdm import tqdm

    from datasets import DatasetError, Scene

    from .viewer.common import APPLICATION_ID, recording_file
    from .viewer.seed import blueprint, frame_rate, record_scene

    try:
        scene = Scene(args.seed)
    except DatasetError as exc:
        raise ViewError(str(exc)) from None
    kinds = args.trajectory or scene.trajectories
    unknown = [k for k in kinds if k not in scene.trajectories]
    if unknown:
        raise ViewError(f"--trajectory {unknown[0]}: not in {args.seed} (it has {', '.join(scene.trajectories)})")
    out = args.out or Path(f"{scene.path.resolve().name}.rrd")
    if args.spawn:
        if not has_display():
            raise ViewError("--spawn: no display here; write a file (--out seed.rrd) and open it with "
                            "`rerun seed.rrd` where there is one, or `rerun --web-viewer seed.rrd`")
    else:
        check_out(out, scene.path)

    def progress(frames, kind):
        return tqdm(frames, desc=f"{kind} frames", leave=False, file=sys.stderr)

    recording_id = f"seed_{scene.seed:06d}"
    try:
        layout = blueprint(kinds, frame_rate(scene[kinds[0]]))
    except DatasetError as exc:
        raise ViewError(str(exc)) from None
    try:
        if args.spawn:
            import rerun as rr

            rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id)
            rec.spawn(default_blueprint=layout)
            record_scene(rec, scene, kinds, args.max_points, progress)
            rec.flush()
            return None
        with recording_file(out, recording_id, layout) as rec:
            record_scene(rec, scene, kinds, args.max_points, progress)
    except DatasetError as exc:
        raise ViewError(str(exc)) from None
    except OSError as exc:
        raise ViewError(f"{out}: cannot write it ({exc.strerror or exc.__class__.__name__})") from None
    return out


def main(argv=None) -> int:
    try:
        out = run(parse_args(argv))
    except ViewError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # e.g. a folder on the way that this user may not look into
        print(f"error: {exc.filename or 'input'}: {exc.strerror or exc}; check the path and its permissions", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("error: interrupted; no recording was written", file=sys.stderr)
        return 130
    if out is not None:
        print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""``python -m datasets.view SEED_FOLDER``: everything a seed holds, as a Rerun recording.

  python -m datasets.view output/seed_000000                       # writes ./seed_000000.rrd
  python -m datasets.view output/seed_000000 --trajectory orbit --out seed0.rrd
  python -m datasets.view output/seed_000000 --spawn               # opens the Rerun viewer (needs a display)
  python -m datasets.view output/seed_000005/phase_1               # stage 1 of a timeline seed (--phases)

Open a recording with ``rerun seed0.rrd`` (desktop) or ``rerun --web-viewer seed0.rrd``
(browser). What is logged, and the subsampling rule of large clouds: docs/viewer.md.
Bad input: one line on stderr, exit code 2, no .rrd written.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
from pathlib import Path

from exporters.manifest import seed_folder_containing
from generator.cli_args import OneLineParser, int_at_least

from .viewer.common import MAX_POINTS


def parse_args(argv=None) -> argparse.Namespace:
    p = OneLineParser(prog="python -m datasets.view", description="Write a Rerun recording of a generated seed: "
                      "labelled GT cloud, site mesh, cameras with their images, point tracks, coverage.")
    p.add_argument("seed", type=Path, help="a seed folder written by python -m generator (output/seed_NNNNNN), "
                   "or one stage of a timeline seed (output/seed_NNNNNN/phase_K)")
    p.add_argument("--trajectory", action="append", metavar="KIND",
                   help="log only this trajectory (repeatable, each once; default: all of the seed's)")
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


def viewer_executable() -> Path:
    """The Rerun viewer of this Python's environment (``rerun`` next to ``sys.executable``, as
    in a virtual environment that is not activated), else the one on PATH."""
    for name in ("rerun", "rerun.exe"):
        beside = Path(sys.executable).with_name(name)
        if beside.is_file() and os.access(beside, os.X_OK):
            return beside
    found = shutil.which("rerun")
    if found is None:
        raise ViewError(f"--spawn: no Rerun viewer (rerun) next to {sys.executable} or on PATH; install rerun-sdk "
                        "in this environment, or write a file (--out seed.rrd) and open it with `rerun seed.rrd`")
    return Path(found)


def chosen_trajectories(requested: list[str] | None, scene, folder: Path) -> list[str]:
    """The trajectories to log: each named once and in the seed (default: all of the seed's)."""
    if not requested:
        return list(scene.trajectories)
    repeated = sorted({k for k in requested if requested.count(k) > 1})
    if repeated:
        raise ViewError(f"--trajectory {repeated[0]}: given more than once; name each trajectory once")
    unknown = [k for k in requested if k not in scene.trajectories]
    if unknown:
        raise ViewError(f"--trajectory {unknown[0]}: not in {folder} (it has {', '.join(scene.trajectories)})")
    return requested


def run(args) -> Path | None:
    from tqdm import tqdm

    from datasets import DatasetError

    from .viewer.common import APPLICATION_ID, recording_file
    from .viewer.seed import blueprint, default_file_name, open_scene, record_scene, recording_id

    try:
        scene = open_scene(args.seed)
    except DatasetError as exc:
        raise ViewError(str(exc)) from None
    kinds = chosen_trajectories(args.trajectory, scene, args.seed)
    out = args.out or Path(default_file_name(scene))
    if args.spawn:
        if not has_display():
            raise ViewError("--spawn: no display here; write a file (--out seed.rrd) and open it with "
                            "`rerun seed.rrd` where there is one, or `rerun --web-viewer seed.rrd`")
        executable = viewer_executable()
    else:
        check_out(out, scene.path)

    def progress(frames, kind):
        return tqdm(frames, desc=f"{kind} frames", leave=False, file=sys.stderr)

    try:
        layout = blueprint(scene, kinds)
    except DatasetError as exc:
        raise ViewError(str(exc)) from None
    try:
        if args.spawn:
            import rerun as rr

            rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id(scene))
            rr.spawn(executable_path=str(executable), default_blueprint=layout, recording=rec)
            record_scene(rec, scene, kinds, args.max_points, progress)
            try:
                rec.flush()
            except RuntimeError as exc:  # the viewer did not start (e.g. no X server at $DISPLAY) or went away
                rec.disconnect()  # Rerun's own shutdown messages come before the error line
                raise ViewError(f"--spawn: the Rerun viewer {executable} did not take the recording "
                                f"({str(exc).splitlines()[0]}); check that the display works, or write a file "
                                "(--out seed.rrd) and open it with `rerun seed.rrd`") from None
            return None
        with recording_file(out, recording_id(scene), layout) as rec:
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

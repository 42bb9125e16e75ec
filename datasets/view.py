"""``python -m datasets.view SEED_FOLDER``: everything a seed holds, as a Rerun recording.

  python -m datasets.view output/seed_000000                       # writes ./seed_000000.rrd
  python -m datasets.view output/seed_000000 --trajectory orbit --out seed0.rrd
  python -m datasets.view output/seed_000000 --spawn               # opens the Rerun viewer (needs a display)
  python -m datasets.view output/seed_000005/phase_1               # stage 1 of a timeline seed (--phases)

Open a recording with ``rerun seed0.rrd`` (desktop) or ``rerun --web-viewer seed0.rrd``
(browser). What is logged, and the subsampling rule of large clouds: docs/viewer.md.
Bad input, or a spawned viewer that does not come up or take the recording: one line on stderr,
exit code 2, no .rrd written. Ctrl-C: exit 130, SIGTERM: exit 143, one line, no .rrd (and no
temporary file) left.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import signal
import socket
import sys
import threading
import time
from pathlib import Path

from generator.cli_args import OneLineParser, int_at_least

from .viewer.common import MAX_POINTS, quiet_rerun


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


class Terminated(BaseException):
    """SIGTERM arrived: unwinds like Ctrl-C's KeyboardInterrupt (the .rrd's temporary file is removed)."""


VIEWER_PORT = 9876      # the port rr.spawn starts the viewer on (and connects to)
VIEWER_GRACE_S = 3.0    # how long to wait for the viewer's port after rr.spawn's own wait (about 6 s) ran out
FLUSH_POLL_S = 1.0      # flush to the viewer in steps this long, checking between them that it is still there
# the stream to a spawned viewer, held until the process ends: dropping a stream whose viewer never
# came up makes Rerun wait for that viewer (5 s, or forever with a recording still buffered)
_VIEWER_STREAMS: list = []


def check_out(out: Path, seed: Path) -> None:
    """Refuse an output that is not a .rrd name, a folder, inside the seed folder or any
    generated seed, a file this project did not write, or where nothing can be written
    (exporters.write_guard)."""
    from exporters.write_guard import WriteRefused, check_output_file

    if out.suffix != ".rrd":
        raise ViewError(f"--out {out}: name a .rrd file")
    try:
        check_output_file(out, "--out", "rrd", inputs=(seed,))
    except WriteRefused as exc:
        raise ViewError(str(exc)) from None


def partial_file(out: Path, pid: int) -> Path:
    """The temporary file that process ``pid`` writes ``out`` to (datasets.viewer.common.recording_file)."""
    return out.with_name(f".{out.name}.{pid}.partial")


def stale_partials(out: Path) -> list[Path]:
    """Temporary files of ``out`` (:func:`partial_file`) whose process is gone on this machine:
    what a killed run left behind. The temporary file of a process that is still running is
    never among them."""
    pattern = re.compile(rf"\.{re.escape(out.name)}\.(\d+)\.partial")
    stale = []
    try:
        entries = list(out.parent.iterdir())
    except OSError:
        return []
    for entry in entries:
        m = pattern.fullmatch(entry.name)
        if m is None or int(m.group(1)) == os.getpid() or not entry.is_file() or entry.is_symlink():
            continue
        try:
            os.kill(int(m.group(1)), 0)  # signal 0: only asks whether the process exists
        except ProcessLookupError:
            stale.append(entry)
        except (OSError, OverflowError):  # alive but another user's (PermissionError), or not a pid: left alone
            pass
    return sorted(stale)


def remove_stale_partials(out: Path) -> None:
    for path in stale_partials(out):
        try:
            path.unlink()
        except OSError:  # gone already, or not ours to remove: best effort
            pass


def viewer_listening(port: int = VIEWER_PORT) -> bool:
    """Whether something accepts connections on 127.0.0.1:``port`` (where rr.spawn's viewer listens)."""
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=1.0):
            return True
    except OSError:
        return False


def wait_for_viewer(port: int = VIEWER_PORT, seconds: float = VIEWER_GRACE_S) -> bool:
    deadline = time.monotonic() + seconds
    while not viewer_listening(port):
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.2)
    return True


def display_named() -> str:
    for name in ("DISPLAY", "WAYLAND_DISPLAY"):
        if os.environ.get(name):
            return f"{name}={os.environ[name]}"
    return "the display"


def spawn_advice() -> str:
    return (f"check that {display_named()} is a running display, or write a file (--out seed.rrd) and open it "
            "with `rerun seed.rrd` where there is one, or in a browser with `rerun --web-viewer seed.rrd`")


def flush_to_viewer(rec, executable: Path, port: int = VIEWER_PORT) -> None:
    """rec.flush() to the spawned viewer, in steps of FLUSH_POLL_S: Rerun's own flush can wait
    forever on a viewer that went away (rerun-sdk 0.41), so between steps the viewer must still
    listen on its port, and Ctrl-C and SIGTERM are handled."""
    while True:
        try:
            rec.flush(timeout_sec=FLUSH_POLL_S)
            return
        except RuntimeError as exc:
            reason = (str(exc).splitlines() or [exc.__class__.__name__])[0]
            if "timed out" in reason.lower() and viewer_listening(port):
                continue  # a large recording still on its way to a viewer that is there
            if not viewer_listening(port):
                reason = f"it no longer listens on port {port}"
            raise ViewError(f"--spawn: the Rerun viewer {executable} did not take the recording ({reason}); "
                            f"{spawn_advice()}") from None


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
            _VIEWER_STREAMS.append(rec)
            rr.spawn(port=VIEWER_PORT, executable_path=str(executable), default_blueprint=layout, recording=rec)
            # the viewer listens before it opens its window: one that cannot (no X server at
            # $DISPLAY) is gone by now, and Rerun would buffer the recording for it and wait forever
            if not wait_for_viewer(VIEWER_PORT):
                raise ViewError(f"--spawn: the Rerun viewer {executable} did not start (nothing listens on port "
                                f"{VIEWER_PORT}); {spawn_advice()}")
            record_scene(rec, scene, kinds, args.max_points, progress)
            flush_to_viewer(rec, executable, VIEWER_PORT)
            return None
        remove_stale_partials(out)
        try:
            with recording_file(out, recording_id(scene), layout) as rec:
                record_scene(rec, scene, kinds, args.max_points, progress)
        except BaseException:  # also a signal that came while recording_file created the file, before its clean-up
            try:
                partial_file(out, os.getpid()).unlink(missing_ok=True)
            except OSError:
                pass
            raise
    except DatasetError as exc:
        raise ViewError(str(exc)) from None
    except OSError as exc:
        raise ViewError(f"{out}: cannot write it ({exc.strerror or exc.__class__.__name__})") from None
    return out


def terminate(signum, frame):
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # a second SIGTERM must not cut the clean-up short
    raise Terminated


def end_process(code: int) -> None:
    """End the process now, without interpreter shutdown: after a failed --spawn, Rerun's exit
    handler (and the stream's own clean-up) flushes to a viewer that is not there, and can wait
    for it forever."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(code)


def main(argv=None) -> int:
    args = parse_args(argv)
    quiet_rerun()
    main_thread = threading.current_thread() is threading.main_thread()  # signal handlers can only be set there
    if main_thread:
        previous = signal.signal(signal.SIGTERM, terminate)
    try:
        out = run(args)
    except ViewError as exc:
        print(f"error: {exc}", file=sys.stderr)
        code = 2
    except OSError as exc:  # e.g. a folder on the way that this user may not look into
        print(f"error: {exc.filename or 'input'}: {exc.strerror or exc}; check the path and its permissions", file=sys.stderr)
        code = 2
    except KeyboardInterrupt:
        print("error: interrupted; no recording was written", file=sys.stderr)
        code = 130
    except Terminated:
        print("error: terminated (SIGTERM); no recording was written", file=sys.stderr)
        code = 143
    else:
        if out is not None:
            print(out)
        return 0
    finally:
        if main_thread:
            signal.signal(signal.SIGTERM, signal.SIG_DFL if previous is None else previous)
    if args.spawn:
        end_process(code)
    return code


if __name__ == "__main__":
    sys.exit(main())

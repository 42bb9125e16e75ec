"""What every recording shares: the subsampling rule, the label colours as an annotation
context, and a file written whole or not at all."""

from __future__ import annotations

import math
import os
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from exporters.palette import UNLABELLED, label_colors
from exporters.write_guard import RRD_APPLICATION_ID
from generator.checks import check_integer

APPLICATION_ID = RRD_APPLICATION_ID  # what marks a recording as written by this project
MAX_POINTS = 1_000_000  # default cap on the points of one logged cloud
UNLABELLED_ID = 65535   # class id of unlabelled pixels and points (label -1)
FRAME_TIMELINE = "frame"  # sequence timeline: frame index t of a trajectory
TIME_TIMELINE = "time"    # duration timeline: the frame's timestamp, seconds


def subsample_stride(n: int, max_points: int) -> int:
    """The stated rule: a cloud of ``n`` points is logged as ``points[::k]`` with
    ``k = ceil(n / max_points)`` (every point when it fits), i.e. ``ceil(n / k)`` points."""
    return max(1, math.ceil(n / check_integer("max_points", max_points, 1)))


def subsampled_count(n: int, max_points: int) -> int:
    """How many of ``n`` points the rule keeps."""
    return math.ceil(n / subsample_stride(n, max_points)) if n else 0


def class_ids(labels: np.ndarray) -> np.ndarray:
    """Label ids as Rerun class ids (uint16): the same numbers, -1 (unlabelled) as 65535."""
    labels = np.asarray(labels)
    return np.where(labels < 0, UNLABELLED_ID, labels).astype(np.uint16)


def annotation_context(names: list[str]):
    """The label table as a Rerun annotation context: class id = label id, the class name and
    its colour (exporters.palette), plus 65535 'unlabelled' in black."""
    import rerun as rr

    colors = label_colors(names)
    infos = [rr.AnnotationInfo(id=i, label=name, color=tuple(int(c) for c in colors[i]))
             for i, name in enumerate(names)]
    infos.append(rr.AnnotationInfo(id=UNLABELLED_ID, label="unlabelled", color=UNLABELLED))
    return rr.AnnotationContext(infos)


def quiet_rerun() -> None:
    """Keep Rerun's own log lines (Rust's, on stderr) out of a command-line tool's one-line
    errors, unless the user set RUST_LOG; call before rerun is first imported."""
    os.environ.setdefault("RUST_LOG", "off")


@contextmanager
def recording_file(path: str | Path, recording_id: str, blueprint=None):
    """A RecordingStream whose recording is written to ``path`` (with ``blueprint`` as the
    default layout) when everything is logged: Rerun encodes it in memory (about 120 MB for a
    default seed) and this process writes it, through a temporary file renamed into place, so
    an interrupted run or a full disk leaves no half-written .rrd and a write failure is an
    OSError naming the file. (Rerun's own file sink can block forever when the disk refuses
    its first bytes, and reports a failure only as a RuntimeError on flush.)"""
    import rerun as rr

    path = Path(path)
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id)
    memory = rec.memory_recording()
    if blueprint is not None:
        rec.send_blueprint(blueprint, make_active=False, make_default=True)
    try:
        yield rec
        rec.flush()
        data = memory.drain_as_bytes()
    finally:
        rec.disconnect()
    write_whole(path, data)


def write_whole(path: Path, data: bytes) -> None:
    """``data`` written to ``path`` through a temporary file beside it, renamed into place
    once whole; the temporary file is removed whatever fails (a full disk: OSError ENOSPC)."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.partial")
    try:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)

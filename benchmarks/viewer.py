"""Seconds to write a seed's Rerun recording (python -m datasets.view) against the seed's
generation time (manifest.json "timing"), side by side with the strongest honest reference:
reading the same data through the same readers without logging it (what any viewer must pay).

Both passes in one process, alternating (reader pass first, so the file cache is warm for
both), best of ``--repeat``. The recording goes to a temporary folder and is deleted.

Usage: .venv/bin/python benchmarks/viewer.py SEED_FOLDER [--repeat 2] [--max-points 1000000]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from datasets import Scene  # noqa: E402
from datasets.viewer import MAX_POINTS, record_seed  # noqa: E402
from exporters.ground_truth import read_mesh, read_points  # noqa: E402


def read_only(folder: Path) -> float:
    """Everything the recording holds, read and converted, nothing logged."""
    t0 = time.perf_counter()
    scene = Scene(folder)
    scene.point_cloud()
    read_mesh(scene.path / "ground_truth")
    for seq in scene.sequences:
        _ = seq.coverage, seq.points
        for t in range(len(seq)):
            f = seq[t]
            np.round(np.clip(f.rgb.astype(np.float32), 0, 1) * 255).astype(np.uint8)
            vis = seq.visible_tracks(t)
            seq.point_positions(t, vis["ids"])
    return time.perf_counter() - t0


def record(folder: Path, out: Path, max_points: int) -> tuple[float, dict]:
    t0 = time.perf_counter()
    counts = record_seed(folder, out, max_points=max_points)
    return time.perf_counter() - t0, counts


def record_static(folder: Path, out: Path, max_points: int) -> float:
    """The part that does not grow with the frames: label table, GT cloud, mesh."""
    from datasets.viewer.common import recording_file
    from datasets.viewer.seed import record_scene

    t0 = time.perf_counter()
    with recording_file(out, "static") as rec:
        record_scene(rec, Scene(folder), [], max_points)
    return time.perf_counter() - t0


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("seed", type=Path)
    p.add_argument("--repeat", type=int, default=2)
    p.add_argument("--max-points", type=int, default=MAX_POINTS)
    p.add_argument("--estimate-frames", type=int, default=80,
                   help="also extrapolate the recording time to this many frames (default 80: a default seed)")
    args = p.parse_args()
    scene = Scene(args.seed)
    generation = float(scene.manifest["timing"]["seconds"])
    n_gt = len(read_points(args.seed / "ground_truth").vertex["x"])
    frames = {k: len(scene[k]) for k in scene.trajectories}
    reads, writes, statics, size, counts = [], [], [], 0, {}
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "seed.rrd"
        for _ in range(args.repeat):
            reads.append(read_only(args.seed))
            seconds, counts = record(args.seed, out, args.max_points)
            writes.append(seconds)
            statics.append(record_static(args.seed, Path(tmp) / "static.rrd", args.max_points))
            size = out.stat().st_size
    w, r, fixed = min(writes), min(reads), min(statics)
    n_frames = sum(frames.values())
    per_frame = (w - fixed) / n_frames
    print(f"seed {scene.seed}: {sum(frames.values())} frames {frames}, GT cloud {n_gt:,} points -> "
          f"{counts['points']:,} logged (max {args.max_points:,})")
    print(f"generation (manifest timing): {generation:.1f} s")
    print(f"recording written: {w:.2f} s (best of {args.repeat}: {', '.join(f'{x:.2f}' for x in writes)}), "
          f"{size / 1e6:.0f} MB = {100 * w / generation:.1f}% of the generation time (target <= 10%)")
    print(f"reference, same reads without logging: {r:.2f} s; logging and writing add {w - r:.2f} s "
          f"(x{w / r:.2f} of reading alone)")
    print(f"split: label table + GT cloud + mesh {fixed:.2f} s, then {per_frame:.3f} s per frame; "
          f"at {args.estimate_frames} frames: {fixed + per_frame * args.estimate_frames:.1f} s (extrapolated)")


if __name__ == "__main__":
    main()

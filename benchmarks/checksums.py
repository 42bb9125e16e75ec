"""Cost of the tracks.h5 checksums (Fletcher-32 on every dataset, HDF5 1.10 metadata):
write time, full read time and file size, side by side with the same writer without them
(HDF5's earliest format, no filter: the layout before issue #13).

Synthetic but realistic sizes: N surface points, T frames, V points visible per frame
(positions drawn once; visibility a random subset per frame), written frame by frame by
``exporters.tracks.TrackWriter``, read back by ``exporters.tracks.read_tracks``; both runs
in one process, alternating, best of ``--repeat``.

Usage: .venv/bin/python benchmarks/checksums.py [--points 1000000] [--frames 300] [--visible 60000]
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

from exporters import hdf5, tracks  # noqa: E402


def write(path: Path, table: dict, frames: int, visible: int) -> float:
    rng = np.random.default_rng(0)
    K = np.array([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]])
    t0 = time.perf_counter()
    w = tracks.TrackWriter(path, table, [], ["a", "b"], K, 640, 480, queries=256, seed=0)
    world = table["local"]
    for t in range(frames):
        pose = np.eye(4)
        pose[:3, 3] = [0.0, -50.0 + 0.1 * t, 1.5]
        pose[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]  # looking along +y
        mask = np.zeros(len(world), bool)
        mask[rng.choice(len(world), visible, replace=False)] = True
        w.add_frame(t / 10, pose, world, mask, np.zeros((0, 4, 4)), float(t) / frames)
    w.close()
    return time.perf_counter() - t0


def read(path: Path) -> float:
    t0 = time.perf_counter()
    tracks.read_tracks(path)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=1_000_000)
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--visible", type=int, default=60_000)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    rng = np.random.default_rng(1)
    n = args.points
    table = {"local": np.column_stack([rng.uniform(-50, 50, n), rng.uniform(0, 100, n), rng.uniform(0, 10, n)]),
             "labels": rng.integers(0, 10, n), "instance": rng.integers(0, 500, n), "dynamic_object": np.full(n, -1)}
    settings = {"checksummed": (hdf5.LIBVER, {"fletcher32": True}), "plain (before)": (("earliest", "v200"), {})}
    results = {k: {"write": [], "read": [], "bytes": 0} for k in settings}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.repeat):
            for name, (libver, checksum) in settings.items():
                hdf5.LIBVER, hdf5.CHECKSUM, tracks.CHECKSUM = libver, checksum, checksum
                path = Path(tmp) / "tracks.h5"
                results[name]["write"].append(write(path, table, args.frames, args.visible))
                results[name]["read"].append(read(path))
                results[name]["bytes"] = path.stat().st_size
    print(f"{n:,} points, {args.frames} frames, {args.visible:,} visible per frame "
          f"({args.frames * args.visible:,} visibility rows); best of {args.repeat}")
    print(f"{'layout':<16}{'write s':>10}{'read s':>10}{'MB':>10}")
    for name, r in results.items():
        print(f"{name:<16}{min(r['write']):>10.2f}{min(r['read']):>10.2f}{r['bytes'] / 1e6:>10.1f}")
    a, b = results["checksummed"], results["plain (before)"]
    print(f"ratio checksummed / plain: write {min(a['write']) / min(b['write']):.3f}, "
          f"read {min(a['read']) / min(b['read']):.3f}, size {a['bytes'] / b['bytes']:.3f}")


if __name__ == "__main__":
    main()

"""Frames per second read by ``datasets.FrameDataset`` (RGB + depth + labels, 640x480),
single process and with 2 worker processes, side by side with reading the same EXR files
with the plain OpenEXR API in a loop.

Usage: .venv/bin/python benchmarks/loader.py [--data SEED_FOLDER] [--frames 20] [--repeat 5]
(without --data, a small site is generated first with python -m generator).
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
import OpenEXR  # noqa: E402

from datasets import FrameDataset  # noqa: E402


def plain(paths: list[str]) -> float:
    total = 0.0
    for p in paths:
        with OpenEXR.File(p, separate_channels=True) as f:  # format 0.5: one part per component type
            parts = {part.name(): part.channels for part in f.parts}
            rgb = np.stack([parts["colour"][c].pixels for c in "RGB"], axis=-1)
            depth, label = parts["data"]["Z"].pixels, parts["ids"]["label"].pixels.view(np.int32)
        total += float(rgb[0, 0, 0]) + float(depth[0, 0]) + float(label[0, 0])
    return total


def loader(args: tuple[str, list[int]]) -> float:
    folder, indices = args
    ds = FrameDataset(folder, keys=("rgb_linear", "depth", "label"))
    total = 0.0
    for i in indices:
        s = ds[i]
        total += float(s["rgb_linear"][0, 0, 0]) + float(s["depth"][0, 0]) + float(s["label"][0, 0])
    return total


def timed(fn, *args) -> float:
    t0 = time.perf_counter()
    fn(*args)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path)
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    folder = args.data
    if folder is None:
        out = Path(tempfile.mkdtemp())
        subprocess.run([sys.executable, "-m", "generator", "--out", str(out), "--seeds", "0", "--scene-preset", "small",
                        "--frames", str(args.frames), "--trajectory", "orbit", "--scoring-density", "1"],
                       check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
        folder = out / "seed_000000"
    ds = FrameDataset(folder, keys=("rgb_linear", "depth", "label"))
    n = len(ds)
    paths = [str(ds.scenes[0][kind].exr_path(i)) for _, kind, i in ds.index]
    all_idx = list(range(n)) * args.repeat
    all_paths = paths * args.repeat
    plain(paths), loader((str(folder), list(range(n))))  # warm the page cache
    rows = []
    for label, fn_plain, fn_ours in (
        ("1 process", lambda: plain(all_paths), lambda: loader((str(folder), all_idx))),
        ("2 worker processes", lambda: _pool(plain, [all_paths[0::2], all_paths[1::2]]),
         lambda: _pool(loader, [(str(folder), all_idx[0::2]), (str(folder), all_idx[1::2])])),
    ):
        best_plain = min(timed(fn_plain) for _ in range(3))
        best_ours = min(timed(fn_ours) for _ in range(3))
        rows.append((label, len(all_idx) / best_plain, len(all_idx) / best_ours, best_ours / best_plain - 1))
    print(f"{n} frames of {ds[0]['rgb_linear'].shape[1]}x{ds[0]['rgb_linear'].shape[0]}, read {args.repeat} times, best of 3")
    print("| setting | plain OpenEXR loop | FrameDataset | loader overhead |")
    print("|---|---|---|---|")
    for label, a, b, over in rows:
        print(f"| {label} | {a:.1f} frames/s | {b:.1f} frames/s | {over:+.1%} |")


def _pool(fn, chunks):
    with mp.get_context("fork").Pool(len(chunks)) as pool:
        return pool.map(fn, chunks)


if __name__ == "__main__":
    main()

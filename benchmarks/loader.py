"""Frames per second read by ``datasets.FrameDataset`` (640x480) for two key sets, single
process and with 2 worker processes, side by side with plain loops reading the same files:

- ``linear``: keys rgb_linear + depth + label (what needs the frame EXR);
- ``segmentation``: keys rgb + label (display colour and ids: both have PNGs of their own).

References: (a) the plain OpenEXR API (``OpenEXR.File``: it decodes every part of the file,
it has no part selection), plus PIL for the display PNG; (b) the strongest plain loop we
know: only the parts each key needs, with OpenImageIO (``read_image(subimage, ..., chbegin,
chend)``; a test dependency) for EXR-only keys and PIL for keys with an exact PNG.

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
import OpenImageIO as oiio  # noqa: E402
from PIL import Image  # noqa: E402

from datasets import FrameDataset  # noqa: E402

KEY_SETS = {"linear": ("rgb_linear", "depth", "label"), "segmentation": ("rgb", "label")}


def plain_openexr(args: tuple[str, list[str]]) -> float:
    which, paths = args
    total = 0.0
    for p in paths:
        with OpenEXR.File(p, separate_channels=True) as f:  # format 0.5: one part per component type
            parts = {part.name(): part.channels for part in f.parts}
            label = parts["ids"]["label"].pixels.view(np.int32)
            if which == "linear":
                rgb = np.stack([parts["colour"][c].pixels for c in "RGB"], axis=-1)
                depth = parts["data"]["Z"].pixels
            else:
                rgb, depth = _display_rgb(p), label
        total += float(rgb[0, 0, 0]) + float(depth[0, 0]) + float(label[0, 0])
    return total


def plain_parts(args: tuple[str, list[str]]) -> float:
    which, paths = args
    total = 0.0
    for p in paths:
        label = np.asarray(Image.open(p.replace("frame_", "label_").replace(".exr", ".png"))).astype(np.int32) - 1
        if which == "linear":
            f = oiio.ImageInput.open(p)
            rgb = f.read_image(0, 0, 0, 3, "unknown")  # part colour: R, G, B
            depth = f.read_image(1, 0, 0, 1, "unknown")[..., 0]  # part data: Z is its first channel
            f.close()
        else:
            rgb, depth = _display_rgb(p), label
        total += float(rgb[0, 0, 0]) + float(depth[0, 0]) + float(label[0, 0])
    return total


def _display_rgb(exr_path: str) -> np.ndarray:
    """The display PNG as FrameDataset returns it: float32 in [0, 1]."""
    return np.asarray(Image.open(exr_path.replace("frame_", "rgb_").replace(".exr", ".png"))).astype(np.float32) / 255


def loader(args: tuple[str, str, list[int]]) -> float:
    which, folder, indices = args
    keys = KEY_SETS[which]
    ds = FrameDataset(folder, keys=keys)
    total = 0.0
    for i in indices:
        s = ds[i]
        total += sum(float(s[k].flat[0]) for k in keys)
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
    ds = FrameDataset(folder, keys=KEY_SETS["linear"])
    n = len(ds)
    paths = [str(ds.scenes[0][kind].exr_path(i)) for _, kind, i in ds.index]
    all_idx, all_paths = list(range(n)) * args.repeat, paths * args.repeat
    rows = []
    for which in KEY_SETS:
        jobs = ((plain_openexr, (which, all_paths)), (plain_parts, (which, all_paths)),
                (loader, (which, str(folder), all_idx)))
        for fn, job in jobs:
            fn((*job[:-1], job[-1][:n]))  # warm the page cache
        for label, split in (("1 process", 1), ("2 worker processes", 2)):
            best = [min(timed(_run, fn, [(*job[:-1], job[-1][k::split]) for k in range(split)]) for _ in range(3))
                    for fn, job in jobs]
            rows.append((which, label, *(len(all_idx) / b for b in best), best[2] / min(best[:2]) - 1))
    print(f"{n} frames of {ds[0]['rgb_linear'].shape[1]}x{ds[0]['rgb_linear'].shape[0]}, read {args.repeat} times, "
          "best of 3")
    print("| keys | setting | plain OpenEXR loop (whole file) | plain loop, needed parts only | FrameDataset | "
          "loader vs the faster plain loop |")
    print("|---|---|---|---|---|---|")
    for which, label, a, b, c, over in rows:
        print(f"| {' + '.join(KEY_SETS[which])} | {label} | {a:.1f} frames/s | {b:.1f} frames/s | {c:.1f} frames/s "
              f"| {over:+.1%} time |")


def _run(fn, chunks):
    """``fn`` on each chunk: in this process for one chunk, else in one worker process each."""
    if len(chunks) == 1:
        return [fn(chunks[0])]
    with mp.get_context("fork").Pool(len(chunks)) as pool:
        return pool.map(fn, chunks)


if __name__ == "__main__":
    main()

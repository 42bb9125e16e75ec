"""Write and read cost of the frame EXR per part and lossless compression: for each part
of an existing frame (colour HALF, data FLOAT, ids UINT), its size, the time to write it
with ``exporters.exr.write_frame`` and to read it back with ``exporters.exr.read_frame_exr``,
for every lossless compression ``write_frame`` offers (checked: values read back equal).
Then the whole frame with the default compression, single-threaded against OpenEXR's thread
pool on every core (what ``exporters.exr`` turns on), alternating.

Usage: .venv/bin/python benchmarks/frame_exr.py FRAME_EXR [--repeat 10]
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
import OpenEXR  # noqa: E402

from exporters.exr import COMPRESSIONS, read_frame_exr, write_frame  # noqa: E402
from exporters.modalities import MODALITIES  # noqa: E402


def best_ms(fn, repeat: int) -> float:
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("frame", type=Path)
    ap.add_argument("--repeat", type=int, default=10)
    args = ap.parse_args()
    frame = read_frame_exr(args.frame)
    header = frame.pop("header")
    labels = {"buildee/labels": header["buildee/labels"]} if "buildee/labels" in header else {}
    parts: dict[str, dict] = {}
    for name, array in frame.items():
        parts.setdefault(MODALITIES[name].part, {})[name] = array
    shape = next(iter(frame.values())).shape[:2]
    print(f"{args.frame} ({shape[1]}x{shape[0]}), best of {args.repeat}")
    print("| part (modalities) | compression | size | write | read |")
    print("|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for part, outputs in parts.items():
            for compression in COMPRESSIONS:
                path = Path(tmp) / f"{part}_{compression}.exr"
                write = best_ms(lambda: write_frame(path, outputs, compression, labels), args.repeat)
                read = best_ms(lambda: read_frame_exr(path), args.repeat)
                back = read_frame_exr(path)
                assert all(np.array_equal(back[k], v, equal_nan=True) for k, v in outputs.items()), compression
                print(f"| {part} ({', '.join(outputs)}) | {compression} | {path.stat().st_size / 1e6:.2f} MB | "
                      f"{write:.1f} ms | {read:.1f} ms |")
        threads_table(frame, labels, Path(tmp) / "frame.exr", args.repeat)


def threads_table(frame: dict, labels: dict, path: Path, repeat: int) -> None:
    pool = OpenEXR.global_thread_count()
    times: dict[int, list[tuple[float, float]]] = {0: [], pool: []}
    for _ in range(3):
        for threads in times:
            OpenEXR.set_global_thread_count(threads)
            times[threads].append((best_ms(lambda: write_frame(path, frame, "zip", labels), repeat),
                                   best_ms(lambda: read_frame_exr(path), repeat)))
    OpenEXR.set_global_thread_count(pool)
    print("\n| whole frame, zip | write | read |\n|---|---|---|")
    for threads, runs in times.items():
        print(f"| OpenEXR threads {threads} | {min(r[0] for r in runs):.1f} ms | {min(r[1] for r in runs):.1f} ms |")


if __name__ == "__main__":
    main()

"""Cost of the checked reads (issue #36) for training loaders: PNG frames decoded once every
chunk passes its CRC, and a seed's JSON files compared with the manifest's sha256, side by
side in one process with the same reads unchecked (Pillow's decode of the same file; json of
the same bytes). Best of ``--repeat`` for each.

Usage: .venv/bin/python benchmarks/read_checks.py SEED_FOLDER [--kind orbit] [--repeat 5] [--json FILE]
(SEED_FOLDER: a seed of the main job, e.g. output/seed_000000)
"""

from __future__ import annotations

import argparse
import io
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402

from exporters.frames import checked_png_bytes  # noqa: E402
from exporters.jsonfile import read_json_file  # noqa: E402
from exporters.manifest import forget_manifests  # noqa: E402


def best(fn, paths, repeat: int) -> float:
    """Best over ``repeat`` passes of the mean seconds per file of ``fn`` over ``paths``."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for p in paths:
            fn(p)
        times.append((time.perf_counter() - t0) / len(paths))
    return min(times)


def decode_plain(path: Path) -> np.ndarray:
    with Image.open(path) as im:
        return np.asarray(im)


def decode_checked(path: Path) -> np.ndarray:
    with Image.open(io.BytesIO(checked_png_bytes(path))) as im:
        return np.asarray(im)


def json_plain(path: Path):
    return json.loads(path.read_bytes())


def json_checked_cold(path: Path):
    forget_manifests()  # as the first read of a process (a DataLoader worker)
    return read_json_file(path, "file")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("seed", type=Path)
    p.add_argument("--kind", default="orbit")
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--json", type=Path)
    args = p.parse_args(argv)
    folder = args.seed / args.kind
    rows = {}
    for prefix in ("rgb", "label", "instance"):
        paths = sorted(folder.glob(f"{prefix}_*.png"))
        if paths:
            plain, checked = best(decode_plain, paths, args.repeat), best(decode_checked, paths, args.repeat)
            rows[f"{prefix} PNG ({len(paths)} files, {paths[0].stat().st_size / 1e3:.0f} kB)"] = (plain, checked)
    for name in ("coco.json", "boxes3d.json", "frames.json"):
        path = folder / name
        if path.is_file():
            plain = best(json_plain, [path], args.repeat)
            warm = best(lambda q: read_json_file(q, "file"), [path], args.repeat)
            cold = best(json_checked_cold, [path], args.repeat)
            label = f"{name} ({path.stat().st_size / 1e3:.0f} kB)"
            rows[f"{label}, manifest cached"], rows[f"{label}, manifest read too"] = (plain, warm), (plain, cold)
    print(f"{'read':<52} {'unchecked':>10} {'checked':>10} {'ratio':>7}")
    for name, (plain, checked) in rows.items():
        print(f"{name:<52} {plain * 1e3:>8.2f} ms {checked * 1e3:>7.2f} ms {checked / plain:>6.2f}x")
    if args.json:
        args.json.write_text(json.dumps({k: {"unchecked_s": a, "checked_s": b} for k, (a, b) in rows.items()}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

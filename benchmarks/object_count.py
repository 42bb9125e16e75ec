"""Simulator load time against the number of objects: .blend files of N one-triangle objects
(each its own mesh, on a 100-wide grid in front of the camera), ``Simulator(path)`` timed in a
fresh process per file (Blender holds one file per process; the import of bpy is not timed).

Prints each load time, the increments 5,000 -> 10,000 and 10,000 -> 20,000 and their ratio
(linear cost: 2; issue #36 accepts at most 2.6), and the time to refuse a file over Blender's
32,767 object pass indices (``--over``; the acceptance: less than the smallest count's load).
The files are built once into ``--cache`` (a process each) and reused.

Usage: .venv/bin/python benchmarks/object_count.py [--counts 5000 10000 20000] [--over 40000]
       [--repeat 3] [--cache /tmp/buildee-object-count] [--json results.json]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def build(count: int, path: Path) -> None:
    """Write a .blend of ``count`` one-triangle objects and a camera looking at them."""
    from generator.blender import session

    bpy = session.bpy
    session.new_empty_file()
    scene = bpy.context.scene
    for i in range(count):
        mesh = bpy.data.meshes.new(f"Tri{i}")
        mesh.from_pydata([(0, 0, 0), (0.5, 0, 0), (0, 0, 0.5)], [], [(0, 1, 2)])
        obj = bpy.data.objects.new(f"Tri{i}", mesh)
        obj.location = (i % 100 - 50, 10 + i // 100, 0)
        scene.collection.objects.link(obj)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.rotation_euler = (1.5708, 0.0, 0.0)  # looking along +y
    scene.collection.objects.link(cam)
    scene.camera = cam
    session.save_blend(path)


def load(path: Path) -> dict:
    """Seconds to construct a Simulator on ``path`` (or to refuse it), in this process."""
    from generator import Simulator

    t0 = time.perf_counter()
    try:
        sim = Simulator(path)
        return {"seconds": time.perf_counter() - t0, "objects": len(sim.object_names)}
    except ValueError as exc:
        return {"seconds": time.perf_counter() - t0, "refused": str(exc)}


def _child(*args) -> str:
    r = subprocess.run([sys.executable, __file__, *map(str, args)], capture_output=True, text=True, cwd=ROOT)
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(map(str, args))} failed: {r.stderr.strip()[-2000:]}")
    return r.stdout


def blend_of(count: int, cache: Path) -> Path:
    path = cache / f"triangles_{count}.blend"
    if not path.exists():
        _child("--build", count, path)
    return path


def timed(count: int, cache: Path, repeat: int) -> dict:
    """The fastest of ``repeat`` loads (each in a fresh process) of ``count`` objects."""
    runs = [json.loads(_child("--load", blend_of(count, cache)).splitlines()[-1]) for _ in range(repeat)]
    best = min(runs, key=lambda r: r["seconds"])
    return best | {"runs": [r["seconds"] for r in runs]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--counts", type=int, nargs=3, default=[5000, 10000, 20000])
    ap.add_argument("--over", type=int, default=40000, help="a count over Blender's limit (0: skip)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--cache", type=Path, default=Path("/tmp/buildee-object-count"))
    ap.add_argument("--json", type=Path, default=None, help="write the results here too")
    ap.add_argument("--build", nargs=2, metavar=("COUNT", "PATH"), help=argparse.SUPPRESS)
    ap.add_argument("--load", type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.build:
        return build(int(args.build[0]), Path(args.build[1]))
    if args.load:
        return print(json.dumps(load(args.load)))
    args.cache.mkdir(parents=True, exist_ok=True)
    results = {"loads": {}}
    for n in args.counts:
        results["loads"][n] = timed(n, args.cache, args.repeat)
        run = results["loads"][n]
        print(f"{n:>6} objects: {run['seconds']:.2f} s (runs: {', '.join(f'{s:.2f}' for s in run['runs'])})", flush=True)
    t = [results["loads"][n]["seconds"] for n in args.counts]
    results["increments"] = [t[1] - t[0], t[2] - t[1]]
    results["ratio"] = (t[2] - t[1]) / (t[1] - t[0])
    print(f"increments: {t[1] - t[0]:.2f} s, then {t[2] - t[1]:.2f} s: ratio {results['ratio']:.2f} (linear: "
          f"{(args.counts[2] - args.counts[1]) / (args.counts[1] - args.counts[0]):.2f})")
    if args.over:
        over = results["over"] = timed(args.over, args.cache, args.repeat)
        print(f"{args.over:>6} objects: {'refused' if 'refused' in over else 'loaded'} in {over['seconds']:.2f} s "
              f"({over['seconds'] / t[0]:.2f} of the {args.counts[0]}-object load): {over.get('refused', '')}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()

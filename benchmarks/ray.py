"""Throughput of the Ray executor against the local executor on the same tiny seeds, side by
side in one run, on a real two-node Ray cluster on this machine's loopback
(tests/loopback_ray.py: one CPU per node, so two seeds at once).

    python benchmarks/ray.py [--seeds 31 32 33 34] [--repeat 1]

Each variant is one real `python -m generator` command over the same seeds into a fresh
folder, timed from start to exit:

    local -w1   the local executor as by default (one seed at a time; Cycles uses both cores)
    local -w2   the local executor with --workers 2 (two seeds at once, like the two nodes)
    ray         --executor ray --cpus-per-seed 1 on the two nodes (two seeds at once)
    ray, done   the same Ray command again over the finished folder: joining the cluster,
                checking the nodes, checking and skipping every seed (Ray's fixed cost)

Ray's overhead per seed = (ray - local -w2) / seeds, in seconds of wall time; the outputs
of the Ray run are checked against the local ones (manifest hashes, as tests/test_ray.py)."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from conftest import TINY  # noqa: E402  (the tests' tiniest batch configuration)
from loopback_ray import env, loopback_cluster  # noqa: E402


def _run(out: Path, seeds: list[str], extra: list[str], environ: dict) -> float:
    t = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "generator", "--out", str(out), *TINY, "--seeds", *seeds, *extra],
                       cwd=ROOT, env=environ, capture_output=True, text=True)
    seconds = time.perf_counter() - t
    if r.returncode != 0:
        sys.exit(f"{' '.join(extra) or 'local'} failed (exit {r.returncode}):\n{r.stdout[-2000:]}{r.stderr[-2000:]}")
    return seconds


def _hashes(out: Path, seed: str) -> dict:
    files = json.loads((out / f"seed_{int(seed):06d}" / "manifest.json").read_text())["files"]
    return {k: v["sha256"] for k, v in files.items() if not k.endswith((".log", ".blend"))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", nargs="+", default=["31", "32", "33", "34"])
    ap.add_argument("--repeat", type=int, default=1)
    args = ap.parse_args()
    n = len(args.seeds)
    times: dict[str, list[float]] = {}
    with tempfile.TemporaryDirectory(prefix="bench-ray-") as tmp, loopback_cluster(nodes=2, cpus=1) as address:
        ray_args = ["--executor", "ray", "--cpus-per-seed", "1", "--ray-address", address]
        for rep in range(args.repeat):
            outs = {name: Path(tmp) / f"{name}-{rep}" for name in ("local1", "local2", "ray")}
            for name, extra, out in (("local -w1", [], outs["local1"]), ("local -w2", ["--workers", "2"], outs["local2"]),
                                     ("ray", ray_args, outs["ray"]), ("ray, done", ray_args, outs["ray"])):
                times.setdefault(name, []).append(_run(out, args.seeds, extra, env()))
                print(f"{name:>10}: {times[name][-1]:6.1f} s", flush=True)
            for s in args.seeds:
                if _hashes(outs["ray"], s) != _hashes(outs["local1"], s):
                    sys.exit(f"seed {s}: the Ray run's files differ from the local run's")
    best = {k: min(v) for k, v in times.items()}
    print(f"\n{n} tiny seeds ({' '.join(TINY)}), 2 loopback nodes x 1 CPU, best of {args.repeat}:")
    for name, t in best.items():
        rate = "" if name == "ray, done" else f"  {n / t * 3600:7.0f} seeds/h"
        print(f"  {name:<10} {t:6.1f} s{rate}")
    print(f"  Ray's overhead per seed against local -w2: {(best['ray'] - best['local -w2']) / n:+.2f} s "
          f"(ray / local -w2 = {best['ray'] / best['local -w2']:.2f}x); fixed cost of a Ray run "
          f"(join, node check, skip {n} seeds): {best['ray, done']:.1f} s")
    print("  outputs: every file of the Ray run equals the local run's (sha256), Blender's log and .blend aside")


if __name__ == "__main__":
    main()

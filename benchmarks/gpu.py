"""Rendering on a GPU against the CPU of the same machine: seconds per frame and quality per
preset, and whether the ground-truth passes agree between the two devices.

Same site, poses and quality measure as ``benchmarks/render.py`` (medium site of ``--seed``,
the batch job's 40-frame orbit, 640x480, ``Simulator.render()``; PSNR and SSIM of the display
image against the 256-sample CPU reference of the same frame, read from ``--cache`` when it is
there). For each preset, each device renders one untimed frame first (on a GPU the first render
also loads the kernels: its time is reported as "first render"), then ``--repeats`` rounds of
``--frames``; the devices alternate by round. Agreement: for every frame of the preview preset,
depth, label and instance maps of the GPU render against the CPU render (bit-equal share, and
the largest depth difference), with the ground truth of ``--ground-truth``: ``geometry`` (the
Simulator's default, cast by us on the CPU: expected bit-equal) or ``renderer`` (each device's
own Cycles passes, docs/rendering.md "Ground truth").

Usage: python benchmarks/gpu.py [--presets preview default high] [--frames 0 13 26] [--repeats 3]
       [--devices cpu gpu] [--ground-truth geometry|renderer] [--json results.json]
Needs a machine where ``python -m generator.blender.devices`` names a GPU (else 'gpu' is a
one-line error).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from generator.blender import session  # noqa: E402

bpy = session.bpy
import numpy as np  # noqa: E402

from generator import Simulator  # noqa: E402
from render import REFERENCE, RESOLUTION, medium_site, orbit_poses, psnr, ssim  # noqa: E402  (benchmarks/render.py)


def render_frame(sim: Simulator, poses: np.ndarray, i: int):
    sim.set_frame(1 + i)
    sim.set_world_from_camera(poses[i], check_collisions=False)
    t0 = time.perf_counter()
    out = sim.render()
    return time.perf_counter() - t0, out


def agreement(a, b) -> dict:
    """How the ground-truth maps of two renders of the same frame compare."""
    da, db = a.depth, b.depth
    both = np.isfinite(da) & np.isfinite(db)
    return {
        "depth_bit_equal": float(np.mean((da == db) | (np.isinf(da) & np.isinf(db)))),
        "depth_max_abs_diff_m": float(np.max(np.abs(da[both] - db[both]))) if both.any() else 0.0,
        "depth_within_1e-5_relative": float(np.mean(np.abs(da[both] - db[both]) <= 1e-5 * da[both])) if both.any() else 1.0,
        "depth_pixels_off_by_over_1cm": int(np.sum(np.abs(da[both] - db[both]) > 0.01)),
        "depth_finite_mismatch": int(np.sum(np.isfinite(da) != np.isfinite(db))),
        "label_pixels_differing": int(np.sum(a.seg != b.seg)),
        "label_equal": float(np.mean(a.seg == b.seg)),
        "instance_equal": float(np.mean(a.instance == b.instance)),
        "rgb_psnr_between_devices": psnr(a.rgb, b.rgb),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", nargs="+", default=["preview", "default", "high"])
    ap.add_argument("--frames", type=int, nargs="+", default=[0, 13, 26], help="orbit frame indices (0-39)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--devices", nargs="+", default=["cpu", "gpu"], choices=["cpu", "gpu"])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cache", type=Path, default=Path("/tmp/buildee-render-bench"),
                    help="site and 256-sample references (benchmarks/render.py makes them)")
    ap.add_argument("--json", type=Path, default=None, help="write the results here too")
    ap.add_argument("--ground-truth", choices=["geometry", "renderer"], default="geometry",
                    help="where depth, labels and ids come from (Simulator(ground_truth=...))")
    ap.add_argument("--save", type=Path, default=None, help="save each device's depth/label/instance of the frames (npz)")
    args = ap.parse_args()
    args.cache.mkdir(parents=True, exist_ok=True)
    sim = Simulator(medium_site(args.seed, args.cache), points_density=0.1, seed=args.seed, render_preset="preview",
                    ground_truth=args.ground_truth)
    sim.configure_render(resolution=RESOLUTION)
    poses = orbit_poses(sim, args.seed)
    key = hashlib.sha1(json.dumps([vars(REFERENCE), bpy.app.version_string]).encode()).hexdigest()[:10]
    refs = {}
    for i in args.frames:
        path = args.cache / f"ref-{args.seed}-orbit{i}-{key}.npy"
        if path.exists():
            refs[i] = np.load(path)
    results: dict = {"frames": args.frames, "references": sorted(refs), "ground_truth": args.ground_truth, "presets": {}}
    names = {}
    for preset in args.presets:
        per = {d: {"times": [], "quality": {}, "outputs": {}} for d in args.devices}
        for d in args.devices:
            sim.configure_render(preset, device=d, resolution=RESOLUTION)
            names[d] = sim.render_device
            per[d]["first"] = render_frame(sim, poses, args.frames[-1])[0]
        for _ in range(args.repeats):
            for d in args.devices:
                sim.configure_render(preset, device=d, resolution=RESOLUTION)
                render_frame(sim, poses, args.frames[-1])  # untimed: re-synchronisation after the switch
                for i in args.frames:
                    dt, out = render_frame(sim, poses, i)
                    per[d]["times"].append(dt)
                    per[d]["outputs"][i] = out
                    if i in refs:
                        per[d]["quality"][i] = (psnr(out.rgb, refs[i]), ssim(out.rgb, refs[i]))
        entry = {}
        for d in args.devices:
            q = per[d]["quality"]
            entry[d] = {"device": names[d], "s_per_frame": float(np.median(per[d]["times"])),
                        "first_render_s": per[d]["first"], "runs": per[d]["times"],
                        "psnr_db": float(np.mean([v[0] for v in q.values()])) if q else None,
                        "ssim": float(np.mean([v[1] for v in q.values()])) if q else None}
            print(f"{preset} on {names[d]}: {entry[d]['s_per_frame']:.3f} s/frame (first render "
                  f"{per[d]['first']:.2f} s)" + (f", PSNR {entry[d]['psnr_db']:.2f} dB, SSIM {entry[d]['ssim']:.4f}"
                                                 if q else ""), flush=True)
        if set(args.devices) == {"cpu", "gpu"}:
            entry["speedup"] = entry["cpu"]["s_per_frame"] / entry["gpu"]["s_per_frame"]
            entry["agreement"] = {i: agreement(per["cpu"]["outputs"][i], per["gpu"]["outputs"][i]) for i in args.frames}
            if args.save:
                np.savez_compressed(args.save / f"{preset}-maps.npz", **{
                    f"{d}_{k}_{i}": getattr(per[d]["outputs"][i], k) for d in args.devices for i in args.frames
                    for k in ("depth", "seg", "instance")})
            print(f"{preset}: the GPU takes {entry['speedup']:.1f}x fewer seconds per frame; agreement per frame: "
                  + json.dumps(entry["agreement"]), flush=True)
        results["presets"][preset] = entry
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()

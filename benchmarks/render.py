"""Render speed and quality per preset on a real medium site: seconds per frame and PSNR/SSIM
of the display image against a 256-sample reference of the same frame.

Builds the medium site of ``--seed`` (cached under ``--cache``), plans the batch job's orbit
(40 frames) and renders ``--frames`` of its poses at 640x480 with ``Simulator.render()``.
For each preset it alternates two settings, in the same process, on the same frames:
- before: the preset as it was before the render-throughput work (issue 15), exactly;
- after:  the preset as it is now (``generator.render_settings.PRESETS``).
Each block starts with one untimed 1-sample render (settings changes make Cycles re-synchronise).
Quality: PSNR (dB, peak 1) and SSIM (Gaussian window, sigma 1.5, on luminance) of the
display-referred RGB against a reference rendered once per frame and cached: 256 samples,
no adaptive sampling, 12 bounces of every kind, OpenImageDenoise with the accurate
prefilter and its large network. Timings: median seconds per frame of ``Simulator.render()``,
wall clock and CPU time of all its threads (the latter barely moves when other work shares the machine).

``--set`` changes RenderSettings fields of the 'after' presets; ``--raw`` sets Blender properties
that RenderSettings does not hold (for trying a Cycles setting before it becomes one): ``NAME``
is ``scene.cycles.NAME``, ``view_layer.NAME`` and ``view_layer.cycles.NAME`` apply to every view
layer; the 'before' blocks get the values these properties had when the site was opened.

Usage: .venv/bin/python benchmarks/render.py [--presets preview default high] [--frames 0 13 26]
       [--repeats 2] [--references-only] [--set samples=3 ...] [--raw sampling_pattern=TABULATED_SOBOL ...]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from generator.blender import session  # noqa: E402

bpy = session.bpy
import numpy as np  # noqa: E402
from scipy.ndimage import gaussian_filter  # noqa: E402

from generator import Simulator  # noqa: E402
from generator.render_settings import PRESETS, RenderSettings, resolve_settings  # noqa: E402

RESOLUTION = (640, 480)
ORBIT_FRAMES = 40  # the batch job's default trajectory length
# The presets before issue 15. Bounces then capped the diffuse/glossy/transmission limits at
# min(current, bounces) of a .blend saved with 4 of each, hence the explicit per-kind limits.
BEFORE: dict[str, tuple[RenderSettings, dict]] = {
    "preview": (RenderSettings("CYCLES", samples=4, denoise=True, denoise_prefilter="FAST", bounces=2, threads=0,
                               persistent_data=True, denoise_quality="HIGH", light_tree=True, adaptive_threshold=0.01),
                {"diffuse_bounces": 2, "glossy_bounces": 2, "transmission_bounces": 2}),
    "default": (RenderSettings("CYCLES", samples=16, denoise=True, denoise_prefilter="FAST", bounces=4, threads=0,
                               persistent_data=True, denoise_quality="HIGH", light_tree=True, adaptive_threshold=0.01),
                {"diffuse_bounces": 4, "glossy_bounces": 4, "transmission_bounces": 4}),
    "high": (RenderSettings("CYCLES", samples=128, denoise=True, denoise_prefilter="ACCURATE", bounces=12, threads=0,
                            persistent_data=True, denoise_quality="HIGH", light_tree=True, adaptive_threshold=0.01),
             {"diffuse_bounces": 4, "glossy_bounces": 4, "transmission_bounces": 4}),
}
REFERENCE = RenderSettings("CYCLES", samples=256, denoise=True, denoise_prefilter="ACCURATE", bounces=12, threads=0,
                           persistent_data=True, denoise_quality="HIGH", light_tree=True, adaptive_threshold=0.0)


def medium_site(seed: int, cache: Path) -> Path:
    """The medium site of ``seed`` (built once, then reused from ``cache``)."""
    from generator.scene import build_site

    folder = cache / f"site-medium-{seed}"
    blend = folder / "site.blend"
    if not blend.exists():
        build_site(seed, "medium", folder, preview=False, frames=250)
    return blend


def orbit_poses(sim: Simulator, seed: int) -> np.ndarray:
    from generator.batch.config import plan_trajectory

    start = sim.respawn_camera()
    return plan_trajectory("orbit", sim, sim.spawn_points, start, seed, ORBIT_FRAMES, 10.0).poses


def preview_frames(argv_parser) -> tuple:
    """The preview-frame benchmarks' common set-up: adds ``--frames``, ``--rounds``, ``--seed``
    and ``--cache`` to ``argv_parser``, parses it, and returns (args, a Simulator of the medium
    site of ``--seed`` at 640x480 with the ``preview`` preset, the batch job's orbit poses)."""
    argv_parser.add_argument("--frames", type=int, nargs="+", default=[0, 13, 26])
    argv_parser.add_argument("--rounds", type=int, default=3)
    argv_parser.add_argument("--seed", type=int, default=0)
    argv_parser.add_argument("--cache", type=Path, default=Path("/tmp/buildee-render-bench"))
    args = argv_parser.parse_args()
    sim = Simulator(medium_site(args.seed, args.cache), points_density=0.1, seed=args.seed, render_preset="preview")
    sim.configure_render(resolution=(640, 480))
    return args, sim, orbit_poses(sim, args.seed)


def raw_targets(path: str) -> tuple[list, str]:
    """The Blender structs a ``--raw`` property path names, and the property's name."""
    scene = bpy.context.scene
    if path.startswith("view_layer.cycles."):
        return [vl.cycles for vl in scene.view_layers], path[len("view_layer.cycles."):]
    if path.startswith("view_layer."):
        return list(scene.view_layers), path[len("view_layer."):]
    return [scene.cycles], path


def current_raw(paths) -> dict:
    out = {}
    for path in paths:
        structs, name = raw_targets(path)
        if not hasattr(structs[0], name):
            raise SystemExit(f"--raw {path}: Blender has no such property (see {type(structs[0]).__name__})")
        out[path] = getattr(structs[0], name)
    return out


def apply(sim: Simulator, settings: RenderSettings, raw: dict | None = None) -> None:
    sim.configure_render(**{k: v for k, v in vars(settings).items() if v is not None}, resolution=RESOLUTION)
    with session.quiet():
        for path, value in (raw or {}).items():
            structs, name = raw_targets(path)
            for struct in structs:
                setattr(struct, name, value)


def render_at(sim: Simulator, poses: np.ndarray, i: int) -> tuple[float, float, np.ndarray]:
    """Wall and CPU seconds (all threads; robust to other work on the machine) of one render."""
    sim.set_frame(1 + i)
    sim.set_world_from_camera(poses[i], check_collisions=False)
    t0, c0 = time.perf_counter(), time.process_time()
    out = sim.render()
    return time.perf_counter() - t0, time.process_time() - c0, out.rgb


def psnr(img: np.ndarray, ref: np.ndarray) -> float:
    mse = float(np.mean((img.astype(np.float64) - ref) ** 2))
    return 10 * np.log10(1.0 / mse) if mse > 0 else float("inf")


def ssim(img: np.ndarray, ref: np.ndarray) -> float:
    """Mean SSIM (Wang et al. 2004: Gaussian window sigma 1.5, K1 0.01, K2 0.03, peak 1) on luminance."""
    w = np.array([0.2126, 0.7152, 0.0722])
    x, y = img.astype(np.float64) @ w, ref.astype(np.float64) @ w
    f = lambda a: gaussian_filter(a, 1.5, truncate=3.5)  # noqa: E731
    mx, my = f(x), f(y)
    sxx, syy, sxy = f(x * x) - mx * mx, f(y * y) - my * my, f(x * y) - mx * my
    c1, c2 = 0.01**2, 0.03**2
    s = ((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx * mx + my * my + c1) * (sxx + syy + c2))
    return float(s.mean())


def reference(sim, poses, i, path: Path) -> np.ndarray:
    if path.exists():
        return np.load(path)
    apply(sim, REFERENCE)
    dt, _, rgb = render_at(sim, poses, i)
    np.save(path, rgb)
    print(f"reference for frame {i}: {dt:.0f} s", flush=True)
    return rgb


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", nargs="+", choices=list(PRESETS), default=["preview", "default", "high"])
    ap.add_argument("--frames", type=int, nargs="+", default=[0, 13, 26], help="orbit frame indices (0-39)")
    ap.add_argument("--repeats", type=int, default=2, help="timed renders per frame and setting")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cache", type=Path, default=Path("/tmp/buildee-render-bench"),
                    help="site and references, reused between runs")
    ap.add_argument("--references-only", action="store_true", help="render the missing references and stop")
    ap.add_argument("--set", nargs="+", default=[], metavar="NAME=VALUE",
                    help="render settings on top of the 'after' presets, e.g. samples=3 light_tree=true (JSON values)")
    ap.add_argument("--raw", nargs="+", default=[], metavar="PATH=VALUE",
                    help="Blender properties on top of the 'after' presets: NAME (scene.cycles), view_layer.NAME, "
                         "view_layer.cycles.NAME, e.g. sampling_pattern=TABULATED_SOBOL (JSON values)")
    args = ap.parse_args()
    parse = lambda items: {k: json.loads(v) if v[:1] in "0123456789-[tfn" else v  # noqa: E731
                           for k, v in (a.split("=", 1) for a in items)}
    overrides, raw = parse(args.set), parse(args.raw)
    args.cache.mkdir(parents=True, exist_ok=True)
    sim = Simulator(medium_site(args.seed, args.cache), points_density=0.1, seed=args.seed, render_preset="preview")
    sim.configure_render(resolution=RESOLUTION)
    poses = orbit_poses(sim, args.seed)
    if raw:  # Cycles' debug-only choices (e.g. sampling_pattern SOBOL_BURLEY) need its developer options
        bpy.context.preferences.experimental.use_cycles_debug = True
        bpy.context.preferences.view.show_developer_ui = True
    raw_before = current_raw(raw)
    key = hashlib.sha1(json.dumps([vars(REFERENCE), bpy.app.version_string]).encode()).hexdigest()[:10]
    refs = {i: reference(sim, poses, i, args.cache / f"ref-{args.seed}-orbit{i}-{key}.npy") for i in args.frames}
    if args.references_only:
        return
    print(f"medium site of seed {args.seed}, orbit frames {args.frames}, {RESOLUTION[0]}x{RESOLUTION[1]}, "
          f"device {sim.render_device}" + (f", after with {overrides | raw}" if overrides or raw else ""), flush=True)
    for preset in args.presets:
        before, before_raw = BEFORE[preset]
        runs = {"before": (before, raw_before | before_raw), "after": (resolve_settings(preset, **overrides), raw)}
        times = {k: [] for k in runs}
        cpu = {k: [] for k in runs}
        quality = {k: {} for k in runs}
        for _ in range(args.repeats):
            for name, (settings, extra) in runs.items():
                apply(sim, replace(settings, samples=1), extra)
                render_at(sim, poses, args.frames[-1])  # untimed, 1 sample: re-synchronisation after the change
                apply(sim, settings, extra)
                for i in args.frames:
                    dt, ct, rgb = render_at(sim, poses, i)
                    times[name].append(dt)
                    cpu[name].append(ct)
                    quality[name][i] = (psnr(rgb, refs[i]), ssim(rgb, refs[i]))
        for name in runs:
            p = np.mean([q[0] for q in quality[name].values()])
            s = np.mean([q[1] for q in quality[name].values()])
            print(f"{preset} {name}: {np.median(times[name]):.2f} s/frame, {np.median(cpu[name]):.2f} CPU s/frame (runs: "
                  + " ".join(f"{t:.2f}" for t in times[name]) + f"), PSNR {p:.2f} dB, SSIM {s:.4f} (per frame: "
                  + ", ".join(f"{q[0]:.2f}" for q in quality[name].values()) + ")", flush=True)
        ratio = np.median(times["before"]) / np.median(times["after"])
        cratio = np.median(cpu["before"]) / np.median(cpu["after"])
        print(f"{preset}: after takes {ratio:.2f}x fewer seconds per frame than before ({cratio:.2f}x fewer CPU seconds)",
              flush=True)


if __name__ == "__main__":
    main()

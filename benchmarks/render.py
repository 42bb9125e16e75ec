"""Per-frame render cost: Simulator.render() vs a bare bpy.ops.render.render(), per preset.

Scene built in code: a ground plane, 40 boxes, a sun and a sky texture, 640x480. For each
preset, in one run and alternating, it times
- bare:  ``bpy.ops.render.render()`` with only the Combined pass and no file output;
- bare+passes: the same with our passes enabled (depth, object index, Cryptomatte);
- ours:  ``Simulator.render()`` (render + writing the EXR/TIFF to /dev/shm, reading them
  back, label mapping) and then ``exporters.exr.write_frame_exr`` (ZIP) of its arrays.
Usage: .venv/bin/python benchmarks/render.py [--presets preview default high] [--frames 2]
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from generator.blender import session  # noqa: E402

bpy = session.bpy
import numpy as np  # noqa: E402

from exporters.exr import write_frame_exr  # noqa: E402
from generator import Simulator  # noqa: E402


def build_scene(path: Path) -> None:
    session.new_empty_file()
    scene = bpy.context.scene
    with session.quiet():
        bpy.ops.mesh.primitive_plane_add(size=200)
        bpy.context.active_object.name = "Ground"
        rng = np.random.default_rng(0)
        for _ in range(40):
            x, y = rng.uniform(-40, 40, 2)
            bpy.ops.mesh.primitive_cube_add(size=2.5, location=(x, y, 1.25))
            bpy.context.active_object.name = "Container"
        bpy.ops.object.light_add(type="SUN", rotation=(0.7, 0.2, 0.5))
        world = bpy.data.worlds.new("World")
        scene.world = world
        world.use_nodes = True
        sky = world.node_tree.nodes.new("ShaderNodeTexSky")
        world.node_tree.links.new(sky.outputs["Color"], world.node_tree.nodes["Background"].inputs["Color"])
        bpy.ops.object.camera_add(location=(0, -50, 8), rotation=(math.radians(80), 0, 0))
        scene.camera = bpy.context.active_object
        scene.camera.data.clip_end = 500
    session.save_blend(path)


def bare_render(passes: bool) -> float:
    scene = bpy.context.scene
    vl = scene.view_layers[0]
    saved = (vl.use_pass_z, vl.use_pass_object_index, vl.use_pass_cryptomatte_object, scene.render.use_compositing)
    vl.use_pass_z = vl.use_pass_object_index = vl.use_pass_cryptomatte_object = passes
    scene.render.use_compositing = False
    t0 = time.perf_counter()
    with session.quiet():
        bpy.ops.render.render()
    dt = time.perf_counter() - t0
    vl.use_pass_z, vl.use_pass_object_index, vl.use_pass_cryptomatte_object, scene.render.use_compositing = saved
    return dt


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", nargs="+", default=["preview", "default", "high"])
    ap.add_argument("--frames", type=int, default=2, help="timed frames per approach and preset")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp())
    build_scene(tmp / "bench.blend")
    rows = []
    for preset in args.presets:
        sim = Simulator(tmp / "bench.blend", points_density=0.1, segmentation_sensitivity=0.1, render_preset=preset)
        sim.configure_render(resolution=(640, 480))
        sim.render()  # warm-up: scene sync, kernel and denoiser set-up
        bare, bare_passes, ours, stages = [], [], [], []
        for _ in range(args.frames):
            bare.append(bare_render(False))
            bare_passes.append(bare_render(True))
            t0 = time.perf_counter()
            out = sim.render()
            t1 = time.perf_counter()
            write_frame_exr(tmp / "frame.exr", out.rgb, out.depth, out.seg, out.instance, compression="zip")
            t2 = time.perf_counter()
            ours.append(t2 - t0)
            stages.append(dict(sim.last_render_timings, exr_write=t2 - t1))
        b, bp, o = np.median(bare), np.median(bare_passes), np.median(ours)
        st = {k: float(np.median([s[k] for s in stages])) for k in stages[0]}
        rows.append((preset, b, bp, o, st))
        print(f"{preset}: bare {b:.2f} s, bare+passes {bp:.2f} s, ours {o:.2f} s "
              f"(overhead {100 * (o - b) / b:+.1f}% vs bare, {100 * (o - bp) / bp:+.1f}% vs bare+passes); stages: "
              + ", ".join(f"{k} {v * 1e3:.0f} ms" for k, v in st.items()), flush=True)


if __name__ == "__main__":
    main()

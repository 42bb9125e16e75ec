"""Render settings with real Blender on tiny images: the .blend's own settings, presets and their
checks, engines, devices, resolution and quality, temporary files, a clean stdout and work run
beside a render. The ground truth of a render is in test_render.py."""

import math
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import bpy
import numpy as np
import pytest

import scenes
from exporters.exr import write_frame_exr
from exporters.modalities import COMBINED
from generator import Simulator
from generator.blender import egl
from generator.blender.render import Renderer, resolve_settings

ROOT = Path(__file__).resolve().parents[1]


def test_a_render_border_in_the_blend_is_ignored(tmp_path):
    """The ground truth describes the whole frame, so the colour does too: a .blend's render
    border (cropped or not) would give an RGB of another size or black outside the border."""
    scenes.new_scene(64, 48)
    r = bpy.context.scene.render
    r.use_border, r.use_crop_to_border = True, True
    r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = 0.25, 0.75, 0.25, 0.75
    scenes.add_plane("Ground", (100, 100), (0, 0, 0))
    scenes.add_sun()
    scenes.add_camera((0, -15, 3), (math.radians(80), 0, 0))
    sim = Simulator(scenes.save(tmp_path / "border.blend"), segmentation_sensitivity=0.0, render_preset="preview")
    out = sim.render()
    assert out.rgb.shape == (48, 64, 3) and out.depth.shape == (48, 64)
    ground = np.isfinite(out.depth)
    assert ground[:, :16].any() and out.rgb[:, :16][ground[:, :16]].mean() > 0.05  # lit outside the old border


def test_bad_render_settings(plane_blend):
    sim = Simulator(plane_blend, points_density=1)
    for kwargs, message in [
        ({"resolution": (0, 10)}, "resolution"),
        ({"resolution": (-4, 10)}, "resolution"),
        ({"engine": "POVRAY"}, "unknown render engine"),
        ({"samples": 0}, "samples"),
        ({"preset": "ultra"}, "unknown render preset"),
    ]:
        with pytest.raises(ValueError, match=message):
            sim.configure_render(**kwargs)
    with pytest.raises(ValueError, match="compression"):
        write_frame_exr("/tmp/never.exr", depth=np.zeros((2, 2), np.float32), compression="jpeg")


def test_resolution_override_updates_intrinsics(plane_blend):
    sim = Simulator(plane_blend, points_density=1, render_preset="preview")
    fx = sim.K[0, 0]
    sim.configure_render(resolution=(40, 30))
    assert (sim.width, sim.height) == (40, 30) and sim.K[0, 0] == pytest.approx(fx / 2)
    out = sim.render()
    assert out.depth.shape == (30, 40) and np.allclose(out.K, sim.K)


def stat_mode(path: str) -> int:
    return os.stat(path).st_mode & 0o777


def _render_folders() -> set[str]:
    """This process's render folders (docs/rendering.md: /dev/shm, else the temp folder)."""
    import glob
    import tempfile

    pattern = f"buildee-render-{os.getpid()}-*"
    return {p for base in ("/dev/shm", tempfile.gettempdir()) for p in glob.glob(os.path.join(base, pattern))}


def test_temporary_files_are_private_and_cleaned(plane_blend, monkeypatch):
    import gc

    before = _render_folders()
    sim = Simulator(plane_blend, points_density=1, render_preset="preview")
    sim.configure_render(resolution=(16, 12))
    assert _render_folders() == before  # made at the first render, not before
    sim.render()
    made = _render_folders() - before
    assert len(made) == 1
    tmp = made.pop()
    assert stat_mode(tmp) == 0o700 and os.listdir(tmp) == []  # private, emptied after the render
    import generator.blender.render as render_mod

    def broken(path):
        raise OSError("simulated read failure")

    monkeypatch.setattr(render_mod, "read_blender_exr", broken)
    with pytest.raises(OSError, match="simulated"):
        sim.render()
    assert os.listdir(tmp) == []  # emptied when a render fails too
    del sim
    gc.collect()
    assert not os.path.exists(tmp)  # removed when the Simulator goes away


def test_engine_without_egl_fails_cleanly(plane_blend, monkeypatch):
    sim = Simulator(plane_blend, points_density=1)
    monkeypatch.setattr(egl, "_probe_result", None)
    monkeypatch.setenv("__EGL_VENDOR_LIBRARY_DIRS", "/nonexistent")  # hides every EGL driver
    sim.configure_render(engine="BLENDER_WORKBENCH", resolution=(16, 12))
    with pytest.raises(egl.EngineUnavailableError, match="EGL"):
        sim.render()
    monkeypatch.setattr(egl, "_probe_result", None)


def test_render_keeps_stdout_clean(plane_blend):
    code = textwrap.dedent(
        f"""
        from generator import Simulator
        sim = Simulator({str(plane_blend)!r}, points_density=1, render_preset="preview")
        sim.configure_render(resolution=(16, 12))
        rgb, depth, seg = sim.render()
        print("shape", depth.shape)
        """
    )
    env = {k: v for k, v in os.environ.items() if k != "OCIO"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, env=env)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout == "shape (12, 16)\n"
    assert out.stderr == ""


def test_presets_resolve():
    assert resolve_settings("default").samples == 16
    assert resolve_settings("preview", samples=2).samples == 2
    assert resolve_settings(None).engine is None  # keep the .blend's settings


@pytest.mark.parametrize("kwargs, message", [
    ({"samples": 0}, "^samples must be an integer >= 1, got 0$"),
    ({"samples": 4.0}, "^samples must be an integer >= 1, got 4.0$"),
    ({"bounces": -1}, "^bounces must be an integer >= 0, got -1$"),
    ({"threads": True}, r"^threads must be an integer >= 0 \(0 = all cores\), got True$"),
    ({"adaptive_threshold": 1}, r"^adaptive_threshold must be a number in \[0, 1\) \(0 = off\), got 1$"),
    ({"adaptive_threshold": math.nan}, r"^adaptive_threshold must be a number in \[0, 1\) \(0 = off\), got nan$"),
    ({"resolution": (64.0, 48)}, r"^resolution width must be an integer from 4 to 16,384 pixels \(Blender renders "
                                  r"smaller sides as 4\), got 64.0$"),
    ({"resolution": (64, 0)}, r"^resolution height must be an integer from 4 to 16,384 pixels .*got 0$"),
    ({"resolution": (2, 2)}, r"^resolution width must be an integer from 4 .*got 2$"),  # Blender would render 4x4
    ({"resolution": (100000, 10)}, r"^resolution width must be an integer from 4 to 16,384 pixels .*got 100000$"),
    ({"resolution": 64}, r"^resolution must be \(width, height\), got 64$"),
])
def test_render_setting_numbers_are_one_line_errors(kwargs, message):
    with pytest.raises(ValueError, match=message):
        resolve_settings("preview", **kwargs)


def test_render_setting_numbers_reach_blender_as_python_numbers():
    s = resolve_settings("preview", samples=np.int64(3), threads=np.uint8(2), resolution=np.array([64, 48]))
    assert (s.samples, s.threads, s.resolution) == (3, 2, (64, 48))
    assert {type(v) for v in (s.samples, s.threads, *s.resolution)} == {int}


def test_quality_settings_leave_depth_labels_and_ids_unchanged(plane_blend):
    """Depth, labels and instance ids come from the pixel centre of the first sample: the
    quality settings (samples, bounces, denoiser, light tree, adaptive sampling) never change them."""
    sim = Simulator(plane_blend, points_density=1, segmentation_sensitivity=0.0, render_preset="preview")
    first = sim.render()
    for preset, extra in [("high", {"samples": 8}),
                          ("default", {"light_tree": False, "adaptive_threshold": 0.0, "denoise_quality": "FAST",
                                       "denoise_prefilter": "NONE", "bounces": 1, "samples": 3})]:
        sim.configure_render(preset, **extra)
        out = sim.render()
        np.testing.assert_array_equal(out.depth, first.depth)
        np.testing.assert_array_equal(out.seg, first.seg)
        np.testing.assert_array_equal(out.instance, first.instance)
        assert np.abs(out.rgb - first.rgb).max() > 0  # the colour did change


def test_bounces_do_not_depend_on_the_previous_preset(plane_blend):
    import bpy

    sim = Simulator(plane_blend, points_density=1, render_preset="preview")
    sim.configure_render("high")
    c = bpy.context.scene.cycles
    assert (c.max_bounces, c.diffuse_bounces, c.glossy_bounces, c.transmission_bounces) == (12, 12, 12, 12)


def test_device_auto_gpu_and_cpu(plane_blend):
    """No GPU here: 'auto' renders on the CPU, 'gpu' is a one-line error that changes nothing."""
    import bpy

    from generator.blender.devices import DeviceUnavailableError, gpu_devices

    with pytest.raises(ValueError, match="device must be one of cpu, gpu, auto"):
        resolve_settings("preview", device="tpu")
    sim = Simulator(plane_blend, points_density=1, segmentation_sensitivity=0.0, render_preset="preview")
    assert sim.render_device == "CPU"  # the CPU unless told otherwise
    cpu = sim.render()
    gpu = gpu_devices()
    sim.configure_render(device="auto")
    if gpu is not None:  # a GPU machine: auto and gpu use it
        assert sim.render_device.startswith(gpu[0] + ": ")
        return
    assert sim.render_device == "CPU"
    with pytest.raises(DeviceUnavailableError, match="no CUDA or OptiX GPU") as err:
        sim.configure_render(device="gpu", samples=7)
    assert "\n" not in str(err.value)
    assert bpy.context.scene.cycles.samples == 4 and sim.render_device == "CPU"  # nothing was applied
    out = sim.render()
    np.testing.assert_array_equal(out.rgb, cpu.rgb)  # same device, same settings: same pixels
    np.testing.assert_array_equal(out.depth, cpu.depth)


def test_cli_device(finished, tmp_path):
    from conftest import run_generator
    from exporters.manifest import read_manifest
    from generator.render_settings import probe_gpu

    out, _ = finished
    manifest = read_manifest(out / "seed_000004")
    assert manifest["config"]["device"] == "auto"
    gpu = probe_gpu()
    assert manifest["summary"]["render_device"] == ("CPU" if gpu is None else gpu)
    if gpu is None:
        r = run_generator(tmp_path / "gpu", "--seeds", "1", "--device", "gpu")
        assert r.returncode == 2 and r.stdout == ""
        assert r.stderr.count("\n") == 1 and "no CUDA or OptiX GPU" in r.stderr
        assert not any((tmp_path / "gpu").glob("seed_*"))


def test_work_alongside_runs_during_the_render_and_raises_its_errors(plane_blend):
    """Renderer.render(alongside=...): started by the render itself (render() casts its
    ground truth this way), finished before the call returns, its exception raised, and
    Blender's handler list left as it was."""
    sim = Simulator(plane_blend, points_density=1, render_preset="preview")
    sim.configure_render(resolution=(16, 12))
    renderer = Renderer()
    marks = {}

    def post(*_):
        marks["render_post"] = time.perf_counter()

    handlers = list(bpy.app.handlers.render_pre)
    bpy.app.handlers.render_post.append(post)
    try:
        raw = renderer.render([COMBINED], alongside=lambda: marks.setdefault("alongside", time.perf_counter()))
        assert raw["Combined"].shape == (12, 16, 3)
        assert marks["alongside"] < marks["render_post"]  # began while Blender was rendering

        def failing():
            raise ValueError("simulated failure beside the render")

        with pytest.raises(ValueError, match="simulated failure"):
            renderer.render([COMBINED], alongside=failing)
        assert os.listdir(renderer.tmpdir) == []
        assert list(bpy.app.handlers.render_pre) == handlers
    finally:
        bpy.app.handlers.render_post.remove(post)
        renderer.close()

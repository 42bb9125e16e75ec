"""Rendering with Blender: settings and presets, the passes asked for, private temporary files.

One call to :meth:`Renderer.render` runs one Blender render that writes
- a multilayer EXR (float32, uncompressed) with the Combined pass (linear RGB) and the
  passes it is given (exporters/modalities.py ``BlenderPass``: switched on by their
  ``switches`` and ``settings``, decoded by their ``decode``), and
- through the compositor, a 16-bit TIFF of the display-referred RGB (Blender's own view
  transform applied),
into a private temporary folder (on /dev/shm when it exists) that is emptied after every
render, failed or not, and removed when the renderer is garbage-collected or at exit.
"""

from __future__ import annotations

import glob
import os
import shutil
import tempfile
import threading
import time
import weakref
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor

import bpy

from exporters.modalities import BlenderPass

from ..passes import decode_passes, read_blender_exr, read_display_tiff
from ..render_settings import ENGINES, PRESETS, RenderSettings, resolve_settings  # noqa: F401
from . import devices, session
from .devices import DeviceUnavailableError  # noqa: F401
from .egl import require_gpu_context
from .sky import MIST_DEPTH, fog_of_scene

def apply_settings(settings: RenderSettings) -> None:
    """Write settings into the open scene (None fields are left as the .blend has them;
    the device, when None, stays as chosen for this file, the CPU at first). Raises
    :class:`DeviceUnavailableError` for device='gpu' without a GPU."""
    devices.select(settings.device)  # first: a missing GPU leaves the scene untouched
    with session.quiet():  # touching Cycles' device settings makes it log its device probe
        _apply_settings(settings)


def _apply_settings(settings: RenderSettings) -> None:
    scene = bpy.context.scene
    r = scene.render
    if settings.engine is not None:
        r.engine = settings.engine
    if settings.resolution is not None:
        r.resolution_x, r.resolution_y = settings.resolution
        r.resolution_percentage = 100
    if settings.threads is not None:
        r.threads_mode = "FIXED" if settings.threads else "AUTO"
        if settings.threads:
            r.threads = settings.threads
    if settings.persistent_data is not None:
        r.use_persistent_data = settings.persistent_data
    c = scene.cycles
    if settings.samples is not None:
        c.samples = settings.samples
        scene.eevee.taa_render_samples = settings.samples
    if settings.denoise is not None:
        c.use_denoising = settings.denoise
        c.denoiser = "OPENIMAGEDENOISE"
    if settings.denoise_prefilter is not None:
        c.denoising_prefilter = settings.denoise_prefilter
    if settings.denoise_quality is not None:
        c.denoising_quality = settings.denoise_quality
    if settings.bounces is not None:
        c.max_bounces = settings.bounces
        for name in ("diffuse_bounces", "glossy_bounces", "transmission_bounces"):
            setattr(c, name, settings.bounces)
    if settings.light_tree is not None:
        c.use_light_tree = settings.light_tree
    if settings.adaptive_threshold is not None:
        c.use_adaptive_sampling = settings.adaptive_threshold > 0
        if settings.adaptive_threshold > 0:
            c.adaptive_threshold = settings.adaptive_threshold


def _render_with(alongside: Callable[[], object] | None) -> None:
    """``bpy.ops.render.render`` with ``alongside`` started in a thread by the render's own
    ``render_pre`` handler (so it begins once Blender renders, not before)."""
    if alongside is None:
        bpy.ops.render.render(write_still=True)
        return
    started = threading.Event()

    def start(*_):
        started.set()

    def run():
        started.wait()
        return alongside()

    bpy.app.handlers.render_pre.append(start)
    with ThreadPoolExecutor(1) as pool:
        job = pool.submit(run)
        try:
            bpy.ops.render.render(write_still=True)
        finally:
            started.set()  # a render that failed before starting must not leave it waiting
            bpy.app.handlers.render_pre.remove(start)
        job.result()


def switch_passes(on: Iterable[BlenderPass], off: Iterable[BlenderPass]) -> None:
    """Switch the passes ``on`` on (with their settings) and ``off`` off, in every view layer of
    the open scene; a property already at its value is not written (no needless update)."""
    wanted = [(p, path, True) for p in on for path in p.switches] + [
        (p, path, value) for p in on for path, value in p.settings.items()]
    wanted += [(p, path, False) for p in off for path in p.switches]
    for vl in bpy.context.scene.view_layers:
        for p, path, value in wanted:
            *groups, name = path.split(".")
            owner = vl
            try:
                for g in groups:
                    owner = getattr(owner, g)
                if getattr(owner, name) != value:
                    setattr(owner, name, value)
            except (AttributeError, TypeError) as e:
                raise ValueError(f"Blender pass {p.name!r}: cannot set view-layer property {path!r} to {value!r} "
                                 f"({e}); fix its declaration (exporters/modalities.py BlenderPass)") from None


class Renderer:
    """Renders the open scene, one Blender render per call, into decoded passes."""

    def __init__(self):
        base = "/dev/shm" if os.path.isdir("/dev/shm") and os.access("/dev/shm", os.W_OK) else None
        self.tmpdir = tempfile.mkdtemp(prefix=f"buildee-render-{os.getpid()}-", dir=base)
        self._finalizer = weakref.finalize(self, shutil.rmtree, self.tmpdir, True)
        self.last_timings: dict[str, float] = {}  # seconds, for benchmarks (never written out)
        with session.quiet():
            self._configure_outputs()

    def close(self) -> None:
        self._finalizer()

    def _configure_outputs(self) -> None:
        scene = bpy.context.scene
        r = scene.render
        r.compositor_device = "CPU"
        r.use_compositing = True
        r.use_sequencer = False
        r.dither_intensity = 0.0  # no dither noise in the display-referred RGB we return
        fmt = r.image_settings
        fmt.media_type = "MULTI_LAYER_IMAGE"
        fmt.file_format = "OPEN_EXR_MULTILAYER"
        fmt.color_depth = "32"
        fmt.exr_codec = "NONE"
        r.filepath = os.path.join(self.tmpdir, "passes.exr")
        r.use_file_extension = True
        for vl in scene.view_layers:
            vl.cycles.denoising_store_passes = False
        tree = bpy.data.node_groups.new("buildee-outputs", "CompositorNodeTree")
        scene.compositing_node_group = tree
        layers = tree.nodes.new("CompositorNodeRLayers")
        out = self._file_output(tree, "display", "TIFF", "16")
        out.format.tiff_codec = "NONE"
        out.save_as_render = True  # Blender's view transform, as in its own PNG output
        image = layers.outputs["Image"]
        self.fog = fog_of_scene(scene)
        if self.fog is not None:
            image = self._fogged(tree, layers, image)
        tree.links.new(image, out.inputs[0])

    def _fogged(self, tree, layers, image):
        """``image`` seen through the scene's fog (generator/blender/sky.py): mixed with the fog's
        colour by the transmittance exp(-extinction x distance) along each pixel's ray, the
        distance from Cycles' Mist pass (ray length, linear from 0 to MIST_DEPTH; the sky is
        at MIST_DEPTH, so fully fogged). Also written as a linear EXR, the fogged ``Combined``."""
        scene = bpy.context.scene
        for vl in scene.view_layers:
            vl.use_pass_mist = True
        mist = scene.world.mist_settings
        mist.start, mist.depth, mist.falloff = 0.0, MIST_DEPTH, "LINEAR"
        optical = tree.nodes.new("ShaderNodeMath")
        optical.operation = "MULTIPLY"
        tree.links.new(layers.outputs["Mist"], optical.inputs[0])
        optical.inputs[1].default_value = -self.fog["extinction_per_m"] * MIST_DEPTH
        transmittance = tree.nodes.new("ShaderNodeMath")
        transmittance.operation = "EXPONENT"
        tree.links.new(optical.outputs[0], transmittance.inputs[0])
        mix = tree.nodes.new("ShaderNodeMix")
        mix.data_type = "RGBA"
        tree.links.new(transmittance.outputs[0], mix.inputs["Factor"])
        mix.inputs["A"].default_value = (*self.fog["colour"], 1.0)
        tree.links.new(image, mix.inputs["B"])
        linear = self._file_output(tree, "fogged", "OPEN_EXR", "32")
        linear.format.exr_codec = "NONE"
        tree.links.new(mix.outputs["Result"], linear.inputs[0])
        return mix.outputs["Result"]

    def _file_output(self, tree, name: str, file_format: str, depth: str):
        """A compositor File Output node writing one RGB image ``name`` of ``file_format`` and
        ``depth`` bits into the private folder."""
        node = tree.nodes.new("CompositorNodeOutputFile")
        node.directory = self.tmpdir + os.sep
        node.file_name = name
        node.format.media_type = "IMAGE"
        node.format.file_format = file_format
        node.format.color_depth = depth
        node.format.color_mode = "RGB"
        node.file_output_items.new("RGBA", "Image")
        return node

    def render(self, passes: Iterable[BlenderPass], alongside: Callable[[], object] | None = None,
               off: Iterable[BlenderPass] = ()) -> dict[str, object]:
        """One Blender render with ``passes`` switched on and ``off`` switched off; returns pass
        name -> decoded value of each of ``passes`` (None: the engine wrote no such pass).
        Temporary files never outlive the call.

        ``alongside`` (optional) runs in a thread once Blender has started rendering (which
        releases Python's GIL), so CPU work that holds the GIL overlaps the render; it has
        finished, and its exception is raised, before this returns."""
        passes = list(passes)
        require_gpu_context(bpy.context.scene.render.engine)
        devices.select(None)  # a file opened since the last settings renders on the CPU unless told
        bpy.context.scene.render.use_border = False  # the ground truth and K describe the whole frame
        try:
            with session.quiet():
                switch_passes(passes, off)
            t0 = time.perf_counter()
            with session.quiet():
                _render_with(alongside)
            t1 = time.perf_counter()
            exr = glob.glob(os.path.join(self.tmpdir, "passes*.exr"))
            tif = glob.glob(os.path.join(self.tmpdir, "display*.tif*"))
            if not exr or not tif:
                raise RuntimeError(f"Blender wrote no render output (see its log: {session.log_path()})")
            channels = read_blender_exr(exr[0])
            if self.fog is not None:  # the fogged image stands for the render's Combined pass
                fogged = read_blender_exr(glob.glob(os.path.join(self.tmpdir, "fogged*.exr"))[0])
                for key in [k for k in channels if k.split(".")[-2:-1] == ["Combined"] and k[-1] in "RGB"]:
                    channels[key] = fogged[key.rsplit(".", 1)[1]]
            decoded = decode_passes(channels | read_display_tiff(tif[0]), passes)
            self.last_timings = {"blender_render_and_write": t1 - t0, "read_passes": time.perf_counter() - t1}
            return decoded
        finally:
            for name in os.listdir(self.tmpdir):
                try:
                    os.remove(os.path.join(self.tmpdir, name))
                except OSError:
                    pass

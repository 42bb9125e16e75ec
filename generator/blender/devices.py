"""Which device Cycles renders on: the CPU, or a CUDA/OptiX GPU when one is present.

Cycles' device list comes from its add-on preferences
(``bpy.context.preferences.addons['cycles'].preferences``); probing it initialises the
GPU drivers once per process, so the result is cached. ``python -m generator.blender.devices``
prints what :func:`gpu_devices` finds (the batch CLI runs it to check ``--device gpu``).
"""

from __future__ import annotations

import sys

import bpy

from ..render_settings import NO_GPU_MESSAGE
from . import session

GPU_BACKENDS = ("OPTIX", "CUDA")  # in order of preference (OptiX: RTX ray tracing on NVIDIA GPUs)
CPU = "CPU"

_gpus: tuple[str, tuple[str, ...]] | None | bool = False  # False: not probed yet
_chosen_generation = -1  # session.generation() of the file whose device was last chosen


class DeviceUnavailableError(RuntimeError):
    """A GPU was asked for (device='gpu') but Cycles finds none."""


def _prefs():
    return bpy.context.preferences.addons["cycles"].preferences


def gpu_devices() -> tuple[str, tuple[str, ...]] | None:
    """(backend, device names) of the first GPU backend with devices, or None (cached)."""
    global _gpus
    if _gpus is False:
        _gpus = None
        with session.quiet():  # Cycles logs every driver it fails to load
            prefs = _prefs()
            prefs.refresh_devices()
            for backend in GPU_BACKENDS:
                names = tuple(d.name for d in prefs.get_devices_for_type(backend) if d.type == backend)
                if names:
                    _gpus = (backend, names)
                    break
    return _gpus


def select(device: str | None) -> None:
    """Make Cycles render on ``device`` ('cpu', 'gpu' or 'auto'); None keeps the device chosen
    for the open file, or the CPU when none was. Raises DeviceUnavailableError for 'gpu'
    without a GPU (the scene is then left unchanged)."""
    global _chosen_generation
    if device is None:
        if _chosen_generation == session.generation():
            return
        device = "cpu"
    gpu = gpu_devices() if device in ("gpu", "auto") else None
    if device == "gpu" and gpu is None:
        raise DeviceUnavailableError(NO_GPU_MESSAGE)
    with session.quiet():  # Cycles logs its device probe when its settings are touched
        _use(gpu)
    _chosen_generation = session.generation()


def _use(gpu: tuple[str, tuple[str, ...]] | None) -> None:
    c = bpy.context.scene.cycles
    if gpu is None:
        c.device = "CPU"
        c.denoising_use_gpu = False
        return
    prefs = _prefs()
    prefs.compute_device_type = gpu[0]
    for d in prefs.get_devices_for_type(gpu[0]):
        d.use = d.type == gpu[0]  # the GPUs only, not the CPU beside them
    c.device = "GPU"
    c.denoising_use_gpu = bool(prefs.has_oidn_gpu_devices())


def active() -> str:
    """The device the open scene renders on: 'CPU', or e.g. 'OPTIX: NVIDIA H100 80GB HBM3'
    (engines other than Cycles: the engine's name, they use the OpenGL/EGL context)."""
    scene = bpy.context.scene
    if scene.render.engine != "CYCLES":
        return f"{scene.render.engine} (OpenGL)"
    if scene.cycles.device != "GPU":
        return CPU
    prefs = _prefs()
    backend = prefs.get_compute_device_type()
    names = [d.name for d in prefs.devices if d.use and d.type == backend]
    return f"{backend}: {', '.join(names)}" if backend != "NONE" and names else CPU


def main() -> int:
    gpu = gpu_devices()
    print(f"{gpu[0]}: {', '.join(gpu[1])}" if gpu else "none")
    return 0


if __name__ == "__main__":
    sys.exit(main())

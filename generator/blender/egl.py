"""EEVEE and Workbench need an EGL/OpenGL context; without one Blender kills the process.

:func:`require_gpu_context` probes once per process, in a child process, by rendering an
8x8 Workbench image, so a missing context becomes a clear Python error instead of a crash.
"""

from __future__ import annotations

import os
import subprocess
import sys

NEEDS_EGL = {"BLENDER_EEVEE", "BLENDER_WORKBENCH"}

_PROBE = """
import bpy
s = bpy.context.scene
s.render.engine = 'BLENDER_WORKBENCH'
s.render.resolution_x = s.render.resolution_y = 8
bpy.ops.object.camera_add()
s.camera = bpy.context.active_object
bpy.ops.render.render()
print('EGL-OK')
"""

_probe_result: tuple[bool, str] | None = None


class EngineUnavailableError(RuntimeError):
    """The requested render engine cannot run on this machine."""


def gpu_context_available() -> tuple[bool, str]:
    """(available, reason), probed once per process in a child process."""
    global _probe_result
    if _probe_result is None:
        env = {k: v for k, v in os.environ.items() if k != "OCIO"}
        try:
            out = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True, timeout=300, env=env)
            ok = out.returncode == 0 and "EGL-OK" in out.stdout
            reason = "" if ok else f"probe render exited with code {out.returncode}"
        except subprocess.TimeoutExpired:
            ok, reason = False, "probe render timed out"
        _probe_result = (ok, reason)
    return _probe_result


def require_gpu_context(engine: str) -> None:
    """Raise EngineUnavailableError if ``engine`` needs EGL and this machine has none."""
    if engine not in NEEDS_EGL:
        return
    ok, reason = gpu_context_available()
    if not ok:
        raise EngineUnavailableError(
            f"{engine} needs an EGL/OpenGL context, which this machine does not provide ({reason}); "
            "use engine='CYCLES', or install libegl1 and a Mesa driver (libegl-mesa0, libgl1-mesa-dri)"
        )

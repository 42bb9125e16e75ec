"""A lens model in Blender: a Cycles custom camera (an OSL camera shader) that fires each
sample's ray through the lens (docs/cameras.md).

Cycles asks the shader for the ray of every sample position on the sensor (raster
coordinates in [0, 1], x right, y up, jittered within the pixel by the pixel filter, as for
its perspective camera). The shader turns the position into OpenCV pixel coordinates
(u, v) = (x W, (1 - y) H), then into distorted normalised coordinates with ``K``, inverts
the lens there (:class:`generator.geometry.lens.Lens`: the same Newton iteration, in OSL's
float32, stopped once converged) and returns the direction (a, -b, 1) normalised (Blender's camera frame: x right,
y up, looking down -z, which the shader's frame maps to +z). The colour is then rendered
through the lens itself: no warp of a pinhole image, no resampling. The ground truth is cast
through the same lens in float64 at the pixel centres (generator/geometry/raycam.py); the
shader's float32 rays differ from those by about 1e-7 of a radian (1e-4 of a pixel at a
focal length of 500 pixels).

The lens, ``K`` and the image size are written into the shader's source as constants (one
text block, :data:`TEXT_NAME`, rewritten whenever the lens or the resolution changes). An
ideal lens gives the plain perspective camera back.
"""

from __future__ import annotations

import os
import sys

import bpy
import numpy as np

from ..geometry.lens import NEWTON_STEPS, Lens

TEXT_NAME = "buildee_lens.osl"
# the shader's Newton iteration stops once a step is this small (normalised units): converging
# quadratically, it is then at float32's precision (4 to 6 steps for the lenses of docs/cameras.md)
OSL_CONVERGED = 1e-6


def _osl_modules() -> None:
    """Cycles compiles a camera shader with ``oslquery``, which the bpy wheel ships in its own
    Python folder rather than on ``sys.path``."""
    folder = os.path.join(bpy.utils.resource_path("LOCAL"), "python", "lib",
                          f"python{sys.version_info.major}.{sys.version_info.minor}", "site-packages")
    if os.path.isdir(folder) and folder not in sys.path:
        sys.path.append(folder)


def _literal(x: float) -> str:
    return repr(float(x))


def osl_source(lens: Lens, K: np.ndarray, width: int, height: int) -> str:
    """The camera shader of ``lens`` with ``K`` for a ``width`` x ``height`` image."""
    f = _literal
    head = (f"    float pu = raster[0] * {f(width)};\n    float pv = (1.0 - raster[1]) * {f(height)};\n"
            f"    float bd = (pv - {f(K[1, 2])}) / {f(K[1, 1])};\n"
            f"    float ad = (pu - {f(K[0, 2])} - {f(K[0, 1])} * bd) / {f(K[0, 0])};\n")
    if lens.model == "fisheye":
        k1, k2, k3, k4 = map(f, lens.coefficients)
        body = (f"    float rd = sqrt(ad * ad + bd * bd);\n    float th = rd;\n"
                f"    for (int i = 0; i < {NEWTON_STEPS}; i++) {{\n        float t2 = th * th;\n"
                f"        float g = th * (1.0 + t2 * ({k1} + t2 * ({k2} + t2 * ({k3} + t2 * {k4})))) - rd;\n"
                f"        float s = 1.0 + t2 * (3.0 * {k1} + t2 * (5.0 * {k2} + t2 * (7.0 * {k3} + t2 * 9.0 * {k4})));\n"
                f"        th = th - g / s;\n        if (abs(g / s) < {OSL_CONVERGED}) break;\n    }}\n"
                f"    float ca = 0.0;\n    float cb = 0.0;\n"
                f"    if (rd > 0.0) {{ ca = sin(th) * ad / rd; cb = sin(th) * bd / rd; }}\n"
                f"    direction = normalize(vector(ca, -cb, cos(th)));\n")
    else:
        k1, k2, p1, p2, k3 = map(f, lens.coefficients if lens.model == "opencv" else (0.0,) * 5)
        body = (f"    float a = ad;\n    float b = bd;\n"
                f"    for (int i = 0; i < {NEWTON_STEPS}; i++) {{\n        float s = a * a + b * b;\n"
                f"        float rad = 1.0 + s * ({k1} + s * ({k2} + s * {k3}));\n"
                f"        float slope = {k1} + s * (2.0 * {k2} + s * 3.0 * {k3});\n"
                f"        float fa = a * rad + 2.0 * {p1} * a * b + {p2} * (s + 2.0 * a * a) - ad;\n"
                f"        float fb = b * rad + {p1} * (s + 2.0 * b * b) + 2.0 * {p2} * a * b - bd;\n"
                f"        float cr = 2.0 * a * b * slope + 2.0 * {p1} * a + 2.0 * {p2} * b;\n"
                f"        float jaa = rad + 2.0 * a * a * slope + 2.0 * {p1} * b + 6.0 * {p2} * a;\n"
                f"        float jbb = rad + 2.0 * b * b * slope + 6.0 * {p1} * b + 2.0 * {p2} * a;\n"
                f"        float det = jaa * jbb - cr * cr;\n"
                f"        float da = (jbb * fa - cr * fb) / det;\n"
                f"        float db = (jaa * fb - cr * fa) / det;\n        a = a - da;\n        b = b - db;\n"
                f"        if (abs(da) + abs(db) < {OSL_CONVERGED}) break;\n    }}\n"
                f"    direction = normalize(vector(a, -b, 1.0));\n")
    return ("shader buildee_lens(output point position = 0, output vector direction = 0,\n"
            "                    output color throughput = 1) {\n"
            "    point raster = camera_shader_raster_position();\n"
            + head + body + "    position = point(0, 0, 0);\n}\n")


def apply_lens(cam, lens: Lens, K: np.ndarray, width: int, height: int) -> None:
    """Make the camera object ``cam`` render through ``lens`` (a perspective camera for an
    ideal lens), for ``K`` and the image size."""
    if lens.ideal:
        cam.data.type = "PERSP"
        return
    _osl_modules()
    text = bpy.data.texts.get(TEXT_NAME) or bpy.data.texts.new(TEXT_NAME)
    text.clear()
    text.write(osl_source(lens, K, width, height))
    cam.data.type = "CUSTOM"
    cam.data.custom_mode = "INTERNAL"
    cam.data.custom_shader = None
    cam.data.custom_shader = text  # compiles the shader (Cycles' update of the property)
    if not cam.data.custom_bytecode:
        raise RuntimeError(f"Cycles could not compile the {lens.model} lens shader (see the console)")

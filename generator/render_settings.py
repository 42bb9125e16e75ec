"""Render quality settings and presets (bpy-free, so command lines can validate them)."""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import dataclass, fields, replace

from .checks import check_integer, check_number

MIN_SIDE = 4  # Blender renders sides below 4 pixels as 4 (measured: 3x2 gives a 4x4 image)
MAX_SIDE = 16384  # Blender clamps above 65536


def check_side(name: str, value, high: int = MAX_SIDE) -> int:
    """An image side in pixels, MIN_SIDE to ``high``; else a one-line ValueError."""
    return check_integer(name, value, MIN_SIDE, high, valid=f"an integer from {MIN_SIDE} to {high:,} pixels "
                         f"(Blender renders smaller sides as {MIN_SIDE})")

ENGINES = ("CYCLES", "BLENDER_EEVEE", "BLENDER_WORKBENCH")
DEVICES = ("cpu", "gpu", "auto")  # Cycles device: the CPU, a CUDA/OptiX GPU, or a GPU when there is one
DENOISE_PREFILTERS = ("NONE", "FAST", "ACCURATE")
DENOISE_QUALITIES = ("HIGH", "BALANCED", "FAST")
NO_GPU_MESSAGE = ("device 'gpu' asked for, but Cycles finds no CUDA or OptiX GPU on this machine; use device "
                  "'cpu' or 'auto' (auto renders on a GPU when there is one, else on the CPU)")


@dataclass(frozen=True)
class RenderSettings:
    """Render quality settings; None leaves the .blend's own value untouched.

    samples: Cycles samples per pixel (EEVEE: TAA samples); bounces: Cycles max bounces
    (also the diffuse, glossy and transmission limits); denoise: OpenImageDenoise on the final
    image; denoise_prefilter: 'NONE', 'FAST' or 'ACCURATE' (cleaning of the albedo and normal
    guides); denoise_quality: 'HIGH', 'BALANCED' or 'FAST' (OpenImageDenoise's network size);
    light_tree: Cycles' light tree (helps scenes with many lights, costs time with a sun and
    a sky); adaptive_threshold: Cycles' adaptive-sampling noise threshold, 0 = off; threads:
    CPU threads (0 = all cores); resolution: (width, height) pixels; persistent_data: keep
    Cycles' scene between renders; device: 'cpu', 'gpu' or 'auto' (None: the CPU).
    """

    engine: str | None = None
    samples: int | None = None
    denoise: bool | None = None
    denoise_prefilter: str | None = None
    bounces: int | None = None
    threads: int | None = None
    resolution: tuple[int, int] | None = None
    persistent_data: bool | None = None
    denoise_quality: str | None = None
    light_tree: bool | None = None
    adaptive_threshold: float | None = None
    device: str | None = None

    def merged(self, other: "RenderSettings") -> "RenderSettings":
        """These settings with every non-None field of ``other`` applied on top."""
        return replace(self, **{f.name: getattr(other, f.name) for f in fields(other) if getattr(other, f.name) is not None})


PRESETS: dict[str, RenderSettings] = {
    # fast look (the batch job's default): few samples, denoised, short light paths; no light
    # tree (one sun and a sky: it only costs time) and no adaptive sampling (inert at 4 samples)
    "preview": RenderSettings("CYCLES", samples=4, denoise=True, denoise_prefilter="FAST", bounces=2, threads=0,
                              persistent_data=True, denoise_quality="HIGH", light_tree=False, adaptive_threshold=0.0),
    # clean enough for training
    "default": RenderSettings("CYCLES", samples=16, denoise=True, denoise_prefilter="FAST", bounces=4, threads=0,
                              persistent_data=True, denoise_quality="HIGH", light_tree=False, adaptive_threshold=0.01),
    # paper-quality stills
    "high": RenderSettings("CYCLES", samples=128, denoise=True, denoise_prefilter="ACCURATE", bounces=12, threads=0,
                           persistent_data=True, denoise_quality="HIGH", light_tree=False, adaptive_threshold=0.01),
}


def _choice(name: str, value, choices) -> None:
    if value is not None and value not in choices:
        raise ValueError(f"{name} must be one of {', '.join(map(str, choices))}, got {value!r}")


def resolve_settings(preset: str | None = None, **overrides) -> RenderSettings:
    """Validated settings from a preset name (or None: keep the .blend's) and overrides."""
    if preset is not None and preset not in PRESETS:
        raise ValueError(f"unknown render preset {preset!r}; choose one of {', '.join(PRESETS)}")
    base = PRESETS[preset] if preset else RenderSettings()
    unknown = set(overrides) - {f.name for f in fields(RenderSettings)}
    if unknown:
        raise TypeError(f"unknown render setting(s): {', '.join(sorted(unknown))}")
    s = base.merged(RenderSettings(**overrides))
    if s.engine is not None and s.engine not in ENGINES:
        raise ValueError(f"unknown render engine {s.engine!r}; choose one of {', '.join(ENGINES)}")
    s = replace(s, **{name: check_integer(name, getattr(s, name), low, valid=valid)
                      for name, low, valid in (("samples", 1, None), ("bounces", 0, None),
                                               ("threads", 0, "an integer >= 0 (0 = all cores)"))
                      if getattr(s, name) is not None})
    _choice("denoise_prefilter", s.denoise_prefilter, DENOISE_PREFILTERS)
    _choice("denoise_quality", s.denoise_quality, DENOISE_QUALITIES)
    _choice("device", s.device, DEVICES)
    for name in ("denoise", "light_tree", "persistent_data"):
        if getattr(s, name) is not None and not isinstance(getattr(s, name), bool):
            raise ValueError(f"{name} must be True or False, got {getattr(s, name)!r}")
    if s.adaptive_threshold is not None:
        s = replace(s, adaptive_threshold=check_number("adaptive_threshold", s.adaptive_threshold, 0, 1,
                                                       open_high=True, valid="a number in [0, 1) (0 = off)"))
    if s.resolution is not None:
        try:
            w, h = s.resolution
        except (TypeError, ValueError):
            raise ValueError(f"resolution must be (width, height), got {s.resolution!r}") from None
        s = replace(s, resolution=(check_side("resolution width", w), check_side("resolution height", h)))
    return s


def probe_gpu() -> str | None:
    """The GPU Cycles would render on ('OPTIX: <name>' or 'CUDA: <name>'), or None. Asked in a
    child process (``python -m generator.blender.devices``), so the caller never imports bpy."""
    env = {k: v for k, v in os.environ.items() if k != "OCIO"}
    r = subprocess.run([sys.executable, "-m", "generator.blender.devices"], capture_output=True, text=True, env=env,
                       cwd=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    lines = r.stdout.strip().splitlines()
    return lines[-1] if r.returncode == 0 and lines and lines[-1] != "none" else None

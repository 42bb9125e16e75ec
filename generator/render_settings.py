"""Render quality settings and presets (bpy-free, so command lines can validate them)."""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

ENGINES = ("CYCLES", "BLENDER_EEVEE", "BLENDER_WORKBENCH")
CRYPTOMATTE_LEVELS = 4  # objects ranked per pixel (two EXR layers)


@dataclass(frozen=True)
class RenderSettings:
    """Render quality settings; None leaves the .blend's own value untouched.

    samples: Cycles samples per pixel (EEVEE: TAA samples); bounces: Cycles max bounces;
    denoise: OpenImageDenoise on the final image; denoise_prefilter: 'NONE', 'FAST' or
    'ACCURATE'; threads: CPU threads (0 = all cores); resolution: (width, height) pixels.
    """

    engine: str | None = None
    samples: int | None = None
    denoise: bool | None = None
    denoise_prefilter: str | None = None
    bounces: int | None = None
    threads: int | None = None
    resolution: tuple[int, int] | None = None
    persistent_data: bool | None = None

    def merged(self, other: "RenderSettings") -> "RenderSettings":
        """These settings with every non-None field of ``other`` applied on top."""
        return replace(self, **{f.name: getattr(other, f.name) for f in fields(other) if getattr(other, f.name) is not None})


PRESETS: dict[str, RenderSettings] = {
    # fast look: few samples, quick denoise, short light paths
    "preview": RenderSettings("CYCLES", samples=4, denoise=True, denoise_prefilter="FAST", bounces=2, threads=0, persistent_data=True),
    # the batch job's default: clean enough for training, ~11 s at 640x480 on 2 cores
    "default": RenderSettings("CYCLES", samples=16, denoise=True, denoise_prefilter="FAST", bounces=4, threads=0, persistent_data=True),
    # paper-quality stills
    "high": RenderSettings("CYCLES", samples=128, denoise=True, denoise_prefilter="ACCURATE", bounces=12, threads=0, persistent_data=True),
}


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
    if s.samples is not None and (not isinstance(s.samples, int) or isinstance(s.samples, bool) or s.samples < 1):
        raise ValueError(f"samples must be an integer >= 1, got {s.samples!r}")
    if s.bounces is not None and (not isinstance(s.bounces, int) or s.bounces < 0):
        raise ValueError(f"bounces must be an integer >= 0, got {s.bounces!r}")
    if s.threads is not None and (not isinstance(s.threads, int) or s.threads < 0):
        raise ValueError(f"threads must be an integer >= 0 (0 = all cores), got {s.threads!r}")
    if s.denoise_prefilter is not None and s.denoise_prefilter not in ("NONE", "FAST", "ACCURATE"):
        raise ValueError(f"denoise_prefilter must be NONE, FAST or ACCURATE, got {s.denoise_prefilter!r}")
    if s.resolution is not None:
        try:
            w, h = (int(v) for v in s.resolution)
        except (TypeError, ValueError):
            raise ValueError(f"resolution must be (width, height), got {s.resolution!r}") from None
        if w <= 0 or h <= 0 or (w, h) != tuple(s.resolution):
            raise ValueError(f"resolution must be two positive integers, got {s.resolution!r}")
    return s

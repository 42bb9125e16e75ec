"""Preview images of a trajectory: a contact sheet of frames, one column per modality, each
coloured as its entry in exporters/modalities.py says (``preview``), written by the
``previews`` sink (``contact_sheet.png``); and the trajectory over the site map, written by
the ``map`` sink (``map.png``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from generator.geometry import portable_math

from .modalities import MODALITIES
from .palette import colorize_labels
from .sinks import FrameRecord, TrajectoryContext, register_sink

PREVIEW_FRAMES = 6  # rows of each trajectory's contact sheet

# an inferno-like ramp: near (0) bright yellow -> orange -> magenta -> far (1) dark blue
_RAMP = np.array([[252, 255, 164], [250, 193, 39], [245, 125, 21], [212, 72, 66], [159, 42, 99],
                  [101, 21, 110], [40, 11, 84], [0, 0, 40]], np.float64)


def colorize_depth(depth: np.ndarray, far: float | None = None) -> np.ndarray:
    """(H, W, 3) uint8: near = bright yellow, far = dark blue (square-root scale up to
    ``far``), no surface = black. ``far`` defaults to the 98th percentile of the finite depths."""
    finite = np.isfinite(depth)
    if not finite.any():
        return np.zeros(depth.shape + (3,), np.uint8)
    far = far or float(np.percentile(depth[finite], 98)) or 1.0
    s = np.sqrt(np.clip(np.where(finite, depth, far) / far, 0, 1)) * (len(_RAMP) - 1)
    k = np.minimum(s.astype(np.int64), len(_RAMP) - 2)
    t = (s - k)[..., None]
    rgb = _RAMP[k] * (1 - t) + _RAMP[k + 1] * t
    rgb[~finite] = 0
    return (rgb + 0.5).astype(np.uint8)


def colorize_ids(ids: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8: a distinct hue per id (golden-ratio steps), -1 = black."""
    ids = np.asarray(ids)
    hue = (np.maximum(ids, 0) * 0.618033988749895) % 1.0
    rgb = _hsv(hue, np.full(ids.shape, 0.65), np.full(ids.shape, 0.95))
    rgb[ids < 0] = 0
    return rgb


def colorize_normals(normal: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8: unit vector (x, y, z) -> RGB ((n + 1) / 2); no surface (0 or NaN) = black."""
    n = np.nan_to_num(np.asarray(normal, np.float64))
    rgb = ((n + 1.0) / 2.0 * 255.0 + 0.5).clip(0, 255).astype(np.uint8)
    rgb[~(np.abs(n).sum(-1) > 0)] = 0
    return rgb


def colorize_flow(flow: np.ndarray, max_flow: float | None = None) -> np.ndarray:
    """(H, W, 3) uint8 on the flow colour wheel: hue = direction (image axes: +x right is
    red, +y down is yellow-green), saturation = magnitude / ``max_flow`` (white = no motion,
    full colour at ``max_flow`` pixels and beyond); NaN = black."""
    f = np.asarray(flow, np.float64)
    ok = np.isfinite(f).all(-1)
    mag = np.where(ok, portable_math.hypot(f[..., 0], f[..., 1]), 0.0)
    if max_flow is None:
        max_flow = float(np.percentile(mag[ok], 98)) if ok.any() else 1.0
    max_flow = max(max_flow, 1e-6)
    hue = (portable_math.atan2(np.where(ok, f[..., 1], 0), np.where(ok, f[..., 0], 0)) / (2 * np.pi)) % 1.0
    rgb = _hsv(hue, np.clip(mag / max_flow, 0, 1), np.ones(mag.shape))
    rgb[~ok] = 0
    return rgb


def flow_wheel(size: int = 48) -> np.ndarray:
    """The legend: (size, size, 3) uint8 disc coloured by :func:`colorize_flow` for flows up to
    1 (centre = 0, rim = ``max_flow``; right = +x, down = +y), white outside."""
    c = (np.arange(size) + 0.5 - size / 2) / (size / 2)
    x, y = np.meshgrid(c, c)
    rgb = colorize_flow(np.stack([x, y], -1), 1.0)
    rgb[portable_math.hypot(x, y) > 1] = 255
    return rgb


def _hsv(h: np.ndarray, s: np.ndarray, v: np.ndarray) -> np.ndarray:
    i = np.floor(h * 6).astype(int) % 6
    f = h * 6 - np.floor(h * 6)
    p, q, t = v * (1 - s), v * (1 - f * s), v * (1 - (1 - f) * s)
    r = np.choose(i, [v, q, p, p, t, v])
    g = np.choose(i, [t, v, v, q, p, p])
    b = np.choose(i, [p, p, t, v, v, q])
    return (np.stack([r, g, b], -1) * 255 + 0.5).astype(np.uint8)


def _scales(frames: list[dict], names: list[str]) -> dict[str, float]:
    """Shared colour scales of the sheet: far depth (m) and max flow (px) per column."""
    out = {}
    for n in names:
        kind = MODALITIES[n].preview
        if kind == "depth":
            finite = np.concatenate([f[n][np.isfinite(f[n])] for f in frames])
            out[n] = float(np.percentile(finite, 98)) if len(finite) else 1.0
        elif kind == "flow":
            mags = np.concatenate([portable_math.hypot(f[n][..., 0], f[n][..., 1]).ravel() for f in frames])
            mags = mags[np.isfinite(mags)]
            out[n] = max(float(np.percentile(mags, 98)), 1e-3) if len(mags) else 1.0
    return out


def preview_tile(name: str, array: np.ndarray, labels: list[str], scale: float | None = None) -> np.ndarray:
    """(H, W, 3) uint8 preview of one modality's array, coloured as its entry says."""
    kind = MODALITIES[name].preview
    if callable(kind):
        return np.asarray(kind(array, labels), np.uint8)
    if kind == "rgb":
        return (np.clip(np.asarray(array, np.float32), 0, 1) * 255 + 0.5).astype(np.uint8)
    if kind == "depth":
        return colorize_depth(array, scale)
    if kind == "labels":
        return colorize_labels(np.asarray(array), labels)
    if kind == "ids":
        return colorize_ids(array)
    if kind == "normal":
        return colorize_normals(array)
    if kind == "flow":
        return colorize_flow(array, scale)
    raise ValueError(f"modality {name!r} has no preview colouring")


def contact_sheet(path: str | Path, frames: list[dict], labels: list[str], names: list[str] | None = None,
                  max_width: int = 320) -> Path:
    """One row per frame, one column per modality of ``names`` (default: rgb, depth, label),
    each scaled to at most ``max_width`` pixels wide; each row's caption names the columns
    and their scales; a flow colour wheel with its scale closes the sheet when flow is shown.
    ``frames``: dicts with ``index`` and the modalities' arrays."""
    if not frames:
        raise ValueError("contact_sheet needs at least one frame")
    names = list(names or ("rgb", "depth", "label"))
    h, w = np.asarray(frames[0][names[0]]).shape[:2]
    scale = min(1.0, max_width / w)
    tw, th = max(1, int(w * scale)), max(1, int(h * scale))
    scales = _scales(frames, names)
    flows = [n for n in names if MODALITIES[n].preview == "flow"]
    pad, top, legend = 4, 14, (64 if flows else 0)
    width = max(len(names) * tw + (len(names) + 1) * pad, 380 if flows else 0)
    sheet = Image.new("RGB", (width, len(frames) * (th + top) + pad + legend),
                      (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for r, f in enumerate(frames):
        y = r * (th + top) + top
        for c, n in enumerate(names):
            x = pad + c * (tw + pad)
            caption = f"frame {f['index']}" if c == 0 else n
            if MODALITIES[n].preview == "depth":
                caption += f" 0-{scales[n]:.0f} m"
            draw.text((x, y - top + 1), caption, fill=(0, 0, 0))
            tile = preview_tile(n, f[n], labels, scales.get(n))
            sheet.paste(Image.fromarray(tile).resize((tw, th), Image.NEAREST), (x, y))
    if flows:
        y = len(frames) * (th + top) + pad
        sheet.paste(Image.fromarray(flow_wheel(56)), (pad, y + 4))
        lines = ["flow colour wheel: hue = direction (right +x, down +y)",
                 "white = still; full colour at " + ", ".join(f"{n} {scales[n]:.1f} px" for n in flows),
                 "black = no surface, or no such frame"]
        for k, line in enumerate(lines):
            draw.text((pad + 64, y + 8 + 14 * k), line, fill=(0, 0, 0))
    path = Path(path)
    sheet.save(path)
    return path


@register_sink("previews")
class PreviewSink:
    """``contact_sheet.png``: up to :data:`PREVIEW_FRAMES` frames spread over the trajectory,
    one column per written modality that has a preview colouring."""

    def __init__(self, context: TrajectoryContext):
        self.context = context
        T = len(context.poses)
        self.rows = set(np.linspace(0, T - 1, min(PREVIEW_FRAMES, T)).round().astype(int).tolist())
        self.names = [n for n in context.modalities if MODALITIES[n].preview is not None]
        self.frames: list[dict] = []

    def add_frame(self, frame: FrameRecord) -> None:
        if frame.index in self.rows and self.names:
            self.frames.append({"index": frame.index} | {n: frame.outputs[n] for n in self.names})

    def close(self) -> None:
        if self.frames:
            contact_sheet(Path(self.context.folder) / "contact_sheet.png", self.frames, self.context.labels, self.names)


@register_sink("map")
class MapSink:
    """``map.png``: the trajectory over the top-down site map (when ``options["plan"]`` holds
    the generated site's plan)."""

    def __init__(self, context: TrajectoryContext):
        self.context = context

    def add_frame(self, frame: FrameRecord) -> None:
        pass

    def close(self) -> None:
        plan = self.context.options.get("plan")
        if plan is not None:
            from generator.scene.site_map import draw_map

            draw_map(plan, Path(self.context.folder) / "map.png", trajectory=np.asarray(self.context.poses)[:, :3, 3])

"""Per-frame modalities, declared once (bpy-free).

Each entry of :data:`MODALITIES` says everything the rest of the code needs about one
per-frame array: how it is produced (``"render"``: from Blender render passes, each a
:class:`BlenderPass` saying how the renderer switches it on and how its EXR channels decode;
``"geometry"``: computed from the scene's geometry at the pixel centres by
``compute(pixel_geometry)``), where it is stored (EXR part and channels, their EXR type,
extra PNG files), how it decodes, how ``datasets`` transforms resample it, and how the
contact sheet colours it. The renderer, the simulator, the frame writer and reader, the
datasets' transforms and the previews all loop over this table: adding a modality is one
:func:`register_modality` call, here or in a new module of this package, which is imported
with this one (:func:`import_modality_modules`; docs/format.md lists the built-in ones).
"""

from __future__ import annotations

import importlib
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping

import numpy as np

NONE_ID = -1  # ids (label, instance) where there is no surface / no object

# resampling rules of datasets.transforms.Resize (Crop only slices)
RESAMPLE = {
    "area": "box filter when shrinking, bilinear when enlarging (colour)",
    "nearest": "nearest pixel centre (ids: values are never blended)",
    "bilinear": "bilinear at the new pixel centres on a continuous surface, nearest across depth edges",
    "unit_vector": "as bilinear, then renormalised to unit length",
    "flow": "as bilinear, then each component scaled by the resize ratio of its axis",
}
EXR_TYPES = {"HALF": np.float16, "FLOAT": np.float32, "UINT": np.uint32}
PART_OF_TYPE = {"HALF": "colour", "FLOAT": "data", "UINT": "ids"}  # EXR parts, in file order


@dataclass(frozen=True, eq=False)
class BlenderPass:
    """One Blender render pass: how the renderer switches it on and how its channels decode.

    name: the key of its decoded value, its layer's name in Blender's multilayer EXR where it
        has one (``"Depth"``, ``"Ambient Occlusion"``); one object per name (modalities share it).
    channels: the channels it writes, ``"<layer>.<channel>"`` without the view layer's name
        (Blender's ``ViewLayer.Depth.Z`` is ``"Depth.Z"``).
    decode: numpy on those channels (name -> (H, W) array as Blender stored it) -> the pass's
        value, usually an array.
    switches: view-layer properties the renderer sets True for a render that needs the pass
        and False for one that does not; a dotted name reaches a nested group
        (``"cycles.use_pass_shadow_catcher"``). Empty: always written (Combined, the display image).
    settings: further view-layer properties (name -> value) set while the pass is on.
    """

    name: str
    channels: tuple[str, ...]
    decode: Callable[[dict[str, np.ndarray]], object]
    switches: tuple[str, ...] = ()
    settings: Mapping[str, object] = field(default_factory=dict)

    def __post_init__(self):
        if not self.channels or not all(isinstance(c, str) and "." in c.strip(".") for c in self.channels):
            raise ValueError(f"Blender pass {self.name!r}: channels must be names '<layer>.<channel>', "
                             f"got {self.channels!r}")


@dataclass(frozen=True)
class Modality:
    """One per-frame modality.

    name: key in ``RenderOutput.outputs``, ``FrameRecord.outputs``, dataset frames, ``--outputs``.
    description: units and conventions (written into the files and docs).
    source: ``"render"`` (Blender passes) or ``"geometry"`` (``compute`` from the geometry).
    channels: EXR channel names; one channel gives (H, W), several (H, W, C).
    exr_type: ``HALF``, ``FLOAT`` or ``UINT`` (ids: int32 with -1 stored as uint32).
    part: the EXR part holding it, one per component type so that readers that want one type
        per part (imageio's FreeImage) open the first: ``"colour"`` (HALF), ``"data"``
        (FLOAT), ``"ids"`` (UINT); or ``None`` if it is not stored in the EXR (``pngs`` only).
    pngs: extra image files per frame: ``(prefix, kind)`` with kind ``"rgb8"`` (8-bit sRGB)
        or ``"id16"`` (16-bit, id + 1, 0 = none), written as ``<prefix>_NNNNNN.png``.
    resample: key of :data:`RESAMPLE`.
    preview: ``"rgb"``, ``"depth"``, ``"labels"``, ``"ids"``, ``"normal"``, ``"flow"``, a
        callable ``(array, labels) -> (H, W, 3) uint8``, or None (not on the contact sheet).
    compute: for ``source="geometry"``: ``(generator.geometry.pixels.PixelGeometry) -> array``.
    dtype: numpy type the datasets return (the EXR type; ``rgb``: float32 from its 8-bit PNG).
    truth: a ``"render"`` modality that ``render()`` takes from the Simulator's ``ground_truth``
        source: cast at the pixel centres (``"geometry"``, the default) or Blender's passes
        (``"renderer"``): ``depth``, ``label`` and ``instance``, which generator/view_render.py
        assembles from the cast or from their passes; see :func:`produced_by`.
    passes: for ``source="render"``: the Blender passes it is made from, switched on for the
        renders that ask for it (generator/blender/render.py) and decoded by their ``decode``.
    from_passes: for ``source="render"``: ``(decoded passes: pass name -> value) -> array``;
        None: the value of its one pass.
    """

    name: str
    description: str
    source: str
    channels: tuple[str, ...]
    exr_type: str
    part: str | None
    resample: str
    preview: str | Callable | None = None
    compute: Callable | None = None
    pngs: tuple[tuple[str, str], ...] = ()
    dtype: str = ""
    truth: bool = False
    passes: tuple[BlenderPass, ...] = ()
    from_passes: Callable[[Mapping[str, object]], np.ndarray] | None = None

    def __post_init__(self):
        if self.source not in ("render", "geometry"):
            raise ValueError(f"modality {self.name!r}: source must be 'render' or 'geometry', got {self.source!r}")
        if self.source == "geometry" and (self.compute is None or self.passes):
            raise ValueError(f"modality {self.name!r}: a geometry modality needs compute and no Blender passes")
        if self.source == "render" and (not self.passes or not all(isinstance(p, BlenderPass) for p in self.passes)):
            raise ValueError(f"modality {self.name!r}: a render modality needs passes, a tuple of BlenderPass")
        if self.source == "render" and len(self.passes) > 1 and self.from_passes is None and not self.truth:
            raise ValueError(f"modality {self.name!r}: made from {len(self.passes)} passes, it needs from_passes")
        if self.exr_type not in EXR_TYPES:
            raise ValueError(f"modality {self.name!r}: exr_type must be one of {', '.join(EXR_TYPES)}")
        if self.resample not in RESAMPLE:
            raise ValueError(f"modality {self.name!r}: resample must be one of {', '.join(RESAMPLE)}")
        if self.truth and self.source != "render":
            raise ValueError(f"modality {self.name!r}: only a 'render' modality can take the ground_truth source")
        if self.part not in (None, PART_OF_TYPE[self.exr_type]):
            raise ValueError(f"modality {self.name!r}: {self.exr_type} channels go to EXR part "
                             f"{PART_OF_TYPE[self.exr_type]!r} (or None: not in the EXR)")
        if not self.dtype:
            object.__setattr__(self, "dtype", "int32" if self.exr_type == "UINT" else np.dtype(EXR_TYPES[self.exr_type]).name)

    @property
    def is_ids(self) -> bool:
        return self.exr_type == "UINT"

    def encode(self, array: np.ndarray) -> dict[str, np.ndarray]:
        """The EXR channels (name -> contiguous (H, W) array of the EXR type) of ``array``."""
        a = np.asarray(array)
        want = 2 if len(self.channels) == 1 else 3
        if a.ndim != want or (want == 3 and a.shape[2] != len(self.channels)):
            shape = "(H, W)" if want == 2 else f"(H, W, {len(self.channels)})"
            raise ValueError(f"{self.name} must have shape {shape}, got {a.shape}")
        planes = [a] if want == 2 else [a[..., k] for k in range(a.shape[2])]
        if self.is_ids:
            if not np.issubdtype(a.dtype, np.integer):
                raise ValueError(f"{self.name} must hold integer ids, got {a.dtype}")
            if a.size and (a.min() < NONE_ID or a.max() > np.iinfo(np.int32).max):
                raise ValueError(f"{self.name} ids must lie in [-1, 2^31 - 1]")
            planes = [p.astype(np.int64).astype(np.int32).view(np.uint32) for p in planes]
        t = EXR_TYPES[self.exr_type]
        return {c: np.ascontiguousarray(p, dtype=t) for c, p in zip(self.channels, planes)}

    def decode(self, channels: dict[str, np.ndarray]) -> np.ndarray:
        """The array from its EXR channels, exactly as :meth:`encode` wrote them (the EXR type;
        ids as int32 with -1)."""
        planes = [np.asarray(channels[c]) for c in self.channels]
        if self.is_ids:
            planes = [np.ascontiguousarray(p, dtype=np.uint32).view(np.int32) for p in planes]
        return planes[0] if len(planes) == 1 else np.stack(planes, axis=-1)

    def from_render(self, decoded: Mapping[str, object]) -> np.ndarray:
        """The array of this ``render`` modality from one render's decoded passes (pass name ->
        value, None where the engine wrote no such pass)."""
        missing = [p.name for p in self.passes if decoded.get(p.name) is None]
        if missing:
            raise ValueError(f"modality {self.name!r} needs Blender's {', '.join(missing)} pass, which this render "
                             f"engine did not write: render with Cycles, or leave {self.name} out of the outputs")
        return self.from_passes(decoded) if self.from_passes is not None else decoded[self.passes[0].name]


MODALITIES: dict[str, Modality] = {}


def register_modality(modality: Modality) -> Modality:
    """Add a modality to the table (its name must be new, and each Blender pass it shares
    with another modality the same :class:`BlenderPass` object); returns it."""
    if modality.name in MODALITIES:
        raise ValueError(f"modality {modality.name!r} is registered twice")
    known = blender_passes()
    for p in modality.passes:
        if known.get(p.name, p) is not p:
            raise ValueError(f"modality {modality.name!r}: Blender pass {p.name!r} is already declared by another "
                             f"modality; import that BlenderPass and share it")
    MODALITIES[modality.name] = modality
    return modality


def unregister_modality(name: str) -> None:
    """Remove a modality (for tests that add their own)."""
    MODALITIES.pop(name, None)


def blender_passes(names=None) -> dict[str, BlenderPass]:
    """Pass name -> :class:`BlenderPass` of every pass the modalities ``names`` declare (default:
    all registered), in table order."""
    chosen = MODALITIES.values() if names is None else [MODALITIES[n] for n in resolve(names)]
    return {p.name: p for m in chosen for p in m.passes}


MODALITY_MODULE = re.compile(r"^register_modality\(", re.MULTILINE)  # a module-level registration


def import_modality_modules(package: str = __package__) -> list[str]:
    """Import, sorted by name, every module of ``package`` whose source registers a modality at
    its top level (a line starting ``register_modality(``), such as a new
    ``exporters/ambient_occlusion.py``: dropping that file in is all it takes. Returns their
    names. Runs once for this package when this module is first imported."""
    found = []
    for folder in importlib.import_module(package).__path__:
        for path in sorted(Path(folder).glob("*.py")):
            if path.resolve() != Path(__file__).resolve() and MODALITY_MODULE.search(path.read_text(encoding="utf-8")):
                found.append(f"{package}.{path.stem}")
    for name in found:
        importlib.import_module(name)
    return found


def produced_by(m: Modality, ground_truth: str | None, segmentation_sensitivity: float | None) -> str:
    """How modality ``m`` was made in a run with these Simulator settings (frames.json's
    ``source``; docs/format.md, Per-frame modalities); None: the setting is not known."""
    cast = "geometry: the scene's triangles hit by the ray through the pixel centre"
    if m.source == "geometry" or (m.truth and ground_truth == "geometry"):
        how = cast
    elif m.truth and ground_truth == "renderer":
        how = ("renderer: Blender's passes (ground_truth='renderer'; the ray cast where the engine has no Object "
               "Index pass)")
    elif m.truth:
        return "render(): the Simulator's ground_truth source (not recorded)"
    else:
        return "renderer: Blender's render"
    if m.name == "label" and segmentation_sensitivity:
        how += (f", -1 where Blender's Cryptomatte coverage of the label is below segmentation_sensitivity "
                f"{segmentation_sensitivity:g}")
    return how


def resolve(names=None) -> tuple[str, ...]:
    """Modality names in table order: all by default, else the given ones (a comma-separated
    string or an iterable); unknown names raise a ValueError listing the known ones."""
    if names is None:
        return tuple(MODALITIES)
    if isinstance(names, str):
        names = [n.strip() for n in names.split(",") if n.strip()]
    names = list(names)
    unknown = [n for n in names if n not in MODALITIES]
    if unknown or not names:
        raise ValueError(f"unknown output {', '.join(unknown) or '(none given)'}: choose from {', '.join(MODALITIES)}")
    return tuple(n for n in MODALITIES if n in names)


# ---- the Blender passes of the built-in modalities ----------------------------------------------

BLENDER_NO_SURFACE = 1e10  # what Blender writes in the Depth pass where there is no surface
CRYPTOMATTE_LEVELS = 4  # objects ranked per pixel (two EXR layers)


def stack(*channels: str, dtype=np.float32) -> Callable[[dict[str, np.ndarray]], np.ndarray]:
    """A decoder: the named channels stacked last, as ``dtype`` ((H, W) for one channel)."""
    def decode(c: dict[str, np.ndarray]) -> np.ndarray:
        planes = [c[name] for name in channels]
        return (planes[0] if len(planes) == 1 else np.stack(planes, axis=-1)).astype(dtype)

    return decode


def display_rgb(c: dict[str, np.ndarray]) -> np.ndarray:
    """(H, W, 3) float32 in [0, 1] from the display image's 16-bit channels."""
    rgb = np.stack([c["Display.R"], c["Display.G"], c["Display.B"]], axis=-1)
    if rgb.dtype != np.uint16:
        raise ValueError(f"expected a 16-bit display image from Blender, got {rgb.dtype}")
    return (rgb.astype(np.float32) / np.float32(65535.0)).astype(np.float32)


def planar_depth(c: dict[str, np.ndarray]) -> np.ndarray:
    """(H, W) float32 planar depth, +inf where Blender wrote its "no surface"."""
    depth = c["Depth.Z"].astype(np.float32)
    return np.where(depth >= BLENDER_NO_SURFACE * 0.999, np.float32(np.inf), depth)


CRYPTO_LAYERS = tuple(f"CryptoObject{k:02d}" for k in range(CRYPTOMATTE_LEVELS // 2))


def cryptomatte_ranks(c: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(ids (R, H, W) uint32 Cryptomatte hashes, coverage (R, H, W) float32), best rank first:
    each layer holds two ranks, (id, coverage) in (r, g) and (b, a)."""
    ids = [np.ascontiguousarray(c[f"{layer}.{k}"], dtype=np.float32).view(np.uint32)
           for layer in CRYPTO_LAYERS for k in "rb"]
    cov = [c[f"{layer}.{k}"].astype(np.float32) for layer in CRYPTO_LAYERS for k in "ga"]
    return np.stack(ids), np.stack(cov)


# the display-referred image (Blender's view transform applied), written by the renderer's
# compositor as a 16-bit TIFF beside the EXR, whatever the passes
DISPLAY = BlenderPass("Display", ("Display.R", "Display.G", "Display.B"), display_rgb)
COMBINED = BlenderPass("Combined", ("Combined.R", "Combined.G", "Combined.B"),
                       stack("Combined.R", "Combined.G", "Combined.B"))
DEPTH = BlenderPass("Depth", ("Depth.Z",), planar_depth, switches=("use_pass_z",))
OBJECT_INDEX = BlenderPass("Object Index", ("Object Index.X",), lambda c: np.rint(c["Object Index.X"]).astype(np.int32),
                           switches=("use_pass_object_index",))
CRYPTO_OBJECT = BlenderPass("CryptoObject", tuple(f"{layer}.{k}" for layer in CRYPTO_LAYERS for k in "rgba"),
                            cryptomatte_ranks, switches=("use_pass_cryptomatte_object",),
                            settings={"pass_cryptomatte_depth": CRYPTOMATTE_LEVELS})

# ---- the built-in modalities ------------------------------------------------------------------

register_modality(Modality(
    "rgb", "display-referred sRGB in [0, 1] (Blender's view transform applied), 8-bit in rgb_NNNNNN.png",
    "render", ("R", "G", "B"), "HALF", None, "area", preview="rgb", pngs=(("rgb", "rgb8"),), dtype="float32",
    passes=(DISPLAY,)))
register_modality(Modality(
    "rgb_linear", "scene-linear RGB (Blender's working space, Rec.709 primaries, D65), HDR",
    "render", ("R", "G", "B"), "HALF", "colour", "area", passes=(COMBINED,)))
register_modality(Modality(
    "depth", "planar depth (camera z) in metres at the pixel centre, +inf = no surface",
    "render", ("Z",), "FLOAT", "data", "bilinear", preview="depth", truth=True, passes=(DEPTH,)))
register_modality(Modality(
    "label", "semantic label id at the pixel centre (index into labels.json), -1 = unlabelled",
    "render", ("label",), "UINT", "ids", "nearest", preview="labels", pngs=(("label", "id16"),), truth=True,
    passes=(OBJECT_INDEX, CRYPTO_OBJECT)))
register_modality(Modality(
    "instance", "object id at the pixel centre (index into the object table), -1 = no object",
    "render", ("instance",), "UINT", "ids", "nearest", preview="ids", pngs=(("instance", "id16"),),
    truth=True, passes=(OBJECT_INDEX,)))
register_modality(Modality(
    "normal", "unit surface normal at the pixel centre, world frame, facing the camera; 0 = no surface",
    "geometry", ("normal.X", "normal.Y", "normal.Z"), "FLOAT", "data", "unit_vector", preview="normal",
    compute=lambda g: g.world_normals()))
register_modality(Modality(
    "flow", "optical flow to the next frame in pixels (x, y): where the surface point at the pixel centre, "
    "moving rigidly with its object, projects in the next frame, minus the pixel centre; NaN = no surface, "
    "no next frame, or behind the next camera",
    "geometry", ("flow.X", "flow.Y"), "FLOAT", "data", "flow", preview="flow",
    compute=lambda g: g.flow_to(g.index + 1)))
register_modality(Modality(
    "backward_flow", "optical flow to the previous frame in pixels (x, y), as flow; NaN = no surface, "
    "no previous frame, or behind the previous camera",
    "geometry", ("backward_flow.X", "backward_flow.Y"), "FLOAT", "data", "flow", preview="flow",
    compute=lambda g: g.flow_to(g.index - 1)))


import_modality_modules()  # last: the modules found register theirs with this module complete

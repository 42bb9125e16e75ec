"""Decode Blender's render passes into the simulator's outputs (bpy-free).

Blender writes one multilayer EXR per render (the passes the requested modalities declare:
exporters/modalities.py, ``BlenderPass``) and, through the compositor, a 16-bit TIFF of the
display-referred RGB. This module reads both into channels, decodes each pass by its own
declaration (:func:`decode_passes`), and holds what turns the object-index and Cryptomatte
passes into labels and instance ids. The Cryptomatte manifest Blender writes in the EXR
header is not read (it is not valid JSON for names with quotes, backslashes or control
characters): an object's Cryptomatte id is computed from its name (:func:`cryptomatte_id`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable

import numpy as np

from exporters.modalities import BlenderPass

LABEL_COVERAGE_EPS = 1e-6
# modality name -> RenderOutput field: what every Simulator.render() holds (the paper's
# ``(rgb, depth, seg)``, ``instance`` and ``rgb_linear``); other modalities go to ``extra``
FIELD_OF_MODALITY = {"rgb": "rgb", "rgb_linear": "rgb_linear", "depth": "depth", "label": "seg", "instance": "instance"}


@dataclass
class RenderOutput:
    """What ``Simulator.render()`` returns; behaves as the paper's 3-tuple ``(rgb, depth, seg)``
    (unpacking, integer indexing, slicing, ``len``), holds the fields below, and is keyed by
    modality name (``out["depth"]``, ``out.outputs``; exporters/modalities.py).

    rgb: (H, W, 3) float32 display-referred (view transform applied), in [0, 1].
    depth: (H, W) float32 planar depth in metres, +inf where no surface.
    seg: (H, W) int32 label ids (index into ``Simulator.labels``), -1 = unlabelled
        (modality ``label``).
    instance: (H, W) int32 object ids (index into ``Simulator.object_names``), -1 = none.
    rgb_linear: (H, W, 3) float32 scene-referred linear RGB (HDR).
    K, world_from_camera, frame: the camera and time the image was rendered with.
    extra: further modalities by name when they were asked for: from the geometry (``normal``,
        ``flow``: ``render_outputs``) or from further Blender passes (``render(outputs=...)``).
    exposure_gain: the linear gain the image sensor applied to ``rgb`` (1: as rendered;
        ``Simulator.set_image_sensor``, docs/cameras.md).
    """

    rgb: np.ndarray
    depth: np.ndarray
    seg: np.ndarray
    instance: np.ndarray
    rgb_linear: np.ndarray
    K: np.ndarray
    world_from_camera: np.ndarray
    frame: int
    extra: dict = field(default_factory=dict)
    exposure_gain: float = 1.0

    @classmethod
    def of(cls, arrays: dict[str, np.ndarray], K: np.ndarray, world_from_camera: np.ndarray,
           frame: int) -> "RenderOutput":
        """The output holding ``arrays`` (modality name -> array): the modalities of
        :data:`FIELD_OF_MODALITY` in their fields (None where absent), the others in ``extra``."""
        fields = {f: arrays.get(m) for m, f in FIELD_OF_MODALITY.items()}
        extra = {n: a for n, a in arrays.items() if n not in FIELD_OF_MODALITY}
        return cls(**fields, K=K, world_from_camera=world_from_camera, frame=frame, extra=extra)

    @property
    def outputs(self) -> dict[str, np.ndarray]:
        """Modality name -> array, for every modality this render holds."""
        base = {m: getattr(self, f) for m, f in FIELD_OF_MODALITY.items()}
        return {k: v for k, v in base.items() if v is not None} | dict(self.extra)

    def __iter__(self):
        return iter((self.rgb, self.depth, self.seg))

    def __len__(self) -> int:
        return 3

    def __getitem__(self, index):
        """Indexes and slices like the paper's ``(rgb, depth, seg)`` tuple; a string key
        gives that modality (``out["instance"]``)."""
        if isinstance(index, str):
            outputs = self.outputs
            if index not in outputs:
                raise KeyError(f"this render has no {index!r} (it has {', '.join(outputs)})")
            return outputs[index]
        return (self.rgb, self.depth, self.seg)[index]


_M32 = 0xFFFFFFFF


def _rotl32(x: int, r: int) -> int:
    return ((x << r) | (x >> (32 - r))) & _M32


def _mix_block(k: int) -> int:
    return (_rotl32((k * 0xCC9E2D51) & _M32, 15) * 0x1B873593) & _M32


def murmur3_32(data: bytes, seed: int = 0) -> int:
    """MurmurHash3 (x86, 32-bit) of ``data``: the hash Cryptomatte gives a name."""
    h, n = seed, len(data) - len(data) % 4
    for i in range(0, n, 4):
        h = (_rotl32(h ^ _mix_block(int.from_bytes(data[i:i + 4], "little")), 13) * 5 + 0xE6546B64) & _M32
    if n < len(data):
        h ^= _mix_block(int.from_bytes(data[n:], "little"))
    h ^= len(data)
    h = ((h ^ (h >> 16)) * 0x85EBCA6B) & _M32
    h = ((h ^ (h >> 13)) * 0xC2B2AE35) & _M32
    return h ^ (h >> 16)


def cryptomatte_id(name: str) -> int:
    """The uint32 bits the Cryptomatte object pass holds for the object named ``name``: the
    murmur3 hash of its UTF-8 bytes (the manifest's hash) as Blender stores it in a float."""
    return cryptomatte_pixel_id(murmur3_32(name.encode("utf-8", "surrogateescape")))


def cryptomatte_pixel_id(name_hash: int) -> int:
    """The uint32 bits a Cryptomatte pixel holds for an object whose manifest hash (32-bit
    murmur3 of its name) is ``name_hash``: Blender stores the hash as a float32 with the
    exponent clamped to [1, 254] (no zero/denormal, inf or NaN), so about 2 names in 256
    have pixel ids that differ from their manifest hash in the exponent bits."""
    exponent = min(max((name_hash >> 23) & 0xFF, 1), 254)
    return (name_hash & 0x807FFFFF) | (exponent << 23)


def read_blender_exr(path: str | Path) -> dict[str, np.ndarray]:
    """Every channel (full name, e.g. ``ViewLayer.Depth.Z`` -> (H, W) array) of the multilayer
    EXR that Blender wrote for a render (all parts)."""
    import OpenEXR

    from exporters.exr import use_all_cores

    use_all_cores()

    channels: dict[str, np.ndarray] = {}
    with OpenEXR.File(str(path), separate_channels=True) as f:
        for part in f.parts:
            for name, ch in part.channels.items():
                channels[name] = ch.pixels
    return channels


def read_display_tiff(path: str | Path) -> dict[str, np.ndarray]:
    """The channels ``Display.R``, ``.G``, ``.B`` ((H, W) uint16) of Blender's 16-bit TIFF of the
    display-referred image (the ``Display`` pass of exporters/modalities.py)."""
    import tifffile

    data = tifffile.imread(str(path))
    return {f"Display.{c}": data[..., k] for k, c in enumerate("RGB")}


def decode_passes(channels: dict[str, np.ndarray], passes: Iterable[BlenderPass]) -> dict[str, object]:
    """Pass name -> decoded value of each of ``passes``, None for a pass whose channels the
    render does not hold (an engine without it). A channel ``<layer>.<channel>`` is found
    under any view layer's name (``ViewLayer.Depth.Z``), the first one if several."""
    decoded = {}
    for p in passes:
        found = {}
        for c in p.channels:
            hits = [k for k in channels if k == c or k.endswith("." + c)]
            if hits:
                found[c] = channels[hits[0]]
        decoded[p.name] = p.decode(found) if len(found) == len(p.channels) else None
    return decoded


def label_coverage(crypto: tuple[np.ndarray, np.ndarray], hash_to_label: dict[int, int],
                   seg: np.ndarray) -> np.ndarray:
    """Share (H, W) of each pixel's antialiased footprint covered by objects carrying the
    label ``seg`` holds at that pixel, from the Cryptomatte object ranks ``crypto`` = (ids,
    coverage), each (R, H, W) (exporters/modalities.py, ``CRYPTO_OBJECT``)."""
    keys = np.fromiter(hash_to_label.keys(), dtype=np.uint32, count=len(hash_to_label))
    vals = np.fromiter(hash_to_label.values(), dtype=np.int32, count=len(hash_to_label))
    order = np.argsort(keys)
    keys, vals = keys[order], vals[order]
    total = np.zeros(seg.shape, dtype=np.float32)
    for ids, cov in zip(*crypto):
        pos = np.clip(np.searchsorted(keys, ids), 0, max(len(keys) - 1, 0))
        label = np.where((len(keys) > 0) & (keys[pos] == ids), vals[pos], -2) if len(keys) else np.full(ids.shape, -2)
        total += np.where(label == seg, cov, 0.0).astype(np.float32)
    return total


def semantic_map(
    object_index: np.ndarray,
    label_of_pass_index: np.ndarray,
    instance_of_pass_index: np.ndarray,
    sensitivity: float,
    coverage_fn=None,
) -> tuple[np.ndarray, np.ndarray]:
    """Labels and instances (H, W) int32 from the pixel-centre object index.

    ``label_of_pass_index[k]`` / ``instance_of_pass_index[k]`` give the label and instance of
    pass index k (index 0 = no object = -1). With ``sensitivity`` > 0, labels whose share of
    the pixel (``coverage_fn(seg)``) is below it become -1; instances are kept.
    """
    idx = np.clip(object_index, 0, len(label_of_pass_index) - 1)
    known = (object_index >= 0) & (object_index < len(label_of_pass_index))
    seg = np.where(known, label_of_pass_index[idx], -1).astype(np.int32)
    inst = np.where(known, instance_of_pass_index[idx], -1).astype(np.int32)
    if sensitivity > 0:
        cov = coverage_fn(seg)
        seg = np.where(cov + LABEL_COVERAGE_EPS >= sensitivity, seg, -1).astype(np.int32)
    return seg, inst
